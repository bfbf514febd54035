"""Message <-> array conversion for the sim bridge: the one place where numpy meets ROS messages.

Pure functions over numpy arrays and message objects; nothing here needs ``rclpy.init`` or a
node, so every function is unit-tested by building messages directly.

Conventions (``docs/ARCHITECTURE.md``):

- SI units (REP 103): metres, radians, seconds; right-handed, z up.
- Quaternions are (x, y, z, w), the order of both ``geometry_msgs/Quaternion`` and pybullet.
- Planar poses are ``(x, y, theta)``: position on the table (z = 0 unless given) and the yaw
  ``theta`` about the world z axis, radians.
- Time is float seconds (simulated time in the bridge); messages carry
  ``builtin_interfaces/Time``.
- A push command (``planner/push``) is a ``nav_msgs/Path`` in frame ``world`` with exactly
  three poses: approach point, contact point, end point. Only the positions are used; the
  pusher is a vertical cylinder, so orientations are ignored.

Every parser raises ``ValueError`` with a message naming the offending field, so the node can
log it and report it on ``/diagnostics``.
"""

from __future__ import annotations

import math
import sys
from array import array
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Pose, PoseStamped, Quaternion, TransformStamped
from nav_msgs.msg import Path
from sensor_msgs.msg import CameraInfo, Image

__all__ = [
    "CAMERA_FRAME",
    "PUSH_PATH_LENGTH",
    "WORLD_FRAME",
    "camera_info_msg",
    "camera_matrix_from_info",
    "depth_image_msg",
    "image_to_array",
    "matrix_from_quaternion",
    "matrix_from_transform",
    "path_from_points",
    "points_from_path",
    "pose_msg",
    "pose_stamped_msg",
    "push_points_from_path",
    "quaternion_from_matrix",
    "quaternion_from_yaw",
    "rgb_image_msg",
    "seconds_from_stamp",
    "stamp_from_seconds",
    "transform_msg",
    "xytheta_from_pose",
    "yaw_from_quaternion",
]

#: The table frame (see ARCHITECTURE.md, Frames).
WORLD_FRAME = "world"
#: REP 103 optical frame of the colour camera; depth is aligned to it.
CAMERA_FRAME = "camera_color_optical_frame"
#: Poses in a push command: approach point, contact point, end point.
PUSH_PATH_LENGTH = 3

_NANOSECONDS = 1_000_000_000
#: Largest time a builtin_interfaces/Time can hold (sec is int32).
_MAX_SECONDS = 2**31 - 1
#: Bytes per pixel and numpy dtype of the encodings the pipeline uses.
_ENCODINGS: dict[str, tuple[np.dtype, int]] = {
    "rgb8": (np.dtype(np.uint8), 3),
    "bgr8": (np.dtype(np.uint8), 3),
    "mono8": (np.dtype(np.uint8), 1),
    "32FC1": (np.dtype(np.float32), 1),
}


# --------------------------------------------------------------------------------------------
# Time
# --------------------------------------------------------------------------------------------
def stamp_from_seconds(seconds: float) -> Time:
    """Convert float seconds to a ``builtin_interfaces/Time``.

    Parameters
    ----------
    seconds : float
        Time in seconds, finite and in ``[0, 2**31)``.

    Returns
    -------
    Time
        ``sec`` and ``nanosec`` (rounded to the nearest nanosecond, ``nanosec < 1e9``).

    Raises
    ------
    ValueError
        If ``seconds`` is negative, not finite or does not fit into an int32 ``sec``.
    """
    seconds = float(seconds)
    if not math.isfinite(seconds) or seconds < 0.0 or seconds >= _MAX_SECONDS:
        raise ValueError(f"time must be finite and in [0, {_MAX_SECONDS}) s, got {seconds!r}")
    total_ns = round(seconds * _NANOSECONDS)
    sec, nanosec = divmod(total_ns, _NANOSECONDS)
    return Time(sec=int(sec), nanosec=int(nanosec))


def seconds_from_stamp(stamp: Time) -> float:
    """Convert a ``builtin_interfaces/Time`` to float seconds.

    Parameters
    ----------
    stamp : Time

    Returns
    -------
    float
        Seconds.
    """
    return stamp.sec + stamp.nanosec / _NANOSECONDS


# --------------------------------------------------------------------------------------------
# Images
# --------------------------------------------------------------------------------------------
def rgb_image_msg(rgb: np.ndarray, stamp: Time, frame_id: str = CAMERA_FRAME) -> Image:
    """Build an ``rgb8`` ``sensor_msgs/Image`` from an RGB array.

    Parameters
    ----------
    rgb : (H, W, 3) uint8 ndarray
        Colour image, channels in R, G, B order.
    stamp : Time
        Capture time.
    frame_id : str
        Frame of the image, by default the colour optical frame.

    Returns
    -------
    Image
        ``encoding="rgb8"``, ``step = 3 * W``, row-major data.

    Raises
    ------
    ValueError
        If the array is not (H, W, 3) uint8 with H, W > 0.
    """
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8 or rgb.size == 0:
        raise ValueError(
            f"rgb image must be a non-empty (H, W, 3) uint8 array, got shape {rgb.shape} "
            f"dtype {rgb.dtype}"
        )
    return _image_msg(rgb, "rgb8", stamp, frame_id)


def depth_image_msg(depth: np.ndarray, stamp: Time, frame_id: str = CAMERA_FRAME) -> Image:
    """Build a ``32FC1`` ``sensor_msgs/Image`` from a depth array.

    Parameters
    ----------
    depth : (H, W) float ndarray
        Depth along the optical axis (z of the optical frame), metres; NaN where there is no
        return.
    stamp : Time
        Capture time.
    frame_id : str
        Frame of the image, by default the colour optical frame (depth is aligned to colour).

    Returns
    -------
    Image
        ``encoding="32FC1"``, little-endian float32, ``step = 4 * W``.

    Raises
    ------
    ValueError
        If the array is not 2-D and non-empty.
    """
    depth = np.asarray(depth)
    if depth.ndim != 2 or depth.size == 0 or not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(
            f"depth image must be a non-empty (H, W) float array, got shape {depth.shape} "
            f"dtype {depth.dtype}"
        )
    return _image_msg(depth.astype("<f4", copy=False), "32FC1", stamp, frame_id)


def _image_msg(pixels: np.ndarray, encoding: str, stamp: Time, frame_id: str) -> Image:
    """Fill an Image with tightly packed rows of ``pixels`` (already in the wire dtype)."""
    height, width = pixels.shape[:2]
    pixels = np.ascontiguousarray(pixels)
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height = int(height)
    msg.width = int(width)
    msg.encoding = encoding
    order = pixels.dtype.byteorder
    msg.is_bigendian = int(order == ">" or (order == "=" and sys.byteorder == "big"))
    msg.step = int(pixels.strides[0])
    # array('B', bytes) is the setter's fast path (no per-element type checks).
    msg.data = array("B", pixels.tobytes())
    return msg


def image_to_array(msg: Image) -> np.ndarray:
    """Decode a ``sensor_msgs/Image`` into a numpy array, validating its layout first.

    Parameters
    ----------
    msg : Image
        Encoding ``rgb8``, ``bgr8``, ``mono8`` or ``32FC1``; rows may be padded
        (``step >= width * bytes_per_pixel``).

    Returns
    -------
    ndarray
        (H, W, 3) uint8 for ``rgb8``/``bgr8`` (channel order as encoded), (H, W) uint8 for
        ``mono8``, (H, W) float32 (native byte order) for ``32FC1``. A copy, independent of
        the message.

    Raises
    ------
    ValueError
        For unsupported encodings, ``step`` smaller than a row, or
        ``len(data) != height * step``.
    """
    if msg.encoding not in _ENCODINGS:
        raise ValueError(
            f"unsupported image encoding {msg.encoding!r}; expected one of {sorted(_ENCODINGS)}"
        )
    dtype, channels = _ENCODINGS[msg.encoding]
    row_bytes = msg.width * channels * dtype.itemsize
    if msg.step < row_bytes:
        raise ValueError(
            f"image step {msg.step} is smaller than one row ({msg.width} px * {channels} ch * "
            f"{dtype.itemsize} B = {row_bytes} B)"
        )
    if len(msg.data) != msg.height * msg.step:
        raise ValueError(
            f"image data has {len(msg.data)} bytes, expected height * step = "
            f"{msg.height} * {msg.step} = {msg.height * msg.step}"
        )
    wire = dtype.newbyteorder(">" if msg.is_bigendian else "<")
    rows = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)[:, :row_bytes]
    pixels = np.ascontiguousarray(rows).view(wire).astype(dtype.newbyteorder("="), copy=True)
    shape = (msg.height, msg.width, channels) if channels > 1 else (msg.height, msg.width)
    return pixels.reshape(shape)


# --------------------------------------------------------------------------------------------
# Camera intrinsics
# --------------------------------------------------------------------------------------------
def camera_info_msg(
    camera_matrix: np.ndarray, width: int, height: int, stamp: Time, frame_id: str = CAMERA_FRAME
) -> CameraInfo:
    """Build a ``sensor_msgs/CameraInfo`` for an ideal pinhole camera.

    Parameters
    ----------
    camera_matrix : (3, 3) ndarray
        Intrinsics ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``, pixels.
    width, height : int
        Image size, pixels.
    stamp : Time
        Stamp of the image this info belongs to.
    frame_id : str
        Optical frame, by default the colour optical frame.

    Returns
    -------
    CameraInfo
        ``plumb_bob`` with zero distortion ``d = [0] * 5``, ``k = K``, ``r = I``,
        ``p = [K | 0]`` (monocular), no binning or ROI.

    Raises
    ------
    ValueError
        If K is not a finite (3, 3) matrix with positive focal lengths and last row
        (0, 0, 1), or the size is not positive.
    """
    k = _check_camera_matrix(camera_matrix)
    if int(width) <= 0 or int(height) <= 0:
        raise ValueError(f"image size must be positive, got {width} x {height}")
    msg = CameraInfo()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.width = int(width)
    msg.height = int(height)
    msg.distortion_model = "plumb_bob"
    msg.d = [0.0] * 5
    msg.k = k.ravel().tolist()
    msg.r = np.eye(3).ravel().tolist()
    msg.p = np.hstack([k, np.zeros((3, 1))]).ravel().tolist()
    return msg


def camera_matrix_from_info(msg: CameraInfo) -> np.ndarray:
    """Return the (3, 3) intrinsics ``K`` of a ``CameraInfo``, validated.

    Parameters
    ----------
    msg : CameraInfo

    Returns
    -------
    (3, 3) float ndarray
        ``K``, pixels.

    Raises
    ------
    ValueError
        If K is not a valid pinhole matrix (see :func:`camera_info_msg`).
    """
    return _check_camera_matrix(np.asarray(msg.k, dtype=float).reshape(3, 3))


def _check_camera_matrix(camera_matrix: np.ndarray) -> np.ndarray:
    k = np.asarray(camera_matrix, dtype=float)
    if k.shape != (3, 3) or not np.all(np.isfinite(k)):
        raise ValueError(f"camera matrix must be a finite (3, 3) array, got shape {k.shape}")
    if k[0, 0] <= 0 or k[1, 1] <= 0 or not np.allclose(k[2], [0.0, 0.0, 1.0]):
        raise ValueError(f"camera matrix must have fx, fy > 0 and last row (0, 0, 1), got {k}")
    return k


# --------------------------------------------------------------------------------------------
# Rotations and poses
# --------------------------------------------------------------------------------------------
def quaternion_from_yaw(theta: float) -> np.ndarray:
    """Quaternion (x, y, z, w) of a rotation by ``theta`` radians about z."""
    half = 0.5 * float(theta)
    return np.array([0.0, 0.0, math.sin(half), math.cos(half)])


def yaw_from_quaternion(q: Quaternion | Sequence[float] | np.ndarray) -> float:
    """Yaw (rotation about z, radians in (-pi, pi]) of a quaternion (x, y, z, w).

    For a rotation that is not purely about z this is the z angle of the ZYX (yaw-pitch-roll)
    decomposition.

    Raises
    ------
    ValueError
        If the quaternion is not finite or has (near) zero norm.
    """
    x, y, z, w = _check_quaternion(q)
    return float(math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def _check_quaternion(q: Quaternion | Sequence[float] | np.ndarray) -> np.ndarray:
    if isinstance(q, Quaternion):
        q = (q.x, q.y, q.z, q.w)
    v = np.asarray(q, dtype=float)
    if v.shape != (4,) or not np.all(np.isfinite(v)):
        raise ValueError(f"quaternion must be 4 finite numbers (x, y, z, w), got {v}")
    norm = float(np.linalg.norm(v))
    if norm < 1e-9:
        raise ValueError("quaternion has zero norm")
    return v / norm


def matrix_from_quaternion(q: Quaternion | Sequence[float] | np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion (x, y, z, w); normalises the quaternion.

    Raises
    ------
    ValueError
        If the quaternion is not finite or has (near) zero norm.
    """
    x, y, z, w = _check_quaternion(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion_from_matrix(rotation: np.ndarray) -> np.ndarray:
    """Quaternion (x, y, z, w) with ``w >= 0`` of a rotation matrix.

    Parameters
    ----------
    rotation : (3, 3) ndarray
        Proper rotation (orthonormal, determinant +1, to 1e-6).

    Raises
    ------
    ValueError
        If the matrix is not a finite proper rotation.
    """
    r = np.asarray(rotation, dtype=float)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"rotation must be a finite (3, 3) array, got shape {r.shape}")
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) <= 0:
        raise ValueError("rotation must be orthonormal with determinant +1")
    # Shepperd's method: pivot on the largest of w, x, y, z for numerical stability.
    trace = np.trace(r)
    candidates = np.array([trace, r[0, 0], r[1, 1], r[2, 2]])
    i = int(np.argmax(candidates))
    if i == 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4]
    elif i == 1:
        s = 2.0 * math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s]
    elif i == 2:
        s = 2.0 * math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4, (r[1, 0] - r[0, 1]) / s]
    quat = np.asarray(q)
    quat /= np.linalg.norm(quat)
    return -quat if quat[3] < 0 else quat


def pose_msg(x: float, y: float, theta: float, z: float = 0.0) -> Pose:
    """A ``geometry_msgs/Pose`` from a planar pose.

    Parameters
    ----------
    x, y : float
        Position, metres.
    theta : float
        Yaw about z, radians; stored as the quaternion (x, y, z, w) = (0, 0, sin, cos)(theta/2).
    z : float
        Height, metres (0 = on the table).

    Raises
    ------
    ValueError
        If any value is not finite.
    """
    values = np.array([x, y, theta, z], dtype=float)
    if not np.all(np.isfinite(values)):
        raise ValueError(f"pose must be finite, got x={x}, y={y}, theta={theta}, z={z}")
    msg = Pose()
    msg.position.x, msg.position.y, msg.position.z = float(x), float(y), float(z)
    qx, qy, qz, qw = quaternion_from_yaw(theta)
    msg.orientation.x, msg.orientation.y = float(qx), float(qy)
    msg.orientation.z, msg.orientation.w = float(qz), float(qw)
    return msg


def pose_stamped_msg(
    xytheta: Sequence[float] | np.ndarray, stamp: Time, frame_id: str = WORLD_FRAME
) -> PoseStamped:
    """A ``geometry_msgs/PoseStamped`` from a planar pose ``(x, y, theta)`` (metres, radians).

    Raises
    ------
    ValueError
        If ``xytheta`` is not three finite numbers.
    """
    v = np.asarray(xytheta, dtype=float)
    if v.shape != (3,):
        raise ValueError(f"planar pose must have shape (3,) = (x, y, theta), got {v.shape}")
    msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.pose = pose_msg(v[0], v[1], v[2])
    return msg


def xytheta_from_pose(pose: Pose | PoseStamped) -> np.ndarray:
    """Planar pose ``(x, y, theta)`` (metres, radians in (-pi, pi]) of a Pose or PoseStamped.

    The height and any roll/pitch are dropped.

    Raises
    ------
    ValueError
        If the position or orientation is not finite or the quaternion has zero norm.
    """
    if isinstance(pose, PoseStamped):
        pose = pose.pose
    p = np.array([pose.position.x, pose.position.y, pose.position.z])
    if not np.all(np.isfinite(p)):
        raise ValueError(f"pose position must be finite, got {p}")
    return np.array([p[0], p[1], yaw_from_quaternion(pose.orientation)])


# --------------------------------------------------------------------------------------------
# Transforms
# --------------------------------------------------------------------------------------------
def transform_msg(
    matrix: np.ndarray, stamp: Time, parent_frame: str, child_frame: str
) -> TransformStamped:
    """A ``geometry_msgs/TransformStamped`` from a homogeneous transform.

    Parameters
    ----------
    matrix : (4, 4) ndarray
        ``T_parent_child``: maps points in ``child_frame`` to ``parent_frame``
        (``p_parent = T @ p_child``), i.e. the pose of the child frame in the parent frame.
        Translation in metres.
    stamp : Time
    parent_frame : str
        ``header.frame_id``.
    child_frame : str
        ``child_frame_id``.

    Returns
    -------
    TransformStamped
        Rotation as the quaternion (x, y, z, w) with ``w >= 0``.

    Raises
    ------
    ValueError
        If the matrix is not (4, 4), not finite, its last row is not (0, 0, 0, 1) or its
        rotation block is not a proper rotation.
    """
    t = np.asarray(matrix, dtype=float)
    if t.shape != (4, 4) or not np.all(np.isfinite(t)):
        raise ValueError(f"transform must be a finite (4, 4) array, got shape {t.shape}")
    if not np.allclose(t[3], [0.0, 0.0, 0.0, 1.0]):
        raise ValueError(f"transform's last row must be (0, 0, 0, 1), got {t[3]}")
    qx, qy, qz, qw = quaternion_from_matrix(t[:3, :3])
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = parent_frame
    msg.child_frame_id = child_frame
    tr = msg.transform.translation
    tr.x, tr.y, tr.z = (float(v) for v in t[:3, 3])
    rot = msg.transform.rotation
    rot.x, rot.y, rot.z, rot.w = float(qx), float(qy), float(qz), float(qw)
    return msg


def matrix_from_transform(msg: TransformStamped) -> np.ndarray:
    """The (4, 4) matrix ``T_parent_child`` of a ``TransformStamped`` (see :func:`transform_msg`).

    Raises
    ------
    ValueError
        If the translation is not finite or the quaternion is invalid.
    """
    tr = msg.transform.translation
    translation = np.array([tr.x, tr.y, tr.z])
    if not np.all(np.isfinite(translation)):
        raise ValueError(f"transform translation must be finite, got {translation}")
    t = np.eye(4)
    t[:3, :3] = matrix_from_quaternion(msg.transform.rotation)
    t[:3, 3] = translation
    return t


# --------------------------------------------------------------------------------------------
# Paths
# --------------------------------------------------------------------------------------------
def path_from_points(
    points: np.ndarray,
    stamps: Sequence[Time],
    frame_id: str = WORLD_FRAME,
    stamp: Time | None = None,
) -> Path:
    """A ``nav_msgs/Path`` through planar points, each pose with its own stamp.

    Parameters
    ----------
    points : (N, 2) ndarray
        Positions on the table in ``frame_id``, metres (z = 0, identity orientation).
    stamps : sequence of N Time
        Stamp of each pose.
    frame_id : str
        Frame of the path and of every pose, by default ``world``.
    stamp : Time, optional
        Stamp of the path header; by default the last pose's stamp.

    Raises
    ------
    ValueError
        If the points are not a finite (N, 2) array with N >= 1 or the stamps do not match.
    """
    pts = _check_points(points)
    if len(stamps) != len(pts):
        raise ValueError(f"got {len(pts)} points but {len(stamps)} stamps")
    msg = Path()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp if stamp is not None else stamps[-1]
    for (x, y), t in zip(pts, stamps, strict=True):
        pose = PoseStamped()
        pose.header.frame_id = frame_id
        pose.header.stamp = t
        pose.pose = pose_msg(x, y, 0.0)
        msg.poses.append(pose)
    return msg


def points_from_path(
    msg: Path, frame_id: str = WORLD_FRAME, expected_length: int | None = None
) -> np.ndarray:
    """Planar positions of a ``nav_msgs/Path``, validated.

    Parameters
    ----------
    msg : Path
    frame_id : str
        Required frame of the path header; a pose's own header may be empty (inherits the
        path's frame) or equal to it.
    expected_length : int, optional
        Required number of poses; any number >= 1 when None.

    Returns
    -------
    (N, 2) float ndarray
        x, y of each pose in ``frame_id``, metres; orientations and heights are ignored.

    Raises
    ------
    ValueError
        On a wrong frame, a wrong number of poses, or a non-finite coordinate; the message
        names the pose.
    """
    if msg.header.frame_id != frame_id:
        raise ValueError(f"path frame_id is {msg.header.frame_id!r}, expected {frame_id!r}")
    n = len(msg.poses)
    if expected_length is not None and n != expected_length:
        raise ValueError(f"path has {n} poses, expected exactly {expected_length}")
    if n == 0:
        raise ValueError("path has no poses")
    points = np.empty((n, 2))
    for i, pose in enumerate(msg.poses):
        if pose.header.frame_id not in ("", frame_id):
            raise ValueError(
                f"pose {i} has frame_id {pose.header.frame_id!r}, expected {frame_id!r} or empty"
            )
        p = pose.pose.position
        xyz = (p.x, p.y, p.z)
        if not all(math.isfinite(v) for v in xyz):
            raise ValueError(f"pose {i} position is not finite: {xyz}")
        points[i] = xyz[:2]
    return points


def push_points_from_path(msg: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Approach, contact and end point of a push command (``planner/push``).

    Parameters
    ----------
    msg : Path
        Frame ``world``, exactly three poses: approach point, contact point, end point.

    Returns
    -------
    approach, contact, end : (2,) float ndarray
        World positions on the table, metres.

    Raises
    ------
    ValueError
        See :func:`points_from_path`.
    """
    points = points_from_path(msg, WORLD_FRAME, PUSH_PATH_LENGTH)
    return points[0].copy(), points[1].copy(), points[2].copy()


def _check_points(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0:
        raise ValueError(f"points must be a non-empty (N, 2) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points must be finite")
    return pts

