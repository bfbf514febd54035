"""push_ros codecs of the perception outputs: outline clouds, pose with covariance, mask and
depth images (32FC1, 16UC1)."""

from __future__ import annotations

from array import array
from collections.abc import Callable

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from sensor_msgs.msg import Image, PointCloud2, PointField

from push_ros import NonFiniteError
from push_ros.images import depth_to_metres, image_to_array, mask_image_msg
from push_ros.outline import OUTLINE_FIELDS, outline_cloud_msg, outline_from_cloud
from push_ros.poses import UNMEASURED_VARIANCE, pose_with_covariance_msg, xytheta_from_pose

STAMP = Time(sec=12, nanosec=345)


def square_outline() -> tuple[np.ndarray, np.ndarray]:
    pts = np.array([[0.01, 0.0], [0.0, 0.01], [-0.01, 0.0], [0.0, -0.01]])
    return pts, pts / 0.01


def test_outline_cloud_round_trip_and_layout() -> None:
    points, normals = square_outline()
    msg = outline_cloud_msg(points, normals, STAMP)
    assert msg.header.frame_id == "object" and msg.header.stamp == STAMP
    assert [f.name for f in msg.fields] == list(OUTLINE_FIELDS)
    assert [f.offset for f in msg.fields] == [0, 4, 8, 12, 16, 20]
    assert all(f.datatype == PointField.FLOAT32 and f.count == 1 for f in msg.fields)
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 4, 24, 96)
    assert msg.is_dense and not msg.is_bigendian
    expected = np.zeros((4, 6), dtype="<f4")
    expected[:, 0:2], expected[:, 3:5] = points, normals  # z = normal_z = 0
    assert bytes(msg.data) == expected.tobytes()
    p, n = outline_from_cloud(msg)
    assert p.dtype == n.dtype == np.float64
    np.testing.assert_allclose(p, points, atol=1e-9)
    np.testing.assert_allclose(n, normals, atol=1e-7)
    assert outline_cloud_msg(points, normals).header.stamp == Time()
    world = outline_cloud_msg(points, normals, STAMP, "world")
    np.testing.assert_allclose(outline_from_cloud(world, "world")[0], points, atol=1e-9)


@pytest.mark.parametrize(("points", "normals", "match"), [
    (np.zeros((4, 3)), np.zeros((4, 3)), r"\(K, 2\)"),
    (np.zeros((4, 2)), np.zeros((3, 2)), r"\(K, 2\)"),
    (np.full((4, 2), np.nan), np.zeros((4, 2)), "finite"),
    (np.zeros((4, 2)), np.full((4, 2), np.inf), "finite"),
])
def test_outline_cloud_rejects_bad_arrays(points, normals, match) -> None:
    with pytest.raises(ValueError, match=match):
        outline_cloud_msg(points, normals, STAMP)


def test_outline_reader_takes_big_endian_shuffled_padded_clouds() -> None:
    points, normals = square_outline()
    # Big-endian, 2 rows of 2 points: 36-byte points (fields shuffled, an extra field, 8 bytes
    # of padding), rows padded to 80 bytes.
    order = ["normal_y", "z", "normal_x", "intensity", "y", "normal_z", "x"]
    values = {"x": points[:, 0], "y": points[:, 1], "z": np.full(4, 5.0),
              "normal_x": normals[:, 0], "normal_y": normals[:, 1], "normal_z": np.zeros(4),
              "intensity": np.full(4, 9.0)}
    point = np.stack([values[name] for name in order] + [np.zeros(4)] * 2, axis=1).astype(">f4")
    rows = np.zeros((2, 80), dtype=np.uint8)
    rows[:, :72] = np.frombuffer(point.tobytes(), dtype=np.uint8).reshape(2, 72)
    msg = PointCloud2(height=2, width=2, is_bigendian=True, point_step=36, row_step=80,
                      is_dense=True)
    msg.header.frame_id = "object"
    msg.fields = [PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, name in enumerate(order)]
    msg.data = array("B", rows.tobytes())
    p, n = outline_from_cloud(msg)
    np.testing.assert_allclose(p, points, atol=1e-9)
    np.testing.assert_allclose(n, normals, atol=1e-7)
    msg.is_bigendian = False  # the same bytes read little-endian are garbage
    assert not np.allclose(outline_from_cloud(msg)[0], points)


def _field(name: str) -> Callable[[PointCloud2], PointField]:
    def get(msg: PointCloud2) -> PointField:
        return next(f for f in msg.fields if f.name == name)
    return get


def _nan_at(index: int, column: int) -> Callable[[PointCloud2], None]:
    def mutate(msg: PointCloud2) -> None:
        data = np.frombuffer(bytes(msg.data), dtype="<f4").reshape(-1, 6).copy()
        data[index, column] = np.nan if column != 4 else np.inf
        msg.data = array("B", data.tobytes())
    return mutate


@pytest.mark.parametrize(("mutate", "match"), [
    (lambda m: setattr(m.header, "frame_id", "world"), "frame_id is 'world', expected 'object'"),
    (lambda m: m.fields.pop(3), "missing 'normal_x'"),
    (lambda m: m.fields.pop(5), "missing 'normal_z'"),
    (lambda m: setattr(_field("y")(m), "datatype", PointField.FLOAT64), "'y' must be FLOAT32"),
    (lambda m: setattr(_field("x")(m), "count", 2), "'x' must be FLOAT32 with count 1"),
    (lambda m: setattr(_field("normal_z")(m), "offset", 22), "'normal_z' at offset 22"),
    (lambda m: (setattr(m, "width", 0), setattr(m, "row_step", 0), setattr(m, "data", b"")),
     "empty"),
    (lambda m: (setattr(m, "width", 2), setattr(m, "row_step", 48),
                setattr(m, "data", bytes(m.data)[:48])), "2 points, need >= 3"),
    (lambda m: setattr(m, "row_step", 10), "row_step 10 is smaller"),
    (lambda m: setattr(m, "data", bytes(m.data)[:-4]), "92 bytes, expected"),
    (lambda m: setattr(m, "height", 2), "96 bytes, expected"),
    (_nan_at(2, 0), "NaN or infinite.*index 2"),
    (_nan_at(1, 4), "NaN or infinite.*index 1"),
])
def test_outline_reader_rejects_malformed_clouds(mutate, match) -> None:
    msg = outline_cloud_msg(*square_outline(), STAMP)
    mutate(msg)
    with pytest.raises(ValueError, match=match) as info:
        outline_from_cloud(msg)
    assert isinstance(info.value, NonFiniteError) == ("NaN" in match)


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


def test_occlusion_report_round_trip_and_checks() -> None:
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    from push_ros.occlusion import occlusion_msg, read_occlusion

    msg = occlusion_msg("/segmentation_node", STAMP, "pose", 0.123456, 2048)
    assert msg.level == DiagnosticStatus.OK and msg.hardware_id == "robot_filter"
    got = read_occlusion(msg)
    assert (got.stamp, got.outcome, got.occluded_share, got.robot_pixels) == (
        "12.000000345", "pose", 0.1235, 2048)
    refused = read_occlusion(occlusion_msg("/n", STAMP, "no_joint_state", float("nan"), -1,
                                           "no /joint_states received yet"))
    assert np.isnan(refused.occluded_share) and refused.reason.startswith("no /joint_states")
    assert occlusion_msg("/n", STAMP, "occluded", 0.5, 10).level == DiagnosticStatus.WARN
    for key, value, match in [("stamp", "12.5", "stamp"), ("occluded_share", "1.5", "not in"),
                              ("robot_pixels", "x", "numbers")]:
        bad = occlusion_msg("/n", STAMP, "pose", 0.1, 5)
        bad.values = [kv if kv.key != key else KeyValue(key=key, value=value)
                      for kv in bad.values]
        with pytest.raises(ValueError, match=match):
            read_occlusion(bad)
