"""Message <-> array conversions of the planner node (the only module here that knows messages).

Plain functions over ROS message objects and numpy arrays; no node, no ``rclpy.init``. Every
``*_from_*`` reader validates its message and raises ``ValueError`` with a message that says
what is wrong, so the node can refuse bad input with a clear log.

``perception/outline`` is read and written by the codec of its publisher,
:mod:`push_perception.conversions`: ``outline_from_cloud`` (the checked reader, frame
``object``) and ``outline_cloud`` (its writer ``outline_cloud_msg``) are re-exported here, with
``OBJECT_FRAME`` and ``OUTLINE_FIELDS``.

Frames and units (``docs/ARCHITECTURE.md``): SI; ``world`` is the table frame (z up), ``object``
the object frame (origin at the area centroid). Quaternions are (x, y, z, w), the order of the
ROS messages; a planar pose is a rotation about z by ``theta``, ``q = (0, 0, sin(theta / 2),
cos(theta / 2))``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseStamped, PoseWithCovarianceStamped, Quaternion
from nav_msgs.msg import Path
from numpy.typing import ArrayLike, NDArray
from std_msgs.msg import ColorRGBA, Float64MultiArray, MultiArrayDimension
from visualization_msgs.msg import Marker, MarkerArray

from push_core.geometry import object_to_world
from push_core.planner import Outline, PushPlan
from push_perception.conversions import (
    OBJECT_FRAME,
    OUTLINE_FIELDS,
    outline_from_cloud,
)
from push_perception.conversions import outline_cloud_msg as outline_cloud

__all__ = [
    "OBJECT_FRAME",
    "OUTLINE_FIELDS",
    "STATE_SIZE",
    "WORLD_FRAME",
    "affordance_markers",
    "estimate_from_msg",
    "goal_from_msg",
    "outline_cloud",
    "outline_from_cloud",
    "push_path",
    "seconds_from_stamp",
    "state_from_msg",
    "state_msg",
    "stamp_from_seconds",
    "status_msg",
    "yaw_from_quaternion",
]

WORLD_FRAME = "world"
#: ``estimator/state``: 7 state values, then the 7 x 7 covariance row-major.
STATE_SIZE = 7
STATE_LABELS = ("state", "covariance_row_major")
#: Largest deviation of a quaternion's norm from 1, and largest |q_x|, |q_y| of a planar pose.
QUATERNION_TOLERANCE = 1e-3


# ------------------------------------------------------------------------------ time
def seconds_from_stamp(stamp: Time) -> float:
    """``builtin_interfaces/Time`` -> float seconds."""
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def stamp_from_seconds(seconds: float) -> Time:
    """Float seconds (>= 0) -> ``builtin_interfaces/Time``."""
    if not (math.isfinite(seconds) and seconds >= 0.0):
        raise ValueError(f"stamp must be finite and >= 0 s, got {seconds}")
    sec = int(math.floor(seconds))
    nanosec = min(int(round((seconds - sec) * 1e9)), 999_999_999)
    return Time(sec=sec, nanosec=nanosec)


# ------------------------------------------------------------------------------ poses
def yaw_from_quaternion(q: Quaternion) -> float:
    """Yaw of a planar orientation quaternion (x, y, z, w), radians in (-pi, pi].

    Raises
    ------
    ValueError
        Non-finite values, a norm further than ``QUATERNION_TOLERANCE`` from 1, or a rotation
        that is not about z (``|q_x|`` or ``|q_y|`` above the tolerance).
    """
    v = np.array([q.x, q.y, q.z, q.w], dtype=float)
    if not np.all(np.isfinite(v)):
        raise ValueError(f"quaternion (x, y, z, w) = {v.tolist()} is not finite")
    norm = float(np.linalg.norm(v))
    if abs(norm - 1.0) > QUATERNION_TOLERANCE:
        raise ValueError(f"quaternion (x, y, z, w) = {v.tolist()} is not unit length "
                         f"(norm {norm:.6g})")
    if max(abs(v[0]), abs(v[1])) > QUATERNION_TOLERANCE:
        raise ValueError(f"quaternion (x, y, z, w) = {v.tolist()} is not a rotation about z "
                         "(a planar pose has q_x = q_y = 0)")
    return math.atan2(2.0 * v[2] * v[3], v[3] ** 2 - v[2] ** 2)


def _planar_pose(pose: Pose) -> NDArray[np.float64]:
    p = pose.position
    if not all(math.isfinite(c) for c in (p.x, p.y, p.z)):
        raise ValueError(f"position ({p.x}, {p.y}, {p.z}) is not finite")
    return np.array([p.x, p.y, yaw_from_quaternion(pose.orientation)])


def goal_from_msg(msg: PoseStamped,
                  workspace: tuple[tuple[float, float], tuple[float, float]]
                  ) -> NDArray[np.float64]:
    """Goal pose ``(x, y, theta)`` of the object frame in ``world`` from ``goal_pose``.

    Parameters
    ----------
    msg : geometry_msgs/PoseStamped
        Frame ``world`` (RViz's "2D Goal Pose" with the fixed frame ``world``).
    workspace : ((xmin, xmax), (ymin, ymax))
        The goal position must lie in this rectangle (metres), i.e. on the reachable table.

    Raises
    ------
    ValueError
        Wrong frame, non-finite position, non-unit or non-planar quaternion, or a position
        outside the workspace.
    """
    if msg.header.frame_id != WORLD_FRAME:
        raise ValueError(f"frame_id is {msg.header.frame_id!r}, expected {WORLD_FRAME!r}")
    goal = _planar_pose(msg.pose)
    (x0, x1), (y0, y1) = workspace
    if not (x0 <= goal[0] <= x1 and y0 <= goal[1] <= y1):
        raise ValueError(f"position ({goal[0]:.4f}, {goal[1]:.4f}) m is off the workspace "
                         f"x in [{x0}, {x1}], y in [{y0}, {y1}] m")
    return goal


def estimate_from_msg(msg: PoseWithCovarianceStamped) -> tuple[NDArray[np.float64], float]:
    """Pose ``(x, y, theta)`` in ``world`` and stamp (s) of ``estimator/object_pose``.

    Raises
    ------
    ValueError
        Wrong frame, non-finite position, non-unit or non-planar quaternion.
    """
    if msg.header.frame_id != WORLD_FRAME:
        raise ValueError(f"frame_id is {msg.header.frame_id!r}, expected {WORLD_FRAME!r}")
    return _planar_pose(msg.pose.pose), seconds_from_stamp(msg.header.stamp)


# ------------------------------------------------------------------------------ state
def state_from_msg(msg: Float64MultiArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """State and covariance from ``estimator/state``.

    Returns
    -------
    state : numpy.ndarray, shape (7,)
        ``(x, y, theta, c_x, c_y, l, m)``: pose in ``world`` (m, rad), COM offset in ``object``
        (m), limit-surface parameter (m), pusher-object friction coefficient.
    covariance : numpy.ndarray, shape (7, 7)

    Raises
    ------
    ValueError
        A layout other than dims ``state`` (7) and ``covariance_row_major`` (49), a data length
        other than 56, a non-finite state value, or a covariance that is not finite with a
        non-negative diagonal.
    """
    dims = [(d.label, d.size) for d in msg.layout.dim]
    expected = [(STATE_LABELS[0], STATE_SIZE), (STATE_LABELS[1], STATE_SIZE ** 2)]
    if dims != expected:
        raise ValueError(f"layout dims are {dims}, expected {expected}")
    data = np.asarray(msg.data, dtype=float)
    if data.shape != (STATE_SIZE + STATE_SIZE ** 2,):
        raise ValueError(f"data has {data.size} values, expected {STATE_SIZE + STATE_SIZE ** 2}")
    state = data[:STATE_SIZE].copy()
    if not np.all(np.isfinite(state)):
        raise ValueError(f"state (x, y, theta, c_x, c_y, l, m) = {state.tolist()} is not finite")
    cov = data[STATE_SIZE:].reshape(STATE_SIZE, STATE_SIZE).copy()
    if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) < 0.0):
        raise ValueError("covariance is not finite with a non-negative diagonal")
    return state, cov


def state_msg(state: ArrayLike, covariance: ArrayLike | None = None) -> Float64MultiArray:
    """``estimator/state`` message of a state (7,) and covariance (7, 7) (default zeros)."""
    state = np.asarray(state, dtype=float).reshape(STATE_SIZE)
    cov = np.zeros((STATE_SIZE, STATE_SIZE)) if covariance is None else np.asarray(covariance)
    msg = Float64MultiArray()
    msg.layout.dim = [
        MultiArrayDimension(label=STATE_LABELS[0], size=STATE_SIZE, stride=STATE_SIZE),
        MultiArrayDimension(label=STATE_LABELS[1], size=STATE_SIZE ** 2,
                            stride=STATE_SIZE ** 2),
    ]
    msg.data = [float(v) for v in np.concatenate([state, cov.reshape(-1)])]
    return msg


# ------------------------------------------------------------------------------ outputs
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
    q = Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))
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


def _color(r: float, g: float, b: float, a: float = 1.0) -> ColorRGBA:
    return ColorRGBA(r=float(r), g=float(g), b=float(b), a=float(a))


def _points(xy: NDArray[np.float64], z: float) -> list[Point]:
    return [Point(x=float(x), y=float(y), z=z) for x, y in xy]


def affordance_markers(outline: Outline, pose: ArrayLike, plan: PushPlan, stamp: Time,
                       height: float = 0.015) -> MarkerArray:
    """``planner/affordances``: the plan drawn in ``world`` (namespace ``planner``).

    Markers (fixed ids, so each plan replaces the previous one):

    0. ``outline`` (SPHERE_LIST, 3 mm): every outline point coloured by its eq. (5.1) score,
       green = lowest (best) to red = highest, over the range [min, min + 100 mm];
    1. ``candidates`` (SPHERE_LIST, 8 mm, blue): the sampled contact points;
    2. ``push`` (ARROW, contact -> end, orange) and 3. ``approach`` (SPHERE, 6 mm, grey).

    Parameters
    ----------
    outline : Outline
        Object frame.
    pose : array_like, shape (3,)
        The estimate the plan was made from (object pose in ``world``).
    plan : PushPlan
    stamp : builtin_interfaces/Time
    height : float
        z of the markers, metres (above the table, on top of the object).
    """
    pose = np.asarray(pose, dtype=float)
    world_pts = np.asarray(object_to_world(pose, outline.points))
    header_frame = WORLD_FRAME

    def marker(mid: int, ns: str, kind: int) -> Marker:
        m = Marker()
        m.header.frame_id = header_frame
        m.header.stamp = stamp
        m.ns, m.id, m.type, m.action = ns, mid, kind, Marker.ADD
        m.pose.orientation.w = 1.0
        return m

    s = np.asarray(plan.scores, dtype=float)
    t = np.clip((s - np.min(s)) / 100.0, 0.0, 1.0)
    outline_m = marker(0, "planner/outline", Marker.SPHERE_LIST)
    outline_m.scale.x = outline_m.scale.y = outline_m.scale.z = 0.003
    outline_m.points = _points(world_pts, height)
    outline_m.colors = [_color(v, 1.0 - v, 0.0) for v in t]
    outline_m.color = _color(1.0, 1.0, 1.0)

    cand = marker(1, "planner/candidates", Marker.SPHERE_LIST)
    cand.scale.x = cand.scale.y = cand.scale.z = 0.008
    cand.points = _points(world_pts[np.asarray(plan.candidates, dtype=int)], height)
    cand.color = _color(0.1, 0.3, 1.0)

    arrow = marker(2, "planner/push", Marker.ARROW)
    arrow.scale.x, arrow.scale.y, arrow.scale.z = 0.004, 0.008, 0.008
    arrow.points = _points(np.stack([plan.contact, plan.end]), height)
    arrow.color = _color(1.0, 0.5, 0.0)

    approach = marker(3, "planner/approach", Marker.SPHERE)
    approach.pose.position = Point(x=float(plan.approach[0]), y=float(plan.approach[1]),
                                   z=height)
    approach.scale.x = approach.scale.y = approach.scale.z = 0.006
    approach.color = _color(0.5, 0.5, 0.5)
    return MarkerArray(markers=[outline_m, cand, arrow, approach])


def status_msg(name: str, level: bytes, message: str,
               values: Mapping[str, object] | Sequence[tuple[str, object]]) -> DiagnosticStatus:
    """``planner/status`` / ``/diagnostics`` entry: level, message and string key-values."""
    items = values.items() if isinstance(values, Mapping) else values
    return DiagnosticStatus(level=level, name=name, message=message, hardware_id="",
                            values=[KeyValue(key=str(k), value=str(v)) for k, v in items])
