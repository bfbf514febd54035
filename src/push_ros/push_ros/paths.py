"""``nav_msgs/Path`` <-> points: push commands (``planner/push``) and executed pushes
(``pusher/executed``).

- ``planner/push``: frame ``world``, exactly three poses: approach, contact and end point of
  the pusher axis (positions only; the pusher is a vertical cylinder). Written by
  :func:`push_path` (poses oriented along the push, stamped with when a pusher at ``speed``
  reaches them), read by :func:`push_points_from_path`.
- ``pusher/executed``: frame ``world``, two poses, the pusher at the start and the end of the
  executed straight push, each with its stamp (header stamp = end). Written by
  :func:`path_from_points`, read by :func:`executed_push_from_path`.

A pose's own ``header.frame_id`` may be empty (it inherits the path's) or equal to the path's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import NonFiniteError
from push_ros.frames import WORLD_FRAME
from push_ros.poses import check_frame, pose_msg, quaternion_msg
from push_ros.stamps import seconds_from_stamp, stamp_from_seconds

__all__ = [
    "PUSH_PATH_LENGTH",
    "ExecutedPush",
    "executed_push_from_path",
    "path_from_points",
    "points_from_path",
    "push_path",
    "push_points_from_path",
]

#: Poses in a push command: approach point, contact point, end point.
PUSH_PATH_LENGTH = 3


def push_path(approach: ArrayLike, contact: ArrayLike, end: ArrayLike, stamp_seconds: float,
              speed: float) -> Path:
    """``planner/push``: the three pusher points in ``world``.

    Each pose is at table height (z = 0), oriented along the push (yaw of ``end - approach``,
    so RViz shows the direction). The path is stamped ``stamp_seconds``; the poses carry the
    times at which a pusher starting at the approach point at that instant and moving at
    ``speed`` (m/s) reaches them (the sim bridge uses its own ``push_speed``).
    """
    pts = [np.asarray(p, dtype=float).reshape(2) for p in (approach, contact, end)]
    d = pts[2] - pts[0]
    yaw = math.atan2(d[1], d[0])
    q = quaternion_msg(yaw)
    msg = Path()
    msg.header.frame_id = WORLD_FRAME
    msg.header.stamp = stamp_from_seconds(stamp_seconds)
    for p in pts:
        pose = PoseStamped()
        pose.header.frame_id = WORLD_FRAME
        pose.header.stamp = stamp_from_seconds(
            stamp_seconds + float(np.linalg.norm(p - pts[0])) / speed)
        pose.pose.position = Point(x=float(p[0]), y=float(p[1]), z=0.0)
        pose.pose.orientation = q
        msg.poses.append(pose)
    return msg


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


@dataclass(frozen=True)
class ExecutedPush:
    """An executed straight push (``pusher/executed``): pusher axis in ``world``, m and s."""

    start: NDArray[np.float64]
    end: NDArray[np.float64]
    t_start: float
    t_end: float


def executed_push_from_path(msg: Path, frame: str = WORLD_FRAME) -> ExecutedPush:
    """Parse ``pusher/executed``: exactly two poses (start, end), each with its stamp.

    Raises
    ------
    NonFiniteError
        A NaN or infinite position.
    ValueError
        Wrong frame (path or pose), not two poses, end stamped before start.
    """
    check_frame(msg.header.frame_id, frame)
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
