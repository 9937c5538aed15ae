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
- ``mixed``: each decision one of the others, drawn at random (seeded).

Ties go to the lowest row, so a run is reproducible from its seed on every machine.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from hil.runtime.assembly import select_index

FloatArray = NDArray[np.float64]
Select = Callable[[FloatArray, FloatArray], int]
"""Picks a row of the safe inputs (k, 3) given the previous input (3,)."""

POLICIES = ("J", "random", "largest-change", "zigzag", "fastest", "mixed")
"""Names ``--select`` takes."""


def _largest_change(steps: FloatArray) -> Select:
    def select(safe: FloatArray, previous: FloatArray) -> int:
        return int(np.argmax(np.abs((safe - previous) / steps).sum(axis=1)))

    return select


def _zigzag(steps: FloatArray) -> Select:
    def select(safe: FloatArray, previous: FloatArray) -> int:
        # Against the previous sway and yaw rate's signs (a still axis: toward +).
        sign = np.where(previous[1:] > 0.0, -1.0, 1.0)
        return int(np.argmax((safe[:, 1:] * sign / steps[1:]).sum(axis=1)))

    return select


def _fastest(safe: FloatArray, _previous: FloatArray) -> int:
    return int(np.argmax(np.abs(safe[:, 0]) + np.abs(safe[:, 1])))


def policy(name: str, seed: int, steps: FloatArray) -> Select:
    """Return the selection of policy `name` for one run.

    Args:
        name: One of :data:`POLICIES`.
        seed: The run's seed (``random`` and ``mixed`` draw from it).
        steps: The input lattice's step per axis (surge m/s, sway m/s, yaw rad/s), shape
            (3,): distances in lattice steps.

    Raises:
        ValueError: An unknown name.
    """
    steps = np.asarray(steps, dtype=np.float64)
    rng = np.random.default_rng([seed, POLICIES.index(name) if name in POLICIES else 0])
    fixed: dict[str, Select] = {
        "J": select_index,
        "largest-change": _largest_change(steps),
        "zigzag": _zigzag(steps),
        "fastest": _fastest,
    }
    if name in fixed:
        return fixed[name]

    def uniform(safe: FloatArray, _previous: FloatArray) -> int:
        return int(rng.integers(len(safe)))

    if name == "random":
        return uniform
    if name == "mixed":
        options = [*fixed.values(), uniform]

        def mixed(safe: FloatArray, previous: FloatArray) -> int:
            return options[int(rng.integers(len(options)))](safe, previous)

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
