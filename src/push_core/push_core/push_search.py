"""The planner's push optimisation at sampled contact points (docs/ARCHITECTURE.md,
"Planner", step 4), ROS-free, vectorised over all pushes.

:func:`evaluate` gives the best push (direction and length) at each candidate outline point:
the 5 base directions and the interpolated ones between them rolled out in one batch
(:func:`push_core.rollout.rollout_push`), each truncated at its best length, only the
interpolated directions next to a point's best base direction admitted; the ``direct`` variant
rescales the affordances linearly in the push length instead; with ``horizon > 1`` the first
pushes of the lookahead (:mod:`push_core.lookahead`). :func:`expand` is the lookahead's
continuation, :func:`pusher_points` turns (point, direction, length) into the pusher's world
points. :class:`push_core.planner.Planner` samples the points and picks the best option.

Frames and units: outline points, normals, the COM and affordances in the object frame; poses,
goals and pusher points in ``world``; metres and radians; scores in millimetres of eq. (5.1)
(:mod:`push_core.scores`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core import lookahead
from push_core.affordances import N_ANGLES
from push_core.geometry import (
    closest_point_on_polyline,
    object_to_world,
    world_to_object,
    wrap_angle,
)
from push_core.model import REPRESENTATIVE_ANGLES_DEG, REPRESENTATIVE_LENGTHS
from push_core.plan_inputs import Outline
from push_core.planner_config import APPROACH_MARGIN, PlannerConfig
from push_core.rollout import rollout_push
from push_core.scores import motion_score

__all__ = ["BASE_ANGLES_DEG", "DIRECT_LENGTH_STEP", "INTERPOLATION_STEPS", "Options", "evaluate",
           "expand", "pusher_points", "reached_ahead", "rotation_weight"]

#: Base push directions of the optimisation, degrees from the inward normal, ascending.
BASE_ANGLES_DEG = (-60.0, -30.0, 0.0, 30.0, 60.0)
#: Grid step of the push length in the direct variant, metres.
DIRECT_LENGTH_STEP = 1e-3
#: Interpolated directions between two neighbouring base directions (every 10 degrees).
INTERPOLATION_STEPS = 2

# Column of each base direction (ascending) in the representative-push order (0, 30, -30, ...).
_BASE_TO_REPR = tuple(REPRESENTATIVE_ANGLES_DEG.index(a) for a in BASE_ANGLES_DEG)
# All directions of the optimisation, ascending (radians); base ones at _BASE_COLUMNS.
_FINE_ANGLES = np.radians(np.linspace(
    BASE_ANGLES_DEG[0], BASE_ANGLES_DEG[-1],
    (len(BASE_ANGLES_DEG) - 1) * (INTERPOLATION_STEPS + 1) + 1))
_BASE_COLUMNS = np.arange(0, len(_FINE_ANGLES), INTERPOLATION_STEPS + 1)


@dataclass
class Options:
    """Evaluated pushes (flat batch): outline index, angle, best length and its outcome."""

    index: NDArray[np.intp]
    angle: NDArray[np.float64]
    length: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    score: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    pose: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    travel: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    group: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))


def rotation_weight(cfg: PlannerConfig, outline: Outline) -> float:
    """The rotation weight of eq. (5.1), mm/deg: ``cfg.lam``, or 0 when the orientation does
    not matter (a continuously symmetric outline)."""
    return cfg.lam if outline.orientation_matters else 0.0


def evaluate(cfg: PlannerConfig, outline: Outline, pose: NDArray[np.float64],
             com: NDArray[np.float64], l: float, m: float,  # noqa: E741
             goal: NDArray[np.float64], desired: NDArray[np.float64], aff: NDArray[np.float64],
             candidates: NDArray[np.intp]) -> Options:
    """Best push (direction and length) at each candidate point; flat over the options."""
    if cfg.direct:
        return _direct(cfg, outline, pose, desired, aff, candidates)
    # One batched rollout for the base directions and the interpolated ones between every
    # pair of neighbouring base directions (a rollout call costs the same for 15 or 40
    # pushes); only the interpolated directions next to a candidate's best base direction
    # are then admitted, which gives the result of the sequential procedure.
    n_fine = len(_FINE_ANGLES)
    idx, ang = np.repeat(candidates, n_fine), np.tile(_FINE_ANGLES, len(candidates))
    if cfg.horizon > 1:
        return _first_pushes(cfg, outline, pose, com, l, m, goal, idx, ang)
    opts = _rollouts(cfg, outline, pose, com, l, m, goal, idx, ang)
    opts.score = np.where(_admitted(opts.score), opts.score, np.inf)
    return opts


def _first_pushes(cfg: PlannerConfig, outline: Outline, pose: NDArray[np.float64],
                  com: NDArray[np.float64], l: float, m: float,  # noqa: E741
                  goal: NDArray[np.float64], idx: NDArray[np.intp],
                  ang: NDArray[np.float64]) -> Options:
    """First pushes of the lookahead (:mod:`push_core.lookahead`, step 1): each rolled-out
    (point, direction) at its greedy length, its best lengths for the rotation-first and
    translation-first sub-goals and its longest feasible length; flat over
    ``lookahead.GROUPS`` x pushes, ``score`` always against the goal."""
    lengths, after, valid = _trajectories(cfg, outline, pose, com, l, m, idx, ang)
    score = _path_scores(cfg, outline, after, valid, goal)
    rows = np.arange(len(idx))
    picks = [np.argmin(score, axis=1)]
    for sub in lookahead.subgoals(pose, goal):
        picks.append(np.argmin(_path_scores(cfg, outline, after, valid, sub), axis=1))
    picks.append(valid.shape[1] - 1 - np.argmax(valid[:, ::-1], axis=1))  # longest
    admitted = _admitted(score[rows, picks[0]])
    n = len(picks)
    j = np.concatenate(picks)
    rep = np.tile(rows, n)
    best = np.where(np.tile(admitted, n), score[rep, j], np.inf)
    return Options(index=np.tile(idx, n), angle=np.tile(ang, n), length=lengths[j],
                   score=best, pose=after[rep, j],
                   group=np.repeat(np.arange(n, dtype=np.intp), len(idx)))


def reached_ahead(cfg: PlannerConfig, outline: Outline, poses: NDArray[np.float64],
                  goal: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Predicted poses (B, 3) inside the goal region shrunk to ``REACH_FRACTION``."""
    f = lookahead.REACH_FRACTION
    near = np.hypot(goal[0] - poses[:, 0], goal[1] - poses[:, 1]) <= f * cfg.tolerance_xy
    if not outline.orientation_matters:
        return near
    return near & (np.abs(wrap_angle(goal[2] - poses[:, 2])) <= f * cfg.tolerance_theta)


def expand(cfg: PlannerConfig, outline: Outline, com: NDArray[np.float64],
           l: float, m: float,  # noqa: E741
           goal: NDArray[np.float64], aff: NDArray[np.float64], poses: NDArray[np.float64]
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """The best next push from each pose (B, 3) (``lookahead.Expand``): at the ``k``
    best-scoring outline points by the affordances, the 5 base directions, one rollout in
    substeps of ``lookahead.CONTINUATION_SUBSTEP``."""
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    dx, dy = goal[0] - poses[:, 0], goal[1] - poses[:, 1]
    desired = np.stack([c * dx + s * dy, -s * dx + c * dy,
                        wrap_angle(goal[2] - poses[:, 2]) if outline.orientation_matters
                        else np.zeros(len(poses))], -1)  # (B, 3) object frames
    lam = rotation_weight(cfg, outline)
    point = motion_score(desired[:, None, None, :] - aff[None], lam).min(axis=2)  # (B, N)
    k = min(cfg.k, point.shape[1])
    top = np.argpartition(point, k - 1, axis=1)[:, :k]  # (B, k)
    n_fine = len(_BASE_COLUMNS)
    idx = np.repeat(top.reshape(-1), n_fine)
    ang = np.tile(_FINE_ANGLES[_BASE_COLUMNS], top.size)
    start = np.repeat(poses, k * n_fine, axis=0)
    lengths, after, valid = _trajectories(cfg, outline, start, com, l, m, idx, ang,
                                          lookahead.CONTINUATION_SUBSTEP)
    score = _path_scores(cfg, outline, after, valid, goal)
    j = np.argmin(score, axis=1)
    rows = np.arange(len(idx))
    best, pose = score[rows, j].reshape(len(poses), -1), after[rows, j]
    pick = np.argmin(best, axis=1)
    chosen = np.arange(len(poses)) * k * n_fine + pick
    nxt = pose[chosen]
    return best[np.arange(len(poses)), pick], nxt, reached_ahead(cfg, outline, nxt, goal)


def pusher_points(cfg: PlannerConfig, outline: Outline, pose: NDArray[np.float64],
                  idx: NDArray[np.intp], angle: NDArray[np.float64], length: ArrayLike
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """World approach, contact (touching axis) and end points; shapes broadcast over
    ``idx``, ``angle`` (...) and ``length`` (...), each result (..., 2)."""
    n_out = outline.normals[idx]
    c, s = np.cos(angle), np.sin(angle)
    direction = -np.stack([c * n_out[..., 0] - s * n_out[..., 1],
                           s * n_out[..., 0] + c * n_out[..., 1]], -1)
    touch = outline.points[idx] + cfg.pusher_radius * n_out
    length = np.asarray(length, dtype=np.float64)[..., None]
    approach = object_to_world(pose, touch - cfg.approach_clearance * direction)
    contact = object_to_world(pose, touch)
    end = object_to_world(pose, touch + length * direction)
    return approach, contact, end


def _in_workspace(cfg: PlannerConfig, points: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Points (..., 2) inside ``cfg.workspace`` (world)."""
    (x0, x1), (y0, y1) = cfg.workspace
    x, y = points[..., 0], points[..., 1]
    return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)


def _approach_ok(cfg: PlannerConfig, outline: Outline, pose: NDArray[np.float64],
                 approach: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Approach points inside the workspace and clear of the object (B,)."""
    local = world_to_object(pose, approach)
    _, _, dist, _ = closest_point_on_polyline(outline.polyline, local)
    clear = dist >= cfg.pusher_radius + APPROACH_MARGIN + cfg.simplify_tolerance
    return clear & _in_workspace(cfg, approach)


def _rollouts(cfg: PlannerConfig, outline: Outline, pose: NDArray[np.float64],
              com: NDArray[np.float64], l: float, m: float,  # noqa: E741
              goal: NDArray[np.float64], idx: NDArray[np.intp],
              angle: NDArray[np.float64]) -> Options:
    """Roll out each (point, direction) to ``max_push_length`` and truncate at its best."""
    lengths, after, valid = _trajectories(cfg, outline, pose, com, l, m, idx, angle)
    score = _path_scores(cfg, outline, after, valid, goal)
    j = np.argmin(score, axis=1)
    rows = np.arange(len(idx))
    return Options(index=np.asarray(idx), angle=np.asarray(angle, dtype=np.float64),
                   length=lengths[j], score=score[rows, j], pose=after[rows, j])


def _trajectories(cfg: PlannerConfig, outline: Outline, pose: NDArray[np.float64],
                  com: NDArray[np.float64], l: float, m: float,  # noqa: E741
                  idx: NDArray[np.intp], angle: NDArray[np.float64],
                  substep: float | None = None
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """One batched rollout of pushes at outline points ``idx`` (B,) and directions
    ``angle`` (B,) from ``pose`` ((3,) or one per push, (B, 3)), to ``max_push_length``,
    in substeps of ``substep`` (m; None: ``cfg.substep``).

    Returns the push length after every substep (S,) (m past the contact), the predicted
    pose after every substep (B, S, 3) and whether stopping there is feasible (B, S):
    at least ``min_push_length``, end point in the workspace, approach clear.
    """
    approach, contact, _ = pusher_points(cfg, outline, pose, idx, angle, 0.0)
    direction = (contact - approach) / cfg.approach_clearance  # unit, world
    total = cfg.approach_clearance + cfg.max_push_length
    substep = cfg.substep if substep is None else substep
    res = rollout_push(outline.polyline, pose, com, l, m, approach, total * direction,
                       substep=substep, pusher_radius=cfg.pusher_radius,
                       two_faces=cfg.two_faces)
    n_sub = res.poses.shape[1] - 1
    travelled = np.minimum(substep * np.arange(1, n_sub + 1), total)  # (S,)
    lengths = travelled - cfg.approach_clearance
    ends = approach[:, None, :] + travelled[None, :, None] * direction[:, None, :]
    valid = ((lengths >= cfg.min_push_length - 1e-9)[None, :] & _in_workspace(cfg, ends)
             & _approach_ok(cfg, outline, pose, approach)[:, None])
    return lengths, res.poses[:, 1:], valid


def _path_scores(cfg: PlannerConfig, outline: Outline, after: NDArray[np.float64],
                 valid: NDArray[np.bool_], goal: NDArray[np.float64]) -> NDArray[np.float64]:
    """Eq. (5.1) of poses ``after`` (B, S, 3) against ``goal`` ((3,) or (B, 3)); inf where
    not ``valid``."""
    g = goal if goal.ndim == 1 else goal[:, None, :]
    residual = np.concatenate([g[..., :2] - after[..., :2], g[..., 2:] - after[..., 2:]], -1)
    score = motion_score(residual, rotation_weight(cfg, outline))
    return np.where(valid, score, np.inf)


def _direct(cfg: PlannerConfig, outline: Outline, pose: NDArray[np.float64],
            desired: NDArray[np.float64], aff: NDArray[np.float64],
            candidates: NDArray[np.intp]) -> Options:
    """Direct variant: affordances with the push length rescaled linearly (no rollouts)."""
    cols = np.array(_BASE_TO_REPR)
    m1 = aff[candidates][:, cols]  # (C, 5, 3) the 1 cm pushes
    m5 = aff[candidates][:, N_ANGLES + cols]  # the 5 cm pushes
    l1, l5 = REPRESENTATIVE_LENGTHS
    n_len = int(round((cfg.max_push_length - cfg.min_push_length) / DIRECT_LENGTH_STEP)) + 1
    grid = np.linspace(cfg.min_push_length, cfg.max_push_length, max(n_len, 1))  # (G,)
    t = ((grid - l1) / (l5 - l1))[None, None, :, None]
    motion = m1[:, :, None] + t * (m5 - m1)[:, :, None]  # (C, 5, G, 3)
    score = motion_score(desired - motion, rotation_weight(cfg, outline))
    n_c, n_a = len(candidates), len(cols)
    idx = np.repeat(candidates, n_a)
    ang = np.tile(np.radians(np.array(BASE_ANGLES_DEG)), n_c)
    approach, _, ends = pusher_points(cfg, outline, pose, idx[:, None], ang[:, None],
                                      grid[None, :])
    valid = _in_workspace(cfg, ends) & _approach_ok(cfg, outline, pose, approach[:, 0])[:, None]
    score = np.where(valid.reshape(n_c, n_a, -1), score, np.inf).reshape(n_c * n_a, -1)
    j = np.argmin(score, axis=1)
    rows = np.arange(n_c * n_a)
    best = motion.reshape(n_c * n_a, -1, 3)[rows, j]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    moved = np.stack([pose[0] + c * best[:, 0] - s * best[:, 1],
                      pose[1] + s * best[:, 0] + c * best[:, 1], pose[2] + best[:, 2]], -1)
    return Options(index=idx, angle=ang, length=grid[j], score=score[rows, j], pose=moved)


def _admitted(score: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Directions admitted after the base ones (:mod:`push_core.planner`, step 4d) for a flat batch
    of ``len(_FINE_ANGLES)`` directions per point: every base direction and the interpolated
    ones next to each point's best base direction."""
    n_fine = len(_FINE_ANGLES)
    score = score.reshape(-1, n_fine)
    best_base = _BASE_COLUMNS[np.argmin(score[:, _BASE_COLUMNS], axis=1)]
    col = np.arange(n_fine)
    admitted = (col % (INTERPOLATION_STEPS + 1) == 0)[None, :] | (
        np.abs(col[None, :] - best_base[:, None]) <= INTERPOLATION_STEPS)
    return admitted.reshape(-1)
