"""Lookahead over push sequences for the planner: value of a first push, ROS-free.

The greedy planner (:mod:`push_core.planner`, ``PlannerConfig.horizon = 1``) executes the push
whose predicted pose scores best by eq. (5.1). With ``horizon = H > 1`` each candidate first
push is valued by the best *sequence* of up to ``H`` pushes that starts with it; the first push
of the best sequence is executed and the planner re-plans after every push (receding horizon,
so the stop rule and the avoid list work as before).

Search (a beam search with a greedy rollout policy; :func:`sequence_values`):

1. **First pushes**: the planner's evaluated pushes (k sampled points x 13 directions), each
   at several lengths read off the same rollout (no extra rollout): the greedy one (best
   eq. 5.1 score to the goal), the longest feasible one, and the best lengths for two
   **sub-goals** (:func:`subgoals`): *rotation first* (the goal orientation at the current
   position) and *translation first* (the goal position at the current orientation). These are
   the pushes a greedy planner never takes when translation and rotation conflict (an ellipse
   that turns while it translates: translate fully, then correct the turn).
2. **Beam**: at most ``beam`` first pushes are looked ahead from, filled round-robin from the
   groups of step 1 (each group's best eq. 5.1 score first), so the greedy push and the best
   push of each sub-goal are always in it.
3. **Continuation**: from each beam pose the planner's best next push towards the goal (its
   ``expand`` callback: the k best-scoring outline points by the affordances, the 5 base
   directions, rolled out in substeps of :data:`CONTINUATION_SUBSTEP`, one batched rollout
   for the whole beam), repeated up to depth ``H``. Coarser than the first push (13
   directions, 5 mm substeps): it only values the first push, which is re-planned in full
   after it is executed; a rollout's cost grows with its batch (B x k x 5 pushes here).
4. **Value** of a sequence that stops after ``h`` pushes (when its predicted pose is inside the
   goal region shrunk by :data:`REACH_FRACTION`, or at ``h = H``)::

       V = push_cost * h + score_h

   ``score_h`` is eq. (5.1) of the predicted pose after push ``h`` (millimetres) and
   ``push_cost`` the price of one push (millimetres of score). A first push outside the beam
   gets ``V = inf`` unless it reaches the goal by itself (``V = push_cost + score_1``).
   With ``H = 1`` every first push has ``V = push_cost + score_1``: the greedy choice.

Units: scores and ``push_cost`` in millimetres of eq. (5.1) (mm + lambda x deg); poses
``(x, y, theta)`` in ``world`` (m, rad).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "CONTINUATION_SUBSTEP",
    "GROUPS",
    "REACH_FRACTION",
    "Expand",
    "sequence_values",
    "subgoals",
]

#: Groups of first pushes (step 1 of the module docstring), in beam round-robin order.
GROUPS = ("greedy", "rotation_first", "translation_first", "longest")
#: The search counts a predicted pose as "reached" inside the goal region shrunk to this
#: fraction of the tolerances (the real stop rule also shrinks it by the estimate's
#: uncertainty, and the prediction is a model).
REACH_FRACTION = 0.6
#: Substep of the continuation rollouts, metres (the first push: ``PlannerConfig.substep``).
CONTINUATION_SUBSTEP = 0.01

#: ``expand(poses) -> (scores, next_poses, reached)``: the planner's best next push from each
#: pose (B, 3): its eq. (5.1) score (B,) (inf if none is feasible), the predicted pose after it
#: (B, 3) and whether that pose is in the goal region (B,) (:data:`REACH_FRACTION`).
Expand = Callable[[NDArray[np.float64]],
                  tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]]


def subgoals(pose: ArrayLike, goal: ArrayLike) -> NDArray[np.float64]:
    """Sub-goals of step 1: rotation first and translation first.

    Parameters
    ----------
    pose, goal : array_like, shape (3,)
        Current and goal pose ``(x, y, theta)`` in ``world`` (m, rad).

    Returns
    -------
    numpy.ndarray, shape (2, 3)
        ``(x, y, theta_goal)`` (turn in place) and ``(x_goal, y_goal, theta)`` (move, keep
        the orientation), ``world``.
    """
    p = np.asarray(pose, dtype=np.float64)
    g = np.asarray(goal, dtype=np.float64)
    if p.shape != (3,) or g.shape != (3,):
        raise ValueError(f"pose, goal: expected shape (3,), got {p.shape} and {g.shape}")
    return np.array([[p[0], p[1], g[2]], [g[0], g[1], p[2]]])


def _beam(scores: NDArray[np.float64], groups: NDArray[np.intp], eligible: NDArray[np.bool_],
          beam: int) -> NDArray[np.intp]:
    """Up to ``beam`` eligible options, round-robin over the groups in ascending label order,
    each group's best score first (ties: lower index)."""
    queues = []
    for g in np.unique(groups[eligible]):
        members = np.flatnonzero(eligible & (groups == g))
        queues.append(list(members[np.argsort(scores[members], kind="stable")]))
    chosen: list[int] = []
    taken = np.zeros(len(scores), dtype=bool)
    while len(chosen) < beam and any(queues):
        for q in queues:
            while q and taken[q[0]]:
                q.pop(0)
            if q and len(chosen) < beam:
                i = q.pop(0)
                taken[i] = True
                chosen.append(int(i))
    return np.array(chosen, dtype=np.intp)


def sequence_values(scores: ArrayLike, poses: ArrayLike, reached: ArrayLike, groups: ArrayLike,
                    expand: Expand, horizon: int, beam: int,
                    push_cost: float) -> NDArray[np.float64]:
    """Value of each first push: the best sequence of up to ``horizon`` pushes it starts.

    Parameters
    ----------
    scores : array_like, shape (N,)
        Eq. (5.1) score (mm) of the predicted pose after each first push; inf = infeasible.
    poses : array_like, shape (N, 3)
        Predicted pose after each first push, ``world``.
    reached : array_like of bool, shape (N,)
        Whether that pose is in the (shrunk) goal region.
    groups : array_like of int, shape (N,)
        Group of each first push (index into :data:`GROUPS`; any integers work: the beam is
        filled round-robin over them in ascending order).
    expand : Expand
        The planner's best next push from a batch of poses (see :data:`Expand`).
    horizon : int
        Pushes per sequence, >= 1.
    beam : int
        First pushes looked ahead from, >= 1.
    push_cost : float
        Cost of one push in score units (mm), >= 0.

    Returns
    -------
    numpy.ndarray, shape (N,)
        ``V`` of the module docstring (mm); inf for infeasible first pushes and for those
        outside the beam that do not reach the goal by themselves.
    """
    s = np.asarray(scores, dtype=np.float64)
    n = s.shape[0]
    p = np.asarray(poses, dtype=np.float64).reshape(n, 3)
    done = np.asarray(reached, dtype=bool).reshape(n)
    g = np.asarray(groups).reshape(n)
    values = push_cost + s
    if horizon <= 1:
        return values
    feasible = np.isfinite(s)
    roots = _beam(s, g, feasible & ~done, beam)
    values = np.where(done & feasible, values, np.inf)
    if roots.size == 0:
        return values
    alive, pose, last = roots, p[roots], s[roots]
    for depth in range(2, horizon + 1):
        nxt, nxt_pose, nxt_done = expand(pose)
        ok = np.isfinite(nxt)
        # no feasible continuation: valued as if this push were spent without progress
        values[alive[~ok]] = push_cost * depth + last[~ok]
        stop = ok & (nxt_done | (depth == horizon))
        values[alive[stop]] = push_cost * depth + nxt[stop]
        keep = ok & ~stop
        alive, pose, last = alive[keep], nxt_pose[keep], nxt[keep]
        if alive.size == 0:
            break
    return values
