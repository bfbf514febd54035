"""Message <-> array conversion of the estimator node: the one place where numpy meets messages.

Pure functions; nothing here needs ``rclpy.init`` or a node, so every function is unit-tested by
building messages directly. Conventions (``docs/ARCHITECTURE.md``): SI units, planar poses
``(x, y, theta)`` with ``theta`` the yaw about z, quaternions (x, y, z, w) as in
``geometry_msgs/Quaternion``, time as float seconds.

Every parser raises ``ValueError`` whose message names the offending field, and
:class:`NonFiniteError` (a ``ValueError``) when the only problem is a NaN or infinite value,
so the node can count the two kinds separately on ``/diagnostics``.

``perception/outline`` is read and written by the codec of its publisher,
:mod:`push_perception.conversions` (``outline_from_cloud``, ``outline_cloud_msg``), re-exported
here together with ``OBJECT_FRAME``, ``OUTLINE_FIELDS`` and ``NonFiniteError``, which the
outline reader raises for NaN or infinite coordinates.

``estimator/state`` layout (std_msgs/Float64MultiArray, also in the README topic table): two
blocks concatenated, not a 2-D array. ``layout.dim[0]``: label ``state``, size 7, stride 7 =
``x, y, theta, c_x, c_y, l, m`` (:data:`push_core.estimator.STATE_LABELS`; ``theta``
continuous, not wrapped); ``layout.dim[1]``: label ``covariance_row_major``, size 49, stride
49 = the 7 x 7 covariance, row-major; ``data_offset`` 0; ``data`` = the 7 state values then
the 49 covariance values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import (
    PointStamped,
    Pose,
    PoseWithCovarianceStamped,
    Quaternion,
    TransformStamped,
)
from nav_msgs.msg import Path
from numpy.typing import ArrayLike, NDArray
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from push_core.estimator import STATE_SIZE
from push_perception.conversions import (
    OBJECT_FRAME,
    OUTLINE_FIELDS,
    NonFiniteError,
    outline_cloud_msg,
    outline_from_cloud,
)

__all__ = [
    "COVARIANCE_LABEL",
    "OBJECT_FRAME",
    "OUTLINE_FIELDS",
    "STATE_LABEL",
    "WORLD_FRAME",
    "ExecutedPush",
    "NonFiniteError",
    "Observation",
    "center_of_mass_msg",
    "observation_from_msg",
    "outline_cloud_msg",
    "outline_from_cloud",
    "pose_with_covariance_msg",
    "push_from_path",
    "quaternion_from_yaw",
    "seconds_from_stamp",
    "stamp_from_seconds",
    "state_from_array_msg",
    "state_array_msg",
    "transform_msg",
    "yaw_from_quaternion",
]

WORLD_FRAME = "world"
STATE_LABEL = "state"
COVARIANCE_LABEL = "covariance_row_major"
#: Rows/columns of x, y and yaw in a 6 x 6 pose covariance (x, y, z, rot x, rot y, rot z).
_PLANAR = (0, 1, 5)
_NS = 1_000_000_000


# --------------------------------------------------------------------------------------------
# Time and rotations
# --------------------------------------------------------------------------------------------
def seconds_from_stamp(stamp: Time) -> float:
    """``builtin_interfaces/Time`` -> float seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_from_seconds(seconds: float) -> Time:
    """Float seconds (finite, >= 0, < 2^31) -> ``builtin_interfaces/Time``.

    Raises
    ------
    ValueError
        If the time does not fit a ``Time`` (negative, too large or not finite).
    """
    if not (math.isfinite(seconds) and 0.0 <= seconds < 2**31):
        raise ValueError(f"stamp must be finite and in [0, 2^31) s, got {seconds!r}")
    sec, nanosec = divmod(round(seconds * _NS), _NS)
    return Time(sec=int(sec), nanosec=int(nanosec))


def quaternion_from_yaw(theta: float) -> Quaternion:
    """The quaternion (x, y, z, w) = (0, 0, sin(theta / 2), cos(theta / 2)) of a yaw, rad."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(0.5 * theta), w=math.cos(0.5 * theta))


def yaw_from_quaternion(q: Quaternion) -> float:
    """Yaw (rad, in (-pi, pi]) of a quaternion (x, y, z, w); the z angle of its ZYX angles.

    Raises
    ------
    NonFiniteError
        If a component is NaN or infinite.
    ValueError
        If the quaternion has (near) zero norm.
    """
    x, y, z, w = q.x, q.y, q.z, q.w
    if not all(math.isfinite(v) for v in (x, y, z, w)):
        raise NonFiniteError(f"orientation is not finite: ({x}, {y}, {z}, {w})")
    if x * x + y * y + z * z + w * w < 1e-12:
        raise ValueError("orientation quaternion has zero norm")
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _pose(x: float, y: float, theta: float) -> Pose:
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = float(x), float(y), 0.0
    pose.orientation = quaternion_from_yaw(theta)
    return pose


# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Observation:
    """An observed object pose (``perception/object_pose``).

    Attributes
    ----------
    stamp : float
        s.
    pose : numpy.ndarray, shape (3,)
        ``(x, y, theta)`` of the object frame in ``world``, m and rad in (-pi, pi].
    covariance : numpy.ndarray, shape (3, 3) or None
        x, y, yaw block of the message's covariance; None when the message carries none (all
        zeros) or an unusable one (not symmetric positive definite).
    """

    stamp: float
    pose: NDArray[np.float64]
    covariance: NDArray[np.float64] | None


def observation_from_msg(msg: PoseWithCovarianceStamped,
                         frame: str = WORLD_FRAME) -> Observation:
    """Parse ``perception/object_pose``.

    Raises
    ------
    NonFiniteError
        NaN or infinite position or orientation.
    ValueError
        Wrong ``header.frame_id``, zero quaternion.
    """
    if msg.header.frame_id != frame:
        raise ValueError(f"header.frame_id is {msg.header.frame_id!r}, expected {frame!r}")
    p = msg.pose.pose.position
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
        raise NonFiniteError(f"position is not finite: ({p.x}, {p.y}, {p.z})")
    theta = yaw_from_quaternion(msg.pose.pose.orientation)
    cov = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)[np.ix_(_PLANAR,
                                                                                _PLANAR)]
    usable = (np.all(np.isfinite(cov)) and np.allclose(cov, cov.T, rtol=1e-6, atol=1e-12)
              and np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() > 0.0)
    return Observation(stamp=seconds_from_stamp(msg.header.stamp),
                       pose=np.array([p.x, p.y, theta]),
                       covariance=0.5 * (cov + cov.T) if usable else None)


@dataclass(frozen=True)
class ExecutedPush:
    """An executed straight push (``pusher/executed``): pusher axis in ``world``, m and s."""

    start: NDArray[np.float64]
    end: NDArray[np.float64]
    t_start: float
    t_end: float


def push_from_path(msg: Path, frame: str = WORLD_FRAME) -> ExecutedPush:
    """Parse ``pusher/executed``: exactly two poses (start, end), each with its stamp.

    Raises
    ------
    NonFiniteError
        A NaN or infinite position.
    ValueError
        Wrong frame (path or pose), not two poses, end stamped before start.
    """
    if msg.header.frame_id != frame:
        raise ValueError(f"header.frame_id is {msg.header.frame_id!r}, expected {frame!r}")
    if len(msg.poses) != 2:
        raise ValueError(f"poses: expected 2 (push start and end), got {len(msg.poses)}")
    points, stamps = [], []
    for i, pose in enumerate(msg.poses):
        if pose.header.frame_id not in ("", frame):
            raise ValueError(f"poses[{i}].header.frame_id is {pose.header.frame_id!r}, "
                             f"expected {frame!r} or empty")
        p = pose.pose.position
        if not (math.isfinite(p.x) and math.isfinite(p.y)):
            raise NonFiniteError(f"poses[{i}].pose.position is not finite: ({p.x}, {p.y})")
        points.append((p.x, p.y))
        stamps.append(seconds_from_stamp(pose.header.stamp))
    if stamps[1] < stamps[0]:
        raise ValueError(f"poses[1] is stamped before poses[0] ({stamps[1]} < {stamps[0]} s)")
    return ExecutedPush(start=np.array(points[0]), end=np.array(points[1]),
                        t_start=stamps[0], t_end=stamps[1])


# --------------------------------------------------------------------------------------------
# Outputs
# --------------------------------------------------------------------------------------------
def pose_with_covariance_msg(pose: ArrayLike, covariance: ArrayLike, stamp: Time,
                             frame: str = WORLD_FRAME) -> PoseWithCovarianceStamped:
    """``(x, y, theta)`` and its (3, 3) covariance -> PoseWithCovarianceStamped.

    The 6 x 6 covariance (x, y, z, rot x, rot y, rot z) holds the x, y, yaw block; z, roll and
    pitch are fixed by the table (variance 0).
    """
    x, y, theta = (float(v) for v in pose)
    msg = PoseWithCovarianceStamped()
    msg.header.stamp, msg.header.frame_id = stamp, frame
    msg.pose.pose = _pose(x, y, theta)
    full = np.zeros((6, 6))
    full[np.ix_(_PLANAR, _PLANAR)] = np.asarray(covariance, dtype=np.float64)
    msg.pose.covariance = full.ravel().tolist()
    return msg


def center_of_mass_msg(com: ArrayLike, stamp: Time, frame: str = OBJECT_FRAME) -> PointStamped:
    """COM ``(c_x, c_y)`` in the object frame -> PointStamped (z = 0)."""
    msg = PointStamped()
    msg.header.stamp, msg.header.frame_id = stamp, frame
    msg.point.x, msg.point.y = (float(v) for v in com)
    return msg


def transform_msg(pose: ArrayLike, stamp: Time, parent: str = WORLD_FRAME,
                  child: str = OBJECT_FRAME) -> TransformStamped:
    """The object frame's planar pose ``(x, y, theta)`` as the transform parent -> child."""
    x, y, theta = (float(v) for v in pose)
    msg = TransformStamped()
    msg.header.stamp, msg.header.frame_id, msg.child_frame_id = stamp, parent, child
    msg.transform.translation.x, msg.transform.translation.y = x, y
    msg.transform.rotation = quaternion_from_yaw(theta)
    return msg


def state_array_msg(state: ArrayLike, covariance: ArrayLike) -> Float64MultiArray:
    """State (7,) and covariance (7, 7) -> ``estimator/state`` (layout in the module docstring).

    Raises
    ------
    ValueError
        Wrong shapes.
    """
    x = np.asarray(state, dtype=np.float64)
    p = np.asarray(covariance, dtype=np.float64)
    if x.shape != (STATE_SIZE,) or p.shape != (STATE_SIZE, STATE_SIZE):
        raise ValueError(f"state must be ({STATE_SIZE},) and covariance ({STATE_SIZE}, "
                         f"{STATE_SIZE}), got {x.shape} and {p.shape}")
    msg = Float64MultiArray()
    msg.layout.dim = [
        MultiArrayDimension(label=STATE_LABEL, size=STATE_SIZE, stride=STATE_SIZE),
        MultiArrayDimension(label=COVARIANCE_LABEL, size=STATE_SIZE**2, stride=STATE_SIZE**2),
    ]
    msg.layout.data_offset = 0
    msg.data = np.concatenate([x, p.ravel()]).tolist()
    return msg


def state_from_array_msg(msg: Float64MultiArray) -> tuple[NDArray[np.float64],
                                                          NDArray[np.float64]]:
    """``estimator/state`` -> state (7,) and covariance (7, 7); checks the layout.

    Raises
    ------
    ValueError
        Labels, sizes or data length differ from the documented layout.
    """
    dims = [(d.label, d.size) for d in msg.layout.dim]
    expected = [(STATE_LABEL, STATE_SIZE), (COVARIANCE_LABEL, STATE_SIZE**2)]
    if dims != expected or msg.layout.data_offset != 0:
        raise ValueError(f"layout.dim must be {expected} with data_offset 0, got {dims} and "
                         f"{msg.layout.data_offset}")
    data = np.asarray(msg.data, dtype=np.float64)
    if data.shape != (STATE_SIZE + STATE_SIZE**2,):
        raise ValueError(f"data must hold {STATE_SIZE + STATE_SIZE**2} values, got {data.size}")
    return data[:STATE_SIZE].copy(), data[STATE_SIZE:].reshape(STATE_SIZE, STATE_SIZE)
