"""``planner_node``'s parameters: the declared table and the typed, validated configuration.

:data:`PARAMETERS` is the one declaration of every parameter (name, default, description with
unit, bounds, read-only); :meth:`PlannerNodeParams.from_values` builds the node's frozen
configuration from the values and raises ``ValueError`` naming the parameter (start-up fails,
a set or ``~/reset`` is refused). Episode parameters are settable and apply on ``~/reset``; the
structural ones are read-only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from push_core.episode import AFTER_GOAL
from push_core.planner import PlannerConfig
from push_ros.node import ParamSpec

__all__ = ["PARAMETERS", "PlannerNodeParams", "load_learned_model"]

#: The parameter table. Episode parameters are settable (applied on ``~/reset``); the
#: structural ones are read-only.
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("method", "ana", "Contact selection: ana | lrn (softmax over eq. 5.1 with "
              "analytical / learned affordances), geo | rdn (geometric / uniform baselines)."),
    ParamSpec("direct", False, "Choose the push from the affordances with linear length "
              "rescaling instead of optimising it with rollouts."),
    ParamSpec("k", 3, "Contact points sampled per step.", (1, 1000)),
    ParamSpec("lambda", 2.0, "Rotation weight of eq. 5.1, millimetres per degree.",
              (0.0, 1000.0)),
    ParamSpec("temperature", 2.0, "Softmax temperature of the contact sampling, millimetres "
              "(score units), > 0.", (0.0, 1e6)),
    ParamSpec("goal_tolerance.xy", 0.0075, "Goal position tolerance, m.", (1e-4, 1.0)),
    ParamSpec("goal_tolerance.theta", math.radians(5.0), "Goal orientation tolerance, rad.",
              (1e-4, math.pi)),
    ParamSpec("goal_tolerance.confidence", 0.99, "Confidence of the stop rule: the goal "
              "counts as reached when the estimate lies inside the goal region shrunk by "
              "Phi^-1(confidence) of its standard deviations (0.5 = stop on the point "
              "estimate).", (0.5, 0.999999)),
    ParamSpec("max_steps", 30, "Pushes per episode before it fails.", (1, 100000)),
    ParamSpec("after_goal", "resume", "When the object leaves the goal region after 'goal "
              "reached' (the point estimate outside it): resume (report it and push again, "
              "within max_steps) | report (report it only).",
              constraints="resume | report"),
    ParamSpec("push_speed", 0.02, "Pusher speed the plan's pose stamps assume, m/s.",
              (1e-3, 0.5), read_only=True),
    ParamSpec("approach_clearance", 0.005, "Approach point before the touching position, m.",
              (1e-3, 0.1), read_only=True),
    ParamSpec("pusher_radius", 0.0048, "Radius of the cylindrical pusher, m.", (0.0, 0.05),
              read_only=True),
    ParamSpec("workspace.x_min", -0.25, "Workspace rectangle in world (goals and every pusher "
              "point must lie inside), m.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.x_max", 0.25, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.y_min", -0.3, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.y_max", 0.3, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("push_timeout", 30.0, "Wall-clock seconds to wait for pusher/executed before a "
              "push counts as lost.", (0.1, 3600.0), read_only=True),
    ParamSpec("max_future_stamp", 10.0, "Estimates and pusher/executed stamped more than this "
              "many seconds ahead of the node's clock are refused, s (not applied while a "
              "sim-time clock reads 0).", (0.0, 3600.0), read_only=True),
    ParamSpec("seed", 0, "Seed of the contact sampling (re-seeded on ~/reset).", (0, 2**31 - 1)),
    ParamSpec("lrn_weights", "", "Weights of the learned affordance model (method lrn); "
              "empty = the bundled model.", read_only=True),
)

# PlannerConfig field -> parameter name, for error messages.
_FIELD_TO_PARAM = {
    "lam": "lambda", "tolerance_xy": "goal_tolerance.xy",
    "tolerance_theta": "goal_tolerance.theta", "stop_confidence": "goal_tolerance.confidence",
    "workspace": "workspace.x_min/x_max/y_min/y_max",
}


@dataclass(frozen=True)
class PlannerNodeParams:
    """The node's parameters, typed and validated.

    Attributes
    ----------
    planner : PlannerConfig
        Everything the planning core uses (validated by its constructor).
    max_steps : int
        Pushes per episode.
    push_speed : float
        m/s.
    push_timeout : float
        s of wall time.
    lrn_weights : str
        Path of the learned model's weights, "" = bundled.
    after_goal : str
        ``resume`` | ``report`` (:data:`push_core.episode.AFTER_GOAL`).
    max_future_stamp : float
        s.
    """

    planner: PlannerConfig
    max_steps: int
    push_speed: float
    push_timeout: float
    lrn_weights: str
    after_goal: str = "resume"
    max_future_stamp: float = 10.0

    def summary(self) -> str:
        """The settings a user reads in the log: method, k, seed, tolerances, max steps."""
        cfg = self.planner
        return (f"method {cfg.method}{' (direct)' if cfg.direct else ''}, k {cfg.k}, seed "
                f"{cfg.seed}, lambda {cfg.lam} mm/deg, temperature {cfg.temperature} mm, "
                f"tolerance {cfg.tolerance_xy} m / {math.degrees(cfg.tolerance_theta):.2f} deg, "
                f"max steps {self.max_steps}, after the goal: {self.after_goal}")

    @classmethod
    def from_values(cls, values: dict[str, Any]) -> PlannerNodeParams:
        """Build from ``{parameter name: value}``.

        Raises
        ------
        ValueError
            Naming the parameter.
        """
        try:
            config = PlannerConfig(
                method=str(values["method"]).strip(), direct=bool(values["direct"]),
                k=int(values["k"]), lam=values["lambda"], temperature=values["temperature"],
                tolerance_xy=values["goal_tolerance.xy"],
                tolerance_theta=values["goal_tolerance.theta"],
                stop_confidence=values["goal_tolerance.confidence"],
                pusher_radius=values["pusher_radius"],
                approach_clearance=values["approach_clearance"],
                workspace=((values["workspace.x_min"], values["workspace.x_max"]),
                           (values["workspace.y_min"], values["workspace.y_max"])),
                seed=int(values["seed"]))
        except ValueError as exc:
            field, _, rest = str(exc).partition(":")
            raise ValueError(f"parameter '{_FIELD_TO_PARAM.get(field, field)}':{rest}") from None
        for name in ("max_steps", "push_speed", "push_timeout"):
            if not values[name] > 0:
                raise ValueError(f"parameter '{name}': must be > 0, got {values[name]!r}")
        after_goal = str(values["after_goal"]).strip()
        if after_goal not in AFTER_GOAL:
            raise ValueError(f"parameter 'after_goal': expected one of {', '.join(AFTER_GOAL)}, "
                             f"got {values['after_goal']!r}")
        future = float(values["max_future_stamp"])
        if not (math.isfinite(future) and future >= 0.0):
            raise ValueError(f"parameter 'max_future_stamp': must be finite and >= 0, got "
                             f"{values['max_future_stamp']!r}")
        return cls(planner=config, max_steps=int(values["max_steps"]),
                   push_speed=float(values["push_speed"]),
                   push_timeout=float(values["push_timeout"]),
                   lrn_weights=str(values["lrn_weights"]), after_goal=after_goal,
                   max_future_stamp=future)


def load_learned_model(weights: str) -> Any:
    """The learned affordance model (``push_core.learned``), ``ValueError`` if unavailable."""
    try:
        from push_core.learned import load_affordance_model
    except ImportError as exc:
        raise ValueError(f"parameter 'method': lrn needs push_core.learned ({exc})") from None
    from push_planner.models import default_weights

    path = weights or str(default_weights())
    try:
        return load_affordance_model(path)
    except (OSError, ValueError, RuntimeError) as exc:
        raise ValueError(f"parameter 'lrn_weights': cannot load {path!r}: {exc}") from None


