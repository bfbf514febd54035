"""push_core as a library: PushObject/Pusher, the transit planner, the planner's
obstacles, travel cost and "no push improves", the EKF with known COM/l and friction 0."""

import math
import warnings

import numpy as np
import pytest

from push_core.planner import NoFeasiblePush, NoImprovingPush, Planner, PlannerConfig
from push_core.pushable import Pusher, PushObject
from push_core.transit import TransitPlanner, point_polygon_distance, segment_polygon_clear

# A T in metres (bar on top of the stem), counter-clockwise, about an arbitrary origin.
TEE = np.array([(-60, 0), (60, 0), (60, 30), (15, 30), (15, 120), (-15, 120), (-15, 30),
                (-60, 30)], float) * 1e-3


def _path_clearance(path: np.ndarray, polygon: np.ndarray) -> float:
    """Smallest distance of a polyline from a polygon (dense sampling)."""
    t = np.linspace(0.0, 1.0, 200)[:, None]
    pts = np.concatenate([a + t * (b - a) for a, b in zip(path[:-1], path[1:], strict=True)])
    return float(point_polygon_distance(pts, polygon).min())


# ---- PushObject / Pusher ----------------------------------------------------------------------
def test_object_from_polygon_without_mass_or_thickness() -> None:
    obj = PushObject.from_polygon(TEE, com=(0.0, 0.045))
    assert obj.shape.area == pytest.approx(0.0063)
    assert obj.origin == pytest.approx([0.0, -0.0407142857])  # vertices' origin, object frame
    assert obj.com == pytest.approx([0.0, 0.045 - 0.0407142857])
    assert obj.friction == 0.25 and 0.02 < obj.limit_surface < 0.06  # stated defaults
    assert obj.notes == ()
    pose = obj.to_object_pose([0.1, 0.2, 0.7])
    assert obj.to_source_pose(pose) == pytest.approx([0.1, 0.2, 0.7])
    assert obj.state(pose)[3:] == pytest.approx([*obj.com, obj.limit_surface, 0.25])


def test_clockwise_polygon_is_reoriented_with_a_note() -> None:
    with pytest.warns(UserWarning, match="clockwise"):
        obj = PushObject.from_polygon(TEE[::-1], friction=0.0, limit_surface=0.05)
    assert obj.notes and "re-oriented" in obj.notes[0]
    ccw = PushObject.from_polygon(TEE, friction=0.0, limit_surface=0.05)
    assert obj.shape.area == pytest.approx(ccw.shape.area)
    assert obj.friction == 0.0 and obj.limit_surface == 0.05


def test_ellipse_and_bad_inputs() -> None:
    obj = PushObject.from_ellipse(0.05, 0.03)
    assert obj.com == pytest.approx([0.0, 0.0])
    with pytest.raises(ValueError, match="friction"):
        PushObject.from_polygon(TEE, friction=-1.0)
    with pytest.raises(ValueError, match="com_offset|com"):
        PushObject.from_polygon(TEE, com=(np.nan, 0.0))
    with pytest.raises(ValueError, match="vertices"):
        PushObject.from_polygon([[0, 0], [1, 1]])


def test_pusher_radius_is_set_in_one_place() -> None:
    pusher = Pusher(radius=0.015)
    obj = PushObject.from_polygon(TEE, friction=0.0)
    assert pusher.planner_config().pusher_radius == 0.015
    ekf = pusher.estimator(obj)
    assert ekf.config.pusher_radius == 0.015
    with pytest.raises(ValueError, match="once"):
        pusher.planner_config(pusher_radius=0.01)
    with pytest.raises(ValueError, match="radius"):
        Pusher(radius=-1.0)


# ---- transit ----------------------------------------------------------------------------------
def test_transit_goes_around_the_object_with_clearance() -> None:
    tp = TransitPlanner([TEE], clearance=0.016)
    start, goal = np.array([0.0, -0.04]), np.array([0.0, 0.16])
    path = tp.path(start, goal)
    assert path is not None
    assert path[0] == pytest.approx(start) and path[-1] == pytest.approx(goal)
    assert _path_clearance(path, TEE) >= 0.016 * 0.999
    length = float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
    assert tp.lengths(start, goal[None])[0] == pytest.approx(length)
    assert length > 0.2  # straight through would be 0.2 m


def test_transit_retreats_from_contact_and_reaches_an_inner_corner() -> None:
    tp = TransitPlanner([TEE], clearance=0.016)
    start = np.array([-0.04, 0.031])  # touching the bar's top face
    goal = np.array([0.040, 0.050])  # beside the stem, under the bar's far side
    path = tp.path(start, goal)
    assert path is not None
    assert path[1] == pytest.approx([-0.04, 0.030 + 0.016 * 1.02])  # straight away first
    assert _path_clearance(path[1:], TEE) >= 0.016 * 0.999


def test_transit_respects_obstacles_and_workspace() -> None:
    wall = np.array([[0.1, -0.2], [0.12, -0.2], [0.12, 0.2], [0.1, 0.2]])
    tp = TransitPlanner([wall], clearance=0.01, workspace=((-0.5, 0.5), (-0.5, 0.5)))
    path = tp.path([0.0, 0.0], [0.25, 0.0])
    assert _path_clearance(path, wall) >= 0.01 * 0.999
    blocked = TransitPlanner([wall], clearance=0.01, workspace=((-0.5, 0.5), (-0.19, 0.19)))
    assert blocked.path([0.0, 0.0], [0.25, 0.0]) is None
    assert blocked.lengths([0.0, 0.0], [[0.25, 0.0], [0.0, 0.1]])[0] == math.inf
    assert segment_polygon_clear([[0, 0]], [[0.25, 0]], [wall], 0.0).tolist() == [False]


# ---- planner options --------------------------------------------------------------------------
def _tee_setup():
    obj = PushObject.from_polygon(TEE, com=(0.0, 0.045), friction=0.0, limit_surface=0.055)
    pusher = Pusher(radius=0.015)
    return obj, pusher


def test_defaults_plan_as_before_and_travel_is_a_cost() -> None:
    obj, pusher = _tee_setup()
    state = obj.state([0.25, 0.25, 0.3])
    goal = np.array([0.3, 0.3, 1.0])
    ws = ((0.0, 0.5), (0.0, 0.5))
    base = pusher.planner(workspace=ws, seed=3).plan(obj.outline, state, goal)
    same = pusher.planner(workspace=ws, seed=3).plan(obj.outline, state, goal, avoid=None)
    assert base.travel == 0.0 and same.index == base.index and same.length == base.length
    planner = pusher.planner(workspace=ws, seed=3, travel_weight=1.0,
                             transit_clearance=0.017)
    plan = planner.plan(obj.outline, state, goal, pusher=[0.05, 0.05])
    assert plan.travel > 0.0
    path = planner.transit(obj.outline, state[:3], [0.05, 0.05], plan.approach)
    assert path[-1] == pytest.approx(plan.approach)
    assert plan.travel == pytest.approx(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


def test_obstacles_exclude_pushes_through_them() -> None:
    obj, pusher = _tee_setup()
    state = obj.state([0.25, 0.25, 0.0])
    goal = np.array([0.25, 0.40, 0.0])
    # a wall over everything above the T except a gap: pushes ending in it are excluded
    wall = np.array([[0.0, 0.34], [0.5, 0.34], [0.5, 0.36], [0.0, 0.36]])
    planner = pusher.planner(workspace=((0.0, 0.5), (0.0, 0.5)), obstacles=[wall[::-1]])
    assert planner.config.obstacles[0].shape == (4, 2)  # clockwise accepted
    plan = planner.plan(obj.outline, state, goal)
    assert segment_polygon_clear(plan.approach[None], plan.end[None], [wall],
                                 pusher.radius).all()


def test_plan_says_when_no_push_improves() -> None:
    obj, pusher = _tee_setup()
    pose = np.array([0.25, 0.25, 0.0])
    planner = pusher.planner(workspace=((0.0, 0.5), (0.0, 0.5)), require_improvement=True,
                             min_push_length=0.02)
    with pytest.raises(NoImprovingPush, match="no push improves") as info:
        planner.plan(obj.outline, obj.state(pose), pose)  # already at the goal
    assert isinstance(info.value, NoFeasiblePush)
    assert info.value.plan.score >= info.value.plan.current_score
    far = pusher.planner(workspace=((0.0, 0.5), (0.0, 0.5)), require_improvement=True)
    assert far.plan(obj.outline, obj.state(pose), pose + [0.05, 0.0, 0.0]).score > 0.0


def test_config_rejects_bad_library_options() -> None:
    with pytest.raises(ValueError, match="obstacles\\[0\\]"):
        PlannerConfig(obstacles=[[[0, 0], [1, 1]]])
    with pytest.raises(ValueError, match="travel_weight"):
        PlannerConfig(travel_weight=-1.0)
    with pytest.raises(ValueError, match="require_improvement"):
        PlannerConfig(require_improvement="yes")
    assert Planner(PlannerConfig()).config.clearance == pytest.approx(0.0048 + 0.0005)


# ---- estimator with known parameters ----------------------------------------------------------
def test_estimator_with_known_com_and_friction_zero() -> None:
    obj, pusher = _tee_setup()
    ekf = pusher.estimator(obj)
    assert ekf.config.known_m == 0.0 and ekf.config.known_com == tuple(obj.com)
    ekf.initialize([0.25, 0.25, 0.0])
    assert ekf.state[3:] == pytest.approx([*obj.com, obj.limit_surface, 0.0])
    rng = np.random.default_rng(0)
    for _ in range(3):
        ekf.predict_push([0.25, 0.17], [0.25, 0.21])
        ekf.update_pose(ekf.state[:3] + rng.normal(0.0, [1e-3, 1e-3, 0.01]))
    assert ekf.state[3:] == pytest.approx([*obj.com, obj.limit_surface, 0.0])
    assert np.all(np.isfinite(ekf.covariance)) and ekf.covariance[3:, 3:] == pytest.approx(0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        from push_core.estimator.config import EKFConfig
        with pytest.raises(ValueError, match="known_m"):
            EKFConfig(known_m=-0.1)
        with pytest.raises(ValueError, match="known_l"):
            EKFConfig(known_l=0.0)


# ---- two faces at once ------------------------------------------------------------------------
def test_wedge_twist_in_a_symmetric_corner_translates_with_the_pusher() -> None:
    from push_core.rollout import wedge_twist
    # an inner corner at the origin between faces with inward normals (0, 1) and (1, 0)
    contacts = np.array([[[0.01, 0.0], [0.0, 0.01]]])
    normals_in = np.array([[[0.0, 1.0], [1.0, 0.0]]])
    push = np.array([[0.002, 0.002]])  # along the bisector, into both faces
    com = np.array([[0.05, 0.05]])  # on the bisector: no net torque
    twist, ok = wedge_twist(push, contacts, normals_in, com, np.array([0.03]))
    assert ok.all()
    assert twist[0] == pytest.approx([0.002, 0.002, 0.0], abs=1e-12)
    # moving away from the second face: its multiplier would be negative -> one contact
    _, ok = wedge_twist(np.array([[-0.002, 0.002]]), contacts, normals_in, com,
                        np.array([0.03]))
    assert not ok.any()


def test_rollout_two_faces_only_changes_corner_pushes() -> None:
    from push_core.rollout import rollout_push
    obj = PushObject.from_polygon(TEE, com=(0.0, 0.045), friction=0.0, limit_surface=0.055)
    pose = np.zeros(3)
    corner = np.array([0.015, 0.030]) + obj.origin  # inner corner, object frame
    start = corner + np.array([0.04, 0.04])
    push = np.array([-0.05, -0.05])  # about 35 mm of it wedged in the corner
    one = rollout_push(obj.outline.polyline, pose, obj.com, 0.055, 0.0, start, push,
                       pusher_radius=0.015)
    two = rollout_push(obj.outline.polyline, pose, obj.com, 0.055, 0.0, start, push,
                       pusher_radius=0.015, two_faces=True)
    assert not np.allclose(one.poses[0, -1], two.poses[0, -1])
    # wedged in the corner, the T moves with the pusher: translation close to the push left
    moved = two.poses[0, -1, :2] - pose[:2]
    assert moved @ push / np.linalg.norm(push) > 0.025
    face = rollout_push(obj.outline.polyline, pose, obj.com, 0.055, 0.0,
                        np.array([0.0, -0.06]) + obj.origin, np.array([0.0, 0.04]),
                        pusher_radius=0.015, two_faces=True)
    plain = rollout_push(obj.outline.polyline, pose, obj.com, 0.055, 0.0,
                         np.array([0.0, -0.06]) + obj.origin, np.array([0.0, 0.04]),
                         pusher_radius=0.015)
    np.testing.assert_array_equal(face.poses, plain.poses)  # one face: bit-identical
