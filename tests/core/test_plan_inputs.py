"""Unit tests of push_core.plan_inputs: the outline's validation and bounded size."""

import numpy as np
import pytest

from push_core.plan_inputs import MAX_OUTLINE_POINTS, prepare_outline


def test_bad_outline_names_the_argument(square_outline):
    points, normals = square_outline()
    with pytest.raises(ValueError, match="points"):
        prepare_outline(points[:2], normals[:2])
    with pytest.raises(ValueError, match="points"):
        prepare_outline(points[::-1], normals[::-1])  # clockwise
    bad = points.copy()
    bad[3, 0] = np.nan
    with pytest.raises(ValueError, match="points"):
        prepare_outline(bad, normals)
    zero = normals.copy()
    zero[5] = 0.0
    with pytest.raises(ValueError, match="normals_out"):
        prepare_outline(points, zero)
    with pytest.raises(ValueError, match="normals_out"):
        prepare_outline(points, normals[:-1])

def test_outlines_above_the_cap_are_decimated_and_normal_ones_kept(square, square_outline):
    points, normals = square_outline(1e-4)  # 3996 points
    big = prepare_outline(points, normals)
    assert len(big.points) == MAX_OUTLINE_POINTS and big.source_points == len(points)
    keep = np.linspace(0, len(points), MAX_OUTLINE_POINTS, endpoint=False).astype(np.intp)
    np.testing.assert_array_equal(big.points, points[keep])
    assert square.source_points == len(square.points)  # below the cap: as given
    small = prepare_outline(points, normals, max_points=50)
    assert len(small.points) == 50
    with pytest.raises(ValueError, match="max_points"):
        prepare_outline(points, normals, max_points=2)
