"""push_core.shapes: polygons and ellipses against closed forms; every validation error names
its field."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.shapes import Ellipse, Polygon, polygon_signed_area

W, H = 0.12, 0.04
RECT = np.array([[0.0, 0.0], [W, 0.0], [W, H], [0.0, H]])
#: An L: a 2 x 2 square with its upper-right 1 x 1 quarter removed (non-convex).
ELL = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]])


def test_signed_area_follows_the_orientation() -> None:
    assert polygon_signed_area(RECT) == pytest.approx(W * H)
    assert polygon_signed_area(RECT[::-1]) == pytest.approx(-W * H)


def test_rectangle_area_centroid_and_polar_moment() -> None:
    rect = Polygon(RECT)
    assert rect.area == pytest.approx(W * H)
    np.testing.assert_allclose(rect.centroid, [W / 2, H / 2])
    # J about the centroid = A (w^2 + h^2) / 12; about a corner add A d^2 (parallel axes).
    j = W * H * (W**2 + H**2) / 12
    assert rect.polar_moment() == pytest.approx(j)
    assert rect.polar_moment(np.zeros(2)) == pytest.approx(j + W * H * (W**2 + H**2) / 4)
    assert rect.radius == pytest.approx(math.hypot(W, H))
    assert rect.is_convex


def test_l_shape_centroid_by_decomposition() -> None:
    # Three unit squares centred at (0.5, 0.5), (1.5, 0.5), (0.5, 1.5): centroid (5/6, 5/6).
    ell = Polygon(ELL)
    assert ell.area == pytest.approx(3.0)
    np.testing.assert_allclose(ell.centroid, [5 / 6, 5 / 6])
    assert not ell.is_convex
    pieces = ell.convex_pieces(tolerance=1e-6)
    assert len(pieces) >= 2
    assert sum(polygon_signed_area(p) for p in pieces) == pytest.approx(3.0)
    assert all(Polygon(p).is_convex for p in pieces)
    tris = ell.triangles()  # vertex indices, each triangle counter-clockwise
    assert tris.shape == (4, 3)  # a hexagon: P - 2 triangles
    areas = [polygon_signed_area(ELL[t]) for t in tris]
    assert min(areas) > 0 and sum(areas) == pytest.approx(3.0)


def test_translated_and_closed_ring() -> None:
    moved = Polygon(RECT).translated(np.array([1.0, -2.0]))
    np.testing.assert_allclose(moved.centroid, [1.0 + W / 2, -2.0 + H / 2])
    closed = Polygon(np.vstack([RECT, RECT[:1]]))  # an explicitly closed ring is tolerated
    assert len(closed.vertices) == 4


def test_outline_is_evenly_spaced_with_outward_normals() -> None:
    points, normals = Polygon(RECT).outline(spacing=0.004)
    perimeter = 2 * (W + H)
    assert len(points) == round(perimeter / 0.004)  # 80 interval centres
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    straight = steps > 0.0039  # steps along one side (around a corner they are shorter)
    np.testing.assert_allclose(steps[straight], 0.004, rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    # Outward: from the centroid to a point and that point's normal agree.
    assert np.all(np.sum((points - [W / 2, H / 2]) * normals, axis=1) > 0)
    with pytest.raises(ValueError, match="spacing: must be > 0"):
        Polygon(RECT).outline(spacing=0.0)


def test_simplified_keeps_corners_within_the_tolerance() -> None:
    poly = Polygon(np.concatenate([np.linspace(a, b, 30, endpoint=False)
                                   for a, b in zip(RECT, np.roll(RECT, -1, 0), strict=True)]))
    simple = poly.simplified(1e-4)
    assert len(simple.vertices) == 4
    np.testing.assert_allclose(np.sort(simple.vertices, axis=0), np.sort(RECT, axis=0))
    assert simple.area == pytest.approx(poly.area)


@pytest.mark.parametrize(("vertices", "match"), [
    ([[0.0, 0.0], [1.0, 0.0]], "shape.vertices: a polygon needs at least 3 vertices, got 2"),
    ([[0.0, 0.0], [1.0, 0.0, 2.0]], "shape.vertices: expected a list of"),
    ([[0.0, 0.0], [1.0, 0.0], [math.nan, 1.0]], "shape.vertices: vertices must be finite"),
    ([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0]], "vertices 1 and 2 coincide"),
    ([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], "shape.vertices: polygon has zero area"),
    (RECT[::-1], r"shape.vertices: polygon is clockwise \(signed area -0.0048 m\^2\)"),
    ([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]], "polygon is self-intersecting"),
])
def test_polygon_errors_name_the_field(vertices: list, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Polygon(vertices, field="shape.vertices")


def test_ellipse_closed_forms() -> None:
    e = Ellipse(0.05, 0.03)
    assert e.area == pytest.approx(math.pi * 0.05 * 0.03)
    assert e.polar_moment() == pytest.approx(e.area * (0.05**2 + 0.03**2) / 4)
    assert e.radius == 0.05 and e.is_convex
    assert Ellipse(0.04, 0.04).perimeter == pytest.approx(2 * math.pi * 0.04)
    points, normals = e.outline(spacing=0.002)
    np.testing.assert_allclose((points[:, 0] / 0.05) ** 2 + (points[:, 1] / 0.03) ** 2, 1.0)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    # The normal of x^2/a^2 + y^2/b^2 = 1 is parallel to (x / a^2, y / b^2).
    grad = points / [0.05**2, 0.03**2]
    np.testing.assert_allclose(normals[:, 0] * grad[:, 1] - normals[:, 1] * grad[:, 0], 0.0,
                               atol=1e-9)
    assert e.as_polygon().area == pytest.approx(e.area, rel=1e-3)


@pytest.mark.parametrize(("a", "b"), [(0.0, 0.03), (-0.05, 0.03), (math.inf, 0.03)])
def test_ellipse_refuses_bad_semi_axes(a: float, b: float) -> None:
    with pytest.raises(ValueError, match="shape: semi-axes must be finite and > 0"):
        Ellipse(a, b, field="shape")
