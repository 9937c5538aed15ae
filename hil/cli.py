"""The `hil` command line: one sub-command per module under `hil/commands/`.

Each command module defines `add_arguments(parser)` and `run(args) -> int` and
imports its heavy dependencies (numba, rosbags, rerun) inside `run`, so that
`hil --help` starts instantly.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import Protocol

from hil import __version__


class CommandModule(Protocol):
    """What a module under `hil/commands/` provides."""

    HELP: str

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        """Declare the command's arguments."""

    def run(self, args: argparse.Namespace) -> int:
        """Execute the command; return the process exit status."""


# name on the command line -> module under hil.commands
COMMANDS: dict[str, str] = {
    "run": "run",
    "campaign": "campaign",
    "vessel": "vessel",
    "sim-vessel": "sim_vessel",
    "synth": "synth",
    "replay": "replay",
    "record-suite": "record_suite",
    "info": "info",
    "inspect": "inspect",
    "plot": "plot",
    "recover": "recover",
}


def _load(module_name: str) -> CommandModule:
    module: CommandModule = importlib.import_module(f"hil.commands.{module_name}")
    return module


def build_parser() -> argparse.ArgumentParser:
    """Return the top-level parser with every registered sub-command."""
    parser = argparse.ArgumentParser(
        prog="hil",
        description="Hardware-in-the-loop harness for symbolic docking control of the C/S Voyager.",
    )
    parser.add_argument("--version", action="version", version=f"hil {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module_name in COMMANDS.items():
        module = _load(module_name)
        command_parser = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(command_parser)
        command_parser.set_defaults(_module=module)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the `hil` command line; return the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    module: CommandModule = args._module
    try:
        return module.run(args)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
