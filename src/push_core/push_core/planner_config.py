"""The planner's parameters, :class:`PlannerConfig`, validated on construction, ROS-free.

Units and frames: SI (metres, radians) except the score-valued fields (``lam`` mm/deg,
``temperature``, ``travel_weight``, ``push_cost`` in millimetres of eq. 5.1,
:mod:`push_core.scores`); the workspace and obstacles in ``world``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from push_core.model import REPRESENTATIVE_LENGTHS
from push_core.rollout import PUSHER_RADIUS, SUBSTEP
from push_core.stopping import STOP_CONFIDENCE, stop_quantile
from push_core.transit import ccw_polygon

__all__ = ["APPROACH_MARGIN", "METHODS", "PlannerConfig"]

#: Contact-selection methods: analytical / learned affordances, geometric / random baselines.
METHODS = ("ana", "lrn", "geo", "rdn")
#: Extra clearance beyond the pusher radius between an approach point and the outline, metres
#: (the value ``sim_bridge.world`` enforces).
APPROACH_MARGIN = 5e-4


@dataclass(frozen=True)
class PlannerConfig:
    """Planner parameters, validated on construction (``ValueError`` naming the field).

    Attributes
    ----------
    method : str
        Contact selection: ``ana`` | ``lrn`` (softmax over eq. 5.1 with analytical / learned
        affordances), ``geo`` | ``rdn`` (baselines, :func:`push_core.scores.geo_mask` / uniform).
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
        Douglas-Peucker tolerance of the contact polyline
        (:func:`push_core.plan_inputs.prepare_outline`), metres.
    seed : int
        Seed of the planner's random generator, >= 0.
    stop_confidence : float
        Confidence of the stop rule (:func:`push_core.stopping.goal_reached`), in
        ``[0.5, 1)``; 0.5 stops on the point estimate.
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
        Raise :class:`push_core.planner.NoImprovingPush` instead of returning a push whose
        predicted score is no better than the current pose's (default False: the best push is
        returned anyway).
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
