"""The checks and report texts of the commands ``sim_bridge_node`` takes: ``sim/knock``, pushes
and the scene built by ``~/reset``. ROS-free (the node converts the messages with push_ros's
codecs first)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["COUNTERS", "MAX_KNOCK_SHIFT", "PUSH_COUNTER", "check_knock", "knocked_pose",
           "push_report", "scene_summary", "startup_warnings", "unused_com_warning"]

#: Largest displacement of the object one ``sim/knock`` may ask for, m.
MAX_KNOCK_SHIFT = 0.1


#: The node's own event counters (refusals are also ``refused`` / ``refused_<kind>``).
COUNTERS = ("pushes_executed", "pushes_rejected_busy", "pushes_rejected_invalid",
            "pushes_failed", "pushes_refused_fault", "pushes_ignored_arm_mode", "resets",
            "knocks", "knocks_rejected", "frames_dropped", "frames_delayed", "frames_reordered",
            "trajectories_accepted", "trajectories_rejected", "trajectory_runs",
            "trajectory_runs_failed", "resets_refused")
#: A refused push's counter by its refusal kind (the world's refusals carry their own kind).
PUSH_COUNTER = {"busy": "pushes_rejected_busy", "fault": "pushes_refused_fault"}


def check_knock(delta: Any) -> np.ndarray:
    """A knock ``(dx, dy, dyaw)`` (m, m, rad; world frame) as a (3,) array.

    Raises
    ------
    ValueError
        Not 3 finite values, or ``|(dx, dy)|`` above ``MAX_KNOCK_SHIFT``.
    """
    arr = np.asarray(delta, dtype=float)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"a knock is 3 finite values (dx, dy m, dyaw rad), got {arr.shape}")
    shift = float(np.hypot(arr[0], arr[1]))
    if shift > MAX_KNOCK_SHIFT:
        raise ValueError(f"displacement {shift:.4f} m is larger than {MAX_KNOCK_SHIFT} m")
    return arr


def knocked_pose(pose: Any, delta: np.ndarray,
                 workspace: tuple[tuple[float, float], tuple[float, float]]) -> np.ndarray:
    """The object's pose (x, y m, yaw rad; world) after the knock ``delta`` (added).

    Raises
    ------
    ValueError
        The new origin lies outside ``workspace`` ((x0, x1), (y0, y1), m).
    """
    after = np.asarray(pose, dtype=float) + delta
    (x0, x1), (y0, y1) = workspace
    if not (x0 <= after[0] <= x1 and y0 <= after[1] <= y1):
        raise ValueError(f"the object would leave the workspace (to x {after[0]:.4f}, "
                         f"y {after[1]:.4f} m)")
    return after


def scene_summary(spec: Any, pose: Any, width: int, height: int, time: float) -> str:
    """The one line ``~/reset`` answers with (``pushbot`` reads the COM and time from it).

    Parameters
    ----------
    spec : push_core.objects.ObjectSpec
        The object as built (mass kg, COM m in the object frame, frictions).
    pose : (3,) array_like
        Its pose in world (x, y m, yaw rad).
    width, height : int
        Camera image size, px.
    time : float
        Stamp of the new scene's first frame, s (frames before it show the old scene).
    """
    return (f"built {spec.name!r} (mass {spec.mass:.4g} kg, COM ({spec.com[0]:.4f}, "
            f"{spec.com[1]:.4f}) m, friction table {spec.friction_table:.3g}, pusher "
            f"{spec.friction_pusher:.3g}) at pose {np.round(pose, 4) + 0.0} (world, m/rad); "
            f"camera {width}x{height}; first frame at {time:.9f} s")


def push_report(seq: int, result: Any, t_start: float, t_end: float) -> str:
    """The log line of an executed push (``PushResult`` of :mod:`sim_bridge.world`; times s)."""
    moved = np.asarray(result.pose_after) - np.asarray(result.pose_before)
    return (f"push {seq} done: pusher {np.round(result.pusher_start, 4)} -> "
            f"{np.round(result.pusher_end, 4)} m, sim {t_start:.3f} -> {t_end:.3f} s, "
            f"touched={bool(result.touched)}, object moved {np.round(moved, 4)} (m, m, rad)")


def unused_com_warning(values: dict[str, Any]) -> str:
    """A warning when ``com_offset`` is set but not used (``use_com_offset`` false), else ""."""
    com = [float(v) for v in values.get("com_offset", ())]
    if values.get("use_com_offset") or not any(com):
        return ""
    return (f"com_offset {com} is not used: use_com_offset is false (the object spec's COM "
            "is built)")


def startup_warnings(values: dict[str, Any], use_sim_time: bool) -> str:
    """What the node warns about at start: an unused ``com_offset``
    (:func:`unused_com_warning`) and ``use_sim_time`` set on the node that owns ``/clock``."""
    notes = [unused_com_warning(values)]
    if use_sim_time:
        notes.append("use_sim_time is true, but the sim bridge is the /clock source; its "
                     "timers run on the steady clock")
    return "; ".join(n for n in notes if n)
