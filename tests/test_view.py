"""``pushbot view`` (issue 14, item 6): a real Foxglove WebSocket client receives the graph.

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

PUSHBOT = str(Path(sys.executable).parent / 'pushbot')
IMAGE, ESTIMATE = '/camera/color/image_raw', '/estimator/object_pose'


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

    node = rclpy.create_node('view_test_talker', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    rgb = np.zeros((12, 16, 3), dtype=np.uint8)
    rgb[..., 0] = 7
    try:
        camera = node.create_publisher(Image, IMAGE, SENSOR_QOS)
        estimate = node.create_publisher(PoseWithCovarianceStamped, ESTIMATE, LATCHED_QOS)
        estimate.publish(pose_with_covariance_msg([0.125, -0.5, 0.25], np.eye(3) * 1e-4,
                                                  stamp_from_seconds(3.0)))
        proc = processes.start([PUSHBOT, 'view', '--port', '0', '--topics', IMAGE, ESTIMATE],
                               name='view')
        deadline = time.monotonic() + 30.0
        port = None
        while port is None and time.monotonic() < deadline and proc.poll() is None:
            found = re.search(r'ws://127\.0\.0\.1:(\d+)', processes.output(proc))
            port = int(found.group(1)) if found else None
            executor.spin_once(timeout_sec=0.05)
        assert port, processes.output(proc)

        received: dict[str, object] = {}
        with connect(f'ws://127.0.0.1:{port}', subprotocols=['foxglove.sdk.v1']) as ws:
            assert ws.subprotocol == 'foxglove.sdk.v1'
            channels: dict[str, dict] = {}
            subscribed: dict[int, str] = {}
            asked: dict[str, float] = {}  # topic -> when it was last subscribed
            other_ops: list[dict] = []

            def subscribe(ch: dict) -> None:
                sub_id = len(subscribed) + 1
                subscribed[sub_id] = ch['topic']
                asked[ch['topic']] = time.monotonic()
                ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                    {'id': sub_id, 'channelId': ch['id']}]}))

            while len(received) < 2 and time.monotonic() < deadline:
                camera.publish(rgb_image_msg(rgb, stamp_from_seconds(4.0)))
                executor.spin_once(timeout_sec=0.01)
                # foxglove-sdk can advertise a channel an instant before it accepts
                # subscriptions to it ("unknown channel"): subscribe again to a channel that
                # has sent nothing for 3 s (a liveness retry; the assertions do not depend on
                # it).
                for topic, when in list(asked.items()):
                    if topic not in received and time.monotonic() - when > 3.0:
                        subscribe(channels[topic])
                try:
                    frame = ws.recv(timeout=0.1)
                except TimeoutError:
                    continue
                if isinstance(frame, str):
                    op = json.loads(frame)
                    if op['op'] == 'advertise':
                        for ch in op['channels']:
                            channels[ch['topic']] = ch
                            subscribe(ch)
                    else:
                        other_ops.append(op)
                    continue
                opcode, sub_id, _ = struct.unpack_from('<BIQ', frame)
                assert opcode == 1
                topic = subscribed[sub_id]
                cls = Image if topic == IMAGE else PoseWithCovarianceStamped
                received.setdefault(topic, deserialize_message(bytes(frame[13:]), cls))
        assert set(received) == {IMAGE, ESTIMATE}, (channels, other_ops,
                                                     processes.output(proc))
    finally:
        executor.shutdown()
        node.destroy_node()
    assert channels[IMAGE]['encoding'] == 'cdr'
    assert channels[IMAGE]['schemaEncoding'] == 'ros2msg'
    assert channels[IMAGE]['schemaName'] == 'sensor_msgs/msg/Image'
    assert 'MSG: std_msgs/Header' in channels[IMAGE]['schema']
    assert np.array_equal(image_to_array(received[IMAGE]), rgb)
    assert received[ESTIMATE].pose.pose.position.x == 0.125
    assert received[ESTIMATE].header.stamp.sec == 3


def test_view_bad_options(capsys) -> None:
    assert cli.main(['view', '--port', '70000']) == 2
    assert '--port must be in [0, 65535]' in capsys.readouterr().err
    assert cli.main(['view', '--exclude', '(']) == 2
    assert 'is not a regular expression' in capsys.readouterr().err


# ---- the RViz config for full-install users ---------------------------------------------------
REPO = Path(__file__).resolve().parents[1]
RVIZ = REPO / 'src' / 'pushbot_bringup' / 'rviz' / 'pushbot.rviz'


def _readme_topics() -> dict[str, str]:
    """Absolute topic name -> type of the topic table (docs/INTERFACES.md)."""
    topics = {}
    for line in (REPO / 'docs' / 'INTERFACES.md').read_text().splitlines():
        row = re.match(r'\| `([^`]+)` \| ([\w/]+)', line)
        if row:
            name = row.group(1)
            topics[name if name.startswith('/') else '/' + name] = row.group(2)
    return topics


def _topic_values(node: object) -> list[str]:
    if isinstance(node, dict):
        found = [node['Topic']['Value']] if isinstance(node.get('Topic'), dict) else []
        return found + [t for v in node.values() for t in _topic_values(v)]
    if isinstance(node, list):
        return [t for v in node for t in _topic_values(v)]
    return []


def test_rviz_config_shows_the_graph_topics() -> None:
    import yaml

    config = yaml.safe_load(RVIZ.read_text())
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'world'
    table = _readme_topics()
    assert len(table) > 10  # the table was parsed
    displays: dict[str, dict] = {}
    for d in manager['Displays']:  # the first display of each class
        displays.setdefault(d['Class'], d)
    wanted = {
        'rviz_default_plugins/Image': ('/camera/color/image_raw', 'sensor_msgs/Image'),
        'rviz_default_plugins/PointCloud2': ('/perception/outline', 'sensor_msgs/PointCloud2'),
        'rviz_default_plugins/PoseWithCovariance': (
            '/estimator/object_pose', 'geometry_msgs/PoseWithCovarianceStamped'),
        'rviz_default_plugins/Pose': ('/goal_pose', 'geometry_msgs/PoseStamped'),
        'rviz_default_plugins/Path': ('/planner/push', 'nav_msgs/Path'),
        'rviz_default_plugins/MarkerArray': ('/planner/affordances',
                                             'visualization_msgs/MarkerArray'),
    }
    for cls, (topic, msgtype) in wanted.items():
        assert displays[cls]['Topic']['Value'] == topic, cls
        assert table[topic] == msgtype, (topic, table.get(topic))
    assert 'rviz_default_plugins/TF' in displays
    # Every topic the config names (displays and the goal tool) is in the graph's table, with
    # the QoS of the table: sensor = best effort, latched = transient local.
    for topic in _topic_values(config):
        assert topic in table, f'{topic} is not in the topic table (docs/INTERFACES.md)'
    for d in manager['Displays']:
        if isinstance(d.get('Topic'), dict):
            qos = d['Topic']
            if d['Topic']['Value'] in ('/camera/color/image_raw', '/perception/mask'):
                assert qos['Reliability Policy'] == 'Best Effort'
            if d['Topic']['Value'] in ('/perception/outline', '/estimator/object_pose'):
                assert qos['Durability Policy'] == 'Transient Local'
