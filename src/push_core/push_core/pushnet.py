"""A Push-Net-style sampling baseline (Li et al., RSS 2018), ROS-free.

Its place in the evaluation: docs/design/evaluation.md.

Push-Net samples many random pushes from the object's segmentation mask at every step, predicts
the outcome of each and executes the one whose predicted pose is closest to a nearby sub-goal.
This baseline keeps that structure and replaces Push-Net's learned predictor by the analytical
model, so the comparison with the planner (:mod:`push_core.planner`) isolates the *search*:
sampling whole pushes versus choosing contact points from affordances and optimising the push.

One step (:meth:`PushNetPlanner.plan`):

1. **Sub-goal**: the pose at most ``subgoal_xy`` (5 cm) and ``subgoal_theta`` (10 deg) along
   the way from the current pose to the goal: ``pose + t (goal - pose)`` with
   ``t = min(1, subgoal_xy / |dp|, subgoal_theta / |dtheta|)`` (rotation wrapped).
2. **Samples**: ``n_samples`` (1000) straight pushes. The end point is uniform over the
   object's footprint (the polygon of the outline, rejection sampling in its bounding box);
   the start point is uniform over the bounding box grown by ``start_margin`` (5 cm) minus the
   object and a clearance band of ``pusher_radius + APPROACH_MARGIN + simplify_tolerance``
   around it (the pusher must be lowered outside the object). Points are drawn in the object
   frame and mapped to ``world``; pushes leaving the workspace are dropped.
3. **Prediction**: every push is rolled out with the analytical model
   (:func:`push_core.rollout.rollout_push`, one batched call, 5 mm substeps, contact found again
   on the moved outline at every substep) from its start to its end point.
4. **Score**: eq. (5.1) of the planner (:func:`push_core.planner.motion_score`: millimetres +
   ``lam`` x degrees) between the predicted final pose and the sub-goal; pushes that never touch
   the object, whose first touch is farther than ``MAX_APPROACH_DISTANCE`` from the start or
   whose travel after the touch is outside ``[min_push_length, max_push_length]`` score
   ``inf``. The best push is returned, with its ``contact`` at the pusher position at the start
   of the first substep in contact (on the push line, within one substep of the touch).

Frames and units as in :mod:`push_core.planner`: SI, outline in the object frame, poses and
pusher points in ``world``; the state is the estimator's ``(x, y, theta, c_x, c_y, l, m)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import closest_point_on_polyline, object_to_world, wrap_angle
from push_core.planner import (
    APPROACH_MARGIN,
    STOP_CONFIDENCE,
    NoFeasiblePush,
    Outline,
    PlannerConfig,
    goal_reached,
    motion_score,
)
from push_core.rollout import PUSHER_RADIUS, SUBSTEP, rollout_push

__all__ = ["MAX_APPROACH_DISTANCE", "PushNetConfig", "PushNetPlan", "PushNetPlanner",
           "sample_pushes", "subgoal"]

#: Largest distance between the pusher's start and its first touch, metres (the limit of
#: ``sim_bridge.world``'s approach).
MAX_APPROACH_DISTANCE = 0.1
#: Rejection sampling draws this many times the needed points per round.
_OVERSAMPLE = 4


@dataclass(frozen=True)
class PushNetConfig:
    """Parameters of the baseline, validated on construction (``ValueError`` naming the field).

    Attributes
    ----------
    n_samples : int
        Pushes sampled per step (1000 as in Push-Net).
    subgoal_xy : float
        Largest translation of the sub-goal from the current pose, metres.
    subgoal_theta : float
        Largest rotation of the sub-goal from the current pose, radians.
    lam : float
        Rotation weight of eq. (5.1), millimetres per degree (the planner's).
    start_margin : float
        The start points are drawn in the footprint's bounding box grown by this, metres.
    tolerance_xy, tolerance_theta : float
        Goal region (:meth:`PushNetPlanner.reached`), metres and radians.
    pusher_radius : float
        Metres.
    min_push_length, max_push_length : float
        Range of the pusher travel after the first touch, metres.
    substep : float
        Rollout substep, metres.
    workspace : ((xmin, xmax), (ymin, ymax))
        Every pusher point stays in this rectangle of ``world``, metres.
    simplify_tolerance : float
        Tolerance of the outline's contact polyline (``Outline.polyline``), metres.
    seed : int
        Seed of the sampler.
    stop_confidence : float
        Confidence of the stop rule (:func:`push_core.planner.goal_reached`).
    """

    n_samples: int = 1000
    subgoal_xy: float = 0.05
    subgoal_theta: float = math.radians(10.0)
    lam: float = 2.0
    start_margin: float = 0.05
    tolerance_xy: float = 0.0075
    tolerance_theta: float = math.radians(5.0)
    pusher_radius: float = PUSHER_RADIUS
    min_push_length: float = 1e-3
    max_push_length: float = 0.2
    substep: float = SUBSTEP
    workspace: tuple[tuple[float, float], tuple[float, float]] = ((-0.25, 0.25), (-0.3, 0.3))
    simplify_tolerance: float = 5e-4
    seed: int = 0
    stop_confidence: float = STOP_CONFIDENCE

    def __post_init__(self) -> None:
        # The fields shared with the planner are validated (and normalised) by PlannerConfig.
        shared = ("lam", "tolerance_xy", "tolerance_theta", "pusher_radius", "min_push_length",
                  "max_push_length", "substep", "workspace", "simplify_tolerance", "seed",
                  "stop_confidence")
        checked = PlannerConfig(**{name: getattr(self, name) for name in shared})
        for name in shared:
            object.__setattr__(self, name, getattr(checked, name))
        n = self.n_samples
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"n_samples: expected an integer >= 1, got {n!r}")
        object.__setattr__(self, "n_samples", int(n))
        for name in ("subgoal_xy", "subgoal_theta", "start_margin"):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"{name}: expected a number, got {value!r}") from None
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {value!r}")
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class PushNetPlan:
    """The chosen push.

    Attributes
    ----------
    approach, contact, end : numpy.ndarray, shape (2,)
        Pusher axis in ``world``: lowered at ``approach`` (the sampled start), first touch
        expected near ``contact``, stopping at ``end`` (the sampled end point). Collinear.
    predicted_pose : numpy.ndarray, shape (3,)
        Predicted object pose after the push, ``world``.
    subgoal : numpy.ndarray, shape (3,)
        The sub-goal the pushes were scored against, ``world``.
    score : float
        Eq. (5.1) of the predicted pose against the sub-goal, millimetres.
    current_score : float
        Eq. (5.1) of the current pose against the sub-goal, millimetres.
    n_valid : int
        Sampled pushes with a finite score.
    """

    approach: NDArray[np.float64]
    contact: NDArray[np.float64]
    end: NDArray[np.float64]
    predicted_pose: NDArray[np.float64]
    subgoal: NDArray[np.float64]
    score: float
    current_score: float
    n_valid: int


def subgoal(pose: ArrayLike, goal: ArrayLike, max_xy: float, max_theta: float
            ) -> NDArray[np.float64]:
    """The pose at most ``max_xy`` metres and ``max_theta`` radians from ``pose`` toward ``goal``.

    Parameters
    ----------
    pose, goal : array_like, shape (3,)
        ``(x, y, theta)`` in ``world``.
    max_xy, max_theta : float
        Largest translation (m) and rotation (rad) of the sub-goal from ``pose``, > 0.

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``pose + t (goal - pose)`` (rotation difference wrapped to (-pi, pi]) with
        ``t = min(1, max_xy / |dp|, max_theta / |dtheta|)``; the goal itself when it is closer.
    """
    p = np.asarray(pose, dtype=np.float64)
    d = np.asarray(goal, dtype=np.float64) - p
    d[2] = float(wrap_angle(d[2]))
    dist, rot = math.hypot(d[0], d[1]), abs(d[2])
    t = 1.0
    if dist > max_xy:
        t = min(t, max_xy / dist)
    if rot > max_theta:
        t = min(t, max_theta / rot)
    return p + t * d


def _uniform(rng: np.random.Generator, lo: NDArray[np.float64], hi: NDArray[np.float64],
             n: int) -> NDArray[np.float64]:
    return lo + (hi - lo) * rng.random((n, 2))


def sample_pushes(outline: Outline, n: int, rng: np.random.Generator, start_margin: float,
                  clearance: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Random straight pushes in the object frame: start outside the object, end inside it.

    Parameters
    ----------
    outline : Outline
        The object's outline (object frame); its ``polyline`` is the footprint.
    n : int
        Number of pushes.
    rng : numpy.random.Generator
    start_margin : float
        The start points lie in the footprint's bounding box grown by this, metres.
    clearance : float
        Smallest distance of a start point from the outline, metres.

    Returns
    -------
    start, end : numpy.ndarray, shape (n, 2)
        Object frame, metres; ``end`` uniform over the footprint, ``start`` uniform over the
        grown box outside the clearance band.
    """
    poly = outline.polyline
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    ends = _rejection(rng, lo, hi, n, lambda q: closest_point_on_polyline(poly, q)[2] < 0.0)
    starts = _rejection(rng, lo - start_margin, hi + start_margin, n,
                        lambda q: closest_point_on_polyline(poly, q)[2] >= clearance)
    return starts, ends


def _rejection(rng: np.random.Generator, lo: NDArray[np.float64], hi: NDArray[np.float64],
               n: int, accept: object) -> NDArray[np.float64]:
    out: list[NDArray[np.float64]] = []
    have = 0
    for _ in range(1000):
        q = _uniform(rng, lo, hi, _OVERSAMPLE * n)
        q = q[accept(q)]  # type: ignore[operator]
        out.append(q)
        have += len(q)
        if have >= n:
            return np.concatenate(out)[:n]
    raise ValueError("could not sample points in the region (degenerate outline?)")


class PushNetPlanner:
    """The sampling baseline (module docstring); ``plan`` and ``reached`` as :class:`Planner`.

    Parameters
    ----------
    config : PushNetConfig, optional
    """

    def __init__(self, config: PushNetConfig | None = None) -> None:
        config = PushNetConfig() if config is None else config
        if not isinstance(config, PushNetConfig):
            raise ValueError(f"config: expected a PushNetConfig, got {type(config).__name__}")
        self.config = config
        self.rng = np.random.default_rng(config.seed)

    def reached(self, pose: ArrayLike, goal: ArrayLike, covariance: ArrayLike | None = None,
                outline: Outline | None = None) -> bool:
        """The stop rule of :meth:`push_core.planner.Planner.reached` with this config."""
        cfg = self.config
        orientation = outline is None or outline.orientation_matters
        return goal_reached(pose, goal, cfg.tolerance_xy, cfg.tolerance_theta, covariance,
                            cfg.stop_confidence, orientation)

    def plan(self, outline: Outline, state: ArrayLike, goal: ArrayLike,
             avoid: ArrayLike | None = None) -> PushNetPlan:
        """Sample, predict and score pushes; return the best.

        ``avoid`` (refused contact regions, as for :meth:`push_core.planner.Planner.plan`) is
        accepted and not needed: the baseline draws new random pushes every step.

        Parameters
        ----------
        outline : Outline
            Object frame (:func:`push_core.planner.prepare_outline`).
        state : array_like, shape (7,)
            ``(x, y, theta, c_x, c_y, l, m)`` as for :meth:`Planner.plan`.
        goal : array_like, shape (3,)
            Goal pose in ``world``.

        Raises
        ------
        ValueError
            Bad outline, state or goal.
        NoFeasiblePush
            No sampled push touches the object within the limits.
        """
        cfg = self.config
        if not isinstance(outline, Outline):
            raise ValueError(f"outline: expected an Outline (prepare_outline), got "
                             f"{type(outline).__name__}")
        state = _finite("state", state, 7)
        goal = _finite("goal", goal, 3)
        if not state[5] > 0.0 or not state[6] >= 0.0:
            raise ValueError(f"state: l must be > 0 and m >= 0, got l = {state[5]}, "
                             f"m = {state[6]}")
        pose, com, l, m = state[:3], state[3:5], state[5], state[6]  # noqa: E741
        lam = cfg.lam if outline.orientation_matters else 0.0  # a disc: position only
        target = subgoal(pose, goal, cfg.subgoal_xy, cfg.subgoal_theta)
        clearance = cfg.pusher_radius + APPROACH_MARGIN + cfg.simplify_tolerance
        start_o, end_o = sample_pushes(outline, cfg.n_samples, self.rng, cfg.start_margin,
                                       clearance)
        start, end = object_to_world(pose, start_o), object_to_world(pose, end_o)
        (x0, x1), (y0, y1) = cfg.workspace
        inside = np.all((start >= (x0, y0)) & (start <= (x1, y1))
                        & (end >= (x0, y0)) & (end <= (x1, y1)), axis=1)
        start, end = start[inside], end[inside]
        if len(start) == 0:
            raise NoFeasiblePush("no sampled push lies inside the workspace")
        res = rollout_push(outline.polyline, pose, com, l, m, start, end - start,
                           substep=cfg.substep, pusher_radius=cfg.pusher_radius)
        final = res.poses[np.arange(len(start)), res.n_steps]
        touched = res.contact.any(axis=1)
        first = np.argmax(res.contact, axis=1)
        contact = res.pusher[np.arange(len(start)), first]
        approach_len = np.hypot(*(contact - start).T)
        travel = np.hypot(*(end - contact).T)
        ok = (touched & (approach_len <= MAX_APPROACH_DISTANCE)
              & (travel >= cfg.min_push_length) & (travel <= cfg.max_push_length))
        residual = target - final
        score = np.where(ok, motion_score(residual, lam), np.inf)
        if not np.isfinite(score).any():
            raise NoFeasiblePush("no sampled push touches the object within the push limits")
        best = int(np.argmin(score))
        return PushNetPlan(approach=start[best].copy(), contact=contact[best].copy(),
                           end=end[best].copy(), predicted_pose=final[best].copy(),
                           subgoal=target, score=float(score[best]),
                           current_score=float(motion_score(target - pose, lam)),
                           n_valid=int(np.count_nonzero(np.isfinite(score))))


def _finite(name: str, value: ArrayLike, size: int) -> NDArray[np.float64]:
    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {size} numbers, got {value!r}") from None
    if v.shape != (size,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: expected {size} finite numbers, got {value!r}")
    return v
