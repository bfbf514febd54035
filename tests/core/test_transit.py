"""push_core.transit: distances and the visibility-graph pusher paths, against a square
obstacle whose shortest detour has a closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.transit import (
    TransitPlanner,
    ccw_polygon,
    point_polygon_distance,
    segment_polygon_clear,
)

#: A 1 x 1 square centred on the origin, counter-clockwise.
SQUARE = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])


def test_ccw_polygon_accepts_either_orientation() -> None:
    np.testing.assert_array_equal(ccw_polygon(SQUARE), SQUARE)
    np.testing.assert_array_equal(ccw_polygon(SQUARE[::-1]), SQUARE)  # reversed back
    with pytest.raises(ValueError, match="wall"):
        ccw_polygon([[0.0, 0.0], [1.0, 0.0]], "wall")


def test_point_polygon_distance_is_signed() -> None:
    d = point_polygon_distance([[0.0, 0.0], [0.8, 0.0], [0.8, 0.9], [0.5, 0.2]], SQUARE[::-1])
    np.testing.assert_allclose(d, [-0.5, 0.3, 0.5, 0.0], atol=1e-15)  # 0.3-0.4-0.5 corner


def test_segment_polygon_clear() -> None:
    starts = np.array([[-1.0, 0.7], [-1.0, 0.55], [-1.0, 0.0], [0.0, 0.0]])
    ends = np.array([[1.0, 0.7], [1.0, 0.55], [1.0, 0.0], [0.1, 0.0]])
    ok = segment_polygon_clear(starts, ends, [SQUARE], 0.1)
    # 0.2 above: clear; 0.05 above: too close; through it; inside it.
    assert ok.tolist() == [True, False, False, False]


def test_free_straight_path() -> None:
    planner = TransitPlanner([SQUARE], 0.1)
    path = planner.path([-1.0, 0.8], [1.0, 0.8])
    np.testing.assert_allclose(path, [[-1.0, 0.8], [1.0, 0.8]])
    assert planner.lengths([-1.0, 0.8], [[1.0, 0.8]]) == pytest.approx([2.0])


def _length(path: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


def test_detour_around_a_square_is_near_the_exact_shortest_path() -> None:
    # From (-1, 0) to (1, 0) with clearance r = 0.1: tangent to the rounded corner (centre at
    # distance sqrt(0.5), tangent sqrt(0.5 - r^2) = 0.7), an arc of atan2(4, 3) rad, the side
    # (1 m), and the same on the other end.
    exact = 2 * (0.7 + 0.1 * math.atan2(4.0, 3.0)) + 1.0
    planner = TransitPlanner([SQUARE], 0.1)
    path = planner.path([-1.0, 0.0], [1.0, 0.0])
    np.testing.assert_allclose(path[[0, -1]], [[-1.0, 0.0], [1.0, 0.0]])
    assert exact <= _length(path) <= 1.01 * exact  # corner nodes circumscribe the arcs
    assert segment_polygon_clear(path[:-1], path[1:], [SQUARE], 0.0999).all()
    assert planner.lengths([-1.0, 0.0], [[1.0, 0.0]]) == pytest.approx([_length(path)])


def test_a_workspace_too_narrow_for_the_detour_has_no_path() -> None:
    planner = TransitPlanner([SQUARE], 0.1, workspace=((-2.0, 2.0), (-0.55, 0.55)))
    assert planner.path([-1.0, 0.0], [1.0, 0.0]) is None
    assert planner.lengths([-1.0, 0.0], [[1.0, 0.0]]).tolist() == [math.inf]


def test_retreat_moves_out_to_the_clearance() -> None:
    planner = TransitPlanner([SQUARE], 0.1)
    np.testing.assert_allclose(planner.retreat([0.9, 0.0]), [0.9, 0.0])  # already clear
    out = planner.retreat([0.55, 0.0])
    assert out[1] == pytest.approx(0.0) and 0.6 <= out[0] <= 0.61
    inside = planner.retreat([0.0, 0.0])  # out through the nearest edge
    assert point_polygon_distance(inside[None], SQUARE)[0] >= 0.1 * (1 - 1e-9)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"clearance": 0.0}, "clearance: expected a finite number > 0"),
    ({"clearance": math.nan}, "clearance: expected a finite number > 0"),
    ({"clearance": 0.1, "workspace": ((1.0, -1.0), (0.0, 1.0))}, "workspace: expected"),
    ({"clearance": 0.1, "obstacles": [SQUARE, [[0.0, 0.0], [1.0, 1.0]]]}, r"obstacles\[1\]"),
])
def test_transit_planner_checks_its_inputs(kwargs: dict, match: str) -> None:
    obstacles = kwargs.pop("obstacles", [SQUARE])
    with pytest.raises(ValueError, match=match):
        TransitPlanner(obstacles, **kwargs)
