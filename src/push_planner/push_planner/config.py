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

from push_core.episode import AFTER_GOAL, EpisodeEngine
from push_core.planner import Planner, PlannerConfig
from push_ros.interfaces import SIM_TIME
from push_ros.node import ParamSpec

__all__ = ["NODE_NAME", "PARAMETERS", "YAML_EXTRA", "YAML_HEADER", "YAML_NOTES",
           "PlannerNodeParams", "episode_parts", "load_learned_model"]

#: The parameter table. Episode parameters are settable (applied on ``~/reset``); the
#: structural ones are read-only.
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("method", "ana", "Contact selection: ana | lrn (sample contact points from a "
              "softmax over the eq. 5.1 scores of analytical / learned affordances), geo | rdn "
              "(baselines: points behind the object on the correct side of the line to the goal "
              "/ uniform)."),
    ParamSpec("direct", False, "Choose the push from the affordances with linear length "
              "rescaling instead of optimising direction and length with rollouts of the "
              "analytical model."),
    ParamSpec("k", 3, "Contact points sampled per step; 1 is often enough, 3 saturates.",
              (1, 1000)),
    ParamSpec("lambda", 2.0, "Rotation weight of eq. 5.1 (score = translation error in mm + "
              "lambda x rotation error in deg), millimetres per degree; tuned on bench_planner "
              "(docs/results/bench_planner.md).", (0.0, 1000.0)),
    ParamSpec("temperature", 2.0, "Softmax temperature of the contact sampling, millimetres "
              "(score units), > 0: small = nearly the best-scoring points only, large = nearly "
              "uniform.", (0.0, 1e6)),
    ParamSpec("goal_tolerance.xy", 0.0075, "Goal position tolerance, m (the evaluation's "
              "'small' region: 0.75 cm).", (1e-4, 1.0)),
    ParamSpec("goal_tolerance.theta", math.radians(5.0), "Goal orientation tolerance, rad "
              "(5 deg); ignored for a rotationally symmetric outline (push_core.symmetry).",
              (1e-4, math.pi)),
    ParamSpec("goal_tolerance.confidence", 0.99, "Confidence of the stop rule: the goal "
              "counts as reached when the estimate lies inside the goal region shrunk by "
              "z = Phi^-1(confidence) standard deviations of estimator/state's pose "
              "covariance (0.99: z = 2.33; 0.5: z = 0, stop on the point estimate).",
              (0.5, 0.999999)),
    ParamSpec("max_steps", 30, "Pushes per episode; after that many the status says 'failed "
              "after max steps'.", (1, 100000)),
    ParamSpec("after_goal", "resume", "When the object leaves the goal region after 'goal "
              "reached' (the point estimate outside it, so uncertainty alone never re-opens "
              "it; counter left_goal): resume (report it and push again, within the same "
              "max_steps) | report (report it only: state 'left'; 'goal reached' again once "
              "the stop rule holds).",
              constraints="resume | report"),
    ParamSpec("push_speed", 0.02, "Pusher speed the plan's pose stamps assume, m/s (the sim "
              "bridge pushes at its own push_speed: keep both equal; quasi-static below about "
              "0.05).",
              (1e-3, 0.5), read_only=True),
    ParamSpec("approach_clearance", 0.005, "Approach point before the touching position on "
              "the push line, m; the rollouts start there, so the way in is checked too.",
              (1e-3, 0.1), read_only=True),
    ParamSpec("pusher_radius", 0.0048, "Radius of the cylindrical pusher, m (the contact "
              "point is the pusher axis touching).", (0.0, 0.05),
              read_only=True),
    ParamSpec("workspace.x_min", -0.25, "Workspace rectangle in world (sim_bridge's), m: goals "
              "outside are refused, pushes whose approach or end point would leave it are never "
              "planned.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.x_max", 0.25, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.y_min", -0.3, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.y_max", 0.3, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("push_timeout", 30.0, "Wall-clock seconds to wait for pusher/executed after "
              "publishing a push; then it counts as lost (still a step) and the node plans again "
              "from the newest estimate.", (0.1, 3600.0), read_only=True),
    ParamSpec("robot_timeout", 300.0, "Longest wait, s of the steady clock, for a robot that "
              "refused a push as not available (disabled for a dry run, no joint states, no "
              "controller, an impossible posture: no other push avoids it): the episode waits "
              "('robot unavailable: <kind>: <reason>', no step spent) until the executor says "
              "on executor/status that it is ready again, then resumes from a frame taken since "
              "the wait began; it fails with that reason after this long.", (0.1, 86400.0)),
    ParamSpec("max_future_stamp", 10.0, "Estimates and pusher/executed stamped more than this "
              "many seconds ahead of the node's clock are refused (one far-future stamp would "
              "make every later estimate look stale), s; not applied while a sim-time clock "
              "reads 0 (no /clock yet), ~/reset recovers from anything accepted then.",
              (0.0, 3600.0), read_only=True),
    ParamSpec("seed", 0, "Seed of the contact sampling (re-seeded on ~/reset).", (0, 2**31 - 1)),
    ParamSpec("lookahead.horizon", 1, "Pushes looked ahead (push_core.lookahead); 1 = greedy.",
              (1, 5)),
    ParamSpec("lookahead.beam", 8, "First pushes looked ahead from (horizon > 1).", (1, 64)),
    ParamSpec("lookahead.push_cost", 20.0, "Price of one push in eq. 5.1 score units, mm "
              "(horizon > 1).", (0.0, 1000.0)),
    ParamSpec("avoid_contradicted", False, "Avoid the contact regions of pushes whose outcome "
              "contradicted their prediction (push_core.episode rule 8)."),
    ParamSpec("lrn_weights", "", "Weights of the learned affordance model (method lrn), a "
              "path; empty = the model bundled in push_planner/models (see its model card).",
              read_only=True),
)

#: The node's name: the top-level key of its parameter file.
NODE_NAME = "planner_node"
#: Written before the table in the parameter file (ROS declares it).
YAML_EXTRA = (SIM_TIME,)
#: Comment at the top of the bundled parameter file (pushbot_bringup/config/push_planner.yaml).
YAML_HEADER = """
Parameters of planner_node (package push_planner): the greedy affordance-based push planner
(docs/design/planner.md; algorithm and units in push_core/planner.py). Values below
are the defaults. Units SI (REP 103: metres, radians, seconds) except where a line says mm or
deg; the table is also in docs/INTERFACES.md.

  pushbot run planner_node --ros-args --params-file src/pushbot_bringup/config/push_planner.yaml
  ros2 run push_planner planner_node --ros-args --params-file \\
      $(ros2 pkg prefix pushbot_bringup)/share/pushbot_bringup/config/push_planner.yaml
  (`ros2 launch pushbot_bringup pushbot.launch.py` loads this file and sets use_sim_time
  from sim:=true|false)

All parameters are read and validated at start-up (a bad value stops the node with a message
naming the parameter and exit status 2). The episode parameters (those not marked read-only)
can be set at run time and take effect on the next ~/reset (an invalid value refuses that
reset). Doubles must be written with a decimal point (2.0, not 2): ROS rejects an integer for a
double parameter."""
#: Comment paragraphs before a parameter in the parameter file.
YAML_NOTES = {
    "use_sim_time": "The node's clock only stamps the plans; the stale-estimate rule compares "
                    "the stamps of the estimates and of pusher/executed, and the push timeout "
                    "runs on the steady clock.",
    "goal_tolerance.xy": "Stop rule (docs/design/stopping.md).",
    "push_speed": "Structural parameters (read-only).",
}

# PlannerConfig field -> parameter name, for error messages.
_FIELD_TO_PARAM = {
    "lam": "lambda", "tolerance_xy": "goal_tolerance.xy",
    "tolerance_theta": "goal_tolerance.theta", "stop_confidence": "goal_tolerance.confidence",
    "workspace": "workspace.x_min/x_max/y_min/y_max", "horizon": "lookahead.horizon",
    "beam": "lookahead.beam", "push_cost": "lookahead.push_cost",
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
    robot_timeout : float
        s of the steady clock (``EpisodeEngine.robot_timeout``).
    """

    planner: PlannerConfig
    max_steps: int
    push_speed: float
    push_timeout: float
    lrn_weights: str
    after_goal: str = "resume"
    max_future_stamp: float = 10.0
    robot_timeout: float = 300.0

    def summary(self) -> str:
        """The settings a user reads in the log: method, k, seed, tolerances, max steps."""
        cfg = self.planner
        return (f"method {cfg.method}{' (direct)' if cfg.direct else ''}, k {cfg.k}, seed "
                f"{cfg.seed}, lambda {cfg.lam} mm/deg, temperature {cfg.temperature} mm, "
                f"tolerance {cfg.tolerance_xy} m / {math.degrees(cfg.tolerance_theta):.2f} deg, "
                f"max steps {self.max_steps}, after the goal: {self.after_goal}"
                + (f", lookahead {cfg.horizon} pushes (beam {cfg.beam}, push cost "
                   f"{cfg.push_cost} mm)" if cfg.horizon > 1 else "")
                + (", contradicted pushes avoided" if cfg.avoid_contradicted else ""))

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
                seed=int(values["seed"]), horizon=int(values["lookahead.horizon"]),
                beam=int(values["lookahead.beam"]), push_cost=values["lookahead.push_cost"],
                avoid_contradicted=bool(values["avoid_contradicted"]))
        except ValueError as exc:
            field, _, rest = str(exc).partition(":")
            raise ValueError(f"parameter '{_FIELD_TO_PARAM.get(field, field)}':{rest}") from None
        for name in ("max_steps", "push_speed", "push_timeout", "robot_timeout"):
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
                   max_future_stamp=future, robot_timeout=float(values["robot_timeout"]))


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




def episode_parts(params: PlannerNodeParams, model: Any = None,
                  counts: dict[str, int] | None = None) -> tuple[Any, Planner, EpisodeEngine]:
    """The learned model (``model``, or loaded when method ``lrn`` needs one), the planner and
    a fresh episode engine (``counts``: the counters to carry on) of ``params``.

    Raises
    ------
    ValueError
        Naming the parameter (the learned model cannot be loaded).
    """
    if params.planner.method == "lrn" and model is None:
        model = load_learned_model(params.lrn_weights)
    planner = Planner(params.planner, affordance_model=model)
    extra = {} if counts is None else {"counts": counts}
    return model, planner, EpisodeEngine(planner, params.max_steps, after_goal=params.after_goal,
                                         robot_timeout=params.robot_timeout, **extra)
