"""``pushbot view``: a real Foxglove WebSocket client receives the graph.

A node here publishes a camera image (best effort, like ``sim_bridge``) and a latched
estimate (like ``ekf_node``) on the session's DDS domain; ``pushbot view --port 0`` runs as a
child process; a ``websockets`` client speaks the Foxglove protocol (subprotocol
``foxglove.sdk.v1``): it reads ``serverInfo`` and ``advertise`` (channels with ``cdr``
encoding and ``ros2msg`` schemas), subscribes, and decodes the binary ``messageData`` frames
(opcode 1, subscription id, timestamp, CDR payload) with rclpy. The latched estimate is
published once, before the client subscribes: it must still arrive (late-subscriber rule).
"""

from __future__ import annotations

import json
import re
import struct
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pushbot import cli

pytestmark = [pytest.mark.ros, pytest.mark.graph]  # starts node processes

PUSHBOT = str(Path(sys.executable).parent / "pushbot")
IMAGE, ESTIMATE = "/camera/color/image_raw", "/estimator/object_pose"


class FoxgloveClient:
    """The client side of the Foxglove WebSocket protocol over a ``websockets`` connection:
    subscribes to every advertised channel of ``wanted`` and keeps, per topic, the
    ``(log time ns, payload)`` of each ``messageData`` frame (opcode 1: subscription id,
    timestamp, payload) and the server times of the ``time`` frames (opcode 2)."""

    def __init__(self, ws, wanted: set[str]) -> None:
        self.ws = ws
        self.wanted = wanted
        self.server_info: dict = {}
        self.channels: dict[str, dict] = {}
        self.subscribed: dict[int, str] = {}
        self.asked: dict[str, float] = {}  # topic -> when it was last subscribed
        self.messages: dict[str, list[tuple[int, bytes]]] = {}
        self.times: list[int] = []
        self.other_ops: list[dict] = []

    def subscribe(self, ch: dict) -> None:
        sub_id = len(self.subscribed) + 1
        self.subscribed[sub_id] = ch["topic"]
        self.asked[ch["topic"]] = time.monotonic()
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": sub_id, "channelId": ch["id"]}]}))

    def poll(self) -> None:
        """Handle one frame (or none within 0.1 s)."""
        # foxglove-sdk can advertise a channel an instant before it accepts subscriptions to
        # it ("unknown channel"): subscribe again to a channel that has sent nothing for 3 s
        # (a liveness retry; the assertions do not depend on it).
        for topic, when in list(self.asked.items()):
            if topic not in self.messages and time.monotonic() - when > 3.0:
                self.subscribe(self.channels[topic])
        try:
            frame = self.ws.recv(timeout=0.1)
        except TimeoutError:
            return
        if isinstance(frame, str):
            op = json.loads(frame)
            if op["op"] == "serverInfo":
                self.server_info = op
            elif op["op"] == "advertise":
                for ch in op["channels"]:
                    self.channels[ch["topic"]] = ch
                    if ch["topic"] in self.wanted:
                        self.subscribe(ch)
            else:
                self.other_ops.append(op)
            return
        if frame[0] == 2:  # time
            self.times.append(struct.unpack_from("<Q", frame, 1)[0])
            return
        opcode, sub_id, log_time = struct.unpack_from("<BIQ", frame)
        assert opcode == 1
        self.messages.setdefault(self.subscribed[sub_id], []).append((log_time,
                                                                      bytes(frame[13:])))


def _view_port(proc, processes, executor) -> int:
    """The port ``pushbot view --port 0`` printed (spinning ``executor`` meanwhile)."""
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and proc.poll() is None:
        found = re.search(r"ws://127\.0\.0\.1:(\d+)", processes.output(proc))
        if found:
            return int(found.group(1))
        executor.spin_once(timeout_sec=0.05)
    raise AssertionError(processes.output(proc))


def test_foxglove_client_receives_camera_and_estimator(ros_context, processes) -> None:
    import rclpy
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Image
    from websockets.sync.client import connect

    from push_ros.images import image_to_array, rgb_image_msg
    from push_ros.poses import pose_with_covariance_msg
    from push_ros.qos import LATCHED_QOS, SENSOR_QOS
    from push_ros.stamps import stamp_from_seconds

    node = rclpy.create_node("view_test_talker", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    rgb = np.zeros((12, 16, 3), dtype=np.uint8)
    rgb[..., 0] = 7
    try:
        camera = node.create_publisher(Image, IMAGE, SENSOR_QOS)
        estimate = node.create_publisher(PoseWithCovarianceStamped, ESTIMATE, LATCHED_QOS)
        estimate.publish(pose_with_covariance_msg([0.125, -0.5, 0.25], np.eye(3) * 1e-4,
                                                  stamp_from_seconds(3.0)))
        proc = processes.start([PUSHBOT, "view", "--port", "0", "--topics", IMAGE, ESTIMATE],
                               name="view")
        port = _view_port(proc, processes, executor)
        deadline = time.monotonic() + 30.0
        with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws:
            assert ws.subprotocol == "foxglove.sdk.v1"
            client = FoxgloveClient(ws, {IMAGE, ESTIMATE})
            while len(client.messages) < 2 and time.monotonic() < deadline:
                camera.publish(rgb_image_msg(rgb, stamp_from_seconds(4.0)))
                executor.spin_once(timeout_sec=0.01)
                client.poll()
        assert set(client.messages) == {IMAGE, ESTIMATE}, (client.channels, client.other_ops,
                                                           processes.output(proc))
    finally:
        executor.shutdown()
        node.destroy_node()
    channels = client.channels
    received = {IMAGE: deserialize_message(client.messages[IMAGE][0][1], Image),
                ESTIMATE: deserialize_message(client.messages[ESTIMATE][0][1],
                                              PoseWithCovarianceStamped)}
    assert channels[IMAGE]["encoding"] == "cdr"
    assert channels[IMAGE]["schemaEncoding"] == "ros2msg"
    assert channels[IMAGE]["schemaName"] == "sensor_msgs/msg/Image"
    assert "MSG: std_msgs/Header" in channels[IMAGE]["schema"]
    assert np.array_equal(image_to_array(received[IMAGE]), rgb)
    assert received[ESTIMATE].pose.pose.position.x == 0.125
    assert received[ESTIMATE].header.stamp.sec == 3
    # Logged at their header stamps (the graph's time), not at the wall clock.
    assert client.messages[IMAGE][0][0] == 4 * 10**9
    assert client.messages[ESTIMATE][0][0] == 3 * 10**9


@pytest.mark.parametrize("offered, granted", [
    (["foxglove.websocket.v1"], "foxglove.websocket.v1"),
    (["foxglove.sdk.v1"], "foxglove.sdk.v1"),
    (["foxglove.sdk.v1.1"], "foxglove.sdk.v1.1"),
    (["foxglove.websocket.v1", "foxglove.sdk.v1"], "foxglove.sdk.v1"),  # the SDK's name first
])
def test_view_accepts_the_foxglove_subprotocols(offered, granted, ros_context,
                                                processes) -> None:
    # Older clients offer only foxglove.websocket.v1 (the SDK itself answers HTTP 400): the
    # view's relay grants it and the client gets the latched estimate like any other.
    import rclpy
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.serialization import deserialize_message
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    from push_ros.poses import pose_with_covariance_msg
    from push_ros.qos import LATCHED_QOS
    from push_ros.stamps import stamp_from_seconds

    node = rclpy.create_node("view_test_protocols", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        estimate = node.create_publisher(PoseWithCovarianceStamped, ESTIMATE, LATCHED_QOS)
        estimate.publish(pose_with_covariance_msg([0.25, 0.5, 0.0], np.eye(3) * 1e-4,
                                                  stamp_from_seconds(2.0)))
        proc = processes.start([PUSHBOT, "view", "--port", "0", "--topics", ESTIMATE],
                               name="view")
        port = _view_port(proc, processes, executor)
        deadline = time.monotonic() + 30.0
        with connect(f"ws://127.0.0.1:{port}", subprotocols=offered) as ws:
            client = FoxgloveClient(ws, {ESTIMATE})
            while ESTIMATE not in client.messages and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.01)
                client.poll()
        with pytest.raises(InvalidStatus, match="400"):
            connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.other.v9"])
        with pytest.raises(InvalidStatus, match="400"):
            connect(f"ws://127.0.0.1:{port}")
    finally:
        executor.shutdown()
        node.destroy_node()
    assert ws.subprotocol == granted
    assert client.server_info["name"] == "pushbot"
    assert ESTIMATE in client.messages, (client.channels, processes.output(proc))
    log_time, payload = client.messages[ESTIMATE][0]
    assert log_time == 2 * 10**9
    assert deserialize_message(payload, PoseWithCovarianceStamped).pose.pose.position.y == 0.5


def _decode_protobuf(channel: dict, payload: bytes):
    """A protobuf message of an advertised channel (schema: base64 FileDescriptorSet)."""
    import base64

    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    pending = list(files.file)
    while pending:  # dependencies first
        fd = pending.pop(0)
        try:
            pool.Add(fd)
        except TypeError:
            pending.append(fd)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
    return cls.FromString(payload)


def test_view_sends_sim_time_and_frame_transforms(ros_context, processes) -> None:
    # A graph on sim time (/clock at 42.5 s): the server sends /clock as its time, logs a
    # stamped message at its stamp and one without a header at /clock, and sends the frame
    # transforms world -> object (estimate), world -> camera (extrinsics) and world ->
    # pusher (end of the executed push) with the messages' values.
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, TransformStamped
    from nav_msgs.msg import Path as PathMsg
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Image
    from websockets.sync.client import connect

    from push_ros.images import rgb_image_msg
    from push_ros.poses import pose_with_covariance_msg
    from push_ros.qos import CLOCK_QOS, LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS
    from push_ros.stamps import stamp_from_seconds
    from pushbot.viz.view import FRAMES_TOPIC

    status_topic = "/view_test/status"
    node = rclpy.create_node("view_test_sim", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        clock = node.create_publisher(Clock, "/clock", CLOCK_QOS)
        camera = node.create_publisher(Image, IMAGE, SENSOR_QOS)
        status = node.create_publisher(DiagnosticStatus, status_topic, RELIABLE_QOS)
        estimate = node.create_publisher(PoseWithCovarianceStamped, ESTIMATE, LATCHED_QOS)
        extrinsics = node.create_publisher(TransformStamped, "/camera/color/extrinsics",
                                           LATCHED_QOS)
        executed = node.create_publisher(PathMsg, "/pusher/executed", RELIABLE_QOS)
        estimate.publish(pose_with_covariance_msg([0.125, -0.5, 0.25], np.eye(3) * 1e-4,
                                                  stamp_from_seconds(41.0)))
        camera_pose = TransformStamped()
        camera_pose.header.stamp = stamp_from_seconds(40.0)
        camera_pose.header.frame_id = "world"
        camera_pose.child_frame_id = "camera_color_optical_frame"
        camera_pose.transform.translation.x, camera_pose.transform.translation.z = 0.1, 0.8
        camera_pose.transform.rotation.x = 1.0  # 180 deg about x: looking down
        camera_pose.transform.rotation.w = 0.0
        extrinsics.publish(camera_pose)
        push = PathMsg()
        push.header.stamp = stamp_from_seconds(42.25)
        push.header.frame_id = "world"
        for x in (0.0, 0.02, 0.05):
            pose = PoseStamped()
            pose.header = push.header
            pose.pose.position.x, pose.pose.position.y = x, -0.02
            pose.pose.orientation.w = 1.0
            push.poses.append(pose)

        proc = processes.start([PUSHBOT, "view", "--port", "0", "--topics", IMAGE,
                                status_topic], name="view")
        port = _view_port(proc, processes, executor)
        deadline = time.monotonic() + 40.0
        rgb = np.zeros((4, 4, 3), dtype=np.uint8)

        def frames_in(client: FoxgloveClient) -> dict:
            if FRAMES_TOPIC not in client.messages:
                return {}
            message = _decode_protobuf(client.channels[FRAMES_TOPIC],
                                       client.messages[FRAMES_TOPIC][-1][1])
            return {t.child_frame_id: t for t in message.transforms}

        with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws:
            client = FoxgloveClient(ws, {IMAGE, status_topic, FRAMES_TOPIC})
            while time.monotonic() < deadline and not (
                    client.times and {IMAGE, status_topic} <= set(client.messages)
                    and len(frames_in(client)) == 3):
                clock.publish(Clock(clock=stamp_from_seconds(42.5)))
                camera.publish(rgb_image_msg(rgb, stamp_from_seconds(42.0)))
                status.publish(DiagnosticStatus(name="view_test", message="idle"))
                executed.publish(push)
                executor.spin_once(timeout_sec=0.01)
                for _ in range(5):
                    client.poll()
        frames = frames_in(client)
        assert client.times and len(frames) == 3, (client.channels.keys(), client.times,
                                                   frames, processes.output(proc))
    finally:
        executor.shutdown()
        node.destroy_node()
    assert "time" in client.server_info["capabilities"]
    assert set(client.times) == {42_500_000_000}  # the server time is the graph's /clock
    assert {t for t, _ in client.messages[IMAGE]} == {42_000_000_000}  # header stamp
    assert {t for t, _ in client.messages[status_topic]} == {42_500_000_000}  # no header
    assert client.channels[FRAMES_TOPIC]["schemaName"] == "foxglove.FrameTransforms"
    obj, cam, pusher = frames["object"], frames["camera_color_optical_frame"], frames["pusher"]
    assert {t.parent_frame_id for t in frames.values()} == {"world"}
    assert (obj.translation.x, obj.translation.y, obj.translation.z) == (0.125, -0.5, 0.0)
    assert obj.rotation.z == pytest.approx(np.sin(0.125), abs=1e-12)
    assert obj.rotation.w == pytest.approx(np.cos(0.125), abs=1e-12)
    assert (obj.timestamp.seconds, obj.timestamp.nanos) == (41, 0)
    assert (cam.translation.x, cam.translation.z, cam.rotation.x, cam.rotation.w) == \
        (0.1, 0.8, 1.0, 0.0)
    assert (pusher.translation.x, pusher.translation.y, pusher.rotation.w) == (0.05, -0.02, 1.0)
    assert (pusher.timestamp.seconds, pusher.timestamp.nanos) == (42, 250_000_000)


def test_view_bad_options(capsys) -> None:
    assert cli.main(["view", "--port", "70000"]) == 2
    assert "--port must be in [0, 65535]" in capsys.readouterr().err
    assert cli.main(["view", "--exclude", "("]) == 2
    assert "is not a regular expression" in capsys.readouterr().err


# ---- the RViz config for full-install users ---------------------------------------------------
REPO = Path(__file__).resolve().parents[1]
RVIZ = REPO / "src" / "pushbot_bringup" / "rviz" / "pushbot.rviz"


def _readme_topics() -> dict[str, str]:
    """Absolute topic name -> type of the topic table (docs/INTERFACES.md)."""
    topics = {}
    for line in (REPO / "docs" / "INTERFACES.md").read_text().splitlines():
        row = re.match(r"\| `([^`]+)` \| ([\w/]+)", line)
        if row:
            name = row.group(1)
            topics[name if name.startswith("/") else "/" + name] = row.group(2)
    return topics


def _topic_values(node: object) -> list[str]:
    if isinstance(node, dict):
        found = [node["Topic"]["Value"]] if isinstance(node.get("Topic"), dict) else []
        return found + [t for v in node.values() for t in _topic_values(v)]
    if isinstance(node, list):
        return [t for v in node for t in _topic_values(v)]
    return []


def test_rviz_config_shows_the_graph_topics() -> None:
    import yaml

    config = yaml.safe_load(RVIZ.read_text())
    manager = config["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "world"
    table = _readme_topics()
    assert len(table) > 10  # the table was parsed
    displays: dict[str, dict] = {}
    for d in manager["Displays"]:  # the first display of each class
        displays.setdefault(d["Class"], d)
    wanted = {
        "rviz_default_plugins/Image": ("/camera/color/image_raw", "sensor_msgs/Image"),
        "rviz_default_plugins/PointCloud2": ("/perception/outline", "sensor_msgs/PointCloud2"),
        "rviz_default_plugins/PoseWithCovariance": (
            "/estimator/object_pose", "geometry_msgs/PoseWithCovarianceStamped"),
        "rviz_default_plugins/Pose": ("/goal_pose", "geometry_msgs/PoseStamped"),
        "rviz_default_plugins/Path": ("/planner/push", "nav_msgs/Path"),
        "rviz_default_plugins/MarkerArray": ("/planner/affordances",
                                             "visualization_msgs/MarkerArray"),
    }
    for cls, (topic, msgtype) in wanted.items():
        assert displays[cls]["Topic"]["Value"] == topic, cls
        assert table[topic] == msgtype, (topic, table.get(topic))
    assert "rviz_default_plugins/TF" in displays
    # Every topic the config names (displays and the goal tool) is in the graph's table, with
    # the QoS of the table: sensor = best effort, latched = transient local.
    for topic in _topic_values(config):
        assert topic in table, f"{topic} is not in the topic table (docs/INTERFACES.md)"
    for d in manager["Displays"]:
        if isinstance(d.get("Topic"), dict):
            qos = d["Topic"]
            if d["Topic"]["Value"] in ("/camera/color/image_raw", "/perception/mask"):
                assert qos["Reliability Policy"] == "Best Effort"
            if d["Topic"]["Value"] in ("/perception/outline", "/estimator/object_pose"):
                assert qos["Durability Policy"] == "Transient Local"
