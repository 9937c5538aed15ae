"""`hil vessel --config FILE`: the on-vessel entry point (ROS 2 backend, wall time).

Runs the full stack against the lab's topics, records the run, and on SIGINT or
SIGTERM sends zero thrust and closes the log before exiting.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

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
    """Run until docked or stopped; exit 0 when docked, 1 when not, 2 on bad input."""
    from rich.console import Console

    from hil.adapters.ros import RosBackendError
    from hil.bag.errors import ReplayError
    from hil.core.config import ConfigError
    from hil.runs.vessel_run import VesselConfig, run_on_ros
    from hil.scenarios import ScenarioError

    try:
        config = VesselConfig.load(args.config)
        summary = run_on_ros(config, args.out)
    except (ConfigError, ScenarioError, RosBackendError, ReplayError) as err:
        print(f"hil vessel: {err}", file=sys.stderr)
        return 2
    summary.render(Console(stderr=args.json))
    if args.json:
        print(summary.to_json())
    return 0 if summary.docked else 1
