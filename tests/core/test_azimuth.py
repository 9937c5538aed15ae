"""The lab's azimuth wrench convention: one encoding, one decode rule."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.core.azimuth import azimuth_command, azimuth_commands, azimuth_vector, azimuth_vectors


def test_the_vector_is_the_command_times_the_pod_direction() -> None:
    assert azimuth_vector(0.5, math.pi / 2) == pytest.approx((0.0, 0.5))
    assert azimuth_vector(-0.5, 0.0) == pytest.approx((-0.5, 0.0))
    rng = np.random.default_rng(2)
    thrust, angle = rng.uniform(-1, 1, 50), rng.uniform(-math.pi, math.pi, 50)
    np.testing.assert_allclose(
        azimuth_vectors(thrust, angle),
        [azimuth_vector(float(c), float(a)) for c, a in zip(thrust, angle, strict=True)],
        atol=0, rtol=0,
    )


def test_the_pod_keeps_its_side_and_reverses_the_propeller() -> None:
    # A vector ahead of the pod's side: forward thrust at the vector's angle.
    assert azimuth_command(0.0, 0.5, math.pi / 2) == pytest.approx((0.5, math.pi / 2))
    # Behind it: the pod stays on its side, the propeller runs backwards.
    assert azimuth_command(0.0, -0.5, math.pi / 2) == pytest.approx((-0.5, math.pi / 2))
    # No vector, no angle: the pod stays where it was.
    assert azimuth_command(0.0, 0.0, 1.0) == (0.0, 1.0)
    # Commands are normalized: a longer vector is clipped.
    assert azimuth_command(3.0, 4.0, 0.9)[0] == 1.0


def test_a_stream_decodes_row_by_row_and_gives_back_what_was_encoded() -> None:
    # Pods that turn less than 90 degrees per command (as the lab's driver does) come back
    # exactly: command and angle, negative commands included.
    rng = np.random.default_rng(3)
    turn = rng.uniform(-1.2, 1.2, 300)
    thrust = rng.uniform(-1, 1, 300)
    thrust[::17] = 0.0  # stopped: the vector carries no angle, the pod does not turn
    turn[::17] = 0.0
    angle = np.cumsum(turn) + math.pi / 2  # from the reference angle
    angle = np.mod(angle + math.pi, 2 * math.pi) - math.pi
    forces = azimuth_vectors(thrust, angle)
    got_thrust, got_angle = azimuth_commands(forces[:, 0], forces[:, 1], math.pi / 2)
    np.testing.assert_allclose(got_thrust, thrust, atol=1e-12)
    moving = thrust != 0.0
    np.testing.assert_allclose(np.cos(got_angle[moving] - angle[moving]), 1.0, atol=1e-12)
    previous = math.pi / 2
    for k in range(300):  # the stream's rule is the scalar rule, row by row
        fx, fy = float(forces[k, 0]), float(forces[k, 1])
        assert (got_thrust[k], got_angle[k]) == azimuth_command(fx, fy, previous)
        previous = got_angle[k]
