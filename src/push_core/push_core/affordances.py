"""Affordances: predicted object motion for every outline point x representative push.

docs/design/planner.md. An affordance model maps an outline (points with outward normals in
the object frame), the COM offset ``c`` and the pushing-model parameters ``l``, ``m`` to the
predicted motion of the object for each of the 10 representative pushes
(:func:`push_core.model.representative_pushes`: directions 0, +-30, +-60 degrees relative to the
inward normal, lengths 1 cm and 5 cm, length-major) at every point. Two interchangeable models
implement the :class:`AffordanceModel` protocol:
- :func:`analytical_affordances` (``ana``): the analytical model of :mod:`push_core.model`, one
  step, all points x pushes in one vectorised call;
- ``push_core.learned.LearnedAffordances`` (``lrn``): the CNN of :mod:`push_core.learned` (ignores
  ``l`` and ``m``).

Units and frames: metres and radians; everything in the object frame. The motion is that of the
object frame **origin** expressed in the object frame before the push, plus the rotation
(:func:`push_core.model.predict_motion`).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.model import (
    REPRESENTATIVE_ANGLES_DEG,
    REPRESENTATIVE_LENGTHS,
    predict_motion,
    representative_pushes,
)

__all__ = [
    "N_ANGLES",
    "N_PUSHES",
    "AffordanceModel",
    "analytical_affordances",
]

#: Number of base directions and of representative pushes (length-major: the first
#: ``N_ANGLES`` are 1 cm long, the last ``N_ANGLES`` 5 cm).
N_ANGLES = len(REPRESENTATIVE_ANGLES_DEG)
N_PUSHES = N_ANGLES * len(REPRESENTATIVE_LENGTHS)


class AffordanceModel(Protocol):
    """What the planner calls to get affordances (``ana`` or ``lrn``)."""

    def __call__(
        self,
        points: NDArray[np.float64],
        normals_out: NDArray[np.float64],
        com: NDArray[np.float64],
        l: float,  # noqa: E741 - the limit-surface symbol of Lynch et al.
        m: float,
    ) -> NDArray[np.float64]:
        """Predicted motion, shape (N, 10, 3); see :func:`analytical_affordances`."""
        ...


def analytical_affordances(
    points: ArrayLike,
    normals_out: ArrayLike,
    com: ArrayLike,
    l: float,  # noqa: E741 - the limit-surface symbol of Lynch et al.
    m: float,
) -> NDArray[np.float64]:
    """Analytical one-step affordances (``ana``) for every point x representative push.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Outline points, object frame (metres).
    normals_out : array_like, shape (N, 2)
        Outward unit normals at ``points``, object frame.
    com : array_like, shape (2,)
        COM offset in the object frame (metres).
    l, m : float
        Limit-surface parameter (metres) and pusher-object friction coefficient.

    Returns
    -------
    numpy.ndarray, shape (N, 10, 3)
        ``(dx, dy, dtheta)`` of the object frame origin in the object frame before the push
        (metres, radians) for push ``j`` of :func:`push_core.model.representative_pushes`
        (length-major: ``j = k * 5 + a`` has length ``(0.01, 0.05)[k]`` and direction
        ``(0, 30, -30, 60, -60)[a]`` degrees from the inward normal). The contact is assumed to
        hold for the whole push.
    """
    normals_out = np.asarray(normals_out, dtype=np.float64)
    pushes = representative_pushes(normals_out)
    return np.asarray(predict_motion(points, normals_out, pushes, com, l, m))
