"""A small extended Kalman filter base: the propagation and the Joseph-form update.

ROS-free, numpy only. The state is a ``(dim_x, 1)`` column ``x`` with covariance ``P``; the
attributes have the names of filterpy's ``ExtendedKalmanFilter`` (Labbe, *Kalman and Bayesian
Filters in Python*) so the equations read the same:

- predict (:meth:`EKFBase.predict`): the subclass's :meth:`~EKFBase.predict_x` sets the
  nonlinear prediction ``x = f(x, u)``, its Jacobian ``F`` and the process noise ``Q``; then
  ``P = F P F^T + Q``, symmetrised; ``x_prior`` and ``P_prior`` keep the result.
- update (:meth:`EKFBase.update_leading`): an observation of the first ``n`` state entries,
  ``H = [I_n 0]``, in Joseph form ``P = (I - K H) P (I - K H)^T + K R K^T`` multiplied out for
  this ``H`` (``S = P_nn + R``, ``K = P_:n S^-1``, ``x += K y``, ``P = P - K A^T - A K^T + K S
  K^T`` with ``A = P H^T = P[:, :n]``: no ``dim_x x dim_x`` identity products), symmetrised;
  the residual is :meth:`~EKFBase.residual` (override it for angles), the posterior is
  projected by :meth:`~EKFBase.constrain` (override it for bounded states); ``y``, ``S``,
  ``SI``, ``K``, ``z``, ``x_post`` and ``P_post`` record the update.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["EKFBase"]


class EKFBase:
    """Extended Kalman filter state and equations; see the module docstring.

    Parameters
    ----------
    dim_x : int
        State size.
    dim_z : int
        Observation size (the observation is of the first ``dim_z`` state entries at most).

    Attributes
    ----------
    x : numpy.ndarray, shape (dim_x, 1)
        State estimate (zeros).
    P : numpy.ndarray, shape (dim_x, dim_x)
        Its covariance (identity).
    F, Q : numpy.ndarray, shape (dim_x, dim_x)
        Jacobian of the last prediction and its process noise (identity until then).
    R : numpy.ndarray, shape (dim_z, dim_z)
        Default observation noise (identity).
    x_prior, P_prior : numpy.ndarray
        State and covariance after the last prediction.
    x_post, P_post : numpy.ndarray
        State and covariance after the last update.
    y, S, SI, K, z : numpy.ndarray
        Residual ``(n, 1)``, its covariance and inverse ``(n, n)``, gain ``(dim_x, n)`` and
        observation ``(dim_z, 1)`` of the last update (zeros until then).
    """

    def __init__(self, dim_x: int, dim_z: int) -> None:
        self.dim_x, self.dim_z = int(dim_x), int(dim_z)
        self.x = np.zeros((dim_x, 1))
        self.P = np.eye(dim_x)
        self.F = np.eye(dim_x)
        self.Q = np.eye(dim_x)
        self.R = np.eye(dim_z)
        self.y = np.zeros((dim_z, 1))
        self.z = np.zeros((dim_z, 1))
        self.S = np.zeros((dim_z, dim_z))
        self.SI = np.zeros((dim_z, dim_z))
        self.K = np.zeros((dim_x, dim_z))
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()
        self.x_post, self.P_post = self.x.copy(), self.P.copy()

    def predict_x(self, u: object = None) -> None:
        """Set ``x`` to the prediction ``f(x, u)``, ``F`` to its Jacobian and ``Q`` to the
        process noise; subclasses implement it."""
        raise NotImplementedError

    def predict(self, u: object = None) -> None:
        """:meth:`predict_x`, then ``P = F P F^T + Q`` (symmetrised); sets ``x_prior`` and
        ``P_prior``."""
        self.predict_x(u)
        p = np.dot(self.F, self.P).dot(self.F.T) + self.Q
        self.P = 0.5 * (p + p.T)
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()

    def residual(self, z: NDArray[np.float64], hx: NDArray[np.float64]) -> NDArray[np.float64]:
        """Observation minus predicted observation; subclasses override it for angles."""
        return np.asarray(z, dtype=np.float64) - np.asarray(hx, dtype=np.float64)

    def constrain(self) -> None:
        """Project the updated state onto its feasible set (in place); the default keeps it."""

    def update_leading(self, z: NDArray[np.float64], R: NDArray[np.float64],  # noqa: N803
                       n: int | None = None, y: NDArray[np.float64] | None = None,
                       S: NDArray[np.float64] | None = None,  # noqa: N803
                       SI: NDArray[np.float64] | None = None) -> None:  # noqa: N803
        """Joseph-form update with an observation of the first ``n`` state entries.

        Parameters
        ----------
        z : numpy.ndarray, shape (dim_z, 1)
            The observation (entries beyond ``n`` are not used).
        R : numpy.ndarray, shape (dim_z, dim_z) or larger
            Its covariance; the leading ``(n, n)`` block is used.
        n : int, optional
            Observed entries, ``1 <= n <= dim_z``; default ``dim_z``.
        y : numpy.ndarray, shape (>= n, 1), optional
            The residual, if the caller has it (default :meth:`residual` of ``z`` and the
            leading ``dim_z`` entries of ``x``); its first ``n`` rows are used.
        S, SI : numpy.ndarray, shape (n, n), optional
            ``P[:n, :n] + R[:n, :n]`` and its inverse for the current ``P``, if the caller has
            them (both or neither).
        """
        n = self.dim_z if n is None else n
        p = self.P
        if y is None:
            y = self.residual(z, self.x[0:self.dim_z])
        y = y[0:n]
        if S is None:
            S = p[0:n, 0:n] + R[0:n, 0:n]
            SI = np.linalg.inv(S)
        a = p[:, 0:n]
        k = a @ SI
        ka = k @ a.T
        p = p - ka - ka.T + k @ S @ k.T
        self.P = 0.5 * (p + p.T)
        self.x = self.x + k @ y
        self.S, self.SI, self.K, self.y, self.z = S, SI, k, y, z.copy()
        self.constrain()
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
