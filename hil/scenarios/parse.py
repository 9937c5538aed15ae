"""Read a scenario from parsed TOML: every key checked, every message naming it.

Keys and types are checked by :mod:`hil.core.config` (the tables that are one
dataclass, ``hull``, by :func:`~hil.core.config.from_table`); this
module adds what only a scenario knows: cells dividing the arena, input grids,
heading cells dividing the circle, plausible units, shapes told apart by their
keys, a ``[transient]`` budget whose bins cover a period held late (missing: the paper's
zero budget), obstacle speed bounds (``[obstacle_motion]``, per obstacle
``max_speed_mps``; missing: fixed obstacles), and sets that fit together
(:func:`~hil.scenarios.scenario.check_sets`). What the simulated obstacles do,
``[[simulated_motion]]`` and ``[sim]``, is checked against the obstacles it names and
their speed bounds (:func:`_simulation`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil.core.config import ConfigError, check_keys, from_table, number, numbers, table
from hil.core.motion import ObstacleMotion
from hil.core.pose_feeds import DEFAULT_POSE_FEED, POSE_FEEDS
from hil.core.shapes import Polygon, Rect, Shape
from hil.core.transient import (
    LATE_S,
    BudgetClass,
    TransientBudget,
    TransientBudgetError,
    horizon_bins,
)
from hil.scenarios.errors import ScenarioError
from hil.scenarios.scenario import (
    REPORT_AGES,
    Hull,
    InputAxis,
    Obstacle,
    ObstacleTracking,
    Scenario,
    SimulatedWorld,
    Target,
    check_geometry,
    check_sets,
    check_transient,
)

__all__ = ["parse_scenario"]

_UNITS = "keys carry their unit (_m, _s, _mps, _radps, _rad)"

_TOP_KEYS = {
    "name",
    "description",
    "state",
    "grid",
    "inputs",
    "timing",
    "transient",
    "pose_feeds",
    "hull",
    "abstraction",
    "obstacle_motion",
    "obstacles",
    "target",
    "simulated_motion",
    "sim",
}


def _keys(data: dict[str, Any], allowed: set[str], where: str) -> None:
    check_keys(data, allowed, where, _UNITS)


def _interval(data: dict[str, Any], key: str, where: str) -> tuple[float, float]:
    lo, hi = numbers(data, key, where, 2)
    if not hi > lo:
        raise ScenarioError(f"key {where}{key!r} is empty: {[lo, hi]!r} needs min < max")
    return lo, hi


def _divides(length: float, step: float) -> bool:
    n = length / step
    return abs(n - round(n)) < 1e-6 and round(n) >= 1


def _shape(data: dict[str, Any], where: str, extra: frozenset[str] = frozenset()) -> Shape:
    """Read a rectangle, rotated rectangle or polygon; `extra` are further allowed keys."""
    if "center_m" in data:
        allowed = {"name", "center_m", "size_m", "angle_rad", "inflation_m", "deflation_m"}
        _keys(data, allowed | extra, where)
        cx, cy = numbers(data, "center_m", where, 2)
        length, width = numbers(data, "size_m", where, 2)
        if not (length > 0.0 and width > 0.0):
            raise ScenarioError(f"key {where}'size_m' is empty: {[length, width]!r}")
        return Polygon.rotated_rect(
            (cx, cy), (length, width), number(data, "angle_rad", where, 0.0)
        )
    if "vertices_m" in data:
        _keys(data, {"name", "vertices_m", "inflation_m", "deflation_m"} | extra, where)
        raw = data["vertices_m"]
        if not isinstance(raw, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(c, int | float) for c in p)
            for p in raw
        ):
            raise ScenarioError(
                f"key {where}'vertices_m' must be a list of [x, y] pairs, got {raw!r}"
            )
        poly = Polygon(tuple((float(p[0]), float(p[1])) for p in raw))
        if poly.is_empty():
            raise ScenarioError(
                f"key {where}'vertices_m' is not a convex counter-clockwise polygon "
                f"with area: {raw!r}"
            )
        return poly
    _keys(data, {"name", "x_m", "y_m", "inflation_m", "deflation_m"} | extra, where)
    x = _interval(data, "x_m", where)
    y = _interval(data, "y_m", where)
    return Rect(x[0], x[1], y[0], y[1])


def _axis(data: dict[str, Any], key: str, where: str) -> InputAxis:
    lo, hi, step = numbers(data, key, where, 3)
    if not ((step > 0.0 and hi >= lo and _divides(hi - lo, step)) or hi == lo):
        raise ScenarioError(
            f"key {where}{key!r} = {[lo, hi, step]!r}: need [min, max, step] "
            "with step > 0 dividing max - min"
        )
    return InputAxis(lo, hi, step)


def parse_scenario(data: dict[str, Any], default_name: str = "scenario") -> Scenario:
    """Build a scenario from parsed TOML data, validating every key.

    Args:
        data: The TOML document as :func:`tomllib.loads` returns it.
        default_name: Name when the document has no ``name`` key.

    Raises:
        ScenarioError: A key is missing, unknown, of the wrong type or inconsistent.
    """
    try:
        return _parse(data, default_name)
    except ScenarioError:
        raise
    except ConfigError as err:
        raise ScenarioError(str(err)) from err


def _heading_cells(grid: dict[str, Any]) -> int:
    if "heading_cells" in grid:
        heading_cells = grid["heading_cells"]
        if (
            isinstance(heading_cells, bool)
            or not isinstance(heading_cells, int)
            or heading_cells < 1
        ):
            raise ScenarioError(
                f"key grid.'heading_cells' must be a positive integer, got {heading_cells!r}"
            )
        return heading_cells
    width = number(grid, "heading_cell_rad", "grid.")
    if not (width > 0.0 and _divides(2.0 * math.pi, width)):
        raise ScenarioError(f"key grid.'heading_cell_rad' = {width!r} does not divide 2 pi")
    return round(2.0 * math.pi / width)


_RETIRED_MARGIN = (
    "table 'margin' was retired: the constant tracking-error margin was replaced by the "
    "[transient] deviation budget; delete [margin] and copy the [transient] table that "
    "`python3 tools/dev.py bench lowlevel` prints"
)


def _at_least_zero(data: dict[str, Any], key: str, where: str, default: float) -> float:
    """Return `data[key]`, a finite number >= 0, or `default` when absent."""
    value = number(data, key, where, default)
    if value < 0.0:
        raise ScenarioError(f"key {where}{key!r} must be >= 0, got {value!r}")
    return value


def _obstacle_motion(data: dict[str, Any]) -> tuple[float, ObstacleTracking]:
    """Read `[obstacle_motion]`: the default speed bound (m/s) and the report age it relies on.

    A missing table means fixed obstacles (speed 0). Every number must be finite (TOML's
    ``nan`` and ``inf`` are refused), the speed and the position tolerance >= 0, the age > 0.
    """
    raw = table(data, "obstacle_motion", required=False)
    where = "obstacle_motion."
    _keys(raw, {"max_speed_mps", "max_report_age_s", "position_tolerance_m", "report_age"}, where)
    speed = _at_least_zero(raw, "max_speed_mps", where, 0.0)
    default_age = ObstacleTracking().max_report_age_s
    age = number(raw, "max_report_age_s", where, default_age)
    if not age > 0.0:
        raise ScenarioError(f"key {where}'max_report_age_s' must be > 0, got {age!r}")
    lag = _at_least_zero(raw, "position_tolerance_m", where,
                         ObstacleTracking().position_tolerance_m)
    mode = raw.get("report_age", "stated")
    if mode not in REPORT_AGES:
        raise ScenarioError(
            f"key {where}'report_age' must be one of {', '.join(map(repr, REPORT_AGES))}, "
            f"got {mode!r}"
        )
    return speed, ObstacleTracking(
        max_report_age_s=age, position_tolerance_m=lag, report_age=str(mode)
    )


_MOTION_KEYS = {"obstacle", "velocity_mps", "start_s", "stop_s"}
_SPEED_TOLERANCE_MPS = 1e-12  # a speed written as the bound itself passes despite rounding


def _simulation(data: dict[str, Any], obstacles: list[Obstacle]) -> SimulatedWorld:
    """Read ``[[simulated_motion]]`` and ``[sim]``: what the simulated obstacles do.

    Each motion names an ``[[obstacles]]`` entry (a name two entries share is ambiguous),
    moves it at ``velocity_mps`` = (vx, vy) (m/s, arena frame) from ``start_s`` (default
    0) to ``stop_s`` (s of run time, 0 <= start < stop), no faster than that obstacle's
    ``max_speed_mps`` (the bound its synthesis budget assumes). Motions of one obstacle
    must not overlap in time (back and forth is one entry after the other): their speeds
    would add up past the bound each respects. ``[sim] obstacle_report_period_s`` (> 0,
    default 1 s) is how often the simulated tracker reports every obstacle.
    """
    sim = table(data, "sim", required=False)
    _keys(sim, {"obstacle_report_period_s"}, "sim.")
    default_period = SimulatedWorld().obstacle_report_period_s
    period = number(sim, "obstacle_report_period_s", "sim.", default_period)
    if not period > 0.0:
        raise ScenarioError(f"key sim.'obstacle_report_period_s' must be > 0, got {period!r}")
    raw_motions = data.get("simulated_motion", [])
    if not isinstance(raw_motions, list):
        raise ScenarioError(
            f"key 'simulated_motion' must be an array of tables ([[simulated_motion]]), "
            f"got {raw_motions!r}"
        )
    names = [o.name for o in obstacles]
    motions: list[ObstacleMotion] = []
    for n, raw in enumerate(raw_motions):
        where = f"simulated_motion[{n}]."
        if not isinstance(raw, dict):
            raise ScenarioError(f"key {where[:-1]!r} must be a table, got {raw!r}")
        _keys(raw, _MOTION_KEYS, where)
        if "obstacle" not in raw:
            raise ScenarioError(f"missing key {where}'obstacle' (an [[obstacles]] name)")
        name = raw["obstacle"]
        if not isinstance(name, str) or name not in names:
            raise ScenarioError(
                f"key {where}'obstacle' = {name!r} names no [[obstacles]] entry "
                f"(names: {', '.join(repr(m) for m in names) or 'none'})"
            )
        if names.count(name) > 1:
            raise ScenarioError(
                f"key {where}'obstacle' = {name!r} is ambiguous: {names.count(name)} "
                "[[obstacles]] entries have that name"
            )
        index = names.index(name)
        vx, vy = numbers(raw, "velocity_mps", where, 2)
        start = _at_least_zero(raw, "start_s", where, 0.0)
        stop = number(raw, "stop_s", where)
        if not stop > start:
            raise ScenarioError(
                f"key {where}'stop_s' = {stop!r} must be after {where}'start_s' = {start!r}"
            )
        speed = math.hypot(vx, vy)
        bound = obstacles[index].max_speed_mps
        if speed > bound + _SPEED_TOLERANCE_MPS:
            raise ScenarioError(
                f"key {where}'velocity_mps' = {[vx, vy]!r} moves {name!r} at {speed!r} m/s, "
                f"faster than its max_speed_mps = {bound!r} (obstacles[{index}] or "
                "[obstacle_motion]): the synthesis budgets its motion by that bound; raise it"
            )
        motion = ObstacleMotion(index, (vx, vy), start, stop)
        for m, other in enumerate(motions):
            if other.index == index and other.start_s < stop and start < other.stop_s:
                raise ScenarioError(
                    f"key {where}'start_s' = {start!r}, 'stop_s' = {stop!r} overlaps "
                    f"simulated_motion[{m}] of {name!r} ([{other.start_s!r}, {other.stop_s!r}]"
                    " s): motions of one obstacle would add up past its max_speed_mps; "
                    "let one end where the next starts"
                )
        motions.append(motion)
    return SimulatedWorld(tuple(motions), period)


_ENVELOPE_AXES = ("surge_mps", "sway_mps", "yaw_rate_radps")
_CLASSES = {BudgetClass.HOLD: "hold", BudgetClass.CHANGE: "change", BudgetClass.START: "start"}
_DEVIATIONS = ("position_m", "heading_rad")
_TRANSIENT_KEYS = {
    "bin_s",
    "estimation_position_m",
    "estimation_heading_rad",
    "source",
    *(f"{c}_{a}" for c in _CLASSES.values() for a in (*_DEVIATIONS, *_ENVELOPE_AXES)),
}


def _transient(data: dict[str, Any], tau_s: float) -> TransientBudget:
    """Read `[transient]`; a missing table is the paper's zero budget.

    ``bin_s`` divides ``tau_s``, and the bins cover a period held late, ``tau_s +
    LATE_S``: every per-bin key lists ``ceil((tau_s + LATE_S) / bin_s)`` numbers >= 0
    (9 for 0.25-s bins and tau = 2 s). The deviation bounds ``{class}_position_m`` and
    ``{class}_heading_rad`` hold up to each bin's end, so they never decrease.
    """
    if "transient" not in data:
        return TransientBudget.zero(tau_s)
    return _budget(table(data, "transient"), "transient", tau_s)


def _pose_feeds(data: dict[str, Any], tau_s: float) -> tuple[tuple[str, TransientBudget], ...]:
    """Read ``[pose_feeds.NAME]``: a ``[transient]`` table per other named pose feed."""
    feeds = table(data, "pose_feeds", required=False)
    out = []
    for name, raw in feeds.items():
        if name not in POSE_FEEDS or name == DEFAULT_POSE_FEED:
            others = ", ".join(sorted(set(POSE_FEEDS) - {DEFAULT_POSE_FEED}))
            raise ScenarioError(
                f"table 'pose_feeds.{name}': not a pose feed with premises of its own "
                f"(known: {others}; {DEFAULT_POSE_FEED}'s are [transient])")
        if not isinstance(raw, dict):
            raise ScenarioError(f"key 'pose_feeds.{name}' must be a table, got {raw!r}")
        out.append((name, _budget(raw, f"pose_feeds.{name}", tau_s)))
    return tuple(out)


def _budget(raw: dict[str, Any], name: str, tau_s: float) -> TransientBudget:
    """Read one budget table (``[transient]`` or ``[pose_feeds.NAME]``), `name` its key."""
    where = f"{name}."
    _keys(raw, _TRANSIENT_KEYS, where)
    bin_s = number(raw, "bin_s", where)
    if not (bin_s > 0.0 and _divides(tau_s, bin_s)):
        raise ScenarioError(
            f"key {where}'bin_s' = {bin_s!r} must be > 0 and divide timing.'tau_s' = {tau_s!r}"
        )
    bin_s = tau_s / round(tau_s / bin_s)
    n_bins = horizon_bins(tau_s, bin_s)
    n_classes = len(_CLASSES)
    env = np.empty((n_classes, n_bins, len(_ENVELOPE_AXES)))
    deviation = {name: np.empty((n_classes, n_bins)) for name in _DEVIATIONS}
    for cls, prefix in _CLASSES.items():
        for name in _DEVIATIONS:
            key = f"{prefix}_{name}"
            values = _per_bin(raw, key, where, n_bins)
            drop = next((j for j in range(n_bins - 1) if values[j + 1] < values[j]), None)
            if drop is not None:
                raise ScenarioError(
                    f"key {where}{key!r} must not decrease (a bound up to each bin's end), "
                    f"got {values[drop]!r} then {values[drop + 1]!r} at bins {drop}-{drop + 1}"
                )
            deviation[name][cls] = values
        for axis, suffix in enumerate(_ENVELOPE_AXES):
            env[cls, :, axis] = _per_bin(raw, f"{prefix}_{suffix}", where, n_bins)
    estimation = {}
    for key in ("estimation_position_m", "estimation_heading_rad"):
        estimation[key] = number(raw, key, where)
        if estimation[key] < 0.0:
            raise ScenarioError(f"key {where}{key!r} must be >= 0, got {estimation[key]!r}")
    source = raw.get("source", "")
    if not isinstance(source, str):
        raise ScenarioError(f"key {where}'source' must be a string, got {source!r}")
    try:
        budget = TransientBudget(
            bin_s=bin_s,
            envelopes=env,
            position_m=deviation["position_m"],
            heading_rad=deviation["heading_rad"],
            source=source,
            **estimation,
        )
    except TransientBudgetError as err:
        raise ScenarioError(f"table {name!r}: {err}") from err
    check_transient(budget, tau_s)
    return budget


def _per_bin(raw: dict[str, Any], key: str, where: str, n_bins: int) -> tuple[float, ...]:
    """Return `raw[key]`: one number >= 0 per bin (the message says how many bins and why)."""
    try:
        values = numbers(raw, key, where, n_bins)
    except ConfigError as err:
        if key not in raw:
            raise
        raise ScenarioError(
            f"{err} (one per {raw.get('bin_s')!r}-s bin up to timing.'tau_s' + {LATE_S!r} s)"
        ) from err
    bad = [v for v in values if v < 0.0]
    if bad:
        raise ScenarioError(f"key {where}{key!r} must be >= 0, got {bad[0]!r}")
    return values


def _grid(
    data: dict[str, Any], x_range: tuple[float, float], y_range: tuple[float, float]
) -> tuple[tuple[float, float], int]:
    """Return the ``[grid]`` table's cell sizes (m, m) and heading cells, checked."""
    grid = table(data, "grid")
    _keys(grid, {"cell_m", "heading_cells", "heading_cell_rad"}, "grid.")
    cell = numbers(grid, "cell_m", "grid.", 2)
    if not (cell[0] > 0.0 and cell[1] > 0.0):
        raise ScenarioError(f"key grid.'cell_m' must be positive, got {list(cell)!r}")
    if not _divides(x_range[1] - x_range[0], cell[0]):
        raise ScenarioError(
            f"key grid.'cell_m' x width {cell[0]!r} does not divide state.x_m {list(x_range)!r}"
        )
    if not _divides(y_range[1] - y_range[0], cell[1]):
        raise ScenarioError(
            f"key grid.'cell_m' y width {cell[1]!r} does not divide state.y_m {list(y_range)!r}"
        )
    return (cell[0], cell[1]), int(_heading_cells(grid))


def _inputs(data: dict[str, Any]) -> tuple[InputAxis, InputAxis, InputAxis]:
    """Return the ``[inputs]`` table's surge, sway and yaw-rate axes, checked."""
    inputs = table(data, "inputs")
    _keys(inputs, {"surge_mps", "sway_mps", "yaw_rate_radps"}, "inputs.")
    surge = _axis(inputs, "surge_mps", "inputs.")
    sway = _axis(inputs, "sway_mps", "inputs.")
    yaw = _axis(inputs, "yaw_rate_radps", "inputs.")
    if max(abs(yaw.min), abs(yaw.max)) > math.pi:
        raise ScenarioError(
            f"key inputs.'yaw_rate_radps' = {[yaw.min, yaw.max]!r} exceeds pi rad/s: degrees given?"
        )
    return surge, sway, yaw


def _obstacles(data: dict[str, Any], inflation: float, max_speed: float) -> list[Obstacle]:
    """Return the ``[[obstacles]]`` array, each with its inflation and speed bound."""
    raw_obstacles = data.get("obstacles", [])
    if not isinstance(raw_obstacles, list):
        raise ScenarioError(f"key 'obstacles' must be an array of tables, got {raw_obstacles!r}")
    obstacles = []
    for n, raw in enumerate(raw_obstacles):
        where = f"obstacles[{n}]."
        if not isinstance(raw, dict):
            raise ScenarioError(f"key {where[:-1]!r} must be a table, got {raw!r}")
        obstacles.append(
            Obstacle(
                str(raw.get("name", f"O{n + 1}")),
                _shape(raw, where, frozenset({"max_speed_mps"})),
                number(raw, "inflation_m", where, inflation),
                _at_least_zero(raw, "max_speed_mps", where, max_speed),
            )
        )
    return obstacles


def _parse(data: dict[str, Any], default_name: str) -> Scenario:
    if "margin" in data:
        raise ScenarioError(_RETIRED_MARGIN)
    _keys(data, _TOP_KEYS, "")
    state = table(data, "state")
    _keys(state, {"x_m", "y_m"}, "state.")
    x_range = _interval(state, "x_m", "state.")
    y_range = _interval(state, "y_m", "state.")

    cell, heading_cells = _grid(data, x_range, y_range)
    surge, sway, yaw = _inputs(data)

    timing = table(data, "timing")
    _keys(timing, {"tau_s"}, "timing.")
    tau = number(timing, "tau_s", "timing.")
    if not 0.0 < tau <= 60.0:
        raise ScenarioError(
            f"key timing.'tau_s' = {tau!r} must be in (0, 60] s (milliseconds given?)"
        )

    transient = _transient(data, tau)

    hull = from_table(Hull, table(data, "hull", required=False), "hull.", note=_UNITS)
    if not (hull.length_m > 0.0 and hull.beam_m > 0.0):
        raise ScenarioError(f"key 'hull' must have positive sizes, got {hull!r}")

    abstraction = table(data, "abstraction", required=False)
    _keys(abstraction, {"obstacle_inflation_m", "target_deflation_m"}, "abstraction.")
    inflation = number(abstraction, "obstacle_inflation_m", "abstraction.", 0.0)
    deflation = number(abstraction, "target_deflation_m", "abstraction.", 0.0)
    if inflation < 0.0 or deflation < 0.0:
        raise ScenarioError(f"keys abstraction.* must be >= 0, got {abstraction!r}")

    max_speed, tracking = _obstacle_motion(data)
    obstacles = _obstacles(data, inflation, max_speed)
    target_data = table(data, "target")
    target = Target(
        _shape(target_data, "target."), number(target_data, "deflation_m", "target.", deflation)
    )

    scenario = Scenario(
        name=str(data.get("name", default_name)),
        description=str(data.get("description", "")),
        x_range_m=x_range,
        y_range_m=y_range,
        cell_m=cell,
        heading_cells=heading_cells,
        surge=surge,
        sway=sway,
        yaw_rate=yaw,
        tau_s=tau,
        transient=transient,
        hull=hull,
        obstacles=tuple(obstacles),
        target=target,
        tracking=tracking,
        simulation=_simulation(data, obstacles),
        pose_feeds=_pose_feeds(data, tau),
    )
    check_sets(scenario)
    check_geometry(scenario)
    return scenario
