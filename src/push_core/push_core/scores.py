"""The planner's scores and contact selection (docs/design/planner.md), ROS-free.

Eq. (5.1) of the source scores a predicted motion against the desired one::

    s = ||v_d - v_hat||_mm  +  lambda * |omega_d - omega_hat|_deg

**Units: the translation error in millimetres, the rotation error in degrees; lambda in
millimetres per degree.** A score is "millimetres of remaining error", and so is the sampling
temperature. :func:`point_scores` gives every outline point its best score over the
affordances' pushes, :func:`sample_contacts` draws the contact candidates from the softmax over
them (Gumbel top-k) and :func:`geo_mask` is the ``geo`` baseline's rule. The planner
(:mod:`push_core.planner`) combines them; its names re-export these.

Frames: the desired motion and the affordances are in the object frame (origin = area
centroid), poses and goals in ``world``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import check_vector, wrap_angle

__all__ = [
    "GEO_LINE_BAND",
    "GEO_MIN_ROTATION",
    "GEO_MIN_TRANSLATION",
    "desired_motion",
    "geo_mask",
    "motion_score",
    "point_scores",
    "sample_contacts",
    "softmax_probabilities",
]

#: geo baseline: below this rotation (rad) points near the line to the goal are used ...
GEO_MIN_ROTATION = math.radians(2.0)
#: ... within this distance of it (m).
GEO_LINE_BAND = 0.02
#: geo baseline: below this translation (m) the goal is a pure rotation (no line to the goal).
GEO_MIN_TRANSLATION = 1e-3


def motion_score(residual: ArrayLike, lam: float) -> NDArray[np.float64]:
    """Eq. (5.1) of a residual motion: millimetres plus ``lam`` times degrees.

    Parameters
    ----------
    residual : array_like, shape (..., 3)
        ``(dx, dy, dtheta)``: remaining translation (metres, any frame) and rotation (radians;
        wrapped to (-pi, pi] here).
    lam : float
        Weight of the rotation error, millimetres per degree.

    Returns
    -------
    numpy.ndarray, shape (...)
        ``1000 * ||(dx, dy)|| + lam * |deg(wrap(dtheta))|``.
    """
    r = np.asarray(residual, dtype=np.float64)
    return 1e3 * np.hypot(r[..., 0], r[..., 1]) + lam * np.degrees(np.abs(wrap_angle(r[..., 2])))


def desired_motion(pose: ArrayLike, goal: ArrayLike) -> NDArray[np.float64]:
    """Desired motion ``(v_d, omega_d)`` from the current pose to the goal.

    Parameters
    ----------
    pose, goal : array_like, shape (3,)
        Current and goal pose ``(x, y, theta)`` of the object frame in ``world``.

    Returns
    -------
    numpy.ndarray, shape (3,)
        Translation of the object frame origin expressed in the current object frame (metres)
        and the rotation ``wrap(theta_goal - theta)`` in (-pi, pi] (radians), the frame of the
        affordances.
    """
    pose = check_vector(pose, 3, "pose")
    goal = check_vector(goal, 3, "goal")
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = goal[0] - pose[0], goal[1] - pose[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, float(wrap_angle(goal[2] - pose[2]))])


def point_scores(affordances: ArrayLike, desired: ArrayLike, lam: float) -> NDArray[np.float64]:
    """Eq. (5.1) for every outline point: the best residual over its pushes.

    Parameters
    ----------
    affordances : array_like, shape (N, M, 3)
        Predicted motion of each of M pushes at each of N points (object frame, metres, rad).
    desired : array_like, shape (3,)
        Desired motion, :func:`desired_motion`.
    lam : float
        Rotation weight, millimetres per degree.

    Returns
    -------
    numpy.ndarray, shape (N,)
        ``min_j motion_score(desired - affordances[:, j], lam)``.
    """
    aff = np.asarray(affordances, dtype=np.float64)
    if aff.ndim != 3 or aff.shape[2] != 3:
        raise ValueError(f"affordances must have shape (N, M, 3), got shape {aff.shape}")
    desired = check_vector(desired, 3, "desired")
    return motion_score(desired - aff, lam).min(axis=1)


def softmax_probabilities(scores: ArrayLike, temperature: float) -> NDArray[np.float64]:
    """Sampling distribution over outline points: lower score, more likely.

    Parameters
    ----------
    scores : array_like, shape (N,)
        Eq. (5.1) scores (millimetres); ``inf`` marks ineligible points (probability 0).
    temperature : float
        Softmax temperature in score units (millimetres), > 0.

    Returns
    -------
    numpy.ndarray, shape (N,)
        ``exp(-(s_i - min s) / T)`` normalised to sum 1.
    """
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim != 1 or s.size == 0:
        raise ValueError(f"scores must have shape (N,) with N >= 1, got shape {s.shape}")
    if not temperature > 0.0:
        raise ValueError(f"temperature must be > 0, got {temperature}")
    best = np.min(s)
    if not np.isfinite(best):
        raise ValueError("scores: no finite score")
    w = np.exp(-(s - best) / temperature)
    return w / w.sum()


def sample_contacts(scores: ArrayLike, k: int, temperature: float,
                    rng: np.random.Generator) -> NDArray[np.intp]:
    """Sample ``k`` distinct outline points from :func:`softmax_probabilities`.

    Gumbel top-k: the ``k`` largest ``-s_i / T + g_i`` with ``g_i`` standard Gumbel, which is
    sequential sampling without replacement from the softmax (for ``k = 1`` exactly the
    softmax). Points with ``inf`` scores are never drawn.

    Parameters
    ----------
    scores : array_like, shape (N,)
        Eq. (5.1) scores (millimetres).
    k : int
        Number of points, >= 1; at most the number of finite scores are returned.
    temperature : float
        Softmax temperature, millimetres, > 0.
    rng : numpy.random.Generator
        Source of randomness.

    Returns
    -------
    numpy.ndarray of intp, shape (min(k, n_finite),)
        Indices into ``scores``, in the order drawn.
    """
    s = np.asarray(scores, dtype=np.float64)
    softmax_probabilities(s, temperature)  # validates
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    keys = -(s - np.min(s)) / temperature + rng.gumbel(size=s.shape)
    keys[~np.isfinite(s)] = -np.inf
    n = min(int(k), int(np.count_nonzero(np.isfinite(s))))
    order = np.argsort(-keys, kind="stable")
    return order[:n]


def geo_mask(points: ArrayLike, normals_out: ArrayLike, desired: ArrayLike) -> NDArray[np.bool_]:
    """The ``geo`` baseline's eligible contact points (docs/design/planner.md).

    With ``u`` the unit direction of the desired translation (object frame) and ``d_i`` the
    signed distance of point ``i`` from the line through the current position along ``u``
    (positive to the left):

    - "far side": ``points . u < 0`` (the pusher pushes the object towards the goal);
    - rotation ``|omega_d| < 2 deg``: ``|d_i| <= 2 cm`` (pushes near the line keep orientation);
    - otherwise the side of the line that turns the object the right way: a push along ``u`` at
      a point left of the line turns it clockwise, so ``d_i * omega_d < 0``.

    A pure rotation (translation below 1 mm, no line to the goal) takes the points where a push
    along the inward normal has a torque about the object frame origin of the sign of
    ``omega_d`` (this case is not specified by the source).

    Parameters
    ----------
    points, normals_out : array_like, shape (N, 2)
        Outline points and outward normals, object frame.
    desired : array_like, shape (3,)
        Desired motion (:func:`desired_motion`), object frame.

    Returns
    -------
    numpy.ndarray of bool, shape (N,)
    """
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals_out, dtype=np.float64)
    desired = check_vector(desired, 3, "desired")
    dist = math.hypot(desired[0], desired[1])
    omega = desired[2]
    if dist < GEO_MIN_TRANSLATION:
        torque = p[:, 0] * -n[:, 1] - p[:, 1] * -n[:, 0]  # r x n_in
        return torque * omega > 0.0
    u = desired[:2] / dist
    far = p @ u < 0.0
    side = u[0] * p[:, 1] - u[1] * p[:, 0]
    if abs(omega) < GEO_MIN_ROTATION:
        return far & (np.abs(side) <= GEO_LINE_BAND)
    return far & (side * omega < 0.0)
