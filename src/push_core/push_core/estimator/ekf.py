"""The push EKF: pose, centre of mass, limit surface and friction from pushes and poses.

docs/design/estimator.md. ROS-free: numpy in, numpy out. :class:`PushEKF` is an
:class:`~push_core.estimator.kalman.EKFBase` over the state of :mod:`push_core.estimator.config`;
its prediction is the process model :func:`push_core.estimator.process_model.predict_push` on the
perceived outline (:class:`push_core.estimator.contact.ContactOutline`) with the per-push process
noise :meth:`EKFConfig.process_noise`.

Observation model: identity on ``(x, y, theta)``. The innovation's angle is wrapped, and for an
object with ``symmetry_order`` k (its outline looks the same after a rotation by 2 pi / k) it is
taken modulo 2 pi / k, i.e. the observed orientation closest to the prediction among the k
equivalent ones. ``symmetry_order`` = 1 means no symmetry; 0 means "detect it from the outline"
(:func:`push_core.symmetry.symmetry_order_of_polygon`, rotations that map the outline onto
itself within ``symmetry_tolerance``). An observation whose orientation variance says "not
observed" (:func:`push_core.symmetry.orientation_observed`: a continuously symmetric outline
such as a disc) updates only ``(x, y)``; the orientation then follows the process model from
yaw 0 at the first frame. The update is the Joseph form for ``H = [I_3 0]`` (or ``[I_2 0]``)
written out (:meth:`push_core.estimator.kalman.EKFBase.update_leading`), then symmetrised; ``l`` and
``m`` are clipped to physical ranges (``l`` in ``[l_min_fraction * l_0, r_max]`` with ``l_0``
the uniform-pressure guess and ``r_max`` the largest distance of the outline from its centroid,
``m`` in ``m_range``) and ``c`` to the convex hull of the outline (a rigid object's COM lies
inside it; :meth:`ContactOutline.clip_to_hull`).

Iterated update (``EKFConfig.iterations``, default 2): the model is strongly nonlinear in
``c`` and ``l``, and the first pushes are linearised at the prior (``c = 0``). After the
update, the push is linearised again at the smoothed pre-push state (one Rauch-Tung-Striebel /
Gauss-Newton step, :meth:`PushEKF._iterate`) and the update is redone from the pre-push
estimate: an iterated EKF for the process nonlinearity. It doubles the cost of a push (two
model evaluations with Jacobian and two updates). Costs and the NEES / COM error with 1 and 2
iterations on the filter's own model: ``docs/results/bench_estimator.md``; on
pybullet physics the default is section ``eval_estimator`` and ``pushbot eval estimator
--iterations 1`` runs the plain EKF for comparison.

Initialisation: the pose from the first observation (covariance R), ``c = 0`` with covariance
``com_prior_fraction^2`` times the second moment matrix of the outline's area (the COM anywhere
in the object, uniformly), ``l = l_0`` computed from the outline polygon itself
(:func:`push_core.estimator.contact.limit_surface_of_polygon`, mean distance of the area from the
centroid, exact; standard deviation 25 %), ``m = m_init`` (a guess: 0.3, between the
steel-on-steel pusher of the source and the 0.15-0.5 range of the simulator, standard deviation
0.15).

Gating: an innovation whose squared Mahalanobis distance exceeds the chi-square quantile
``gate_probability`` (3 degrees of freedom) re-initialises the pose from the observation
(covariance R, no correlation with the parameters) and keeps ``c``, ``l``, ``m`` and their
covariance; :class:`UpdateResult` reports it (``reinitialized``).

Re-learning (``EKFConfig.relearn``): a gate failure on the first observation after
a push, or NIS values of the last ``relearn_window`` observations after pushes that together
exceed the chi-square quantile ``relearn_probability`` (``3 x window`` degrees of freedom),
mean the pushes' observed motion contradicts the model's prediction, most likely
because ``c``, ``l`` or ``m`` are wrong (keeping them, the planner plans with the very
parameters that are wrong and the gate fires again). The filter then returns to the pre-push
state, restarts the parameters' covariance at the prior (:meth:`PushEKF.initial_state`; means
kept, correlations with the pose dropped), predicts the push again and gates the observation
again: if it passes it is fused (the contradiction now moves the parameters), otherwise the
pose is re-initialised as above, with the parameters left at the prior covariance so the next
pushes re-learn them. :class:`UpdateResult` reports it (``relearned``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

from push_core.estimator.config import STATE_SIZE, EKFConfig, finite_vector
from push_core.estimator.contact import ContactOutline
from push_core.estimator.kalman import EKFBase
from push_core.estimator.process_model import PushPrediction, _predict_push
from push_core.symmetry import orientation_observed

__all__ = ["PushEKF", "UpdateResult"]


@dataclass(frozen=True)
class UpdateResult:
    """What :meth:`PushEKF.update_pose` did with one observation.

    Attributes
    ----------
    innovation : numpy.ndarray, shape (3,)
        Observation minus prediction (m, m, rad), the angle wrapped modulo the symmetry period.
    nis : float
        Normalised innovation squared ``y^T S^-1 y`` (chi-square, 3 dof, if consistent).
    reinitialized : bool
        True if the observation failed the gate and re-initialised the pose.
    initialized : bool
        True if this observation initialised the filter (the first one after a reset).
    orientation_observed : bool
        False if the observation carried no orientation (its variance was at or above
        ``push_core.symmetry.UNOBSERVED_THRESHOLD``): only the position was fused, ``nis``
        has 2 degrees of freedom and the innovation's angle is 0.
    relearned : bool
        True if the observation contradicted the last push's prediction and ``c``, ``l``,
        ``m`` were restarted at their prior covariance (``EKFConfig.relearn``); ``nis`` is
        then the first (failed) test and ``reinitialized`` says whether the second failed too.
    """

    innovation: NDArray[np.float64]
    nis: float
    reinitialized: bool = False
    initialized: bool = False
    orientation_observed: bool = True
    relearned: bool = False


class PushEKF(EKFBase):
    """EKF over ``(x, y, theta, c_x, c_y, l, m)``; see the module docstring.

    An :class:`~push_core.estimator.kalman.EKFBase` whose prediction is the pushing model:
    ``predict(u=(pusher_start, pusher_end))`` (or :meth:`predict_push`) sets ``F`` to the
    closed-form Jacobian and ``Q`` to the push's process noise, then the base propagates
    ``P = F P F^T + Q``. The update is the base's Joseph form for ``H = [I_n 0]`` with the
    symmetry-aware angle residual, Mahalanobis gating and clipping around it. ``x`` is a (7, 1)
    column; :attr:`state` and :attr:`covariance` are flat copies.

    Parameters
    ----------
    outline_points : array_like, shape (N, 2)
        Perceived outline, object frame, counter-clockwise (see
        :meth:`ContactOutline.from_points`).
    outline_normals : array_like, shape (N, 2), optional
        Outward unit normals at the points (checked only).
    config : EKFConfig, optional

    Raises
    ------
    ValueError
        For a bad outline (naming ``points`` or ``normals``) or config.
    """

    def __init__(self, outline_points: ArrayLike, outline_normals: ArrayLike | None = None,
                 config: EKFConfig | None = None) -> None:
        cfg = EKFConfig() if config is None else config
        if not isinstance(cfg, EKFConfig):
            raise ValueError(f"config must be an EKFConfig, got {type(cfg).__name__}")
        self.config = cfg
        self.outline = ContactOutline.from_points(
            outline_points, outline_normals, tolerance=cfg.outline_tolerance,
            symmetry_order=cfg.symmetry_order, symmetry_tolerance=cfg.symmetry_tolerance)
        super().__init__(dim_x=STATE_SIZE, dim_z=3)
        self.R = cfg.observation_noise
        self._gate = cfg.gate_threshold
        self._gate_position = (float(chi2.ppf(cfg.gate_probability, 2))
                               if cfg.gate_probability < 1.0 else math.inf)
        l0 = self.outline.limit_surface
        self.l_bounds = (cfg.l_min_fraction * l0, max(self.outline.radius, l0))
        self.m_bounds = cfg.m_range
        if cfg.known_l is not None:
            self.l_bounds = (cfg.known_l, cfg.known_l)
        if cfg.known_m is not None:
            self.m_bounds = (cfg.known_m, cfg.known_m)
        self.period = 2.0 * math.pi / self.outline.symmetry_order
        self.initialized = False
        self.last_prediction: PushPrediction | None = None
        #: (state, covariance, pusher_start, pusher_end) before the last push, for iterating.
        self._before_push: tuple | None = None
        #: NIS of the recent observations after pushes (the windowed test of ``relearn``).
        self._nis_window: list[float] = []
        self._relearn_threshold = float(chi2.ppf(cfg.relearn_probability,
                                                  3 * cfg.relearn_window))

    # ---- state access ------------------------------------------------------------------------
    @property
    def state(self) -> NDArray[np.float64]:
        """The state ``(x, y, theta, c_x, c_y, l, m)`` (7,), a copy."""
        return self.x[:, 0].copy()

    @property
    def covariance(self) -> NDArray[np.float64]:
        """The covariance (7, 7), a copy."""
        return self.P.copy()

    def initial_state(self, pose: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Prior mean (7,) and covariance (7, 7) for a first observed pose (pose block only
        without its covariance, which the caller sets)."""
        cfg = self.config
        l0 = self.outline.limit_surface
        z = finite_vector("pose", pose, 3)
        mean = np.array([z[0], z[1], z[2], 0.0, 0.0, l0, cfg.m_init])
        cov = np.diag([0.0, 0.0, 0.0, 0.0, 0.0, (cfg.l_sigma_fraction * l0) ** 2,
                       cfg.m_sigma**2])
        cov[3:5, 3:5] = cfg.com_prior_fraction**2 * self.outline.area_moment
        if cfg.known_com is not None:  # known parameters: exact, never updated
            mean[3:5] = cfg.known_com
            cov[3:5, 3:5] = 0.0
        if cfg.known_l is not None:
            mean[5], cov[5, 5] = cfg.known_l, 0.0
        if cfg.known_m is not None:
            mean[6], cov[6, 6] = cfg.known_m, 0.0
        return mean, cov

    # ---- episode -----------------------------------------------------------------------------
    def initialize(self, pose: ArrayLike, R: ArrayLike | None = None) -> None:  # noqa: N803
        """Start an episode: pose from an observation, ``c = 0``, ``l = l_0``, ``m = m_init``.

        Parameters
        ----------
        pose : array_like, shape (3,)
            Observed ``(x, y, theta)`` in ``world`` (m, m, rad).
        R : array_like, shape (3, 3), optional
            Its covariance; default ``config.observation_noise``.
        """
        r = self._observation_noise(R)
        mean, cov = self.initial_state(pose)
        cov[0:3, 0:3] = r
        self.x = mean[:, None]
        self.P = cov
        self.initialized = True
        self.last_prediction = None
        self._before_push = None
        self._nis_window = []

    def snapshot(self) -> tuple:
        """The filter's state at this point, for :meth:`restore` (re-filtering late inputs)."""
        return (self.x.copy(), self.P.copy(), self.initialized, self._before_push,
                self.last_prediction, list(self._nis_window))

    def restore(self, snapshot: tuple) -> None:
        """Return to a :meth:`snapshot` of this filter."""
        x, p, self.initialized, self._before_push, self.last_prediction, window = snapshot
        self.x, self.P = x.copy(), p.copy()
        self._nis_window = list(window)

    def reset(self) -> None:
        """Forget the episode; the next observation initialises the filter again."""
        self.x = np.zeros((STATE_SIZE, 1))
        self.P = np.eye(STATE_SIZE)
        self.initialized = False
        self.last_prediction = None
        self._before_push = None
        self._nis_window = []

    # ---- prediction --------------------------------------------------------------------------
    def predict_push(self, pusher_start: ArrayLike, pusher_end: ArrayLike) -> PushPrediction:
        """Predict through one executed push (:meth:`predict` with ``u`` = the push).

        Parameters
        ----------
        pusher_start, pusher_end : array_like, shape (2,)
            Pusher axis in ``world`` at the start and end of the straight push, metres.

        Returns
        -------
        PushPrediction

        Raises
        ------
        RuntimeError
            Before the first observation (:meth:`initialize`).
        ValueError
            Naming the argument, for malformed points.
        """
        self.predict(u=(pusher_start, pusher_end))
        assert self.last_prediction is not None
        return self.last_prediction

    def expected_covariance(self, pusher_start: ArrayLike, pusher_end: ArrayLike,
                            R: ArrayLike | None = None) -> NDArray[np.float64]:  # noqa: N803
        """Covariance after a *hypothetical* push and one pose observation; the filter is
        unchanged.

        The EKF's own forecast, linearised at the current estimate: ``P_pred = F P F^T + Q``
        for the push, then the update's ``P_pred - P_pred H^T (H P_pred H^T + R)^-1 H P_pred``
        (it does not depend on the observed value). Used to choose informative pushes (the
        push that shrinks the parameters' covariance most); a push the model says will not
        touch the object only adds process noise.

        Parameters
        ----------
        pusher_start, pusher_end : array_like, shape (2,)
            Pusher axis in ``world`` at the start and end of the straight push, metres.
        R : array_like, shape (3, 3), optional
            Observation covariance; default ``config.observation_noise``.

        Returns
        -------
        numpy.ndarray, shape (7, 7)

        Raises
        ------
        RuntimeError
            Before the first observation.
        """
        if not self.initialized:
            raise RuntimeError("expected_covariance before the first observation: call "
                               "initialize() first")
        start = finite_vector("pusher_start", pusher_start, 2)
        end = finite_vector("pusher_end", pusher_end, 2)
        r = self._observation_noise(R)
        pred = self._predict(self.x[:, 0], start, end)
        f = pred.jacobian
        p = f @ self.P @ f.T + self.config.process_noise(pred.contact_length)
        a = p[:, 0:3]
        p = p - a @ np.linalg.solve(p[0:3, 0:3] + r, a.T)
        return 0.5 * (p + p.T)

    def predict_x(self, u: object = None) -> None:
        """The nonlinear prediction through the push ``u = (pusher_start, pusher_end)``; also
        sets ``F`` and ``Q`` for :meth:`predict`."""
        if not self.initialized:
            raise RuntimeError("predict before the first observation: call initialize() first")
        if not (isinstance(u, tuple | list) and len(u) == 2):
            raise ValueError("u must be the push (pusher_start, pusher_end), two (2,) points in "
                             "world, metres")
        start = finite_vector("pusher_start", u[0], 2)
        end = finite_vector("pusher_end", u[1], 2)
        self._before_push = (self.x[:, 0].copy(), self.P.copy(), start, end)
        pred = self._predict(self.x[:, 0], start, end)
        self.x = pred.state[:, None]
        self.F = pred.jacobian
        self.Q = self.config.process_noise(pred.contact_length)
        self.last_prediction = pred

    def _predict(self, state: NDArray[np.float64], start: NDArray[np.float64],
                 end: NDArray[np.float64]) -> PushPrediction:
        cfg = self.config
        return _predict_push(state, self.outline, start, end, cfg.pusher_radius, cfg.substep,
                             cfg.contact_tol, True, cfg.max_substeps)

    # ---- update ------------------------------------------------------------------------------
    def residual(self, z: NDArray[np.float64], hx: NDArray[np.float64]) -> NDArray[np.float64]:
        """``z - hx`` with the angle taken modulo the symmetry period, closest to zero.

        Parameters
        ----------
        z, hx : numpy.ndarray, shape (3, 1) or (3,)
            Observation and predicted observation (m, m, rad).
        """
        y = np.asarray(z, dtype=np.float64) - np.asarray(hx, dtype=np.float64)
        period = self.period
        y[2] = y[2] - period * np.round(y[2] / period)
        return y

    def update_pose(self, pose: ArrayLike, R: ArrayLike | None = None) -> UpdateResult:  # noqa: N803
        """Fuse one observed pose; initialise the filter if it is the first.

        An orientation variance ``R[2, 2] >= push_core.symmetry.UNOBSERVED_THRESHOLD`` means
        the orientation was not observed (a continuously symmetric outline,
        :mod:`push_core.symmetry`): only ``(x, y)`` are fused (gate with 2 degrees of
        freedom), and a first observation starts the orientation at its value (yaw 0 of the
        episode frame, by definition) with the configured orientation noise.

        Parameters
        ----------
        pose : array_like, shape (3,)
            Observed ``(x, y, theta)`` of the object frame in ``world`` (m, m, rad; any angle
            range).
        R : array_like, shape (3, 3), optional
            Its covariance (symmetric positive definite); default ``config.observation_noise``.

        Returns
        -------
        UpdateResult

        Raises
        ------
        ValueError
            Naming ``pose`` or ``R``: wrong shape, non-finite values, R not symmetric positive
            definite.
        """
        z = finite_vector("pose", pose, 3)
        r = self._observation_noise(R)
        observed = orientation_observed(r[2, 2])
        if not observed:
            r = r.copy()
            r[2, :2] = r[:2, 2] = 0.0
            if not self.initialized:
                r[2, 2] = self.config.observation_noise[2, 2]
        n = 3 if observed else 2
        if not self.initialized:
            self.initialize(z, r)
            return UpdateResult(innovation=np.zeros(3), nis=0.0, initialized=True,
                                orientation_observed=observed)
        zc = z[:, None]
        y = self.residual(zc, self.x[0:3])
        if not observed:
            y[2] = 0.0
        s = self.P[0:n, 0:n] + r[0:n, 0:n]
        si = np.linalg.inv(s)
        nis = float(y[0:n, 0] @ si @ y[0:n, 0])
        gate = self._gate if observed else self._gate_position
        relearned = False
        if self.config.relearn and self._before_push is not None and self._contradicted(nis, n):
            relearned = True
            self._restart_parameters()
            y = self.residual(zc, self.x[0:3])
            if not observed:
                y[2] = 0.0
            s = self.P[0:n, 0:n] + r[0:n, 0:n]
            si = np.linalg.inv(s)
            if float(y[0:n, 0] @ si @ y[0:n, 0]) <= gate:
                innovation = y[:, 0].copy()
                self._update(zc, r, y, s, si, n)
                for _ in range(self.config.iterations - 1):
                    self._iterate(zc, r, n)
                self._before_push = None
                return UpdateResult(innovation=innovation, nis=nis, orientation_observed=observed,
                                    relearned=True)
        if nis > gate:
            if observed:
                self._reinitialize_pose(self.x[0:3, 0] + y[:, 0], r)
            else:
                self._reinitialize_position(z[:2], r[:2, :2])
            self._before_push = None
            return UpdateResult(innovation=y[:, 0].copy(), nis=nis, reinitialized=True,
                                orientation_observed=observed, relearned=relearned)
        innovation = y[:, 0].copy()
        self._update(zc, r, y, s, si, n)
        if self._before_push is not None:
            for _ in range(self.config.iterations - 1):
                self._iterate(zc, r, n)
        self._before_push = None
        return UpdateResult(innovation=innovation, nis=nis, orientation_observed=observed)

    def _update(self, zc: NDArray[np.float64], r: NDArray[np.float64],
                y: NDArray[np.float64] | None = None, s: NDArray[np.float64] | None = None,
                si: NDArray[np.float64] | None = None, n: int = 3) -> None:
        """The Joseph-form update for ``H = [I_n 0]`` (:meth:`EKFBase.update_leading`): the
        pose, ``n = 3``, or only the position, ``n = 2``, when the orientation is not observed;
        with :meth:`residual`, symmetrised, then :meth:`constrain` clips the parameters.
        ``y``, ``s`` and ``si`` may be passed when the caller has them for this ``P``.
        """
        self.update_leading(zc, r, n, y, s, si)

    def _iterate(self, zc: NDArray[np.float64], r: NDArray[np.float64], n: int = 3) -> None:
        """One more Gauss-Newton step over the last push: re-linearise, predict, update.

        The linearisation point is the smoothed pre-push state (Rauch-Tung-Striebel step with
        the current linearisation ``F``), ``x_lin = x_prev + P_prev F^T P_prior^-1 (x_post -
        x_prior)``; the prediction is ``f(x_lin) + F(x_lin) (x_prev - x_lin)`` with covariance
        ``F P_prev F^T + Q``. c, l and m do not change in a push, so their posterior is also
        the best point to linearise the push at. ``n`` as in :meth:`_update`.
        """
        x_prev, p_prev, start, end = self._before_push
        cfg = self.config
        if cfg.known_com is None and cfg.known_l is None and cfg.known_m is None:
            gain = np.linalg.solve(self.P_prior, self.F @ p_prev).T  # P_prev F^T P_prior^-1
        else:  # known parameters have zero variance: P_prior is singular, use its pseudo-inverse
            gain = (np.linalg.pinv(self.P_prior, hermitian=True) @ (self.F @ p_prev)).T
        x_lin = x_prev + gain @ (self.x[:, 0] - self.x_prior[:, 0])
        x_lin[5] = min(max(x_lin[5], self.l_bounds[0]), self.l_bounds[1])
        x_lin[6] = min(max(x_lin[6], self.m_bounds[0]), self.m_bounds[1])
        pred = self._predict(x_lin, start, end)
        self.F = pred.jacobian
        self.Q = self.config.process_noise(pred.contact_length)
        self.x = (pred.state + self.F @ (x_prev - x_lin))[:, None]
        self.P = self.F @ p_prev @ self.F.T + self.Q
        self.P = 0.5 * (self.P + self.P.T)
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()
        self.last_prediction = pred
        y = self.residual(zc, self.x[0:3])
        if n < 3:
            y[2] = 0.0
        self._update(zc, r, y, n=n)

    def _contradicted(self, nis: float, n: int) -> bool:
        """The tests of ``relearn`` for the observation after a push (module docstring); the
        window restarts after a contradiction."""
        window = self._nis_window
        window.append(nis * 3.0 / n)  # a position-only observation scaled to 3 dof
        del window[:-self.config.relearn_window]
        gate = self._gate if n == 3 else self._gate_position
        if nis > gate or (len(window) == self.config.relearn_window
                          and sum(window) > self._relearn_threshold):
            window.clear()
            return True
        return False

    def _restart_parameters(self) -> None:
        """Back to the state before the last push with the covariance of ``c``, ``l``, ``m``
        restarted at the prior (means kept, uncorrelated with the pose); predict the push
        again (module docstring, "Re-learning")."""
        x_prev, p_prev, start, end = self._before_push
        _, prior = self.initial_state(x_prev[0:3])
        p = p_prev.copy()
        p[3:, :] = 0.0
        p[:, 3:] = 0.0
        p[3:, 3:] = prior[3:, 3:]
        self.x, self.P = x_prev[:, None].copy(), p
        self.predict(u=(start, end))

    def _reinitialize_pose(self, pose: NDArray[np.float64], r: NDArray[np.float64]) -> None:
        """Pose from the observation (angle continuous), covariance R, uncorrelated."""
        self.x[0:3, 0] = pose
        self.P[0:3, :] = 0.0
        self.P[:, 0:3] = 0.0
        self.P[0:3, 0:3] = r

    def _reinitialize_position(self, xy: NDArray[np.float64], r: NDArray[np.float64]) -> None:
        """Position from the observation, covariance R, uncorrelated; orientation kept."""
        self.x[0:2, 0] = xy
        self.P[0:2, :] = 0.0
        self.P[:, 0:2] = 0.0
        self.P[0:2, 0:2] = r

    def constrain(self) -> None:
        """Clip ``l`` and ``m`` to their physical ranges and ``c`` to the outline's convex hull
        (:meth:`ContactOutline.clip_to_hull`), in place."""
        x = self.x[:, 0]
        x[5] = min(max(x[5], self.l_bounds[0]), self.l_bounds[1])
        x[6] = min(max(x[6], self.m_bounds[0]), self.m_bounds[1])
        if self.config.known_com is not None:
            x[3], x[4] = self.config.known_com
        else:
            x[3], x[4] = self.outline.clip_to_hull(float(x[3]), float(x[4]))

    def _observation_noise(self, r: ArrayLike | None) -> NDArray[np.float64]:
        if r is None:
            return self.config.observation_noise
        out = np.asarray(r, dtype=np.float64)
        if out.shape != (3, 3):
            raise ValueError(f"R must have shape (3, 3), got shape {out.shape}")
        if not np.all(np.isfinite(out)) or not np.allclose(out, out.T, rtol=1e-9, atol=1e-15):
            raise ValueError("R must be finite and symmetric")
        if np.linalg.eigvalsh(out).min() <= 0.0:
            raise ValueError("R must be positive definite")
        return out
