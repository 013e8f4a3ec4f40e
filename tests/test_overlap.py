"""How deep boxes overlap planes, circles and other boxes, on configurations whose depth is
known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from qpbench.simulation.overlap import box_box_depth, box_plane_depth, circle_box_depth

UNIT = np.array([0.5, 0.5])  # half widths of a unit square
FLOOR = (np.zeros(2), np.array([0.0, 1.0]))


def test_a_square_sunk_into_the_floor_overlaps_by_how_far_its_lowest_vertex_is_below() -> None:
    assert box_plane_depth(np.array([0.0, 0.4]), 0.0, UNIT, *FLOOR) == pytest.approx(0.1)
    # on a corner: the lowest vertex is half a diagonal below the centre
    centre = np.array([3.0, 0.7])
    assert box_plane_depth(centre, math.pi / 4, UNIT, *FLOOR) == \
        pytest.approx(0.5 * math.sqrt(2) - 0.7)
    assert box_plane_depth(np.array([0.0, 0.6]), 0.0, UNIT, *FLOOR) == 0.0


def test_a_circle_overlaps_a_box_by_its_radius_less_its_distance_to_the_box() -> None:
    box, half = np.zeros(2), np.array([1.0, 1.0])
    assert circle_box_depth(np.array([1.3, 0.0]), 0.5, box, 0.0, half) == pytest.approx(0.2)
    assert circle_box_depth(np.array([1.3, 1.3]), 0.5, box, 0.0, half) == \
        pytest.approx(0.5 - 0.3 * math.sqrt(2))
    assert circle_box_depth(np.array([2.0, 0.0]), 0.5, box, 0.0, half) == 0.0
    # the centre inside: the radius plus the way out through the nearest face
    assert circle_box_depth(np.array([0.8, 0.0]), 0.5, box, 0.0, half) == pytest.approx(0.7)
    # the box turned a quarter turn is the same box
    assert circle_box_depth(np.array([1.3, 0.0]), 0.5, box, math.pi / 2, half) == \
        pytest.approx(0.2)


def test_two_boxes_overlap_by_the_least_overlap_over_their_face_normals() -> None:
    origin = np.zeros(2)
    assert box_box_depth(origin, 0.0, UNIT, np.array([0.8, 0.1]), 0.0, UNIT) == \
        pytest.approx(0.2)
    assert box_box_depth(origin, 0.0, UNIT, np.array([1.2, 0.0]), 0.0, UNIT) == 0.0
    # a diamond whose corner reaches 0.1 into the square's right face
    corner = 0.5 * math.sqrt(2)
    diamond = np.array([0.5 + corner - 0.1, 0.0])
    assert box_box_depth(origin, 0.0, UNIT, diamond, math.pi / 4, UNIT) == pytest.approx(0.1)
    # beside each other diagonally, separated along the diamond's own face normal
    far = np.array([0.5 + corner + 0.05, 0.5 + 0.3])
    assert box_box_depth(origin, 0.0, UNIT, far, math.pi / 4, UNIT) == 0.0
