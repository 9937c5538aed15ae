"""Records the runtime logs beside the adapter samples: decisions, estimates, forces, events.

The sensor and actuator samples live in :mod:`hil.core.samples`; the records
here are what only the stack produces. They are frozen and made of tuples, so two
records compare equal field by field (a round trip through a bag is checked with
``==``). Times are integer nanoseconds on the run clock; the arena frame is the
paper's planar frame (x, y in metres, psi in radians).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hil.core.arrays import FloatArray


class RecordValueError(ValueError):
    """A record holds a value that must not be written (NaN, wrong shape, bad time)."""


Vec3 = tuple[float, float, float]


def _check_time(name: str, t_ns: int) -> None:
    if isinstance(t_ns, bool) or not isinstance(t_ns, int | np.integer) or t_ns < 0:
        raise RecordValueError(f"{name}: time must be a non-negative integer (ns), got {t_ns!r}")


def _check_finite(name: str, values: Iterable[float]) -> None:
    values = tuple(values)
    if not all(math.isfinite(v) for v in values):
        raise RecordValueError(f"{name} has non-finite values: {values!r}")


def _vec3(name: str, value: ArrayLike) -> Vec3:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise RecordValueError(f"{name} must have shape (3,), got {arr.shape!r}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


@dataclass(frozen=True, slots=True)
class StateEstimate:
    """The observer's state estimate (nav_msgs/Odometry on the lab's odom topic).

    Attributes:
        t_ns: Time of the estimate (ns).
        x_m: Arena x (m).
        y_m: Arena y (m).
        yaw_rad: Heading psi (rad).
        surge_mps: Body surge velocity u (m/s).
        sway_mps: Body sway velocity v (m/s).
        yaw_rate_radps: Yaw rate r (rad/s).
    """

    t_ns: int
    x_m: float
    y_m: float
    yaw_rad: float
    surge_mps: float
    sway_mps: float
    yaw_rate_radps: float

    def __post_init__(self) -> None:
        _check_time("state estimate", self.t_ns)
        _check_finite(
            "state estimate",
            (self.x_m, self.y_m, self.yaw_rad, self.surge_mps, self.sway_mps, self.yaw_rate_radps),
        )

    def eta(self) -> FloatArray:
        """Return the pose (x, y, psi), shape (3,)."""
        return np.array([self.x_m, self.y_m, self.yaw_rad])

    def nu(self) -> FloatArray:
        """Return the body velocity (u, v, r), shape (3,)."""
        return np.array([self.surge_mps, self.sway_mps, self.yaw_rate_radps])


@dataclass(frozen=True, slots=True)
class ForceCommand:
    """The generalized force tau = (X, Y, N) asked of the allocation (body frame).

    Attributes:
        t_ns: Time the command was issued (ns).
        surge_n: Surge force X (N).
        sway_n: Sway force Y (N).
        yaw_nm: Yaw moment N (N m).
    """

    t_ns: int
    surge_n: float
    sway_n: float
    yaw_nm: float

    def __post_init__(self) -> None:
        _check_time("force command", self.t_ns)
        _check_finite("force command", (self.surge_n, self.sway_n, self.yaw_nm))

    def as_array(self) -> FloatArray:
        """Return (X, Y, N), shape (3,)."""
        return np.array([self.surge_n, self.sway_n, self.yaw_nm])


@dataclass(frozen=True, slots=True)
class Decision:
    """One decision of the symbolic controller.

    Attributes:
        t_ns: Time of the decision (ns).
        state: Estimated state (x m, y m, psi rad) the decision was taken at.
        cell: Flat grid cell index of `state`; -1 outside the grid.
        value: Value function at the cell (steps to target); +inf outside the winning set.
        winning: Whether the cell is in the winning set.
        safe_inputs: The safe inputs (u m/s, v m/s, r rad/s), one triple per input;
            where docking is not winning, those that keep the vessel in the safety set
            (:attr:`staying`).
        safe_input_indices: Index of each safe input in the controller's input grid.
        chosen_index: Input-grid index of the chosen input; -1 when none was chosen.
        chosen_input: The chosen (u, v, r); zeros when `chosen_index` is -1.
        controller_version: Counter bumped on every re-synthesis swap.
        scenario_hash: Hash of the scenario the controller was synthesized for.
        reference_index: Input-grid index of the reference in force when the decision
            was taken (the previous command; on a first decision the input nearest the
            estimated velocity); -1 when unknown.
        first: A first decision (start, or after a stop or hold): every candidate was
            budgeted as a reference change and the vessel may have been moving.
        report_age_s: The obstacle report age its controller was solved for (s): moving
            obstacles grown for it, the decision relying on a report at most this old;
            None in logs written before it was recorded (the scenario's
            ``max_report_age_s``).
        report_t_ns: Stamp of the obstacle report the decision relied on (ns): its
            controller's layout, or a renewal of the same shapes; -1 unknown (logs
            written before it was recorded).
    """

    t_ns: int
    state: Vec3
    cell: int
    value: float
    winning: bool
    safe_inputs: tuple[Vec3, ...]
    safe_input_indices: tuple[int, ...]
    chosen_index: int
    chosen_input: Vec3
    controller_version: int
    scenario_hash: str
    reference_index: int = -1
    first: bool = False
    report_age_s: float | None = None
    report_t_ns: int = -1

    @property
    def staying(self) -> bool:
        """Whether the decision was the safety controller's.

        Docking was not winning, yet an input was chosen among those that keep the
        vessel in the safety set.
        """
        return not self.winning and self.chosen_index >= 0

    def __post_init__(self) -> None:
        _check_time("decision", self.t_ns)
        if self.report_age_s is not None and not (
            math.isfinite(self.report_age_s) and self.report_age_s > 0.0
        ):
            raise RecordValueError(
                f"decision report_age_s must be finite and > 0 s, got {self.report_age_s!r}"
            )
        if self.report_t_ns < -1:
            raise RecordValueError(
                f"decision report_t_ns must be a stamp or -1 (unknown), got {self.report_t_ns!r}"
            )
        _check_finite("decision state", self.state)
        _check_finite("decision chosen input", self.chosen_input)
        for row in self.safe_inputs:
            if len(row) != 3:
                raise RecordValueError(f"decision safe input must be (u, v, r), got {row!r}")
            _check_finite("decision safe input", row)
        if math.isnan(self.value) or self.value == -math.inf:
            raise RecordValueError(f"decision value must be finite or +inf, got {self.value!r}")
        if len(self.safe_input_indices) != len(self.safe_inputs):
            raise RecordValueError(
                f"decision has {len(self.safe_inputs)} safe inputs but "
                f"{len(self.safe_input_indices)} indices: {self.safe_input_indices!r}"
            )
        if self.chosen_index < -1 or self.reference_index < -1:
            raise RecordValueError(
                f"decision chosen_index and reference_index must be >= -1, got "
                f"{self.chosen_index!r} and {self.reference_index!r}"
            )
        if not 0 <= self.controller_version < 2**32:
            raise RecordValueError(
                f"decision controller_version must fit uint32, got {self.controller_version!r}"
            )

    @staticmethod
    def from_arrays(
        t_ns: int,
        state: ArrayLike,
        cell: int,
        value: float,
        winning: bool,
        safe_inputs: ArrayLike,
        safe_input_indices: ArrayLike,
        chosen_index: int,
        controller_version: int,
        scenario_hash: str,
        chosen_input: ArrayLike | None = None,
        reference_index: int = -1,
        first: bool = False,
        report_age_s: float | None = None,
        report_t_ns: int = -1,
    ) -> Decision:
        """Build a decision from numpy arrays.

        Args:
            t_ns: Time of the decision (ns).
            state: (x, y, psi), shape (3,).
            cell: Flat cell index, -1 outside the grid.
            value: Value at the cell (+inf outside the winning set).
            winning: Whether the cell is winning.
            safe_inputs: Safe inputs, shape (k, 3), rows (u, v, r).
            safe_input_indices: Input-grid indices, shape (k,).
            chosen_index: Input-grid index of the chosen input, -1 for none.
            controller_version: Re-synthesis counter.
            scenario_hash: Scenario hash.
            chosen_input: The chosen (u, v, r), shape (3,); looked up in `safe_inputs`
                when omitted (zeros when `chosen_index` is -1).
            reference_index: Input-grid index of the reference in force, -1 unknown.
            first: Whether it was a first decision.
            report_age_s: The report age its controller was solved for (s).
            report_t_ns: Stamp of the obstacle report it relied on (ns), -1 unknown.

        Returns:
            The decision.

        Raises:
            RecordValueError: Shapes do not match or a value is not finite.
        """
        inputs = np.asarray(safe_inputs, dtype=np.float64).reshape(-1, 3)
        indices = np.asarray(safe_input_indices, dtype=np.int64).reshape(-1)
        if chosen_input is None:
            hits = np.flatnonzero(indices == chosen_index)
            if chosen_index == -1:
                chosen: Vec3 = (0.0, 0.0, 0.0)
            elif hits.size:
                chosen = _vec3("chosen input", inputs[hits[0]])
            else:
                raise RecordValueError(
                    f"chosen_index {chosen_index!r} is not among the safe inputs "
                    f"{indices.tolist()!r}; pass chosen_input"
                )
        else:
            chosen = _vec3("chosen input", chosen_input)
        return Decision(
            t_ns=int(t_ns),
            state=_vec3("decision state", state),
            cell=int(cell),
            value=float(value),
            winning=bool(winning),
            safe_inputs=tuple((float(u), float(v), float(r)) for u, v, r in inputs),
            safe_input_indices=tuple(int(i) for i in indices),
            chosen_index=int(chosen_index),
            chosen_input=chosen,
            controller_version=int(controller_version),
            scenario_hash=str(scenario_hash),
            reference_index=int(reference_index),
            first=bool(first),
            report_age_s=None if report_age_s is None else float(report_age_s),
            report_t_ns=int(report_t_ns),
        )

    def safe_inputs_array(self) -> FloatArray:
        """Return the safe inputs, shape (k, 3), rows (u, v, r)."""
        return np.array(self.safe_inputs, dtype=np.float64).reshape(-1, 3)


class EventLevel(enum.IntEnum):
    """Severity of an event (the values of rcl_interfaces/Log)."""

    DEBUG = 10
    INFO = 20
    WARN = 30
    ERROR = 40
    FATAL = 50


@dataclass(frozen=True, slots=True)
class Event:
    """A runtime event or fault (pose lost, sample rejected, no winning set, ...).

    Attributes:
        t_ns: Time of the event (ns).
        level: Severity.
        code: Short machine-readable code, e.g. ``"pose_stale"``.
        text: Human-readable description.
    """

    t_ns: int
    level: EventLevel
    code: str
    text: str

    def __post_init__(self) -> None:
        _check_time("event", self.t_ns)
        if not isinstance(self.level, EventLevel):
            raise RecordValueError(f"event level must be an EventLevel, got {self.level!r}")


class ControllerSource(enum.IntEnum):
    """Where a controller put in force came from (the values of hil_msgs/ControllerReady)."""

    SOLVED = 0
    """The fixed point ran for it."""
    STORE = 1
    """Read from the solved-controller store on disk."""
    MEMORY = 2
    """This process had solved the same layout before (the solver's memo)."""
    UNKNOWN = 255
    """Not recorded (logs written before the record existed)."""


@dataclass(frozen=True, slots=True)
class ControllerReady:
    """A controller the runtime took from its re-synthesis (early or full).

    Attributes:
        t_ns: When the runtime took it (ns): a full one is in force from here, an
            early one waits for a decision it covers.
        version: Controller version (the decisions' ``controller_version``).
        seconds: Wall time from the layout's submission to this result (s); NaN where
            not kept (the regression suite leaves wall times out).
        source: Solved, from the store or from memory.
        complete: False for an early controller (it covers the vessel's state and every
            state of a lower value; the full one follows under the same version).
        report_age_s: The obstacle report age it was solved for (s).
        layout_t_ns: Stamp of the obstacle layout it was solved for (ns); -1 unknown.
    """

    t_ns: int
    version: int
    seconds: float
    source: ControllerSource
    complete: bool
    report_age_s: float
    layout_t_ns: int

    def __post_init__(self) -> None:
        _check_time("controller_ready", self.t_ns)
        if self.version < 0:
            raise RecordValueError(f"controller version must be >= 0, got {self.version!r}")
        if not isinstance(self.source, ControllerSource):
            raise RecordValueError(f"source must be a ControllerSource, got {self.source!r}")

    def describe(self) -> str:
        """Return the human text of the ``controller_ready`` event this record goes with."""
        took = "" if math.isnan(self.seconds) else f" in {self.seconds:.3f} s"
        if not self.complete:
            return (
                f"controller v{self.version} early{took}: it covers the vessel's state and "
                "every state of a lower value; the full solve goes on"
            )
        came = {ControllerSource.STORE: " (from the store)", ControllerSource.MEMORY:
                " (from memory)"}.get(self.source, "")
        return f"controller v{self.version}{took}{came}"
