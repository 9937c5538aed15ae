"""`hil inspect LOG [-o run.rrd] [--spawn]`: look at a recorded run in Rerun.

Converts a run to an ``.rrd`` file (or streams it to a new viewer with
``--spawn``): the arena top-down with the real and inflated obstacles, the
targets, the hull at every pose and the trajectory; the controller's view at
each decision (safe inputs as predicted arcs, the chosen one, the winning set at
the current heading cell, re-synthesized for the recorded layout); and the time
series (velocity tracking, tracking error against the velocity envelope, thrusters, value,
synthesis time, events), laid out by a blueprint. Never modifies the log. A log
that cannot be read gets a one-line error on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hil.commands.lab_args import add_lab_arguments, load_for_view
from hil.commands.stages import Stages

HELP = "Open a recorded run in Rerun (write an .rrd, or --spawn the viewer)."

_PROG = "hil inspect"
DEFAULT_BUDGET_S = 3.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare `LOG`, `-o/--output`, `--spawn` and `--no-winning-set`."""
    parser.add_argument("log", metavar="LOG", help="bag directory, or a .mcap file")
    parser.add_argument(
        "-o",
        "--output",
        metavar="RRD",
        type=Path,
        default=None,
        help="the .rrd file to write (default: LOG's name with .rrd, in the current directory)",
    )
    parser.add_argument(
        "--spawn",
        action="store_true",
        help="open the Rerun viewer and stream the run to it (writes no file unless -o is given)",
    )
    parser.add_argument(
        "--synthesis-budget",
        type=float,
        default=DEFAULT_BUDGET_S,
        metavar="S",
        help=f"seconds allowed for re-synthesizing the winning set (default {DEFAULT_BUDGET_S:g}); "
        "a run whose obstacles keep moving has one layout per decision",
    )
    parser.add_argument(
        "--no-winning-set",
        action="store_true",
        help="leave out the winning set (skips re-synthesizing the controller)",
    )
    add_lab_arguments(parser)


def default_output(log: Path) -> Path:
    """Return ``<LOG name>.rrd`` in the current directory."""
    name = log.resolve().name
    return Path(f"{Path(name).stem if log.suffix == '.mcap' else name}.rrd")


def _inside(path: Path, log: Path) -> bool:
    """Return True when writing `path` would touch the log."""
    out, src = path.resolve(), log.resolve()
    return out == src or (src.is_dir() and src in out.parents)


def _error(message: str) -> int:
    print(f"{_PROG}: error: {message}", file=sys.stderr)
    return 2


def _note(message: str) -> None:
    print(f"{_PROG}: note: {message}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Convert or show `args.log`.

    Returns:
        0 on success; 2 when the log cannot be read or the output not written.
    """
    stages = Stages(_PROG, stream=sys.stdout)
    stages.say(f"reading {args.log} ...")
    from hil.bag.errors import ReplayError
    from hil.commands.common import missing_display

    log = Path(args.log)
    headless = missing_display() if args.spawn else None
    if headless is not None:
        return _error(f"--spawn needs a viewer window but there is {headless}: "
                      f"write a recording with -o run.rrd and open it where there is a screen "
                      f"(rerun run.rrd)")
    output: Path | None = args.output
    if output is None and not args.spawn:
        output = default_output(log)
    if output is not None and log.exists() and _inside(output, log):
        return _error(f"output {str(output)!r} would write into the log {str(log)!r}")
    try:
        data, scenario, notes = load_for_view(log, args.scenario, args.config)
    except (ReplayError, ValueError) as err:
        return _error(str(err).splitlines()[0] if str(err) else type(err).__name__)
    for note in notes:  # damaged files, repairs, what a lab bag's reading assumed
        _note(note)
    from hil.views.controller_view import controller_view

    stages.say(
        f"read {len(data.decisions)} decisions, {len(data.layouts)} obstacle layout(s), "
        f"scenario {scenario.name if scenario is not None else 'unknown'}"
    )
    view = None
    if scenario is not None and not args.no_winning_set:
        with stages.stage(
            f"re-synthesizing the winning set for {len(data.layouts)} layout(s) "
            f"(budget {args.synthesis_budget:g} s; solved layouts come from the store)"
        ):
            view = controller_view(data, scenario, budget_s=args.synthesis_budget)
        if view.note:
            _note(view.note)
    from hil.views import rerun_export

    try:
        if output is not None:
            with stages.stage(f"writing {output}"):
                stats = rerun_export.write_rrd(data, output, scenario, view)
            print(
                f"wrote {output} ({stats.bytes / 1e6:.2f} MB, {stats.rows} rows, "
                f"{len(data.decisions)} decisions) in {stages.total_s():.2f} s "
                f"(writing {stats.seconds:.2f} s)"
            )
        if args.spawn:
            with stages.stage("streaming the run to the Rerun viewer"):
                rerun_export.spawn_viewer(data, scenario, view)
    except (rerun_export.ViewerError, rerun_export.RrdWriteError) as err:
        return _error(str(err))
    except OSError as err:
        return _error(f"cannot write {str(output)!r}: {err.strerror or err}")
    return 0
