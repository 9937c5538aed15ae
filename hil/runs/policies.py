"""Which listed safe input a simulated run flies: the paper's J, or an adversary.

The guarantee is promised for every input the controller lists as safe, not only for
the one the cost J picks; ``hil campaign --select POLICY`` stresses that promise by
flying another (:data:`POLICIES`):

- ``J``: the paper's cost (the default);
- ``random``: uniformly among the safe inputs (seeded by the run's seed);
- ``largest-change``: the one farthest from the previous input, in lattice steps (the
  most aggressive transient the one-step rule allows);
- ``zigzag``: the one that reverses the previous sway and yaw rate the most (alternating
  turns, a weave);
- ``fastest``: the one of greatest speed |u| + |v| (the most momentum to brake, the
  largest transients; the paper's J penalizes speed, so it flies the slow end instead);
- ``slowest``: the one whose successor cells reach the largest value (the least progress
  toward the target that the controller still promises: each decision one step nearer
  at most, the longest way round);
- ``closest``: the one whose exact arc over tau (the input held from the estimated
  state) brings the hull closest to an obstacle (where the scenario places it) or a
  wall: the guarantee's margins, tested where they are thinnest;
- ``mixed``: each decision one of the others, drawn at random (seeded).

Ties go to the lowest row, so a run is reproducible from its seed on every machine.
"""

from __future__ import annotations

import numpy as np

from hil.controllers.symbolic import Options, Select, j_select
from hil.controllers.symbolic.abstraction import arc_poses
from hil.core.arrays import FloatArray
from hil.runs.clearance import hull_margin_series
from hil.scenarios import Scenario

__all__ = ["ARC_POINTS", "POLICIES", "Select", "arc_clearance", "policies_of", "policy"]

POLICIES = (
    "J", "random", "largest-change", "zigzag", "fastest", "slowest", "closest", "mixed",
)  # fmt: skip
"""Names ``--select`` takes."""

ARC_POINTS = 21
"""Poses per arc the ``closest`` policy judges (every tau / 20: 0.1 s at tau = 2 s, 1 cm
at the fastest surge)."""


def _largest_change(steps: FloatArray) -> Select:
    def select(o: Options) -> int:
        return int(np.argmax(np.abs((o.inputs - o.previous) / steps).sum(axis=1)))

    return select


def _zigzag(steps: FloatArray) -> Select:
    def select(o: Options) -> int:
        # Against the previous sway and yaw rate's signs (a still axis: toward +).
        sign = np.where(o.previous[1:] > 0.0, -1.0, 1.0)
        return int(np.argmax((o.inputs[:, 1:] * sign / steps[1:]).sum(axis=1)))

    return select


def _fastest(o: Options) -> int:
    return int(np.argmax(np.abs(o.inputs[:, 0]) + np.abs(o.inputs[:, 1])))


def _slowest(o: Options) -> int:
    return int(np.argmax(o.successor_values))


def arc_clearance(scenario: Scenario, state: FloatArray, inputs: FloatArray) -> FloatArray:
    """Return the least hull clearance along each input's exact arc over tau (m), shape (k,).

    To the real obstacles where the scenario places them and to the arena's walls
    (negative: a hull corner past a wall); the inputs (k, 3) held from `state` (3,).
    """
    t_s = np.linspace(0.0, scenario.tau_s, ARC_POINTS)
    poses = arc_poses(state, inputs, t_s).reshape(-1, 3)
    out: FloatArray = hull_margin_series(scenario, poses).reshape(len(inputs), ARC_POINTS).min(
        axis=1
    )
    return out


def _closest(scenario: Scenario) -> Select:
    def select(o: Options) -> int:
        return int(np.argmin(arc_clearance(scenario, o.state, o.inputs)))

    return select


def policy(name: str, seed: int, steps: FloatArray, scenario: Scenario | None = None) -> Select:
    """Return the selection of policy `name` for one run.

    Args:
        name: One of :data:`POLICIES`.
        seed: The run's seed (``random`` and ``mixed`` draw from it).
        steps: The input lattice's step per axis (surge m/s, sway m/s, yaw rad/s), shape
            (3,): distances in lattice steps.
        scenario: The run's obstacles, walls, hull and tau (``closest`` judges arcs
            against them; without it ``closest`` is refused and ``mixed`` leaves it out).

    Raises:
        ValueError: An unknown name.
    """
    steps = np.asarray(steps, dtype=np.float64)
    rng = np.random.default_rng([seed, POLICIES.index(name) if name in POLICIES else 0])
    fixed: dict[str, Select] = {
        "J": j_select,
        "largest-change": _largest_change(steps),
        "zigzag": _zigzag(steps),
        "fastest": _fastest,
        "slowest": _slowest,
    }
    if scenario is not None:
        fixed["closest"] = _closest(scenario)
    elif name == "closest":
        raise ValueError("the closest policy needs the run's scenario (obstacles and walls)")
    if name in fixed:
        return fixed[name]

    def uniform(o: Options) -> int:
        return int(rng.integers(len(o.inputs)))

    if name == "random":
        return uniform
    if name == "mixed":
        options = [*fixed.values(), uniform]

        def mixed(o: Options) -> int:
            return options[int(rng.integers(len(options)))](o)

        return mixed
    raise ValueError(f"selection policy must be one of {', '.join(POLICIES)}, got {name!r}")


def policies_of(text: str) -> tuple[str, ...]:
    """Parse ``--select``: policy names, comma-separated (runs rotate through them).

    Raises:
        ValueError: An empty list or an unknown name (naming it and the choices).
    """
    names = tuple(part.strip() for part in text.split(",") if part.strip())
    if not names:
        raise ValueError(f"--select needs a policy: one of {', '.join(POLICIES)}")
    for name in names:
        if name not in POLICIES:
            raise ValueError(
                f"--select: unknown policy {name!r}; choose from {', '.join(POLICIES)} "
                "(comma-separated to rotate)"
            )
    return names
