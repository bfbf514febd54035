"""Times and frames of ``pushbot view`` without a graph.

``pushbot.viz.view_frames`` (ROS-free): the header stamp read from CDR bytes (serialized by the
``rosbags`` Jazzy type store, and a big-endian buffer built by hand), the log-time rule
(stamp, else /clock, else wall clock), checked transforms; and the message -> transform
conversions of ``pushbot.viz.view`` on real message objects (no rclpy context).
"""

from __future__ import annotations

import math
import struct
import time

import pytest

from pushbot.viz.view_frames import FrameTree, SimTime, header_stamp_ns, make_transform


def _pose_stamped_cdr(sec: int, nanosec: int) -> bytes:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    t = store.types
    msg = t["geometry_msgs/msg/PoseStamped"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](
            sec=sec, nanosec=nanosec), frame_id="world"),
        pose=t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
    return bytes(store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))


def test_header_stamp_from_cdr_bytes() -> None:
    assert header_stamp_ns(_pose_stamped_cdr(7, 250)) == 7_000_000_250
    assert header_stamp_ns(_pose_stamped_cdr(0, 0)) is None  # unset stamp
    big_endian = b"\x00\x00\x00\x00" + struct.pack(">iI", 3, 5) + b"\x00" * 8
    assert header_stamp_ns(big_endian) == 3_000_000_005
    little = b"\x00\x01\x00\x00" + struct.pack("<iI", 3, 5)
    assert header_stamp_ns(little) == 3_000_000_005
    assert header_stamp_ns(little[:11]) is None  # too short
    assert header_stamp_ns(b"\x01\x01\x00\x00" + little[4:]) is None  # not an encapsulation
    assert header_stamp_ns(b"\x00\x01\x00\x00" + struct.pack("<iI", 1, 10**9)) is None
    assert header_stamp_ns(b"\x00\x01\x00\x00" + struct.pack("<iI", -1, 0)) is None


def test_log_time_is_stamp_else_clock_else_wall() -> None:
    sim = SimTime()
    before = time.time_ns()
    wall = sim.log_time(None)
    assert before <= wall <= time.time_ns()
    assert sim.log_time(42) == 42
    sim.on_clock(42_500_000_000)
    assert sim.log_time(None) == 42_500_000_000
    assert sim.log_time(0) == 42_500_000_000
    assert sim.log_time(41_000_000_000) == 41_000_000_000


def test_transforms_are_checked_and_normalised() -> None:
    t = make_transform("world", "object", 5, (0.1, 0.2, 0.0), (0.0, 0.0, 2.0, 0.0))
    assert t.rotation == (0.0, 0.0, 1.0, 0.0) and t.translation == (0.1, 0.2, 0.0)
    with pytest.raises(ValueError, match="two different frame ids"):
        make_transform("world", "world", 0, (0, 0, 0), (0, 0, 0, 1))
    with pytest.raises(ValueError, match="two different frame ids"):
        make_transform("", "object", 0, (0, 0, 0), (0, 0, 0, 1))
    with pytest.raises(ValueError, match="finite"):
        make_transform("world", "object", 0, (math.nan, 0, 0), (0, 0, 0, 1))
    with pytest.raises(ValueError, match="zero quaternion"):
        make_transform("world", "object", 0, (0, 0, 0), (0, 0, 0, 0))
    tree = FrameTree()
    assert tree.latest_ns() == 0
    tree.update(t)
    tree.update(make_transform("world", "pusher", 9, (0, 0, 0), (0, 0, 0, 1)))
    tree.update(make_transform("world", "object", 3, (0.3, 0, 0), (0, 0, 0, 1)))
    assert tree.transforms["object"].translation == (0.3, 0.0, 0.0)  # the last received
    assert tree.latest_ns() == 9


def test_message_conversions_of_the_view() -> None:
    import numpy as np
    from diagnostic_msgs.msg import DiagnosticStatus
    from geometry_msgs.msg import PoseStamped, TransformStamped
    from nav_msgs.msg import Path
    from sensor_msgs.msg import Image

    from push_ros.poses import pose_with_covariance_msg
    from push_ros.stamps import stamp_from_seconds
    from pushbot.viz.view import _has_header, camera_transform, object_transform, pusher_transform

    estimate = pose_with_covariance_msg([0.125, -0.5, 0.25], np.eye(3) * 1e-4,
                                        stamp_from_seconds(3.5))
    t = object_transform(estimate)
    assert (t.parent, t.child, t.stamp_ns) == ("world", "object", 3_500_000_000)
    assert t.translation == (0.125, -0.5, 0.0)
    assert t.rotation == pytest.approx((0.0, 0.0, math.sin(0.125), math.cos(0.125)))

    extrinsics = TransformStamped()
    extrinsics.header.frame_id, extrinsics.child_frame_id = "world", "camera_color_optical_frame"
    extrinsics.header.stamp = stamp_from_seconds(1.0)
    extrinsics.transform.translation.z = 0.8
    extrinsics.transform.rotation.x, extrinsics.transform.rotation.w = 1.0, 0.0
    t = camera_transform(extrinsics)
    assert (t.parent, t.child, t.translation, t.rotation) == (
        "world", "camera_color_optical_frame", (0.0, 0.0, 0.8), (1.0, 0.0, 0.0, 0.0))

    path = Path()
    path.header.frame_id = "world"
    with pytest.raises(ValueError, match="without poses"):
        pusher_transform(path)
    for x in (0.0, 0.04):
        pose = PoseStamped()
        pose.pose.position.x, pose.pose.orientation.w = x, 1.0
        path.poses.append(pose)
    t = pusher_transform(path)
    assert (t.parent, t.child, t.translation) == ("world", "pusher", (0.04, 0.0, 0.0))

    assert _has_header(Image) and not _has_header(DiagnosticStatus)
