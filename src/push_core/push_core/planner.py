"""Greedy affordance-based push planner (docs/design/planner.md): one push per cycle.

ROS-free, numpy, seeded. One planning step (:meth:`Planner.plan`):

1. **Affordances** (:mod:`push_core.affordances`): the predicted object motion for every outline
   point x the 10 representative pushes (``ana``: analytical model; ``lrn``: learned CNN).
2. **Scores**, eq. (5.1) of the source, for every outline point ``r_i``::

       s(r_i) = min_u  ||v_d - v_hat(u, r_i)||_mm  +  lambda * |omega_d - omega_hat(u, r_i)|_deg

   ``(v_d, omega_d)`` is the desired motion (goal minus current pose, the translation expressed
   in the object frame, the rotation wrapped to (-pi, pi]). **Units: the translation error in
   millimetres, the rotation error in degrees; lambda in millimetres per degree.** A score is
   therefore "millimetres of remaining error" and so is the sampling temperature.
   (``lambda = 2`` mm/deg is the tuned default, see ``docs/results/bench_planner.md``.)
3. **Contact proposal**: ``k`` points sampled without replacement from the softmax
   ``p_i ~ exp(-(s_i - min s) / T)`` (Gumbel top-k, exact for any k); baselines ``rdn``
   (uniform over the outline) and ``geo`` (:func:`geo_mask`). Points within ``AVOID_RADIUS``
   of ``plan(avoid=...)`` (outline points of pushes the robot refused since the object last
   moved) are left out.
4. **Push optimisation** at each sampled point (skipped by the ``direct`` variant):

   a. 5 base directions (-60, -30, 0, 30, 60 degrees from the inward normal), each rolled out
      with :func:`push_core.rollout.rollout_push` (analytical model, 5 mm substeps, contact point
      and normal found again on the moved outline at every substep). The rollout starts at the
      approach point, ``approach_clearance`` before the touching position, so the pusher's way in
      is simulated too (a push into a concavity that first meets another part of the outline is
      predicted as such) and runs until the push is ``max_push_length`` (5 cm) past the contact.
   b. eq. (5.1) of the predicted pose (residual to the goal) after every substep;
   c. each direction truncated at its best-scoring length >= ``min_push_length`` (1 cm);
   d. direction interpolation between the best base direction and its two neighbours:
      the directions every 10 degrees between them (``INTERPOLATION_STEPS = 2`` per 30 degree
      gap, so best +-10 and +-20 degrees);
   e. their lengths optimised as in a-c.

   Implementation note: the rollouts of d-e run in the *same* batched rollout call as a
   (speculatively for every gap between neighbouring base directions, 13 directions per
   point), because a rollout call costs ~4 ms of per-substep overhead almost independent of
   the batch size (docs/results/bench_planner.md); afterwards only the interpolated directions
   next to each point's best base direction are admitted, so the answer is that of the
   sequential procedure at half the time.
   The best admitted push over all candidates is returned.
   **direct** variant: no rollouts; for the 5 base directions the affordance predictions for
   1 cm and 5 cm are interpolated linearly in the push length (``motion(L) = m_1 + (L - 1 cm) /
   4 cm * (m_5 - m_1)``; for the analytical model this is exactly proportional to ``L``) and the
   length in ``[min_push_length, max_push_length]`` (1 mm grid) with the best score is taken.
5. **Feasibility**: a push is excluded when its approach point or its end point lies outside the
   workspace rectangle, or the approach point is inside the object or closer than
   ``pusher_radius + APPROACH_MARGIN + simplify_tolerance`` to the contact polyline (the pusher
   could not be lowered there; the simplified polyline is within ``simplify_tolerance`` of the
   outline).
   If no sampled candidate has a feasible push, every other eligible point is tried once, the
   best-scoring first and at most ``MAX_FALLBACK_POINTS`` (256) of them (``PushPlan.fallback``);
   if none has one, :class:`NoFeasiblePush` is raised.

Bounded work and memory (issue 15; no bound binds on a normal input, so normal results are
unchanged): outlines above ``MAX_OUTLINE_POINTS`` (1000) points are decimated
(:func:`prepare_outline`), an implausible state is refused (:func:`check_state`: ``l``, ``m``
and the COM against the outline's radius; ``planner_node`` also refuses an object larger than
the workspace, :meth:`Planner.check_outline`), and the closest-point queries of the rollouts and
approach checks run in chunks of bounded size (``push_core.geometry.CLOSEST_POINT_BUDGET``).
Per call: affordances N x 10 x 3, rollouts B x S with B = 13 x (k or up to 256 fallback
points) and S = (approach_clearance + max_push_length) / substep.

Frames and units: SI (metres, radians) except inside scores (see above). Outline points and
normals, the COM and affordances are in the object frame (origin = area centroid); poses, goals
and the returned pusher points are in ``world``. The returned ``contact`` is the pusher *axis*
where the pusher touches the outline, ``point + pusher_radius * n_out``; ``approach`` lies
``approach_clearance`` before it and ``end`` ``length`` after it on the same straight line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from statistics import NormalDist

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core import lookahead
from push_core.affordances import N_ANGLES, AffordanceModel, analytical_affordances
from push_core.geometry import (
    check_polyline,
    closest_point_on_polyline,
    object_to_world,
    world_to_object,
    wrap_angle,
)
from push_core.model import REPRESENTATIVE_ANGLES_DEG, REPRESENTATIVE_LENGTHS
from push_core.rollout import PUSHER_RADIUS, SUBSTEP, rollout_push
from push_core.shapes import Polygon
from push_core.symmetry import has_continuous_symmetry
from push_core.transit import TransitPlanner, ccw_polygon, segment_polygon_clear

__all__ = [
    "APPROACH_MARGIN",
    "AVOID_RADIUS",
    "BASE_ANGLES_DEG",
    "MAX_COM_RADII",
    "MAX_FALLBACK_POINTS",
    "MAX_FRICTION",
    "MAX_L_RADII",
    "MAX_OUTLINE_POINTS",
    "METHODS",
    "STOP_CONFIDENCE",
    "NoFeasiblePush",
    "NoImprovingPush",
    "Outline",
    "Planner",
    "PlannerConfig",
    "PushPlan",
    "check_state",
    "desired_motion",
    "geo_mask",
    "goal_reached",
    "motion_score",
    "point_scores",
    "prepare_outline",
    "sample_contacts",
    "softmax_probabilities",
    "stop_quantile",
]

#: Default confidence of the stop rule (:func:`goal_reached`): the goal counts as reached when
#: the true pose is inside the goal region with at least this probability along the worst
#: direction.
STOP_CONFIDENCE = 0.99
#: Contact-selection methods: analytical / learned affordances, geometric / random baselines.
METHODS = ("ana", "lrn", "geo", "rdn")
#: Base push directions of the optimisation, degrees from the inward normal, ascending.
BASE_ANGLES_DEG = (-60.0, -30.0, 0.0, 30.0, 60.0)
#: Extra clearance beyond the pusher radius between an approach point and the outline, metres
#: (the value ``sim_bridge.world`` enforces).
APPROACH_MARGIN = 5e-4
#: ``Planner.plan(avoid=...)``: outline points this close (m) to the outline point of a refused
#: push are not used again until the object moves (the robot checks the approach against the
#: true object; a perceived outline rounds sharp corners, and a refused push moves nothing, so
#: the same plan would come again).
AVOID_RADIUS = 0.01
#: geo baseline: below this rotation (rad) points near the line to the goal are used ...
GEO_MIN_ROTATION = math.radians(2.0)
#: ... within this distance of it (m).
GEO_LINE_BAND = 0.02
#: geo baseline: below this translation (m) the goal is a pure rotation (no line to the goal).
GEO_MIN_TRANSLATION = 1e-3
#: Grid step of the push length in the direct variant, metres.
DIRECT_LENGTH_STEP = 1e-3

#: Interpolated directions between two neighbouring base directions (every 10 degrees).
INTERPOLATION_STEPS = 2

# Bounded work and memory (issue 15). None of these binds on a normal input (the library's
# outlines have at most ~260 points at the perception's 2 mm spacing), so normal results are
# unchanged to the bit.
#: :func:`prepare_outline` decimates an outline of more points to this many (every
#: ``N / MAX_OUTLINE_POINTS``-th point, normals with them): its simple-polygon check is
#: O(N^2) in memory (~80 MB at this size), every later step O(N) or O(N P).
MAX_OUTLINE_POINTS = 1000
#: The fallback of :meth:`Planner.plan` (no sampled candidate feasible) tries at most this many
#: further points, the best-scoring first (each costs 13 rollouts).
MAX_FALLBACK_POINTS = 256
#: Plausible state (:func:`check_state`): ``0 < l <= MAX_L_RADII * r`` and
#: ``|c| <= MAX_COM_RADII * r`` with ``r`` the outline's radius (its largest distance from the
#: object frame origin; the estimator keeps ``l <= r`` and ``c`` in the convex hull), and
#: ``0 <= m <= MAX_FRICTION``.
MAX_L_RADII = 4.0
MAX_COM_RADII = 2.0
MAX_FRICTION = 10.0
#: :func:`_allowed_points` compares the outline with at most this many avoided points at a time.
_AVOID_CHUNK = 256

# Column of each base direction (ascending) in the representative-push order (0, 30, -30, ...).
_BASE_TO_REPR = tuple(REPRESENTATIVE_ANGLES_DEG.index(a) for a in BASE_ANGLES_DEG)
# All directions of the optimisation, ascending (radians); base ones at _BASE_COLUMNS.
_FINE_ANGLES = np.radians(np.linspace(
    BASE_ANGLES_DEG[0], BASE_ANGLES_DEG[-1],
    (len(BASE_ANGLES_DEG) - 1) * (INTERPOLATION_STEPS + 1) + 1))
_BASE_COLUMNS = np.arange(0, len(_FINE_ANGLES), INTERPOLATION_STEPS + 1)


class NoFeasiblePush(RuntimeError):
    """No outline point admits a push inside the workspace with a clear approach."""


class NoImprovingPush(NoFeasiblePush):
    """``PlannerConfig.require_improvement``: no feasible push is predicted to bring the object
    closer to the goal (by eq. 5.1) than it is now. ``plan`` holds the best push found."""

    def __init__(self, message: str, plan: PushPlan) -> None:
        super().__init__(message)
        self.plan = plan


# ------------------------------------------------------------------------------ scores
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
    pose = _vector(pose, 3, "pose")
    goal = _vector(goal, 3, "goal")
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = goal[0] - pose[0], goal[1] - pose[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, float(wrap_angle(goal[2] - pose[2]))])


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
    desired = _vector(desired, 3, "desired")
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
    desired = _vector(desired, 3, "desired")
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


# ------------------------------------------------------------------------------ outline
@dataclass(frozen=True, eq=False)
class Outline:
    """A validated outline for planning (build it with :func:`prepare_outline`, once per shape).

    Attributes
    ----------
    points : numpy.ndarray, shape (N, 2)
        Candidate contact points, counter-clockwise, object frame (metres).
    normals : numpy.ndarray, shape (N, 2)
        Outward unit normals at ``points``.
    polyline : numpy.ndarray, shape (P, 2)
        Closed counter-clockwise polyline for contact search in rollouts and approach checks:
        ``points`` simplified by Douglas-Peucker (``P <= N``).
    orientation_matters : bool
        False for a continuously symmetric outline (a disc,
        :func:`push_core.symmetry.has_continuous_symmetry`): its orientation cannot be
        observed, so the planner scores and stops on the goal position alone.
    source_points : int
        Points of the outline as given (more than ``len(points)`` when it was decimated to
        :data:`MAX_OUTLINE_POINTS`); 0 = not recorded.
    """

    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    polyline: NDArray[np.float64]
    orientation_matters: bool = True
    source_points: int = 0

    @property
    def radius(self) -> float:
        """Largest distance of an outline point from the object frame origin, metres."""
        return float(np.max(np.hypot(self.points[:, 0], self.points[:, 1])))


def prepare_outline(points: ArrayLike, normals_out: ArrayLike,
                    simplify_tolerance: float = 5e-4,
                    max_points: int = MAX_OUTLINE_POINTS) -> Outline:
    """Validate an outline and build the simplified polyline used for contact search.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Outline points, counter-clockwise, object frame (metres), ``N >= 3``, finite, with a
        positive enclosed area.
    normals_out : array_like, shape (N, 2)
        Outward normals at ``points``, finite and non-zero; normalised here.
    simplify_tolerance : float
        Douglas-Peucker tolerance of the contact polyline, metres (>= 0; 0 keeps ``points``).
        Measured outlines that do not form a simple polygon are used unsimplified.
    max_points : int
        An outline of more points is decimated to this many (every ``N / max_points``-th
        point from point 0, with its normal; bounded work and memory, see
        :data:`MAX_OUTLINE_POINTS`); ``Outline.source_points`` keeps ``N``.

    Returns
    -------
    Outline

    Raises
    ------
    ValueError
        Naming ``points`` or ``normals_out``.
    """
    p = np.array(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3:
        raise ValueError(f"points must have shape (N, 2) with N >= 3, got shape {p.shape}")
    n = np.array(normals_out, dtype=np.float64)
    if n.shape != p.shape:
        raise ValueError(f"normals_out must have the shape of points {p.shape}, got {n.shape}")
    source_points = len(p)
    if isinstance(max_points, bool) or int(max_points) != max_points or max_points < 3:
        raise ValueError(f"max_points must be an integer >= 3, got {max_points!r}")
    if len(p) > max_points:
        keep = np.linspace(0, len(p), int(max_points), endpoint=False).astype(np.intp)
        p, n = p[keep], n[keep]
    check_polyline(p, "points")
    norm = np.hypot(n[:, 0], n[:, 1])
    if not np.all(np.isfinite(norm)) or np.any(norm <= 1e-12):
        raise ValueError("normals_out must be finite and non-zero")
    if not simplify_tolerance >= 0.0:
        raise ValueError(f"simplify_tolerance must be >= 0, got {simplify_tolerance}")
    polyline = p
    if simplify_tolerance > 0.0:
        try:
            polyline = np.array(Polygon(p).simplified(simplify_tolerance).vertices)
        except ValueError:  # not a simple polygon (noisy measured outline): use it as it is
            polyline = p
    for a in (p, n, polyline):
        a.setflags(write=False)
    n = n / norm[:, None]
    n.setflags(write=False)
    return Outline(points=p, normals=n, polyline=polyline,
                   orientation_matters=not has_continuous_symmetry(p),
                   source_points=source_points)


def check_state(state: ArrayLike, outline: Outline | None = None) -> NDArray[np.float64]:
    """A plausible planner state ``(x, y, theta, c_x, c_y, l, m)``, (7,), or ``ValueError``.

    Finite; ``l > 0`` and ``m`` in ``[0, MAX_FRICTION]``; with ``outline``, also
    ``l <= MAX_L_RADII * r`` and ``|c| <= MAX_COM_RADII * r`` (``r = outline.radius``: the COM
    of a rigid object lies inside its outline, and the estimator keeps ``l <= r``). The message
    starts with ``state``.
    """
    s = _vector(state, 7, "state")
    com, l, m = s[3:5], float(s[5]), float(s[6])  # noqa: E741
    if not l > 0.0 or not 0.0 <= m <= MAX_FRICTION:
        raise ValueError(f"state: l must be > 0 and m in [0, {MAX_FRICTION}], got l = {l}, "
                         f"m = {m}")
    if outline is not None:
        r = outline.radius
        if l > MAX_L_RADII * r:
            raise ValueError(f"state: l = {l:.6g} m is more than {MAX_L_RADII:g} times the "
                             f"outline's radius {r:.6g} m")
        if math.hypot(com[0], com[1]) > MAX_COM_RADII * r:
            raise ValueError(f"state: the COM ({com[0]:.6g}, {com[1]:.6g}) m is more than "
                             f"{MAX_COM_RADII:g} outline radii ({r:.6g} m) from the object "
                             f"frame origin")
    return s


# ------------------------------------------------------------------------------ planner
@dataclass(frozen=True)
class PlannerConfig:
    """Planner parameters, validated on construction (``ValueError`` naming the field).

    Attributes
    ----------
    method : str
        Contact selection: ``ana`` | ``lrn`` (softmax over eq. 5.1 with analytical / learned
        affordances), ``geo`` | ``rdn`` (baselines, :func:`geo_mask` / uniform).
    direct : bool
        Choose the push from the affordances with linear length rescaling instead of rollouts.
    k : int
        Contact points sampled per step, >= 1.
    lam : float
        Rotation weight lambda of eq. (5.1), millimetres per degree, >= 0.
    temperature : float
        Softmax temperature, millimetres (score units), > 0.
    tolerance_xy : float
        Goal position tolerance, metres, > 0.
    tolerance_theta : float
        Goal orientation tolerance, radians, > 0.
    pusher_radius : float
        Radius of the cylindrical pusher, metres, >= 0.
    approach_clearance : float
        Distance of the approach point before the touching position along the push, metres, > 0.
    min_push_length, max_push_length : float
        Range of push lengths past the contact, metres, ``0 < min <= max``.
    substep : float
        Rollout substep, metres, > 0.
    workspace : ((xmin, xmax), (ymin, ymax))
        Rectangle in ``world`` every pusher point must stay in, metres.
    simplify_tolerance : float
        Douglas-Peucker tolerance of the contact polyline (:func:`prepare_outline`), metres.
    seed : int
        Seed of the planner's random generator, >= 0.
    stop_confidence : float
        Confidence of the stop rule (:func:`goal_reached`), in ``[0.5, 1)``; 0.5 stops on the
        point estimate.
    obstacles : tuple of (P_i, 2) polygons
        Walls and other obstacles in ``world`` (metres, either orientation): a push whose
        pusher line from approach to end comes closer than ``pusher_radius`` to one is
        excluded, and the pusher's way in (``plan(pusher=...)``) avoids them. Default none.
    travel_weight : float
        With ``plan(pusher=...)``: score cost of the pusher's travel to the approach point,
        millimetres of score per millimetre of (collision-free, :mod:`push_core.transit`)
        path, >= 0 (0: travel only decides feasibility). Default 0.
    transit_clearance : float
        Distance (m) the pusher centre keeps from the object and the obstacles while it
        travels (``plan(pusher=...)``); 0 (default) means ``pusher_radius + APPROACH_MARGIN``.
        Give a pusher that tracks its path loosely a larger margin.
    require_improvement : bool
        Raise :class:`NoImprovingPush` instead of returning a push whose predicted score is no
        better than the current pose's (default False: the best push is returned anyway).
    two_faces : bool
        Rollouts of frictionless pushes (``m = 0``) let a pusher in an inner corner push both
        faces at once (:func:`push_core.rollout.wedge_twist`); default False (nearest face).
    horizon : int
        Pushes looked ahead (:mod:`push_core.lookahead`), >= 1; 1 (default) is the greedy
        planner: each push chosen by its own predicted score.
    beam : int
        ``horizon > 1``: first pushes looked ahead from, >= 1.
    push_cost : float
        ``horizon > 1``: price of one push in eq. (5.1) score units (mm), >= 0.
    avoid_contradicted : bool
        The episode engine avoids the contact regions of executed pushes whose outcome
        contradicted their prediction (:mod:`push_core.episode`, rule 8); default False.
    """

    method: str = "ana"
    direct: bool = False
    k: int = 3
    lam: float = 2.0
    temperature: float = 2.0
    tolerance_xy: float = 0.0075
    tolerance_theta: float = math.radians(5.0)
    pusher_radius: float = PUSHER_RADIUS
    approach_clearance: float = 0.005
    min_push_length: float = REPRESENTATIVE_LENGTHS[0]
    max_push_length: float = REPRESENTATIVE_LENGTHS[-1]
    substep: float = SUBSTEP
    workspace: tuple[tuple[float, float], tuple[float, float]] = ((-0.25, 0.25), (-0.3, 0.3))
    simplify_tolerance: float = 5e-4
    seed: int = 0
    stop_confidence: float = STOP_CONFIDENCE
    obstacles: tuple = ()
    travel_weight: float = 0.0
    transit_clearance: float = 0.0
    require_improvement: bool = False
    two_faces: bool = False
    horizon: int = 1
    beam: int = 8
    push_cost: float = 20.0
    avoid_contradicted: bool = False

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {self.method!r}")
        if not isinstance(self.direct, bool | np.bool_):
            raise ValueError(f"direct: expected a bool, got {self.direct!r}")
        object.__setattr__(self, "direct", bool(self.direct))
        for name, low in (("k", 1), ("seed", 0), ("horizon", 1), ("beam", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
                raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
            object.__setattr__(self, name, int(value))
        for name, strict in (("lam", False), ("temperature", True), ("tolerance_xy", True),
                             ("tolerance_theta", True), ("pusher_radius", False),
                             ("approach_clearance", True), ("min_push_length", True),
                             ("max_push_length", True), ("substep", True),
                             ("simplify_tolerance", False), ("travel_weight", False),
                             ("transit_clearance", False), ("push_cost", False)):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"{name}: expected a number, got {value!r}") from None
            ok = math.isfinite(value) and (value > 0.0 if strict else value >= 0.0)
            if not ok:
                raise ValueError(f"{name}: must be finite and {'>' if strict else '>='} 0, "
                                 f"got {value!r}")
            object.__setattr__(self, name, value)
        try:
            stop_quantile(self.stop_confidence)
        except (TypeError, ValueError):
            raise ValueError(f"stop_confidence: must be a number in [0.5, 1), got "
                             f"{self.stop_confidence!r}") from None
        object.__setattr__(self, "stop_confidence", float(self.stop_confidence))
        if self.max_push_length < self.min_push_length:
            raise ValueError(f"max_push_length: must be >= min_push_length "
                             f"({self.min_push_length}), got {self.max_push_length}")
        try:
            ws = np.array(self.workspace, dtype=float)
        except (TypeError, ValueError):
            ws = np.zeros(0)
        if ws.shape != (2, 2) or not np.all(np.isfinite(ws)) or np.any(ws[:, 1] <= ws[:, 0]):
            raise ValueError(f"workspace: expected ((xmin, xmax), (ymin, ymax)) with min < max, "
                             f"got {self.workspace!r}")
        object.__setattr__(self, "workspace", tuple(tuple(float(v) for v in r) for r in ws))
        for name in ("require_improvement", "two_faces", "avoid_contradicted"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                raise ValueError(f"{name}: expected a bool, got {getattr(self, name)!r}")
            object.__setattr__(self, name, bool(getattr(self, name)))
        obstacles = []
        for i, poly in enumerate(self.obstacles):
            p = ccw_polygon(poly, f"obstacles[{i}]")
            p.setflags(write=False)
            obstacles.append(p)
        object.__setattr__(self, "obstacles", tuple(obstacles))

    @property
    def clearance(self) -> float:
        """The transit clearance in use (:attr:`transit_clearance`, or its default)."""
        return self.transit_clearance or self.pusher_radius + APPROACH_MARGIN


@dataclass(frozen=True)
class PushPlan:
    """The planner's answer for one step. Points in ``world`` (metres).

    Attributes
    ----------
    approach, contact, end : numpy.ndarray, shape (2,)
        Pusher axis: lowered at ``approach``, touching at ``contact``, stopping at ``end``.
    index : int
        Outline point of the contact.
    angle : float
        Push direction relative to the inward normal at that point, radians (counter-clockwise).
    length : float
        Push length ``|end - contact|``, metres.
    predicted_pose : numpy.ndarray, shape (3,)
        Object pose after the push predicted by the rollout (or the affordances, ``direct``).
    score : float
        Eq. (5.1) of the predicted residual to the goal, millimetres.
    current_score : float
        Eq. (5.1) of the residual without pushing, millimetres.
    scores : numpy.ndarray, shape (N,)
        Eq. (5.1) of every outline point from the affordances (``ana``: analytical; ``lrn``:
        learned; ``geo``/``rdn``: analytical, for display).
    probabilities : numpy.ndarray, shape (N,)
        The distribution the candidates were drawn from.
    candidates : numpy.ndarray of intp, shape (k',)
        The sampled outline points (``k' <= k``), in the order drawn.
    fallback : bool
        No sampled candidate had a feasible push; every other eligible point was tried.
    method : str
    direct : bool
    travel : float
        Length of the pusher's way in (``plan(pusher=...)``), metres; 0 without it.
    """

    approach: NDArray[np.float64]
    contact: NDArray[np.float64]
    end: NDArray[np.float64]
    index: int
    angle: float
    length: float
    predicted_pose: NDArray[np.float64]
    score: float
    current_score: float
    scores: NDArray[np.float64]
    probabilities: NDArray[np.float64]
    candidates: NDArray[np.intp]
    fallback: bool = False
    method: str = "ana"
    direct: bool = False
    travel: float = 0.0


@dataclass
class _Options:
    """Evaluated pushes (flat batch): outline index, angle, best length and its outcome."""

    index: NDArray[np.intp]
    angle: NDArray[np.float64]
    length: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    score: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    pose: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    travel: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    group: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))


def _allowed_points(points: NDArray[np.float64], avoid: ArrayLike | None) -> NDArray[np.bool_]:
    """Outline points farther than ``AVOID_RADIUS`` from every ``avoid`` point (all of them if
    ``avoid`` is None or empty, or would exclude every point)."""
    allowed = np.ones(len(points), dtype=bool)
    if avoid is None:
        return allowed
    a = np.asarray(avoid, dtype=np.float64)
    if a.size == 0:
        return allowed
    if a.ndim != 2 or a.shape[1] != 2 or not np.all(np.isfinite(a)):
        raise ValueError(f"avoid: expected finite points of shape (M, 2), got shape {a.shape}")
    for i in range(0, len(a), _AVOID_CHUNK):  # memory N x chunk, whatever M
        chunk = a[i:i + _AVOID_CHUNK]
        near = np.linalg.norm(points[:, None, :] - chunk[None, :, :], axis=-1) <= AVOID_RADIUS
        allowed &= ~near.any(axis=1)
    return allowed if allowed.any() else np.ones(len(points), dtype=bool)


class Planner:
    """The greedy push planner (module docstring).

    Parameters
    ----------
    config : PlannerConfig
        Parameters (already validated).
    affordance_model : AffordanceModel, optional
        Required for ``method = "lrn"`` (e.g. ``push_core.learned.LearnedAffordances``); the
        other methods use :func:`push_core.affordances.analytical_affordances`.

    Raises
    ------
    ValueError
        ``config`` is not a PlannerConfig, or ``lrn`` without a model.
    """

    def __init__(self, config: PlannerConfig | None = None,
                 affordance_model: AffordanceModel | None = None) -> None:
        config = PlannerConfig() if config is None else config
        if not isinstance(config, PlannerConfig):
            raise ValueError(f"config: expected a PlannerConfig, got {type(config).__name__}")
        if config.method == "lrn" and affordance_model is None:
            raise ValueError("affordance_model: method 'lrn' needs a learned affordance model")
        self.config = config
        self._affordances = affordance_model if config.method == "lrn" else analytical_affordances
        self.rng = np.random.default_rng(config.seed)

    def reached(self, pose: ArrayLike, goal: ArrayLike, covariance: ArrayLike | None = None,
                outline: Outline | None = None) -> bool:
        """The stop rule (:func:`goal_reached`) with the configured tolerances and confidence.

        ``covariance``: of the pose estimate ((3, 3) or the estimator's (7, 7); None = exact
        state). ``outline``: the orientation is ignored when ``outline.orientation_matters``
        is False (a continuously symmetric object).
        """
        cfg = self.config
        orientation = outline is None or outline.orientation_matters
        return goal_reached(pose, goal, cfg.tolerance_xy, cfg.tolerance_theta, covariance,
                            cfg.stop_confidence, orientation)

    def check_outline(self, outline: Outline) -> Outline:
        """``outline`` if the object fits the workspace, else ``ValueError`` (``outline: ...``).

        Refused: an outline whose radius (:attr:`Outline.radius`) exceeds the diagonal of the
        workspace rectangle (no pose puts such an object on the table; planning for it would
        only search every point for a feasible push). Not called by :meth:`plan` (which
        raises :class:`NoFeasiblePush` for such an object); ``planner_node`` refuses the
        outline with it.
        """
        if not isinstance(outline, Outline):
            raise ValueError(f"outline: expected an Outline (prepare_outline), got "
                             f"{type(outline).__name__}")
        (x0, x1), (y0, y1) = self.config.workspace
        diagonal = math.hypot(x1 - x0, y1 - y0)
        if not outline.radius <= diagonal:
            raise ValueError(f"outline: the object's radius {outline.radius:.6g} m exceeds the "
                             f"workspace diagonal {diagonal:.6g} m")
        return outline

    def _lam(self, outline: Outline) -> float:
        """The rotation weight of eq. (5.1): 0 when the orientation does not matter."""
        return self.config.lam if outline.orientation_matters else 0.0

    def plan(self, outline: Outline, state: ArrayLike, goal: ArrayLike,
             avoid: ArrayLike | None = None, pusher: ArrayLike | None = None) -> PushPlan:
        """Plan one push.

        Parameters
        ----------
        outline : Outline
            From :func:`prepare_outline` (object frame).
        state : array_like, shape (7,)
            ``(x, y, theta, c_x, c_y, l, m)``: object pose in ``world`` (m, rad), COM offset in
            the object frame (m), limit-surface parameter (m, > 0), pusher friction (>= 0); the
            layout of the estimator's state.
        goal : array_like, shape (3,)
            Goal pose ``(x, y, theta)`` of the object frame in ``world``.
        avoid : array_like, shape (M, 2), optional
            Object-frame points (the outline points of pushes the robot refused since the
            object last moved): outline points within ``AVOID_RADIUS`` of any are not used, so
            a refused push is not planned again from the same estimate. Ignored when it would
            leave no point; None or empty changes nothing (the same plan, the same random
            draws).
        pusher : array_like, shape (2,), optional
            Where the pusher centre is now (``world``), for a pusher that cannot lift: each
            push needs a collision-free way from here to its approach point around the object
            and ``config.obstacles`` (:class:`push_core.transit.TransitPlanner` with
            ``config.clearance``; pushes without one are infeasible) and costs
            ``config.travel_weight`` times its length (``PushPlan.travel``). None (default):
            the pusher is lowered at the approach point from above.

        Returns
        -------
        PushPlan

        Raises
        ------
        ValueError
            Bad ``outline``, ``state`` (:func:`check_state`) or ``goal`` (the message names
            it).
        NoFeasiblePush
            No outline point admits a feasible push (see the module docstring).
        NoImprovingPush
            ``config.require_improvement`` and no feasible push is predicted to improve on the
            current pose (its ``plan`` is the best push found).
        """
        cfg = self.config
        if pusher is not None:
            pusher = _vector(pusher, 2, "pusher")
        if not isinstance(outline, Outline):
            raise ValueError(f"outline: expected an Outline (prepare_outline), got "
                             f"{type(outline).__name__}")
        state = check_state(state, outline)
        goal = _vector(goal, 3, "goal")
        pose, com, l, m = state[:3], state[3:5], float(state[5]), float(state[6])  # noqa: E741
        desired = desired_motion(pose, goal)
        if not outline.orientation_matters:  # a disc: only the position of the goal counts
            desired[2] = 0.0
        aff = np.asarray(self._affordances(outline.points, outline.normals, com, l, m))
        lam = self._lam(outline)
        scores = point_scores(aff, desired, lam)

        n = len(outline.points)
        allowed = _allowed_points(outline.points, avoid)
        if cfg.method in ("ana", "lrn"):
            eligible = allowed
            sampled = scores if allowed.all() else np.where(allowed, scores, np.inf)
            probabilities = softmax_probabilities(sampled, cfg.temperature)
            candidates = sample_contacts(sampled, cfg.k, cfg.temperature, self.rng)
        else:
            eligible = (geo_mask(outline.points, outline.normals, desired)
                        if cfg.method == "geo" else np.ones(n, dtype=bool)) & allowed
            if not eligible.any():  # e.g. a goal direction no outline point is behind
                eligible = allowed.copy()
            probabilities = eligible / np.count_nonzero(eligible)
            pool = np.flatnonzero(eligible)
            candidates = self.rng.choice(pool, size=min(cfg.k, pool.size), replace=False)

        options = self._evaluate(outline, pose, com, l, m, goal, desired, aff, candidates)
        options = self._reachable(outline, pose, options, pusher)
        fallback = not np.isfinite(options.score).any()
        if fallback:
            rest = np.flatnonzero(eligible & ~np.isin(np.arange(n), candidates))
            rest = rest[np.argsort(scores[rest], kind="stable")][:MAX_FALLBACK_POINTS]
            if rest.size:
                options = self._evaluate(outline, pose, com, l, m, goal, desired, aff, rest)
                options = self._reachable(outline, pose, options, pusher)
            if not np.isfinite(options.score).any():
                raise NoFeasiblePush(
                    "no outline point admits a push with its approach and end point inside the "
                    f"workspace {cfg.workspace} and an approach clear of the object")
        value = options.score
        if cfg.horizon > 1:
            value = lookahead.sequence_values(
                options.score, options.pose, self._reached_ahead(outline, options.pose, goal),
                options.group if len(options.group) == len(options.score)
                else np.zeros(len(options.score), dtype=np.intp),  # direct: one group
                lambda poses: self._expand(outline, com, l, m, goal, aff, poses),
                cfg.horizon, cfg.beam, cfg.push_cost)
            if not np.isfinite(value).any():
                value = options.score
        cost = value + cfg.travel_weight * 1e3 * np.where(np.isfinite(options.travel),
                                                          options.travel, 0.0)
        best = int(np.argmin(cost))
        index, angle, length = (int(options.index[best]), float(options.angle[best]),
                                float(options.length[best]))
        approach, contact, end = self._pusher_points(outline, pose, options.index[best:best + 1],
                                                     options.angle[best:best + 1],
                                                     options.length[best:best + 1])
        result = PushPlan(
            approach=approach[0], contact=contact[0], end=end[0], index=index, angle=angle,
            length=length, predicted_pose=options.pose[best].copy(),
            score=float(options.score[best]), current_score=float(motion_score(desired, lam)),
            scores=scores, probabilities=probabilities, candidates=np.asarray(candidates),
            fallback=fallback, method=cfg.method, direct=cfg.direct,
            travel=float(options.travel[best]))
        if cfg.require_improvement and not result.score < result.current_score:
            raise NoImprovingPush(
                f"no push improves on the current pose: the best predicted score "
                f"{result.score:.3f} mm is not below the current {result.current_score:.3f} mm",
                result)
        return result

    def _reachable(self, outline: Outline, pose: NDArray[np.float64], options: _Options,
                   pusher: NDArray[np.float64] | None) -> _Options:
        """Exclude pushes whose pusher line (approach to end) meets an obstacle and, with a
        ``pusher`` position, those without a way in; record the travel lengths (metres)."""
        cfg = self.config
        options.travel = np.zeros(len(options.score))
        ok = np.isfinite(options.score)
        if not ok.any() or (pusher is None and not cfg.obstacles):
            return options
        approach, _, end = self._pusher_points(outline, pose, options.index, options.angle,
                                               options.length)
        if cfg.obstacles:
            ok[ok] = segment_polygon_clear(approach[ok], end[ok], cfg.obstacles,
                                           cfg.pusher_radius)
        if pusher is not None and ok.any():
            body = object_to_world(pose, outline.polyline)
            transit = TransitPlanner([body, *cfg.obstacles], cfg.clearance, cfg.workspace)
            options.travel[ok] = transit.lengths(pusher, approach[ok])
            ok &= np.isfinite(options.travel)
        options.score = np.where(ok, options.score, np.inf)
        return options

    def transit(self, outline: Outline, pose: ArrayLike, pusher: ArrayLike,
                target: ArrayLike) -> NDArray[np.float64] | None:
        """The pusher's collision-free way (K, 2) from ``pusher`` to ``target`` (usually
        ``PushPlan.approach``) around the object at ``pose`` and ``config.obstacles``, world
        frame, or None if there is none (:meth:`push_core.transit.TransitPlanner.path`)."""
        cfg = self.config
        pose = _vector(pose, 3, "pose")
        body = object_to_world(pose, outline.polyline)
        transit = TransitPlanner([body, *cfg.obstacles], cfg.clearance, cfg.workspace)
        return transit.path(_vector(pusher, 2, "pusher"), _vector(target, 2, "target"))

    # -------------------------------------------------------------- internals
    def _evaluate(self, outline: Outline, pose: NDArray[np.float64], com: NDArray[np.float64],
                  l: float, m: float, goal: NDArray[np.float64],  # noqa: E741
                  desired: NDArray[np.float64], aff: NDArray[np.float64],
                  candidates: NDArray[np.intp]) -> _Options:
        """Best push (direction and length) at each candidate point; flat over the options."""
        if self.config.direct:
            return self._direct(outline, pose, desired, aff, candidates)
        # One batched rollout for the base directions and the interpolated ones between every
        # pair of neighbouring base directions (a rollout call costs the same for 15 or 40
        # pushes); only the interpolated directions next to a candidate's best base direction
        # are then admitted, which gives the result of the sequential procedure.
        n_fine = len(_FINE_ANGLES)
        idx, ang = np.repeat(candidates, n_fine), np.tile(_FINE_ANGLES, len(candidates))
        if self.config.horizon > 1:
            return self._first_pushes(outline, pose, com, l, m, goal, idx, ang)
        opts = self._rollouts(outline, pose, com, l, m, goal, idx, ang)
        opts.score = np.where(_admitted(opts.score), opts.score, np.inf)
        return opts

    # -------------------------------------------------------------- lookahead (horizon > 1)
    def _first_pushes(self, outline: Outline, pose: NDArray[np.float64],
                      com: NDArray[np.float64], l: float, m: float,  # noqa: E741
                      goal: NDArray[np.float64], idx: NDArray[np.intp],
                      ang: NDArray[np.float64]) -> _Options:
        """First pushes of the lookahead (:mod:`push_core.lookahead`, step 1): each rolled-out
        (point, direction) at its greedy length, its best lengths for the rotation-first and
        translation-first sub-goals and its longest feasible length; flat over
        ``lookahead.GROUPS`` x pushes, ``score`` always against the goal."""
        lengths, after, valid = self._trajectories(outline, pose, com, l, m, idx, ang)
        score = self._path_scores(outline, after, valid, goal)
        rows = np.arange(len(idx))
        picks = [np.argmin(score, axis=1)]
        for sub in lookahead.subgoals(pose, goal):
            picks.append(np.argmin(self._path_scores(outline, after, valid, sub), axis=1))
        picks.append(valid.shape[1] - 1 - np.argmax(valid[:, ::-1], axis=1))  # longest
        admitted = _admitted(score[rows, picks[0]])
        n = len(picks)
        j = np.concatenate(picks)
        rep = np.tile(rows, n)
        best = np.where(np.tile(admitted, n), score[rep, j], np.inf)
        return _Options(index=np.tile(idx, n), angle=np.tile(ang, n), length=lengths[j],
                        score=best, pose=after[rep, j],
                        group=np.repeat(np.arange(n, dtype=np.intp), len(idx)))

    def _reached_ahead(self, outline: Outline, poses: NDArray[np.float64],
                       goal: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Predicted poses (B, 3) inside the goal region shrunk to ``REACH_FRACTION``."""
        cfg = self.config
        f = lookahead.REACH_FRACTION
        near = np.hypot(goal[0] - poses[:, 0], goal[1] - poses[:, 1]) <= f * cfg.tolerance_xy
        if not outline.orientation_matters:
            return near
        return near & (np.abs(wrap_angle(goal[2] - poses[:, 2])) <= f * cfg.tolerance_theta)

    def _expand(self, outline: Outline, com: NDArray[np.float64], l: float,  # noqa: E741
                m: float, goal: NDArray[np.float64], aff: NDArray[np.float64],
                poses: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """The best next push from each pose (B, 3) (``lookahead.Expand``): at the ``k``
        best-scoring outline points by the affordances, the 5 base directions, one rollout in
        substeps of ``lookahead.CONTINUATION_SUBSTEP``."""
        cfg = self.config
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        dx, dy = goal[0] - poses[:, 0], goal[1] - poses[:, 1]
        desired = np.stack([c * dx + s * dy, -s * dx + c * dy,
                            wrap_angle(goal[2] - poses[:, 2]) if outline.orientation_matters
                            else np.zeros(len(poses))], -1)  # (B, 3) object frames
        lam = self._lam(outline)
        point = motion_score(desired[:, None, None, :] - aff[None], lam).min(axis=2)  # (B, N)
        k = min(cfg.k, point.shape[1])
        top = np.argpartition(point, k - 1, axis=1)[:, :k]  # (B, k)
        n_fine = len(_BASE_COLUMNS)
        idx = np.repeat(top.reshape(-1), n_fine)
        ang = np.tile(_FINE_ANGLES[_BASE_COLUMNS], top.size)
        start = np.repeat(poses, k * n_fine, axis=0)
        lengths, after, valid = self._trajectories(outline, start, com, l, m, idx, ang,
                                                   lookahead.CONTINUATION_SUBSTEP)
        score = self._path_scores(outline, after, valid, goal)
        j = np.argmin(score, axis=1)
        rows = np.arange(len(idx))
        best, pose = score[rows, j].reshape(len(poses), -1), after[rows, j]
        pick = np.argmin(best, axis=1)
        chosen = np.arange(len(poses)) * k * n_fine + pick
        nxt = pose[chosen]
        return best[np.arange(len(poses)), pick], nxt, self._reached_ahead(outline, nxt, goal)

    def _pusher_points(self, outline: Outline, pose: NDArray[np.float64], idx: NDArray[np.intp],
                       angle: NDArray[np.float64], length: ArrayLike
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """World approach, contact (touching axis) and end points; shapes broadcast over
        ``idx``, ``angle`` (...) and ``length`` (...), each result (..., 2)."""
        cfg = self.config
        n_out = outline.normals[idx]
        c, s = np.cos(angle), np.sin(angle)
        direction = -np.stack([c * n_out[..., 0] - s * n_out[..., 1],
                               s * n_out[..., 0] + c * n_out[..., 1]], -1)
        touch = outline.points[idx] + cfg.pusher_radius * n_out
        length = np.asarray(length, dtype=np.float64)[..., None]
        approach = object_to_world(pose, touch - cfg.approach_clearance * direction)
        contact = object_to_world(pose, touch)
        end = object_to_world(pose, touch + length * direction)
        return approach, contact, end

    def _in_workspace(self, points: NDArray[np.float64]) -> NDArray[np.bool_]:
        (x0, x1), (y0, y1) = self.config.workspace
        x, y = points[..., 0], points[..., 1]
        return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)

    def _approach_ok(self, outline: Outline, pose: NDArray[np.float64],
                     approach: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Approach points inside the workspace and clear of the object (B,)."""
        local = world_to_object(pose, approach)
        _, _, dist, _ = closest_point_on_polyline(outline.polyline, local)
        cfg = self.config
        clear = dist >= cfg.pusher_radius + APPROACH_MARGIN + cfg.simplify_tolerance
        return clear & self._in_workspace(approach)

    def _rollouts(self, outline: Outline, pose: NDArray[np.float64], com: NDArray[np.float64],
                  l: float, m: float, goal: NDArray[np.float64],  # noqa: E741
                  idx: NDArray[np.intp], angle: NDArray[np.float64]) -> _Options:
        """Roll out each (point, direction) to ``max_push_length`` and truncate at its best."""
        lengths, after, valid = self._trajectories(outline, pose, com, l, m, idx, angle)
        score = self._path_scores(outline, after, valid, goal)
        j = np.argmin(score, axis=1)
        rows = np.arange(len(idx))
        return _Options(index=np.asarray(idx), angle=np.asarray(angle, dtype=np.float64),
                        length=lengths[j], score=score[rows, j], pose=after[rows, j])

    def _trajectories(self, outline: Outline, pose: NDArray[np.float64],
                      com: NDArray[np.float64], l: float, m: float,  # noqa: E741
                      idx: NDArray[np.intp], angle: NDArray[np.float64],
                      substep: float | None = None
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """One batched rollout of pushes at outline points ``idx`` (B,) and directions
        ``angle`` (B,) from ``pose`` ((3,) or one per push, (B, 3)), to ``max_push_length``,
        in substeps of ``substep`` (m; None: ``config.substep``).

        Returns the push length after every substep (S,) (m past the contact), the predicted
        pose after every substep (B, S, 3) and whether stopping there is feasible (B, S):
        at least ``min_push_length``, end point in the workspace, approach clear.
        """
        cfg = self.config
        approach, contact, _ = self._pusher_points(outline, pose, idx, angle, 0.0)
        direction = (contact - approach) / cfg.approach_clearance  # unit, world
        total = cfg.approach_clearance + cfg.max_push_length
        substep = cfg.substep if substep is None else substep
        res = rollout_push(outline.polyline, pose, com, l, m, approach, total * direction,
                           substep=substep, pusher_radius=cfg.pusher_radius,
                           two_faces=cfg.two_faces)
        n_sub = res.poses.shape[1] - 1
        travelled = np.minimum(substep * np.arange(1, n_sub + 1), total)  # (S,)
        lengths = travelled - cfg.approach_clearance
        ends = approach[:, None, :] + travelled[None, :, None] * direction[:, None, :]
        valid = ((lengths >= cfg.min_push_length - 1e-9)[None, :] & self._in_workspace(ends)
                 & self._approach_ok(outline, pose, approach)[:, None])
        return lengths, res.poses[:, 1:], valid

    def _path_scores(self, outline: Outline, after: NDArray[np.float64],
                     valid: NDArray[np.bool_], goal: NDArray[np.float64]) -> NDArray[np.float64]:
        """Eq. (5.1) of poses ``after`` (B, S, 3) against ``goal`` ((3,) or (B, 3)); inf where
        not ``valid``."""
        g = goal if goal.ndim == 1 else goal[:, None, :]
        residual = np.concatenate([g[..., :2] - after[..., :2], g[..., 2:] - after[..., 2:]], -1)
        score = motion_score(residual, self._lam(outline))
        return np.where(valid, score, np.inf)

    def _direct(self, outline: Outline, pose: NDArray[np.float64],
                desired: NDArray[np.float64], aff: NDArray[np.float64],
                candidates: NDArray[np.intp]) -> _Options:
        """Direct variant: affordances with the push length rescaled linearly (no rollouts)."""
        cfg = self.config
        cols = np.array(_BASE_TO_REPR)
        m1 = aff[candidates][:, cols]  # (C, 5, 3) the 1 cm pushes
        m5 = aff[candidates][:, N_ANGLES + cols]  # the 5 cm pushes
        l1, l5 = REPRESENTATIVE_LENGTHS
        n_len = int(round((cfg.max_push_length - cfg.min_push_length) / DIRECT_LENGTH_STEP)) + 1
        grid = np.linspace(cfg.min_push_length, cfg.max_push_length, max(n_len, 1))  # (G,)
        t = ((grid - l1) / (l5 - l1))[None, None, :, None]
        motion = m1[:, :, None] + t * (m5 - m1)[:, :, None]  # (C, 5, G, 3)
        score = motion_score(desired - motion, self._lam(outline))
        n_c, n_a = len(candidates), len(cols)
        idx = np.repeat(candidates, n_a)
        ang = np.tile(np.radians(np.array(BASE_ANGLES_DEG)), n_c)
        approach, _, ends = self._pusher_points(outline, pose, idx[:, None], ang[:, None],
                                                grid[None, :])
        valid = self._in_workspace(ends) & self._approach_ok(outline, pose, approach[:, 0])[:, None]
        score = np.where(valid.reshape(n_c, n_a, -1), score, np.inf).reshape(n_c * n_a, -1)
        j = np.argmin(score, axis=1)
        rows = np.arange(n_c * n_a)
        best = motion.reshape(n_c * n_a, -1, 3)[rows, j]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        moved = np.stack([pose[0] + c * best[:, 0] - s * best[:, 1],
                          pose[1] + s * best[:, 0] + c * best[:, 1], pose[2] + best[:, 2]], -1)
        return _Options(index=idx, angle=ang, length=grid[j], score=score[rows, j], pose=moved)


def _admitted(score: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Directions admitted after the base ones (module docstring, step 4d) for a flat batch
    of ``len(_FINE_ANGLES)`` directions per point: every base direction and the interpolated
    ones next to each point's best base direction."""
    n_fine = len(_FINE_ANGLES)
    score = score.reshape(-1, n_fine)
    best_base = _BASE_COLUMNS[np.argmin(score[:, _BASE_COLUMNS], axis=1)]
    col = np.arange(n_fine)
    admitted = (col % (INTERPOLATION_STEPS + 1) == 0)[None, :] | (
        np.abs(col[None, :] - best_base[:, None]) <= INTERPOLATION_STEPS)
    return admitted.reshape(-1)


def _vector(value: ArrayLike, size: int, name: str) -> NDArray[np.float64]:
    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {size} numbers, got {value!r}") from None
    if v.shape != (size,):
        raise ValueError(f"{name}: expected shape ({size},), got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: must be finite, got {v.tolist()}")
    return v
