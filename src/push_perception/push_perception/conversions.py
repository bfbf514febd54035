"""Message <-> array conversion for push_perception: the one place where numpy meets its messages.

Reuses :mod:`sim_bridge.conversions` (images, camera info, transforms, time, quaternions) and
adds what perception publishes or accepts beyond it:

- the outline (``perception/outline``) as ``sensor_msgs/PointCloud2`` with float32 fields
  ``x, y, z, normal_x, normal_y, normal_z`` (frame ``object``, points counter-clockwise,
  outward unit normals, z = normal_z = 0) and its checked inverse. This writer and reader are
  the only codec of that topic: ``push_estimator.conversions`` and ``push_planner.conversions``
  re-export them, so the module must stay light (no torch, no cv2);
- the measured pose as ``geometry_msgs/PoseWithCovarianceStamped`` in ``world``;
- the mask as a ``mono8`` image (255 = object);
- depth images in ``32FC1`` (metres, the sim bridge) or ``16UC1`` (millimetres, 0 = no
  return: the RealSense driver's ``aligned_depth_to_color``), both as float32 metres with NaN.

Pure functions; nothing here needs ``rclpy.init``. Every parser raises ``ValueError`` naming
the offending field; the outline reader raises its subclass :class:`NonFiniteError` when the
problem is a NaN or infinite value. Quaternions are (x, y, z, w).
"""

from __future__ import annotations

from array import array

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseWithCovarianceStamped
from numpy.typing import ArrayLike, NDArray
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
    "NonFiniteError",
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


class NonFiniteError(ValueError):
    """A message field holds NaN or infinity (a ``ValueError``, so callers may lump it in)."""


def outline_cloud_msg(points: ArrayLike, normals: ArrayLike, stamp: Time | None = None,
                      frame_id: str = OBJECT_FRAME) -> PointCloud2:
    """The outline as ``perception/outline``: an unorganised ``PointCloud2``.

    The wire format (this writer defines it; :func:`outline_from_cloud` reads it back): height
    1, width K, little-endian, ``point_step`` 24, ``row_step`` 24 K, dense; the float32 fields
    :data:`OUTLINE_FIELDS` at offsets 0, 4, ..., 20, with z = normal_z = 0.

    Parameters
    ----------
    points, normals : array_like, shape (K, 2)
        Outline points (metres) and outward unit normals in ``frame_id``, counter-clockwise.
        Any K >= 0 is written (an outline of fewer than 3 points is refused by the reader, not
        here, so tests can publish one).
    stamp : builtin_interfaces/Time, optional
        ``header.stamp``; None leaves it zero.
    frame_id : str
        ``header.frame_id``.

    Returns
    -------
    sensor_msgs/PointCloud2

    Raises
    ------
    ValueError
        If points and normals are not (K, 2) arrays of the same shape, or hold NaN or infinity.
    """
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape != n.shape:
        raise ValueError(f"outline points and normals must both be (K, 2), got {p.shape} and "
                         f"{n.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
        raise ValueError("outline points and normals must be finite")
    data = np.zeros((len(p), len(OUTLINE_FIELDS)), dtype="<f4")
    data[:, 0:2] = p
    data[:, 3:5] = n
    msg = PointCloud2()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = 1, len(p)
    msg.fields = [PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, name in enumerate(OUTLINE_FIELDS)]
    msg.is_bigendian = False
    msg.point_step = 4 * len(OUTLINE_FIELDS)
    msg.row_step = msg.point_step * len(p)
    msg.is_dense = True
    msg.data = array("B", data.tobytes())
    return msg


def outline_from_cloud(msg: PointCloud2, frame_id: str = OBJECT_FRAME
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Outline points and outward normals of ``perception/outline``, checked.

    Accepts the format of :func:`outline_cloud_msg` and any other layout of the same fields:
    offsets are read from ``fields`` (other fields and padding are skipped), rows may be padded
    (``row_step > width * point_step``), and ``is_bigendian`` selects the byte order.

    Parameters
    ----------
    msg : sensor_msgs/PointCloud2
        Fields :data:`OUTLINE_FIELDS`, each FLOAT32 with count 1; points ordered
        counter-clockwise along the outline (not checked here).
    frame_id : str
        The required ``header.frame_id``.

    Returns
    -------
    points, normals : numpy.ndarray, shape (K, 2)
        x, y of each point and of its normal, float64; z and normal_z are ignored.

    Raises
    ------
    NonFiniteError
        A NaN or infinite x, y, normal_x or normal_y (the only problem of the cloud).
    ValueError
        Every other problem, named in the message: a wrong ``header.frame_id``; a missing
        field, one that is not FLOAT32 with count 1, or one whose offset does not fit
        ``point_step``; an empty cloud or one of fewer than 3 points; ``row_step`` smaller than
        ``width * point_step``; ``data`` not ``row_step * height`` bytes long.
    """
    if msg.header.frame_id != frame_id:
        raise ValueError(f"header.frame_id is {msg.header.frame_id!r}, expected {frame_id!r}")
    fields = {f.name: f for f in msg.fields}
    for name in OUTLINE_FIELDS:
        f = fields.get(name)
        if f is None:
            raise ValueError(f"fields: missing {name!r} (need {', '.join(OUTLINE_FIELDS)}; "
                             f"got {', '.join(sorted(fields)) or 'none'})")
        if f.datatype != PointField.FLOAT32 or f.count != 1:
            raise ValueError(f"fields: {name!r} must be FLOAT32 with count 1, got datatype "
                             f"{f.datatype} count {f.count}")
        if f.offset + 4 > msg.point_step:
            raise ValueError(f"fields: {name!r} at offset {f.offset} does not fit point_step "
                             f"{msg.point_step}")
    count = int(msg.width) * int(msg.height)
    if count == 0:
        raise ValueError("the outline is empty: the cloud has no points (width * height = 0)")
    if count < 3:
        raise ValueError(f"the outline has {count} points, need >= 3")
    if msg.row_step < msg.width * msg.point_step:
        raise ValueError(f"row_step {msg.row_step} is smaller than width * point_step = "
                         f"{msg.width} * {msg.point_step}")
    if len(msg.data) != msg.row_step * msg.height:
        raise ValueError(f"data buffer has {len(msg.data)} bytes, expected row_step * height = "
                         f"{msg.row_step} * {msg.height} = {msg.row_step * msg.height}")
    raw = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.row_step)
    rows = raw[:, :msg.width * msg.point_step].reshape(count, msg.point_step)
    order = ">f4" if msg.is_bigendian else "<f4"

    def column(name: str) -> NDArray[np.float64]:
        off = fields[name].offset
        return np.ascontiguousarray(rows[:, off:off + 4]).view(order)[:, 0].astype(np.float64)

    points = np.stack([column("x"), column("y")], axis=1)
    normals = np.stack([column("normal_x"), column("normal_y")], axis=1)
    bad = ~(np.all(np.isfinite(points), axis=1) & np.all(np.isfinite(normals), axis=1))
    if np.any(bad):
        raise NonFiniteError(f"the outline has NaN or infinite coordinates ({int(bad.sum())} "
                             f"of {count} points, the first at index {int(np.argmax(bad))})")
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
