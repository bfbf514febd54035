"""Active push choice for the estimator: informative candidate pushes and the one to execute.

ROS-free and simulator-free (numpy in, numpy out; ``world`` frame, metres, radians). Used by
``pushbot eval estimator`` (:mod:`pushbot.experiments.estimator_episodes`, its ``active`` push
policy), the own-model consistency runs and ``benchmarks/bench_estimator.py``.

- :func:`informative_push`: a push at a random outline point toward the object's centre
  +-30 deg (``PUSH_ANGLE``), 2-4 cm (``PUSH_LENGTH``) after a 0.5-1.5 cm approach
  (``PUSH_GAP``).
- :func:`most_informative_push`: of several candidate pushes, the one the filter
  (:class:`push_core.estimator.PushEKF`) expects to shrink its COM covariance most.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from push_core.geometry import object_to_world, rot2

if TYPE_CHECKING:
    from push_core.estimator import PushEKF

__all__ = [
    "ACTIVE_CANDIDATES",
    "PUSH_ANGLE",
    "PUSH_GAP",
    "PUSH_LENGTH",
    "informative_push",
    "most_informative_push",
]

#: Informative pushes: direction toward the object's centre +-30 deg, length 2-4 cm, the pusher
#: lowered 0.5-1.5 cm before the outline.
PUSH_ANGLE = math.radians(30.0)
PUSH_LENGTH = (0.02, 0.04)
PUSH_GAP = (0.005, 0.015)
#: Candidates the active policy draws (valid :func:`informative_push` pushes) and chooses
#: among with :func:`most_informative_push`.
ACTIVE_CANDIDATES = 16


def informative_push(points: NDArray[np.float64], normals: NDArray[np.float64],
                     pose: NDArray[np.float64], rng: np.random.Generator,
                     pusher_radius: float = 0.0048,
                     towards: NDArray[np.float64] | None = None,
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """A push that tells the filter something: at a random outline point, toward the centre.

    Parameters
    ----------
    points, normals : numpy.ndarray, shape (N, 2)
        Outline points and outward unit normals, object frame (origin at the area centroid).
    pose : numpy.ndarray, shape (3,)
        Object pose ``(x, y, theta)`` in ``world`` the push is planned for.
    rng : numpy.random.Generator
    pusher_radius : float
        m.
    towards : numpy.ndarray, shape (2,), optional
        If given, only pushes whose direction (world) has a positive component along this
        vector are drawn (to bring the object back toward the workspace centre).

    Returns
    -------
    start, contact, end : numpy.ndarray, shape (2,)
        Pusher axis in ``world``: lowered at ``start`` (0.5-1.5 cm before the outline), expected
        to touch at ``contact``, stopping at ``end`` (2-4 cm after the touch). Collinear.
    """
    for _ in range(1000):
        i = rng.integers(len(points))
        centre_dir = -points[i] / max(float(np.hypot(*points[i])), 1e-9)
        d = rot2(rng.uniform(-PUSH_ANGLE, PUSH_ANGLE)) @ centre_dir
        if d @ normals[i] > -0.2:  # too grazing (or outward): push along the inward normal
            d = -normals[i]
        if towards is not None and (rot2(pose[2]) @ d) @ towards <= 0.0:
            continue
        gap, length = rng.uniform(*PUSH_GAP), rng.uniform(*PUSH_LENGTH)
        contact = points[i] + pusher_radius * normals[i]
        local = np.stack([contact - gap * d, contact, contact + length * d])
        start, contact_w, end = object_to_world(pose, local)
        return start, contact_w, end
    raise RuntimeError("no push satisfies the direction constraint")



def most_informative_push(ekf: PushEKF, pushes: Sequence[tuple[NDArray[np.float64], ...]]
                          ) -> int:
    """The push that is expected to tell the filter most about the centre of mass.

    Parameters
    ----------
    ekf : PushEKF
        The filter before the push (initialised).
    pushes : sequence of (start, contact, end)
        Candidate pushes, pusher axis in ``world`` (as :func:`informative_push` returns them).

    Returns
    -------
    int
        Index of the candidate whose expected posterior COM covariance
        (:meth:`PushEKF.expected_covariance`, the EKF's linearised forecast at its current
        estimate) has the smallest trace.
    """
    if not pushes:
        raise ValueError("pushes must not be empty")
    scores = [np.trace(ekf.expected_covariance(start, end)[3:5, 3:5])
              for start, _contact, end in pushes]
    return int(np.argmin(scores))

