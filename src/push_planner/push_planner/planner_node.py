"""``planner_node``: the greedy affordance-based push planner behind ROS 2 topics.

Role: feeds :class:`push_core.episode.EpisodeEngine` (the closed-loop rules, shared with the
in-process loops) and acts on its decisions; planning is :class:`push_core.planner.Planner`.
Estimates are paired by :class:`push_core.estimator.pairing.EstimatePairing`, goals de-duplicated by
:class:`push_ros.message_info.GoalSources`; a matching ``pusher/refused`` (:mod:`push_ros.refusal`)
or a push not executed within ``push_timeout`` is a lost push, and the node re-plans.
Parameters: :mod:`push_planner.config`.

Invariants: at most one plan per usable estimate and one push in flight; push header stamps
strictly increase; a refused input changes nothing; no exception leaves a callback
(:class:`push_ros.health.NodeHealth`); every message goes through a :mod:`push_ros` codec; it
never imports the simulator.

Topics, services, status values and parameters: docs/INTERFACES.md; the rules:
docs/design/planner-node.md, docs/design/episode-engine.md, docs/design/node-runtime.md
and docs/design/arm.md#refusals-for-every-executor.
"""

from __future__ import annotations

import math
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

from push_core.episode import EpisodeEngine
from push_core.estimator.pairing import Estimate, EstimatePairing
from push_core.planner import Planner, PushPlan, check_state, prepare_outline
from push_planner.config import NODE_NAME, PARAMETERS, PlannerNodeParams, load_learned_model
from push_planner.conversions import affordance_markers, executed_end, goal_from_msg, status_message
from push_ros.health import NodeHealth
from push_ros.message_info import GoalSources, publishers_text
from push_ros.node import declare_config, parameter_values, run_node
from push_ros.outline import outline_from_cloud
from push_ros.paths import push_path
from push_ros.poses import pose_with_covariance_from_msg
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS, latched_reader_qos
from push_ros.refusal import MOVING_KINDS, read_refusal, stamp_key
from push_ros.stamps import check_not_ahead, clock_seconds, seconds_from_stamp
from push_ros.state import state_from_array_msg

__all__ = ["PARAMETERS", "PlannerNode", "PlannerNodeParams", "main"]

#: Period of /diagnostics and of the push-timeout check, seconds of wall time.
DIAGNOSTICS_PERIOD_S = 1.0
#: Poses and states kept for pairing (push_core.estimator.pairing).
PAIR_BUFFER = 10
#: Least step between the header stamps of two pushes, ns (a refusal names one push).
PUSH_STAMP_STEP_NS = 1000
#: Seconds between two log lines of one kind (each event is counted regardless).
LOG_THROTTLE_S = 2.0
#: Refusal class (``refused_<kind>``) of each input.
KINDS = {"goal_pose": "goal", "perception/outline": "outline", "estimator/object_pose": "pose",
         "estimator/state": "state", "estimate": "estimate", "pusher/executed": "executed",
         "pusher/refused": "refusal"}
#: The node's own counters besides the engine's.
COUNTERS = ("goal_switches", "pushes_refused", "refusals_ignored",
            *(f"refused_{k}" for k in KINDS.values()))


class PlannerNode(Node):
    """ROS wrapper of the episode engine and the planner; see the module docstring.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        At construction, if a parameter is invalid (the message names it).
    """

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.health = NodeHealth(self, counters=COUNTERS, log_period=LOG_THROTTLE_S,
                                 on_error=self._on_callback_error)
        self.params = declare_config(self, PARAMETERS, PlannerNodeParams.from_values)
        self._model = (load_learned_model(self.params.lrn_weights)
                       if self.params.planner.method == "lrn" else None)
        self._planner = Planner(self.params.planner, affordance_model=self._model)
        #: The closed-loop rules (push_core.episode): goal, outline, estimates, pushes.
        self._engine = EpisodeEngine(self._planner, self.params.max_steps,
                                     after_goal=self.params.after_goal)
        self._pairing = EstimatePairing(PAIR_BUFFER)
        self._goals = GoalSources()
        #: Header stamp of the outline in use (its episode's reference frame), s.
        self._outline_stamp = -math.inf
        #: Header stamp of the newest push (ns, strictly increasing) and, while it is in
        #: flight, its push_ros.refusal.stamp_key.
        self._push_ns = -1
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._new_episode()

        self._pub_push = self.create_publisher(Path, "planner/push", RELIABLE_QOS)
        self._pub_markers = self.create_publisher(MarkerArray, "planner/affordances",
                                                  RELIABLE_QOS)
        self._pub_status = self.create_publisher(DiagnosticStatus, "planner/status", LATCHED_QOS)
        estimates = latched_reader_qos(PAIR_BUFFER)  # late subscriber: the last estimate
        guard = self.health.guard
        for msg_type, topic, callback, qos in (
                (Float64MultiArray, "estimator/state", self._on_state, estimates),
                (PoseWithCovarianceStamped, "estimator/object_pose", self._on_pose, estimates),
                (PointCloud2, "perception/outline", self._on_outline, LATCHED_QOS),
                (Path, "pusher/executed", self._on_executed, RELIABLE_QOS),
                (DiagnosticStatus, "pusher/refused", self._on_refused, RELIABLE_QOS)):
            self.create_subscription(msg_type, topic, guard(callback), qos)
        on_goal = guard(self._on_goal)

        def on_goal_with_info(msg: PoseStamped, info: Any) -> None:  # 2 args: with MessageInfo
            on_goal(msg, info)

        # goal_pose twice: volatile (every publisher, RViz too) and transient local (a
        # (re)started node gets a latched sender's last goal; a volatile writer cannot match it:
        # that expected mismatch is logged at debug level only).
        self.create_subscription(PoseStamped, "goal_pose", on_goal_with_info, RELIABLE_QOS)
        self.create_subscription(
            PoseStamped, "goal_pose", on_goal_with_info, LATCHED_QOS,
            event_callbacks=SubscriptionEventCallbacks(
                incompatible_qos=lambda event: self.get_logger().debug(
                    "a volatile goal_pose publisher (e.g. RViz) does not match the latched "
                    "goal reader; its goals arrive on the volatile one")))
        self.create_service(Trigger, "~/reset", guard(self._on_reset))
        self.create_timer(DIAGNOSTICS_PERIOD_S, guard(self._on_timer), clock=self._steady)
        self.get_logger().info(f"planner ready: {self.params.summary()}")
        self._publish_status()

    # ---- robustness --------------------------------------------------------------------------
    def _on_callback_error(self, name: str, message: str) -> None:
        """An exception reached a guard (counted and logged by it): report it."""
        self._set_note(f"error in {name}: {message}", DiagnosticStatus.WARN)
        self._publish_status()

    def _set_note(self, note: str, level: bytes = DiagnosticStatus.OK) -> None:
        """The note and level ``planner/status`` shows until the next one."""
        self._note = note
        self._level = level

    def _info(self, kind: str, text: str) -> None:
        """An info line, at most one of ``kind`` every ``LOG_THROTTLE_S``."""
        log, suppressed = self.health.log.allow(kind)
        if not log:
            return
        if suppressed:
            text += f" ({suppressed} similar message(s) suppressed)"
        self.get_logger().info(text)

    def _check_stamp(self, stamp: float) -> None:
        """``ValueError`` if ``stamp`` (s) is more than ``max_future_stamp`` ahead of the
        node's clock (push_ros.stamps' clock rule)."""
        check_not_ahead(stamp, clock_seconds(self.get_clock()), self.params.max_future_stamp)

    def _refuse(self, what: str, reason: str) -> None:
        self._set_note(self.health.refuse(what, reason, KINDS[what]), DiagnosticStatus.WARN)
        self._publish_status()

    # ---- episode -----------------------------------------------------------------------------
    def _new_episode(self) -> None:
        self._in_flight_since = 0.0
        self._push_key = ""
        self._set_note("")
        self._pairing.clear()
        self._goals.forget()

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        try:
            params = PlannerNodeParams.from_values(parameter_values(self, PARAMETERS))
            model = self._model
            if params.planner.method == "lrn" and model is None:
                model = load_learned_model(params.lrn_weights)
            planner = Planner(params.planner, affordance_model=model)
        except ValueError as exc:
            response.success = False
            response.message = f"reset refused: {exc}"
            self.get_logger().error(response.message)
            return response
        self.params = params
        self._model = model
        self._planner = planner
        outline = self._engine.outline
        self._engine = EpisodeEngine(planner, params.max_steps, after_goal=params.after_goal,
                                     counts=self._engine.counts)
        if outline is not None:
            self._engine.set_outline(outline)
        self._new_episode()
        response.success = True
        response.message = (f"new episode: step 0, estimates, pushes and goal forgotten, "
                            f"outline kept; {params.summary()}")
        self.get_logger().info(f"reset: {response.message}")
        self._publish_status()
        return response

    # ---- inputs ------------------------------------------------------------------------------
    def _on_goal(self, msg: PoseStamped, info: Any = None) -> None:
        if self._goals.duplicate(info):  # the same sample on the other goal reader
            return
        source = self._goals.arrived(info)
        try:
            goal = goal_from_msg(msg, self.params.planner.workspace)
        except ValueError as exc:
            self._refuse("goal_pose", str(exc))
            return
        # a goal after the last one finished (reached, failed) is a new request, not a rival
        switched = self._goals.take(self._engine.goal is not None and not self._engine.finished)
        self._engine.new_goal(goal)
        self._set_note("")
        text = (f"new goal (x {goal[0]:.4f} m, y {goal[1]:.4f} m, theta {goal[2]:.4f} rad)"
                f"{f' from {source}' if source else ''}: new episode")
        if switched:
            self.health.count("goal_switches")
            self._set_note(f"goal replaced by another publisher ({source or 'unknown'}; "
                           f"goal_pose publishers: {publishers_text(self, 'goal_pose')})",
                           DiagnosticStatus.WARN)
            self.health.log.warning("goal_switch", f"{text}; {self._note}")
        else:
            self._info("goal", text)
        self._try_plan()
        self._publish_status()

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
        self._on_estimate(self._pairing.add_pose(estimate.stamp, estimate.pose))

    def _on_state(self, msg: Float64MultiArray) -> None:
        try:
            state, covariance = state_from_array_msg(msg)
        except ValueError as exc:
            self._refuse("estimator/state", str(exc))
            return
        self._on_estimate(self._pairing.add_state(state, covariance))

    def _on_estimate(self, estimate: Estimate | None) -> None:
        if estimate is None:
            return
        try:
            check_state(estimate.state, self._engine.outline)  # before the engine sees it
            self._engine.estimate(estimate.stamp, estimate.state, estimate.covariance)
        except ValueError as exc:
            self._refuse("estimate", str(exc))
            return
        self._try_plan()
        self._publish_status()

    def _on_executed(self, msg: Path) -> None:
        try:
            end = executed_end(msg)
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
            self.health.count("refusals_ignored")
            self._info("refusal_ignored", f"ignored a refusal of push {refusal.push_stamp} by "
                       f"{refusal.who!r}: not the push in flight")
            self._publish_status()
            return
        note = (f"push of step {self._engine.steps} refused by {refusal.who} ({refusal.kind}): "
                f"{refusal.reason}")[:500]
        self.health.count("pushes_refused")
        self.health.log.warning("push_refused", f"{note}; counted as a step, planning again")
        self._lost(note, wait=refusal.kind in MOVING_KINDS)

    def _on_timer(self) -> None:
        waited = self._steady.now().nanoseconds * 1e-9 - self._in_flight_since
        if self._engine.in_flight and waited > self.params.push_timeout:
            note = (f"push of step {self._engine.steps} not reported on pusher/executed within "
                    f"{self.params.push_timeout} s; counted as a step; its contact region is "
                    f"avoided until a push is executed")
            self.get_logger().warning(note)
            self._lost(note, after=False)
        self.health.publish(self._level, *self._status_text())

    def _lost(self, note: str, after: bool = True, wait: bool = False) -> None:
        """The push in flight is lost (:meth:`EpisodeEngine.push_lost`: its contact region
        avoided); plan again (``wait``: from a newer estimate). ``note`` is set before planning
        (a push clears it) or, with ``after``, kept when planning set none."""
        self._push_key = ""
        self._engine.push_lost(wait)
        if after:
            self._set_note("")
        else:
            self._set_note(note, DiagnosticStatus.WARN)
        self._try_plan()
        if after and not self._note:
            self._set_note(note, DiagnosticStatus.WARN)
        self._publish_status()

    # ---- planning ----------------------------------------------------------------------------
    def _try_plan(self) -> None:
        """Ask the episode engine and act on its decision."""
        step = self._engine.step()
        if step.action == "reached":
            self._set_note("")
            self.get_logger().info(f"goal reached after {self._engine.steps} pushes")
        elif step.action == "left":
            self._set_note(f"{step.reason} (after_goal: report)", DiagnosticStatus.WARN)
            self.get_logger().warning(f"object {step.reason}; reported only (after_goal: "
                                      f"report)")
        elif step.action == "failed":
            self._level = DiagnosticStatus.ERROR
            self.get_logger().error(f"{self._engine.status_text()} ({self._engine.steps} "
                                    f"pushes): {step.reason}")
        elif step.action == "refused":
            self._refuse("estimate", step.reason)
        elif step.action == "push":
            self._publish_push(step.plan, step.state)
            if step.resumed:
                self._set_note(f"{step.reason}; pushing again (after_goal: resume)",
                               DiagnosticStatus.WARN)
                self.get_logger().warning(f"object {self._note}")

    def _publish_push(self, plan: PushPlan, state: np.ndarray) -> None:
        self._set_note("")
        now = self.get_clock().now()
        self._push_ns = max(now.nanoseconds, self._push_ns + PUSH_STAMP_STEP_NS)
        path = push_path(plan.approach, plan.contact, plan.end, self._push_ns * 1e-9,
                         self.params.push_speed)
        self._push_key = stamp_key(path.header.stamp)
        self._pub_push.publish(path)
        self._pub_markers.publish(affordance_markers(self._engine.outline, state[:3], plan,
                                                     now.to_msg()))
        self._in_flight_since = self._steady.now().nanoseconds * 1e-9
        self.get_logger().info(
            f"step {self._engine.steps}: push at outline point {plan.index}, "
            f"{math.degrees(plan.angle):+.0f} deg, {1e3 * plan.length:.1f} mm, predicted score "
            f"{plan.score:.1f} mm (now {plan.current_score:.1f}); approach "
            f"{np.round(plan.approach, 4)}, contact {np.round(plan.contact, 4)}, end "
            f"{np.round(plan.end, 4)} m")

    # ---- status ------------------------------------------------------------------------------
    def _status_text(self) -> tuple[str, dict[str, object]]:
        """``planner/status``'s message and values besides the health counters."""
        engine = self._engine
        message = status_message(engine.status_text(), self._note, engine.goal is not None)
        counts = {k: v for k, v in engine.counts.items() if k != "left"}
        goal = "" if engine.goal is None else " ".join(f"{v:.4f}" for v in engine.goal)
        return message, {
            "state": engine.phase,
            "step": engine.steps,
            "max_steps": self.params.max_steps,
            "goal": goal,
            "orientation": "used" if engine.orientation_matters else "ignored",
            **counts,
            "last_push_end": f"{engine.last_push_end:.6f}",
            "outline_stamp": f"{self._outline_stamp:.6f}",
            "left_goal": engine.counts["left"],
            "after_goal": self.params.after_goal,
            "goal_source": self._goals.source,
        }

    def _status(self) -> DiagnosticStatus:
        return self.health.status(self._level, *self._status_text())

    def _publish_status(self) -> None:
        status = self._status()
        self._pub_status.publish(status)
        self.health.diagnostics.publisher.publish(self.health.diagnostics.array(status))


def main(args: list[str] | None = None) -> None:
    """Entry point of ``planner_node`` (``ros2 run push_planner planner_node`` / ``pushbot run
    planner_node``)."""
    run_node(PlannerNode, NODE_NAME, args)


if __name__ == "__main__":
    main()
