"""Unit tests of push_core.planner: planning with the scores, sampling, baselines and push
optimisation of its parts (each part's own rules: test_scores, test_stopping, ...)."""

import math

import numpy as np
import pytest

from push_core.affordances import analytical_affordances
from push_core.geometry import closest_point_on_polyline, world_to_object
from push_core.objects import load_object
from push_core.planner import (
    APPROACH_MARGIN,
    AVOID_RADIUS,
    NoFeasiblePush,
    Planner,
    PlannerConfig,
    desired_motion,
    geo_mask,
    goal_reached,
    motion_score,
    point_scores,
    prepare_outline,
)
from push_core.rollout import rollout_push

A = 0.05  # half side of the square outline (tests/core/conftest.py), metres
R_P = 0.0048
L, M = 0.04, 0.3  # noqa: E741


def state_at(pose, com=(0.0, 0.0), l=L, m=M):  # noqa: E741
    return np.array([*pose, *com, l, m], dtype=float)


# ------------------------------------------------------------------------------ scores
def test_plan_scores_are_eq_5_1_of_the_analytical_affordances(square):
    state = state_at([0.01, -0.02, 0.4], com=(0.005, 0.0))
    goal = np.array([0.08, 0.03, 0.1])
    plan = Planner(PlannerConfig(k=2)).plan(square, state, goal)
    aff = analytical_affordances(square.points, square.normals, state[3:5], L, M)
    expected = point_scores(aff, desired_motion(state[:3], goal), 2.0)
    np.testing.assert_allclose(plan.scores, expected, atol=1e-12)
    assert plan.current_score == pytest.approx(motion_score(desired_motion(state[:3], goal), 2.0))


# ------------------------------------------------------------------------------ sampling
def test_planner_is_reproducible_with_a_seed(square):
    state, goal = state_at([0.0, 0.0, 0.2]), np.array([0.06, 0.02, 0.5])
    cfg = PlannerConfig(k=3, temperature=20.0, seed=11)
    a = [Planner(cfg).plan(square, state, goal) for _ in range(2)]
    np.testing.assert_array_equal(a[0].candidates, a[1].candidates)
    np.testing.assert_array_equal(a[0].end, a[1].end)
    # The generator advances: successive plans of one planner draw anew.
    p = Planner(cfg)
    draws = {tuple(p.plan(square, state, goal).candidates) for _ in range(5)}
    assert len(draws) > 1


# ------------------------------------------------------------------------------ baselines
def test_geo_mask_translation_keeps_far_points_near_the_line(square):
    mask = geo_mask(square.points, square.normals, [0.05, 0.0, 0.0])
    p = square.points
    np.testing.assert_array_equal(mask, (p[:, 0] < 0) & (np.abs(p[:, 1]) <= 0.02))
    assert mask.any()


def test_geo_mask_rotation_picks_the_side_that_turns_the_right_way(square):
    p = square.points
    ccw = geo_mask(square.points, square.normals, [0.05, 0.0, 0.2])
    np.testing.assert_array_equal(ccw, (p[:, 0] < 0) & (p[:, 1] < 0))  # push +x below: CCW
    cw = geo_mask(square.points, square.normals, [0.05, 0.0, -0.2])
    np.testing.assert_array_equal(cw, (p[:, 0] < 0) & (p[:, 1] > 0))
    # Pure rotation: torque of an inward-normal push about the origin, r x n_in, > 0 for CCW.
    pure = geo_mask(square.points, square.normals, [0.0, 0.0, 0.3])
    torque = p[:, 0] * -square.normals[:, 1] - p[:, 1] * -square.normals[:, 0]
    np.testing.assert_array_equal(pure, torque > 0)
    assert pure.any() and not pure.all()


def test_geo_planner_samples_only_from_the_mask(square):
    state, goal = state_at([0.0, 0.0, 0.0]), np.array([0.05, 0.0, 0.2])
    mask = geo_mask(square.points, square.normals, desired_motion(state[:3], goal))
    planner = Planner(PlannerConfig(method="geo", k=3, seed=3))
    for _ in range(10):
        plan = planner.plan(square, state, goal)
        assert mask[plan.candidates].all()
        assert plan.index in plan.candidates
        np.testing.assert_allclose(plan.probabilities, mask / mask.sum())


def test_rdn_planner_is_uniform_over_the_outline(square):
    state, goal = state_at([0.0, 0.0, 0.0]), np.array([0.05, 0.0, 0.0])
    planner = Planner(PlannerConfig(method="rdn", k=1, seed=5, direct=True))  # no rollouts
    n = len(square.points)
    plan = planner.plan(square, state, goal)
    np.testing.assert_allclose(plan.probabilities, np.full(n, 1.0 / n))
    draws = np.array([planner.plan(square, state, goal).candidates[0] for _ in range(600)])
    # Uniform over 76 points: every face (19 points) gets about a quarter of the draws.
    faces = np.bincount(draws // (n // 4), minlength=4) / len(draws)
    assert np.all(np.abs(faces - 0.25) < 0.08), faces


# ------------------------------------------------------------------------------ planning
def test_goal_straight_ahead_pushes_the_far_side_along_the_goal(square):
    # Goal 5 cm along the object's +x: the best pushes are on the left face near its centre,
    # straight along +x, 5 cm long (sticking contact through the COM: the object follows the
    # pusher, score 0 at the centre), in world rotated by the object's orientation.
    theta = 0.7
    state = state_at([0.02, -0.01, theta])
    direction = np.array([math.cos(theta), math.sin(theta)])
    goal = np.array([0.02 + 0.05 * direction[0], -0.01 + 0.05 * direction[1], theta])
    plan = Planner(PlannerConfig(k=3, temperature=1.0, seed=1)).plan(square, state, goal)
    point = square.points[plan.index]
    assert point[0] == pytest.approx(-A) and abs(point[1]) <= 0.01
    push = plan.end - plan.contact
    assert np.dot(push / np.linalg.norm(push), direction) > math.cos(math.radians(10.5))
    assert plan.length == pytest.approx(0.05, abs=0.0051)
    assert plan.score < 5.0 < plan.current_score
    # contact = outline point + pusher radius along the outward normal, in world.
    np.testing.assert_allclose(world_to_object(state[:3], plan.contact),
                               point + R_P * square.normals[plan.index], atol=1e-12)


def test_pure_rotation_goal_pushes_off_centre_with_the_right_sign(square):
    for sign in (1.0, -1.0):
        state = state_at([0.0, 0.0, 0.3])
        goal = np.array([0.0, 0.0, 0.3 + sign * 0.4])
        plan = Planner(PlannerConfig(k=3, seed=2)).plan(square, state, goal)
        r = world_to_object(state[:3], plan.contact)  # COM at the origin
        u = world_to_object(state[:3], plan.end) - r
        torque = (r[0] * u[1] - r[1] * u[0]) / np.linalg.norm(u)
        assert sign * torque > 0.01  # lever arm of more than 1 cm, turning the right way
        assert sign * (plan.predicted_pose[2] - 0.3) > math.radians(5.0)


def test_rollout_prediction_is_reproduced_by_rolling_out_the_returned_push(square):
    cfg = PlannerConfig(k=3, seed=4)
    state = state_at([0.05, 0.02, -0.4], com=(0.01, -0.005))
    goal = np.array([-0.02, 0.06, 0.2])
    plan = Planner(cfg).plan(square, state, goal)
    assert cfg.min_push_length - 1e-12 <= plan.length <= cfg.max_push_length + 1e-12
    res = rollout_push(square.polyline, state[:3], state[3:5], L, M, plan.approach,
                       plan.end - plan.approach)
    np.testing.assert_allclose(res.poses[0, -1], plan.predicted_pose, atol=1e-12)
    residual = goal - plan.predicted_pose
    assert plan.score == pytest.approx(float(motion_score(residual, cfg.lam)))
    np.testing.assert_allclose(np.linalg.norm(plan.contact - plan.approach),
                               cfg.approach_clearance, atol=1e-12)


def test_direct_variant_rescales_the_push_length_linearly():
    # Only the four face centres as candidates. Analytical affordances are exactly proportional
    # to the push length: the left-centre push through the COM moves the object by its length,
    # so a 3 cm goal gets a 3 cm push with a zero residual (no other point can do that).
    centres = prepare_outline([[0.0, -A], [A, 0.0], [0.0, A], [-A, 0.0]],
                              [[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
    state = state_at([0.0, 0.0, 0.0])
    plan = Planner(PlannerConfig(k=4, direct=True)).plan(centres, state, [0.03, 0.0, 0.0])
    assert plan.index == 3 and plan.angle == 0.0
    assert plan.length == pytest.approx(0.03, abs=1e-12)
    np.testing.assert_allclose(plan.predicted_pose, [0.03, 0.0, 0.0], atol=1e-12)

    # A model whose 1 cm and 5 cm predictions are not proportional: motion(L) is the line
    # through them, 2 cm at L = 1 cm and 4 cm at L = 5 cm, so 2.5 cm needs L = 2 cm.
    def fake_model(points, normals, com, l, m):  # noqa: E741
        aff = np.zeros((len(points), 10, 3))
        aff[3, 0] = [0.02, 0.0, 0.0]
        aff[3, 5] = [0.04, 0.0, 0.0]
        return aff

    planner = Planner(PlannerConfig(method="lrn", k=4, direct=True),
                      affordance_model=fake_model)
    plan = planner.plan(centres, state, [0.025, 0.0, 0.0])
    assert plan.index == 3 and plan.angle == 0.0
    assert plan.length == pytest.approx(0.02, abs=1e-12)
    np.testing.assert_allclose(plan.predicted_pose, [0.025, 0.0, 0.0], atol=1e-12)
    assert plan.score == pytest.approx(0.0, abs=1e-9)


def test_pushes_leaving_the_workspace_are_excluded(square):
    # Goal 3 cm along +x; the left face's approach points lie at x = -A - R_P - 5 mm = -59.8 mm.
    # With the workspace starting at x = -58 mm they are excluded, everything stays inside.
    workspace = ((-0.058, 0.3), (-0.3, 0.3))
    state, goal = state_at([0.0, 0.0, 0.0]), np.array([0.03, 0.0, 0.0])
    for direct in (False, True):
        planner = Planner(PlannerConfig(k=5, workspace=workspace, direct=direct, seed=9))
        for _ in range(5):
            plan = planner.plan(square, state, goal)
            for pt in (plan.approach, plan.contact, plan.end):
                assert -0.058 <= pt[0] <= 0.3 and -0.3 <= pt[1] <= 0.3
    tiny = ((-0.01, 0.01), (-0.01, 0.01))  # inside the object: nowhere to lower the pusher
    with pytest.raises(NoFeasiblePush, match="workspace"):
        Planner(PlannerConfig(workspace=tiny)).plan(square, state, goal)


def test_fallback_when_no_sampled_candidate_is_feasible(square):
    # Sampled with a tiny temperature the best point is on the left face, whose approaches are
    # all outside this workspace: the planner falls back to the other points.
    workspace = ((-0.05, 0.3), (-0.3, 0.3))
    plan = Planner(PlannerConfig(k=1, temperature=1e-3, workspace=workspace)).plan(
        square, state_at([0.0, 0.0, 0.0]), [0.05, 0.0, 0.0])
    assert square.points[plan.candidates[0], 0] == pytest.approx(-A)
    assert plan.fallback
    assert plan.approach[0] >= -0.05 and square.points[plan.index, 0] > -A


def test_butter_pushes_are_feasible_and_clear_of_the_outline():
    spec = load_object("butter")
    outline = prepare_outline(*spec.outline(0.0015))
    poly = spec.polyline()
    rng = np.random.default_rng(0)
    planner = Planner(PlannerConfig(k=3, seed=0))
    for _ in range(10):
        pose = np.array([*rng.uniform(-0.05, 0.05, 2), rng.uniform(-np.pi, np.pi)])
        goal = pose + [*rng.uniform(-0.1, 0.1, 2), rng.uniform(-0.6, 0.6)]
        plan = planner.plan(outline, [*pose, *spec.com, 0.045, 0.25], goal)
        local = world_to_object(pose, np.stack([plan.approach, plan.contact, plan.end]))
        _, _, dist, _ = closest_point_on_polyline(poly, local[0])
        assert dist >= R_P + APPROACH_MARGIN
        a, c, e = local
        assert abs((e - a)[0] * (c - a)[1] - (e - a)[1] * (c - a)[0]) < 1e-12  # collinear
        assert plan.score <= plan.current_score


def test_avoid_leaves_out_the_refused_region_and_changes_nothing_when_empty(square):
    state, goal = state_at([0.0, 0.0, 0.0]), [0.05, 0.0, 0.0]
    plans = [Planner(PlannerConfig(k=1, seed=5)).plan(square, state, goal, avoid=avoid)
             for avoid in (None, [], np.zeros((0, 2)))]
    for other in plans[1:]:  # the same plan and the same random draws
        assert other.index == plans[0].index and other.angle == plans[0].angle
        np.testing.assert_array_equal(other.approach, plans[0].approach)
    first = square.points[plans[0].index]
    again = Planner(PlannerConfig(k=1, seed=5)).plan(square, state, goal, avoid=[first])
    assert np.linalg.norm(square.points[again.index] - first) > AVOID_RADIUS
    assert again.probabilities[np.linalg.norm(square.points - first, axis=1)
                               <= AVOID_RADIUS].sum() == 0.0
    # Avoiding every point would leave nothing: the avoidance is ignored.
    everywhere = Planner(PlannerConfig(k=1, seed=5)).plan(square, state, goal,
                                                          avoid=square.points)
    assert everywhere.index == plans[0].index
    with pytest.raises(ValueError, match="^avoid"):
        Planner(PlannerConfig()).plan(square, state, goal, avoid=[0.0, 0.0])


def test_goal_tolerance_check():
    tol_xy, tol_th = 0.0075, math.radians(5.0)
    assert goal_reached([0, 0, 0], [0.0075, 0, math.radians(5.0)], tol_xy, tol_th)
    assert not goal_reached([0, 0, 0], [0.0076, 0, 0], tol_xy, tol_th)
    assert not goal_reached([0, 0, 0], [0, 0, math.radians(5.1)], tol_xy, tol_th)
    assert goal_reached([0, 0, 3.1], [0.004, 0.004, -3.1], tol_xy, tol_th)  # wrapped: 4.7 deg
    planner = Planner(PlannerConfig())
    assert planner.reached([0.1, 0.1, 1.0], [0.105, 0.1, 1.05])


# ------------------------------------------------------------------------------ bad input
def test_lrn_needs_a_model():
    with pytest.raises(ValueError, match="affordance_model"):
        Planner(PlannerConfig(method="lrn"))


def test_bad_state_and_goal_name_the_argument(square, square_outline):
    planner = Planner(PlannerConfig())
    good = state_at([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="state"):
        planner.plan(square, [*good[:6], np.nan], [0.05, 0.0, 0.0])
    with pytest.raises(ValueError, match="state"):
        planner.plan(square, good[:6], [0.05, 0.0, 0.0])
    with pytest.raises(ValueError, match="state"):
        planner.plan(square, state_at([0, 0, 0], l=0.0), [0.05, 0.0, 0.0])
    with pytest.raises(ValueError, match="goal"):
        planner.plan(square, good, [0.05, 0.0])
    with pytest.raises(ValueError, match="goal"):
        planner.plan(square, good, [0.05, np.inf, 0.0])
    with pytest.raises(ValueError, match="outline"):
        planner.plan(square_outline(), good, [0.05, 0.0, 0.0])


# ------------------------------------------------------------------ stop rule and symmetry
def test_disc_outline_plans_and_stops_on_position_alone() -> None:
    disc = prepare_outline(*load_object("ellip1").outline(0.002))
    hexagon = prepare_outline(*load_object("hex").outline(0.002))
    assert not disc.orientation_matters and hexagon.orientation_matters
    planner = Planner(PlannerConfig(seed=0))
    turned = [0.0, 0.0, 1.0]  # same position, 57 deg of rotation
    assert planner.reached([0, 0, 0], turned, None, disc)
    assert not planner.reached([0, 0, 0], turned, None, hexagon)
    state = [0.0, 0.0, 0.0, 0.0, 0.0, 0.035, 0.3]
    goal = [0.05, 0.0, 1.0]
    plan = planner.plan(disc, state, goal)
    # scored without the rotation: the current score is the distance in mm
    assert plan.current_score == pytest.approx(50.0)
    assert plan.score < plan.current_score


# ------------------------------------------------------------------------------ bounded work
def test_chunked_closest_point_queries_give_the_same_bits(monkeypatch):
    import push_core.geometry as geometry

    poly = load_object("butter").polyline()
    q = np.random.default_rng(4).normal(scale=0.06, size=(41, 29, 2))
    whole = closest_point_on_polyline(poly, q)
    monkeypatch.setattr(geometry, "CLOSEST_POINT_BUDGET", 5 * len(poly) + 1)  # 5 rows a chunk
    chunked = closest_point_on_polyline(poly, q)
    for a, b in zip(whole, chunked, strict=True):
        assert a.shape == b.shape and np.array_equal(a, b)


def test_the_fallback_tries_at_most_the_cap(square, monkeypatch):
    import push_core.planner as planner_module

    evaluated: list[int] = []
    original = planner_module.evaluate

    def counting(*args):
        evaluated.append(len(args[-1]))
        return original(*args)

    monkeypatch.setattr(planner_module, "evaluate", counting)
    monkeypatch.setattr(planner_module, "MAX_FALLBACK_POINTS", 7)
    far = state_at([1.0, 0.0, 0.0])  # the object off the table: nothing is feasible
    with pytest.raises(NoFeasiblePush):
        Planner(PlannerConfig(k=2)).plan(square, far, [1.05, 0.0, 0.0])
    assert evaluated == [2, 7]


def test_implausible_states_and_objects_larger_than_the_workspace_are_refused(
        square, square_outline):
    from push_core.planner import check_state

    planner = Planner(PlannerConfig(k=1))
    goal = [0.03, 0.0, 0.0]
    r = square.radius
    for bad, match in ((state_at([0, 0, 0], l=0.0), "l must be"),
                       (state_at([0, 0, 0], m=11.0), "m in"),
                       (state_at([0, 0, 0], l=4.01 * r), "outline's radius"),
                       (state_at([0, 0, 0], com=(2.01 * r, 0.0)), "COM")):
        with pytest.raises(ValueError, match="^state: .*" + match):
            planner.plan(square, bad, goal)
        with pytest.raises(ValueError, match="^state"):
            check_state(bad, square)
    check_state(state_at([0, 0, 0], l=4.0 * r, com=(0.0, 1.99 * r)), square)
    assert planner.check_outline(square) is square
    huge = prepare_outline(*(a * f for a, f in zip(square_outline(), (1e4, 1.0), strict=True)))
    with pytest.raises(ValueError, match="^outline: .*workspace diagonal"):
        planner.check_outline(huge)
