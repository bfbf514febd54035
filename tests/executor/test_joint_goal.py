"""Joint goals: the 6-D inverse kinematics, the checked motion to a posture, and the node's
``executor/joint_goal`` (reached, refused, the dry run) against the stand-in controller."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from push_executor.joint_goal import GOAL, goal_positions, plan_joint_goal, pose_ik
from push_executor.kinematics import ArmKinematics
from push_executor.motion_types import PANDA_PARK, PANDA_READY, MotionConfig, PushRefused

from .test_kinematics import panda  # noqa: F401 - the fixture

#: A posture that turns the flange about 125 degrees away from pointing down (a calibration
#: view: the board toward a camera above and beside the table).
TILTED = np.array(PANDA_READY) + np.array([0.3, -0.2, 0.2, 0.3, -0.4, -1.2, 0.5])


def test_pose_ik_reaches_a_tilted_flange_pose(panda: ArmKinematics) -> None:  # noqa: F811
    target = panda.frame_pose(TILTED, "panda_link8")
    result = pose_ik(panda, target, [PANDA_READY], PANDA_READY)
    assert result.within(1e-6)
    np.testing.assert_allclose(panda.frame_pose(result.q, "panda_link8"), target, atol=1e-6)
    far = target.copy()
    far[:3, 3] += (2.0, 0.0, 0.0)  # out of reach: not converged, and says so
    assert not pose_ik(panda, far, [PANDA_READY], PANDA_READY).within(1e-3)


def test_the_motion_to_a_goal_is_checked(panda: ArmKinematics) -> None:  # noqa: F811
    config = MotionConfig()
    plan = plan_joint_goal(panda, config, TILTED, PANDA_PARK)
    assert plan.final == GOAL and not plan.is_push
    np.testing.assert_allclose(plan.positions[0], PANDA_PARK)
    np.testing.assert_allclose(plan.positions[-1], TILTED, atol=1e-9)
    beyond = np.array(PANDA_READY)
    beyond[0] = panda.upper[0] - 0.01  # inside the URDF limit, not its margin
    with pytest.raises(PushRefused) as refused:
        plan_joint_goal(panda, config, beyond, PANDA_PARK)
    assert (refused.value.kind, refused.value.stage) == ("joint_limits", GOAL)
    low = panda.solve_ik((0.1, 0.0, -0.02), PANDA_READY).q  # the tip into the table
    assert panda.tip_pose(low)[0][2] < 0
    with pytest.raises(PushRefused) as refused:
        plan_joint_goal(panda, config, low, PANDA_PARK)
    assert refused.value.kind == "tool_height"


def test_a_goal_names_every_chain_joint_once() -> None:
    chain = ("a", "b")
    np.testing.assert_array_equal(goal_positions(["f", "b", "a"], [9, 2, 1], chain), [1, 2])
    for names, positions in ((["a"], [1.0]), (["a", "b"], [1.0]), (["a", "b"], [1.0, np.nan]),
                             (["a", "a", "b"], [1.0, 1.0, 2.0])):
        with pytest.raises(PushRefused) as refused:
            goal_positions(names, positions, chain)
        assert refused.value.kind == "invalid"


# ---- the node ------------------------------------------------------------------------------
pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from push_ros.qos import RELIABLE_QOS  # noqa: E402
from push_ros.refusal import read_refusal, stamp_key  # noqa: E402
from push_ros.stamps import stamp_from_seconds  # noqa: E402

from .test_executor_node import ARM, Graph, graph  # noqa: E402, F401 - the fixture


def _goal(graph: Graph, q: Any, stamp: float, names: list[str] = ARM  # noqa: F811
          ) -> tuple[str, list]:
    """Send a goal (the arm held first: a goal while it moves is refused ``settling``)."""
    c = graph.client
    if not hasattr(graph, "goal_pub"):
        graph.goal_pub = c.create_publisher(JointState, "executor/joint_goal", RELIABLE_QOS)
        graph.goal_results = []
        c.create_subscription(DiagnosticStatus, "executor/goal_result",
                              graph.goal_results.append, RELIABLE_QOS)
        assert graph.spin_until(lambda: graph.goal_pub.get_subscription_count() > 0
                                and graph.executor_node._pub_goal.get_subscription_count() > 0)
    results = graph.goal_results
    assert graph.spin_until(lambda: graph.executor_node.measured.held(time.monotonic()))
    msg = JointState(name=list(names), position=[float(v) for v in q])
    msg.header.stamp = stamp_from_seconds(stamp)
    graph.goal_pub.publish(msg)
    return stamp_key(msg.header.stamp), results


@pytest.mark.ros
def test_a_joint_goal_is_reached(graph: Graph) -> None:  # noqa: F811
    key, results = _goal(graph, TILTED, 3.5)
    assert graph.spin_until(lambda: results, 60.0)
    answer = read_refusal(results[0])
    assert (answer.push_stamp, answer.kind) == (key, "reached"), answer
    assert results[0].level == DiagnosticStatus.OK
    np.testing.assert_allclose(graph.arm.q, TILTED, atol=1e-6)
    assert "goal" in graph.states() and not graph.refused
    # a goal that does not name the chain: answered with its stamp, nothing moves
    sent = len(graph.arm.received)
    key, _ = _goal(graph, PANDA_PARK[:6], 4.5, ARM[:6])
    assert graph.spin_until(lambda: len(results) >= 2)
    assert (read_refusal(results[1]).push_stamp, read_refusal(results[1]).kind) == \
        (key, "invalid")
    assert len(graph.arm.received) == sent


@pytest.mark.ros
def test_a_joint_goal_while_disabled_is_planned_and_moves_nothing(graph: Graph) -> None:  # noqa: F811
    assert graph.call(graph.enable, SetBool.Request(data=False)).success
    assert graph.spin_until(lambda: graph.state() == "disabled")
    key, results = _goal(graph, TILTED, 5.0)
    assert graph.spin_until(lambda: results and graph.paths)
    answer = read_refusal(results[0])
    assert (answer.push_stamp, answer.kind) == (key, "disabled")
    assert len(graph.paths[-1].poses) > 10
    assert not graph.arm.received
