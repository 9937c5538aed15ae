"""`hil vessel --config FILE`: the on-vessel entry point (ROS 2 backend, wall time).

Runs the full stack against the lab's topics, records the run, and on SIGINT or
SIGTERM sends zero thrust and closes the log before exiting.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hil.commands.common import EXIT_ABORTED, EXIT_BAD_INPUT, EXIT_DOCKED, EXIT_NOT_DOCKED

HELP = "run the stack on the vessel over ROS 2 (wall time), recorded; stops cleanly on SIGINT"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("--config", type=Path, required=True, metavar="FILE",
                        help="vessel config (TOML): scenario, [ros], [loop], runs_dir")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="bag directory to create (default: under the config's runs_dir)")
    parser.add_argument("--json", action="store_true",
                        help="end with the summary as one JSON object on the last line")


def run(args: argparse.Namespace) -> int:
    """Run until docked or stopped; exit status as in :mod:`hil.commands.common`.

    0 docked, 1 not docked (time limit, SIGINT/SIGTERM), 2 bad input (config, ROS set-up),
    3 aborted (synthesis failed, or no safe input from the vessel's state).
    """
    from rich.console import Console

    from hil.adapters.ros import RosBackendError
    from hil.bag.errors import ReplayError
    from hil.core.config import ConfigError
    from hil.runs.vessel_run import VesselConfig, run_on_ros
    from hil.scenarios import ScenarioError

    def progress(line: str) -> None:
        print(f"hil vessel: {line}", file=sys.stderr, flush=True)

    try:
        config = VesselConfig.load(args.config)
        summary = run_on_ros(config, args.out, progress=progress)
    except (ConfigError, ScenarioError, RosBackendError, ReplayError) as err:
        print(f"hil vessel: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError as err:
        print(f"hil vessel: error: not enough memory for the scenario's grid ({err}): "
              "use a coarser [grid] cell_m or fewer heading_cells", file=sys.stderr)
        return EXIT_BAD_INPUT
    summary.render(Console(stderr=args.json))
    if summary.aborted:
        progress(f"aborted: {summary.end_reason} (log: {summary.log})")
    if args.json:
        print(summary.to_json())
    if summary.docked:
        return EXIT_DOCKED
    return EXIT_ABORTED if summary.aborted else EXIT_NOT_DOCKED
