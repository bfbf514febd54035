"""Unit tests of the Push-Net-style sampling baseline (push_core.pushnet): hand-checkable."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.geometry import closest_point_on_polyline
from push_core.planner import NoFeasiblePush, prepare_outline
from push_core.pushnet import PushNetConfig, PushNetPlanner, sample_pushes, subgoal
from push_core.shapes import Polygon

SQUARE = [[0.04, -0.04], [0.04, 0.04], [-0.04, 0.04], [-0.04, -0.04]]  # 8 cm, CCW


def square_outline():
    points, normals = Polygon(np.array(SQUARE)).outline(0.002)
    return prepare_outline(points, normals)


def state(x=0.0, y=0.0, theta=0.0):
    # COM at the centre, l of a square's uniform pressure ~ 0.38 * side, m = 0.25
    return np.array([x, y, theta, 0.0, 0.0, 0.03, 0.25])


def test_subgoal_is_the_goal_when_close():
    np.testing.assert_allclose(subgoal([0, 0, 0], [0.03, 0.0, 0.1], 0.05, math.radians(10)),
                               [0.03, 0.0, 0.1])


def test_subgoal_limits_translation_to_5_cm():
    np.testing.assert_allclose(subgoal([0.1, 0, 0], [0.1, 0.2, 0.0], 0.05, math.radians(10)),
                               [0.1, 0.05, 0.0])


def test_subgoal_limits_rotation_and_scales_translation_with_it():
    # 2 cm and 20 deg away: the rotation limit (10 deg) halves both.
    got = subgoal([0, 0, 0], [0.02, 0.0, math.radians(20)], 0.05, math.radians(10))
    np.testing.assert_allclose(got, [0.01, 0.0, math.radians(10)])


def test_subgoal_wraps_the_rotation():
    got = subgoal([0, 0, math.radians(175)], [0, 0, math.radians(-175)], 0.05,
                  math.radians(10))
    np.testing.assert_allclose(got[2], math.radians(185))  # +10 deg, the short way


def test_samples_start_outside_with_clearance_and_end_inside():
    outline = square_outline()
    rng = np.random.default_rng(0)
    start, end = sample_pushes(outline, 500, rng, start_margin=0.05, clearance=0.006)
    assert start.shape == end.shape == (500, 2)
    sd_start = closest_point_on_polyline(outline.polyline, start)[2]
    sd_end = closest_point_on_polyline(outline.polyline, end)[2]
    assert np.all(sd_start >= 0.006)
    assert np.all(sd_end < 0.0)
    assert np.all(np.abs(start) <= 0.04 + 0.05 + 1e-12)
    # the ends cover the square (uniform): every quadrant gets a share
    for sx in (-1, 1):
        for sy in (-1, 1):
            share = np.mean((np.sign(end[:, 0]) == sx) & (np.sign(end[:, 1]) == sy))
            assert 0.15 < share < 0.35


def test_plan_pushes_toward_a_pure_translation_goal():
    planner = PushNetPlanner(PushNetConfig(seed=1))
    plan = planner.plan(square_outline(), state(), [0.10, 0.0, 0.0])
    np.testing.assert_allclose(plan.subgoal, [0.05, 0.0, 0.0])
    direction = (plan.end - plan.approach) / np.linalg.norm(plan.end - plan.approach)
    assert direction[0] > 0.9  # pushes along +x
    assert plan.approach[0] < -0.04  # lowered behind the object
    assert plan.predicted_pose[0] > 0.03  # predicted to move most of the 5 cm
    assert plan.score < plan.current_score
    # contact on the push line, between approach and end
    t = np.dot(plan.contact - plan.approach, direction)
    assert 0.0 < t < np.linalg.norm(plan.end - plan.approach)
    rel = plan.contact - plan.approach
    off = direction[0] * rel[1] - direction[1] * rel[0]
    assert abs(off) < 1e-9


def test_plan_turns_for_a_pure_rotation_goal():
    planner = PushNetPlanner(PushNetConfig(seed=2))
    plan = planner.plan(square_outline(), state(), [0.0, 0.0, math.radians(30)])
    assert plan.predicted_pose[2] > math.radians(4)  # counter-clockwise toward the sub-goal


def test_plan_is_seeded():
    a = PushNetPlanner(PushNetConfig(seed=3)).plan(square_outline(), state(), [0.1, 0.1, 0.3])
    b = PushNetPlanner(PushNetConfig(seed=3)).plan(square_outline(), state(), [0.1, 0.1, 0.3])
    c = PushNetPlanner(PushNetConfig(seed=4)).plan(square_outline(), state(), [0.1, 0.1, 0.3])
    np.testing.assert_array_equal(a.end, b.end)
    assert not np.array_equal(a.end, c.end)


def test_no_feasible_push_when_the_workspace_excludes_the_samples():
    planner = PushNetPlanner(PushNetConfig(workspace=((0.2, 0.25), (0.2, 0.25))))
    with pytest.raises(NoFeasiblePush):
        planner.plan(square_outline(), state(), [0.1, 0.0, 0.0])


def test_reached_uses_the_region():
    planner = PushNetPlanner(PushNetConfig(tolerance_xy=0.05, tolerance_theta=0.2))
    assert planner.reached([0.04, 0, 0.1], [0, 0, 0])
    assert not planner.reached([0.06, 0, 0.1], [0, 0, 0])


@pytest.mark.parametrize("kwargs, match", [
    ({"n_samples": 0}, "n_samples"),
    ({"subgoal_xy": -1.0}, "subgoal_xy"),
    ({"start_margin": float("nan")}, "start_margin"),
    ({"lam": -1.0}, "lam"),
    ({"workspace": ((1, 0), (0, 1))}, "workspace"),
])
def test_config_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PushNetConfig(**kwargs)


def test_plan_rejects_bad_state():
    with pytest.raises(ValueError, match="state"):
        PushNetPlanner().plan(square_outline(), [0, 0, 0], [0.1, 0, 0])
