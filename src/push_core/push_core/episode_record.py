"""The episode record and its scoring, ROS-free: an empty record (:func:`new_record`), the
true end errors and success (:func:`end_score`, :func:`true_errors`), the robot's time
(:func:`robot_times`) and the physical minimum of pushes (:func:`min_pushes`).

Success is judged from the *true* end pose against the true goal, the orientation modulo the
object's k-fold symmetry and not counted for a continuously symmetric outline
(:mod:`push_core.symmetry`); docs/design/episode-engine.md#times-and-scoring. Distances in m,
angles in rad, times in s of the robot's clock. :mod:`push_core.episode` re-exports every name.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import wrap_angle
from push_core.symmetry import has_continuous_symmetry, symmetry_order_of_polygon

__all__ = ["check_goal_offset", "end_score", "min_pushes", "new_record", "robot_times",
           "true_errors"]


def true_errors(pose: ArrayLike, goal: ArrayLike, order: int) -> tuple[float, float]:
    """Position (m) and absolute orientation error (rad) of ``pose`` against ``goal``, the
    orientation modulo ``2 pi / order`` (closest equivalent)."""
    p, g = np.asarray(pose, dtype=np.float64), np.asarray(goal, dtype=np.float64)
    dxy = float(math.hypot(g[0] - p[0], g[1] - p[1]))
    period = 2.0 * math.pi / max(int(order), 1)
    d = float(wrap_angle(g[2] - p[2]))
    d -= period * round(d / period)
    return dxy, abs(d)


def new_record(trial: dict[str, Any], **extra: Any) -> dict[str, Any]:
    """An empty episode record (docs/design/evaluation.md#episode-record) for ``trial`` (the
    trial as a dict), with ``extra`` keys of the engine that fills it."""
    rec: dict[str, Any] = {"trial": trial, "success": False, "steps": 0, "end_error_xy": None,
                           "end_error_theta": None, "com_error": None, "planning_ms": [],
                           "poses_true": [], "poses_est": [], "pushes": [], "refused": 0,
                           "wall_s": 0.0, "reason": ""}
    rec.update(extra)
    return rec


def robot_times(goal: float, commands: Sequence[float], stop: float) -> dict[str, Any]:
    """The episode record's robot time: ``robot_time_s``, the robot's (simulated) seconds
    from the goal to the final stop (``stop - goal``), and ``cycle_s``, the seconds between
    successive push commands (one per push after the first).

    Parameters
    ----------
    goal : float
        When the goal was given, s of the robot's clock.
    commands : sequence of float
        When each push was commanded, s, in order.
    stop : float
        When the robot came to rest after the last push (``goal`` without pushes), s.

    Raises
    ------
    ValueError
        Non-finite times, commands out of order, or one before the goal or after the stop.
    """
    times = np.asarray([goal, *commands, stop], dtype=float)
    if not np.all(np.isfinite(times)) or np.any(np.diff(times) < 0.0):
        raise ValueError(f"robot times must be finite and in order (goal <= commands <= stop), "
                         f"got goal {goal}, commands {list(commands)[:8]}, stop {stop}")
    return {"robot_time_s": float(stop - goal),
            "cycle_s": np.diff(np.asarray(commands, dtype=float)).tolist()}


def end_score(polyline: ArrayLike, end_true: ArrayLike, goal_true: ArrayLike,
              tolerances: tuple[float, float]) -> dict[str, Any]:
    """Success and true end errors of an episode (one rule for every episode record).

    ``polyline``: the true object's outline (object frame). The orientation error is taken
    modulo the outline's k-fold symmetry; for a continuously symmetric outline (a disc,
    :func:`push_core.symmetry.has_continuous_symmetry`) it is reported but not counted
    (``orientation_ignored``). Returns ``end_error_xy`` (m), ``end_error_theta`` (rad),
    ``success`` and ``orientation_ignored``.
    """
    ignored = has_continuous_symmetry(polyline)
    exy, eth = true_errors(end_true, goal_true, symmetry_order_of_polygon(polyline))
    tol_xy, tol_theta = tolerances
    return {"end_error_xy": exy, "end_error_theta": eth,
            "success": bool(exy <= tol_xy and (ignored or eth <= tol_theta)),
            "orientation_ignored": ignored}


def check_goal_offset(offset: ArrayLike, tolerances: tuple[float, float],
                      max_push_length: float) -> tuple[NDArray[np.float64], float, float]:
    """The arguments of :func:`min_pushes` checked: ``(offset (3,), tol_xy, tol_theta)``;
    ``ValueError`` naming ``offset``, ``tolerances`` or ``max_push_length``."""
    o = np.asarray(offset, dtype=np.float64)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise ValueError(f"offset: expected 3 finite numbers, got {offset!r}")
    tol_xy, tol_theta = (float(v) for v in tolerances)
    if not (tol_xy > 0.0 and tol_theta > 0.0):
        raise ValueError(f"tolerances: expected positive (m, rad), got {tolerances!r}")
    if not (isinstance(max_push_length, int | float | np.floating)
            and math.isfinite(max_push_length) and max_push_length > 0.0):
        raise ValueError(f"max_push_length: expected > 0 m, got {max_push_length!r}")
    return o, tol_xy, tol_theta


def min_pushes(offset: ArrayLike, tolerances: tuple[float, float], max_push_length: float,
               order: int = 1) -> int:
    """The physical minimum of pushes for a goal ``offset`` (docs/design/physical-minimum.md)::

        n_min = max(ceil((d - tol_xy) / L_max), 1 if |theta| > tol_theta else 0)

    ``d = |(dx, dy)|``: a quasi-static object moves no farther than the pusher, which advances
    at most ``L_max`` past the contact per push, and the goal region accepts ``tol_xy`` less;
    a rotation beyond the tolerance needs at least one push (one push can turn an object by
    any amount, pivoting near the contact). ``theta`` is taken modulo ``2 pi / order`` (the
    object's symmetry).

    Parameters
    ----------
    offset : array_like, shape (3,)
        Goal minus initial pose: ``(dx, dy)`` in metres (any frame), ``theta`` in radians.
    tolerances : (float, float)
        Goal region: position (m) and orientation (rad), > 0.
    max_push_length : float
        Longest push past the contact, metres (> 0).
    order : int
        Rotational symmetry order of the object (1: none).

    Returns
    -------
    int
        >= 0 (0: the goal is already within the region).

    Raises
    ------
    ValueError
        Naming ``offset``, ``tolerances`` or ``max_push_length``.
    """
    o, tol_xy, tol_theta = check_goal_offset(offset, tolerances, max_push_length)
    dxy, dtheta = true_errors(np.zeros(3), o, order)
    translation = max(0, math.ceil((dxy - tol_xy) / max_push_length - 1e-9))
    return max(translation, 1 if dtheta > tol_theta else 0)
