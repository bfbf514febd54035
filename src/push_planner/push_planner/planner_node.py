"""``planner_node``: the greedy affordance-based push planner behind ROS 2 topics (issue 6).

A thin wrapper around :class:`push_core.planner.Planner` (SPEC section 2 steps 4-5; units,
scores and the algorithm are documented there): it pairs the estimator's outputs into
estimates and decides when to plan. Messages are converted by the codecs of :mod:`push_ros`
(state: :mod:`push_ros.state`; poses and goals: :mod:`push_ros.poses`; ``planner/push``:
:mod:`push_ros.paths`; outline: :mod:`push_ros.outline`; status: :mod:`push_ros.diagnostics`),
except its own ``planner/affordances`` markers (:mod:`push_planner.conversions`). QoS,
parameters and ``main()`` are :mod:`push_ros`'s too; it never imports the simulator.

Subscriptions (names relative and remappable; QoS as in ``docs/ARCHITECTURE.md``):

- ``estimator/state`` (std_msgs/Float64MultiArray; latched, reader queue 10):
  ``x, y, theta, c_x, c_y, l, m`` then the 7 x 7 covariance (layout dims ``state`` 7,
  ``covariance_row_major`` 49).
- ``estimator/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``; latched,
  reader queue 10): the same estimate's pose with its **stamp**; the state message has none.
  Both are transient local, so a planner started after the estimator published still gets
  the last estimate (``push_ros.qos.latched_reader_qos``).
- ``perception/outline`` (sensor_msgs/PointCloud2, ``object``; latched): x, y, z, normal_x,
  normal_y, normal_z float32, counter-clockwise, outward normals.
- ``goal_pose`` (geometry_msgs/PoseStamped, ``world``): RViz's "2D Goal Pose" (volatile) or a
  latched sender (``push_ros.qos.GOAL_QOS``: the graph runner, ``pushbot``'s goal sender).
  Read twice: a reliable *volatile* reader (matches every publisher) and a reliable
  *transient-local* reader (matches latched senders only; it gives a node started or restarted
  mid-episode the last goal, so a restarted planner resumes the episode). A latched sender's
  sample arrives on both and is taken once (same ``publication_sequence_number`` and
  ``source_timestamp``); the transient-local reader's expected QoS mismatch with a volatile
  sender is logged at debug level only. A new goal starts a new episode (step 0). The
  callback takes the message info: a goal from another publisher than the previous goal's
  is still taken, but logged (warning, with the node names and endpoint GIDs of the
  ``goal_pose`` publishers) and noted in the status
  (`` - goal replaced by another publisher ...``, level WARN, ``goal_switches``). rclpy Jazzy's
  message info has no publisher GID, so "another publisher" is decided from
  ``publication_sequence_number`` (a publisher numbers its messages 1, 2, 3, ...: a goal whose
  number does not follow the previous ``goal_pose`` message's comes from another or a
  restarted publisher); a ``publisher_gid`` in the info (later rclpy) is compared instead.
- ``pusher/executed`` (nav_msgs/Path, ``world``; reliable): the executed push; its header stamp
  (= the stamp of its last pose) is the time the push ended.
- ``pusher/refused`` (diagnostic_msgs/DiagnosticStatus; reliable; codec
  :mod:`push_ros.refusal`): whatever executes pushes refuses one. A refusal whose
  ``push_stamp`` is the header stamp of the push in flight counts as a lost push at once (as
  after ``push_timeout``: a step, its contact region avoided; ``pushes_refused``; the status
  notes ``push of step n refused by <who> (<kind>): <reason>``) and the node re-plans; any other
  refusal (stale, another planner's) is ignored (``refusals_ignored``), a malformed one refused.
- ``/clock`` only with ``use_sim_time`` true (default false: wall time; the simulation sets
  it).

Publications:

- ``planner/push`` (nav_msgs/Path, ``world``; reliable): 3 poses, approach, contact (pusher
  axis touching the outline), end; z = 0, oriented along the push, pose stamps = when a pusher
  moving at ``push_speed`` from the approach point at the path's stamp reaches them. The
  header stamps of successive pushes strictly increase (a push at the same clock reading as the
  previous one is stamped ``PUSH_STAMP_STEP_NS`` later), so a refusal names one push.
- ``planner/affordances`` (visualization_msgs/MarkerArray, ``world``; reliable): outline
  coloured by eq. (5.1) score (green = best), the sampled candidates, the chosen push
  (:func:`push_planner.conversions.affordance_markers`).
- ``planner/status`` (diagnostic_msgs/DiagnosticStatus; latched): ``message`` starts with
  ``waiting``, ``pushing step n``, ``goal reached``, ``goal left`` (``after_goal: report``) or
  ``failed`` (``failed after max steps``, ``failed: no feasible push``), followed by
  `` - <note>`` after a refused input (``refused <topic>: <reason>``), a callback error, the
  object leaving a reached goal (``left the goal region: ... off the goal; pushing again``) or
  a goal from another publisher; level OK, WARN (input refused, push lost, goal left, goal
  replaced, callback error) or ERROR (failed). ``values``: ``state`` (waiting | pushing |
  reached | left | failed), ``step``, ``max_steps``, ``goal``, counters (``estimates``,
  ``planned``, ``ignored_stale``, ``ignored_duplicate``, ``ignored_busy``, ``refused`` inputs,
  ``lost`` pushes, ``left_goal``, ``goal_switches``, ``errors``), ``last_refusal``,
  ``last_push_end``, ``outline_stamp`` (header stamp of the outline in use: its episode's
  reference frame), ``after_goal``, ``goal_source``, ``last_error``.
- ``/diagnostics`` (diagnostic_msgs/DiagnosticArray; reliable): the same status, 1 Hz and on
  every change.

Services: ``~/reset`` (std_srvs/srv/Trigger): new episode (a new episode engine: step 0, no
push in flight, the last push end, estimates, the pairing buffers, the goal and its publisher
forgotten, the planner re-seeded); the outline is kept (latched). So whatever was accepted
before (e.g. a far-future push end while a sim-time clock read 0) is cleared by a reset. The episode
parameters (below) are re-read and validated first; an invalid value refuses the reset and
keeps the previous ones. The goal is forgotten because an episode is one goal: with the goal
kept, the first estimate of the next scene would be planned against the previous episode's
goal before the new one arrives (found driving the graph, issue 7).

When it plans: the rules are those of the one episode engine,
:class:`push_core.episode.EpisodeEngine` (the in-process loops drive the same one); this node
feeds it its messages and acts on its decisions. The stale-estimate rule: an *estimate* is an
``estimator/object_pose`` message together with the ``estimator/state`` message of the same
pose (x, y equal to 1 um, theta to 1 urad modulo 2 pi; either may arrive first; the last 10 of
each are kept for pairing); its time is the pose message's stamp. The node plans **exactly
once per estimate** that is

1. newer than every estimate it already used (a re-sent or older estimate is ignored,
   ``ignored_duplicate``),
2. not older than the end of the last executed push (``stamp >= pusher/executed`` end stamp;
   otherwise ``ignored_stale``: it predates the push's effect), and
3. received while no push of its own is in flight (published but not yet reported on
   ``pusher/executed``; ``ignored_busy``) -- the newest such estimate is remembered and used
   as soon as the push is reported, if it satisfies 1-2 then,

and only while an outline and a goal are known and the episode is running. Before planning,
the goal check, the stop rule of :func:`push_core.planner.goal_reached`: the estimate within
``goal_tolerance`` shrunk by ``Phi^-1(goal_tolerance.confidence)`` standard deviations of the
``estimator/state`` pose covariance -> ``goal reached`` (orientation ignored for a continuously
symmetric outline, :mod:`push_core.symmetry`, which the status says); ``max_steps`` pushes
sent -> ``failed after max steps``. A new goal re-opens the newest estimate once (the same
pose, a new question; it is still fresh: nothing has moved since). A push not reported within
``push_timeout`` seconds (wall time; e.g. the robot refused it) counts as a step; the node then
plans again from the newest fresh estimate (nothing has moved, so it is not stale), avoiding
the outline points of the lost pushes (``Planner.plan(avoid=...)``, within ``AVOID_RADIUS``)
until a push is executed or a new outline arrives.

Watching after the goal (:mod:`push_core.episode` rule 7; docs/ARCHITECTURE.md "Episode
engine", rule 5): after ``goal reached`` every further usable estimate is checked by its
*point* estimate (confidence noise never re-opens the goal); outside the goal region the status
says ``left the goal region`` (``left_goal``) and, with ``after_goal: resume`` (default), the
node pushes again within the episode's ``max_steps``; with ``report`` it only reports (``goal
left``) until the stop rule holds again. A ``pusher/executed`` that is not the node's own push
(another client's) is taken like one: estimates before its end are stale, so the next estimate
shows its effect.

Bad input is refused with a (throttled, ``LOG_THROTTLE_S``) warning log, a WARN status and the
``refused`` counter, and changes nothing; the node keeps running. Rules per field:

- ``goal_pose``: frame ``world``; position finite and on the workspace; the quaternion rule of
  :mod:`push_core.geometry` (finite, unit norm within 1e-3, ``|q_x|, |q_y| <= 1e-3``).
- ``perception/outline``: frame ``object``; fields, offsets, steps and sizes consistent
  (:mod:`push_ros.outline`); finite; >= 3 points, counter-clockwise with positive area; more than
  ``push_core.planner.MAX_OUTLINE_POINTS`` (1000) points are decimated to that many (every
  ``N / 1000``-th point); an object whose radius exceeds the workspace diagonal is refused.
- ``estimator/object_pose``: frame ``world``, finite, planar quaternion; its stamp the
  :mod:`push_ros.stamps` rule and at most ``max_future_stamp`` s ahead of the node's clock (not
  applied while a sim-time clock reads 0).
- ``estimator/state``: the documented layout (labels, sizes, offset 0, 56 values), finite,
  covariance finite with a non-negative diagonal.
- estimate (a paired pose + state): :func:`push_core.planner.check_state` against the outline:
  ``0 < l <= 4 r``, ``0 <= m <= 10``, ``|c| <= 2 r`` (``r`` the outline's radius).
- ``pusher/executed``: frame ``world``, at least one pose; its end (the latest of the header's
  and the poses' stamps) by the stamp rule and at most ``max_future_stamp`` ahead.

Every callback (subscriptions, timer, ``~/reset``) is wrapped by :func:`push_ros.node.guarded`:
an exception is logged (throttled), counted (``errors``, ``last_error``), reported on
``planner/status`` and ``/diagnostics``, and the input dropped; the node keeps spinning.
Bounded work per message: the outline cap above and the planner core's bounds
(:mod:`push_core.planner`, "Bounded work and memory").

Parameters (declared once below with descriptors; documented with defaults and units in
``pushbot_bringup/config/push_planner.yaml``; read at start-up and validated by building the
:class:`~push_core.planner.PlannerConfig`, so a bad value fails start-up with a message naming
the parameter; a set that would make it invalid is refused with the reason). Episode
parameters, settable and applied on the next ``~/reset``: ``method``,
``direct``, ``k``, ``lambda``, ``temperature``, ``goal_tolerance.xy``,
``goal_tolerance.theta``, ``goal_tolerance.confidence``, ``max_steps``, ``after_goal``,
``seed``. Read-only: ``push_speed``, ``approach_clearance``, ``pusher_radius``,
``workspace.{x_min,x_max,y_min,y_max}``, ``push_timeout``, ``max_future_stamp``,
``lrn_weights``.

Frames: ``world`` (table, z up), ``object`` (outline). Time: ``use_sim_time`` (the node's
clock stamps the plans; estimates and pushes carry their own stamps, which is all the
stale-estimate rule compares); the push timeout runs on the steady clock.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Path
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from push_core.episode import AFTER_GOAL, EpisodeEngine
from push_core.geometry import wrap_angle
from push_core.planner import Planner, PlannerConfig, PushPlan, check_state, prepare_outline
from push_planner.conversions import affordance_markers
from push_ros.diagnostics import DiagnosticsPublisher
from push_ros.frames import WORLD_FRAME
from push_ros.node import (
    ParamSpec,
    ThrottledLog,
    declare_config,
    guarded,
    parameter_values,
    run_node,
)
from push_ros.outline import outline_from_cloud
from push_ros.paths import push_path
from push_ros.poses import check_frame, pose_with_covariance_from_msg, xytheta_from_pose
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS, latched_reader_qos
from push_ros.refusal import read_refusal, stamp_key
from push_ros.stamps import seconds_from_stamp
from push_ros.state import state_from_array_msg

__all__ = ["PARAMETERS", "PlannerNode", "PlannerNodeParams", "main"]

#: Period of /diagnostics and of the push-timeout check, seconds of wall time.
DIAGNOSTICS_PERIOD_S = 1.0
#: Pairing tolerances of estimator/object_pose and estimator/state (m, rad).
PAIR_TOLERANCE_XY = 1e-6
PAIR_TOLERANCE_THETA = 1e-6
#: Poses and states kept for pairing.
PAIR_BUFFER = 10
#: Goal samples remembered to take a sample received on both goal readers once.
GOAL_SAMPLES_KEPT = 16
#: Said in planner/status when the outline is continuously symmetric (push_core.symmetry).
ORIENTATION_IGNORED = "orientation ignored: rotationally symmetric outline"
#: Least step between the header stamps of two pushes, ns (a refusal names one push).
PUSH_STAMP_STEP_NS = 1000
#: Seconds between two log lines of one kind of refused input or callback error (each is
#: counted on planner/status and /diagnostics regardless).
LOG_THROTTLE_S = 2.0


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


def _load_learned_model(weights: str) -> Any:
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


def _goal_from_msg(msg: PoseStamped,
                   workspace: tuple[tuple[float, float], tuple[float, float]]
                   ) -> np.ndarray:
    """Goal ``(x, y, theta)`` in ``world`` of ``goal_pose``; its position on the workspace.

    Raises
    ------
    ValueError
        Wrong frame, non-finite values, a quaternion that breaks the planarity rule, or a
        position outside ``workspace`` ((xmin, xmax), (ymin, ymax)), m.
    """
    check_frame(msg.header.frame_id, WORLD_FRAME)
    goal = xytheta_from_pose(msg)
    (x0, x1), (y0, y1) = workspace
    if not (x0 <= goal[0] <= x1 and y0 <= goal[1] <= y1):
        raise ValueError(f"position ({goal[0]:.4f}, {goal[1]:.4f}) m is off the workspace "
                         f"x in [{x0}, {x1}], y in [{y0}, {y1}] m")
    return goal


class PlannerNode(Node):
    """ROS wrapper of :class:`push_core.planner.Planner`; see the module docstring.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        At construction, if a parameter is invalid (the message names it).
    """

    def __init__(self, node_name: str = "planner_node", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._log = ThrottledLog(self.get_logger(), LOG_THROTTLE_S)
        self.params = declare_config(self, PARAMETERS, PlannerNodeParams.from_values)
        self._model = (_load_learned_model(self.params.lrn_weights)
                       if self.params.planner.method == "lrn" else None)
        self._planner = Planner(self.params.planner, affordance_model=self._model)
        #: The closed-loop rules (push_core.episode): goal, outline, estimates, pushes.
        self._engine = EpisodeEngine(self._planner, self.params.max_steps,
                                     after_goal=self.params.after_goal)
        self._poses: deque[tuple[float, np.ndarray]] = deque(maxlen=PAIR_BUFFER)
        self._states: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=PAIR_BUFFER)
        self._refused = 0
        #: Header stamp of the outline in use (its episode's reference frame), s.
        self._outline_stamp = -math.inf
        self._last_refusal = ""
        #: Exceptions stopped by the callback guards (push_ros.node.guarded).
        self._errors = 0
        self._last_error = ""
        #: Goals taken from another publisher than the previous goal's (logged, in the status).
        self._goal_switches = 0
        #: Pushes refused by their executor (pusher/refused matching the push in flight), and
        #: refusals of another push (stale, another planner's), ignored.
        self._pushes_refused = 0
        self._refusals_ignored = 0
        #: Header stamp of the newest push published (ns; strictly increasing), and its
        #: ``push_ros.refusal.stamp_key`` while that push is in flight.
        self._push_ns = -1
        self._push_key = ""
        #: (publication sequence number, source timestamp) of the last goal samples: a latched
        #: sender's sample arrives on both goal readers and is taken once.
        self._goal_samples: deque[tuple[int, int]] = deque(maxlen=GOAL_SAMPLES_KEPT)
        self._new_episode()

        self._pub_push = self.create_publisher(Path, "planner/push", RELIABLE_QOS)
        self._pub_markers = self.create_publisher(MarkerArray, "planner/affordances",
                                                  RELIABLE_QOS)
        self._pub_status = self.create_publisher(DiagnosticStatus, "planner/status", LATCHED_QOS)
        self._diagnostics = DiagnosticsPublisher(self)
        estimates = latched_reader_qos(PAIR_BUFFER)  # late subscriber: the last estimate
        guard = self._guard
        self.create_subscription(Float64MultiArray, "estimator/state", guard(self._on_state),
                                 estimates)
        self.create_subscription(PoseWithCovarianceStamped, "estimator/object_pose",
                                 guard(self._on_pose), estimates)
        self.create_subscription(PointCloud2, "perception/outline", guard(self._on_outline),
                                 LATCHED_QOS)
        on_goal = guard(self._on_goal)

        def on_goal_with_info(msg: PoseStamped, info: Any) -> None:  # 2 args: with MessageInfo
            on_goal(msg, info)

        # Two readers of goal_pose (module docstring, "goal_pose"): a volatile one matches every
        # publisher (RViz's volatile "2D Goal Pose" too), a transient-local one gives a
        # (re)started node the last goal of a latched sender (push_ros.qos.GOAL_QOS). A sample
        # of a latched sender arrives on both; _on_goal takes it once. A transient-local reader
        # cannot match a volatile writer: that expected mismatch is logged at debug level only.
        self.create_subscription(PoseStamped, "goal_pose", on_goal_with_info, RELIABLE_QOS)
        self.create_subscription(
            PoseStamped, "goal_pose", on_goal_with_info, LATCHED_QOS,
            event_callbacks=SubscriptionEventCallbacks(
                incompatible_qos=lambda event: self.get_logger().debug(
                    "a volatile goal_pose publisher (e.g. RViz) does not match the latched "
                    "goal reader; its goals arrive on the volatile one")))
        self.create_subscription(Path, "pusher/executed", guard(self._on_executed),
                                 RELIABLE_QOS)
        self.create_subscription(DiagnosticStatus, "pusher/refused", guard(self._on_refused),
                                 RELIABLE_QOS)
        self.create_service(Trigger, "~/reset", guard(self._on_reset))
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._steady = steady
        self.create_timer(DIAGNOSTICS_PERIOD_S, guard(self._on_timer), clock=steady)
        cfg = self.params.planner
        self.get_logger().info(
            f"planner ready: method {cfg.method}{' (direct)' if cfg.direct else ''}, k {cfg.k}, "
            f"lambda {cfg.lam} mm/deg, temperature {cfg.temperature} mm, tolerance "
            f"{cfg.tolerance_xy} m / {math.degrees(cfg.tolerance_theta):.2f} deg, max steps "
            f"{self.params.max_steps}, after the goal: {self.params.after_goal}")
        self._publish_status()

    # ---- robustness --------------------------------------------------------------------------
    def _guard(self, callback: Callable[..., Any]) -> Callable[..., Any]:
        """``callback`` wrapped by :func:`push_ros.node.guarded` (nothing escapes a callback)."""
        return guarded(callback, self._log, self._on_callback_error, callback.__name__)

    def _on_callback_error(self, name: str, message: str) -> None:
        """An exception reached a guard (which logged it): count it, report it."""
        self._errors += 1
        self._last_error = f"{name}: {message}"
        self._note, self._level = f"error in {name}: {message}", DiagnosticStatus.WARN
        self._publish_status()

    def _info(self, kind: str, text: str) -> None:
        """An info line, at most one of ``kind`` every ``LOG_THROTTLE_S`` (a flood of goals or
        outlines must not flood the log; rclpy logging costs ~3 ms a line)."""
        log, suppressed = self._log.allow(kind)
        if log:
            self.get_logger().info(text + (f" ({suppressed} similar message(s) suppressed)"
                                           if suppressed else ""))

    def _clock_seconds(self) -> float | None:
        """The node's clock, s; None while a sim-time clock has not started (reads 0)."""
        clock = self.get_clock()
        ns = clock.now().nanoseconds
        if clock.ros_time_is_active and ns <= 0:
            return None
        return ns * 1e-9

    def _check_stamp(self, stamp: float) -> None:
        """``ValueError`` if ``stamp`` (s) is more than ``max_future_stamp`` ahead of the node's
        clock (not applied while a sim-time clock reads 0)."""
        now = self._clock_seconds()
        if now is not None and stamp > now + self.params.max_future_stamp:
            raise ValueError(f"stamp {stamp:.9f} s is {stamp - now:.3f} s ahead of the node's "
                             f"clock (max_future_stamp {self.params.max_future_stamp} s)")

    # ---- episode -----------------------------------------------------------------------------
    def _new_episode(self) -> None:
        self._failure = ""
        self._in_flight_since = 0.0
        self._note = ""
        self._level = DiagnosticStatus.OK
        self._poses.clear()
        self._states.clear()
        self._push_key = ""
        #: Who published the current goal (:func:`_goal_source`), "" = nobody yet.
        self._goal_source = ""
        self._goal_sequence: int | None = None

    def _read_params(self) -> PlannerNodeParams:
        return PlannerNodeParams.from_values(parameter_values(self, PARAMETERS))

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        try:
            params = self._read_params()
            model = self._model
            if params.planner.method == "lrn" and model is None:
                model = _load_learned_model(params.lrn_weights)
            planner = Planner(params.planner, affordance_model=model)
        except ValueError as exc:
            response.success, response.message = False, f"reset refused: {exc}"
            self.get_logger().error(response.message)
            return response
        self.params, self._model, self._planner = params, model, planner
        outline = self._engine.outline
        self._engine = EpisodeEngine(planner, params.max_steps, after_goal=params.after_goal,
                                     counts=self._engine.counts)
        if outline is not None:
            self._engine.set_outline(outline)
        self._new_episode()
        cfg = params.planner
        response.success = True
        response.message = (f"new episode: step 0, estimates, pushes and goal forgotten, "
                            f"outline kept; method {cfg.method}{' (direct)' if cfg.direct else ''}"
                            f", k {cfg.k}, seed {cfg.seed}, max steps {params.max_steps}, after "
                            f"the goal: {params.after_goal}")
        self.get_logger().info(f"reset: {response.message}")
        self._publish_status()
        return response

    # ---- inputs ------------------------------------------------------------------------------
    def _refuse(self, what: str, reason: str) -> None:
        self._refused += 1
        self._last_refusal = f"{what}: {reason}"[:500]
        self._note = f"refused {what}: {reason}"[:500]
        self._level = DiagnosticStatus.WARN
        self._log.warning(f"refused:{what}", f"refused {what}: {reason}"[:500])
        self._publish_status()

    def _on_goal(self, msg: PoseStamped, info: Any = None) -> None:
        sample = _sample_key(info)
        if sample is not None:
            if sample in self._goal_samples:  # the same sample on the other goal reader
                return
            self._goal_samples.append(sample)
        source, sequence = _goal_source(info)
        previous, self._goal_sequence = self._goal_sequence, sequence
        try:
            goal = _goal_from_msg(msg, self.params.planner.workspace)
        except ValueError as exc:
            self._refuse("goal_pose", str(exc))
            return
        switched = self._is_other_source(source, sequence, previous)
        self._goal_source = source
        self._engine.new_goal(goal)
        self._failure = ""
        self._note, self._level = "", DiagnosticStatus.OK
        text = (f"new goal (x {goal[0]:.4f} m, y {goal[1]:.4f} m, theta {goal[2]:.4f} rad)"
                f"{f' from {source}' if source else ''}: new episode")
        if switched:
            self._goal_switches += 1
            self._note = (f"goal replaced by another publisher ({source or 'unknown'}; "
                          f"goal_pose publishers: {self._goal_publishers()})")
            self._level = DiagnosticStatus.WARN
            self._log.warning("goal_switch", f"{text}; {self._note}")
        else:
            self._info("goal", text)
        self._try_plan()
        self._publish_status()

    def _is_other_source(self, source: str, sequence: int | None,
                         previous: int | None) -> bool:
        """Whether a goal comes from another publisher than the current goal's.

        With a publisher GID in the message info: compared. Without (rclpy Jazzy's
        MessageInfo has none): a publisher numbers its messages 1, 2, 3, ..., so a goal whose
        ``publication_sequence_number`` does not follow that of the previous ``goal_pose``
        message (``previous``, refused ones included) is taken to come from another publisher
        (or a restarted one). Never for the first goal of an episode.
        """
        if self._engine.goal is None:
            return False
        if source or self._goal_source:
            return source != self._goal_source
        return sequence is not None and previous is not None and sequence != previous + 1

    def _goal_publishers(self) -> str:
        """The publishers of ``goal_pose`` now: node names and endpoint GIDs."""
        try:
            infos = self.get_publishers_info_by_topic(self.resolve_topic_name("goal_pose"))
        except Exception as exc:  # noqa: BLE001 - only for the log line
            return f"unknown ({exc})"
        return ", ".join(f"{i.node_namespace.rstrip('/')}/{i.node_name} (gid "
                         f"{'.'.join(format(x, '02x') for x in i.endpoint_gid)})"
                         for i in infos) or "none"

    def _on_outline(self, msg: PointCloud2) -> None:
        try:
            stamp = seconds_from_stamp(msg.header.stamp)
            points, normals = outline_from_cloud(msg)
            outline = self._planner.check_outline(prepare_outline(
                points, normals, simplify_tolerance=self.params.planner.simplify_tolerance))
        except ValueError as exc:
            self._refuse("perception/outline", str(exc))
            return
        self._engine.set_outline(outline)  # also forgets the avoided points of another outline
        self._outline_stamp = stamp
        decimated = (f", decimated from {outline.source_points}"
                     if outline.source_points > len(outline.points) else "")
        self._info("outline", f"outline with {len(outline.points)} points{decimated} "
                   f"({len(outline.polyline)}-vertex contact polyline)")
        self._try_plan()
        self._publish_status()

    def _on_pose(self, msg: PoseWithCovarianceStamped) -> None:
        try:
            estimate = pose_with_covariance_from_msg(msg)
            self._check_stamp(estimate.stamp)
        except ValueError as exc:
            self._refuse("estimator/object_pose", str(exc))
            return
        self._poses.append((estimate.stamp, estimate.pose))
        self._pair()

    def _on_state(self, msg: Float64MultiArray) -> None:
        try:
            state, covariance = state_from_array_msg(msg)
        except ValueError as exc:
            self._refuse("estimator/state", str(exc))
            return
        self._states.append((state, covariance))
        self._pair()

    def _pair(self) -> None:
        """Pair the newest pose with a state of the same pose; see the module docstring."""
        for i in range(len(self._poses) - 1, -1, -1):
            stamp, pose = self._poses[i]
            for state, covariance in reversed(self._states):
                if (math.hypot(*(state[:2] - pose[:2])) <= PAIR_TOLERANCE_XY
                        and abs(float(wrap_angle(state[2] - pose[2]))) <= PAIR_TOLERANCE_THETA):
                    for _ in range(i + 1):  # this pose and older ones are done
                        self._poses.popleft()
                    self._on_estimate(stamp, state, covariance)
                    return

    def _on_estimate(self, stamp: float, state: np.ndarray, covariance: np.ndarray) -> None:
        try:
            check_state(state, self._engine.outline)  # before the engine sees it
            self._engine.estimate(stamp, state, covariance)
        except ValueError as exc:
            self._refuse("estimate", str(exc))
            return
        self._try_plan()
        self._publish_status()

    def _on_executed(self, msg: Path) -> None:
        try:
            if msg.header.frame_id != WORLD_FRAME or not msg.poses:
                raise ValueError(f"expected poses in 'world', got {len(msg.poses)} poses in "
                                 f"{msg.header.frame_id!r}")
            end = max([seconds_from_stamp(msg.header.stamp)]
                      + [seconds_from_stamp(p.header.stamp) for p in msg.poses])
            self._check_stamp(end)
        except ValueError as exc:
            self._refuse("pusher/executed", str(exc))
            return
        # Ours or anybody's: the object may have moved, so nothing is avoided and estimates
        # before its end are stale (a push after "goal reached" is then seen, rule 7).
        self._engine.push_executed(end)
        self._try_plan()
        self._publish_status()

    def _on_refused(self, msg: DiagnosticStatus) -> None:
        try:
            refusal = read_refusal(msg)
        except ValueError as exc:
            self._refuse("pusher/refused", str(exc).removeprefix("pusher/refused: "))
            return
        if not (self._engine.in_flight and refusal.push_stamp == self._push_key):
            self._refusals_ignored += 1
            self._info("refusal_ignored", f"ignored a refusal of push {refusal.push_stamp} by "
                       f"{refusal.who!r}: not the push in flight")
            self._publish_status()
            return
        note = (f"push of step {self._engine.steps} refused by {refusal.who} ({refusal.kind}): "
                f"{refusal.reason}")[:500]
        self._pushes_refused += 1
        self._push_key = ""
        self._engine.push_lost()  # as after push_timeout: its contact region avoided
        self._log.warning("push_refused", f"{note}; counted as a step, planning again")
        self._note, self._level = "", DiagnosticStatus.OK
        self._try_plan()
        if not self._note:
            self._note, self._level = note, DiagnosticStatus.WARN
        self._publish_status()

    def _on_timer(self) -> None:
        if self._engine.in_flight and (self._steady_now() - self._in_flight_since
                                       > self.params.push_timeout):
            # nothing moved: the newest estimate is fresh again, the contact region avoided
            self._engine.push_lost()
            self._note = (f"push of step {self._engine.steps} not reported on pusher/executed "
                          f"within {self.params.push_timeout} s; counted as a step; its "
                          f"contact region is avoided until a push is executed")
            self._level = DiagnosticStatus.WARN
            self.get_logger().warning(self._note)
            self._try_plan()
            self._publish_status()
        self._publish_diagnostics()

    def _steady_now(self) -> float:
        return self._steady.now().nanoseconds * 1e-9

    # ---- planning ----------------------------------------------------------------------------
    def _try_plan(self) -> None:
        """Ask the episode engine (stale-estimate rule, stop rule, max steps, watching after the
        goal) and act on it."""
        step = self._engine.step()
        if step.action == "reached":
            self._note, self._level = "", DiagnosticStatus.OK
            self.get_logger().info(f"goal reached after {self._engine.steps} pushes")
        elif step.action == "left":
            self._note, self._level = f"{step.reason} (after_goal: report)", DiagnosticStatus.WARN
            self.get_logger().warning(f"object {step.reason}; reported only (after_goal: "
                                      f"report)")
        elif step.action == "failed":
            self._failure = ("failed after max steps" if self._engine.failure == "max steps"
                             else "failed: no feasible push")
            self._level = DiagnosticStatus.ERROR
            self.get_logger().error(f"{self._failure} ({self._engine.steps} pushes): "
                                    f"{step.reason}")
        elif step.action == "refused":
            self._refuse("estimate", step.reason)
        elif step.action == "push":
            self._publish_push(step.plan, step.state)
            if step.resumed:
                self._note = f"{step.reason}; pushing again (after_goal: resume)"
                self._level = DiagnosticStatus.WARN
                self.get_logger().warning(f"object {self._note}")

    def _publish_push(self, plan: PushPlan, state: np.ndarray) -> None:
        self._note, self._level = "", DiagnosticStatus.OK
        now = self.get_clock().now()
        outline = self._engine.outline
        self._push_ns = max(now.nanoseconds, self._push_ns + PUSH_STAMP_STEP_NS)
        path = push_path(plan.approach, plan.contact, plan.end, self._push_ns * 1e-9,
                         self.params.push_speed)
        self._push_key = stamp_key(path.header.stamp)
        self._pub_push.publish(path)
        self._pub_markers.publish(affordance_markers(outline, state[:3], plan, now.to_msg()))
        self._in_flight_since = self._steady_now()
        self.get_logger().info(
            f"step {self._engine.steps}: push at outline point {plan.index}, "
            f"{math.degrees(plan.angle):+.0f} deg, {1e3 * plan.length:.1f} mm, predicted score "
            f"{plan.score:.1f} mm (now {plan.current_score:.1f}); approach "
            f"{np.round(plan.approach, 4)}, contact {np.round(plan.contact, 4)}, end "
            f"{np.round(plan.end, 4)} m")

    # ---- status ------------------------------------------------------------------------------
    def _status(self) -> DiagnosticStatus:
        engine = self._engine
        phase = engine.phase
        if phase == "pushing":
            message = f"pushing step {engine.steps}"
        elif phase == "reached":
            message = "goal reached"
            if not self._orientation_matters():
                message += f" ({ORIENTATION_IGNORED})"
        elif phase == "left":
            message = "goal left"
        elif phase == "failed":
            message = self._failure
        else:
            missing = [name for name, have in (("goal", engine.goal is not None),
                                               ("outline", engine.outline is not None),
                                               ("estimate", engine.latest is not None))
                       if not have]
            message = "waiting" + (f" for {', '.join(missing)}" if missing else "")
        if self._note:
            message += f" - {self._note}"
        goal = "" if engine.goal is None else " ".join(f"{v:.4f}" for v in engine.goal)
        counts = {k: v for k, v in engine.counts.items() if k not in ("lost", "left")}
        values = {"state": phase, "step": engine.steps, "max_steps": self.params.max_steps,
                  "goal": goal, "orientation": "used" if self._orientation_matters() else
                  "ignored", **counts, "refused": self._refused, "lost": engine.counts["lost"],
                  "last_refusal": self._last_refusal,
                  "last_push_end": f"{engine.last_push_end:.6f}",
                  "outline_stamp": f"{self._outline_stamp:.6f}",
                  "left_goal": engine.counts["left"], "after_goal": self.params.after_goal,
                  "goal_source": self._goal_source, "goal_switches": self._goal_switches,
                  "pushes_refused": self._pushes_refused,
                  "refusals_ignored": self._refusals_ignored,
                  "errors": self._errors, "last_error": self._last_error}
        return self._diagnostics.status(self._level, message, values)

    def _orientation_matters(self) -> bool:
        outline = self._engine.outline
        return outline is None or outline.orientation_matters

    def _publish_status(self) -> None:
        status = self._status()
        self._pub_status.publish(status)
        self._publish_diagnostics(status)

    def _publish_diagnostics(self, status: DiagnosticStatus | None = None) -> None:
        self._diagnostics.publisher.publish(self._diagnostics.array(status or self._status()))


def _sample_key(info: Any) -> tuple[int, int] | None:
    """(publication sequence number, source timestamp in ns) of a message info, or None.

    The two identify one sample of one writer: the two ``goal_pose`` readers receive the same
    sample with the same pair. rclpy Jazzy's message info is a dict with both entries.
    """
    if not isinstance(info, dict):
        return None
    sequence, stamp = info.get("publication_sequence_number"), info.get("source_timestamp")
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in (sequence, stamp)):
        return None
    return int(sequence), int(stamp)


def _goal_source(info: Any) -> tuple[str, int | None]:
    """(publisher GID as hex or "", publication sequence number or None) of a message info.

    rclpy Jazzy's message info (a dict) carries ``publication_sequence_number`` but no
    publisher GID; a ``publisher_gid`` entry (later rclpy) is used when present.
    """
    if not isinstance(info, dict):
        return "", None
    gid = info.get("publisher_gid")
    data = gid.get("data") if isinstance(gid, dict) else gid
    source = ""
    if data is not None:
        try:
            source = "gid " + ".".join(format(int(x), "02x") for x in data)
        except (TypeError, ValueError):
            source = ""
    sequence = info.get("publication_sequence_number")
    return source, sequence if isinstance(sequence, int) and not isinstance(sequence, bool) \
        else None


def main(args: list[str] | None = None) -> None:
    """Entry point of ``planner_node`` (``ros2 run push_planner planner_node`` / ``pushbot run
    planner_node``)."""
    run_node(PlannerNode, "planner_node", args)


if __name__ == "__main__":
    main()
