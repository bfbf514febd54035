"""Poses, transforms and points <-> arrays: the one codec of each geometry_msgs type we use.

Planar poses are ``(x, y, theta)``: metres on the table (z = 0 unless given) and the yaw about
the world z axis, radians. Quaternions are (x, y, z, w), the order of ``geometry_msgs`` and of
pybullet. The quaternion rule is :mod:`push_core.geometry`'s, for every consumer: finite, unit
norm within ``QUATERNION_TOLERANCE`` (1e-3); a planar pose (every reader here that returns a
yaw) also needs ``|q_x|, |q_y| <= 1e-3``. Transforms are not planar: any unit quaternion, and
a finite translation of at most ``MAX_TRANSLATION`` (100 m) in norm (the table scene spans a
few metres; the bound keeps every product with it finite).

A pose covariance message is 6 x 6 over (x, y, z, rot x, rot y, rot z), row-major; the planar
block is rows/columns (0, 1, 5).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import (
    PointStamped,
    Pose,
    PoseStamped,
    PoseWithCovarianceStamped,
    Quaternion,
    TransformStamped,
)
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import (
    NonFiniteError,
    matrix_from_quaternion,
    quaternion_from_matrix,
    quaternion_from_yaw,
)
from push_core.geometry import yaw_from_quaternion as _yaw
from push_ros.frames import OBJECT_FRAME, WORLD_FRAME
from push_ros.stamps import seconds_from_stamp

__all__ = [
    "MAX_TRANSLATION",
    "PLANAR_INDICES",
    "UNMEASURED_VARIANCE",
    "PoseWithCovariance",
    "center_of_mass_msg",
    "check_frame",
    "matrix_from_transform",
    "planar_matrix",
    "pose_msg",
    "pose_stamped_msg",
    "pose_with_covariance_from_msg",
    "pose_with_covariance_msg",
    "quaternion_msg",
    "transform_msg",
    "xytheta_from_pose",
    "yaw_from_quaternion",
]

#: Largest translation norm a TransformStamped reader accepts, metres.
MAX_TRANSLATION = 100.0
#: Rows/columns of x, y and yaw in a 6 x 6 pose covariance.
PLANAR_INDICES = (0, 1, 5)
#: Variance of a pose component that is not measured (z, roll, pitch of the perception):
#: "unknown", as robot_localization and REP 145 practice has it.
UNMEASURED_VARIANCE = 1e6


def check_frame(actual: str, expected: str, what: str = "header.frame_id") -> None:
    """Raise ``ValueError`` naming ``what`` unless ``actual == expected``."""
    if actual != expected:
        raise ValueError(f"{what} is {actual!r}, expected {expected!r}")


# ------------------------------------------------------------------------------ quaternions
def quaternion_msg(theta: float) -> Quaternion:
    """``geometry_msgs/Quaternion`` (x, y, z, w) = (0, 0, sin, cos)(theta / 2) of a yaw."""
    x, y, z, w = (float(v) for v in quaternion_from_yaw(theta))
    return Quaternion(x=x, y=y, z=z, w=w)


def _components(q: Quaternion | Sequence[float] | np.ndarray) -> tuple[float, ...]:
    if isinstance(q, Quaternion):
        return (q.x, q.y, q.z, q.w)
    return tuple(np.asarray(q, dtype=float).ravel())


def yaw_from_quaternion(q: Quaternion | Sequence[float] | np.ndarray) -> float:
    """Yaw (rad, in (-pi, pi]) of a planar quaternion (x, y, z, w), message or 4 numbers.

    Raises
    ------
    NonFiniteError
        A NaN or infinite component.
    ValueError
        Zero norm, not unit length, or not a rotation about z (the planarity rule).
    """
    return _yaw(_components(q))


# ------------------------------------------------------------------------------ poses
def pose_msg(x: float, y: float, theta: float, z: float = 0.0) -> Pose:
    """A ``geometry_msgs/Pose`` from a planar pose (metres, radians; z = height).

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
    msg.orientation = quaternion_msg(theta)
    return msg


def pose_stamped_msg(xytheta: ArrayLike, stamp: Time, frame_id: str = WORLD_FRAME
                     ) -> PoseStamped:
    """A ``geometry_msgs/PoseStamped`` from ``(x, y, theta)``.

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


def xytheta_from_pose(pose: Pose | PoseStamped) -> NDArray[np.float64]:
    """Planar pose ``(x, y, theta)`` (theta in (-pi, pi]) of a Pose or PoseStamped.

    The height is dropped (it must be finite).

    Raises
    ------
    NonFiniteError
        A NaN or infinite position or orientation (the message names which).
    ValueError
        A quaternion that breaks the planarity rule.
    """
    if isinstance(pose, PoseStamped):
        pose = pose.pose
    p = (pose.position.x, pose.position.y, pose.position.z)
    if not all(math.isfinite(v) for v in p):
        raise NonFiniteError(f"pose position must be finite, got {p}")
    try:
        theta = yaw_from_quaternion(pose.orientation)
    except NonFiniteError as exc:
        raise NonFiniteError(f"orientation: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"orientation: {exc}") from None
    return np.array([p[0], p[1], theta])


# ------------------------------------------------------------------------------ with covariance
def pose_with_covariance_msg(xytheta: ArrayLike, covariance: ArrayLike, stamp: Time,
                             frame_id: str = WORLD_FRAME,
                             unmeasured_variance: float = UNMEASURED_VARIANCE
                             ) -> PoseWithCovarianceStamped:
    """``(x, y, theta)`` and its (3, 3) covariance -> PoseWithCovarianceStamped.

    Parameters
    ----------
    xytheta : (3,) float
        x, y (m) and yaw (rad) in ``frame_id``; z = 0.
    covariance : (3, 3) float
        Covariance of (x, y, theta), m^2 / rad^2, placed into the planar block.
    stamp : Time
    frame_id : str
    unmeasured_variance : float
        Diagonal of z, roll and pitch: :data:`UNMEASURED_VARIANCE` (perception: not
        measured) or 0 (the estimator: fixed by the table).

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
    full[np.ix_(PLANAR_INDICES, PLANAR_INDICES)] = c
    full[2, 2] = full[3, 3] = full[4, 4] = float(unmeasured_variance)
    msg.pose.covariance = full.ravel().tolist()
    return msg


@dataclass(frozen=True)
class PoseWithCovariance:
    """A planar pose read from a PoseWithCovarianceStamped.

    Attributes
    ----------
    stamp : float
        s.
    pose : numpy.ndarray, shape (3,)
        ``(x, y, theta)`` in the message's frame, m and rad in (-pi, pi].
    covariance : numpy.ndarray, shape (3, 3) or None
        The planar block, symmetrised; None when the message carries none (all zeros) or an
        unusable one (not finite, not symmetric or not positive definite).
    """

    stamp: float
    pose: NDArray[np.float64]
    covariance: NDArray[np.float64] | None


def pose_with_covariance_from_msg(msg: PoseWithCovarianceStamped,
                                  frame_id: str = WORLD_FRAME) -> PoseWithCovariance:
    """Read ``(x, y, theta)``, its covariance and the stamp of a PoseWithCovarianceStamped.

    Raises
    ------
    NonFiniteError
        NaN or infinite position or orientation.
    ValueError
        Wrong ``header.frame_id``, or an orientation that breaks the planarity rule.
    """
    check_frame(msg.header.frame_id, frame_id)
    pose = xytheta_from_pose(msg.pose.pose)
    cov = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)[
        np.ix_(PLANAR_INDICES, PLANAR_INDICES)]
    usable = (np.all(np.isfinite(cov)) and np.allclose(cov, cov.T, rtol=1e-6, atol=1e-12)
              and np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() > 0.0)
    return PoseWithCovariance(stamp=seconds_from_stamp(msg.header.stamp), pose=pose,
                              covariance=0.5 * (cov + cov.T) if usable else None)


def center_of_mass_msg(com: ArrayLike, stamp: Time, frame_id: str = OBJECT_FRAME
                       ) -> PointStamped:
    """COM ``(c_x, c_y)`` (m) in the object frame -> PointStamped (z = 0)."""
    msg = PointStamped()
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    msg.point.x, msg.point.y = (float(v) for v in com)
    return msg


# ------------------------------------------------------------------------------ transforms
def planar_matrix(xytheta: ArrayLike) -> NDArray[np.float64]:
    """The (4, 4) homogeneous transform of a planar pose ``(x, y, theta)`` (z = 0)."""
    x, y, theta = (float(v) for v in xytheta)
    t = np.eye(4)
    c, s = math.cos(theta), math.sin(theta)
    t[:2, :2] = [[c, -s], [s, c]]
    t[:2, 3] = (x, y)
    return t


def transform_msg(matrix: ArrayLike, stamp: Time, parent_frame: str, child_frame: str
                  ) -> TransformStamped:
    """A ``geometry_msgs/TransformStamped`` from ``T_parent_child`` (4, 4).

    ``T_parent_child`` maps points in ``child_frame`` to ``parent_frame``
    (``p_parent = T @ p_child``): the pose of the child frame in the parent frame, metres.
    The rotation is written as the quaternion (x, y, z, w) with ``w >= 0``.

    Raises
    ------
    ValueError
        If the matrix is not a finite (4, 4) array with last row (0, 0, 0, 1) and a proper
        rotation block.
    """
    t = np.asarray(matrix, dtype=float)
    if t.shape != (4, 4) or not np.all(np.isfinite(t)):
        raise ValueError(f"transform must be a finite (4, 4) array, got shape {t.shape}")
    if not np.allclose(t[3], [0.0, 0.0, 0.0, 1.0]):
        raise ValueError(f"transform's last row must be (0, 0, 0, 1), got {t[3]}")
    qx, qy, qz, qw = (float(v) for v in quaternion_from_matrix(t[:3, :3]))
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = parent_frame
    msg.child_frame_id = child_frame
    tr = msg.transform.translation
    tr.x, tr.y, tr.z = (float(v) for v in t[:3, 3])
    msg.transform.rotation = Quaternion(x=qx, y=qy, z=qz, w=qw)
    return msg


def matrix_from_transform(msg: TransformStamped,
                          max_translation: float = MAX_TRANSLATION) -> NDArray[np.float64]:
    """The (4, 4) matrix ``T_parent_child`` of a ``TransformStamped`` (see :func:`transform_msg`).

    Raises
    ------
    NonFiniteError
        A NaN or infinite translation or rotation component.
    ValueError
        A translation longer than ``max_translation`` (m), or a quaternion that is not unit
        length.
    """
    tr = msg.transform.translation
    translation = np.array([tr.x, tr.y, tr.z])
    if not np.all(np.isfinite(translation)):
        raise NonFiniteError(f"transform translation must be finite, got {translation}")
    if float(np.linalg.norm(translation)) > max_translation:
        raise ValueError(f"transform translation is {np.linalg.norm(translation):.3g} m long; "
                         f"at most {max_translation:g} m is accepted")
    t = np.eye(4)
    t[:3, :3] = matrix_from_quaternion(_components(msg.transform.rotation))
    t[:3, 3] = translation
    return t
