"""sim_bridge_node in arm mode (in-process, real messages over DDS) and the pusher mode's
``pusher/refused`` answer to a push it does not execute."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros]

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("pybullet")

from builtin_interfaces.msg import Duration  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from nav_msgs.msg import Path  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Image, JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from push_ros.paths import push_path  # noqa: E402
from push_ros.qos import CLOCK_QOS, LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS  # noqa: E402
from push_ros.refusal import read_refusal, stamp_key  # noqa: E402
from push_ros.stamps import seconds_from_stamp, stamp_from_seconds  # noqa: E402
from pushbot.ros2cli.discovery import spin_until  # noqa: E402
from sim_bridge.arm_robot import ARM_JOINTS  # noqa: E402
from sim_bridge.sim_bridge_node import SimBridgeNode  # noqa: E402

SMALL = [Parameter("image_width", value=160), Parameter("image_height", value=120),
         Parameter("object", value="rect1")]
TOPIC = "/joint_trajectory_controller/joint_trajectory"


def _graph(ctx: Any, name: str, params: list) -> tuple[Any, Any, Any]:
    node = SimBridgeNode(node_name=name, context=ctx, parameter_overrides=params)
    client = rclpy.create_node(f"{name}_client", context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    executor.add_node(client)
    return node, client, executor


def _trajectory(q0: np.ndarray, q1: np.ndarray, duration: float) -> JointTrajectory:
    msg = JointTrajectory(joint_names=list(reversed(ARM_JOINTS)))  # order is free
    for frac in (0.5, 1.0):
        q = q0 + frac * (q1 - q0)
        msg.points.append(JointTrajectoryPoint(
            positions=list(reversed(q.tolist())),
            time_from_start=Duration(sec=int(frac * duration),
                                     nanosec=int(round((frac * duration % 1) * 1e9)))))
    return msg


def test_arm_mode_follows_trajectories_and_rejects_invalid_ones(ros_context: Any) -> None:
    node, client, executor = _graph(ros_context, "arm_sim_bridge_node",
                                    [*SMALL, Parameter("robot", value="arm")])
    got: dict[str, list] = {k: [] for k in ("js", "desc", "clock", "rgb", "tip")}
    try:
        client.create_subscription(JointState, "/joint_states", got["js"].append, RELIABLE_QOS)
        client.create_subscription(String, "/robot_description", got["desc"].append,
                                   LATCHED_QOS)
        client.create_subscription(Clock, "/clock", got["clock"].append, CLOCK_QOS)
        client.create_subscription(Image, "camera/color/image_raw", got["rgb"].append,
                                   SENSOR_QOS)
        client.create_subscription(Path, "sim/tool_tip", got["tip"].append, RELIABLE_QOS)
        pub = client.create_publisher(JointTrajectory, TOPIC, RELIABLE_QOS)
        assert spin_until(executor, lambda: got["desc"] and got["js"] and got["rgb"]
                          and pub.get_subscription_count() > 0, time.monotonic() + 30.0)
        assert "pusher_rod" in got["desc"][0].data  # latched URDF with the rod
        js = got["js"][-1]
        assert list(js.name) == list(ARM_JOINTS)
        q0 = np.array(js.position)
        np.testing.assert_allclose(q0, node._params.arm_park, atol=1e-3)

        # Invalid (a joint missing): counted, nothing moves, no new frame.
        bad = _trajectory(q0, q0 + 0.1, 1.0)
        bad.joint_names.pop()
        for pt in bad.points:
            pt.positions.pop()
        pub.publish(bad)
        assert spin_until(executor, lambda: node.health.get("trajectories_rejected") == 1,
                          time.monotonic() + 10.0)
        assert "joints" in node.health.last_refusal
        assert node.health.get("trajectory_runs") == 0
        np.testing.assert_allclose(node._world.arm_state().positions, q0, atol=1e-6)

        # Valid: sim time advances, the arm moves, a frame follows after the end.
        t0 = node.timeline.epoch + node._world.sim_time
        q1 = q0 + np.array([0.3, 0.2, 0.0, 0.2, 0.0, -0.2, 0.0])
        n_rgb = len(got["rgb"])
        pub.publish(_trajectory(q0, q1, 1.0))
        assert spin_until(executor, lambda: node.health.get("trajectory_runs") == 1 and got["tip"],
                          time.monotonic() + 60.0), "the trajectory did not run"
        assert spin_until(executor, lambda: len(got["rgb"]) > n_rgb
                          and seconds_from_stamp(got["rgb"][-1].header.stamp) > t0 + 1.0,
                          time.monotonic() + 10.0), "no fresh frame after the trajectory"
        np.testing.assert_allclose(node._world.arm_state().positions, q1, atol=5e-3)
        # Joint states went out while the arm moved, stamped with advancing sim time (100 Hz of
        # sim time, as fast as the physics runs: a reliable depth-10 reader may keep any part of
        # a burst, so neither a count nor the last of the burst is asserted). What the node
        # guarantees: once the trajectory has ended, the resting arm's state is published again
        # (the idle timer), stamped after the trajectory's end and holding its final posture.
        assert spin_until(executor, lambda: seconds_from_stamp(got["js"][-1].header.stamp)
                          > t0 + 1.0, time.monotonic() + 10.0), "no joint state after the end"
        stamps = [seconds_from_stamp(m.header.stamp) for m in got["js"]]
        moving = [t for t in stamps if t > t0]
        assert moving and moving == sorted(moving)
        np.testing.assert_allclose(got["js"][-1].position, q1, atol=5e-3)
        assert spin_until(executor, lambda: got["clock"] and max(
            seconds_from_stamp(c.clock) for c in got["clock"]) > t0 + 1.0,
            time.monotonic() + 10.0), "/clock did not pass the trajectory's end"
        tip = got["tip"][-1]
        assert tip.header.frame_id == "world" and len(tip.poses) >= 50
        tip_now = node._world.arm.tip_position()
        last = tip.poses[-1].pose.position
        np.testing.assert_allclose([last.x, last.y, last.z], tip_now, atol=1e-3)

        # planner/push is not executed in arm mode.
        node.on_push(push_path((-0.07, 0.0), (-0.05, 0.0), (0.0, 0.0), stamp_seconds=1.0,
                               speed=0.02))
        assert node.health.get("pushes_ignored_arm_mode") == 1
        assert node.health.get("callback_errors") == 0
    finally:
        executor.shutdown()
        client.destroy_node()
        node.destroy_node()


def test_pusher_mode_answers_refused_pushes_on_pusher_refused(ros_context: Any) -> None:
    node, client, executor = _graph(ros_context, "refuse_sim_bridge_node",
                                    [*SMALL, Parameter("push_speed", value=0.002)])
    refused: list[DiagnosticStatus] = []
    try:
        client.create_subscription(DiagnosticStatus, "pusher/refused", refused.append,
                                   RELIABLE_QOS)
        assert spin_until(executor, lambda: node.scene.pub_refused.get_subscription_count() > 0,
                          time.monotonic() + 30.0)
        slow = push_path((-0.065, 0.0), (-0.045, 0.0), (0.0, 0.0), stamp_seconds=5.0,
                         speed=0.002)  # 25 s of sim time: still running for the next one
        node.on_push(slow)
        busy = push_path((-0.065, 0.01), (-0.045, 0.01), (0.0, 0.01), stamp_seconds=7.25,
                         speed=0.02)
        node.on_push(busy)
        outside = push_path((-0.065, 0.0), (-0.045, 0.0), (0.0, 0.0), stamp_seconds=9.5,
                            speed=0.02)
        outside.poses[2].pose.position.x = float("nan")
        node.on_push(outside)
        assert spin_until(executor, lambda: len(refused) >= 2, time.monotonic() + 10.0)
        first, second = (read_refusal(m) for m in refused[:2])
        assert (first.kind, first.push_stamp) == ("busy", stamp_key(stamp_from_seconds(7.25)))
        assert (second.kind, second.push_stamp) == ("invalid",
                                                    stamp_key(stamp_from_seconds(9.5)))
        assert first.who.endswith("refuse_sim_bridge_node")
        # The running push is not refused: it finishes and is executed.
        assert spin_until(executor, lambda: node.health.get("pushes_executed") == 1,
                          time.monotonic() + 120.0)
        assert len(refused) == 2
        # The world's refusal (outside the workspace) carries its kind.
        far = push_path((0.27, 0.0), (0.28, 0.0), (0.29, 0.0), stamp_seconds=11.0, speed=0.02)
        node.on_push(far)
        assert spin_until(executor, lambda: len(refused) == 3, time.monotonic() + 10.0)
        assert read_refusal(refused[2]).kind == "workspace"
    finally:
        executor.shutdown()
        client.destroy_node()
        node.destroy_node()
