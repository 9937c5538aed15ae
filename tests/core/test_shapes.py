"""Convex shapes: distance, overlap, inflation against closed forms."""

from __future__ import annotations

import math

import pytest

from hil.core.shapes import Polygon, Rect, convex_distance_m, shapes_overlap


def test_distance_between_rectangles_is_the_gap() -> None:
    assert convex_distance_m(Rect(0, 1, 0, 1), Rect(2, 3, 0, 1)) == pytest.approx(1.0)
    # Corner to corner: (1, 1) to (2, 3).
    assert convex_distance_m(Rect(0, 1, 0, 1), Rect(2, 3, 3, 4)) == pytest.approx(math.sqrt(5))
    assert convex_distance_m(Rect(0, 1, 0, 1), Rect(1, 2, 0, 1)) == 0.0  # touching


def test_touching_is_not_overlap() -> None:
    assert not shapes_overlap(Rect(0, 1, 0, 1), Rect(1, 2, 0, 1))
    assert shapes_overlap(Rect(0, 1, 0, 1), Rect(0.5, 2, 0.5, 2))


def test_rotated_rect_inflates_by_the_margin() -> None:
    square = Polygon.rotated_rect((0.0, 0.0), (2.0, 2.0), math.pi / 4)
    grown = square.inflate(0.5)
    # A square turned 45 deg: its vertex sits at sqrt(2) from the centre; each edge moved
    # out by 0.5 puts the vertex at sqrt(2) + 0.5 sqrt(2).
    assert max(x for x, _ in grown.vertices_m) == pytest.approx(1.5 * math.sqrt(2))
    assert not grown.is_empty()


def test_rect_may_be_empty_after_shrinking() -> None:
    assert Rect(0, 1, 0, 1).inflate(-0.6).is_empty()
    assert Rect(0, 1, 0, 1).translate(1.0, -1.0) == Rect(1, 2, -1, 0)
