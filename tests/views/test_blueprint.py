"""The Rerun viewer layout: the arena seen from above, as `hil plot` draws it."""

from __future__ import annotations

import math

import numpy as np
import rerun as rr

from hil.scenarios import load_scenario
from hil.views.blueprint import blueprint, top_down_eye
from tests.views.rrd_store import Exported


def test_blueprint_builds_without_a_scenario() -> None:
    assert blueprint(None) is not None


def _on_screen(
    points_m: np.ndarray, position: np.ndarray, target: np.ndarray, up: np.ndarray
) -> np.ndarray:
    """Project arena points (N, 3) onto a camera's screen: (right, up), shape (N, 2)."""
    forward = (target - position) / np.linalg.norm(target - position)
    up = up - forward * float(up @ forward)
    right = np.cross(forward, up)  # a right-handed camera: right = forward x up
    return np.column_stack([points_m @ right, points_m @ up])


def _signed_area(points: np.ndarray) -> float:
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def test_the_eye_sees_the_arena_from_above_with_a_starboard_turn_clockwise() -> None:
    eye = top_down_eye(load_scenario("paper"))
    position, target, up = (np.array(v) for v in (eye.position_m, eye.look_target_m, eye.up))
    assert position[2] < target[2], "z is down: the eye must stand above the water (z < 0)"
    # North, a quarter turn to starboard (heading grows), then east: r > 0.
    arc = np.array(
        [[math.sin(a), 1.0 - math.cos(a), 0.0] for a in np.linspace(0.0, math.pi / 2, 9)]
    )
    screen = _on_screen(arc, position, target, up)
    assert _signed_area(screen) < 0, "a starboard turn must be drawn clockwise"
    # As `hil plot` draws it: x (north) to the right, y (east) down the screen.
    x_axis, y_axis = _on_screen(np.eye(3)[:2], position, target, up)
    np.testing.assert_allclose(x_axis, [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(y_axis, [0.0, -1.0], atol=1e-12)


def test_the_recording_declares_the_arena_frame_z_down(exported: Exported) -> None:
    chunks = exported.store.stream().filter(content="/world", is_static=True).to_chunks()
    batch = next(c for c in chunks if c.entity_path == "/world").to_record_batch()
    coordinates = batch.column("ViewCoordinates:xyz").to_pylist()[0][0]
    view_dir = rr.components.ViewCoordinates.ViewDir
    # x right, y back, z down: RIGHT_HAND_Z_DOWN (x north, y east, z down on the tank).
    assert coordinates == [d.value for d in (view_dir.Right, view_dir.Back, view_dir.Down)]
