"""The `hil` command line: one sub-command per module under `hil/commands/`.

Each command module defines `add_arguments(parser)` and `run(args) -> int` and
imports its heavy dependencies (numba, rosbags, rerun) inside `run`, so that
`hil --help` starts instantly.
"""

from __future__ import annotations

import argparse
import importlib
import os
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
    "sweep": "sweep",
    "vessel": "vessel",
    "sim-vessel": "sim_vessel",
    "synth": "synth",
    "replay": "replay",
    "judge": "judge",
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


ROS_COMMANDS = ("vessel", "sim-vessel")
"""The commands that take ROS 2 arguments (``--ros-args -r FROM:=TO -p NAME:=VALUE``)."""


def split_ros_args(argv: Sequence[str]) -> tuple[list[str], tuple[str, ...]]:
    """Split a command line into hil's arguments and the ROS 2 arguments after ``--ros-args``.

    As on any ROS 2 command line, the ROS arguments run to a ``--`` (after which hil's
    arguments go on) or to the end.
    """
    raw = list(argv)
    if "--ros-args" not in raw:
        return raw, ()
    at = raw.index("--ros-args")
    rest = raw[at + 1 :]
    end = rest.index("--") if "--" in rest else len(rest)
    return raw[:at] + rest[end + 1 :], tuple(rest[:end])


# Exit status when the reader of our output went away (`hil info LOG | head`), as a
# process killed by SIGPIPE would report it.
EXIT_BROKEN_PIPE = 128 + 13


def _quiet_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # no real stdout (tests): nothing left to flush
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the `hil` command line; return the exit status."""
    from hil.commands.common import join_negative_values

    parser = build_parser()
    raw, ros_args = split_ros_args(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(join_negative_values(raw))
    args.ros_args = ros_args
    if ros_args and args.command not in ROS_COMMANDS:
        print(f"hil {args.command}: error: --ros-args is for {' and '.join(ROS_COMMANDS)} only",
              file=sys.stderr)
        return 2
    module: CommandModule = args._module
    try:
        status = module.run(args)
        sys.stdout.flush()
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        _quiet_stdout()
        return EXIT_BROKEN_PIPE
    except MemoryError as err:
        print(f"hil {args.command}: error: out of memory ({err})", file=sys.stderr)
        return 2
    return status
