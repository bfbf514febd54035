"""Unit tests of push_core.push_search: the pusher's points of a push, the directions the
optimisation admits, the rotation weight of a symmetric outline."""

import math

import numpy as np
import pytest

from push_core.objects import load_object
from push_core.plan_inputs import prepare_outline
from push_core.planner_config import PlannerConfig
from push_core.push_search import (
    BASE_ANGLES_DEG,
    INTERPOLATION_STEPS,
    _admitted,
    pusher_points,
    rotation_weight,
)


def test_pusher_points_by_hand(square) -> None:
    cfg = PlannerConfig(pusher_radius=0.005, approach_clearance=0.01)
    left = int(np.argmin(square.points[:, 0] + np.abs(square.points[:, 1])))  # (-A, 0)
    point = square.points[left]
    assert square.normals[left] == pytest.approx([-1.0, 0.0])
    # Along the inward normal (+x), 2 cm past the touching position, object frame = world.
    approach, contact, end = pusher_points(cfg, square, np.zeros(3), left, 0.0, 0.02)
    np.testing.assert_allclose(contact, point + [-0.005, 0.0], atol=1e-15)
    np.testing.assert_allclose(approach, contact - [0.01, 0.0], atol=1e-15)
    np.testing.assert_allclose(end, contact + [0.02, 0.0], atol=1e-15)
    # The object turned by 90 deg and moved: the same points, rotated and shifted.
    pose = np.array([0.1, -0.05, math.pi / 2])
    turned = pusher_points(cfg, square, pose, left, 0.0, 0.02)
    for before, after in zip((approach, contact, end), turned, strict=True):
        np.testing.assert_allclose(after, [0.1 - before[1], -0.05 + before[0]], atol=1e-15)
    # 30 deg counter-clockwise from the inward normal.
    _, c30, e30 = pusher_points(cfg, square, np.zeros(3), left, math.radians(30.0), 0.02)
    np.testing.assert_allclose(e30 - c30, 0.02 * np.array([math.cos(math.radians(30.0)),
                                                          math.sin(math.radians(30.0))]),
                               atol=1e-15)


def test_admitted_directions_are_the_base_ones_and_the_best_ones_neighbours() -> None:
    step = INTERPOLATION_STEPS + 1
    n_fine = (len(BASE_ANGLES_DEG) - 1) * step + 1
    score = np.full((2, n_fine), 10.0)
    score[0, 2 * step] = 1.0  # point 0: best base direction 0 deg (column 6)
    score[1, 0] = 1.0  # point 1: best base direction -60 deg (column 0)
    score[1, 1] = 0.0  # an interpolated direction scores better: it does not decide
    admitted = _admitted(score.reshape(-1)).reshape(2, n_fine)
    base = set(range(0, n_fine, step))
    assert set(np.flatnonzero(admitted[0])) == base | {4, 5, 7, 8}
    assert set(np.flatnonzero(admitted[1])) == base | {1, 2}


def test_the_rotation_weight_is_zero_for_a_disc() -> None:
    cfg = PlannerConfig(lam=2.0)
    disc = prepare_outline(*load_object("ellip1").outline(0.002))
    hexagon = prepare_outline(*load_object("hex").outline(0.002))
    assert rotation_weight(cfg, disc) == 0.0
    assert rotation_weight(cfg, hexagon) == 2.0
