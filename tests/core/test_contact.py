"""push_core.estimator.contact: the EKF's outline, against closed forms (square, rectangle,
disc)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator.contact import ContactOutline, area_second_moment, limit_surface_of_polygon

#: A 10 cm square centred on the origin, counter-clockwise.
SQUARE = np.array([[0.05, -0.05], [0.05, 0.05], [-0.05, 0.05], [-0.05, -0.05]])


def test_limit_surface_of_a_square_is_its_mean_distance_from_the_centre() -> None:
    # Mean distance from the centre over a square of side s: s (sqrt 2 + asinh 1) / 6.
    s = 0.1
    expected = s * (math.sqrt(2.0) + math.asinh(1.0)) / 6.0
    assert limit_surface_of_polygon(SQUARE) == pytest.approx(expected, rel=1e-12)


def test_limit_surface_of_a_disc_is_two_thirds_of_its_radius() -> None:
    r, n = 0.04, 2000
    t = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    disc = r * np.column_stack([np.cos(t), np.sin(t)])
    assert limit_surface_of_polygon(disc) == pytest.approx(2 * r / 3, rel=1e-5)


def test_limit_surface_about_a_corner() -> None:
    # About a corner the square of side s is a quarter of a square of side 2 s about its centre:
    # the mean distance doubles.
    at_corner = limit_surface_of_polygon(SQUARE, com=(0.05, 0.05))
    assert at_corner == pytest.approx(2 * limit_surface_of_polygon(SQUARE), rel=1e-12)


def test_area_second_moment_of_a_rectangle() -> None:
    w, h = 0.12, 0.04
    rect = np.array([[0, 0], [w, 0], [w, h], [0, h]]) - [w / 2, h / 2]
    np.testing.assert_allclose(area_second_moment(rect), np.diag([w**2 / 12, h**2 / 12]),
                               atol=1e-15)
    # About a shifted origin: E[x^2] gains the offset squared, E[xy] the product of offsets.
    shifted = area_second_moment(rect + [0.01, 0.02])
    np.testing.assert_allclose(shifted, [[w**2 / 12 + 1e-4, 2e-4], [2e-4, h**2 / 12 + 4e-4]],
                               atol=1e-15)


def _dense_square() -> tuple[np.ndarray, np.ndarray]:
    """50 points per side of SQUARE, corners included; each with its side's outward normal."""
    f = np.linspace(0.0, 1.0, 50, endpoint=False)[:, None]
    ends = np.roll(SQUARE, -1, axis=0)
    points = np.concatenate([a + f * (b - a) for a, b in zip(SQUARE, ends, strict=True)])
    sides = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    return points, np.repeat(sides, 50, axis=0)


def test_from_points_decimates_to_the_corners_and_detects_the_symmetry() -> None:
    points, normals = _dense_square()
    outline = ContactOutline.from_points(points, normals, symmetry_order=0)
    assert len(outline.vertices) == 4 and outline.convex.all()
    assert outline.area == pytest.approx(0.01, rel=1e-9)
    assert outline.symmetry_order == 4
    np.testing.assert_allclose(outline.lengths, 0.1, rtol=1e-6)
    # Outward normals: each is the tangent turned clockwise, unit length.
    np.testing.assert_allclose(outline.normals, np.column_stack([outline.tangents[:, 1],
                                                                 -outline.tangents[:, 0]]))
    np.testing.assert_allclose(np.hypot(*outline.normals.T), 1.0)
    np.testing.assert_allclose(outline.area_moment, np.diag([0.1**2 / 12] * 2), rtol=1e-6,
                               atol=1e-15)
    assert outline.limit_surface == pytest.approx(limit_surface_of_polygon(SQUARE), rel=1e-6)
    assert outline.radius == pytest.approx(0.05 * math.sqrt(2))  # the corners


def test_closest_feature_segment_or_vertex() -> None:
    outline = ContactOutline.from_points(SQUARE, tolerance=1e-4)
    v = outline.vertices
    kind, i = outline.closest_feature(0.2, 0.01)  # right of the square: the x = 0.05 side
    assert kind == 0
    np.testing.assert_allclose(outline.normals[i], [1.0, 0.0], atol=1e-12)
    kind, i = outline.closest_feature(0.2, 0.2)  # beyond the corner: the vertex
    assert kind == 1
    np.testing.assert_allclose(v[i], [0.05, 0.05])


def test_clip_to_hull_projects_outside_points_only() -> None:
    outline = ContactOutline.from_points(SQUARE)
    assert outline.clip_to_hull(0.01, -0.02) == (0.01, -0.02)
    assert outline.clip_to_hull(0.2, 0.0) == pytest.approx((0.05, 0.0))
    assert outline.clip_to_hull(0.2, 0.3) == pytest.approx((0.05, 0.05))


@pytest.mark.parametrize(("points", "normals", "kwargs", "match"), [
    (SQUARE[:2], None, {}, r"points must have shape \(N, 2\) with N >= 3"),
    (SQUARE[::-1], None, {}, "points: polygon is clockwise"),
    (np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]), None, {},
     "points: polygon is self-intersecting"),
    (SQUARE, None, {"tolerance": 0.0}, "tolerance must be > 0"),
    (SQUARE, None, {"symmetry_order": -1}, "symmetry_order must be >= 0"),
    (SQUARE, np.ones((3, 2)), {}, "normals must have the shape of points"),
    (SQUARE, 2 * SQUARE / np.hypot(*SQUARE.T)[:, None], {}, "normals must be unit vectors"),
])
def test_from_points_refuses_bad_outlines(points: np.ndarray, normals: np.ndarray | None,
                                          kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ContactOutline.from_points(points, normals, **kwargs)


def test_from_points_refuses_inward_normals() -> None:
    points, normals = _dense_square()
    with pytest.raises(ValueError, match=r"normals must point outward .* only 0 % do"):
        ContactOutline.from_points(points, -normals)
