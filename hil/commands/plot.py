"""`hil plot LOG -o run.png`: a one-page picture of a recorded run.

The arena with obstacles, targets, trajectory and hull outlines, beside velocity
tracking per axis (like the paper's Fig. 6-8). Never modifies the log. A log that
cannot be read gets a one-line error on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hil.commands.lab_args import add_lab_arguments, load_for_view
from hil.commands.stages import Stages

HELP = "Draw a recorded run: arena with trajectory and hull, velocity tracking (PNG)."

_PROG = "hil plot"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare `LOG`, `-o/--output`, `--dpi` and `--hull-every`."""
    parser.add_argument("log", metavar="LOG", help="bag directory, or a .mcap file")
    parser.add_argument(
        "-o", "--output", metavar="PNG", type=Path, required=True, help="the PNG file to write"
    )
    parser.add_argument(
        "--dpi",
        type=int,
        default=None,
        help="pixels per inch (default 110: a 1430 x 715 px picture)",
    )
    parser.add_argument(
        "--hull-every",
        type=float,
        default=None,
        metavar="S",
        help="seconds between two hull outlines (default 5)",
    )
    add_lab_arguments(parser)


def _error(message: str) -> int:
    print(f"{_PROG}: error: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    """Draw `args.log` into `args.output`.

    Returns:
        0 on success; 2 when the log cannot be read or the picture not written.
    """
    stages = Stages(_PROG, stream=sys.stdout)
    stages.say(f"reading {args.log} ...")
    from hil.bag.errors import ReplayError

    log, output = Path(args.log), Path(args.output)
    if output.suffix.lower() != ".png":
        return _error(f"output {str(output)!r} must end in .png")
    if log.exists() and (
        output.resolve() == log.resolve()
        or (log.is_dir() and log.resolve() in output.resolve().parents)
    ):
        return _error(f"output {str(output)!r} would write into the log {str(log)!r}")
    if args.dpi is not None and not 20 <= args.dpi <= 600:
        return _error(f"--dpi must be in [20, 600], got {args.dpi!r}")
    if args.hull_every is not None and not args.hull_every > 0:
        return _error(f"--hull-every must be positive, got {args.hull_every!r}")
    try:
        data, scenario, notes = load_for_view(log, args.scenario, args.config)
    except (ReplayError, ValueError) as err:
        return _error(str(err).splitlines()[0] if str(err) else type(err).__name__)
    from hil.views.plot import DEFAULT_DPI, HULL_EVERY_S, save_run_figure

    for note in notes:  # damaged files, repairs, what a lab bag's reading assumed
        print(f"{_PROG}: note: {note}", file=sys.stderr)
    try:
        with stages.stage(f"drawing {output}"):
            save_run_figure(
                data,
                scenario,
                output,
                dpi=args.dpi or DEFAULT_DPI,
                hull_every_s=args.hull_every or HULL_EVERY_S,
            )
    except OSError as err:
        return _error(f"cannot write {str(output)!r}: {err.strerror or err}")
    print(f"wrote {output} in {stages.total_s():.2f} s")
    return 0
