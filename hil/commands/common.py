"""What several commands share: argument types, the display check, exit statuses.

Exit statuses of the commands that run the vessel (`hil run`, `hil vessel`):

- 0: docked;
- 1: not docked (time limit, stopped by a signal);
- 2: bad input, refused before anything moved (a one-line message names the value);
- 3: aborted: the run could not go on (synthesis failed, the start or the state has
  no safe input); the thrusters were zeroed and the log says why.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the CLI imports every command for --help: keep rerun out of it
    from hil.runs.sim_run import LiveView
    from hil.runtime.protocols import RunLog
    from hil.scenarios import Scenario

EXIT_DOCKED = 0
EXIT_NOT_DOCKED = 1
EXIT_BAD_INPUT = 2
EXIT_ABORTED = 3
EXIT_STOPPED = 130
"""A campaign stopped by Ctrl-C (128 + SIGINT, the shell's convention); its finished runs
are still reported."""
EXIT_CLUSTER_LOST = 3
"""A campaign whose Dask scheduler went away; its finished runs are reported and kept in
the results file (``--resume FILE`` continues it)."""

# A value such as "-1,-2,0": argparse takes it for an option unless written with "=".
_NUMBER_LIST = re.compile(r"^-\d*\.?\d+(e[-+]?\d+)?(,[-+]?\d*\.?\d*(e[-+]?\d+)?)+$", re.I)


def positive_seconds(text: str) -> float:
    """Parse a duration that must be a finite number of seconds above zero.

    Raises:
        argparse.ArgumentTypeError: Naming the value.
    """
    return _positive(text, "a positive number of seconds")


def positive_factor(text: str) -> float:
    """Parse a factor that must be a finite number above zero.

    Raises:
        argparse.ArgumentTypeError: Naming the value.
    """
    return _positive(text, "a positive factor")


def _positive(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"needs {what}, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    """Parse a whole number >= 0 (a seed).

    Raises:
        argparse.ArgumentTypeError: Naming the value and what is allowed.
    """
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"needs a whole number >= 0, got {text!r}")
    return value


def start_pose(text: str) -> tuple[float, float, float]:
    """Parse ``X,Y,PSI_DEG`` (m, m, deg) into (x m, y m, psi rad).

    Raises:
        argparse.ArgumentTypeError: Not three finite numbers.
    """
    try:
        x, y, psi = (float(v) for v in text.split(","))
    except ValueError as err:
        raise argparse.ArgumentTypeError(
            f"needs X,Y,PSI in metres and degrees, got {text!r}") from err
    if not all(math.isfinite(v) for v in (x, y, psi)):
        raise argparse.ArgumentTypeError(f"needs finite X,Y,PSI, got {text!r}")
    return (x, y, math.radians(psi))


def join_negative_values(argv: Sequence[str]) -> list[str]:
    """Return `argv` with ``--opt -1,-2,0`` joined to ``--opt=-1,-2,0``.

    argparse reads a value that starts with "-" and is not a plain number as an
    option; a comma-separated list of numbers never is one here.
    """
    out: list[str] = []
    for arg in argv:
        if (out and out[-1].startswith("--") and "=" not in out[-1]
                and _NUMBER_LIST.match(arg)):
            out[-1] = f"{out[-1]}={arg}"
        else:
            out.append(arg)
    return out


def missing_display() -> str | None:
    """Return why no viewer window can open here (Linux without a display), else None."""
    if not sys.platform.startswith("linux"):
        return None
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return None
    return "no display (DISPLAY and WAYLAND_DISPLAY are unset)"


def live_rerun(target: str) -> LiveView:
    """Return the live view that streams a run to a spawned viewer ("spawn") or an .rrd path."""
    from hil.views.rerun_live import LiveRerunLog  # rerun only when asked for

    save = None if target == "spawn" else Path(target)

    def live(scenario: Scenario, inner: RunLog) -> RunLog:
        return LiveRerunLog.open(scenario, spawn=save is None, save=save, inner=inner)

    return live
