"""Parameter sweeps: a grid or a random sample of simulated runs, from a TOML file.

A sweep varies six axes; each is a list of values (every one omitted has one
default value):

```toml
mode = "grid"                 # every combination; "random": `samples` draws
# samples = 100               # random: how many runs
# seed = 0                    # random: seed of the draws
max_duration_s = 240.0        # give a run up after this long (simulated s)
scenarios = ["coarse"]        # packaged names or TOML paths (default: ["paper"])
seeds = [0, 1, 2]             # or { first = 0, count = 10 } (default: [0])
starts = ["default", [0.25, -1.2, 120.0]]   # x m, y m, psi deg (default: ["default"])
start_velocities = ["rest", [0.05, 0.0, 0.0]]   # u m/s, v m/s, r deg/s (default: ["rest"])

[[gains]]                     # velocity-PID gains (hil.controllers.pid.PidGains fields);
[[gains]]                     # an empty table keeps the shipped gains (default: [{}])
kp_per_s = [6.0, 5.0, 10.0]

[[disturbances]]              # environmental load (hil.model.environment.EnvironmentalLoad
[[disturbances]]              # fields, N and N m); an empty table is calm water (default: [{}])
gm_std_n = [0.5, 0.5, 0.05]
```

In random mode each run draws one value of every axis uniformly; ``starts`` and
``start_velocities`` may also be a box ``{ low = [...], high = [...] }`` drawn
uniformly. A disturbance's Gauss-Markov noise is seeded by the run's seed. Starts
are not checked for being winning: a sweep explores (a start on an obstacle is a
failed run, reported with its spec).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from hil.controllers.pid import PidGains
from hil.core.codec import CodecError, from_jsonable
from hil.model.environment import EnvironmentalLoad
from hil.runs.sim_run import SimRunSpec
from hil.runtime.settings import LoopConfig

__all__ = ["AXES", "Sweep", "SweepError", "SweepPoint", "load_sweep"]

AXES = ("scenario", "seed", "start", "start_velocity", "gains", "disturbance")
"""The axes a sweep varies, in the order of its grid."""

Triple = tuple[float, float, float]
Box = tuple[Triple, Triple]


class SweepError(ValueError):
    """A sweep file that cannot be read, with the key and value at fault."""


@dataclass(frozen=True, slots=True)
class SweepPoint:
    """One run of a sweep.

    Attributes:
        spec: The simulated run.
        labels: The run's value on each axis of :data:`AXES`, as written in the file.
    """

    spec: SimRunSpec
    labels: dict[str, str]


@dataclass(frozen=True)
class Sweep:
    """A parsed sweep file (see the module docstring).

    Attributes:
        mode: "grid" or "random".
        samples: Runs drawn in random mode.
        seed: Seed of the random draws.
        max_duration_s: Longest a run may last (simulated s).
        scenarios: Scenario names or paths.
        seeds: World seeds.
        starts: Start poses (x m, y m, psi rad), None for the scenario's default, or
            boxes (low, high) in random mode.
        start_velocities: Start body velocities (u m/s, v m/s, r rad/s), None at rest,
            or boxes.
        gains: PID gains, None for the shipped ones.
        disturbances: Environmental loads, None for calm water.
        names: Each axis's values as the file writes them (labels), in :data:`AXES` order.
    """

    mode: str
    samples: int
    seed: int
    max_duration_s: float
    scenarios: tuple[str, ...]
    seeds: tuple[int, ...]
    starts: tuple[Triple | Box | None, ...]
    start_velocities: tuple[Triple | Box | None, ...]
    gains: tuple[PidGains | None, ...]
    disturbances: tuple[EnvironmentalLoad | None, ...]
    names: tuple[tuple[str, ...], ...] = ()

    def points(self) -> list[SweepPoint]:
        """Return every run: the grid in :data:`AXES` order, or `samples` random draws."""
        axes: list[Sequence[Any]] = [self.scenarios, self.seeds, self.starts,
                                     self.start_velocities, self.gains, self.disturbances]
        if self.mode == "grid":
            return [self._point(axes, picks, None)
                    for picks in itertools.product(*(range(len(a)) for a in axes))]
        rng = np.random.default_rng(self.seed)
        out = []
        for _ in range(self.samples):
            picks = [int(rng.integers(len(axis))) for axis in axes]
            out.append(self._point(axes, picks, rng))
        return out

    def _point(self, axes: Sequence[Sequence[Any]], picks: Sequence[int],
               rng: np.random.Generator | None) -> SweepPoint:
        scenario, seed, start, velocity, gains, load = (
            axis[i] for axis, i in zip(axes, picks, strict=True))
        labels = {name: self.names[a][i] if self.names else str(i)
                  for a, (name, i) in enumerate(zip(AXES, picks, strict=True))}
        if _is_box(start):
            start = _draw(start, rng)
        if _is_box(velocity):
            velocity = _draw(velocity, rng)
        spec = SimRunSpec(
            scenario=scenario, seed=seed, start=start, start_velocity=velocity,
            loop=LoopConfig(resynthesis_period_s=None, max_duration_s=self.max_duration_s),
            gains=gains, load=None if load is None else replace(load, seed=seed))
        return SweepPoint(spec, labels)


def _is_box(value: object) -> bool:
    return isinstance(value, tuple) and len(value) == 2


def _draw(box: Box, rng: np.random.Generator | None) -> Triple:
    assert rng is not None  # boxes are refused in grid mode
    low, high = box
    v = rng.uniform(low, high)
    return (float(v[0]), float(v[1]), float(v[2]))


def load_sweep(path: Path) -> Sweep:
    """Read a sweep file.

    Raises:
        SweepError: Unreadable, not TOML, or a key or value that does not fit (named).
    """
    try:
        with path.open("rb") as f:
            data = tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise SweepError(f"cannot read sweep file {str(path)!r}: {err}") from err
    return parse_sweep(data)


def parse_sweep(data: dict[str, Any]) -> Sweep:
    """Build a sweep from a TOML table (see the module docstring).

    Raises:
        SweepError: Naming the key and value at fault.
    """
    known = {"mode", "samples", "seed", "max_duration_s", "scenarios", "seeds", "starts",
             "start_velocities", "gains", "disturbances"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise SweepError(f"unknown sweep key(s) {unknown!r}; allowed: {', '.join(sorted(known))}")
    mode = data.get("mode", "grid")
    if mode not in ("grid", "random"):
        raise SweepError(f"key 'mode' must be 'grid' or 'random', got {mode!r}")
    samples = data.get("samples", 0 if mode == "grid" else None)
    if mode == "random" and (not isinstance(samples, int) or samples < 1):
        raise SweepError(f"key 'samples' must be a whole number >= 1 in a random sweep, "
                         f"got {samples!r}")
    seed = data.get("seed", 0)
    max_duration = data.get("max_duration_s", 600.0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        hint = " (the runs' seeds are key 'seeds')" if isinstance(seed, list | dict) else ""
        raise SweepError(f"key 'seed' (of the random draw) must be a whole number >= 0, "
                         f"got {seed!r}{hint}")
    if not isinstance(max_duration, int | float) or isinstance(max_duration, bool) \
            or not max_duration > 0:
        raise SweepError(f"key 'max_duration_s' must be a positive number of seconds, "
                         f"got {max_duration!r}")
    boxes = mode == "random"
    defaults: dict[str, list[Any]] = {"scenarios": ["paper"], "seeds": [0],
                                      "starts": ["default"], "start_velocities": ["rest"],
                                      "gains": [{}], "disturbances": [{}]}
    names = []
    for key, default in defaults.items():
        raw = data.get(key, default)
        values = _seeds(raw) if key == "seeds" else raw if isinstance(raw, list) else [raw]
        names.append(tuple(_name(v, key) for v in values))
    return Sweep(
        mode=mode, samples=int(samples or 0), seed=seed, max_duration_s=float(max_duration),
        scenarios=_axis(data, "scenarios", ["paper"], _scenario),
        seeds=_seeds(data.get("seeds", [0])),
        starts=_axis(data, "starts", ["default"],
                     lambda v: _triple(v, "starts", "default", math.radians, boxes)),
        start_velocities=_axis(data, "start_velocities", ["rest"],
                               lambda v: _triple(v, "start_velocities", "rest", math.radians,
                                                 boxes)),
        gains=_axis(data, "gains", [{}], lambda v: _table(PidGains, v, "gains")),
        disturbances=_axis(data, "disturbances", [{}],
                           lambda v: _table(EnvironmentalLoad, v, "disturbances")),
        names=tuple(names),
    )


def _name(value: object, key: str) -> str:
    """Label a value as the file writes it (a table as its keys; {} as the default)."""
    if isinstance(value, dict) and not value:
        return "shipped" if key == "gains" else "calm" if key == "disturbances" else "{}"
    if isinstance(value, dict):
        return ", ".join(f"{k}={v}" for k, v in value.items())
    return str(value)


def _axis(data: dict[str, Any], key: str, default: list[Any],
          parse: Callable[[Any], Any]) -> tuple[Any, ...]:
    values = data.get(key, default)
    if not isinstance(values, list) or not values:
        raise SweepError(f"key {key!r} must be a non-empty list, got {values!r}")
    return tuple(parse(v) for v in values)


def _scenario(value: object) -> str:
    if not isinstance(value, str) or not value:
        raise SweepError(f"key 'scenarios' must hold names or paths, got {value!r}")
    return value


def _seeds(value: object) -> tuple[int, ...]:
    if isinstance(value, dict):
        first, count = value.get("first", 0), value.get("count")
        if set(value) - {"first", "count"} or not isinstance(first, int) \
                or not isinstance(count, int) or count < 1:
            raise SweepError(f"key 'seeds' must be a list or {{ first = N, count = M }}, "
                             f"got {value!r}")
        return tuple(range(first, first + count))
    if not isinstance(value, list) or not value or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise SweepError(f"key 'seeds' must be a non-empty list of integers, got {value!r}")
    return tuple(value)


def _triple(value: object, key: str, none: str, third: Callable[[float], float],
            boxes: bool) -> Triple | Box | None:
    """Parse a triple whose third number is in degrees (pose) or deg/s (yaw rate)."""
    if value == none:
        return None
    if isinstance(value, dict) and set(value) == {"low", "high"}:
        if not boxes:
            raise SweepError(f"key {key!r}: a box {value!r} needs mode = 'random'")
        low = _triple(value["low"], key, none, third, False)
        high = _triple(value["high"], key, none, third, False)
        if low is None or high is None:
            raise SweepError(f"key {key!r}: a box needs two triples, got {value!r}")
        return (low, high)  # type: ignore[return-value]
    if not (isinstance(value, list) and len(value) == 3 and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in value)):
        raise SweepError(f"key {key!r}: values must be {none!r} or 3 finite numbers, "
                         f"got {value!r}")
    return (float(value[0]), float(value[1]), third(float(value[2])))


def _table(kind: type[Any], value: object, key: str) -> Any:
    if not isinstance(value, dict):
        raise SweepError(f"key {key!r} must hold tables, got {value!r}")
    if not value:
        return None
    fields = sorted(f.name for f in dataclasses.fields(kind) if f.init)
    unknown = sorted(set(value) - set(fields))
    if unknown:
        raise SweepError(f"key {key!r}: unknown field(s) {unknown!r} in {value!r}; "
                         f"allowed ({kind.__name__}): {', '.join(fields)}")
    try:
        return from_jsonable(kind, value)
    except (CodecError, ValueError) as err:
        raise SweepError(f"key {key!r}: {err}") from err
