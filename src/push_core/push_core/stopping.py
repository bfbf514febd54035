"""The planner's stop rule, ROS-free: is the goal reached, with confidence
(docs/design/stopping.md)?

:func:`goal_reached` compares a pose estimate and its covariance with the goal region; the
planner (:meth:`push_core.planner.Planner.reached`) and the episode engine stop on it.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np
from numpy.typing import ArrayLike

from push_core.scores import desired_motion

__all__ = ["STOP_CONFIDENCE", "goal_reached", "stop_quantile"]

#: Default confidence of the stop rule (:func:`goal_reached`): the goal counts as reached when
#: the true pose is inside the goal region with at least this probability along the worst
#: direction.
STOP_CONFIDENCE = 0.99


def goal_reached(pose: ArrayLike, goal: ArrayLike, tolerance_xy: float,
                 tolerance_theta: float, covariance: ArrayLike | None = None,
                 confidence: float = STOP_CONFIDENCE, orientation: bool = True) -> bool:
    """The stop rule: is the goal reached, with confidence (docs/design/stopping.md)?

    With no covariance this is the evaluation's "small" goal region (0.75 cm and 5 degrees by
    default; docs/design/evaluation.md) around the pose. With the
    estimator's covariance the region is shrunk by ``z`` standard deviations, ``z =
    Phi^-1(confidence)`` (2.33 at the default 0.99)::

        |p - p_goal| + z * sqrt(lambda_max(P_xy)) <= tolerance_xy   and
        |theta - theta_goal| + z * sigma_theta    <= tolerance_theta

    so that, for a Gaussian estimate, the true position lies beyond the tolerance along the
    worst direction with probability at most ``1 - confidence`` (likewise the orientation).
    ``orientation=False`` (the object's orientation cannot be observed,
    :func:`push_core.symmetry.has_continuous_symmetry`) drops the orientation condition.

    Parameters
    ----------
    pose, goal : array_like, shape (3,)
        Poses ``(x, y, theta)`` in ``world``.
    tolerance_xy : float
        Largest position error, metres (inclusive).
    tolerance_theta : float
        Largest orientation error, radians (inclusive; the error is wrapped).
    covariance : array_like, shape (3, 3) or (7, 7), optional
        Covariance of ``pose`` (m^2, rad^2; the estimator's 7 x 7 state covariance is
        accepted, its pose block is used). None or zeros: the point rule.
    confidence : float
        In ``[0.5, 1)``; 0.5 gives ``z = 0``, the point rule.
    orientation : bool
        Whether the orientation counts.

    Raises
    ------
    ValueError
        Naming ``covariance`` (wrong shape, non-finite) or ``confidence``.
    """
    d = desired_motion(pose, goal)
    xy, theta = math.hypot(d[0], d[1]), abs(float(d[2]))
    margin_xy = margin_theta = 0.0
    if covariance is not None:
        z = stop_quantile(confidence)
        cov = np.asarray(covariance, dtype=np.float64)
        if cov.shape not in ((3, 3), (7, 7)) or not np.all(np.isfinite(cov)):
            raise ValueError(f"covariance: expected a finite (3, 3) or (7, 7) matrix, got "
                             f"shape {cov.shape}")
        pxy = 0.5 * (cov[0:2, 0:2] + cov[0:2, 0:2].T)
        margin_xy = z * math.sqrt(max(float(np.linalg.eigvalsh(pxy)[-1]), 0.0))
        margin_theta = z * math.sqrt(max(float(cov[2, 2]), 0.0))
    ok_xy = xy + margin_xy <= tolerance_xy
    return bool(ok_xy and (not orientation or theta + margin_theta <= tolerance_theta))


def stop_quantile(confidence: float) -> float:
    """``z = Phi^-1(confidence)`` of the stop rule (:func:`goal_reached`); ``confidence`` in
    ``[0.5, 1)``."""
    c = float(confidence)
    if not 0.5 <= c < 1.0:
        raise ValueError(f"confidence: must be in [0.5, 1), got {confidence!r}")
    return float(NormalDist().inv_cdf(c))
