"""The compiled box narrow phase (``qpbench.simulation.boxes``) on hand-made configurations.

Each expected contact is worked out by hand from SCISim's rules (``BoxBoxTools``,
``CircleBoxTools``, ``computeBodyPlaneActiveSetAllPairs``): the contact point in the middle
of the overlap, the normal from body b towards body a, the arms from the start centres, the
vertices in SCISim's order, and a kinematic box or circle against a box refused.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from qpbench.errors import UnsupportedError
from qpbench.simulation.boxes import box_contacts
from qpbench.simulation.broad_phase import candidate_pairs
from qpbench.simulation.contacts import BODY_BODY, BOX_PLANE, Contacts

CIRCLE = (math.nan, math.nan)  # half-widths of a circle
NO_PLANES = np.zeros((0, 2))


def contacts_of(positions: list[tuple[float, float]], half_widths: list[tuple[float, float]],
                theta: list[float], radii: list[float] | None = None,
                fixed: list[bool] | None = None, theta0: list[float] | None = None,
                planes: tuple[np.ndarray, np.ndarray] = (NO_PLANES, NO_PLANES)
                ) -> tuple[Contacts, Contacts]:
    """box_contacts of bodies at rest (x0 = x1); a box's radius is its circumradius."""
    x = np.array(positions, dtype=float)
    half = np.array(half_widths, dtype=float)
    if radii is None:
        radii = [math.hypot(*h) for h in half_widths]
    count = len(positions)
    return box_contacts(x, x.copy(), np.array(theta0 if theta0 is not None else theta,
                                              dtype=float),
                        np.array(theta, dtype=float), np.array(radii, dtype=float), half,
                        np.array(fixed or [False] * count), planes[0], planes[1],
                        where="scene.xml: ")


def test_a_box_resting_flat_on_another_touches_at_both_ends_of_the_overlap() -> None:
    # box 1 sinks 0.01 into box 0's top face: SCISim clips box 1's bottom face to box 0's
    # top face and puts each end in the middle of the overlap
    body_body, planes = contacts_of([(0.0, 0.0), (0.0, 0.99)], [(0.5, 0.5)] * 2, [0.0, 0.0])
    assert planes.count == 0 and body_body.count == 2
    assert body_body.body_a.tolist() == [0, 0] and body_body.body_b.tolist() == [1, 1]
    assert np.all(body_body.kind == BODY_BODY) and body_body.point.tolist() == [0, 1]
    assert np.allclose(body_body.normals, [[0.0, -1.0], [0.0, -1.0]])  # from 1 towards 0
    points = np.array([[-0.5, 0.495], [0.5, 0.495]])
    assert np.allclose(body_body.arms[:, 0:2], points - [0.0, 0.0], atol=1e-12)
    assert np.allclose(body_body.arms[:, 2:4], points - [0.0, 0.99], atol=1e-12)


def test_a_narrower_box_on_a_wider_one_is_clipped_to_its_own_face() -> None:
    # the incident face (box 1's bottom, 0.6 wide) lies inside box 0's top face (2 wide)
    body_body, _ = contacts_of([(0.3, 0.0), (0.0, 0.78)], [(1.0, 0.5), (0.3, 0.3)], [0.0, 0.0])
    points = np.array([[-0.3, 0.49], [0.3, 0.49]])
    assert body_body.count == 2
    assert np.allclose(body_body.arms[:, 0:2], points - [0.3, 0.0], atol=1e-12)


@pytest.mark.parametrize("rotated_first", [False, True])
def test_a_rotated_box_pressing_a_corner_into_a_face_has_one_contact(rotated_first: bool
                                                                       ) -> None:
    # a box turned by 45 degrees, its lowest corner 0.02 deep in the top face of a flat box:
    # one contact, at the corner moved up by half the depth; the other clipped end is above
    corner_height = 0.5 - 0.02
    rotated = (0.0, corner_height + math.sqrt(0.5))
    flat = (0.0, 0.0)
    positions = [rotated, flat] if rotated_first else [flat, rotated]
    theta = [math.pi / 4, 0.0] if rotated_first else [0.0, math.pi / 4]
    body_body, _ = contacts_of(positions, [(0.5, 0.5)] * 2, theta)
    assert body_body.count == 1 and body_body.point.tolist() == [0]
    assert (body_body.body_a[0], body_body.body_b[0]) == (0, 1)
    up = 1.0 if rotated_first else -1.0  # the normal points from body 1 towards body 0
    assert np.allclose(body_body.normals[0], [0.0, up], atol=1e-12)
    point = np.array([0.0, 0.49])
    assert np.allclose(body_body.arms[0, 0:2], point - positions[0], atol=1e-12)
    assert np.allclose(body_body.arms[0, 2:4], point - positions[1], atol=1e-12)


@pytest.mark.parametrize("circle_first", [True, False])
def test_a_circle_against_a_face_touches_in_the_middle_of_the_overlap(circle_first: bool
                                                                        ) -> None:
    circle, box = (0.2, 0.99), (0.0, 0.0)  # 0.01 into the top face of a 2 x 1 box
    positions = [circle, box] if circle_first else [box, circle]
    half = [CIRCLE, (1.0, 0.5)] if circle_first else [(1.0, 0.5), CIRCLE]
    radii = [0.5, math.hypot(1.0, 0.5)] if circle_first else [math.hypot(1.0, 0.5), 0.5]
    body_body, _ = contacts_of(positions, half, [0.0, 0.0], radii)
    assert body_body.count == 1 and (body_body.body_a[0], body_body.body_b[0]) == (0, 1)
    # n points from b to a: up when the circle is a, down when the box is
    assert np.allclose(body_body.normals[0], [0.0, 1.0 if circle_first else -1.0])
    point = np.array([0.2, 0.495])
    assert np.allclose(body_body.arms[0, 0:2], point - positions[0], atol=1e-12)
    assert np.allclose(body_body.arms[0, 2:4], point - positions[1], atol=1e-12)


def test_a_circle_against_a_face_of_a_turned_box_uses_the_box_frame() -> None:
    # the same 2 x 1 box turned by 90 degrees: its long side is vertical, and the circle
    # touches the face that now looks along +x
    body_body, _ = contacts_of([(0.99, 0.2), (0.0, 0.0)], [CIRCLE, (1.0, 0.5)],
                               [0.0, math.pi / 2], [0.5, math.hypot(1.0, 0.5)])
    assert body_body.count == 1
    assert np.allclose(body_body.normals[0], [1.0, 0.0], atol=1e-12)
    assert np.allclose(body_body.arms[0, 2:4], [0.495, 0.2], atol=1e-12)


@pytest.mark.parametrize("quadrant", [(1.0, 1.0), (-1.0, -1.0), (-1.0, 1.0)])
def test_a_circle_against_a_corner_has_the_normal_through_the_corner(quadrant: tuple) -> None:
    sx, sy = quadrant
    centre = (sx * 0.8, sy * 0.8)  # 0.3 beyond the corner (0.5, 0.5) along each axis
    body_body, _ = contacts_of([(0.0, 0.0), centre], [(0.5, 0.5), CIRCLE], [0.0, 0.0],
                               [math.hypot(0.5, 0.5), 0.5])
    assert body_body.count == 1 and (body_body.body_a[0], body_body.body_b[0]) == (0, 1)
    outward = np.array([sx, sy]) / math.sqrt(2.0)  # from the box towards the circle
    assert np.allclose(body_body.normals[0], -outward)  # b (circle) towards a (box)
    depth = math.hypot(0.3, 0.3) - 0.5  # negative: overlapping
    point = np.array([sx * 0.5, sy * 0.5]) + 0.5 * depth * outward
    assert np.allclose(body_body.arms[0, 0:2], point, atol=1e-12)
    assert np.allclose(body_body.arms[0, 2:4], point - centre, atol=1e-12)


def test_bodies_whose_collision_boxes_overlap_but_which_are_apart_have_no_contact() -> None:
    # a circle off a box's corner, and two diamonds side by side along their diagonal: each
    # pair is a broad-phase candidate, but the narrow phase finds them apart
    positions = [(0.0, 0.0), (0.9, 0.9), (10.0, 0.0), (11.1, 1.1)]
    half = [(0.5, 0.5), CIRCLE, (0.5, 0.5), (0.5, 0.5)]
    theta = [0.0, 0.0, math.pi / 4, math.pi / 4]
    radii = [math.hypot(0.5, 0.5), 0.5, math.hypot(0.5, 0.5), math.hypot(0.5, 0.5)]
    extents = np.array([[0.5, 0.5], [0.5, 0.5], [math.sqrt(0.5)] * 2, [math.sqrt(0.5)] * 2])
    x = np.array(positions)
    assert candidate_pairs(x - extents, x + extents).tolist() == [[0, 1], [2, 3]]
    body_body, planes = contacts_of(positions, half, theta, radii)
    assert body_body.count == 0 and planes.count == 0


def test_contacts_come_in_candidate_pair_order() -> None:
    # three boxes in a row, each 0.01 into the next, and a circle on top of the middle one
    positions = [(0.0, 0.0), (0.99, 0.0), (1.98, 0.0), (0.99, 0.99)]
    half = [(0.5, 0.5)] * 3 + [CIRCLE]
    radii = [math.hypot(0.5, 0.5)] * 3 + [0.5]
    body_body, _ = contacts_of(positions, half, [0.0] * 4, radii)
    pairs = list(zip(body_body.body_a.tolist(), body_body.body_b.tolist(), strict=True))
    assert pairs == [(0, 1), (0, 1), (1, 2), (1, 2), (1, 3)]
    assert body_body.point.tolist() == [0, 1, 0, 1, 0]


def test_box_vertices_at_or_below_a_plane_in_scisims_order_with_arms_at_theta0() -> None:
    # the box's two lower vertices are 0.01 below the floor at x1 (theta1 = 0); the arms
    # are the same vertices turned by the start angle theta0
    floor = (np.array([[0.0, 0.0]]), np.array([[0.0, 1.0]]))
    _, planes = contacts_of([(0.0, 0.49)], [(0.5, 0.5)], [0.0], theta0=[0.1], planes=floor)
    assert planes.count == 2 and np.all(planes.kind == BOX_PLANE)
    assert planes.point.tolist() == [0, 2]  # vertices (-hx, -hy) and (+hx, -hy)
    assert planes.body_b.tolist() == [-1, -1] and planes.boundary.tolist() == [0, 0]
    assert np.allclose(planes.normals, [[0.0, 1.0], [0.0, 1.0]])
    c, s = math.cos(0.1), math.sin(0.1)
    arms = [[c * -0.5 - s * -0.5, s * -0.5 + c * -0.5], [c * 0.5 - s * -0.5, s * 0.5 + c * -0.5]]
    assert np.allclose(planes.arms[:, 0:2], arms, atol=1e-15)
    assert np.all(np.isnan(planes.arms[:, 2:4]))


def test_a_fixed_box_has_no_plane_contacts_and_planes_come_first_in_the_order() -> None:
    # floor and left wall; box 0 in the corner, box 1 (fixed) below the floor, box 2 on it
    walls = (np.zeros((2, 2)), np.array([[0.0, 1.0], [1.0, 0.0]]))
    _, planes = contacts_of([(0.49, 0.49), (5.0, -1.0), (9.0, 0.5)], [(0.5, 0.5)] * 3,
                            [0.0, 0.0, 0.0], fixed=[False, True, False], planes=walls)
    rows = list(zip(planes.boundary.tolist(), planes.body_a.tolist(), planes.point.tolist(),
                    strict=True))
    assert rows == [(0, 0, 0), (0, 0, 2), (0, 2, 0), (0, 2, 2), (1, 0, 0), (1, 0, 1)]


@pytest.mark.parametrize(("fixed", "message"), [
    ([True, False], "scene.xml: bodies #0 and #1: kinematic box-box contacts"),
    ([False, True], "scene.xml: bodies #0 and #1: kinematic box-box contacts"),
])
def test_a_kinematic_box_against_a_box_is_refused(fixed: list[bool], message: str) -> None:
    with pytest.raises(UnsupportedError, match=message) as raised:
        contacts_of([(0.0, 0.0), (0.0, 0.99)], [(0.5, 0.5)] * 2, [0.0, 0.0], fixed=fixed)
    assert str(raised.value).endswith("(SCISim stops there too)")


def test_a_kinematic_circle_against_a_box_is_refused_the_circle_named_first() -> None:
    with pytest.raises(UnsupportedError,
                       match="bodies #1 and #0: kinematic circle-box contacts"):
        contacts_of([(0.0, 0.0), (0.0, 0.99)], [(0.5, 0.5), CIRCLE], [0.0, 0.0],
                    [math.hypot(0.5, 0.5), 0.5], fixed=[False, True])


def test_two_kinematic_bodies_and_a_kinematic_box_under_a_circle_are_not_refused() -> None:
    # both kinematic: no contact at all; a kinematic box under a free circle: the box second
    body_body, _ = contacts_of([(0.0, 0.0), (0.0, 0.99)], [(0.5, 0.5)] * 2, [0.0, 0.0],
                               fixed=[True, True])
    assert body_body.count == 0
    body_body, _ = contacts_of([(0.0, 0.0), (0.0, 0.99)], [(0.5, 0.5), CIRCLE], [0.0, 0.0],
                               [math.hypot(0.5, 0.5), 0.5], fixed=[True, False])
    assert (body_body.body_a[0], body_body.body_b[0]) == (1, 0)
    assert np.allclose(body_body.normals[0], [0.0, 1.0])  # from the box towards the circle
