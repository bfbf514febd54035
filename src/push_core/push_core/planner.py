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
   (``lambda = 2`` mm/deg is the tuned default, see ``docs/RESULTS.md``, section bench_planner.)
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
   the batch size (docs/RESULTS.md, bench_planner); afterwards only the interpolated directions
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

Bounded work and memory (no bound binds on a normal input, so normal results are
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

Structure: this module is the planner (:class:`Planner`, :class:`PushPlan`) and the facade of
its parts, whose public names it re-exports: the scores and contact selection of steps 2-3
(:mod:`push_core.scores`), the stop rule (:mod:`push_core.stopping`), the validated outline and
state (:mod:`push_core.plan_inputs`), the parameters (:mod:`push_core.planner_config`) and the
push optimisation of steps 4-5 (:mod:`push_core.push_search`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core import lookahead
from push_core.affordances import AffordanceModel, analytical_affordances
from push_core.geometry import check_vector, object_to_world
from push_core.plan_inputs import (
    MAX_COM_RADII,
    MAX_FRICTION,
    MAX_L_RADII,
    MAX_OUTLINE_POINTS,
    Outline,
    check_state,
    prepare_outline,
)
from push_core.planner_config import APPROACH_MARGIN, METHODS, PlannerConfig
from push_core.push_search import (
    BASE_ANGLES_DEG,
    Options,
    evaluate,
    expand,
    pusher_points,
    reached_ahead,
    rotation_weight,
)
from push_core.scores import (
    desired_motion,
    geo_mask,
    motion_score,
    point_scores,
    sample_contacts,
    softmax_probabilities,
)
from push_core.stopping import STOP_CONFIDENCE, goal_reached, stop_quantile
from push_core.transit import TransitPlanner, segment_polygon_clear

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

#: ``Planner.plan(avoid=...)``: outline points this close (m) to the outline point of a refused
#: push are not used again until the object moves (the robot checks the approach against the
#: true object; a perceived outline rounds sharp corners, and a refused push moves nothing, so
#: the same plan would come again).
AVOID_RADIUS = 0.01
#: The fallback of :meth:`Planner.plan` (no sampled candidate feasible) tries at most this many
#: further points, the best-scoring first (each costs 13 rollouts).
MAX_FALLBACK_POINTS = 256
#: :func:`_allowed_points` compares the outline with at most this many avoided points at a time.
_AVOID_CHUNK = 256


class NoFeasiblePush(RuntimeError):
    """No outline point admits a push inside the workspace with a clear approach."""


class NoImprovingPush(NoFeasiblePush):
    """``PlannerConfig.require_improvement``: no feasible push is predicted to bring the object
    closer to the goal (by eq. 5.1) than it is now. ``plan`` holds the best push found."""

    def __init__(self, message: str, plan: PushPlan) -> None:
        super().__init__(message)
        self.plan = plan


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
            pusher = check_vector(pusher, 2, "pusher")
        if not isinstance(outline, Outline):
            raise ValueError(f"outline: expected an Outline (prepare_outline), got "
                             f"{type(outline).__name__}")
        state = check_state(state, outline)
        goal = check_vector(goal, 3, "goal")
        pose, com, l, m = state[:3], state[3:5], float(state[5]), float(state[6])  # noqa: E741
        desired = desired_motion(pose, goal)
        if not outline.orientation_matters:  # a disc: only the position of the goal counts
            desired[2] = 0.0
        aff = np.asarray(self._affordances(outline.points, outline.normals, com, l, m))
        lam = rotation_weight(self.config, outline)
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

        options = evaluate(cfg, outline, pose, com, l, m, goal, desired, aff, candidates)
        options = self._reachable(outline, pose, options, pusher)
        fallback = not np.isfinite(options.score).any()
        if fallback:
            rest = np.flatnonzero(eligible & ~np.isin(np.arange(n), candidates))
            rest = rest[np.argsort(scores[rest], kind="stable")][:MAX_FALLBACK_POINTS]
            if rest.size:
                options = evaluate(cfg, outline, pose, com, l, m, goal, desired, aff, rest)
                options = self._reachable(outline, pose, options, pusher)
            if not np.isfinite(options.score).any():
                raise NoFeasiblePush(
                    "no outline point admits a push with its approach and end point inside the "
                    f"workspace {cfg.workspace} and an approach clear of the object")
        value = options.score
        if cfg.horizon > 1:
            value = lookahead.sequence_values(
                options.score, options.pose, reached_ahead(cfg, outline, options.pose, goal),
                options.group if len(options.group) == len(options.score)
                else np.zeros(len(options.score), dtype=np.intp),  # direct: one group
                lambda poses: expand(cfg, outline, com, l, m, goal, aff, poses),
                cfg.horizon, cfg.beam, cfg.push_cost)
            if not np.isfinite(value).any():
                value = options.score
        cost = value + cfg.travel_weight * 1e3 * np.where(np.isfinite(options.travel),
                                                          options.travel, 0.0)
        best = int(np.argmin(cost))
        index, angle, length = (int(options.index[best]), float(options.angle[best]),
                                float(options.length[best]))
        approach, contact, end = pusher_points(cfg, outline, pose, options.index[best:best + 1],
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

    def _reachable(self, outline: Outline, pose: NDArray[np.float64], options: Options,
                   pusher: NDArray[np.float64] | None) -> Options:
        """Exclude pushes whose pusher line (approach to end) meets an obstacle and, with a
        ``pusher`` position, those without a way in; record the travel lengths (metres)."""
        cfg = self.config
        options.travel = np.zeros(len(options.score))
        ok = np.isfinite(options.score)
        if not ok.any() or (pusher is None and not cfg.obstacles):
            return options
        approach, _, end = pusher_points(cfg, outline, pose, options.index, options.angle,
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
        pose = check_vector(pose, 3, "pose")
        body = object_to_world(pose, outline.polyline)
        transit = TransitPlanner([body, *cfg.obstacles], cfg.clearance, cfg.workspace)
        return transit.path(check_vector(pusher, 2, "pusher"), check_vector(target, 2, "target"))
