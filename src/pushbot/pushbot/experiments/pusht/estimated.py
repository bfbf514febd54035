"""Push-T with the object unknown (``--object-model estimated``): the T perceived.

Nothing of the object comes from the env's physics (:mod:`pushbot.experiments.pusht.guard`
seals it): the outline and its normals from the first 96 x 96 image of the episode
(:func:`pushbot.experiments.pusht.vision.fit_outline`), the centre of mass, limit surface
``l`` and friction ``m`` estimated online by push_core's EKF from the pushes, starting from
the priors of the robot graph (:class:`push_core.estimator.EKFConfig` defaults, the
``push_estimator`` parameters: COM at the outline's centroid with the area's second moment as
covariance, ``l_0`` the uniform-pressure guess with 25 % standard deviation, ``m = 0.3 +-
0.15`` clipped to ``[0.05, 1.2]``).

Frames: the **perceived object frame** has its origin at the area centroid of the outline
perceived in the episode's first image and the env's axes at that moment (env units here,
metres in push_core: :data:`pushbot.experiments.pusht.world.METRES_PER_UNIT`). Its pose is
tracked from the image (``--obs pixels``: the outline fitted to each image) or follows from
the state's block pose (``--obs state``): the state reports the pose of an unknown reference
frame ``B`` on the block; the perceived frame's pose in ``B``, ``D = B_0^-1 P_0``, is fixed by
the first image and the first state (``P_0`` the perceived frame at the first image), so
``P_t = B_t D``; the goal likewise ``G D`` (the task gives ``G`` in the terms of the state).
From pixels the goal is the green goal region of the image, fitted with the perceived outline
(:func:`fit_goal`).

Diagnostics against the true T (never given to the planner or the filter): the outline error
(:func:`outline_error`) and the COM error in the perceived frame.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.shapes import Polygon
from push_core.transit import point_polygon_distance
from pushbot.experiments.pusht.vision import (
    AGENT_MARGIN,
    TeeFitter,
    colour_fractions,
    fit_outline,
)

__all__ = ["GOAL_DILATION", "SDF_CELL", "PerceivedTee", "agent_near", "compose", "fit_goal",
           "inverse", "outline_error", "perceive_tee", "tracker"]

#: Growth of the goal region as pygame fills a polygon (its edge pixels drawn), env units.
GOAL_DILATION = 0.5
#: Pixels whose block fraction exceeds this are left out of the goal fit (the block hides it).
GOAL_BLOCK_MAX = 0.02
#: Grid cell (env units) of the perceived outline's signed distance in the pose fits.
SDF_CELL = 0.75


def compose(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Pose ``a b`` (3,): the pose ``b`` given in frame ``a``, in ``a``'s parent frame."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


def inverse(a: ArrayLike) -> NDArray[np.float64]:
    """Pose ``a^-1`` (3,)."""
    a = np.asarray(a, dtype=np.float64)
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2]])


@dataclass(frozen=True)
class PerceivedTee:
    """The object as perceived in one image (env units, the env's axes).

    Attributes
    ----------
    outline : numpy.ndarray, shape (P, 2)
        Polygon in the perceived object frame (origin at its area centroid), counter-clockwise.
    pose : numpy.ndarray, shape (3,)
        Pose of the perceived object frame in the env at that image (centroid, angle 0).
    residual : float
        Mean absolute fraction residual of the outline fit.
    """

    outline: NDArray[np.float64]
    pose: NDArray[np.float64]
    residual: float


def perceive_tee(image: ArrayLike, agent: ArrayLike, agent_radius: float) -> PerceivedTee:
    """The object's outline from an image (96, 96, 3) and the agent position (env units):
    :func:`pushbot.experiments.pusht.vision.fit_outline`, re-centred on its area centroid."""
    poly, residual = fit_outline(image, agent, agent_radius)
    centre = Polygon(poly, field="outline").centroid  # raises for a self-intersecting fit
    return PerceivedTee(outline=poly - centre, pose=np.array([centre[0], centre[1], 0.0]),
                        residual=residual)


def tracker(outline: ArrayLike, agent_radius: float) -> TeeFitter:
    """The pose fitter of a perceived outline (P, 2) (env units): its signed distance on a
    grid of :data:`SDF_CELL` (:func:`pushbot.experiments.pusht.vision.sdf_grid`)."""
    return TeeFitter(outline, agent_radius=agent_radius, sdf_cell=SDF_CELL)


def fit_goal(image: ArrayLike, agent: ArrayLike, fitter: TeeFitter
             ) -> tuple[NDArray[np.float64], float]:
    """Pose (env units, rad) of the goal region drawn in the image, for the object frame of
    ``fitter``'s outline (:func:`tracker`), and the fit's mean absolute residual: the
    perceived outline fitted to the goal colour's fractions (grown by
    :data:`GOAL_DILATION`, not by the block's fat edges) over the pixels the block and the
    agent leave visible, searched over every orientation."""
    fitter = copy.copy(fitter)
    fitter.dilation = GOAL_DILATION
    block, goal = colour_fractions(image)
    usable = fitter.usable(agent) & (block <= GOAL_BLOCK_MAX)
    return fitter.fit_fraction(goal, usable, None)


def outline_error(outline: ArrayLike, truth: ArrayLike, samples: int = 600
                  ) -> tuple[float, float]:
    """Mean and largest distance (same unit) between two closed outlines (P, 2) and (Q, 2) in
    one frame: the mean over ``samples`` points evenly spaced along each of the distance to
    the other, and the symmetric Hausdorff distance of those points."""
    a, b = _dense(outline, samples), _dense(truth, samples)
    da = np.abs(point_polygon_distance(a, truth))
    db = np.abs(point_polygon_distance(b, outline))
    return float(0.5 * (da.mean() + db.mean())), float(max(da.max(), db.max()))


def _dense(poly: ArrayLike, n: int) -> NDArray[np.float64]:
    p = np.asarray(poly, dtype=np.float64)
    closed = np.vstack([p, p[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    q = np.linspace(0.0, s[-1], n, endpoint=False)
    return np.column_stack([np.interp(q, s, closed[:, 0]), np.interp(q, s, closed[:, 1])])


def agent_near(image: ArrayLike, agent: ArrayLike, agent_radius: float, size: int = 96
               ) -> NDArray[np.float64] | None:
    """If the agent disc hides or touches the block in the image, the unit direction (2,)
    from the block's pixels' centroid to the agent (the way to step back before the block is
    perceived); else None."""
    block, _ = colour_fractions(image)
    scale = 512.0 / size
    rows, cols = np.nonzero(block > 0.3)
    if len(rows) == 0:
        return None
    pts = np.column_stack([(cols + 0.5) * scale - 0.5, (rows + 0.5) * scale - 0.5])
    a = np.asarray(agent, dtype=np.float64)
    if np.min(np.linalg.norm(pts - a, axis=1)) > agent_radius + AGENT_MARGIN + 2.0 * scale:
        return None
    d = a - pts.mean(axis=0)
    return d / max(float(np.linalg.norm(d)), 1e-9)
