"""push_perception.conversions: outline clouds, pose with covariance, mask and depth images."""

from __future__ import annotations

from array import array

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from sensor_msgs.msg import Image, PointField

from push_perception.conversions import (
    OUTLINE_FIELDS,
    UNMEASURED_VARIANCE,
    depth_to_metres,
    mask_image_msg,
    outline_cloud_msg,
    outline_from_cloud,
    pose_with_covariance_msg,
)
from sim_bridge.conversions import image_to_array, xytheta_from_pose

STAMP = Time(sec=12, nanosec=345)


def square_outline() -> tuple[np.ndarray, np.ndarray]:
    pts = np.array([[0.01, 0.0], [0.0, 0.01], [-0.01, 0.0], [0.0, -0.01]])
    return pts, pts / 0.01


def test_outline_cloud_round_trip_and_layout() -> None:
    points, normals = square_outline()
    msg = outline_cloud_msg(points, normals, STAMP)
    assert msg.header.frame_id == "object" and msg.header.stamp == STAMP
    assert [f.name for f in msg.fields] == list(OUTLINE_FIELDS)
    assert all(f.datatype == PointField.FLOAT32 and f.count == 1 for f in msg.fields)
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 4, 24, 96)
    assert msg.is_dense and not msg.is_bigendian
    raw = np.frombuffer(bytes(msg.data), dtype="<f4").reshape(4, 6)
    np.testing.assert_array_equal(raw[:, [2, 5]], 0.0)  # z and normal_z
    p, n = outline_from_cloud(msg)
    np.testing.assert_allclose(p, points, atol=1e-9)
    np.testing.assert_allclose(n, normals, atol=1e-7)


@pytest.mark.parametrize(("points", "normals", "match"), [
    (np.zeros((2, 2)), np.zeros((2, 2)), "K >= 3"),
    (np.zeros((4, 2)), np.zeros((3, 2)), r"\(K, 2\)"),
    (np.full((4, 2), np.nan), np.zeros((4, 2)), "finite"),
])
def test_outline_cloud_rejects_bad_arrays(points, normals, match) -> None:
    with pytest.raises(ValueError, match=match):
        outline_cloud_msg(points, normals, STAMP)


def test_outline_parser_rejects_malformed_clouds() -> None:
    msg = outline_cloud_msg(*square_outline(), STAMP)
    short = outline_cloud_msg(*square_outline(), STAMP)
    short.data = array("B", bytes(short.data)[:-4])
    with pytest.raises(ValueError, match="bytes"):
        outline_from_cloud(short)
    msg.fields = [f for f in msg.fields if f.name != "normal_y"]
    with pytest.raises(ValueError, match="normal_y"):
        outline_from_cloud(msg)


def test_pose_with_covariance_places_the_planar_block() -> None:
    cov = np.array([[4e-6, 1e-7, 0.0], [1e-7, 9e-6, 2e-7], [0.0, 2e-7, 1e-4]])
    msg = pose_with_covariance_msg(np.array([0.1, -0.2, 2.5]), cov, STAMP)
    assert msg.header.frame_id == "world"
    np.testing.assert_allclose(xytheta_from_pose(msg.pose.pose), [0.1, -0.2, 2.5])
    full = np.array(msg.pose.covariance).reshape(6, 6)
    np.testing.assert_allclose(full[np.ix_([0, 1, 5], [0, 1, 5])], cov)
    np.testing.assert_allclose(np.diag(full)[2:5], UNMEASURED_VARIANCE)
    assert full[0, 2] == full[5, 3] == 0.0
    with pytest.raises(ValueError, match="symmetric"):
        pose_with_covariance_msg(np.zeros(3), np.array([[1.0, 2, 0], [0, 1, 0], [0, 0, 1]]),
                                 STAMP)


def test_mask_image_is_mono8() -> None:
    mask = np.zeros((3, 5), dtype=bool)
    mask[1, 2:4] = True
    msg = mask_image_msg(mask, STAMP, "cam")
    assert (msg.encoding, msg.step, msg.header.frame_id) == ("mono8", 5, "cam")
    np.testing.assert_array_equal(image_to_array(msg), mask.astype(np.uint8) * 255)


def _depth16(values: np.ndarray, step: int | None = None) -> Image:
    msg = Image(height=values.shape[0], width=values.shape[1], encoding="16UC1",
                is_bigendian=0)
    msg.step = step or 2 * values.shape[1]
    rows = np.zeros((values.shape[0], msg.step), dtype=np.uint8)
    rows[:, :2 * values.shape[1]] = values.astype("<u2").view(np.uint8)
    msg.data = array("B", rows.tobytes())
    return msg


def test_depth_to_metres_16uc1_with_padding_and_32fc1() -> None:
    mm = np.array([[0, 600], [1234, 65535]], dtype=np.uint16)
    depth = depth_to_metres(_depth16(mm, step=6))
    assert np.isnan(depth[0, 0])
    np.testing.assert_allclose(depth[[0, 1, 1], [1, 0, 1]], [0.6, 1.234, 65.535], rtol=1e-6)
    f = Image(height=1, width=3, encoding="32FC1", is_bigendian=0, step=12)
    f.data = array("B", np.array([0.5, 0.0, np.inf], dtype="<f4").tobytes())
    np.testing.assert_array_equal(np.isnan(depth_to_metres(f)), [[False, True, True]])


@pytest.mark.parametrize(("mutate", "match"), [
    (lambda m: setattr(m, "encoding", "rgb8"), "unsupported depth encoding"),
    (lambda m: setattr(m, "step", 2), "smaller than one row"),
    (lambda m: setattr(m, "height", 3), "bytes"),
])
def test_depth_to_metres_rejects_bad_images(mutate, match) -> None:
    msg = _depth16(np.ones((2, 2), dtype=np.uint16))
    mutate(msg)
    with pytest.raises(ValueError, match=match):
        depth_to_metres(msg)
