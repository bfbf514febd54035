"""Message <-> array conversion for push_perception: the one place where numpy meets its messages.

Reuses :mod:`sim_bridge.conversions` (images, camera info, transforms, time, quaternions) and
adds what perception publishes or accepts beyond it:

- the outline as ``sensor_msgs/PointCloud2`` with float32 fields ``x, y, z, normal_x,
  normal_y, normal_z`` (frame ``object``, points counter-clockwise, outward unit normals,
  z = normal_z = 0) and its inverse;
- the measured pose as ``geometry_msgs/PoseWithCovarianceStamped`` in ``world``;
- the mask as a ``mono8`` image (255 = object);
- depth images in ``32FC1`` (metres, the sim bridge) or ``16UC1`` (millimetres, 0 = no
  return: the RealSense driver's ``aligned_depth_to_color``), both as float32 metres with NaN.

Pure functions; nothing here needs ``rclpy.init``. Every parser raises ``ValueError`` naming
the offending field. Quaternions are (x, y, z, w).
"""

from __future__ import annotations

from array import array

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseWithCovarianceStamped
from sensor_msgs.msg import Image, PointCloud2, PointField

from sim_bridge.conversions import (
    CAMERA_FRAME,
    WORLD_FRAME,
    image_to_array,
    pose_msg,
)

__all__ = [
    "OBJECT_FRAME",
    "OUTLINE_FIELDS",
    "UNMEASURED_VARIANCE",
    "depth_to_metres",
    "mask_image_msg",
    "outline_cloud_msg",
    "outline_from_cloud",
    "pose_with_covariance_msg",
]

#: The object frame (ARCHITECTURE.md, Frames): origin at the area centroid, axes of the first
#: frame of the episode.
OBJECT_FRAME = "object"
#: Field names of the outline cloud, all float32, in this order.
OUTLINE_FIELDS = ("x", "y", "z", "normal_x", "normal_y", "normal_z")
#: Variance reported for the pose components perception does not measure (z, roll, pitch):
#: "unknown", as robot_localization and REP 145 practice has it.
UNMEASURED_VARIANCE = 1e6


def outline_cloud_msg(points: np.ndarray, normals: np.ndarray, stamp: Time,
                      frame_id: str = OBJECT_FRAME) -> PointCloud2:
    """The outline as an unorganised ``PointCloud2`` (height 1, width K, dense).

    Parameters
    ----------
    points, normals : (K, 2) float
        Outline points (metres) and outward unit normals in ``frame_id``, counter-clockwise.
    stamp : Time
    frame_id : str

    Raises
    ------
    ValueError
        If the arrays are not finite (K, 2) arrays of the same K >= 3.
    """
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape != n.shape or len(p) < 3:
        raise ValueError(f"outline points and normals must be (K, 2) with K >= 3, got "
                         f"{p.shape} and {n.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
        raise ValueError("outline points and normals must be finite")
    data = np.zeros((len(p), 6), dtype="<f4")
    data[:, 0:2] = p
    data[:, 3:5] = n
    msg = PointCloud2()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = 1, len(p)
    msg.fields = [PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, name in enumerate(OUTLINE_FIELDS)]
    msg.is_bigendian = False
    msg.point_step = 24
    msg.row_step = 24 * len(p)
    msg.is_dense = True
    msg.data = array("B", data.tobytes())
    return msg


def outline_from_cloud(msg: PointCloud2) -> tuple[np.ndarray, np.ndarray]:
    """Outline points and normals (K, 2) float64 of a cloud written by :func:`outline_cloud_msg`.

    Any field layout with float32 ``x, y, normal_x, normal_y`` is accepted (offsets are read
    from ``fields``).

    Raises
    ------
    ValueError
        Missing or non-float32 fields, a ``data`` size that does not match
        ``row_step * height``, fewer than 3 points, non-finite values.
    """
    fields = {f.name: f for f in msg.fields}
    for name in ("x", "y", "normal_x", "normal_y"):
        if name not in fields:
            raise ValueError(f"outline cloud has no field {name!r} (fields: {sorted(fields)})")
        if fields[name].datatype != PointField.FLOAT32:
            raise ValueError(f"outline cloud field {name!r} is not float32")
        if fields[name].offset + 4 > msg.point_step:
            raise ValueError(f"outline cloud field {name!r} lies outside point_step")
    count = msg.width * msg.height
    if msg.row_step < msg.width * msg.point_step or len(msg.data) != msg.row_step * msg.height:
        raise ValueError(f"outline cloud data has {len(msg.data)} bytes, expected row_step * "
                         f"height = {msg.row_step} * {msg.height} with row_step >= width * "
                         f"point_step")
    if count < 3:
        raise ValueError(f"outline cloud has {count} points, need >= 3")
    raw = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.row_step)
    rows = raw[:, :msg.width * msg.point_step].reshape(count, msg.point_step)
    order = ">f4" if msg.is_bigendian else "<f4"

    def column(name: str) -> np.ndarray:
        off = fields[name].offset
        return np.ascontiguousarray(rows[:, off:off + 4]).view(order)[:, 0].astype(np.float64)

    points = np.stack([column("x"), column("y")], axis=1)
    normals = np.stack([column("normal_x"), column("normal_y")], axis=1)
    if not (np.all(np.isfinite(points)) and np.all(np.isfinite(normals))):
        raise ValueError("outline cloud holds non-finite values")
    return points, normals


def pose_with_covariance_msg(xytheta: np.ndarray, covariance: np.ndarray, stamp: Time,
                             frame_id: str = WORLD_FRAME) -> PoseWithCovarianceStamped:
    """A planar pose with covariance as ``geometry_msgs/PoseWithCovarianceStamped``.

    Parameters
    ----------
    xytheta : (3,) float
        x, y (metres) and yaw theta (radians) in ``frame_id``; z = 0.
    covariance : (3, 3) float
        Covariance of (x, y, theta), m^2 / rad^2; placed into the message's 6 x 6 row-major
        matrix over (x, y, z, roll, pitch, yaw); z, roll and pitch get
        ``UNMEASURED_VARIANCE`` on the diagonal and no correlations.
    stamp : Time
    frame_id : str

    Raises
    ------
    ValueError
        Non-finite pose, or a covariance that is not a finite symmetric (3, 3) matrix with a
        non-negative diagonal.
    """
    v = np.asarray(xytheta, dtype=float)
    c = np.asarray(covariance, dtype=float)
    if v.shape != (3,):
        raise ValueError(f"pose must be (x, y, theta), got shape {v.shape}")
    if c.shape != (3, 3) or not np.all(np.isfinite(c)) or not np.allclose(c, c.T) \
            or np.any(np.diag(c) < 0):
        raise ValueError("covariance must be a finite symmetric (3, 3) matrix with a "
                         "non-negative diagonal")
    msg = PoseWithCovarianceStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.pose.pose = pose_msg(v[0], v[1], v[2])
    full = np.zeros((6, 6))
    idx = np.array([0, 1, 5])
    full[np.ix_(idx, idx)] = c
    full[2, 2] = full[3, 3] = full[4, 4] = UNMEASURED_VARIANCE
    msg.pose.covariance = full.ravel().tolist()
    return msg


def mask_image_msg(mask: np.ndarray, stamp: Time, frame_id: str = CAMERA_FRAME) -> Image:
    """A ``mono8`` image of a boolean mask (255 = object, 0 = not), ``step = W``.

    Raises
    ------
    ValueError
        If the mask is not a non-empty 2-D array.
    """
    m = np.asarray(mask)
    if m.ndim != 2 or m.size == 0:
        raise ValueError(f"mask must be a non-empty 2-D array, got shape {m.shape}")
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = (int(s) for s in m.shape)
    msg.encoding = "mono8"
    msg.is_bigendian = 0
    msg.step = msg.width
    msg.data = array("B", (m.astype(bool).astype(np.uint8) * 255).tobytes())
    return msg


def depth_to_metres(msg: Image) -> np.ndarray:
    """Depth image as float32 metres (H, W), NaN where there is no return.

    Parameters
    ----------
    msg : Image
        ``32FC1`` in metres (NaN, inf or <= 0 = no return), or ``16UC1`` / ``mono16`` in
        millimetres (0 = no return).

    Raises
    ------
    ValueError
        Other encodings, or a layout that does not match (``step``, ``len(data)``).
    """
    if msg.encoding in ("16UC1", "mono16"):
        row = msg.width * 2
        if msg.step < row:
            raise ValueError(f"image step {msg.step} is smaller than one row ({msg.width} px "
                             f"* 2 B = {row} B)")
        if len(msg.data) != msg.height * msg.step:
            raise ValueError(f"image data has {len(msg.data)} bytes, expected height * step = "
                             f"{msg.height} * {msg.step} = {msg.height * msg.step}")
        order = ">u2" if msg.is_bigendian else "<u2"
        rows = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)[:, :row]
        mm = np.ascontiguousarray(rows).view(order).astype(np.float32)
        depth = mm * np.float32(1e-3)
        depth[mm == 0] = np.nan
        return depth
    if msg.encoding != "32FC1":
        raise ValueError(f"unsupported depth encoding {msg.encoding!r}; expected 32FC1 "
                         "(metres) or 16UC1 (millimetres)")
    depth = image_to_array(msg)
    depth[~np.isfinite(depth) | (depth <= 0)] = np.nan
    return depth
