"""push_ros codecs of the estimator inputs and outputs: messages built directly, no rclpy.init."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Path

from push_core.estimator import STATE_LABELS
from push_ros import NonFiniteError
from push_ros.outline import outline_cloud_msg, outline_from_cloud
from push_ros.paths import executed_push_from_path as push_from_path
from push_ros.poses import (
    center_of_mass_msg,
    planar_matrix,
    pose_with_covariance_msg,
    quaternion_msg,
    transform_msg,
    yaw_from_quaternion,
)
from push_ros.poses import pose_with_covariance_from_msg as observation_from_msg
from push_ros.stamps import seconds_from_stamp, stamp_from_seconds
from push_ros.state import state_array_msg, state_from_array_msg

POINTS = np.array([[0.03, -0.03], [0.03, 0.03], [-0.03, 0.03], [-0.03, -0.03]])
NORMALS = np.array([[0.7071, -0.7071], [0.7071, 0.7071], [-0.7071, 0.7071], [-0.7071, -0.7071]])


def test_stamps_round_trip() -> None:
    stamp = stamp_from_seconds(12.345678901)
    assert (stamp.sec, stamp.nanosec) == (12, 345678901)
    assert seconds_from_stamp(stamp) == pytest.approx(12.345678901, abs=1e-9)
    for bad in (-1.0, math.nan, 2.0**31):
        with pytest.raises(ValueError, match="stamp"):
            stamp_from_seconds(bad)


@pytest.mark.parametrize("theta", [0.0, 0.3, -2.0, math.pi])
def test_yaw_round_trip(theta: float) -> None:
    assert yaw_from_quaternion(quaternion_msg(theta)) == pytest.approx(
        math.atan2(math.sin(theta), math.cos(theta)))


def test_outline_codec_raises_the_estimators_non_finite_error() -> None:
    # The codec is push_perception's (tests/perception/test_conversions.py); what the node
    # relies on here: its frame parameter and NonFiniteError for NaN coordinates.
    msg = outline_cloud_msg(POINTS, NORMALS, stamp_from_seconds(1.0), "table_object")
    points, normals = outline_from_cloud(msg, "table_object")
    np.testing.assert_allclose(points, POINTS, atol=1e-7)
    np.testing.assert_allclose(normals, NORMALS, atol=1e-7)
    msg.data = np.full(24, np.nan, dtype="<f4").tobytes() + bytes(msg.data)[96:]
    with pytest.raises(NonFiniteError, match="NaN"):
        outline_from_cloud(msg, "table_object")


def test_observation_parses_pose_and_planar_covariance() -> None:
    cov = np.diag([4e-6, 9e-6, 1e-4])
    msg = pose_with_covariance_msg([0.1, -0.2, 2.5], cov, stamp_from_seconds(3.5),
                                   unmeasured_variance=0.0)  # the estimator's outputs
    obs = observation_from_msg(msg)
    assert obs.stamp == 3.5
    np.testing.assert_allclose(obs.pose, [0.1, -0.2, 2.5])
    np.testing.assert_allclose(obs.covariance, cov)
    full = np.asarray(msg.pose.covariance).reshape(6, 6)
    assert full[5, 5] == 1e-4 and full[2, 2] == 0.0  # yaw is rot z; z is fixed


def test_observation_without_usable_covariance_gives_none() -> None:
    msg = pose_with_covariance_msg([0.0, 0.0, 0.0], np.zeros((3, 3)), stamp_from_seconds(1.0))
    assert observation_from_msg(msg).covariance is None  # all zeros = unknown
    # The one writer refuses a negative variance; another publisher may send one.
    msg.pose.covariance = (-np.eye(6)).ravel().tolist()
    assert observation_from_msg(msg).covariance is None


@pytest.mark.parametrize(("mutate", "error", "match"), [
    (lambda m: setattr(m.pose.pose.position, "x", math.nan), NonFiniteError, "position"),
    (lambda m: setattr(m.pose.pose.orientation, "w", math.inf), NonFiniteError, "orientation"),
    (lambda m: setattr(m.pose.pose.orientation, "w", 0.0), ValueError, "zero norm"),
    (lambda m: setattr(m.header, "frame_id", "map"), ValueError, "frame_id"),
])
def test_bad_observations_raise(mutate: object, error: type, match: str) -> None:
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = "world"
    msg.pose.pose.orientation.w = 1.0
    mutate(msg)  # type: ignore[operator]
    with pytest.raises(error, match=match):
        observation_from_msg(msg)


def executed_path(points: list[tuple[float, float]], stamps: list[float]) -> Path:
    msg = Path()
    msg.header.frame_id = "world"
    for (x, y), t in zip(points, stamps, strict=True):
        pose = PoseStamped()
        pose.header.stamp = stamp_from_seconds(t)
        pose.pose.position.x, pose.pose.position.y = x, y
        msg.poses.append(pose)
    return msg


def test_executed_push_parses() -> None:
    push = push_from_path(executed_path([(0.0, 0.1), (0.03, 0.1)], [2.0, 3.5]))
    np.testing.assert_allclose([*push.start, *push.end], [0.0, 0.1, 0.03, 0.1])
    assert (push.t_start, push.t_end) == (2.0, 3.5)


@pytest.mark.parametrize(("path", "error", "match"), [
    (executed_path([(0.0, 0.0)], [1.0]), ValueError, "expected 2"),
    (executed_path([(0.0, 0.0), (math.nan, 0.0)], [1.0, 2.0]), NonFiniteError, "poses\\[1\\]"),
    (executed_path([(0.0, 0.0), (0.01, 0.0)], [2.0, 1.0]), ValueError, "before"),
])
def test_bad_executed_pushes_raise(path: Path, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        push_from_path(path)


def test_executed_push_in_the_wrong_frame_raises() -> None:
    path = executed_path([(0.0, 0.0), (0.01, 0.0)], [1.0, 2.0])
    path.poses[0].header.frame_id = "camera"
    with pytest.raises(ValueError, match="frame_id"):
        push_from_path(path)


def test_state_array_has_the_documented_layout() -> None:
    x = np.arange(7.0)
    p = np.arange(49.0).reshape(7, 7)
    msg = state_array_msg(x, p)
    assert [(d.label, d.size, d.stride) for d in msg.layout.dim] == [
        ("state", 7, 7), ("covariance_row_major", 49, 49)]
    assert len(STATE_LABELS) == 7 and list(msg.data[:7]) == list(x)
    assert list(msg.data[7:]) == list(p.ravel())
    x2, p2 = state_from_array_msg(msg)
    np.testing.assert_array_equal(x2, x)
    np.testing.assert_array_equal(p2, p)
    msg.layout.dim[0].label = "pose"
    with pytest.raises(ValueError, match="layout"):
        state_from_array_msg(msg)
    with pytest.raises(ValueError, match="state"):
        state_array_msg(np.zeros(6), p)


def test_com_point_and_transform() -> None:
    com = center_of_mass_msg([0.004, -0.002], stamp_from_seconds(1.0))
    assert com.header.frame_id == "object" and (com.point.x, com.point.y) == (0.004, -0.002)
    tf = transform_msg(planar_matrix([0.1, 0.2, math.pi / 2]), stamp_from_seconds(1.0),
                       "world", "object")
    assert (tf.header.frame_id, tf.child_frame_id) == ("world", "object")
    assert tf.transform.rotation.z == pytest.approx(math.sqrt(0.5))
