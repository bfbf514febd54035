"""The executor's state checks before planning, the plan bounds and its readiness.

Core tests on the real Panda model (pinocchio), then the real node class in-process (its
guarded callbacks called with real messages, publishers captured, no DDS): the impossible
measured states of a glitched encoder (``panda_joint7`` = 100 rad, -1e6 rad, NaN) are refused
with kind ``state`` naming the joint, nothing is published on the controller topic, and the
refusal says the robot is unavailable; a plausible state afterwards makes the node ready again.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from push_executor.kinematics import ArmKinematics, ToolSpec
from push_executor.motion_types import PANDA_PARK, PANDA_SIM_BASE_POSE, MotionConfig, PushRefused
from push_executor.push_executor_node import HELD_STATES
from push_executor.state_check import (
    StateCheckConfig,
    StuckPosture,
    check_before_planning,
    check_posture,
    joint_move_bound,
    joint_stage_bound,
    nonfinite_joints,
    unavailable,
)
from push_executor.timing import joint_move
from push_executor.tracking import MeasuredArm
from pushbot.runner.arm_faults import FOREIGN_POSTURE

from .test_kinematics import panda_urdf

ARM = [f"panda_joint{i}" for i in range(1, 8)]
CHECKS = StateCheckConfig()
#: The in-process node's simulated clock, s (set through its /clock callback).
CLOCK = 10.0
MOTION = MotionConfig()


@pytest.fixture(scope="module")
def arm() -> ArmKinematics:
    return ArmKinematics(panda_urdf(), "panda_link0", ToolSpec(), PANDA_SIM_BASE_POSE)


@pytest.fixture(scope="module")
def plan(arm: ArmKinematics) -> Any:
    from push_executor.motion import plan_push

    return plan_push(arm, MOTION, (-0.055, 0.02), (-0.05, 0.02), (0.0, 0.02), PANDA_PARK)


def posture(q: Any = PANDA_PARK, stamp: float = 10.0, steady: float = 100.0,
            problem: str = "", states: int = HELD_STATES) -> MeasuredArm:
    """The measured arm after ``states`` joint states at ``q`` (held), the newest's problem."""
    measured = MeasuredArm(HELD_STATES)
    for _ in range(states):
        measured.update(stamp, np.array(q, dtype=float), steady)
    measured.problem = problem
    return measured


def with_joint7(value: float) -> list[float]:
    return [*PANDA_PARK[:6], value]


# ---- core --------------------------------------------------------------------------------------
@pytest.mark.parametrize("value", [100.0, -1e6, 1e300, math.nan, math.inf])
def test_an_impossible_posture_is_refused_naming_the_joint(arm: ArmKinematics,
                                                           value: float) -> None:
    with pytest.raises(PushRefused, match="panda_joint7") as info:
        check_posture(arm, with_joint7(value), CHECKS.state_margin)
    assert info.value.kind == "state"


def test_a_posture_just_inside_the_margin_is_planned_from(arm: ArmKinematics) -> None:
    q = with_joint7(arm.upper[6] + 0.9 * CHECKS.state_margin)
    check_posture(arm, q, CHECKS.state_margin)
    with pytest.raises(PushRefused, match="panda_joint7"):
        check_posture(arm, with_joint7(arm.upper[6] + 1.1 * CHECKS.state_margin),
                      CHECKS.state_margin)


def test_no_state_stale_and_old_stamps(arm: ArmKinematics) -> None:
    with pytest.raises(PushRefused, match="no joint state yet") as info:
        check_before_planning(arm, MeasuredArm(), CHECKS, MOTION, 100.0, 10.0)
    assert info.value.kind == "no_state"
    with pytest.raises(PushRefused, match="state_timeout") as info:
        check_before_planning(arm, posture(steady=100.0), CHECKS, MOTION,
                              100.0 + CHECKS.state_timeout + 0.01, 10.0)
    assert info.value.kind == "no_state"
    with pytest.raises(PushRefused, match="before the node's clock") as info:
        check_before_planning(arm, posture(stamp=10.0), CHECKS, MOTION, 100.0,
                              10.0 + CHECKS.max_state_age + 0.01)
    assert info.value.kind == "state"
    with pytest.raises(PushRefused, match="panda_joint7 = nan") as info:
        check_before_planning(arm, posture(problem="non-finite joint position "
                                           "(panda_joint7 = nan)"), CHECKS, MOTION, 100.0, 10.0)
    assert info.value.kind == "state"
    q = check_before_planning(arm, posture(), CHECKS, MOTION, 100.0, 10.0)
    np.testing.assert_array_equal(q, PANDA_PARK)
    # No valid clock (simulated time not started): no age check.
    check_before_planning(arm, posture(stamp=-1e9), CHECKS, MOTION, 100.0, None)


def test_nonfinite_joints_names_them_and_ignores_malformed_messages() -> None:
    names = ["finger", *ARM]
    positions = [0.0, *with_joint7(math.nan)]
    assert nonfinite_joints(ARM, names, positions) == \
        "non-finite joint position (panda_joint7 = nan)"
    assert nonfinite_joints(ARM, names, [0.0, *PANDA_PARK]) == ""
    assert nonfinite_joints(ARM, names[:-1], positions[:-1]) == ""  # a joint missing
    assert nonfinite_joints(ARM, names, positions[:-1]) == ""  # lengths differ


def test_joint_stage_bound_covers_the_planned_stages(arm: ArmKinematics, plan: Any) -> None:
    """The bound of a posture within the limits is at least every joint-space stage planned
    from it (transit and withdraw or park of a real plan), and grows with the distance to the
    limits."""
    joint_stages = [s.t_end - s.t_start for s in plan.stages
                    if s.name in ("transit", "withdraw", "park")]
    bound = joint_stage_bound(arm, PANDA_PARK, MOTION)
    assert max(joint_stages) <= bound < CHECKS.max_duration
    assert joint_stage_bound(arm, with_joint7(arm.upper[6] + 0.04), MOTION) >= bound


def test_joint_move_bound_holds_for_ruckig_profiles(arm: ArmKinematics) -> None:
    """Ruckig's time-optimal profiles (push_executor.timing.joint_move, the executor's joint
    stages) never last longer than the bound: rest to rest across each joint's whole range
    (where the bound is tight: cruise at the velocity limit), and between seeded random
    moving states within the limits."""
    m = MOTION.speed_margin
    v, a, j = arm.velocity_limits * m, arm.acceleration_limits * m, arm.jerk_limits * m
    lower, upper, rest = arm.lower, arm.upper, np.zeros(arm.n_joints)
    period = 0.05
    times = joint_move((lower, rest, rest), (upper, rest, rest), v, a, j, lower, upper,
                       period)[0]
    bound = joint_move_bound(upper - lower, v, a, j, moving=False)
    assert times[-1] <= bound * (1 + 1e-9)
    assert times[-1] >= 0.99 * bound  # tight: not a bound that says nothing
    rng = np.random.default_rng(33)
    for _ in range(40):
        q0, q1 = rng.uniform(lower, upper), rng.uniform(lower, upper)
        v0, v1 = rng.uniform(-0.9, 0.9, (2, arm.n_joints)) * v
        a0 = rng.uniform(-0.9, 0.9, arm.n_joints) * a
        try:
            times = joint_move((q0, v0, a0), (q1, v1, rest), v, a, j, lower - 1.0, upper + 1.0,
                               period)[0]
        except ValueError:
            continue  # no profile from this state within the limits
        assert times[-1] <= joint_move_bound(np.abs(q1 - q0), v, a, j)


def test_a_long_plan_is_refused(plan: Any) -> None:
    from push_executor.state_check import check_plan

    check_plan(plan, CHECKS)
    with pytest.raises(PushRefused, match="max_trajectory_duration") as info:
        check_plan(plan, StateCheckConfig(max_duration=plan.duration - 0.1))
    assert info.value.kind == "plan"
    with pytest.raises(PushRefused, match="max_trajectory_points"):
        check_plan(plan, StateCheckConfig(max_points=len(plan.times) - 1))


def test_a_posture_that_cannot_be_left_until_the_arm_moves(arm: ArmKinematics) -> None:
    stuck = StuckPosture()
    q = np.array(PANDA_PARK)  # the tool tip high above the table
    low = np.array(FOREIGN_POSTURE)  # the tool tip 1.5 cm above the table
    other = PushRefused("ik", "transit", "no inverse kinematics solution")
    assert stuck.classify(other, arm, low, MOTION) is other  # the target's, not the posture's
    high = PushRefused("tool_height", "transit", "tip below")
    assert stuck.classify(high, arm, q, MOTION) is high  # a high tip leaves by the transit
    assert stuck.classify(high, arm, None, MOTION) is high and stuck.q is None
    refusal = stuck.classify(PushRefused("tool_height", "transit", "tip at z = 0.001"), arm,
                             low, MOTION)
    assert refusal.kind == "state" and "0.015 m above" in refusal.reason
    q = low
    refusal = stuck.classify(PushRefused("tool_height", "clear", "tip at z = 0.001"), arm, q,
                             MOTION)
    assert refusal.kind == "state" and "cannot leave its posture" in refusal.reason
    kwargs = dict(model=True, enabled=True, arm=arm, stuck=stuck, config=CHECKS, motion=MOTION,
                  controller=True, moving=False, steady=100.0, clock=10.0)
    assert unavailable(measured=posture(q), **kwargs)[0] == "state"
    assert unavailable(measured=posture(q + 0.005), **kwargs)[0] == "state"  # within STUCK_MOVE
    assert unavailable(measured=posture(q + 0.02), **kwargs) is None  # moved: ready
    assert unavailable(measured=posture(q), **kwargs) is None  # and forgotten


def test_unavailable_in_order(arm: ArmKinematics) -> None:
    kwargs = dict(model=True, enabled=True, arm=arm, measured=posture(), stuck=StuckPosture(),
                  config=CHECKS, motion=MOTION, controller=True, moving=False, steady=100.0,
                  clock=10.0)
    assert unavailable(**kwargs) is None
    assert unavailable(**{**kwargs, "model": False, "arm": None})[0] == "no_model"
    assert unavailable(**{**kwargs, "enabled": False})[0] == "disabled"
    assert unavailable(**{**kwargs, "measured": MeasuredArm()})[0] == "no_state"
    assert unavailable(**{**kwargs, "clock": None})[0] == "no_state"
    problem = "measured panda_joint7 = 100 is outside its URDF limits"
    assert unavailable(**{**kwargs, "measured": posture(problem=problem)})[0] == "state"
    assert unavailable(**{**kwargs, "controller": False})[0] == "no_controller"


@pytest.mark.parametrize("field, value", [("state_margin", -0.1), ("max_duration", 0.0),
                                          ("max_points", 1), ("max_state_age", math.nan)])
def test_config_is_validated(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        StateCheckConfig(**{field: value})


# ---- the node, in-process ------------------------------------------------------------------------
@pytest.fixture
def node(ros_context: Any) -> Iterator[Any]:
    pytest.importorskip("rclpy")
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String

    from push_executor.push_executor_node import PushExecutorNode
    from push_ros.stamps import stamp_from_seconds

    n = PushExecutorNode(context=ros_context, parameter_overrides=[
        Parameter("start_enabled", value=True), Parameter("use_sim_time", value=True)])
    try:
        n.sent = []
        n.refusals = []
        n.statuses = []
        n._pub_traj.publish = n.sent.append
        n._pub_traj.get_subscription_count = lambda: 1  # a controller "matched"
        n._pub_refused.publish = n.refusals.append
        n._pub_status.publish = n.statuses.append
        n.callbacks = {sub.topic_name.lstrip("/"): sub.callback for sub in n.subscriptions}
        n.callbacks["clock"](Clock(clock=stamp_from_seconds(CLOCK)))  # simulated time
        n.callbacks["robot_description"](String(data=panda_urdf()))
        assert n._arm is not None
        yield n
    finally:
        n.destroy_node()


def joint_state(q: Any, stamp: float = CLOCK) -> Any:
    from sensor_msgs.msg import JointState

    from push_ros.stamps import stamp_from_seconds

    msg = JointState(name=[*ARM, "panda_finger_joint1"], position=[float(v) for v in q] + [0.0])
    msg.header.stamp = stamp_from_seconds(stamp)
    return msg


def hold(node: Any, q: Any) -> None:
    """Joint states of an arm held at ``q`` (a push is planned at once, not deferred)."""
    for _ in range(HELD_STATES):
        node.callbacks["joint_states"](joint_state(q))


def push(node: Any, stamp: float) -> Any:
    from push_ros.paths import push_path
    from push_ros.refusal import read_refusal

    before = len(node.refusals)
    node.callbacks["planner/push"](push_path((-0.055, 0.02), (-0.05, 0.02), (0.0, 0.02),
                                             stamp, 0.02))
    return read_refusal(node.refusals[-1]) if len(node.refusals) > before else None


@pytest.mark.parametrize("value", [100.0, -1e6, math.nan])
def test_the_node_refuses_an_impossible_state_and_sends_nothing(node: Any, value: float) -> None:
    from push_ros.refusal import read_readiness, robot_unavailable

    hold(node, PANDA_PARK)
    node.callbacks["joint_states"](joint_state(with_joint7(value)))
    t0 = time.monotonic()
    refusal = push(node, 5.0)
    assert time.monotonic() - t0 < 5.0  # refused before planning, not after minutes of it
    assert refusal is not None and refusal.kind == "state", refusal
    assert "panda_joint7" in refusal.reason and robot_unavailable(refusal)
    assert node.sent == []
    node._on_watchdog()  # the readiness as executor/status says it
    readiness = read_readiness(node.statuses[-1])
    assert readiness.ready is False and readiness.unavailable.startswith("state: ")
    # A plausible state again: ready, and the next push is executed.
    hold(node, PANDA_PARK)
    node._on_watchdog()
    assert read_readiness(node.statuses[-1]).ready is True
    assert push(node, 6.0) is None and len(node.sent) == 1
    assert node.health.get("callback_errors") == 0


def test_an_impossible_state_while_moving_is_not_tracked_and_the_hold_is_plausible(
        node: Any) -> None:
    """Joint states with an impossible posture during a push are not taken as the measured
    posture: the motion stops as on stale states, and the hold trajectory holds the last
    plausible posture, never the impossible one."""
    hold(node, PANDA_PARK)
    assert push(node, 5.0) is None and len(node.sent) == 1 and node._run is not None
    deadline = time.monotonic() + 30.0
    while node._run is not None and time.monotonic() < deadline:
        node.callbacks["joint_states"](joint_state(with_joint7(100.0)))
        node._on_watchdog()  # the stale-state watchdog (state_timeout of the steady clock)
    assert node._run is None, "the motion was not stopped"
    stop = node.sent[-1]
    assert len(node.sent) == 2 and len(stop.points) == 1
    order = [stop.joint_names.index(j) for j in ARM]
    np.testing.assert_allclose(np.array(stop.points[0].positions)[order], PANDA_PARK)
    from push_ros.refusal import read_refusal

    refusal = read_refusal(node.refusals[-1])
    assert refusal.kind == "fault" and "stale" in refusal.reason and refusal.available is False


def test_a_moving_arm_is_settling_not_refused(arm: ArmKinematics) -> None:
    """An arm still moving is not refused before planning (the node defers the push until
    the arm is held, or chains it to its own motion); readiness says ``settling`` while no
    motion of the executor's own runs, and nothing while one does."""
    moving = posture(states=1)  # one state: not yet held
    check_before_planning(arm, moving, CHECKS, MOTION, 100.0, 10.0)
    kwargs = dict(model=True, enabled=True, arm=arm, stuck=StuckPosture(), config=CHECKS,
                  motion=MOTION, controller=True, steady=100.0, clock=10.0)
    assert unavailable(measured=moving, moving=False, **kwargs)[0] == "settling"
    assert unavailable(measured=moving, moving=True, **kwargs) is None
    assert unavailable(measured=posture(), moving=False, **kwargs) is None
    # No joint state for MeasuredArm's quiet time counts as held (a resting simulator).
    assert unavailable(measured=moving, moving=False, **{**kwargs, "steady": 100.6}) is None
