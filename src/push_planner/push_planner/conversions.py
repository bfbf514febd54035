"""The planner's own messages and reading rules: the ``planner/affordances`` MarkerArray (RViz
view of a plan), the goal of ``goal_pose`` on the workspace (:func:`goal_from_msg`), the end
time of any ``pusher/executed`` (:func:`executed_end`), ``planner/status``'s message and values
(:func:`status_message`, :func:`status_values`) and the log line of a push
(:func:`push_log_text`).

Every other message the planner reads or writes has its one codec in :mod:`push_ros`
(``estimator/state``: :mod:`push_ros.state`; poses and goals: :mod:`push_ros.poses`;
``planner/push``: :mod:`push_ros.paths`; ``perception/outline``: :mod:`push_ros.outline`;
``planner/status``: :mod:`push_ros.diagnostics`). Frames and units: ``world``, SI.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path
from numpy.typing import ArrayLike, NDArray
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from push_core.episode import EpisodeEngine
from push_core.geometry import object_to_world
from push_core.planner import Outline, PushPlan
from push_ros.frames import WORLD_FRAME
from push_ros.poses import check_frame, xytheta_from_pose
from push_ros.stamps import seconds_from_stamp

__all__ = ["GOAL_HINT", "affordance_markers", "executed_end", "goal_from_msg", "goal_log_text",
           "outline_text", "push_log_text", "status_message", "status_values"]


#: What ``planner/status`` adds while no goal is set: where goals come from and how to send
#: one that a (re)started planner still gets. A volatile sender (RViz's "2D Goal Pose",
#: ``ros2 topic pub``'s default QoS) reaches only a planner that is running when it publishes.
GOAL_HINT = ("goal_pose (geometry_msgs/PoseStamped, frame world); a goal sent before this node "
             "started arrives only from a latched sender: pushbot goal X Y YAW, or ros2 topic pub "
             "--once --qos-durability transient_local --qos-reliability reliable /goal_pose "
             "geometry_msgs/msg/PoseStamped '{header: {frame_id: world}, pose: ...}' (keep it "
             "running: the latched sample lives in the sender)")


def status_message(engine_text: str, note: str, has_goal: bool) -> str:
    """``planner/status``'s message: the episode in words (``EpisodeEngine.status_text``),
    the node's note, and while no goal is set, what a goal is and how to send one
    (:data:`GOAL_HINT`)."""
    text = engine_text + (f" - {note}" if note else "")
    return text if has_goal else f"{text} on {GOAL_HINT}"


def status_values(engine: EpisodeEngine, max_steps: int, after_goal: str,
                  outline_stamp: float, goal_source: str) -> dict[str, Any]:
    """``planner/status``'s values besides the health counters (docs/INTERFACES.md): the
    episode's state, step, goal, the engine's counters, ``robot_unavailable`` (rule 9's
    ``<kind>: <reason>`` while waiting for the robot, else empty)."""
    counts = {k: v for k, v in engine.counts.items() if k != "left"}
    return {
        "state": engine.phase, "step": engine.steps, "max_steps": max_steps,
        "goal": "" if engine.goal is None else " ".join(f"{v:.4f}" for v in engine.goal),
        "orientation": "used" if engine.orientation_matters else "ignored", **counts,
        "last_push_end": f"{engine.last_push_end:.6f}",
        "outline_stamp": f"{outline_stamp:.6f}", "left_goal": engine.counts["left"],
        "after_goal": after_goal, "goal_source": goal_source,
        "robot_unavailable": engine.unavailable}


def outline_text(outline: Outline) -> str:
    """The log line of an outline taken."""
    decimated = (f", decimated from {outline.source_points}"
                 if outline.source_points > len(outline.points) else "")
    return (f"outline with {len(outline.points)} points{decimated} "
            f"({len(outline.polyline)}-vertex contact polyline)")


def goal_log_text(goal: ArrayLike, source: str) -> str:
    """The log line of a goal taken (x, y m, theta rad) from ``source`` (may be empty)."""
    x, y, theta = (float(v) for v in goal)
    return (f"new goal (x {x:.4f} m, y {y:.4f} m, theta {theta:.4f} rad)"
            f"{f' from {source}' if source else ''}: new episode")


def push_log_text(step: int, plan: PushPlan) -> str:
    """The log line of a push sent."""
    return (f"step {step}: push at outline point {plan.index}, "
            f"{math.degrees(plan.angle):+.0f} deg, {1e3 * plan.length:.1f} mm, predicted score "
            f"{plan.score:.1f} mm (now {plan.current_score:.1f}); approach "
            f"{np.round(plan.approach, 4)}, contact {np.round(plan.contact, 4)}, end "
            f"{np.round(plan.end, 4)} m")


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


def goal_from_msg(msg: PoseStamped,
                   workspace: tuple[tuple[float, float], tuple[float, float]]
                   ) -> np.ndarray:
    """Goal ``(x, y, theta)`` in ``world`` of ``goal_pose``; its position on the workspace.

    Raises
    ------
    ValueError
        Wrong frame, non-finite values, a quaternion that breaks the planarity rule, or a
        position outside ``workspace`` ((xmin, xmax), (ymin, ymax)), m.
    """
    check_frame(msg.header.frame_id, WORLD_FRAME)
    goal = xytheta_from_pose(msg)
    (x0, x1), (y0, y1) = workspace
    if not (x0 <= goal[0] <= x1 and y0 <= goal[1] <= y1):
        raise ValueError(f"position ({goal[0]:.4f}, {goal[1]:.4f}) m is off the workspace "
                         f"x in [{x0}, {x1}], y in [{y0}, {y1}] m")
    return goal


def executed_end(msg: Path) -> float:
    """The end (s) of a ``pusher/executed`` from any executor: the latest of its header stamp
    and its poses' stamps.

    Raises
    ------
    ValueError
        Not in ``world``, no poses, or a stamp outside the time rule of :mod:`push_ros.stamps`.
    """
    if msg.header.frame_id != WORLD_FRAME or not msg.poses:
        raise ValueError(f"expected poses in 'world', got {len(msg.poses)} poses in "
                         f"{msg.header.frame_id!r}")
    return max([seconds_from_stamp(msg.header.stamp)]
               + [seconds_from_stamp(p.header.stamp) for p in msg.poses])
