"""Extended Kalman filter over the object pose, centre of mass, limit surface and friction.

SPEC section 2 step 3. ROS-free: numpy in, numpy out, float seconds where time appears.

State (``STATE_LABELS``), SI units::

    x = (x, y, theta, c_x, c_y, l, m)

``(x, y, theta)``: pose of the ``object`` frame in ``world`` (metres, radians). ``theta`` is kept
*continuous* (never wrapped, so a symmetric object's orientation stays continuous; wrap it with
:func:`push_core.geometry.wrap_angle` for display). ``(c_x, c_y)``: centre of mass in the object
frame (metres). ``l``: limit-surface parameter (metres). ``m``: pusher-object friction
coefficient. The object frame is the one of the perceived outline: origin at the area centroid.

Process model (:func:`predict_push`): the analytical pushing model of SPEC section 3
(:mod:`push_core.model`) driven by the executed straight push (pusher axis from
``pusher_start`` to ``pusher_end`` in ``world``), integrated in substeps of at most
``EKFConfig.substep`` (a push no longer than one substep is a single model step). Every substep
finds the contact on a *decimated* outline polygon (Douglas-Peucker, ``outline_tolerance``), the
way :func:`push_core.rollout.rollout_push` does (closest outline feature to the pusher centre at
the substep start, contact test ``approach > 0`` and ``gap - approach <= contact_tol``), with one
refinement: when the pusher closes a gap inside the substep, the contact point is taken where it
touches (not at the substep start) and only the rest of the substep pushes. ``c``, ``l`` and ``m``
do not change in the prediction; they are slowly varying parameters with a random walk per push.

Jacobian: closed form. The substep model is written out in scalar arithmetic together with its
partial derivatives (the contact point and normal on the touched segment or vertex as functions
of the pose, the touch fraction, both contact modes of the motion cone, the twist about the COM
and its application to the pose) and chained over the substeps. Tests check it against central
finite differences and the model part against ``torch.func.jacfwd`` through
:func:`push_core.model.push_twist`; the values equal ``push_twist`` / ``apply_twist`` to
rounding. Cost: ``torch.func.jacfwd`` through the torch model takes about 10 ms per substep,
the closed form about 0.02 ms with the contact search (numpy calls on 2-vectors cost more than
the arithmetic, so the scalar model and its derivatives run on Python floats, written out per
component; the contact search is a Python loop over outlines of at most ``_SMALL_POLYGON``
segments and vectorised over larger ones).

Process noise (per push, :meth:`EKFConfig.process_noise`): pose, world frame, isotropic in x
and y, standard deviations ``position_noise_min + position_noise_per_metre * L`` and
``angle_noise_min + angle_noise_per_metre * L`` with ``L`` the pusher travel in contact (the
model's error grows with the motion it predicts); parameters: independent random walks with
standard deviations ``com_noise`` (each axis), ``l_noise`` and ``m_noise`` per push.

Observation model: identity on ``(x, y, theta)``. The innovation's angle is wrapped, and for an
object with ``symmetry_order`` k (its outline looks the same after a rotation by 2 pi / k) it is
taken modulo 2 pi / k, i.e. the observed orientation closest to the prediction among the k
equivalent ones. ``symmetry_order`` = 1 means no symmetry; 0 means "detect it from the outline"
(:func:`symmetry_order_of_polygon`, rotations that map the outline onto itself within
``symmetry_tolerance``). An observation whose orientation variance says "not observed"
(:func:`push_core.symmetry.orientation_observed`: a continuously symmetric outline such as a
disc) updates only ``(x, y)``; the orientation then follows the process model from yaw 0 at the
first frame. The update is filterpy's Joseph form with these ``H`` and residual,
written out for ``H = [I_3 0]`` (:meth:`PushEKF._update`: the same equations and filterpy
attributes, without filterpy's generic 7 x 7 products), then symmetrised; ``l`` and ``m`` are
clipped to physical ranges (``l`` in ``[l_min_fraction * l_0, r_max]`` with ``l_0`` the
uniform-pressure guess and ``r_max`` the largest distance of the outline from its centroid,
``m`` in ``m_range``) and ``c`` to the convex hull of the outline (a rigid object's COM lies
inside it; :meth:`ContactOutline.clip_to_hull`).

Iterated update (``EKFConfig.iterations``, default 2): the model is strongly nonlinear in
``c`` and ``l``, and the first pushes are linearised at the prior (``c = 0``). After the
update, the push is linearised again at the smoothed pre-push state (one Rauch-Tung-Striebel /
Gauss-Newton step, :meth:`PushEKF._iterate`) and the update is redone from the pre-push
estimate: an iterated EKF for the process nonlinearity. On the pybullet benchmark (50
episodes, 10 pushes, ``pushbot eval estimator --iterations 1`` vs the default) it lowered
butter's median COM error from 10.6 to 6.5 mm, tri1's and hex's stayed about equal (11.3 and
4.9 -> 4.6 mm), and the NEES came inside its chi-square band; it doubles the cost of a
push (two model evaluations with Jacobian and two updates; figures in ``docs/RESULTS.md``,
``bench_estimator``).

Initialisation: the pose from the first observation (covariance R), ``c = 0`` with covariance
``com_prior_fraction^2`` times the second moment matrix of the outline's area (the COM anywhere
in the object, uniformly), ``l = l_0`` computed from the outline polygon itself
(:func:`limit_surface_of_polygon`, mean distance of the area from the centroid, exact; standard
deviation 25 %), ``m = m_init`` (a guess: 0.3, between the steel-on-steel pusher of the source
and the 0.15-0.5 range of the simulator, standard deviation 0.15).

Gating: an innovation whose squared Mahalanobis distance exceeds the chi-square quantile
``gate_probability`` (3 degrees of freedom) re-initialises the pose from the observation
(covariance R, no correlation with the parameters) and keeps ``c``, ``l``, ``m`` and their
covariance; :class:`UpdateResult` reports it (``reinitialized``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull
from scipy.stats import chi2

from push_core.geometry import check_points, closest_point_on_polyline
from push_core.model import ALPHA_MAX, ALPHA_MIN, L_MAX, L_MIN
from push_core.rollout import CONTACT_TOL, PUSHER_RADIUS
from push_core.shapes import Polygon
from push_core.symmetry import orientation_observed, symmetry_order_of_polygon

__all__ = [
    "STATE_LABELS",
    "STATE_SIZE",
    "ContactOutline",
    "EKFConfig",
    "PushEKF",
    "area_second_moment",
    "PushPrediction",
    "UpdateResult",
    "limit_surface_of_polygon",
    "predict_push",
    "symmetry_order_of_polygon",
]

#: Names of the state entries, in order.
STATE_LABELS = ("x", "y", "theta", "c_x", "c_y", "l", "m")
STATE_SIZE = len(STATE_LABELS)
#: Below this distance (m) of the pusher centre from a vertex, use the segment's normal.
_VERTEX_EPS = 1e-12
#: Outlines with at most this many segments are searched in a Python loop, larger ones in numpy.
_SMALL_POLYGON = 16
_EYE_7 = np.eye(STATE_SIZE)
_EYE_3x7_ROWS = np.eye(3, STATE_SIZE).tolist()


# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EKFConfig:
    """Every setting of :class:`PushEKF`; SI units. Validated on construction.

    Attributes
    ----------
    pusher_radius : float
        Radius of the cylindrical pusher, m.
    substep : float
        Longest model step along the push, m; longer pushes are integrated in substeps.
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
    iterations : int
        Linearisations of the push per observation (>= 1). 1 is the plain EKF; each further
        iteration re-linearises the process model at the smoothed pre-push state and redoes
        the update (an iterated EKF for the process nonlinearity in c, l and m).
    """

    pusher_radius: float = PUSHER_RADIUS
    substep: float = 0.01
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
    iterations: int = 2

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "m_range":
                lo, hi = _pair("m_range", value)
                if not 0.0 < lo < hi:
                    raise ValueError(f"m_range must satisfy 0 < low < high, got {value!r}")
                object.__setattr__(self, "m_range", (lo, hi))
            elif f.name in ("symmetry_order", "iterations"):
                low = 0 if f.name == "symmetry_order" else 1
                if isinstance(value, bool) or not isinstance(value, int | float) or \
                        int(value) != value or not low <= value <= 64:
                    raise ValueError(f"{f.name} must be an integer in [{low}, 64], got {value!r}")
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
        return np.diag([s_pos**2, s_pos**2, s_ang**2, self.com_noise**2, self.com_noise**2,
                        self.l_noise**2, self.m_noise**2])


def _pair(name: str, value: object) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be two numbers (low, high), got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return lo, hi


# --------------------------------------------------------------------------------------------
# Outline geometry
# --------------------------------------------------------------------------------------------
def limit_surface_of_polygon(vertices: ArrayLike, com: ArrayLike = (0.0, 0.0)) -> float:
    """Limit-surface parameter ``l`` of a polygon under uniform pressure, exactly.

    ``l`` = mean distance of the area from the centre of mass (maximum friction torque over
    maximum friction force for uniform pressure; ``2R/3`` for a disc of radius R), the quantity
    :meth:`push_core.objects.ObjectSpec.limit_surface_guess` estimates by sampling.

    Parameters
    ----------
    vertices : array_like, shape (P, 2)
        Closed counter-clockwise polygon, metres (may be non-convex).
    com : array_like, shape (2,)
        Centre of mass in the same frame, metres.

    Returns
    -------
    float
        ``l`` in metres.

    Notes
    -----
    Sum over the edges of the signed triangles (com, a, b): in polar coordinates about the COM,
    ``int |p| dA = int rho(phi)^3 / 3 dphi`` with ``rho = h / cos(psi)``, which integrates to
    ``F(t) = (h |p| t + h^3 asinh(t / h)) / 6`` along the edge (``h`` distance of the edge's line
    from the COM, ``t`` coordinate along the edge from the foot of the perpendicular).
    """
    v = Polygon(vertices, field="vertices").vertices - np.asarray(
        check_points(com, "com"), dtype=np.float64)
    a, b = v, np.roll(v, -1, axis=0)
    edge = b - a
    length = np.hypot(edge[:, 0], edge[:, 1])
    e = edge / length[:, None]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    h = np.abs(cross) / length
    keep = h > 1e-15  # edges whose line passes through the COM add nothing
    t_a = np.sum(a * e, axis=1)
    t_b = np.sum(b * e, axis=1)
    hk = np.where(keep, h, 1.0)

    def primitive(t: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
        r = np.hypot(p[:, 0], p[:, 1])
        return (hk * r * t + hk**3 * np.arcsinh(t / hk)) / 6.0

    integral = np.sign(cross) * (primitive(t_b, b) - primitive(t_a, a))
    area = 0.5 * float(np.sum(cross))
    return float(np.sum(np.where(keep, integral, 0.0)) / area)


def area_second_moment(vertices: ArrayLike) -> NDArray[np.float64]:
    """Second moment matrix of a polygon's area about the frame origin, per unit area.

    Parameters
    ----------
    vertices : array_like, shape (P, 2)
        Closed counter-clockwise polygon, metres.

    Returns
    -------
    numpy.ndarray, shape (2, 2)
        ``[[E x^2, E xy], [E xy, E y^2]]`` for a point uniformly distributed over the area, m^2
        (its covariance when the origin is the area centroid).
    """
    v = Polygon(vertices, field="vertices").vertices
    a, b = v, np.roll(v, -1, axis=0)
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]  # twice the signed area of (0, a, b)
    sxx = np.sum(cross * (a[:, 0] ** 2 + a[:, 0] * b[:, 0] + b[:, 0] ** 2)) / 12.0
    syy = np.sum(cross * (a[:, 1] ** 2 + a[:, 1] * b[:, 1] + b[:, 1] ** 2)) / 12.0
    sxy = np.sum(cross * (2 * a[:, 0] * a[:, 1] + a[:, 0] * b[:, 1] + b[:, 0] * a[:, 1]
                          + 2 * b[:, 0] * b[:, 1])) / 24.0
    area = 0.5 * np.sum(cross)
    return np.array([[sxx, sxy], [sxy, syy]]) / area


@dataclass(frozen=True)
class ContactOutline:
    """The perceived outline prepared for contact queries: a decimated CCW polygon.

    Build it with :meth:`from_points`. Object frame, metres.

    Attributes
    ----------
    vertices : numpy.ndarray, shape (P, 2)
        Decimated polygon, counter-clockwise.
    tangents : numpy.ndarray, shape (P, 2)
        Unit direction of segment i (vertex i -> i + 1).
    lengths : numpy.ndarray, shape (P,)
        Segment lengths.
    normals : numpy.ndarray, shape (P, 2)
        Outward unit normal of segment i.
    convex : numpy.ndarray of bool, shape (P,)
        Whether vertex i is convex.
    area : float
        Area of the full (undecimated) outline, m^2.
    area_moment : numpy.ndarray, shape (2, 2)
        Second moment matrix of the area about the origin divided by the area, m^2: the
        covariance of a point uniformly distributed over the object.
    limit_surface : float
        ``l_0``: uniform-pressure ``l`` about the origin (:func:`limit_surface_of_polygon`).
    radius : float
        Largest distance of the outline from the origin, m.
    symmetry_order : int
        Rotational symmetry order used for the orientation (1 = none).
    """

    vertices: NDArray[np.float64]
    tangents: NDArray[np.float64]
    lengths: NDArray[np.float64]
    normals: NDArray[np.float64]
    convex: NDArray[np.bool_]
    area: float
    area_moment: NDArray[np.float64]
    limit_surface: float
    radius: float
    symmetry_order: int
    #: Python-float copies of the arrays for the scalar model (numpy indexing costs more than
    #: the arithmetic there): per segment (a_x, a_y, t_x, t_y, n_x, n_y), convex flags.
    _segments: tuple[tuple[float, ...], ...] = field(default=(), repr=False, compare=False)
    _convex: tuple[bool, ...] = field(default=(), repr=False, compare=False)
    _lengths: tuple[float, ...] = field(default=(), repr=False, compare=False)
    #: Contiguous columns (a_x, a_y, t_x, t_y) for the vectorised closest-feature search.
    _columns: tuple[NDArray[np.float64], ...] = field(default=(), repr=False, compare=False)
    #: Convex hull edges (a_x, a_y, t_x, t_y, length, n_x, n_y), counter-clockwise.
    _hull: tuple[tuple[float, ...], ...] = field(default=(), repr=False, compare=False)

    def __post_init__(self) -> None:
        segments = tuple(tuple(row) for row in np.hstack(
            [self.vertices, self.tangents, self.normals]).tolist())
        object.__setattr__(self, "_segments", segments)
        object.__setattr__(self, "_convex", tuple(bool(c) for c in self.convex))
        object.__setattr__(self, "_lengths", tuple(self.lengths.tolist()))
        object.__setattr__(self, "_columns", tuple(np.ascontiguousarray(a) for a in (
            self.vertices[:, 0], self.vertices[:, 1], self.tangents[:, 0], self.tangents[:, 1])))
        hull = self.vertices[ConvexHull(self.vertices).vertices]  # counter-clockwise in 2-D
        edge = np.roll(hull, -1, axis=0) - hull
        length = np.hypot(edge[:, 0], edge[:, 1])
        t = edge / length[:, None]
        object.__setattr__(self, "_hull", tuple(tuple(row) for row in np.column_stack(
            [hull, t, length, t[:, 1], -t[:, 0]]).tolist()))

    def clip_to_hull(self, x: float, y: float) -> tuple[float, float]:
        """The point of the outline's convex hull closest to ``(x, y)`` (object frame, m).

        A rigid object's centre of mass lies inside the convex hull of its outline; the filter
        projects its COM estimate onto it. Points inside are returned unchanged.
        """
        if all(nx * (x - ax) + ny * (y - ay) <= 0.0 for ax, ay, _, _, _, nx, ny in self._hull):
            return x, y
        best, out = math.inf, (x, y)
        for ax, ay, ex, ey, length, _, _ in self._hull:
            s = min(max((x - ax) * ex + (y - ay) * ey, 0.0), length)
            px, py = ax + s * ex, ay + s * ey
            d2 = (x - px) ** 2 + (y - py) ** 2
            if d2 < best:
                best, out = d2, (px, py)
        return out

    @classmethod
    def from_points(cls, points: ArrayLike, normals: ArrayLike | None = None, *,
                    tolerance: float = 5e-4, symmetry_order: int = 1,
                    symmetry_tolerance: float = 1e-3) -> ContactOutline:
        """Validate a perceived outline and decimate it.

        Parameters
        ----------
        points : array_like, shape (N, 2)
            Outline points in the object frame (origin at the area centroid), metres, ordered
            counter-clockwise along the outline (a closed polyline), ``N >= 3``.
        normals : array_like, shape (N, 2), optional
            Outward unit normals at ``points``; only checked (unit length, pointing outward).
            Contact normals come from the decimated polygon's segments.
        tolerance : float
            Douglas-Peucker tolerance, m.
        symmetry_order : int
            1 = none, k > 1 = k-fold, 0 = detect (:func:`symmetry_order_of_polygon`).
        symmetry_tolerance : float
            Tolerance of the detection, m.

        Raises
        ------
        ValueError
            Naming ``points`` or ``normals``: wrong shape, non-finite values, fewer than 3
            points, clockwise or self-intersecting outline, normals that are not unit or point
            inward.
        """
        pts = np.asarray(check_points(points, "points"), dtype=np.float64)
        if pts.ndim != 2 or len(pts) < 3:
            raise ValueError(f"points must have shape (N, 2) with N >= 3, got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ValueError("points must be finite")
        polygon = Polygon(pts, field="points")  # raises on clockwise / self-intersecting
        if normals is not None:
            _check_outline_normals(pts, normals)
        if not tolerance > 0.0:
            raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
        order = int(symmetry_order)
        if order == 0:
            order = symmetry_order_of_polygon(polygon.vertices, symmetry_tolerance)
        elif order < 0:
            raise ValueError(f"symmetry_order must be >= 0, got {symmetry_order!r}")
        v = polygon.simplified(tolerance).vertices
        edge = np.roll(v, -1, axis=0) - v
        lengths = np.hypot(edge[:, 0], edge[:, 1])
        tangents = edge / lengths[:, None]
        prev = np.roll(tangents, 1, axis=0)
        convex = prev[:, 0] * tangents[:, 1] - prev[:, 1] * tangents[:, 0] > 0.0
        arrays = {
            "vertices": v, "tangents": tangents, "lengths": lengths,
            "normals": np.stack([tangents[:, 1], -tangents[:, 0]], axis=1), "convex": convex,
        }
        arrays["area_moment"] = area_second_moment(polygon.vertices)
        for a in arrays.values():
            a.setflags(write=False)
        return cls(**arrays, area=float(polygon.area),
                   limit_surface=limit_surface_of_polygon(polygon.vertices),
                   radius=float(np.max(np.hypot(pts[:, 0], pts[:, 1]))),
                   symmetry_order=order)

    def closest_feature(self, qx: float, qy: float) -> tuple[int, int]:
        """Closest feature of the polygon to the point ``(qx, qy)`` (object frame).

        Returns
        -------
        kind, index : int, int
            ``(0, i)``: the interior of segment i; ``(1, i)``: vertex i.
        """
        if len(self._segments) <= _SMALL_POLYGON:  # a Python loop beats numpy's overhead
            best, i, si = math.inf, 0, 0.0
            for j, (ax, ay, ex, ey, _, _) in enumerate(self._segments):
                rx, ry = qx - ax, qy - ay
                s = min(max(rx * ex + ry * ey, 0.0), self._lengths[j])
                dx, dy = rx - s * ex, ry - s * ey
                d2 = dx * dx + dy * dy
                if d2 < best:  # the first of equal minima, as numpy's argmin
                    best, i, si = d2, j, s
        else:
            ax, ay, ex, ey = self._columns
            rx, ry = qx - ax, qy - ay
            s = np.minimum(np.maximum(rx * ex + ry * ey, 0.0), self.lengths)
            dx, dy = rx - s * ex, ry - s * ey
            i = int(np.argmin(dx * dx + dy * dy))
            si = float(s[i])
        if si <= 0.0:
            return 1, i
        if si >= self._lengths[i]:
            return 1, (i + 1) % len(self._lengths)
        return 0, i


def _check_outline_normals(points: NDArray[np.float64], normals: ArrayLike) -> None:
    n = np.asarray(check_points(normals, "normals"), dtype=np.float64)
    if n.shape != points.shape:
        raise ValueError(f"normals must have the shape of points {points.shape}, got {n.shape}")
    if not np.all(np.isfinite(n)):
        raise ValueError("normals must be finite")
    norm = np.hypot(n[:, 0], n[:, 1])
    if np.any(np.abs(norm - 1.0) > 1e-3):
        raise ValueError(f"normals must be unit vectors, got norms in [{norm.min():.4g}, "
                         f"{norm.max():.4g}]")
    _, seg_normals, _, _ = closest_point_on_polyline(points, points)
    outward = np.mean(np.sum(n * seg_normals, axis=1) > 0.0)
    if outward < 0.9:
        raise ValueError(f"normals must point outward (counter-clockwise outline), but only "
                         f"{100 * outward:.0f} % do")


# --------------------------------------------------------------------------------------------
# Process model with its closed-form Jacobian
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PushPrediction:
    """What :func:`predict_push` returns.

    Attributes
    ----------
    state : numpy.ndarray, shape (7,)
        Predicted state (only the pose changes).
    jacobian : numpy.ndarray, shape (7, 7) or None
        ``d state / d previous state``; None when not requested.
    touched : bool
        Whether the pusher touched the object in any substep.
    contact_length : float
        Pusher travel in contact, m.
    n_substeps : int
        Model steps the push was split into.
    """

    state: NDArray[np.float64]
    jacobian: NDArray[np.float64] | None
    touched: bool
    contact_length: float
    n_substeps: int


def _twist_with_jacobian(ux: float, uy: float, rx: float, ry: float, nx: float, ny: float,
                         cx: float, cy: float, l: float, m: float,  # noqa: E741
                         jacobian: bool) -> tuple[float, float, float, tuple | None]:
    """:func:`push_core.model.push_twist` for one push, with its Jacobian.

    The same arithmetic and branches as ``push_twist`` on Python floats (a tiny problem: numpy's
    per-call overhead would dominate). ``n`` must be a unit vector pointing into the object.
    Returns ``(v_ox, v_oy, omega, J)`` with ``J`` the (3, 10) matrix d twist / d (u_x, u_y,
    r_x, r_y, n_x, n_y, c_x, c_y, l, m) as three row tuples, None if not requested. The
    columns for ``n`` omit the derivative of the model's normalisation: they are exact for
    changes of ``n`` tangent to the unit circle, the only ones a unit normal can make.
    """
    dl = 1.0 if L_MIN <= l <= L_MAX else 0.0
    l = min(max(l, L_MIN), L_MAX)  # noqa: E741
    alpha = math.atan(m)
    dalpha = 1.0 / (1.0 + m * m) if ALPHA_MIN <= alpha <= ALPHA_MAX else 0.0
    alpha = min(max(alpha, ALPHA_MIN), ALPHA_MAX)
    u_n = ux * nx + uy * ny
    if u_n <= 0.0:  # the pusher leaves the surface
        return 0.0, 0.0, 0.0, (((0.0,) * 10,) * 3 if jacobian else None)
    px, py = rx - cx, ry - cy  # r' = r - c
    l2 = l * l
    ca, sa = math.cos(alpha), math.sin(alpha)

    def boundary(sigma: float) -> tuple[float, ...]:
        # f = R(sigma alpha) n, tau = r' x f, v_b = l^2 f + tau (k x r'), and v_b . n
        fx, fy = ca * nx - sigma * sa * ny, sigma * sa * nx + ca * ny
        tau = px * fy - py * fx
        vx, vy = l2 * fx - tau * py, l2 * fy + tau * px
        return fx, fy, tau, vx, vy, vx * nx + vy * ny

    sigma, b = 0.0, ()
    b_r = boundary(1.0)
    if b_r[5] > 0.0 and b_r[3] * uy - b_r[4] * ux > 0.0:
        sigma, b = 1.0, b_r
    else:
        b_l = boundary(-1.0)
        if b_l[5] > 0.0 and ux * b_l[4] - uy * b_l[3] > 0.0:
            sigma, b = -1.0, b_l
    if sigma:  # sliding along boundary b
        k = u_n / b[5]
        vpx, vpy = k * b[3], k * b[4]
    else:  # sticking
        vpx, vpy = ux, uy

    rxx, ryy, rxy = px * px, py * py, px * py
    d = l2 + rxx + ryy
    vox = ((l2 + rxx) * vpx + rxy * vpy) / d
    voy = ((l2 + ryy) * vpy + rxy * vpx) / d
    omega = (px * voy - py * vox) / l2
    if not jacobian:
        return vox, voy, omega, None

    # d v_p / d X with X = (u_x, u_y, p_x, p_y, n_x, n_y, l, alpha), p = r' = r - c.
    if sigma:
        fx, fy, tau, vx, vy, v_n = b
        # d v_b / d f = [[l^2 + p_y^2, -p_x p_y], [-p_x p_y, l^2 + p_x^2]];
        # d f / d n = R(sigma alpha); d f / d alpha = sigma (-f_y, f_x).
        m00, m01, m11 = l2 + ryy, -rxy, l2 + rxx
        r01, r10 = -sigma * sa, sigma * sa
        gx, gy = -sigma * fy, sigma * fx
        # d v_b / d X (zero for u), components p_x, p_y, n_x, n_y, l, alpha
        b0p, b0q, b0nx, b0ny, b0l, b0a = (-fy * py, fx * py - tau, m00 * ca + m01 * r10,
                                          m00 * r01 + m01 * ca, 2.0 * l * fx,
                                          m00 * gx + m01 * gy)
        b1p, b1q, b1nx, b1ny, b1l, b1a = (fy * px + tau, -fx * px, m01 * ca + m11 * r10,
                                          m01 * r01 + m11 * ca, 2.0 * l * fy,
                                          m01 * gx + m11 * gy)
        # k = (u . n) / (v_b . n): d k = (d(u . n) - k (n . d v_b + v_b . d n)) / (v_b . n)
        inv, mk = 1.0 / v_n, -k / v_n
        k_ux, k_uy = nx * inv, ny * inv
        k_px, k_py = mk * (nx * b0p + ny * b1p), mk * (nx * b0q + ny * b1q)
        k_nx = ux * inv + mk * (nx * b0nx + ny * b1nx + vx)
        k_ny = uy * inv + mk * (nx * b0ny + ny * b1ny + vy)
        k_l, k_a = mk * (nx * b0l + ny * b1l), mk * (nx * b0a + ny * b1a)
        # v_p = k v_b
        dvp0 = (vx * k_ux, vx * k_uy, k * b0p + vx * k_px, k * b0q + vx * k_py,
                k * b0nx + vx * k_nx, k * b0ny + vx * k_ny, k * b0l + vx * k_l,
                k * b0a + vx * k_a)
        dvp1 = (vy * k_ux, vy * k_uy, k * b1p + vy * k_px, k * b1q + vy * k_py,
                k * b1nx + vy * k_nx, k * b1ny + vy * k_ny, k * b1l + vy * k_l,
                k * b1a + vy * k_a)
    else:
        dvp0 = dvp1 = None  # sticking: v_p = u, d v_p / d X selects u

    # Stage 2: (v_o, omega) = f(v_p, p, l); partials w.r.t. v_p and directly w.r.t. p and l.
    a00, a01, a11 = (l2 + rxx) / d, rxy / d, (l2 + ryy) / d
    w0, w1 = (px * a01 - py * a00) / l2, (px * a11 - py * a01) / l2
    x_px = (2.0 * px * vpx + py * vpy - 2.0 * px * vox) / d
    x_py = (px * vpy - 2.0 * py * vox) / d
    y_px = (py * vpx - 2.0 * px * voy) / d
    y_py = (2.0 * py * vpy + px * vpx - 2.0 * py * voy) / d
    x_l = 2.0 * l * (vpx - vox) / d
    y_l = 2.0 * l * (vpy - voy) / d
    w_px = (voy + px * y_px - py * x_px) / l2
    w_py = (px * y_py - vox - py * x_py) / l2
    w_l = (px * y_l - py * x_l) / l2 - 2.0 * omega / l
    rows = []
    for c0, c1, d_px, d_py, d_l in ((a00, a01, x_px, x_py, x_l), (a01, a11, y_px, y_py, y_l),
                                    (w0, w1, w_px, w_py, w_l)):
        if dvp0 is None:
            t = (c0, c1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        else:
            t = [c0 * p + c1 * q for p, q in zip(dvp0, dvp1)]  # noqa: B905 (8 each)
        t2, t3 = t[2] + d_px, t[3] + d_py
        # columns u (2), r (2), n (2), c (2) = -r, l, m = alpha * d alpha / d m
        rows.append((t[0], t[1], t2, t3, t[4], t[5], -t2, -t3, (t[6] + d_l) * dl,
                     t[7] * dalpha))
    return vox, voy, omega, tuple(rows)


def _substep(pose: list[float], c: tuple[float, float], l: float, m: float,  # noqa: E741
             w: tuple[float, float], delta: tuple[float, float], outline: ContactOutline,
             pusher_radius: float, contact_tol: float,
             jacobian: bool) -> tuple[list[float], tuple | None, float]:
    """One model step: pusher centre ``w`` -> ``w + delta`` (world) against the outline.

    Returns the new pose ``[x, y, theta]``, ``G`` (3, 7) = d new pose / d (x, y, theta, c_x,
    c_y, l, m) at the substep start as three row lists (None if not requested or without
    contact) and the pusher
    travel in contact (m). Contact as in :func:`push_core.rollout.rollout_push`, with the
    contact point taken where the pusher touches when it closes a gap within the substep.
    """
    px, py, th = pose
    ct, st = math.cos(th), math.sin(th)
    wx, wy = w[0] - px, w[1] - py
    qx, qy = ct * wx + st * wy, -st * wx + ct * wy  # pusher centre, object frame
    dx, dy = ct * delta[0] + st * delta[1], -st * delta[0] + ct * delta[1]

    kind, i = outline.closest_feature(qx, qy)
    ax, ay, ex, ey, nox, noy = outline._segments[i]
    if kind == 1:  # vertex v: outward normal sign (q - v) / |q - v|, signed distance sign |q - v|
        vx, vy = ax, ay
        sx, sy = qx - vx, qy - vy
        dist = math.hypot(sx, sy)
        if dist < _VERTEX_EPS:
            kind = 0
        else:
            sign = 1.0 if outline._convex[i] else -1.0
            nox, noy = sign * sx / dist, sign * sy / dist
            sd = sign * dist
    if kind == 0:  # interior of a segment
        sd = nox * (qx - ax) + noy * (qy - ay)
    gap = sd - pusher_radius  # clearance at the substep start
    approach = -(dx * nox + dy * noy)  # motion into the surface over the substep
    if not (approach > 0.0 and gap - approach <= contact_tol):
        return [px, py, th], None, 0.0
    t0 = gap / approach if gap > 0.0 else 0.0  # fraction of the substep before the touch
    if t0 >= 1.0:
        return [px, py, th], None, 0.0
    frac = 1.0 - t0
    tx, ty = qx + t0 * dx, qy + t0 * dy  # pusher centre at the touch
    if kind == 0:
        along = ex * (tx - ax) + ey * (ty - ay)
        rx, ry = ax + along * ex, ay + along * ey
        nix, niy = -nox, -noy
    else:
        rx, ry = vx, vy
        hx, hy = tx - vx, ty - vy
        dist_t = math.hypot(hx, hy)
        hx, hy = hx / dist_t, hy / dist_t
        nix, niy = -sign * hx, -sign * hy
    cx, cy = c
    vox, voy, omega, jt = _twist_with_jacobian(frac * dx, frac * dy, rx, ry, nix, niy, cx, cy,
                                               l, m, jacobian)

    # apply_twist (push_core.model): the COM moves by R(theta) v_o, the object turns about it.
    ox, oy = cx + vox, cy + voy
    th1 = th + omega
    c1, s1 = math.cos(th1), math.sin(th1)
    rcx, rcy = c1 * cx - s1 * cy, s1 * cx + c1 * cy  # R(theta1) c
    new = [px + ct * ox - st * oy - rcx, py + st * ox + ct * oy - rcy, th1]
    length = frac * math.hypot(dx, dy)
    if not jacobian:
        return new, None, length

    # Partials w.r.t. the pose (x, y, theta) at the substep start, written out per component
    # (suffix 0, 1, 2 = x, y, theta): loops and tuples over three numbers cost more than the
    # arithmetic.
    # q = R^T (w - p): dq/dp = -R^T, dq/dtheta = (q_y, -q_x); d = R^T delta: dd/dtheta = (d_y, -d_x)
    qx0, qx1, qx2 = -ct, -st, qy  # d q_x
    qy0, qy1, qy2 = st, -ct, -qx  # d q_y
    if t0 > 0.0:
        # t0 = gap / approach; gap = sd - r_p with d sd = n_out . dq; approach = -(d . n_out):
        # d t0 = (n_out . dq + t0 (n_out . dd + d . dn_out)) / approach
        a0 = nox * qx0 + noy * qy0
        a1 = nox * qx1 + noy * qy1
        a2 = nox * qx2 + noy * qy2 + t0 * (nox * dy - noy * dx)
        if kind == 1:  # d n_out = sign (I - u u^T) dq / |q - v|, u = (q - v) / |q - v|
            ux_, uy_ = sx / dist, sy / dist
            f = t0 * sign / dist
            # t0 d . d n_out = bx . dq_x + by . dq_y
            bx = f * ((1.0 - ux_ * ux_) * dx - ux_ * uy_ * dy)
            by = f * ((1.0 - uy_ * uy_) * dy - ux_ * uy_ * dx)
            a0 += bx * qx0 + by * qy0
            a1 += bx * qx1 + by * qy1
            a2 += bx * qx2 + by * qy2
        t00, t01, t02 = a0 / approach, a1 / approach, a2 / approach  # d t0
    else:
        t00 = t01 = t02 = 0.0
    # touch point q_t = q + t0 d; pushed part u = (1 - t0) d
    tx0, tx1, tx2 = qx0 + dx * t00, qx1 + dx * t01, qx2 + t0 * dy + dx * t02
    ty0, ty1, ty2 = qy0 + dy * t00, qy1 + dy * t01, qy2 - t0 * dx + dy * t02
    ux0, ux1, ux2 = -dx * t00, -dx * t01, frac * dy - dx * t02
    uy0, uy1, uy2 = -dy * t00, -dy * t01, -frac * dx - dy * t02
    # d twist / d pose = J_u du + J_r dr + J_n dn (J: the model's Jacobian rows), written as
    # J_u du + ca za + cb zb per row
    if kind == 0:  # r = projection of q_t on the segment (dr = t t^T dq_t); n constant
        za0, za1, za2 = ex * tx0 + ey * ty0, ex * tx1 + ey * ty1, ex * tx2 + ey * ty2
        zb0 = zb1 = zb2 = 0.0
        coeffs = [(j[2] * ex + j[3] * ey, 0.0) for j in jt]
    else:  # r = v; n_in = -sign (q_t - v) / |q_t - v|: dn = f (I - h h^T) dq_t
        f = -sign / dist_t
        hxx, hxy, hyy = 1.0 - hx * hx, -hx * hy, 1.0 - hy * hy
        za0, za1, za2 = f * (hxx * tx0 + hxy * ty0), f * (hxx * tx1 + hxy * ty1), \
            f * (hxx * tx2 + hxy * ty2)
        zb0, zb1, zb2 = f * (hxy * tx0 + hyy * ty0), f * (hxy * tx1 + hyy * ty1), \
            f * (hxy * tx2 + hyy * ty2)
        coeffs = [(j[4], j[5]) for j in jt]
    rows = [[j[0] * ux0 + j[1] * uy0 + ca * za0 + cb * zb0,
             j[0] * ux1 + j[1] * uy1 + ca * za1 + cb * zb1,
             j[0] * ux2 + j[1] * uy2 + ca * za2 + cb * zb2, j[6], j[7], j[8], j[9]]
            for j, (ca, cb) in zip(jt, coeffs)]  # noqa: B905 (three rows each)
    # new pose = apply_twist(pose, twist, c): partials w.r.t. the twist (A) and directly
    d0, d1, d2 = rows
    s_c = s1 * cx + c1 * cy
    g0 = [ct * a - st * b + s_c * e for a, b, e in zip(d0, d1, d2)]  # noqa: B905 (7 each)
    g1 = [st * a + ct * b - rcx * e for a, b, e in zip(d0, d1, d2)]  # noqa: B905
    g2 = d2
    g0[0] += 1.0
    g0[2] += s_c - (st * ox + ct * oy)
    g0[3] += ct - c1
    g0[4] += s1 - st
    g1[1] += 1.0
    g1[2] += (ct * ox - st * oy) - rcx
    g1[3] += st - s1
    g1[4] += ct - c1
    g2[2] += 1.0
    return new, (g0, g1, g2), length


def predict_push(state: ArrayLike, outline: ContactOutline, pusher_start: ArrayLike,
                 pusher_end: ArrayLike, *, pusher_radius: float = PUSHER_RADIUS,
                 substep: float = 0.01, contact_tol: float = CONTACT_TOL,
                 jacobian: bool = True) -> PushPrediction:
    """The process model: the state after one straight push, with its Jacobian.

    Parameters
    ----------
    state : array_like, shape (7,)
        ``(x, y, theta, c_x, c_y, l, m)`` before the push (see the module docstring).
    outline : ContactOutline
        The object's outline (object frame).
    pusher_start, pusher_end : array_like, shape (2,)
        Executed pusher axis positions at the start and end of the straight push, ``world``,
        metres.
    pusher_radius : float
        m.
    substep : float
        Longest model step, m.
    contact_tol : float
        Contact test tolerance, m.
    jacobian : bool
        Also compute ``d new state / d state``.

    Returns
    -------
    PushPrediction

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, non-finite values, ``substep <= 0`` or a negative
        ``pusher_radius`` / ``contact_tol``.
    """
    x = _finite_vector("state", state, STATE_SIZE)
    start = _finite_vector("pusher_start", pusher_start, 2)
    end = _finite_vector("pusher_end", pusher_end, 2)
    if not substep > 0.0:
        raise ValueError(f"substep must be > 0, got {substep!r}")
    if not pusher_radius >= 0.0:
        raise ValueError(f"pusher_radius must be >= 0, got {pusher_radius!r}")
    if not contact_tol >= 0.0:
        raise ValueError(f"contact_tol must be >= 0, got {contact_tol!r}")
    if not isinstance(outline, ContactOutline):
        raise ValueError(f"outline must be a ContactOutline, got {type(outline).__name__}")
    return _predict_push(x, outline, start, end, pusher_radius, substep, contact_tol, jacobian)


def _predict_push(x: NDArray[np.float64], outline: ContactOutline, start: NDArray[np.float64],
                  end: NDArray[np.float64], pusher_radius: float, substep: float,
                  contact_tol: float, jacobian: bool) -> PushPrediction:
    """:func:`predict_push` without the input checks (the filter checks once)."""
    # Python floats throughout: numpy scalars would make every operation below slower.
    push = (float(end[0]) - float(start[0]), float(end[1]) - float(start[1]))
    total = math.hypot(push[0], push[1])
    n_sub = math.ceil(total / substep * (1.0 - 1e-12)) if total > 0.0 else 0
    pose = [float(x[0]), float(x[1]), float(x[2])]
    c = (float(x[3]), float(x[4]))
    l, m = float(x[5]), float(x[6])  # noqa: E741
    jp = _EYE_3x7_ROWS  # d pose / d initial state, three row lists
    touched, in_contact = False, 0.0
    sx, sy = float(start[0]), float(start[1])
    scale = substep / total if total > 0.0 else 0.0  # substep as a fraction of the push
    for k in range(n_sub):
        # Fixed-length substeps from the start, the last one shorter: the substep boundaries
        # do not depend on the state, so the prediction is continuous in it.
        a = k * scale
        b = (k + 1) * scale if k + 1 < n_sub else 1.0
        w = (sx + a * push[0], sy + a * push[1])
        delta = ((b - a) * push[0], (b - a) * push[1])
        pose, g, length = _substep(pose, c, l, m, w, delta, outline, pusher_radius,
                                   contact_tol, jacobian)
        if length > 0.0:
            touched = True
            in_contact += length
            if g is not None and jp is _EYE_3x7_ROWS:  # first contact: jp = G
                jp = g
            elif g is not None:  # chain rule: jp <- G[:, :3] jp + [0 | G[:, 3:]]
                j0, j1, j2 = jp
                jp = []
                for r in g:
                    r0, r1, r2 = r[0], r[1], r[2]
                    row = [r0 * a + r1 * b + r2 * e for a, b, e in zip(j0, j1, j2)]  # noqa: B905
                    row[3] += r[3]
                    row[4] += r[4]
                    row[5] += r[5]
                    row[6] += r[6]
                    jp.append(row)
    new_state = x.copy()
    new_state[0:3] = pose
    jac = None
    if jacobian:
        jac = _EYE_7.copy()
        jac[0:3] = jp
    return PushPrediction(state=new_state, jacobian=jac, touched=touched,
                          contact_length=in_contact, n_substeps=n_sub)


def _finite_vector(name: str, value: ArrayLike, size: int) -> NDArray[np.float64]:
    try:
        out = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {size} numbers, got {value!r}") from None
    if out.shape != (size,):
        raise ValueError(f"{name} must have shape ({size},), got shape {out.shape}")
    if not math.isfinite(math.fsum(out.tolist())):  # NaN or inf anywhere (cheap for small sizes)
        raise ValueError(f"{name} must be finite, got {out.tolist()}")
    return out


# --------------------------------------------------------------------------------------------
# The filter
# --------------------------------------------------------------------------------------------
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
    """

    innovation: NDArray[np.float64]
    nis: float
    reinitialized: bool = False
    initialized: bool = False
    orientation_observed: bool = True


class PushEKF(ExtendedKalmanFilter):
    """EKF over ``(x, y, theta, c_x, c_y, l, m)``; see the module docstring.

    A filterpy :class:`~filterpy.kalman.ExtendedKalmanFilter` whose prediction is the pushing
    model: ``predict(u=(pusher_start, pusher_end))`` (or :meth:`predict_push`) sets ``F`` to the
    closed-form Jacobian and ``Q`` to the push's process noise, then filterpy propagates
    ``P = F P F^T + Q``. The update is filterpy's (Joseph form) with the symmetry-aware angle
    residual, Mahalanobis gating and clipping around it. filterpy keeps ``x`` as a (7, 1)
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
        self._h = np.eye(3, STATE_SIZE)
        self._gate = cfg.gate_threshold
        self._gate_position = (float(chi2.ppf(cfg.gate_probability, 2))
                               if cfg.gate_probability < 1.0 else math.inf)
        l0 = self.outline.limit_surface
        self.l_bounds = (cfg.l_min_fraction * l0, max(self.outline.radius, l0))
        self.m_bounds = cfg.m_range
        self.period = 2.0 * math.pi / self.outline.symmetry_order
        self.initialized = False
        self.last_prediction: PushPrediction | None = None
        #: (state, covariance, pusher_start, pusher_end) before the last push, for iterating.
        self._before_push: tuple | None = None

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
        z = _finite_vector("pose", pose, 3)
        mean = np.array([z[0], z[1], z[2], 0.0, 0.0, l0, cfg.m_init])
        cov = np.diag([0.0, 0.0, 0.0, 0.0, 0.0, (cfg.l_sigma_fraction * l0) ** 2,
                       cfg.m_sigma**2])
        cov[3:5, 3:5] = cfg.com_prior_fraction**2 * self.outline.area_moment
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

    def snapshot(self) -> tuple:
        """The filter's state at this point, for :meth:`restore` (re-filtering late inputs)."""
        return (self.x.copy(), self.P.copy(), self.initialized, self._before_push,
                self.last_prediction)

    def restore(self, snapshot: tuple) -> None:
        """Return to a :meth:`snapshot` of this filter."""
        x, p, self.initialized, self._before_push, self.last_prediction = snapshot
        self.x, self.P = x.copy(), p.copy()

    def reset(self) -> None:
        """Forget the episode; the next observation initialises the filter again."""
        self.x = np.zeros((STATE_SIZE, 1))
        self.P = np.eye(STATE_SIZE)
        self.initialized = False
        self.last_prediction = None
        self._before_push = None

    # ---- prediction --------------------------------------------------------------------------
    def predict_push(self, pusher_start: ArrayLike, pusher_end: ArrayLike) -> PushPrediction:
        """Predict through one executed push (filterpy ``predict`` with ``u`` = the push).

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
        start = _finite_vector("pusher_start", pusher_start, 2)
        end = _finite_vector("pusher_end", pusher_end, 2)
        r = self._observation_noise(R)
        pred = self._predict(self.x[:, 0], start, end)
        f = pred.jacobian
        p = f @ self.P @ f.T + self.config.process_noise(pred.contact_length)
        a = p[:, 0:3]
        p = p - a @ np.linalg.solve(p[0:3, 0:3] + r, a.T)
        return 0.5 * (p + p.T)

    def predict_x(self, u: object = 0) -> None:
        """filterpy hook: the nonlinear prediction; also sets ``F`` and ``Q`` for ``predict``."""
        if not self.initialized:
            raise RuntimeError("predict before the first observation: call initialize() first")
        if not (isinstance(u, tuple | list) and len(u) == 2):
            raise ValueError("u must be the push (pusher_start, pusher_end), two (2,) points in "
                             "world, metres")
        start = _finite_vector("pusher_start", u[0], 2)
        end = _finite_vector("pusher_end", u[1], 2)
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
                             cfg.contact_tol, True)

    def predict(self, u: object = 0) -> None:
        """filterpy ``predict`` (``P = F P F^T + Q``), then symmetrise ``P``."""
        super().predict(u)
        self.P = 0.5 * (self.P + self.P.T)
        self.P_prior = self.P.copy()

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
        z = _finite_vector("pose", pose, 3)
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
        if nis > (self._gate if observed else self._gate_position):
            if observed:
                self._reinitialize_pose(self.x[0:3, 0] + y[:, 0], r)
            else:
                self._reinitialize_position(z[:2], r[:2, :2])
            self._before_push = None
            return UpdateResult(innovation=y[:, 0].copy(), nis=nis, reinitialized=True,
                                orientation_observed=observed)
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
        """filterpy's ``update`` (Joseph form) for ``H = [I_n 0]``, symmetrised, parameters
        clipped.

        The same equations as :meth:`filterpy.kalman.ExtendedKalmanFilter.update` with this
        filter's ``H`` (select the pose, ``n = 3``, or only the position, ``n = 2``, when the
        orientation is not observed) and :meth:`residual`, written for it:
        ``S = P_pp + R``, ``K = P_:p S^-1``, ``x += K y`` and ``(I - K H) P (I - K H)^T + K R
        K^T = P - K A^T - A K^T + K S K^T`` with ``A = P H^T = P[:, :n]`` (the Joseph form
        multiplied out; no 7 x 7 identity products). Sets filterpy's ``y``, ``S``, ``SI``,
        ``K``, ``z``, ``x_post`` and ``P_post`` as its ``update`` does; about ten times faster.
        ``y``, ``s`` and ``si`` may be passed when the caller has them for this ``P``.
        """
        p = self.P
        if y is None:
            y = self.residual(zc, self.x[0:3])
        y = y[0:n]
        if s is None:
            s = p[0:n, 0:n] + r[0:n, 0:n]
            si = np.linalg.inv(s)
        a = p[:, 0:n]
        k = a @ si
        ka = k @ a.T
        p = p - ka - ka.T + k @ s @ k.T
        self.P = 0.5 * (p + p.T)
        self.x = self.x + k @ y
        self.S, self.SI, self.K, self.y, self.z = s, si, k, y, zc.copy()
        self._log_likelihood = self._likelihood = self._mahalanobis = None
        self._clip_parameters()
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()

    def _iterate(self, zc: NDArray[np.float64], r: NDArray[np.float64], n: int = 3) -> None:
        """One more Gauss-Newton step over the last push: re-linearise, predict, update.

        The linearisation point is the smoothed pre-push state (Rauch-Tung-Striebel step with
        the current linearisation ``F``), ``x_lin = x_prev + P_prev F^T P_prior^-1 (x_post -
        x_prior)``; the prediction is ``f(x_lin) + F(x_lin) (x_prev - x_lin)`` with covariance
        ``F P_prev F^T + Q``. c, l and m do not change in a push, so their posterior is also
        the best point to linearise the push at. ``n`` as in :meth:`_update`.
        """
        x_prev, p_prev, start, end = self._before_push
        gain = np.linalg.solve(self.P_prior, self.F @ p_prev).T  # P_prev F^T P_prior^-1
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

    def _jacobian_h(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._h

    def _hx(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return x[0:3]

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

    def _clip_parameters(self) -> None:
        x = self.x[:, 0]
        x[5] = min(max(x[5], self.l_bounds[0]), self.l_bounds[1])
        x[6] = min(max(x[6], self.m_bounds[0]), self.m_bounds[1])
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
