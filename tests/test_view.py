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

pytestmark = pytest.mark.ros

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

            def subscribe(ch: dict) -> None:
                sub_id = len(subscribed) + 1
                subscribed[sub_id] = ch['topic']
                ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                    {'id': sub_id, 'channelId': ch['id']}]}))

            while len(received) < 2 and time.monotonic() < deadline:
                camera.publish(rgb_image_msg(rgb, stamp_from_seconds(4.0)))
                executor.spin_once(timeout_sec=0.01)
                try:
                    frame = ws.recv(timeout=0.1)
                except TimeoutError:
                    continue
                if isinstance(frame, str):
                    op = json.loads(frame)
                    retry = re.search(r'unknown channel: (\d+)', op.get('message', ''))
                    if op['op'] == 'advertise':
                        for ch in op['channels']:
                            channels[ch['topic']] = ch
                            subscribe(ch)
                    elif op['op'] == 'status' and retry:
                        # foxglove-sdk may advertise a channel an instant before it accepts
                        # subscriptions to it; subscribe again.
                        subscribe(next(c for c in channels.values()
                                       if c['id'] == int(retry.group(1))))
                    continue
                opcode, sub_id, _ = struct.unpack_from('<BIQ', frame)
                assert opcode == 1
                topic = subscribed[sub_id]
                cls = Image if topic == IMAGE else PoseWithCovarianceStamped
                received.setdefault(topic, deserialize_message(bytes(frame[13:]), cls))
        assert set(received) == {IMAGE, ESTIMATE}, (channels, processes.output(proc))
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
