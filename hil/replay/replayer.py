"""Replay a recorded run through the current code and compare it with the recording.

Open loop (default), four checks:

- ``decisions``: at every recorded decision, the controller for the recorded
  obstacle layout is synthesized anew with the current code (one per distinct
  layout, cached) and queried at the recorded estimated state: cell, winning
  status, value, safe-input set and the input the paper's J picks given the
  previous recorded choice. Any difference is a regression.
- ``tracking``: velocity-tracking error per axis (RMS, max) of the recorded
  estimates (odometry) against the recorded references, against thresholds
  (default the paper's tank figures, advisory unless ``--tolerance`` sets them).
- ``margin``: the guarantee's assumption, that the tracking error stayed within
  the margin the controller was synthesized for; says where it did not (WARN).
- ``stack``: the full stack (observer, decisions, PID, allocation) re-run by
  :class:`hil.runtime.loop.Runtime` on the recorded sensor and obstacle streams
  through the ``log`` adapters; its estimates, decisions, references, thruster
  commands and tracking error must reproduce the recording.

Closed loop (``resim``): the recorded scenario, seed and start (from the suite
manifest beside the log when there is one, else the first recorded pose) are
simulated again with the current code and the trajectory, decisions and
tracking error compared with the recording.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hil.adapters.interfaces import ThrusterSinkError
from hil.adapters.log import LogConfig, LogWorld, RecordedRun, Stream, read_log
from hil.bag.errors import ReplayError
from hil.controllers.symbolic import NoWinningSetError, SymbolicError, Synthesizer
from hil.core.geometry import wrap_angles
from hil.core.records import Decision
from hil.core.samples import ObstacleLayout, ThrusterCommand
from hil.core.shapes import Rect
from hil.replay.regression import Check, Finding, LogReport, Status, time_s
from hil.runs.sim_run import (
    SimRunSpec,
    build_runtime,
    run_in_sim,
    scenario_hash,
    spec_from_json,
    synthesizer_for,
)
from hil.runs.summary import PAPER_TRACKING_ERROR
from hil.runtime.assembly import LayoutSolver, SymbolicAdapter, select_index
from hil.runtime.loop import Mode, World
from hil.runtime.resynthesis import ResynthesisMode, Resynthesizer
from hil.runtime.settings import LoopConfig
from hil.runtime.stack import SymbolicController
from hil.runtime.trace import MemoryLog
from hil.scenarios import Scenario, ScenarioError, load_scenario

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
NS_PER_S = 1_000_000_000
MANIFEST = "suite.json"
"""File beside a suite's logs that holds each run's full specification (start, faults)."""

_AXES = ("surge", "sway", "yaw")
_UNITS = ("m/s", "m/s", "deg/s")
_READY = re.compile(r"controller v(\d+)\b")


class ScenarioMismatchError(ReplayError, ValueError):
    """The log was recorded for another scenario than the one it would be replayed with."""


# ------------------------------------------------------------------ options


@dataclass(frozen=True, slots=True)
class Tolerance:
    """Thresholds of the checks.

    Attributes:
        rms: Tracking-error RMS thresholds (surge m/s, sway m/s, yaw deg/s);
            default the paper's tank figures.
        enforce_rms: Whether exceeding `rms` fails (True when set explicitly)
            or only warns.
        max_abs: Thresholds on the largest |error| per axis (same units); None
            checks none (inf on an axis skips it). Always enforced.
        relative: Allowed relative difference of tracking RMS and max between a
            re-run and the recording.
        estimate: Allowed difference of a re-run's estimates (m, rad, m/s, rad/s).
        command: Allowed difference of a re-run's thruster commands (normalized, rad).
        resim_position_m: Allowed distance between the re-simulated and the
            recorded trajectory (m).
        settle_s: The margin check skips this long after each decision (s): the
            transient after a reference step is the paper's assumption (1), not
            covered by the margin, which is measured after settling.
    """

    rms: tuple[float, float, float] = PAPER_TRACKING_ERROR
    enforce_rms: bool = False
    max_abs: tuple[float, float, float] | None = None
    relative: float = 0.05
    estimate: float = 1e-6
    command: float = 1e-4
    resim_position_m: float = 0.05
    settle_s: float = 1.0

    @staticmethod
    def parse(text: str) -> Tolerance:
        """Parse ``key=value`` pairs, comma separated.

        Keys: ``surge``, ``sway`` (m/s), ``yaw`` (deg/s) set enforced RMS
        thresholds; ``surge_max``, ``sway_max``, ``yaw_max`` thresholds on the
        largest error; ``rel``, ``estimate``, ``command``, ``position`` and
        ``settle`` the fields of the same meaning.

        Raises:
            ValueError: An unknown key or a value that is not a number >= 0.
        """
        rms = list(PAPER_TRACKING_ERROR)
        peak = [math.inf] * 3
        values: dict[str, Any] = {}
        keys = {
            "rel": "relative",
            "estimate": "estimate",
            "command": "command",
            "position": "resim_position_m",
            "settle": "settle_s",
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
                values["enforce_rms"] = True
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
    """

    tolerance: Tolerance = field(default_factory=Tolerance)
    stack: bool = True
    resim: bool = False
    scenario: str | None = None
    log: LogConfig = field(default_factory=LogConfig)
    cache_dir: Path | None = None


# ------------------------------------------------------------------ controllers


class ControllerCache:
    """One controller per distinct obstacle layout, synthesized with the current code.

    Callable as a solver for :class:`hil.runtime.resynthesis.Resynthesizer`.

    Args:
        scenario: The scenario (grid, inputs, target, inflation).
        cache_dir: Abstraction-table cache.
    """

    def __init__(self, scenario: Scenario, cache_dir: Path | None = None) -> None:
        self.scenario = scenario
        self._solver = LayoutSolver(scenario, synthesizer_for(scenario, cache_dir))
        self._done: dict[tuple[Rect, ...], SymbolicAdapter | NoWinningSetError] = {}
        self.syntheses = 0

    @property
    def synthesizer(self) -> Synthesizer:
        """The synthesizer holding the scenario grid's abstraction tables."""
        return self._solver.synthesizer

    def __call__(self, layout: ObstacleLayout) -> SymbolicAdapter:
        """Return the controller for `layout`.

        Raises:
            NoWinningSetError: The layout leaves no winning set.
        """
        got = self._done.get(layout.obstacles)
        if got is None:
            self.syntheses += 1
            try:
                got = self._solver(layout)
            except NoWinningSetError as err:
                got = err
            self._done[layout.obstacles] = got
        if isinstance(got, NoWinningSetError):
            raise got
        return got


class ScenarioCache:
    """Controller caches keyed by scenario hash, shared by the logs of one replay."""

    def __init__(self, cache_dir: Path | None = None) -> None:
        self._cache_dir = cache_dir
        self._caches: dict[str, ControllerCache] = {}

    def get(self, scenario: Scenario) -> ControllerCache:
        """Return the cache of `scenario`, created on first use."""
        key = scenario_hash(scenario)
        if key not in self._caches:
            self._caches[key] = ControllerCache(scenario, self._cache_dir)
        return self._caches[key]


def resolve_scenario(run: RecordedRun, override: str | None = None) -> Scenario:
    """Return the scenario the log was recorded with, checked by its hash.

    Raises:
        ScenarioMismatchError: The log names no scenario, names one that cannot be
            loaded, or was recorded for another scenario content.
    """
    info = run.info.run
    recorded_hash = info.scenario_hash if info is not None else ""
    hashes = {d.scenario_hash for d in run.decisions}
    if not recorded_hash and len(hashes) == 1:
        recorded_hash = next(iter(hashes))
    name = override or (info.scenario_file if info is not None else "")
    if not name:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} names no scenario (no hil metadata); pass --scenario"
        )
    try:
        scenario = load_scenario(name)
    except ScenarioError as err:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} was recorded with scenario {name!r}, which cannot be loaded: {err}"
        ) from err
    current = scenario_hash(scenario)
    if recorded_hash and current != recorded_hash:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} was recorded for scenario hash {recorded_hash!r}, but "
            f"{name!r} now hashes to {current!r}: a log from another scenario (or the scenario "
            "changed; regenerate the suite with `hil record-suite`)"
        )
    if len(hashes) > 1:
        raise ScenarioMismatchError(
            f"{str(run.path)!r} mixes decisions of scenarios {sorted(hashes)!r}"
        )
    return scenario


# ------------------------------------------------------------------ decisions


@dataclass(frozen=True, slots=True)
class Recomputed:
    """A decision recomputed with the current code at a recorded state.

    Attributes:
        cell: Flat cell index (-1 outside the grid).
        value: Value at the state (+inf outside the winning set).
        safe: Input-grid indices of the safe inputs, sorted.
        chosen: Input-grid index of the chosen input, -1 for none.
    """

    cell: int
    value: float
    safe: tuple[int, ...]
    chosen: int

    @property
    def winning(self) -> bool:
        """Whether the state is in the winning set."""
        return math.isfinite(self.value)


def recompute(
    controller: SymbolicController, state: FloatArray, previous: FloatArray
) -> Recomputed:
    """Take the runtime's decision at `state` (3,) given the previous choice (3,).

    Mirrors :meth:`hil.runtime.loop.Runtime._decide`: no input in the target
    (value 0) or outside the winning set (value inf).
    """
    cell = controller.locate(state)
    value = controller.value(state)
    if value == 0.0 or math.isinf(value):
        return Recomputed(cell, value, (), -1)
    indices = controller.safe_input_indices(state)
    chosen = -1
    if indices.size:
        chosen = int(indices[select_index(controller.inputs[indices], previous)])
    return Recomputed(cell, value, tuple(sorted(int(i) for i in indices)), chosen)


def _version_times(run: RecordedRun) -> dict[int, int]:
    """Return when each controller version was swapped in (ns), from the events."""
    out: dict[int, int] = {}
    for event in run.events:
        match = _READY.match(event.text) if event.code == "controller_ready" else None
        if match:
            out.setdefault(int(match.group(1)), event.t_ns)
    return out


def layout_at(run: RecordedRun, t_ns: int) -> ObstacleLayout | None:
    """Return the newest recorded layout stamped at or before `t_ns`."""
    best: ObstacleLayout | None = None
    for layout in run.layouts:
        if layout.t_ns <= t_ns and (best is None or layout.t_ns >= best.t_ns):
            best = layout
    return best


def _inputs(controller: SymbolicController, indices: tuple[int, ...]) -> list[list[float]]:
    return [[round(float(v), 6) for v in controller.inputs[i]] for i in indices]


def _mismatch(d: Decision, got: Recomputed, controller: SymbolicController) -> Finding | None:
    recorded_safe = tuple(sorted(d.safe_input_indices))
    fields = [
        name
        for name, same in (
            ("cell", d.cell == got.cell),
            ("winning", d.winning == got.winning),
            ("value", d.value == got.value),
            ("safe set", recorded_safe == got.safe),
            ("chosen input", d.chosen_index == got.chosen),
        )
        if not same
    ]
    if not fields:
        return None
    only_rec = sorted(set(recorded_safe) - set(got.safe))
    only_new = sorted(set(got.safe) - set(recorded_safe))
    state = [round(v, 4) for v in d.state]
    message = (
        f"{', '.join(fields)} differ at state {state}: recorded chosen {d.chosen_index} "
        f"{list(d.chosen_input)} value {d.value}, replayed chosen {got.chosen}"
        f"{_inputs(controller, (got.chosen,)) if got.chosen >= 0 else ''} value {got.value}; "
        f"safe set recorded {len(recorded_safe)}, replayed {len(got.safe)} "
        f"(only recorded {only_rec[:8]}, only replayed {only_new[:8]})"
    )
    return Finding(
        message,
        d.t_ns,
        {
            "fields": fields,
            "state": list(d.state),
            "recorded": {
                "cell": d.cell,
                "value": d.value,
                "winning": d.winning,
                "safe": list(recorded_safe),
                "chosen": d.chosen_index,
                "chosen_input": list(d.chosen_input),
            },
            "replayed": {
                "cell": got.cell,
                "value": got.value,
                "winning": got.winning,
                "safe": list(got.safe),
                "chosen": got.chosen,
                "safe_inputs": _inputs(controller, got.safe),
            },
        },
    )


def _recomputed(
    run: RecordedRun, controllers: ControllerCache
) -> Iterator[tuple[Decision, Recomputed | str, SymbolicAdapter | None]]:
    """Yield each recorded decision with its recomputation (or why there is none)."""
    ready = _version_times(run)
    previous = np.zeros(3)
    for d in run.decisions:
        layout = layout_at(run, ready.get(d.controller_version, d.t_ns))
        if layout is None:
            yield d, "no obstacle layout recorded before this decision", None
            continue
        try:
            controller = controllers(layout)
        except NoWinningSetError as err:
            yield d, f"recorded a decision, but now: {err}", None
            continue
        yield d, recompute(controller, np.array(d.state), previous), controller
        if d.chosen_index >= 0:
            previous = np.array(d.chosen_input)


def replayed_decisions(run: RecordedRun, controllers: ControllerCache) -> list[Decision]:
    """Return the decisions the current code takes at the recorded states, in order.

    A decision that cannot be recomputed (no layout, no winning set) comes back
    with no safe input and no choice, so it shows as different.
    """
    out = []
    for d, got, controller in _recomputed(run, controllers):
        if isinstance(got, str) or controller is None:
            out.append(Decision.from_arrays(d.t_ns, d.state, -1, math.inf, False, np.zeros((0, 3)),
                                            np.zeros(0, dtype=np.int64), -1, d.controller_version,
                                            d.scenario_hash))
            continue
        safe = np.array(got.safe, dtype=np.int64)
        out.append(Decision.from_arrays(
            d.t_ns, d.state, got.cell, got.value, got.winning, controller.inputs[safe], safe,
            got.chosen, d.controller_version, d.scenario_hash,
            chosen_input=controller.inputs[got.chosen] if got.chosen >= 0 else np.zeros(3)))
    return out


def check_decisions(run: RecordedRun, controllers: ControllerCache) -> Check:
    """Recompute every recorded decision at its recorded state (see module docstring)."""
    if not run.decisions:
        return Check("decisions", Status.SKIP, "the log holds no decisions")
    findings: list[Finding] = []
    before = controllers.syntheses
    for d, got, controller in _recomputed(run, controllers):
        if isinstance(got, str) or controller is None:
            findings.append(Finding(str(got), d.t_ns))
            continue
        found = _mismatch(d, got, controller)
        if found is not None:
            findings.append(found)
    n = len(run.decisions)
    synth = controllers.syntheses - before
    metrics = {"decisions": n, "mismatches": len(findings), "syntheses": synth}
    if findings:
        return Check(
            "decisions",
            Status.FAIL,
            f"{len(findings)} of {n} decisions differ, first at {time_s(findings[0].t_ns)}",
            tuple(findings),
            metrics,
        )
    return Check(
        "decisions", Status.PASS, f"{n} decisions reproduced ({synth} new syntheses)", (), metrics
    )


# ------------------------------------------------------------------ tracking


@dataclass(frozen=True, slots=True)
class TrackingSeries:
    """Per-sample tracking error nu_hat - nu_ref.

    Attributes:
        t_ns: Times (ns), shape (N,).
        error: Errors (surge m/s, sway m/s, yaw deg/s), shape (N, 3).
    """

    t_ns: IntArray
    error: FloatArray

    @staticmethod
    def between(estimates: Stream, references: Stream) -> TrackingSeries:
        """Join estimates (N, 6) and references (M, 3) on their stamps."""
        t, i, j = np.intersect1d(estimates.t_ns, references.t_ns, return_indices=True)
        err = estimates.values[i, 3:6] - references.values[j]
        err[:, 2] = np.degrees(err[:, 2])
        return TrackingSeries(t.astype(np.int64), err)

    def rms(self) -> FloatArray:
        """RMS per axis, shape (3,); NaN without samples."""
        if not len(self.t_ns):
            return np.full(3, math.nan)
        return np.asarray(np.sqrt(np.mean(self.error**2, axis=0)), dtype=np.float64)

    def peak(self) -> tuple[FloatArray, IntArray]:
        """Largest |error| per axis (3,) and when it occurred (ns) (3,)."""
        if not len(self.t_ns):
            return np.full(3, math.nan), np.zeros(3, np.int64)
        k = np.argmax(np.abs(self.error), axis=0)
        return np.abs(self.error[k, [0, 1, 2]]), self.t_ns[k]

    def metrics(self) -> dict[str, Any]:
        """Return RMS, max and time of max per axis, JSON-ready."""
        peak, when = self.peak()
        return {
            "samples": len(self.t_ns),
            "rms": [float(v) for v in self.rms()],
            "max_abs": [float(v) for v in peak],
            "t_max_ns": [int(v) for v in when],
        }


def _axes_text(values: FloatArray) -> str:
    return ", ".join(f"{a} {v:.5f} {u}" for a, v, u in zip(_AXES, values, _UNITS, strict=True))


def check_tracking(run: RecordedRun, tolerance: Tolerance) -> Check:
    """Compare the recorded tracking error's RMS per axis with the thresholds."""
    series = TrackingSeries.between(run.estimates, run.references)
    if not len(series.t_ns):
        return Check("tracking", Status.SKIP, "no velocity references with estimates")
    rms = series.rms()
    peak, when = series.peak()
    limit = np.array(tolerance.rms)
    over = [k for k in range(3) if rms[k] > limit[k]]
    findings = [
        Finding(
            f"{_AXES[k]} RMS {rms[k]:.5f} {_UNITS[k]} > threshold {limit[k]:.5f}; "
            f"largest error {peak[k]:.4f} {_UNITS[k]}",
            int(when[k]),
            {
                "axis": _AXES[k],
                "rms": float(rms[k]),
                "threshold": float(limit[k]),
                "max_abs": float(peak[k]),
            },
        )
        for k in over
    ]
    peak_limit = np.array(tolerance.max_abs if tolerance.max_abs is not None else [math.inf] * 3)
    over_peak = [k for k in range(3) if peak[k] > peak_limit[k]]
    findings += [
        Finding(
            f"{_AXES[k]} error {peak[k]:.4f} {_UNITS[k]} > max threshold {peak_limit[k]:.4f}",
            int(when[k]),
            {"axis": _AXES[k], "max_abs": float(peak[k]), "threshold": float(peak_limit[k])},
        )
        for k in over_peak
    ]
    source = "" if tolerance.enforce_rms else " (the paper's tank figures, advisory)"
    text = f"RMS {_axes_text(rms)}; max {_axes_text(peak)}"
    metrics = {
        **series.metrics(),
        "threshold_rms": list(tolerance.rms),
        "threshold_max_abs": [float(v) for v in peak_limit],
    }
    if not findings:
        return Check("tracking", Status.PASS, f"{text}; within thresholds{source}", (), metrics)
    status = Status.FAIL if tolerance.enforce_rms or over_peak else Status.WARN
    axes = ", ".join(sorted({_AXES[k] for k in [*over, *over_peak]}, key=_AXES.index))
    return Check(
        "tracking", status, f"{text}; above threshold{source} in {axes}", tuple(findings), metrics
    )


def _spans(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Return [start, stop) index spans where `mask` is True."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(
        zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True)
    )


def check_margin(run: RecordedRun, scenario: Scenario, settle_s: float = 1.0) -> Check:
    """Re-check the guarantee's assumption: |nu - nu_ref| within the scenario's margin.

    Samples less than `settle_s` after a decision are not checked (the step
    transient; see :class:`Tolerance`).
    """
    series = TrackingSeries.between(run.estimates, run.references)
    if not len(series.t_ns):
        return Check("margin", Status.SKIP, "no velocity references with estimates")
    margin = scenario.margin.as_array().copy()
    margin[2] = math.degrees(margin[2])
    decided = np.array([d.t_ns for d in run.decisions], dtype=np.int64)
    last = np.searchsorted(decided, series.t_ns, side="right") - 1
    since_ns = series.t_ns - np.where(last >= 0, decided[np.maximum(last, 0)], 0)
    settled = since_ns >= round(settle_s * NS_PER_S)
    over = (np.abs(series.error) > margin) & settled[:, None]
    findings: list[Finding] = []
    for k in range(3):
        for start, stop in _spans(over[:, k])[:3]:
            worst = float(np.abs(series.error[start:stop, k]).max())
            findings.append(
                Finding(
                    f"{_AXES[k]} error up to {worst:.4f} {_UNITS[k]} > margin {margin[k]:.4f} "
                    f"until {time_s(int(series.t_ns[stop - 1]))}",
                    int(series.t_ns[start]),
                    {
                        "axis": _AXES[k],
                        "max_abs": worst,
                        "margin": float(margin[k]),
                        "until_ns": int(series.t_ns[stop - 1]),
                    },
                )
            )
    findings.sort(key=lambda f: f.t_ns or 0)
    share = over.sum(axis=0) / max(1, int(settled.sum()))
    metrics = {
        "margin": [float(v) for v in margin],
        "settle_s": settle_s,
        "samples_checked": int(settled.sum()),
        "share_outside": [float(v) for v in share],
    }
    if not over.any():
        return Check(
            "margin",
            Status.PASS,
            f"tracking error within the margin {_axes_text(margin)} "
            f"from {settle_s:g} s after each decision on",
            (),
            metrics,
        )
    note = " (zero margin: the paper's assumption of perfect tracking)" if not margin.any() else ""
    outside = ", ".join(f"{a} {100 * s:.0f}%" for a, s in zip(_AXES, share, strict=True))
    return Check(
        "margin",
        Status.WARN,
        f"tracking error outside the synthesized margin{note} on {outside} of the "
        f"samples {settle_s:g} s or more after a decision; the guarantee does not "
        "cover those spans",
        tuple(findings),
        metrics,
    )


# ------------------------------------------------------------------ stack re-run


def tick_times(run: RecordedRun) -> IntArray:
    """Return the loop's tick times in the recording (ns), sorted.

    Every tick sends a thruster command (zero while waiting or holding) or logs
    that the link failed, so the ticks are the command times and failure times.
    """
    failures = np.array(sorted(run.thruster_failures_ns()), dtype=np.int64)
    return np.unique(np.concatenate([run.thrusters.t_ns, failures]))


def _infer_loop(run: RecordedRun) -> LoopConfig:
    """Return the loop timing the recording shows (defaults where it does not)."""
    loop_hz = LoopConfig().loop_hz
    if len(run.estimates) > 2:
        dt = float(np.median(np.diff(run.estimates.t_ns))) / NS_PER_S
        if dt > 0:
            loop_hz = round(1.0 / dt, 6)
    # Stop at the recording's last sample: a truncated log ends there too.
    return LoopConfig(loop_hz=loop_hz, max_duration_s=max(run.end_ns / NS_PER_S, 1e-3))


def _compare_streams(
    name: str,
    recorded: Stream,
    t_ns: IntArray,
    values: FloatArray,
    tol: float,
    angle_columns: tuple[int, ...] = (),
) -> list[Finding]:
    findings: list[Finding] = []
    t, i, j = np.intersect1d(recorded.t_ns, t_ns, return_indices=True)
    missing = np.setdiff1d(recorded.t_ns, t_ns)
    extra = np.setdiff1d(t_ns, recorded.t_ns)
    if missing.size:
        findings.append(
            Finding(
                f"{name}: {missing.size} recorded sample(s) not reproduced",
                int(missing[0]),
                {"count": int(missing.size)},
            )
        )
    if extra.size:
        findings.append(
            Finding(
                f"{name}: {extra.size} sample(s) the recording does not have",
                int(extra[0]),
                {"count": int(extra.size)},
            )
        )
    if t.size:
        diff = values[j] - recorded.values[i]
        for c in angle_columns:
            diff[:, c] = wrap_angles(diff[:, c])
        err = np.abs(diff).max(axis=1)
        bad = np.flatnonzero(err > tol)
        if bad.size:
            k = int(bad[0])
            findings.append(
                Finding(
                    f"{name}: {bad.size} sample(s) differ by more than {tol:g}, largest "
                    f"{float(err.max()):.3g}; first: recorded "
                    f"{np.round(recorded.values[i[k]], 5).tolist()}, replayed "
                    f"{np.round(values[j[k]], 5).tolist()}",
                    int(t[k]),
                    {"count": int(bad.size), "max_diff": float(err.max())},
                )
            )
    return findings


def _decision_findings(recorded: tuple[Decision, ...], replayed: list[Decision]) -> list[Finding]:
    by_t = {d.t_ns: d for d in replayed}
    findings = []
    for d in recorded:
        other = by_t.pop(d.t_ns, None)
        if other is None:
            findings.append(Finding("decision: recorded but not taken in the re-run", d.t_ns))
        elif (other.chosen_index, other.value, other.cell) != (d.chosen_index, d.value, d.cell):
            findings.append(
                Finding(
                    f"decision: recorded chosen {d.chosen_index} value {d.value} cell {d.cell}, "
                    f"re-run chosen {other.chosen_index} value {other.value} cell {other.cell} "
                    f"at state {[round(v, 4) for v in other.state]}",
                    d.t_ns,
                )
            )
    findings.extend(Finding("decision: taken in the re-run, not recorded", t) for t in sorted(by_t))
    return findings


def _tracking_findings(
    name: str, recorded: TrackingSeries, replayed: TrackingSeries, relative: float
) -> list[Finding]:
    """Compare RMS and max per axis; a difference beyond `relative` is reported."""
    findings = []
    r_rms, n_rms = recorded.rms(), replayed.rms()
    (r_max, r_when), (n_max, n_when) = recorded.peak(), replayed.peak()
    for k in range(3):
        for what, a, b in (("RMS", r_rms[k], n_rms[k]), ("max", r_max[k], n_max[k])):
            floor = 1e-9 if _AXES[k] != "yaw" else 1e-7
            if abs(a - b) > relative * max(abs(a), abs(b)) + floor:
                when = int(r_when[k] if r_max[k] >= n_max[k] else n_when[k])
                findings.append(
                    Finding(
                        f"{name}: {_AXES[k]} tracking {what} recorded {a:.5f} {_UNITS[k]}, "
                        f"replayed {b:.5f} {_UNITS[k]}",
                        when,
                        {
                            "axis": _AXES[k],
                            "measure": what,
                            "recorded": float(a),
                            "replayed": float(b),
                        },
                    )
                )
    return findings


def check_stack(run: RecordedRun, controllers: ControllerCache, options: ReplayOptions) -> Check:
    """Re-run the full stack on the recorded streams and compare with the recording."""
    if not len(run.poses) or not run.layouts:
        return Check("stack", Status.SKIP, "the log holds no poses or no obstacle layout")
    world = LogWorld(run, options.log)
    log = MemoryLog()
    loop = _infer_loop(run)
    runtime = build_runtime(
        controllers.scenario,
        World(world.clock, world.pose, world.imu, world.obstacles, world.thrusters),
        log,
        loop,
        controllers.synthesizer,
        ResynthesisMode.INLINE,
    )
    # The same composition, with the cached solver: identical controllers, one synthesis.
    runtime.resynthesizer = Resynthesizer(controllers, ResynthesisMode.INLINE)
    # Tick when the recording ticked (every tick sends a command or logs its failure):
    # the sim's fixed period, or a vessel's wall-clock ticks with their jitter.
    for t_ns in tick_times(run):
        world.clock.sleep_until(int(t_ns))
        if runtime.mode in (Mode.DOCKED, Mode.STOPPED):
            # Runtime.run() zeroes the thrusters once on its way out, at the next tick.
            with contextlib.suppress(ThrusterSinkError):
                world.thrusters.send(ThrusterCommand.zero(int(t_ns)))
            break
        runtime.tick(int(t_ns))
    stats = runtime.stats
    tol = options.tolerance
    est_t = np.array([e[0] for e in log.estimates], dtype=np.int64)
    est = np.array([np.concatenate([e[1], e[2]]) for e in log.estimates]).reshape(-1, 6)
    ref_t = np.array([r[0] for r in log.velocity_references], dtype=np.int64)
    ref = np.array([r[1] for r in log.velocity_references]).reshape(-1, 3)
    cmd_t, cmd = world.thrusters.as_array()
    end = run.end_ns  # what the loop does after the recording's last sample is not compared
    est_t, est = est_t[est_t <= end], est[est_t <= end]
    ref_t, ref = ref_t[ref_t <= end], ref[ref_t <= end]
    cmd_t, cmd = cmd_t[cmd_t <= end], cmd[cmd_t <= end]
    findings = [
        *_compare_streams("estimates", run.estimates, est_t, est, tol.estimate, (2,)),
        *_decision_findings(run.decisions, [d for d in log.decisions if d.t_ns <= end]),
        *_compare_streams("velocity references", run.references, ref_t, ref, tol.estimate),
        *_compare_streams("thruster commands", run.thrusters, cmd_t, cmd, tol.command, (3, 4)),
        *_tracking_findings(
            "stack",
            TrackingSeries.between(run.estimates, run.references),
            TrackingSeries.between(Stream(est_t, est), Stream(ref_t, ref)),
            tol.relative,
        ),
    ]
    findings.sort(key=lambda f: f.t_ns if f.t_ns is not None else -1)
    metrics = {
        "ticks": len(est_t),
        "decisions": stats.decisions,
        "end_reason": stats.end_reason,
        "commands": len(cmd_t),
    }
    if findings:
        # Over ROS, which samples a tick saw depends on DDS arrival times, which the log
        # does not hold: the re-run cannot be exact, so a difference only warns there.
        over_ros = run.info.run is not None and run.info.run.backend == "ros"
        note = " (a ROS run: sample arrival per tick is not recorded, advisory)" if over_ros else ""
        return Check(
            "stack",
            Status.WARN if over_ros else Status.FAIL,
            f"the re-run stack does not reproduce the recording, first at "
            f"{time_s(findings[0].t_ns)}{note}",
            tuple(findings),
            metrics,
        )
    return Check(
        "stack",
        Status.PASS,
        f"{len(est_t)} ticks, {stats.decisions} decisions and {len(cmd_t)} commands reproduced",
        (),
        metrics,
    )


# ------------------------------------------------------------------ closed loop


def recorded_spec(run: RecordedRun) -> tuple[SimRunSpec, str]:
    """Return the specification that reproduces `run` and where it came from.

    The suite manifest beside the log holds the exact start, faults and motions;
    without it the metadata's scenario and seed are used with the first recorded
    pose as start (noisy by the sensor's noise, so decisions may drift).

    Raises:
        ScenarioMismatchError: Without a manifest entry, the log lacks scenario or seed.
    """
    manifest = run.path.parent / MANIFEST
    if manifest.is_file():
        try:
            entries = json.loads(manifest.read_text()).get("runs", {})
        except (OSError, ValueError, AttributeError):
            entries = {}
        entry = entries.get(run.path.name) if isinstance(entries, dict) else None
        if isinstance(entry, dict):
            return spec_from_json(entry), f"{MANIFEST} entry"
    info = run.info.run
    if info is not None and info.run_spec:
        try:
            return spec_from_json(json.loads(info.run_spec)), "run specification in the metadata"
        except ValueError:
            pass  # a damaged entry: fall back to scenario, seed and first pose
    if info is None or info.seed is None or not info.scenario_file or not len(run.poses):
        raise ScenarioMismatchError(
            f"{str(run.path)!r} lacks the scenario, seed or poses needed to re-simulate it"
        )
    x, y, psi = (float(v) for v in run.poses.values[0])
    return SimRunSpec(
        scenario=info.scenario_file,
        seed=info.seed,
        start=(x, y, psi),
        loop=LoopConfig(max_duration_s=run.end_ns / NS_PER_S + 30.0),
    ), "first recorded pose (start not in the metadata)"


def check_resim(run: RecordedRun, tolerance: Tolerance) -> Check:
    """Re-simulate the run with the current code and compare it with the recording."""
    try:
        spec, source = recorded_spec(run)
    except (ScenarioMismatchError, ValueError) as err:
        return Check("resim", Status.SKIP, str(err))
    log = MemoryLog()
    summary = run_in_sim(spec, log=log)
    est_t = np.array([e[0] for e in log.estimates], dtype=np.int64)
    est = np.array([np.concatenate([e[1], e[2]]) for e in log.estimates]).reshape(-1, 6)
    ref = Stream(
        np.array([r[0] for r in log.velocity_references], dtype=np.int64),
        np.array([r[1] for r in log.velocity_references]).reshape(-1, 3),
    )
    exact = source.endswith("entry")
    # From the first (noisy) pose the re-simulation drifts by the sensor noise: the
    # trajectory and the decisions are then compared for information only.
    drift = Status.FAIL if exact else Status.WARN
    graded: list[tuple[Status, Finding]] = []
    t, i, j = np.intersect1d(run.estimates.t_ns, est_t, return_indices=True)
    deviation = np.hypot(*(est[j, :2] - run.estimates.values[i, :2]).T) if t.size else np.zeros(0)
    worst = float(deviation.max()) if deviation.size else math.nan
    if deviation.size and worst > tolerance.resim_position_m:
        k = int(np.flatnonzero(deviation > tolerance.resim_position_m)[0])
        graded.append(
            (
                drift,
                Finding(
                    "trajectory departs from the recording by more than "
                    f"{tolerance.resim_position_m} m (largest {worst:.3f} m)",
                    int(t[k]),
                    {"max_deviation_m": worst},
                ),
            )
        )
    recorded_docked = any(e.code == "docked" for e in run.events)
    if summary.docked != recorded_docked:
        graded.append(
            (
                Status.FAIL,
                Finding(
                    f"recording {'docked' if recorded_docked else 'did not dock'}, re-simulation "
                    f"{'docked' if summary.docked else 'did not'} ({summary.end_reason})"
                ),
            )
        )
    decision_diffs = _decision_findings(run.decisions, log.decisions)
    graded += [(drift, f) for f in decision_diffs]
    graded += [
        (Status.FAIL if exact else Status.WARN, f)
        for f in _tracking_findings(
            "resim",
            TrackingSeries.between(run.estimates, run.references),
            TrackingSeries.between(Stream(est_t, est), ref),
            tolerance.relative if exact else max(tolerance.relative, 0.25),
        )
    ]
    graded.sort(key=lambda g: g[1].t_ns if g[1].t_ns is not None else -1)
    findings = tuple(f for _, f in graded)
    metrics = {
        "start_from": source,
        "max_deviation_m": worst,
        "docked": summary.docked,
        "decision_differences": len(decision_diffs),
    }
    if not findings:
        return Check(
            "resim",
            Status.PASS,
            f"re-simulation reproduces the recording (start from {source}; "
            f"largest deviation {worst:.4f} m)",
            (),
            metrics,
        )
    return Check(
        "resim",
        Status.worst([g for g, _ in graded]),
        f"re-simulation differs from the recording, first at "
        f"{time_s(findings[0].t_ns)} (start from {source})",
        findings,
        metrics,
    )


# ------------------------------------------------------------------ one log


def replay_log(
    path: str | Path, options: ReplayOptions | None = None, caches: ScenarioCache | None = None
) -> LogReport:
    """Replay one log and return its report; never raises for a bad or foreign log.

    Args:
        path: Bag directory or ``.mcap`` file; never modified.
        options: What to check and with which thresholds.
        caches: Controllers shared with other logs of the same replay.
    """
    options = options or ReplayOptions()
    caches = caches or ScenarioCache(options.cache_dir)
    wall = time.perf_counter()
    try:
        run = read_log(path)
        scenario = resolve_scenario(run, options.scenario)
        controllers = caches.get(scenario)
        checks = [
            check_decisions(run, controllers),
            check_tracking(run, options.tolerance),
            check_margin(run, scenario, options.tolerance.settle_s),
        ]
        if options.stack:
            checks.append(check_stack(run, controllers, options))
        if options.resim:
            checks.append(check_resim(run, options.tolerance))
    except (ReplayError, SymbolicError, ScenarioError, ValueError, OSError) as err:
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        return LogReport(str(path), error=message, wall_s=time.perf_counter() - wall)
    return LogReport(str(path), tuple(checks), run.warnings, "", time.perf_counter() - wall)
