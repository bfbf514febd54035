"""Settings and state layout of the push EKF (:mod:`push_core.estimator`).

ROS-free. State (``STATE_LABELS``), SI units::

    x = (x, y, theta, c_x, c_y, l, m)

``(x, y, theta)``: pose of the ``object`` frame in ``world`` (metres, radians). ``theta`` is kept
*continuous* (never wrapped, so a symmetric object's orientation stays continuous; wrap it with
:func:`push_core.geometry.wrap_angle` for display). ``(c_x, c_y)``: centre of mass in the object
frame (metres). ``l``: limit-surface parameter (metres). ``m``: pusher-object friction
coefficient. The object frame is the one of the perceived outline: origin at the area centroid.

Process noise (per push, :meth:`EKFConfig.process_noise`): pose, world frame, isotropic in x
and y, standard deviations ``position_noise_min + position_noise_per_metre * L`` and
``angle_noise_min + angle_noise_per_metre * L`` with ``L`` the pusher travel in contact (the
model's error grows with the motion it predicts); parameters: independent random walks with
standard deviations ``com_noise`` (each axis), ``l_noise`` and ``m_noise`` per push.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

from push_core.rollout import CONTACT_TOL, PUSHER_RADIUS

__all__ = ["STATE_LABELS", "STATE_SIZE", "EKFConfig", "finite_vector"]

#: Names of the state entries, in order.
STATE_LABELS = ("x", "y", "theta", "c_x", "c_y", "l", "m")
STATE_SIZE = len(STATE_LABELS)


@dataclass(frozen=True)
class EKFConfig:
    """Every setting of :class:`PushEKF`; SI units. Validated on construction.

    Attributes
    ----------
    pusher_radius : float
        Radius of the cylindrical pusher, m.
    substep : float
        Longest model step along the push, m; longer pushes are integrated in substeps.
    max_substeps : int
        Most model steps of one push (bounded work per push, in [1, 10^6]): a push longer than
        ``max_substeps * substep`` is integrated in ``max_substeps`` equal, longer substeps.
        1000 (10 m at the default 1 cm substep) never binds on a table-top push.
    contact_tol : float
        Distance tolerance of the contact test, m (as in :mod:`push_core.rollout`).
    outline_tolerance : float
        Douglas-Peucker tolerance of the decimated outline used for contacts, m.
    symmetry_order : int
        Rotational symmetry order of the outline: 1 = none, k = k-fold, 0 (default) = detect
        it from the outline (:func:`symmetry_order_of_polygon`).
    symmetry_tolerance : float
        Largest outline mismatch (m) for a rotation to count as a symmetry when detecting.
        2 mm: perceived outlines deviate from the true one by up to about 1.5 mm (at 1 mm the
        detection missed hex's and butter's symmetry on some perceived outlines); the library
        outlines give the same orders at 1 and 2 mm.
    com_prior_fraction : float
        Scale of the COM prior: its covariance is ``com_prior_fraction^2`` times the second
        moment matrix of the outline's area about the centroid, i.e. 1 = "the COM is anywhere
        in the object, uniformly" (the COM starts at the centroid, 0).
    l_sigma_fraction : float
        Initial standard deviation of ``l`` as a fraction of the initial guess ``l_0``.
    l_min_fraction : float
        Lower clip of ``l`` as a fraction of ``l_0`` (the upper clip is the outline radius).
    m_init, m_sigma : float
        Initial friction coefficient and its standard deviation.
    m_range : tuple of 2 float
        Clip range of ``m``.
    position_sigma, angle_sigma : float
        Default observation noise (standard deviations, m and rad) when an update gives no R.
    position_noise_min, position_noise_per_metre : float
        Process noise of x and y per push: ``min + per_metre * L`` (m), ``L`` = pusher travel
        in contact (m).
    angle_noise_min, angle_noise_per_metre : float
        Process noise of theta per push: ``min + per_metre * L`` (rad; per_metre in rad/m).
    com_noise, l_noise, m_noise : float
        Random-walk standard deviations of ``c_x`` and ``c_y`` (m), ``l`` (m) and ``m`` per
        push.
    gate_probability : float
        Chi-square probability (3 dof) of the innovation gate, in (0, 1]; 1 disables gating.
    relearn : bool
        When the observations after pushes contradict their predictions (one fails the gate,
        or the NIS of the last ``relearn_window`` after pushes sum beyond the chi-square
        quantile ``relearn_probability`` with ``3 x relearn_window`` degrees of freedom: a
        confidently wrong parameter whose every push lands a little outside the prediction),
        re-learn ``c``, ``l`` and ``m`` instead of keeping them:
        their covariance is restarted at the prior (means kept, correlations dropped), the push
        is predicted again from the pre-push state and the observation fused if it now passes
        the gate (else the pose is re-initialised, the parameters stay at the prior
        covariance). Default False: the pose is re-initialised and ``c``, ``l``, ``m`` kept.
    relearn_window : int
        Observations after pushes in the windowed consistency test of ``relearn`` (1-64).
    relearn_probability : float
        Chi-square probability of that test, in (0, 1).
    iterations : int
        Linearisations of the push per observation (>= 1). 1 is the plain EKF; each further
        iteration re-linearises the process model at the smoothed pre-push state and redoes
        the update (an iterated EKF for the process nonlinearity in c, l and m).
    known_com : tuple of 2 float, optional
        The COM (object frame, m) when it is known: the filter starts there with zero variance
        and no random walk (default None: estimated).
    known_l : float, optional
        Known limit-surface parameter (m, > 0), likewise (default None: estimated).
    known_m : float, optional
        Known pusher-object friction (>= 0; 0 = frictionless contact, outside ``m_range``),
        likewise (default None: estimated).
    """

    pusher_radius: float = PUSHER_RADIUS
    substep: float = 0.01
    max_substeps: int = 1000
    contact_tol: float = CONTACT_TOL
    outline_tolerance: float = 5e-4
    symmetry_order: int = 0
    symmetry_tolerance: float = 2e-3
    com_prior_fraction: float = 1.0
    l_sigma_fraction: float = 0.25
    l_min_fraction: float = 0.3
    m_init: float = 0.3
    m_sigma: float = 0.15
    m_range: tuple[float, float] = (0.05, 1.2)
    position_sigma: float = 0.002
    angle_sigma: float = math.radians(1.5)
    position_noise_min: float = 2e-4
    position_noise_per_metre: float = 0.15
    angle_noise_min: float = math.radians(0.2)
    angle_noise_per_metre: float = 3.0
    com_noise: float = 5e-4
    l_noise: float = 5e-4
    m_noise: float = 0.01
    gate_probability: float = 0.9999
    relearn: bool = False
    relearn_window: int = 3
    relearn_probability: float = 0.99
    iterations: int = 2
    known_com: tuple[float, float] | None = None
    known_l: float | None = None
    known_m: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name.startswith("known_"):
                if value is None:
                    continue
                if f.name == "known_com":
                    object.__setattr__(self, f.name, tuple(finite_vector(f.name, value, 2)))
                    continue
                ok = not isinstance(value, bool) and isinstance(value, int | float) and \
                    math.isfinite(value) and (value > 0.0 if f.name == "known_l" else value >= 0.0)
                if not ok:
                    raise ValueError(f"{f.name} must be a finite number "
                                     f"{'> 0' if f.name == 'known_l' else '>= 0'} or None, got "
                                     f"{value!r}")
                object.__setattr__(self, f.name, float(value))
            elif f.name == "relearn":
                if not isinstance(value, bool | np.bool_):
                    raise ValueError(f"relearn must be a bool, got {value!r}")
                object.__setattr__(self, f.name, bool(value))
            elif f.name == "m_range":
                lo, hi = _pair("m_range", value)
                if not 0.0 < lo < hi:
                    raise ValueError(f"m_range must satisfy 0 < low < high, got {value!r}")
                object.__setattr__(self, "m_range", (lo, hi))
            elif f.name in ("symmetry_order", "iterations", "max_substeps", "relearn_window"):
                low = 0 if f.name == "symmetry_order" else 1
                high = 10**6 if f.name == "max_substeps" else 64
                if isinstance(value, bool) or not isinstance(value, int | float) or \
                        not math.isfinite(value) or int(value) != value or \
                        not low <= value <= high:
                    raise ValueError(f"{f.name} must be an integer in [{low}, {high}], got "
                                     f"{value!r}")
                object.__setattr__(self, f.name, int(value))
            else:
                if isinstance(value, bool) or not isinstance(value, int | float) or \
                        not math.isfinite(value):
                    raise ValueError(f"{f.name} must be a finite number, got {value!r}")
                object.__setattr__(self, f.name, float(value))
        positive = ("substep", "outline_tolerance", "symmetry_tolerance", "com_prior_fraction",
                    "l_sigma_fraction", "m_init", "m_sigma", "position_sigma", "angle_sigma",
                    "l_min_fraction", "gate_probability")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        non_negative = ("pusher_radius", "contact_tol", "position_noise_min",
                        "position_noise_per_metre", "angle_noise_min", "angle_noise_per_metre",
                        "com_noise", "l_noise", "m_noise")
        for name in non_negative:
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if not 0.0 < self.relearn_probability < 1.0:
            raise ValueError(f"relearn_probability must be in (0, 1), got "
                             f"{self.relearn_probability!r}")
        if not self.gate_probability <= 1.0:
            raise ValueError(f"gate_probability must be in (0, 1], got {self.gate_probability!r}")
        if not self.l_min_fraction < 1.0:
            raise ValueError(f"l_min_fraction must be < 1, got {self.l_min_fraction!r}")
        if not self.m_range[0] <= self.m_init <= self.m_range[1]:
            raise ValueError(f"m_init must lie in m_range {self.m_range}, got {self.m_init!r}")

    @property
    def observation_noise(self) -> NDArray[np.float64]:
        """Default observation covariance R (3, 3): x, y (m^2), theta (rad^2)."""
        return np.diag([self.position_sigma**2, self.position_sigma**2, self.angle_sigma**2])

    @property
    def gate_threshold(self) -> float:
        """Squared Mahalanobis distance beyond which an observation re-initialises the pose."""
        return float(chi2.ppf(self.gate_probability, 3)) if self.gate_probability < 1.0 \
            else math.inf

    def process_noise(self, contact_length: float) -> NDArray[np.float64]:
        """Process noise Q (7, 7) of one push.

        Parameters
        ----------
        contact_length : float
            Pusher travel in contact with the object during the push, m.

        Returns
        -------
        numpy.ndarray, shape (7, 7)
            Diagonal: x, y, theta, c_x, c_y, l, m variances (SI units squared).
        """
        s_pos = self.position_noise_min + self.position_noise_per_metre * contact_length
        s_ang = self.angle_noise_min + self.angle_noise_per_metre * contact_length
        s_com = 0.0 if self.known_com is not None else self.com_noise
        s_l = 0.0 if self.known_l is not None else self.l_noise
        s_m = 0.0 if self.known_m is not None else self.m_noise
        return np.diag([s_pos**2, s_pos**2, s_ang**2, s_com**2, s_com**2, s_l**2, s_m**2])


def _pair(name: str, value: object) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be two numbers (low, high), got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return lo, hi


def finite_vector(name: str, value: ArrayLike, size: int) -> NDArray[np.float64]:
    """``value`` as a float64 vector of shape ``(size,)``; ``ValueError`` naming ``name`` for a
    wrong shape or a non-finite entry (the input check of the filter and the process model)."""
    try:
        out = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {size} numbers, got {value!r}") from None
    if out.shape != (size,):
        raise ValueError(f"{name} must have shape ({size},), got shape {out.shape}")
    if not math.isfinite(math.fsum(out.tolist())):  # NaN or inf anywhere (cheap for small sizes)
        raise ValueError(f"{name} must be finite, got {out.tolist()}")
    return out
