"""`hil judge LOG --truth FILE [--config VESSEL_TOML] [--json]`: the guarantee on outside truth.

Holds a recorded run (``hil vessel``'s bag) to the guarantee on a true trajectory that
something other than hil recorded beside it: an independent simulator
(``tools/independent_vessel.py``, a lab's own) or the tank's motion capture. The truth
file's format is :mod:`hil.replay.truth`'s; the vessel config gives the lab-to-arena
transform and the loop rate. Exit 0 when no promise is violated and every decision was
judged, 1 otherwise, 2 on bad input.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

from hil.commands.common import EXIT_BAD_INPUT
from hil.commands.stages import Stages

HELP = "judge a recorded run's decisions on a true trajectory recorded outside hil"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the command's arguments."""
    parser.add_argument("log", metavar="LOG", help="the run's bag directory")
    parser.add_argument("--truth", type=Path, required=True, metavar="FILE",
                        help="true states, CSV: t_ns and north_m, east_m, yaw_rad (world_ned) "
                             "or x_m, y_m, psi_rad (arena)")
    parser.add_argument("--config", type=Path, default=None, metavar="FILE",
                        help="the vessel config the run used ([ros.transform], [loop] loop_hz)")
    parser.add_argument("--json", action="store_true",
                        help="end with the verdict as one JSON object on the last line")


def run(args: argparse.Namespace) -> int:
    """Judge and print the counts; 0 no violation, 1 a violation or an unjudged decision."""
    Stages("hil judge").say(f"reading {args.log} and the truth {args.truth} ...")
    from hil.adapters.ros import RosConfig
    from hil.bag.errors import ReplayError
    from hil.core.config import ConfigError
    from hil.replay.truth import judge_log_on_truth, load_truth
    from hil.runs.vessel_config import VesselConfig
    from hil.scenarios import ScenarioError

    try:
        config = VesselConfig.load(args.config) if args.config is not None else None
        ros = config.ros if config is not None else RosConfig()
        tick_s = 1.0 / config.loop.loop_hz if config is not None else 0.05
        judged = judge_log_on_truth(args.log, load_truth(args.truth), ros.transform,
                                    tick_s=tick_s)
    except (ConfigError, ReplayError, ScenarioError) as err:
        print(f"hil judge: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    g = judged.violations
    lines = [
        f"decisions {g.decisions}, intervals judged {g.intervals}",
        f"tube exits {g.tube_exits} (worst {g.worst_tube_exit_m:.4f} m), successor misses "
        f"{g.successor_misses} (worst {g.worst_successor_miss_m:.4f} m, "
        f"{math.degrees(g.worst_heading_miss_rad):.2f} deg), value not decreasing "
        f"{g.value_not_decreasing}",
        f"centre in an inflated obstacle {g.inflated_obstacle}, hull contacts {g.hull_contacts} "
        f"(worst {g.worst_hull_penetration_m:.4f} m), hull outside the arena "
        f"{g.hull_outside_arena} (worst {g.worst_hull_outside_m:.4f} m)",
        f"premises: late intervals {g.late_intervals} (worst {g.worst_late_s:.2f} s), "
        f"estimation misses {g.estimation_misses} (worst {g.worst_estimation_m * 1000:.1f} mm)",
        f"received poses vs truth: {judged.pose_offset_m * 1000:.1f} mm, "
        f"{math.degrees(judged.heading_offset_rad):.2f} deg at worst",
        *(f"not judged: {line}" for line in judged.unjudged),
        f"verdict: {'PASS' if g.violations == 0 and not judged.unjudged else 'FAIL'}, "
        f"{g.violations} violation(s) on the true state",
    ]
    print("\n".join(lines), file=sys.stderr if args.json else sys.stdout)
    if args.json:
        print(json.dumps({**dataclasses.asdict(g), "violations": g.violations,
                          "unjudged": list(judged.unjudged),
                          "pose_offset_m": judged.pose_offset_m,
                          "heading_offset_rad": judged.heading_offset_rad}))
    return 0 if g.violations == 0 and not judged.unjudged else 1
