"""How to replay: the checks' thresholds and the options of a replay.

Thresholds on the tracking error are in the units the paper prints (surge and
sway m/s, yaw deg/s); :mod:`hil.core.tracking` computes in SI and converts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.adapters.log import LogConfig
from hil.bag.lab_streams import LabTopics
from hil.core.tracking import AXES
from hil.runtime.settings import LoopConfig

_AXES = AXES


@dataclass(frozen=True, slots=True)
class Tolerance:
    """Thresholds of the checks.

    Attributes:
        rms: Tracking-error RMS thresholds (surge m/s, sway m/s, yaw deg/s), enforced
            (FAIL above); inf on an axis sets none, the default: the RMS is then a
            figure, reported beside the paper's tank figures.
        max_abs: Thresholds on the largest |error| per axis (same units); None
            checks none (inf on an axis skips it). Always enforced.
        relative: Allowed relative difference of tracking RMS and max between a
            re-run and the recording.
        estimate: Allowed difference of a re-run's estimates (m, rad, m/s, rad/s).
        command: Allowed difference of a re-run's thruster commands (normalized, rad).
        resim_position_m: Allowed distance between the re-simulated and the
            recorded trajectory (m).
    """

    rms: tuple[float, float, float] = (math.inf, math.inf, math.inf)
    max_abs: tuple[float, float, float] | None = None
    relative: float = 0.05
    estimate: float = 1e-6
    command: float = 1e-4
    resim_position_m: float = 0.05

    @property
    def enforce_rms(self) -> bool:
        """Whether an RMS threshold is set on any axis."""
        return any(math.isfinite(v) for v in self.rms)

    @staticmethod
    def parse(text: str) -> Tolerance:
        """Parse ``key=value`` pairs, comma separated.

        Keys: ``surge``, ``sway`` (m/s), ``yaw`` (deg/s) set enforced RMS
        thresholds (on that axis only); ``surge_max``, ``sway_max``, ``yaw_max`` thresholds on the
        largest error; ``rel``, ``estimate``, ``command`` and ``position``
        the fields of the same meaning.

        Raises:
            ValueError: An unknown key or a value that is not a number >= 0.
        """
        rms = [math.inf] * 3
        peak = [math.inf] * 3
        values: dict[str, Any] = {}
        keys = {
            "rel": "relative",
            "estimate": "estimate",
            "command": "command",
            "position": "resim_position_m",
        }
        for part in filter(None, (p.strip() for p in text.split(","))):
            key, sep, raw = part.partition("=")
            key = key.strip()
            try:
                value = float(raw)
            except ValueError:
                value = math.nan
            if not sep or not (value >= 0 and math.isfinite(value)):
                raise ValueError(f"tolerance {part!r} is not KEY=NUMBER with a number >= 0")
            if key in _AXES:
                rms[_AXES.index(key)] = value
            elif key.endswith("_max") and key[:-4] in _AXES:
                peak[_AXES.index(key[:-4])] = value
                values["max_abs"] = (peak[0], peak[1], peak[2])
            elif key in keys:
                values[keys[key]] = value
            else:
                raise ValueError(
                    f"unknown tolerance key {key!r}; use "
                    f"{[*_AXES, *(a + '_max' for a in _AXES), *keys]!r}"
                )
        return Tolerance(rms=(rms[0], rms[1], rms[2]), **values)


@dataclass(frozen=True)
class ReplayOptions:
    """How to replay.

    Attributes:
        tolerance: Thresholds.
        stack: Re-run the full stack on the recorded streams (open loop).
        resim: Re-simulate the run (closed loop).
        scenario: Replay with this scenario instead of the one the log names.
        log: Delivery delays of the recorded samples.
        cache_dir: Abstraction-table cache (None: the default).
        intervals: Also judge every interval between decisions
            (:mod:`hil.replay.intervals`; ``--jsonl``).
        lab: Where a lab bag's streams are and how its poses map to the arena
            (:func:`hil.replay.lab.lab_topics`); None: the lab's defaults.
        lab_loop: The loop a lab bag's stack re-run ticks at.
    """

    tolerance: Tolerance = field(default_factory=Tolerance)
    stack: bool = True
    resim: bool = False
    scenario: str | None = None
    log: LogConfig = field(default_factory=LogConfig)
    cache_dir: Path | None = None
    intervals: bool = False
    lab: LabTopics | None = None
    lab_loop: LoopConfig = field(default_factory=LoopConfig)
