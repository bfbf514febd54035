"""The object's orientation relative to the episode's first frame: the rotation search.

ROS-free (numpy, OpenCV through :meth:`push_perception.footprint.TopDownView.sample_sdf`); a
step of the mask-to-state pipeline (:mod:`push_perception.tracker`).

:func:`rotation_search` finds the rotation about the centroid that best aligns the current
outline with the first frame's, by a symmetric, truncated chamfer cost (:func:`chamfer_cost`:
mean distance of each outline's points to the other footprint's boundary, read bilinearly from
signed distance fields), searched on a coarse grid over the full circle and refined around
every candidate minimum by successive parabolic fits. Symmetric objects have several
(near-)equal minima: every refined minimum whose cost is within ``symmetry_tolerance`` of the
best is a candidate, and the one closest to the previous frame's angle is reported (the angle
is continuous, not wrapped).

Bounded work: at most ``MAX_REFINED_MINIMA`` (64) coarse minima are refined (the lowest; a
3 degree grid has at most 60).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_perception.footprint import TopDownView
from push_perception.perception_config import PerceptionConfig

__all__ = ["MAX_REFINED_MINIMA", "RotationResult", "chamfer_cost", "coarse_minima",
           "rotation_search"]

#: Most coarse minima of the rotation search that are refined (the lowest ones).
MAX_REFINED_MINIMA = 64


def _rot(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return np.cos(theta), np.sin(theta)


def chamfer_cost(theta: ArrayLike, ref: TopDownView, ref_points: NDArray[np.float64],
                 cur: TopDownView, cur_points: NDArray[np.float64],
                 truncation: float) -> NDArray[np.float64]:
    """Symmetric truncated chamfer cost of the hypothesis "the object turned by ``theta``
    (about its centroid) from the reference view to the current one", metres, for every
    angle in ``theta`` (T,).

    ``ref_points`` / ``cur_points`` (N, 2) are outline points of each view in ``world``. The
    cost is the mean of ``min(|sdf_ref(R(-theta)(p - c_cur) + c_ref)|, truncation)`` over the
    current points plus the same with the roles swapped (rotation by ``+theta``), halved.
    """
    th = np.atleast_1d(np.asarray(theta, dtype=np.float64))
    c, s = _rot(th)
    pc = cur_points - cur.centroid  # (N, 2)
    qr = ref_points - ref.centroid
    # Current points rotated back by -theta onto the reference; reference points by +theta.
    fwd = np.stack([c[:, None] * pc[:, 0] + s[:, None] * pc[:, 1],
                    -s[:, None] * pc[:, 0] + c[:, None] * pc[:, 1]], axis=-1) + ref.centroid
    bwd = np.stack([c[:, None] * qr[:, 0] - s[:, None] * qr[:, 1],
                    s[:, None] * qr[:, 0] + c[:, None] * qr[:, 1]], axis=-1) + cur.centroid
    d1 = np.minimum(np.abs(ref.sample_sdf(fwd, truncation)), truncation).mean(axis=1)
    d2 = np.minimum(np.abs(cur.sample_sdf(bwd, truncation)), truncation).mean(axis=1)
    return 0.5 * (d1 + d2)


@dataclass(frozen=True)
class RotationResult:
    """Outcome of :func:`rotation_search`.

    Attributes
    ----------
    theta : float
        Chosen rotation (current relative to reference), radians, continuous: within pi of
        the previous angle.
    cost : float
        Chamfer cost at ``theta``, metres.
    candidates : (K,) float
        All refined minima within the symmetry tolerance of the best, radians in (-pi, pi].
    """

    theta: float
    cost: float
    candidates: NDArray[np.float64]


def rotation_search(ref: TopDownView, ref_points: NDArray[np.float64], cur: TopDownView,
                    cur_points: NDArray[np.float64], previous: float,
                    cfg: PerceptionConfig) -> RotationResult:
    """Rotation of the current view relative to the reference (see the module docstring).

    Parameters
    ----------
    ref, cur : TopDownView
        Reference (first frame) and current views.
    ref_points, cur_points : (N, 2) float
        Outline points of each view in ``world``, metres.
    previous : float
        Angle reported for the previous frame, radians (0 for the second frame).
    cfg : PerceptionConfig

    Returns
    -------
    RotationResult
    """
    trunc = cfg.chamfer_truncation
    thetas, step = coarse_minima(ref, ref_points, cur, cur_points, cfg)
    thetas, costs = _refine(thetas, step, math.radians(cfg.angle_tolerance_deg),
                            ref, ref_points, cur, cur_points, trunc)
    best = costs.min()
    close = costs <= best + cfg.symmetry_tolerance
    cand = _wrap(thetas[close])
    # The candidate closest to the previous angle, reported continuously around it.
    deltas = _wrap(cand - previous)
    k = int(np.argmin(np.abs(deltas)))
    return RotationResult(theta=float(previous + deltas[k]), cost=float(costs[close][k]),
                          candidates=cand)


def coarse_minima(ref: TopDownView, ref_points: NDArray[np.float64], cur: TopDownView,
                  cur_points: NDArray[np.float64], cfg: PerceptionConfig
                  ) -> tuple[NDArray[np.float64], float]:
    """The promising local minima of the chamfer cost on the coarse grid (the first step of
    :func:`rotation_search`): angles (rad) within a generous margin of the best, and the
    grid step (rad)."""
    step = math.radians(cfg.coarse_step_deg)
    n = int(math.ceil(2 * math.pi / step))
    grid = -math.pi + np.arange(n) * (2 * math.pi / n)
    # Coarse search on every third point (6 mm apart at the default spacing: plenty).
    coarse = chamfer_cost(grid, ref, ref_points[::3], cur, cur_points[::3],
                          cfg.chamfer_truncation)
    left, right = np.roll(coarse, 1), np.roll(coarse, -1)
    minima = np.nonzero((coarse <= left) & (coarse <= right))[0]
    best_coarse = coarse[minima].min()
    margin = cfg.symmetry_tolerance + 0.5 * best_coarse
    promising = minima[coarse[minima] <= best_coarse + margin]
    if len(promising) > MAX_REFINED_MINIMA:  # bounded work (only with a very fine grid)
        promising = promising[np.argsort(coarse[promising], kind="stable")[:MAX_REFINED_MINIMA]]
    return grid[promising], 2 * math.pi / n


def _refine(thetas: NDArray[np.float64], step: float, tol: float, ref: TopDownView,
            ref_points: NDArray[np.float64], cur: TopDownView, cur_points: NDArray[np.float64],
            trunc: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Refine several local minima at once (one vectorised cost call per iteration).

    Each iteration evaluates every angle at ``theta + h (-1, -1/2, 0, 1/2, 1)``; if the lowest
    value is at an end the angle moves there (same ``h``), otherwise it moves to the vertex of
    the parabola through the lowest value and its two neighbours and ``h`` shrinks by 2.5,
    until ``h < tol``. The chamfer cost is not quadratic far from its minimum (it is closer
    to a V with a noise floor), hence the small steps. Returns the angles and their costs.
    """
    h = step
    offsets = np.linspace(-1.0, 1.0, 5)
    for _ in range(100):  # bounded: each end move covers h, each other iteration shrinks h
        if h < tol:
            break
        c = chamfer_cost((thetas[:, None] + h * offsets).ravel(), ref, ref_points, cur,
                         cur_points, trunc).reshape(-1, 5)
        j = np.argmin(c, axis=1)
        at_end = (j == 0) | (j == 4)
        jj = np.clip(j, 1, 3)
        rows = np.arange(len(j))
        c0, c1, c2 = c[rows, jj - 1], c[rows, jj], c[rows, jj + 1]
        denom = c0 - 2.0 * c1 + c2
        vertex = np.where(denom > 0, 0.5 * (c0 - c2) / np.where(denom > 0, denom, 1.0), 0.0)
        inner = offsets[jj] + 0.5 * np.clip(vertex, -1.0, 1.0)
        thetas = thetas + h * np.where(at_end, offsets[j], inner)
        if not np.any(at_end):
            h /= 2.5
    return thetas, chamfer_cost(thetas, ref, ref_points, cur, cur_points, trunc)


def _wrap(theta: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped to (-pi, pi]."""
    t = np.asarray(theta, dtype=np.float64)
    return np.pi - np.mod(np.pi - t, 2 * np.pi)
