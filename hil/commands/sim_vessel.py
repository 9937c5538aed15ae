"""`hil sim-vessel [SCENARIO]`: the simulated vessel as a ROS 2 node on the lab's topics.

Publishes pose and IMU, applies thruster commands, and with `--clock` publishes
`/clock` so that a stack with `use_sim_time` runs faster than real time.
"""

from __future__ import annotations

import argparse
import signal
import sys
from dataclasses import replace
from pathlib import Path
from types import FrameType

from hil.commands.common import non_negative_int, positive_seconds, start_pose

HELP = "simulate the vessel as a ROS 2 node on the lab's topics (for DDS tests of the stack)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("scenario", nargs="?", default=None, metavar="SCENARIO",
                        help="scenario whose arena and obstacles to simulate (default: the "
                        "config's, else paper)")
    parser.add_argument("--config", type=Path, default=None, metavar="FILE",
                        help="a vessel config (as for hil vessel): publish on its [ros.topics] "
                        "in its pose frame, through its [ros.transform], on its domain")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="seed of the sensor noise")
    parser.add_argument("--start", type=start_pose, default=None, metavar="X,Y,PSI_DEG",
                        help="start pose (m, m, deg); default: right of the arena, bow up")
    parser.add_argument("--speed", type=float, default=1.0,
                        help="simulated seconds per wall second (needs --clock above 1)")
    parser.add_argument("--clock", action="store_true", help="publish /clock (ROS sim time)")
    parser.add_argument("--duration", type=positive_seconds, default=None, metavar="S",
                        help="stop after this many simulated seconds")
    parser.add_argument("--domain-id", type=int, default=None,
                        help="ROS_DOMAIN_ID to use (overrides the config's)")


def run(args: argparse.Namespace) -> int:
    """Simulate until SIGINT/SIGTERM or the duration; 2 on bad input."""
    # The first line, before the simulator's and rclpy's imports (a second or more).
    named = args.scenario or ("of the config" if args.config else "paper")
    print(f"hil sim-vessel: scenario {named}: loading the simulator and rclpy ...",
          file=sys.stderr, flush=True)
    from hil.adapters.ros import RosBackendError, check_domain_id
    from hil.adapters.sim import SimConfig, SimWorld
    from hil.core.config import ConfigError
    from hil.runs.ros_vessel import SimVesselNode
    from hil.runs.stack_assembly import default_start
    from hil.runs.vessel_config import VesselConfig
    from hil.runtime.assembly import layout_from_scenario
    from hil.scenarios import ScenarioError, check_start, load_scenario

    try:
        vessel = VesselConfig() if args.config is None else VesselConfig.load(args.config)
        vessel = vessel.with_ros_args(getattr(args, "ros_args", ()))
        scenario = load_scenario(args.scenario or (vessel.scenario if args.config else "paper"))
        start = default_start(scenario) if args.start is None else args.start
        check_start(scenario, *start)
        if args.domain_id is not None:
            check_domain_id(args.domain_id, "--domain-id")
        if args.speed != 1.0 and not args.clock:
            raise ValueError("--speed other than 1 needs --clock (the stack must follow /clock)")
        world = SimWorld(SimConfig(start=start, seed=args.seed,
                                   obstacles=layout_from_scenario(scenario).obstacles),
                         max_duration_s=args.duration + 10.0 if args.duration else 24 * 3600.0)
        domain = vessel.ros.domain_id if args.domain_id is None else args.domain_id
        ros = replace(vessel.ros, use_sim_time=args.clock, domain_id=domain)
        node = SimVesselNode(world, ros, speed=args.speed)
    except (ScenarioError, ConfigError, ValueError) as err:
        print(f"hil sim-vessel: error: {err}", file=sys.stderr)
        return 2

    def stop(signum: int, _frame: FrameType | None) -> None:
        node.stopped_by = signal.Signals(signum).name
        node.stop()

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    def progress(line: str) -> None:
        print(f"hil sim-vessel: {line}", file=sys.stderr, flush=True)

    try:
        node.run(args.duration, progress=progress)
        if node.stopped_by is not None:
            progress(f"stopped by {node.stopped_by}")
    except RosBackendError as err:
        print(f"hil sim-vessel: error: {err}", file=sys.stderr)
        return 2
    return 0
