"""Pairing the estimator's two outputs into estimates, ROS-free.

The estimator publishes one estimate as two messages: the pose with its **stamp** and the full
state ``(x, y, theta, c_x, c_y, l, m)`` with its covariance, which carries no stamp. They travel
on two topics and may arrive in either order. An *estimate* is a pose together with the state
of the same pose: x, y equal to ``tol_xy`` (m) and theta to ``tol_theta`` (rad, modulo 2 pi).
The newest pose that has a matching state is taken; it and every older pose are then done. The
last ``kept`` poses and states are kept (bounded memory under any input).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import wrap_angle

__all__ = ["Estimate", "EstimatePairing"]


@dataclass(frozen=True)
class Estimate:
    """A paired estimate.

    Attributes
    ----------
    stamp : float
        The pose message's stamp, s.
    state : numpy.ndarray
        (7,) ``x, y, theta`` in ``world`` (m, rad), ``c_x, c_y`` (m, ``object`` frame),
        ``l`` (m), ``m``.
    covariance : numpy.ndarray
        (7, 7), the state's.
    """

    stamp: float
    state: NDArray[np.float64]
    covariance: NDArray[np.float64]


class EstimatePairing:
    """Pairs poses (stamp, x, y, theta) with states of the same pose (module docstring).

    Parameters
    ----------
    kept : int
        Poses and states kept while unpaired (>= 1).
    tol_xy : float
        Position tolerance, m.
    tol_theta : float
        Orientation tolerance, rad (modulo 2 pi).
    """

    def __init__(self, kept: int = 10, tol_xy: float = 1e-6, tol_theta: float = 1e-6) -> None:
        if int(kept) < 1:
            raise ValueError(f"kept: expected >= 1, got {kept!r}")
        self.tol_xy, self.tol_theta = float(tol_xy), float(tol_theta)
        #: Unpaired poses (stamp, (3,) pose), oldest first.
        self.poses: deque[tuple[float, NDArray[np.float64]]] = deque(maxlen=int(kept))
        #: States (state (7,), covariance (7, 7)), oldest first.
        self.states: deque[tuple[NDArray[np.float64], NDArray[np.float64]]] = deque(
            maxlen=int(kept))

    def clear(self) -> None:
        """Forget every pose and state (a new episode)."""
        self.poses.clear()
        self.states.clear()

    def add_pose(self, stamp: float, pose: ArrayLike) -> Estimate | None:
        """A pose ``(x, y, theta)`` (m, rad) stamped ``stamp`` (s); the estimate it completes,
        if any."""
        self.poses.append((float(stamp), np.asarray(pose, dtype=np.float64).reshape(3)))
        return self._pair()

    def add_state(self, state: ArrayLike, covariance: ArrayLike) -> Estimate | None:
        """A state (7,) with its (7, 7) covariance; the estimate it completes, if any."""
        self.states.append((np.asarray(state, dtype=np.float64).reshape(7),
                            np.asarray(covariance, dtype=np.float64)))
        return self._pair()

    def _pair(self) -> Estimate | None:
        """The newest pose with a state of the same pose; it and older poses are done."""
        for i in range(len(self.poses) - 1, -1, -1):
            stamp, pose = self.poses[i]
            for state, covariance in reversed(self.states):
                if (math.hypot(*(state[:2] - pose[:2])) <= self.tol_xy
                        and abs(float(wrap_angle(state[2] - pose[2]))) <= self.tol_theta):
                    for _ in range(i + 1):
                        self.poses.popleft()
                    return Estimate(stamp, state, covariance)
        return None
