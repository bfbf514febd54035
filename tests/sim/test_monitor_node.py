"""sim_bridge_node's monitor stream (``sim/monitor/*``), in-process against the real node
class (a 160 x 120 camera, an 80 x 60 monitor, for speed): a push through rect1's centre is
handed to the guarded ``on_push`` as a real ``nav_msgs/Path``; every monitor frame the node
publishes (counted at its publishers, which still publish) is stamped inside the push at the
sim-time rate and goes out before ``pusher/executed``; a subscriber over DDS receives them.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros]

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("pybullet")

from nav_msgs.msg import Path  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image  # noqa: E402

from push_ros.frames import CAMERA_FRAME  # noqa: E402
from push_ros.images import camera_matrix_from_info, image_to_array  # noqa: E402
from push_ros.paths import push_path  # noqa: E402
from push_ros.qos import SENSOR_QOS  # noqa: E402
from push_ros.stamps import seconds_from_stamp  # noqa: E402
from pushbot.ros2cli.discovery import spin_until  # noqa: E402
from sim_bridge.sim_bridge_node import SimBridgeNode  # noqa: E402

HALF = 0.045  # rect1 is a 9 cm square at the origin
RATE = 20.0  # Hz of sim time: every 12 physics steps of 1/240 s
OVERRIDES = [Parameter("image_width", value=160), Parameter("image_height", value=120),
             Parameter("object", value="rect1"), Parameter("monitor.rate", value=RATE),
             Parameter("monitor.width", value=80), Parameter("monitor.height", value=60)]


def _spy(publisher: Any, sink: list) -> None:
    """Record every message the node hands to ``publisher`` (which still publishes it)."""
    publish = publisher.publish

    def recording(msg: Any) -> None:
        sink.append(msg)
        publish(msg)

    publisher.publish = recording


def test_the_bridge_publishes_monitor_frames_during_a_push(ros_context: Any) -> None:
    node = SimBridgeNode(node_name="monitor_sim_bridge_node", context=ros_context,
                         parameter_overrides=OVERRIDES)
    client = rclpy.create_node("monitor_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(client)
    sent: list[Image] = []
    sent_info: list[CameraInfo] = []
    order: list[Any] = []  # what the node published on the monitor and pusher/executed
    received: list[tuple[str, Any]] = []  # (topic, message) in arrival order
    try:
        _spy(node.scene.pub_monitor, sent)
        _spy(node.scene.pub_monitor_info, sent_info)
        _spy(node.scene.pub_executed, order)
        _spy(node.scene.pub_monitor, order)
        client.create_subscription(Image, "sim/monitor/image_raw",
                                   lambda m: received.append(("monitor", m)), SENSOR_QOS)
        client.create_subscription(Path, "pusher/executed",
                                   lambda m: received.append(("executed", m)),
                                   QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        assert spin_until(executor, lambda: node.scene.pub_monitor.get_subscription_count() > 0
                          and node.scene.pub_executed.get_subscription_count() > 0,
                          time.monotonic() + 30.0), "the client was not discovered"
        t_before = node.timeline.epoch + node._world.sim_time
        node.on_push(push_path((-HALF - 0.02, 0.0), (-HALF, 0.0), (-HALF + 0.03, 0.0),
                               stamp_seconds=0.0, speed=0.02))
        assert spin_until(executor, lambda: any(k == "executed" for k, _ in received),
                          time.monotonic() + 60.0), "no pusher/executed"
        t_done = node.timeline.epoch + node._world.sim_time
        assert node.health.get("callback_errors") == 0
    finally:
        executor.shutdown()
        client.destroy_node()
        node.destroy_node()

    stamps = np.array([seconds_from_stamp(m.header.stamp) for m in sent])
    dt = 1.0 / 240.0
    steps = np.round((stamps - t_before) / dt).astype(int)
    # Every 12 physics steps from the start of the push until the object has settled.
    np.testing.assert_array_equal(steps, np.arange(12, round((t_done - t_before) / dt) + 1, 12))
    assert [seconds_from_stamp(m.header.stamp) for m in sent_info] == stamps.tolist()
    for img, info in zip(sent, sent_info, strict=True):
        assert img.header.frame_id == info.header.frame_id == CAMERA_FRAME
        assert (img.encoding, img.width, img.height) == ("rgb8", 80, 60)
        assert image_to_array(img).shape == (60, 80, 3)
        assert (info.width, info.height) == (80, 60)
    k = camera_matrix_from_info(sent_info[0])
    assert k[0, 0] == pytest.approx(615.0 * 80 / 640)  # the D415 camera scaled to 80 px
    # Published (by the worker, in this order) before pusher/executed.
    assert [type(m) for m in order] == [Image] * len(sent) + [Path]
    # Over DDS (best effort): what arrived is what was sent.
    got = [seconds_from_stamp(m.header.stamp) for k, m in received if k == "monitor"]
    assert got and set(got) <= set(stamps.tolist())


def test_a_failing_monitor_publish_does_not_stop_the_push(ros_context: Any) -> None:
    """The monitor is a side stream: its publisher failing (here on every frame) is logged,
    and the push still runs to its end, is counted and reported on pusher/executed."""
    node = SimBridgeNode(node_name="monitor_fail_sim_bridge_node", context=ros_context,
                         parameter_overrides=OVERRIDES)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executed: list[Path] = []
    attempts: list[Image] = []

    def broken(msg: Image) -> None:
        attempts.append(msg)
        raise RuntimeError("publisher gone")

    try:
        node.scene.pub_monitor.publish = broken
        _spy(node.scene.pub_executed, executed)
        before = node._world.object_pose()
        node.on_push(push_path((-HALF - 0.02, 0.0), (-HALF, 0.0), (-HALF + 0.03, 0.0),
                               stamp_seconds=0.0, speed=0.02))
        assert spin_until(executor, lambda: bool(executed), time.monotonic() + 60.0)
        after = node._world.object_pose()
        counts = node.health.counts
    finally:
        executor.shutdown()
        node.destroy_node()
    assert len(attempts) > 10  # every frame was tried, none stopped the physics
    assert counts["pushes_executed"] == 1 and counts["pushes_failed"] == 0
    assert counts["callback_errors"] == 0
    assert 0.02 < after[0] - before[0] < 0.045  # pushed: axis 30 mm past the face, + radius
