"""push_executor.motion: the staged push trajectory, its properties and every refusal class.

No rclpy. The arm is pybullet_data's Panda at the default base pose.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from push_executor.kinematics import ArmKinematics, ToolSpec
from push_executor.motion import (
    CLEAR,
    CLEAR_EXTRA,
    CLEAR_START_MATCH,
    LIFT_EXTRA,
    PARK,
    MotionConfig,
    MotionPlan,
    MotionState,
    PushRefused,
    chain_point,
    plan_park,
    plan_push,
)
from push_executor.motion_types import PANDA_PARK, PANDA_READY, STAGES
from push_executor.timing import joint_move, line_profile
from push_executor.tracking import segment_distance

from .test_kinematics import BASE_POSE, panda_urdf

CONFIG = MotionConfig()
PARKED = np.array(PANDA_PARK)
#: The stages of a push that ends parked (no view of the camera and the object).
PARKING = (*STAGES[:-1], PARK)
#: A 5 cm push in +x through the middle of the workspace, 5 mm approach clearance.
PUSH = ((-0.055, 0.02), (-0.05, 0.02), (0.0, 0.02))


@pytest.fixture(scope="module")
def arm() -> ArmKinematics:
    return ArmKinematics(panda_urdf(), "panda_link0", ToolSpec(), BASE_POSE)


@pytest.fixture(scope="module")
def plan(arm: ArmKinematics) -> MotionPlan:
    return plan_push(arm, CONFIG, *PUSH, PARKED)


def assert_within_limits(arm: ArmKinematics, plan: MotionPlan, config: MotionConfig = CONFIG
                         ) -> None:
    """Positions with margin; velocities, accelerations and jerks -- the sent velocities and
    their finite differences over the sampled points -- within speed_margin x the limits."""
    assert np.all(plan.positions >= arm.lower + config.limit_margin - 1e-9)
    assert np.all(plan.positions <= arm.upper - config.limit_margin + 1e-9)
    m = config.speed_margin
    dt = np.diff(plan.times)[:, None]
    assert np.all(np.abs(plan.velocities) <= arm.velocity_limits * m * (1 + 1e-6))
    qdd = np.diff(plan.velocities, axis=0) / dt
    assert np.all(np.abs(qdd) <= arm.acceleration_limits * m * (1 + 1e-6))
    assert np.all(np.abs(plan.accelerations) <= arm.acceleration_limits * m * (1 + 1e-6))
    jerk = np.diff(plan.accelerations, axis=0) / dt
    assert np.all(np.abs(jerk) <= arm.jerk_limits * m * (1 + 1e-6))
    # The accelerations are those of the velocities (not an unrelated column): the mean of a
    # step's end accelerations is its mean acceleration to within half a step's jerk.
    mid = 0.5 * (plan.accelerations[1:] + plan.accelerations[:-1])
    assert np.all(np.abs(mid - qdd) <= arm.jerk_limits * m * dt / 2 + 1e-6)


def test_trajectory_properties(arm: ArmKinematics, plan: MotionPlan) -> None:
    assert plan.joint_names == arm.joint_names
    # First point: the measured state, after a delay (the controller interpolates to it).
    assert plan.times[0] == pytest.approx(CONFIG.start_delay) and plan.times[0] > 0
    np.testing.assert_array_equal(plan.positions[0], PARKED)
    np.testing.assert_array_equal(plan.velocities[0], 0.0)
    assert np.all(np.diff(plan.times) > 0)
    assert np.max(np.diff(plan.times)) <= CONFIG.waypoint_period + 1e-9
    np.testing.assert_array_equal(plan.velocities[-1], 0.0)
    # No view of the camera and the object: the push ends parked.
    np.testing.assert_allclose(plan.positions[-1], PARKED, atol=1e-9)
    assert plan.final == PARK and plan.is_push
    assert_within_limits(arm, plan)
    # The planned tip is the FK of the planned joints; never below the minimum height.
    np.testing.assert_allclose(plan.tip[::50], arm.tip_positions(plan.positions[::50]),
                               atol=1e-12)
    assert np.min(plan.tip[:, 2]) >= CONFIG.min_tool_height
    # Stages in order, contiguous, covering the trajectory.
    assert tuple(s.name for s in plan.stages) == PARKING
    for a, b in zip(plan.stages, plan.stages[1:], strict=False):
        assert a.t_end == pytest.approx(b.t_start)
    assert plan.stages[-1].t_end == pytest.approx(plan.duration)


def test_the_push_follows_the_commanded_line(arm: ArmKinematics, plan: MotionPlan) -> None:
    span = next(s for s in plan.stages if s.name == "push")
    during = (plan.times >= span.t_start - 1e-9) & (plan.times <= span.t_end + 1e-9)
    a = np.array([*PUSH[0], CONFIG.push_height])
    b = np.array([*PUSH[2], CONFIG.push_height])
    off = segment_distance(plan.tip[during], a, b)
    assert np.max(off) < 1e-5 * 1e-3 * 1e3  # < 0.01 mm
    # The axis is vertical at every waypoint of the push.
    for q in plan.positions[during][::10]:
        assert arm.tip_pose(q)[1][2] < -1 + 1e-9
    # Contact segment: from the contact point to the end point, at the push speed.
    np.testing.assert_allclose(plan.line, [[*PUSH[1], 0.01], [*PUSH[2], 0.01]])
    assert plan.contact_end == pytest.approx(span.t_end)
    # Jerk-limited ramps (the acceleration limit is not reached at 20 mm/s): each lasts
    # 2 sqrt(v / j) and covers half its length at full speed.
    cruise = 0.05 / CONFIG.push_speed
    ramp = 2 * math.sqrt(CONFIG.push_speed / CONFIG.cartesian_jerk)
    assert ramp * CONFIG.cartesian_jerk / 2 < CONFIG.cartesian_acceleration
    assert plan.contact_end - plan.contact_start == pytest.approx(cruise + ramp / 2, abs=0.02)
    i = int(np.searchsorted(plan.times, plan.contact_start))
    assert np.linalg.norm(plan.tip[i, :2] - PUSH[1]) < 0.5e-3
    speed = np.linalg.norm(np.diff(plan.tip[during], axis=0), axis=1) / np.diff(
        plan.times[during])
    assert np.max(speed) == pytest.approx(CONFIG.push_speed, rel=1e-3)


def test_heights_of_the_stages(plan: MotionPlan) -> None:
    def tip_at(t: float) -> np.ndarray:
        return plan.tip[int(np.argmin(np.abs(plan.times - t)))]

    spans = {s.name: s for s in plan.stages}
    high, low = CONFIG.approach_height, CONFIG.push_height
    back = PUSH[2][0] - CONFIG.retreat  # the push runs along +x
    np.testing.assert_allclose(tip_at(spans["descend"].t_start), [*PUSH[0], high], atol=1e-6)
    np.testing.assert_allclose(tip_at(spans["push"].t_start), [*PUSH[0], low], atol=1e-6)
    np.testing.assert_allclose(tip_at(spans["retreat"].t_start), [*PUSH[2], low], atol=1e-6)
    np.testing.assert_allclose(tip_at(spans["lift"].t_start), [back, 0.02, low], atol=1e-6)
    np.testing.assert_allclose(tip_at(spans["park"].t_start), [back, 0.02, high + LIFT_EXTRA],
                               atol=1e-6)  # the lift ends above the approach height
    for name in ("transit", "park"):  # joint space: clear of the object over the workspace
        during = (plan.times >= spans[name].t_start) & (plan.times <= spans[name].t_end)
        over = np.all(np.abs(plan.tip[during, :2]) <= [0.3, 0.35], axis=1)
        assert np.min(plan.tip[during][over, 2]) >= high - 5e-3


def test_transit_blends_into_the_descend(plan: MotionPlan) -> None:
    """No stop between transit and descend (the tip is 5 cm above the table there), nor between
    lift and park; the push's own stages start and end at rest."""
    def speed_at(t: float) -> float:
        return float(np.max(np.abs(plan.velocities[int(np.argmin(np.abs(plan.times - t)))])))

    spans = {s.name: s for s in plan.stages}
    assert speed_at(spans["descend"].t_start) > 0.05
    assert speed_at(spans["park"].t_start) > 0.05
    for name in ("push", "retreat", "lift"):
        assert speed_at(spans[name].t_start) < 1e-9


def test_joint_moves_and_line_profiles_respect_their_limits() -> None:
    """ruckig's motions, sampled: the limits hold, the end states are met exactly, a moving
    start is taken as it is."""
    v, a, j = np.full(3, 1.0), np.full(3, 2.0), np.full(3, 20.0)
    start = (np.zeros(3), np.array([0.5, 0.0, -0.2]), np.array([0.0, 1.0, 0.0]))
    target = (np.array([1.0, -0.2, 0.0]), np.zeros(3), np.zeros(3))
    times, q, qd, qdd = joint_move(start, target, v, a, j, np.full(3, -2.0), np.full(3, 2.0),
                                   0.01)
    for got, want in zip((q, qd, qdd), start, strict=True):
        np.testing.assert_allclose(got[0], want, atol=1e-12)
    for got, want in zip((q, qd, qdd), target, strict=True):
        np.testing.assert_allclose(got[-1], want, atol=1e-9)
    dt = np.diff(times)[:, None]
    assert np.max(dt) <= 0.01 + 1e-12
    assert np.max(np.abs(qd)) <= 1.0 + 1e-9 and np.max(np.abs(qdd)) <= 2.0 + 1e-9
    assert np.max(np.abs(np.diff(qdd, axis=0) / dt)) <= 20.0 * (1 + 1e-6)
    t, s, sd, sdd = line_profile(0.09, 0.25, 0.0, 0.25, 1.0, 10.0, 0.01)
    assert (s[0], sd[0], s[-1], sd[-1]) == pytest.approx((0.0, 0.25, 0.09, 0.0), abs=1e-12)
    assert np.all(np.diff(s) >= 0) and np.max(sd) <= 0.25 + 1e-12
    assert np.max(np.abs(sdd)) <= 1.0 + 1e-9
    with pytest.raises(ValueError, match="maximum velocity|error"):
        line_profile(0.05, 0.3, 0.0, 0.25, 1.0, 10.0, 0.01)


def test_a_push_chains_from_the_previous_motion(arm: ArmKinematics, plan: MotionPlan) -> None:
    """A second push planned while the first lifts: the new trajectory repeats the first one's
    points from its first point up to the chain point (the end of the lift), then transits
    from that moving state: no stop, no park, within the limits."""
    first = plan.contact_end + 0.1  # the previous plan's time of the new first point
    take_over = chain_point(plan, first)
    assert take_over == pytest.approx(plan.chain_from) and take_over > first
    spans = {s.name: s for s in plan.stages}
    assert plan.chain_from == pytest.approx(spans["lift"].t_end)
    start = plan.state_at(take_over)
    assert np.max(np.abs(start.qd)) > 0.05  # moving: the lift blends into what follows
    second = ((0.05, -0.1), (0.055, -0.1), (0.09, -0.1))
    chained = plan_push(arm, CONFIG, *second, start, lead_in=plan, lead_from=first)
    # The lead-in: the previous plan's own points, re-timed to the new start.
    lead = chained.stages[0]
    assert lead.name == "lift" and chained.stages[1].name == "transit"
    inside = chained.times <= lead.t_end + 1e-9
    np.testing.assert_allclose(chained.positions[0], plan.state_at(first).q, atol=1e-12)
    for t, q in zip(chained.times[inside], chained.positions[inside], strict=True):
        np.testing.assert_allclose(q, plan.state_at(t - CONFIG.start_delay + first).q,
                                   atol=1e-9)
    np.testing.assert_allclose(chained.positions[inside][-1], start.q, atol=1e-12)
    np.testing.assert_allclose(chained.velocities[inside][-1], start.qd, atol=1e-12)
    assert_within_limits(arm, chained)
    assert chained.contact_start > lead.t_end and chained.is_push
    # Before its chain point a push is refused nothing: the chain point is where it starts.
    assert chain_point(plan, 0.0) == plan.chain_from
    assert chain_point(plan, plan.duration + 1.0) == plan.duration


def test_park_alone(arm: ArmKinematics) -> None:
    """From a low posture: straight up, then joint space to the park posture, within the
    limits; from the park posture itself: nothing to do."""
    ready = np.array(PANDA_READY)
    low = arm.solve_ik([0.05, 0.1, 0.01], ready, ready).q
    park = plan_park(arm, CONFIG, MotionState.at_rest(low))
    assert tuple(s.name for s in park.stages) == (CLEAR, PARK) and not park.is_push
    np.testing.assert_allclose(park.positions[-1], PARKED, atol=1e-9)
    assert_within_limits(arm, park)
    assert park.chain_from == pytest.approx(park.stages[0].t_end)
    still = plan_park(arm, CONFIG, PARKED)
    assert still.duration == pytest.approx(CONFIG.start_delay) and len(still.times) == 1


def test_plans_over_the_workspace(arm: ArmKinematics) -> None:
    """Random 1-5 cm pushes in the workspace from the park posture: how many plan, and every
    refusal is one of the known classes (seeded)."""
    rng = np.random.default_rng(3)
    kinds: dict[str, int] = {}
    ok = 0
    for _ in range(40):
        contact = rng.uniform([-0.2, -0.25], [0.2, 0.25])
        d = rng.normal(size=2)
        d /= np.linalg.norm(d)
        end = np.clip(contact + rng.uniform(0.01, 0.05) * d, [-0.25, -0.3], [0.25, 0.3])
        try:
            plan_push(arm, CONFIG, contact - 0.005 * d, contact, end, PARKED)
            ok += 1
        except PushRefused as refusal:
            kinds[refusal.kind] = kinds.get(refusal.kind, 0) + 1
    print(f"planned {ok}/40 random pushes; refused {kinds}")
    assert ok >= 32 and set(kinds) <= {"ik", "speed", "singular", "joint_limits", "workspace"}


# ---- refusals ---------------------------------------------------------------------------------
def refusal(arm: ArmKinematics, config: MotionConfig = CONFIG, push: tuple = PUSH,
            q: np.ndarray = PARKED) -> PushRefused:
    with pytest.raises(PushRefused) as info:
        plan_push(arm, config, *push, q)
    return info.value


@pytest.mark.parametrize("push, match", [
    (((math.nan, 0.0), (0.0, 0.0), (0.05, 0.0)), "approach point must be 2 finite"),
    (((0.0, 0.0), (0.0, math.inf), (0.05, 0.0)), "contact point must be 2 finite"),
    (((0.0, 0.0, 0.0), (0.0, 0.0), (0.05, 0.0)), "approach point must be 2 finite"),
    (((-0.2, 0.0), (-0.19, 0.0), (0.2, 0.0)), "max_push_length"),
    (((0.0, 0.0), (0.0, 0.0), (0.0, 0.0)), "coincide"),
    (((0.0, 0.0), (0.01, 0.01), (0.05, 0.0)), "not on the approach"),
])
def test_invalid_input(arm: ArmKinematics, push: tuple, match: str) -> None:
    r = refusal(arm, push=push)
    assert (r.kind, r.stage) == ("invalid", "input") and match in r.reason


def test_invalid_measured_state(arm: ArmKinematics) -> None:
    r = refusal(arm, q=np.array([0.0, math.nan, 0, -2, 0, 2, 0]))
    assert r.kind == "invalid" and "start state" in r.reason
    assert refusal(arm, q=np.zeros(6)).kind == "invalid"


def test_workspace(arm: ArmKinematics) -> None:
    r = refusal(arm, push=((0.20, 0.0), (0.21, 0.0), (0.26, 0.0)))
    assert (r.kind, r.stage) == ("workspace", "input") and "end point" in r.reason
    # The retreat goes back past the workspace edge: found on the Cartesian stage.
    config = dataclasses.replace(CONFIG, retreat=0.08)
    r = refusal(arm, config, push=((0.0, 0.27), (0.0, 0.265), (0.0, 0.24)))
    assert (r.kind, r.stage) == ("workspace", "retreat")


def test_ik(arm: ArmKinematics) -> None:
    config = dataclasses.replace(CONFIG, workspace=(-2.0, 2.0, -2.0, 2.0))
    r = refusal(arm, config, push=((0.6, 0.0), (0.605, 0.0), (0.65, 0.0)))
    assert (r.kind, r.stage) == ("ik", "transit") and "out of reach" in r.reason
    # The approach is reachable, the end is not.
    r = refusal(arm, config, push=((0.20, 0.0), (0.205, 0.0), (0.29, 0.0)))
    assert (r.kind, r.stage) == ("ik", "push")


def test_joint_limits(arm: ArmKinematics) -> None:
    config = dataclasses.replace(CONFIG, park_positions=(0.0, -1.29, 0.0, -1.81, 0.0, 1.02,
                                                         2.95))
    r = refusal(arm, config)
    assert (r.kind, r.stage) == ("joint_limits", "park") and "panda_joint7" in r.reason
    # A measured state outside the margin is fine if the transit only moves inward...
    q = PARKED.copy()
    q[3] = arm.lower[3] + 0.01
    plan_push(arm, CONFIG, *PUSH, q)


def test_tool_height(arm: ArmKinematics) -> None:
    config = dataclasses.replace(CONFIG, min_tool_height=0.01, push_height=0.01)
    plan_push(arm, config, *PUSH, PARKED)  # at the minimum: fine
    # A park posture with the tip at the table is refused at the park stage.
    low = arm.solve_ik([-0.2, 0.0, 0.001], np.array(PANDA_READY), np.array(PANDA_READY)).q
    config = dataclasses.replace(CONFIG, park_positions=tuple(low))
    r = refusal(arm, config)
    assert (r.kind, r.stage) == ("tool_height", "park")


def test_a_low_start_is_cleared_first(arm: ArmKinematics) -> None:
    """From a posture low in the workspace (a push stopped half-way) the arm first goes
    straight up to the approach height, then crosses above the object."""
    ready = np.array(PANDA_READY)
    low_left = arm.solve_ik([0.0, -0.2, 0.01], ready, ready).q
    plan = plan_push(arm, CONFIG, (0.0, 0.25), (0.0, 0.245), (0.0, 0.20), low_left)
    assert tuple(s.name for s in plan.stages) == (CLEAR, *PARKING)
    clear, transit = plan.stages[:2]
    during = plan.times <= clear.t_end + 1e-9
    np.testing.assert_allclose(plan.tip[during, :2], [[0.0, -0.2]] * int(np.sum(during)),
                               atol=1e-6)
    after = (plan.times >= transit.t_start) & (plan.times <= transit.t_end)
    assert np.min(plan.tip[after, 2]) >= CONFIG.approach_height - 1e-3


def test_a_transit_that_dips_rises_first(arm: ArmKinematics) -> None:
    """From rest at the approach height over the workspace (a clear pose), the joint-space
    transit to the far side dips below its clearance: the arm first rises straight up, then
    crosses; a push, not a refusal."""
    ready = np.array(PANDA_READY)
    start = arm.solve_ik([0.017, 0.218, CONFIG.approach_height], ready, ready).q
    far = ((0.126, -0.249), (0.131, -0.249), (0.166, -0.249))
    plan = plan_push(arm, CONFIG, *far, start)
    assert tuple(s.name for s in plan.stages) == (CLEAR, *PARKING)
    rise = plan.stages[0]
    during = plan.times <= rise.t_end + 1e-9
    np.testing.assert_allclose(plan.tip[during, :2], [[0.017, 0.218]] * int(np.sum(during)),
                               atol=1e-6)
    transit = plan.stages[1]
    during = (plan.times >= transit.t_start) & (plan.times <= transit.t_end)
    assert np.min(plan.tip[during, 2]) >= CONFIG.approach_height - 5e-3 - 1e-5
    assert_within_limits(arm, plan)


def test_a_low_start_beside_the_workspace_rises_first(arm: ArmKinematics) -> None:
    """Low beside the workspace (outside its band: no clear stage at first) the joint-space
    transit would enter the workspace below the approach height; the arm rises straight up
    first (from anywhere the tool is), then crosses: a push, not a refusal."""
    ready = np.array(PANDA_READY)
    beside = arm.solve_ik([-0.1, 0.38, 0.02], ready, ready).q
    plan = plan_push(arm, CONFIG, (0.0, 0.1), (0.0, 0.095), (0.0, 0.05), beside)
    assert plan.stages[0].name == CLEAR
    assert_clear_stage(arm, plan, beside, straight=True)


def assert_clear_stage(arm: ArmKinematics, plan: MotionPlan, start: np.ndarray,
                       straight: bool) -> None:
    """The plan starts at the measured posture ``start`` with a clear stage that never goes
    below the tip's start height and ends at CLEAR_EXTRA above the approach height (straight
    up when ``straight``: the tip's x, y kept), then crosses at the approach height."""
    np.testing.assert_allclose(plan.positions[0], start, atol=CLEAR_START_MATCH)
    tip0 = arm.tip_pose(start)[0]
    clear, transit = plan.stages[:2]
    during = plan.times <= clear.t_end + 1e-9
    assert np.min(plan.tip[during, 2]) >= tip0[2] - 1e-4
    assert plan.tip[during][-1, 2] == pytest.approx(CONFIG.approach_height + CLEAR_EXTRA,
                                                    abs=1e-4)
    if straight:
        np.testing.assert_allclose(plan.tip[during, :2], [tip0[:2]] * int(np.sum(during)),
                                   atol=1e-4)
    after = (plan.times >= transit.t_start) & (plan.times <= transit.t_end)
    assert np.min(plan.tip[after, 2]) >= CONFIG.approach_height - 5e-3 - 1e-5
    assert_within_limits(arm, plan)


@pytest.mark.parametrize("case", ["other elbow", "tilted", "edge band"])
def test_the_clear_stage_starts_at_the_measured_posture(arm: ArmKinematics, case: str) -> None:
    """After a foreign motion or a stop the tool may rest low anywhere, in any posture: the
    trajectory's first point is the measured posture (before, the clear stage's first inverse
    kinematics solution was: up to 0.46 rad away when the arm's redundancy differed from the
    reference posture), and the tip only rises. A tilted tool straightens in joint space; a
    tip over the workspace's band but outside its rectangle goes straight up (not refused for
    leaving the workspace)."""
    ready = np.array(PANDA_READY)
    other = ready + np.array([-0.4, 0.0, 0.8, 0.0, 0.0, 0.0, 0.0])
    if case == "other elbow":
        q = arm.solve_ik([0.05, 0.05, 0.012], other, other, posture_gain=1.0,
                         posture_tolerance=1e-8).q
        assert np.max(np.abs(q - arm.solve_ik([0.05, 0.05, 0.012], ready, ready).q)) > 0.1
    elif case == "tilted":
        q = arm.solve_ik([0.05, 0.0, 0.02], ready, ready).q + np.array([0.0] * 5 + [0.2, 0.0])
    else:
        y_max = CONFIG.workspace[3]
        q = arm.solve_ik([0.0, y_max + 0.02, 0.012], ready, ready).q
    plan = plan_push(arm, CONFIG, *PUSH, q)
    assert plan.stages[0].name == CLEAR
    assert_clear_stage(arm, plan, q, straight=case != "tilted")


def test_a_clear_stage_that_cannot_be_planned_is_refused_at_it(arm: ArmKinematics) -> None:
    """Where the arm cannot rise from (the clear height out of reach), the push is refused at
    the clear stage: the node turns that into "cannot leave its posture" (state_check)."""
    ready = np.array(PANDA_READY)
    low = arm.solve_ik([0.0, 0.0, 0.01], ready, ready).q
    config = dataclasses.replace(CONFIG, approach_height=1.5)
    with pytest.raises(PushRefused) as info:
        plan_push(arm, config, *PUSH, low)
    assert info.value.stage == CLEAR


def test_a_push_chained_into_a_low_park_takes_over_above_the_table(arm: ArmKinematics
                                                                   ) -> None:
    """A moving start: a push chained into a park that began low (clear, park) takes over
    after the clear stage, with the tool above the approach height, and stays above it until
    its descend."""
    ready = np.array(PANDA_READY)
    low = arm.solve_ik([0.0, -0.2, 0.01], ready, ready).q
    park = plan_park(arm, CONFIG, low)
    assert tuple(s.name for s in park.stages) == (CLEAR, PARK)
    take_over = chain_point(park, 0.0)
    assert take_over >= park.stages[0].t_end - 1e-9
    start = park.state_at(take_over)
    assert arm.tip_pose(start.q)[0][2] >= CONFIG.approach_height
    plan = plan_push(arm, CONFIG, *PUSH, start, lead_in=park, lead_from=0.0)
    descend = next(s for s in plan.stages if s.name == "descend")
    lead_in = plan.stages[0]  # the park's own points up to the take-over
    before = (plan.times >= lead_in.t_end - 1e-9) & (plan.times <= descend.t_start)
    assert np.min(plan.tip[before, 2]) >= CONFIG.approach_height - 5e-3 - 1e-5


def test_singular(arm: ArmKinematics) -> None:
    config = dataclasses.replace(CONFIG, min_manipulability=0.2)
    r = refusal(arm, config)
    assert (r.kind, r.stage) == ("singular", "descend") and "manipulability" in r.reason


def test_speed(arm: ArmKinematics) -> None:
    # A tip speed beyond what the joints may do (a tenth of their velocity limits): the
    # descend (planned before the transit that joins it) is refused.
    slow = dataclasses.replace(CONFIG, speed_margin=0.05)
    r = refusal(arm, slow)
    assert (r.kind, r.stage) == ("speed", "descend") and "velocity limit" in r.reason
    # Tight acceleration limits: the Cartesian ramps are too steep even scaled down.
    slow_arm = ArmKinematics(panda_urdf(), "panda_link0", ToolSpec(), BASE_POSE,
                             acceleration_limits=0.02)
    r = refusal(slow_arm)
    assert r.kind == "speed" and "accelerates" in r.reason


def test_bad_config() -> None:
    with pytest.raises(ValueError, match="heights"):
        MotionConfig(push_height=0.2)
    with pytest.raises(ValueError, match="speed_margin"):
        MotionConfig(speed_margin=1.5)
    with pytest.raises(ValueError, match="push_speed"):
        MotionConfig(push_speed=math.nan)
    with pytest.raises(ValueError, match="workspace"):
        MotionConfig(workspace=(0.1, -0.1, -0.1, 0.1))


def test_postures_must_fit_the_chain(arm: ArmKinematics) -> None:
    with pytest.raises(ValueError, match="park_positions: 6 values"):
        plan_push(arm, MotionConfig(park_positions=(0.0,) * 6), *PUSH, PARKED)
