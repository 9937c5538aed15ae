"""`hil vessel --config FILE`: the on-vessel entry point (ROS 2 backend, wall time).

Runs the full stack against the lab's topics, records the run, and on SIGINT or
SIGTERM sends zero thrust and closes the log before exiting. With `--check` it only
listens: a preflight of the feeds and the vessel's pose that moves nothing.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from hil.commands.common import (
    EXIT_ABORTED,
    EXIT_BAD_INPUT,
    EXIT_DOCKED,
    EXIT_NOT_DOCKED,
    live_rerun,
    missing_display,
    positive_seconds,
)

if TYPE_CHECKING:
    from hil.runs.vessel_config import VesselConfig

HELP = "run the stack on the vessel over ROS 2 (wall time), recorded; stops cleanly on SIGINT"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("--config", type=Path, default=None, metavar="FILE",
                        help="vessel config (TOML): scenario, [ros], [loop], runs_dir, [qtm] "
                        "(required unless --print-config)")
    parser.add_argument("--rerun", nargs="?", const="spawn", default=None, metavar="RRD",
                        help="stream the run live to Rerun: a spawned viewer, or into RRD")
    parser.add_argument("--print-config", action="store_true",
                        help="print every config key with its value (the defaults, or FILE's "
                        "with --config) and its meaning, as TOML, and exit")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="bag directory to create (default: under the config's runs_dir)")
    parser.add_argument("--json", action="store_true",
                        help="end with the summary as one JSON object on the last line")
    parser.add_argument("--check", action="store_true",
                        help="preflight: listen to the configured topics (no thrust is "
                        "commanded) and judge rate, jitter, latency, clock, frame id, NaN "
                        "share, QoS and the vessel's pose in the arena against the "
                        "guarantee's premises; exit 0 when all hold, 1 otherwise")
    parser.add_argument("--seconds", type=positive_seconds, default=None, metavar="S",
                        help="with --check: how long to listen (default 5 s)")


def run(args: argparse.Namespace) -> int:
    """Run until docked or stopped; exit status as in :mod:`hil.commands.common`.

    0 docked, 1 not docked (time limit, SIGINT/SIGTERM), 2 bad input (config, ROS set-up),
    3 aborted (synthesis failed, or no safe input from the vessel's state).
    """
    def progress(line: str) -> None:
        print(f"hil vessel: {line}", file=sys.stderr, flush=True)

    if args.rerun == "spawn" and (headless := missing_display()) is not None:
        print(f"hil vessel: error: --rerun needs a viewer window but there is {headless}: "
              "stream into a file instead (--rerun run.rrd)", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.seconds is not None and not args.check:
        print("hil vessel: error: --seconds needs --check", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.config is None and not args.print_config:
        print("hil vessel: error: the following arguments are required: --config FILE "
              "(or --print-config for every key with its default)", file=sys.stderr)
        return EXIT_BAD_INPUT
    if not args.print_config:  # the first line, before the stack's imports (seconds)
        progress(f"{'preflight' if args.check else 'run'} with {args.config}: loading the stack "
                 "(numpy, numba, rclpy) ...")
    from rich.console import Console

    from hil.adapters.ros import RosBackendError
    from hil.bag.errors import ReplayError
    from hil.core.config import ConfigError
    from hil.runs.vessel_config import VesselConfig, config_text
    from hil.scenarios import ScenarioError

    try:
        config = VesselConfig() if args.config is None else VesselConfig.load(args.config)
        config = config.with_ros_args(getattr(args, "ros_args", ()))
        if args.print_config:
            print(config_text(config), end="")
            return 0
        if args.check:
            return _check(config, 5.0 if args.seconds is None else args.seconds, progress)
        from hil.runs.vessel_run import run_on_ros  # the stack: seconds of imports

        live = None if args.rerun is None else live_rerun(args.rerun)
        summary = run_on_ros(config, args.out, progress=progress, live=live)
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


def _check(config: VesselConfig, seconds: float, progress: Callable[[str], None]) -> int:
    """Run the preflight, print one line per premise on stdout; 0 all hold, 1 otherwise."""
    from hil.runs.vessel_check import check_vessel

    report = check_vessel(config, seconds, progress)
    for line in report.lines:
        print(line.text(), flush=True)
    failed = sum(not line.ok for line in report.lines)
    progress(f"preflight {'passed' if report.ok else 'FAILED'}: {len(report.lines)} lines, "
             f"{failed} failed, listened {report.listened_s:.1f} s on {report.time_source}")
    return EXIT_DOCKED if report.ok else EXIT_NOT_DOCKED
