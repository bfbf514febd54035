"""push_ros codecs the sim bridge uses (time, images, camera info, poses, transforms, paths)
and the quaternion maths of push_core.geometry: messages built directly, no rclpy.init."""

import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path

from push_core.geometry import matrix_from_quaternion, quaternion_from_matrix, quaternion_from_yaw
from push_ros.frames import CAMERA_FRAME, WORLD_FRAME
from push_ros.images import (
    camera_info_msg,
    camera_matrix_from_info,
    depth_image_msg,
    image_to_array,
    rgb_image_msg,
)
from push_ros.paths import path_from_points, points_from_path, push_points_from_path
from push_ros.poses import (
    matrix_from_transform,
    pose_msg,
    pose_stamped_msg,
    transform_msg,
    xytheta_from_pose,
    yaw_from_quaternion,
)
from push_ros.stamps import seconds_from_stamp, stamp_from_seconds

K = np.array([[615.0, 0.0, 320.5], [0.0, 612.0, 239.5], [0.0, 0.0, 1.0]])
STAMP = Time(sec=12, nanosec=500_000_000)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q @ np.diag(np.sign(np.diag(r)))
    return q if np.linalg.det(q) > 0 else -q


def _push_path(points, frame_id=WORLD_FRAME) -> Path:
    msg = Path()
    msg.header.frame_id = frame_id
    for x, y in points:
        pose = PoseStamped()
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg


# ---- time -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("seconds", "sec", "nanosec"),
    [(0.0, 0, 0), (1.5, 1, 500_000_000), (2.000000001, 2, 1), (0.9999999999, 1, 0)],
)
def test_stamp_from_seconds_splits_and_rounds(seconds, sec, nanosec):
    t = stamp_from_seconds(seconds)
    assert (t.sec, t.nanosec) == (sec, nanosec)


def test_stamp_round_trip_to_nanosecond():
    rng = np.random.default_rng(0)
    for s in rng.uniform(0, 1e5, size=100):
        assert seconds_from_stamp(stamp_from_seconds(s)) == pytest.approx(s, abs=1e-9)


@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf, 2.0**31])
def test_stamp_from_seconds_rejects_bad_time(bad):
    with pytest.raises(ValueError, match="time must be finite"):
        stamp_from_seconds(bad)


# ---- images ---------------------------------------------------------------------------------
def test_rgb_image_round_trip_and_layout():
    rgb = np.random.default_rng(1).integers(0, 256, size=(4, 5, 3), dtype=np.uint8)
    msg = rgb_image_msg(rgb, STAMP)
    assert (msg.height, msg.width, msg.step, msg.encoding) == (4, 5, 15, "rgb8")
    assert msg.header.frame_id == CAMERA_FRAME and msg.header.stamp == STAMP
    assert len(msg.data) == msg.height * msg.step
    # First pixel's red channel is the first byte (row-major, R G B).
    assert msg.data[0] == rgb[0, 0, 0] and msg.data[2] == rgb[0, 0, 2]
    np.testing.assert_array_equal(image_to_array(msg), rgb)


def test_depth_image_round_trip_keeps_nan_and_is_little_endian():
    depth = np.random.default_rng(2).uniform(0.2, 2.0, size=(3, 4)).astype(np.float64)
    depth[1, 2] = np.nan
    msg = depth_image_msg(depth, STAMP, frame_id="cam")
    assert (msg.height, msg.width, msg.step, msg.encoding) == (3, 4, 16, "32FC1")
    assert msg.is_bigendian == 0 and msg.header.frame_id == "cam"
    assert np.frombuffer(msg.data, "<f4")[0] == np.float32(depth[0, 0])
    out = image_to_array(msg)
    assert out.dtype == np.float32 and out.shape == (3, 4)
    np.testing.assert_array_equal(out, depth.astype(np.float32))


def test_image_to_array_handles_padded_rows_and_big_endian():
    depth = np.arange(6, dtype=">f4").reshape(2, 3)
    msg = depth_image_msg(np.zeros((2, 3)), STAMP)
    padded = np.zeros((2, 16), np.uint8)  # 12 bytes of pixels + 4 bytes of padding per row
    padded[:, :12] = np.frombuffer(depth.tobytes(), np.uint8).reshape(2, 12)
    msg.step, msg.is_bigendian, msg.data = 16, 1, padded.tobytes()
    np.testing.assert_array_equal(image_to_array(msg), depth.astype(np.float32))


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.zeros((4, 5), np.uint8), r"\(H, W, 3\) uint8"),
        (np.zeros((4, 5, 3), np.float32), r"\(H, W, 3\) uint8"),
        (np.zeros((0, 5, 3), np.uint8), "non-empty"),
    ],
)
def test_rgb_image_rejects_bad_arrays(bad, match):
    with pytest.raises(ValueError, match=match):
        rgb_image_msg(bad, STAMP)


def test_depth_image_rejects_bad_arrays():
    with pytest.raises(ValueError, match=r"\(H, W\) float"):
        depth_image_msg(np.zeros((2, 3, 1)), STAMP)
    with pytest.raises(ValueError, match=r"\(H, W\) float"):
        depth_image_msg(np.zeros((2, 3), np.uint16), STAMP)


def test_image_to_array_validates_layout_before_reshaping():
    msg = rgb_image_msg(np.zeros((2, 2, 3), np.uint8), STAMP)
    msg.data = msg.data[:-1]
    with pytest.raises(ValueError, match="expected height \\* step"):
        image_to_array(msg)
    msg = rgb_image_msg(np.zeros((2, 2, 3), np.uint8), STAMP)
    msg.step = 5
    with pytest.raises(ValueError, match="smaller than one row"):
        image_to_array(msg)
    msg.encoding = "yuv422"
    with pytest.raises(ValueError, match="unsupported image encoding 'yuv422'"):
        image_to_array(msg)


# ---- camera info ----------------------------------------------------------------------------
def test_camera_info_is_plumb_bob_with_projection_k_zero():
    msg = camera_info_msg(K, 640, 480, STAMP)
    assert (msg.width, msg.height) == (640, 480)
    assert msg.distortion_model == "plumb_bob" and list(msg.d) == [0.0] * 5
    assert msg.header.frame_id == CAMERA_FRAME and msg.header.stamp == STAMP
    np.testing.assert_array_equal(np.reshape(msg.r, (3, 3)), np.eye(3))
    np.testing.assert_array_equal(np.reshape(msg.p, (3, 4)), np.hstack([K, np.zeros((3, 1))]))
    np.testing.assert_array_equal(camera_matrix_from_info(msg), K)


@pytest.mark.parametrize(
    ("k", "match"),
    [
        (np.eye(2), r"finite \(3, 3\)"),
        (np.where(np.eye(3) > 0, np.nan, 0.0), r"finite \(3, 3\)"),
        (np.diag([-1.0, 1.0, 1.0]), "fx, fy > 0"),
        (np.diag([1.0, 1.0, 2.0]), "last row"),
    ],
)
def test_camera_info_rejects_bad_intrinsics(k, match):
    with pytest.raises(ValueError, match=match):
        camera_info_msg(k, 640, 480, STAMP)


def test_camera_info_rejects_bad_size():
    with pytest.raises(ValueError, match="image size must be positive"):
        camera_info_msg(K, 0, 480, STAMP)


# ---- rotations and poses --------------------------------------------------------------------
def test_yaw_quaternion_is_xyzw_and_round_trips():
    np.testing.assert_allclose(quaternion_from_yaw(math.pi / 2), [0, 0, 2**-0.5, 2**-0.5])
    for theta in np.linspace(-math.pi + 1e-6, math.pi, 17):
        assert yaw_from_quaternion(quaternion_from_yaw(theta)) == pytest.approx(theta)


def test_rotation_matrix_quaternion_round_trip():
    rng = np.random.default_rng(3)
    for _ in range(50):
        r = _random_rotation(rng)
        q = quaternion_from_matrix(r)
        assert q[3] >= 0 and np.linalg.norm(q) == pytest.approx(1.0)
        np.testing.assert_allclose(matrix_from_quaternion(q), r, atol=1e-12)
    # 180 degree rotations exercise the non-trace pivots.
    for axis in np.eye(3):
        r = 2 * np.outer(axis, axis) - np.eye(3)
        np.testing.assert_allclose(matrix_from_quaternion(quaternion_from_matrix(r)), r, atol=1e-12)


def test_rotation_validators_name_the_problem():
    with pytest.raises(ValueError, match="orthonormal"):
        quaternion_from_matrix(np.diag([1.0, 1.0, 2.0]))
    with pytest.raises(ValueError, match="orthonormal"):
        quaternion_from_matrix(np.diag([1.0, 1.0, -1.0]))  # a reflection
    with pytest.raises(ValueError, match="zero norm"):
        yaw_from_quaternion([0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        matrix_from_quaternion([0.0, 0.0, math.nan, 1.0])


def test_pose_round_trip_and_quaternion_order():
    msg = pose_msg(0.1, -0.2, 0.3, z=0.01)
    assert (msg.position.x, msg.position.y, msg.position.z) == (0.1, -0.2, 0.01)
    assert msg.orientation.z == pytest.approx(math.sin(0.15))
    assert msg.orientation.w == pytest.approx(math.cos(0.15))
    np.testing.assert_allclose(xytheta_from_pose(msg), [0.1, -0.2, 0.3])
    stamped = pose_stamped_msg([0.05, 0.02, -3.0], STAMP)
    assert stamped.header.frame_id == WORLD_FRAME and stamped.header.stamp == STAMP
    np.testing.assert_allclose(xytheta_from_pose(stamped), [0.05, 0.02, -3.0])


def test_pose_wraps_theta_into_pi_range():
    np.testing.assert_allclose(xytheta_from_pose(pose_msg(0, 0, 3 * math.pi / 2))[2], -math.pi / 2)


def test_pose_rejects_non_finite_and_bad_shape():
    with pytest.raises(ValueError, match="pose must be finite"):
        pose_msg(0.0, math.nan, 0.0)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        pose_stamped_msg([0.0, 0.0], STAMP)
    msg = pose_msg(0.0, 0.0, 0.0)
    msg.position.x = math.inf
    with pytest.raises(ValueError, match="position must be finite"):
        xytheta_from_pose(msg)


# ---- transforms -----------------------------------------------------------------------------
def test_transform_round_trip_maps_child_points_to_parent():
    rng = np.random.default_rng(4)
    t = np.eye(4)
    t[:3, :3] = _random_rotation(rng)
    t[:3, 3] = [0.5, -0.1, 0.6]
    msg = transform_msg(t, STAMP, WORLD_FRAME, CAMERA_FRAME)
    assert msg.header.frame_id == WORLD_FRAME and msg.child_frame_id == CAMERA_FRAME
    assert msg.transform.translation.x == 0.5 and msg.transform.rotation.w >= 0
    back = matrix_from_transform(msg)
    np.testing.assert_allclose(back, t, atol=1e-12)
    p_child = np.array([0.0, 0.0, 1.0, 1.0])  # one metre along the optical axis
    np.testing.assert_allclose(back @ p_child, t @ p_child, atol=1e-12)


@pytest.mark.parametrize(
    ("t", "match"),
    [
        (np.eye(3), r"finite \(4, 4\)"),
        (np.diag([1.0, 1.0, 1.0, 2.0]), "last row"),
        (np.diag([2.0, 1.0, 1.0, 1.0]), "orthonormal"),
    ],
)
def test_transform_rejects_bad_matrices(t, match):
    with pytest.raises(ValueError, match=match):
        transform_msg(t, STAMP, WORLD_FRAME, CAMERA_FRAME)


# ---- paths ----------------------------------------------------------------------------------
def test_path_round_trip_with_per_pose_stamps():
    points = np.array([[0.0, 0.1], [0.05, 0.1]])
    stamps = [stamp_from_seconds(1.0), stamp_from_seconds(3.5)]
    msg = path_from_points(points, stamps)
    assert msg.header.frame_id == WORLD_FRAME and msg.header.stamp == stamps[-1]
    assert [p.header.stamp for p in msg.poses] == stamps
    assert all(p.header.frame_id == WORLD_FRAME for p in msg.poses)
    np.testing.assert_array_equal(points_from_path(msg), points)


def test_path_from_points_rejects_bad_input():
    with pytest.raises(ValueError, match=r"\(N, 2\)"):
        path_from_points(np.zeros((2, 3)), [STAMP, STAMP])
    with pytest.raises(ValueError, match="2 points but 1 stamps"):
        path_from_points(np.zeros((2, 2)), [STAMP])
    with pytest.raises(ValueError, match="finite"):
        path_from_points(np.array([[0.0, math.nan]]), [STAMP])


def test_push_points_from_a_valid_command():
    approach, contact, end = push_points_from_path(
        _push_path([(-0.1, 0.0), (-0.05, 0.0), (0.0, 0.0)])
    )
    np.testing.assert_array_equal(approach, [-0.1, 0.0])
    np.testing.assert_array_equal(contact, [-0.05, 0.0])
    np.testing.assert_array_equal(end, [0.0, 0.0])


@pytest.mark.parametrize(
    ("msg", "match"),
    [
        (_push_path([(0, 0), (1, 0), (2, 0)], "map"), "frame_id is 'map', expected 'world'"),
        (_push_path([(0, 0), (1, 0), (2, 0)], ""), "frame_id is '', expected 'world'"),
        (_push_path([(0, 0), (1, 0)]), "path has 2 poses, expected exactly 3"),
        (_push_path([(0, 0), (1, 0), (2, 0), (3, 0)]), "path has 4 poses, expected exactly 3"),
        (_push_path([]), "path has 0 poses, expected exactly 3"),
        (_push_path([(0, 0), (math.nan, 0), (2, 0)]), "pose 1 position is not finite"),
        (_push_path([(0, 0), (1, 0), (2, -math.inf)]), "pose 2 position is not finite"),
    ],
)
def test_push_command_validation_names_the_problem(msg, match):
    with pytest.raises(ValueError, match=match):
        push_points_from_path(msg)


def test_push_command_rejects_a_pose_in_another_frame():
    msg = _push_path([(0, 0), (1, 0), (2, 0)])
    msg.poses[2].header.frame_id = CAMERA_FRAME
    with pytest.raises(ValueError, match="pose 2 has frame_id 'camera_color_optical_frame'"):
        push_points_from_path(msg)


def test_push_command_rejects_non_finite_height():
    msg = _push_path([(0, 0), (1, 0), (2, 0)])
    msg.poses[0].pose.position.z = math.nan
    with pytest.raises(ValueError, match="pose 0 position is not finite"):
        push_points_from_path(msg)
