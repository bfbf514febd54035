"""The ROS-free arithmetic of a graph episode's record: which estimate starts the episode,
the planner's status fields, the end reason, step latencies, robot time and the arm's
contact-line error.

:class:`pushbot.runner.episode.GraphRunner` applies these to what its client received; they
take plain stamps, strings and arrays, so they are tested without a graph.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from push_core.episode import robot_times

__all__ = ["CONTACT_HEIGHT", "end_reason", "first_estimate", "graph_robot_times", "latencies",
           "line_deviation", "same_goal", "status_seconds"]


def first_estimate(outline_stamps: Sequence[float], estimates: Sequence[tuple[float, Any]],
                   scene: float, after: float) -> tuple[float, float, Any] | None:
    """The episode's first estimate: (reference stamp, estimate stamp, estimate) or None yet.

    ``outline_stamps``: ``perception/outline`` stamps as received (s); ``estimates``: (stamp,
    pose) as received; ``scene``: the new scene's first frame (the simulator's reset answer);
    ``after``: the estimator's boundary. The reference is the first outline of a frame of the
    new scene; the estimate the first one after ``after`` and at or after the reference
    (:meth:`pushbot.runner.episode.GraphRunner.run`).
    """
    ref = next((s for s in outline_stamps if s >= scene), None)
    if ref is None:
        return None
    return next(((ref, s, p) for s, p in estimates if s > after and s >= ref - 1e-6), None)


def same_goal(a: str, b: str) -> bool:
    """Whether two goals as planner/status shows them (``"x y theta"``) are the same goal
    (within the status text's rounding)."""
    try:
        va, vb = [float(v) for v in a.split()], [float(v) for v in b.split()]
    except ValueError:
        return False
    return len(va) == len(vb) == 3 and all(abs(x - y) < 2e-4 for x, y in zip(va, vb,
                                                                              strict=True))


def status_seconds(status: dict[str, str], key: str) -> float:
    """A time value (s) of planner/status; -inf when absent or unreadable."""
    try:
        return float(status.get(key, "-inf"))
    except ValueError:
        return -math.inf


def end_reason(message: str) -> str:
    """The record's ``reason`` for the planner's final status message."""
    if message.startswith("goal reached"):
        return "goal reached"
    if message.startswith("failed after max steps"):
        return "max steps"
    if message.startswith("failed: no feasible push"):
        return "no feasible push"
    if message.startswith("failed: robot unavailable"):
        return "robot unavailable"
    if message.startswith("robot unavailable: "):  # an episode that ended waiting (dry run)
        return message.split(" - ")[0]
    return message


#: Tool tip samples lower than this above the table count as "in contact" for the line error
#: of an arm push (the executor pushes at 1 cm; transit and park moves are far higher), m.
CONTACT_HEIGHT = 0.02


def line_deviation(tip: np.ndarray, contact: np.ndarray, end: np.ndarray,
                   max_height: float = CONTACT_HEIGHT) -> float | None:
    """Largest horizontal distance of tool tip samples from a commanded push line, m.

    Parameters
    ----------
    tip : (K, 3) array
        True tool tip positions in ``world`` (m).
    contact, end : (2,) arrays
        The commanded contact segment (``planner/push``'s contact and end points, m).
    max_height : float
        Only samples at most this high count (the pushing height; not transit), m.

    Returns
    -------
    float or None
        The maximum over the samples whose projection falls on the segment, or None when
        there is none.
    """
    tip = np.asarray(tip, dtype=float).reshape(-1, 3)
    a, b = np.asarray(contact, dtype=float), np.asarray(end, dtype=float)
    d = b - a
    length = float(np.hypot(*d))
    if length == 0.0:
        return None
    u = d / length
    rel = tip[:, :2] - a
    along = rel @ u
    off = np.abs(rel @ np.array([-u[1], u[0]]))
    on = (tip[:, 2] <= max_height) & (along >= 0.0) & (along <= length)
    return float(off[on].max()) if on.any() else None


def latencies(executed: list[tuple[float, float, float]],
              pushes: list[tuple[float, np.ndarray]]) -> list[float]:
    """Wall ms from each pusher/executed to the next planner/push (as the client received
    them: ``executed`` holds (wall s, start, end stamp), ``pushes`` (wall s, points))."""
    out = []
    for t_exec, _, _ in executed:
        following = [t for t, _ in pushes if t > t_exec]
        if following:
            out.append(1e3 * (following[0] - t_exec))
    return out


def graph_robot_times(t_goal: float, first_frame: float, stamps: Sequence[float],
                      stop: float | None) -> dict[str, Any]:
    """``robot_time_s`` and ``cycle_s`` of a graph episode (:func:`push_core.episode.robot_times`).

    ``t_goal``: the client's newest ``/clock`` when it sent the goal (the episode's first
    frame's stamp if none had come), at most the first push's stamp (two nodes' clocks differ
    by their ``/clock`` delivery); ``stamps``: the header stamps of the pushes seen since, of
    which those before the goal (another client's, stamped 0) are not the robot's commands;
    ``stop``: the stamp of the frame after the last executed push (None: nothing executed; the
    episode then ends at its last command, as when every push was refused)."""
    goal = t_goal if math.isfinite(t_goal) else first_frame
    commands = sorted(s for s in stamps if s >= goal - 1.0)
    goal = min([goal, *commands])
    end = max(goal if stop is None else stop, commands[-1] if commands else goal)
    return robot_times(goal, commands, end)
