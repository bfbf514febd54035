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
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from push_core.estimator.pairing import Estimate, EstimatePairing
from push_core.planner import PushPlan, check_state, prepare_outline
from push_planner import conversions as conv
from push_planner import robot
from push_planner.config import NODE_NAME, PARAMETERS, PlannerNodeParams, episode_parts
from push_planner.conversions import affordance_markers, executed_end, goal_from_msg
from push_ros.health import NodeHealth
from push_ros.message_info import GoalSources, publishers_text, subscribe_goals
from push_ros.node import declare_config, on_clock_jump_back, parameter_values, run_node
from push_ros.outline import outline_from_cloud
from push_ros.paths import push_path
from push_ros.poses import pose_with_covariance_from_msg
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS, latched_reader_qos
from push_ros.refusal import MOVING_KINDS, read_readiness, read_refusal, stamp_key
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
        #: The closed-loop rules (push_core.episode): goal, outline, estimates, pushes.
        self._model, self._planner, self._engine = episode_parts(self.params)
        self._robot = robot.RobotLink()  # the executor's answers (push_planner.robot)
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
                (DiagnosticStatus, "pusher/refused", self._on_refused, RELIABLE_QOS),
                (DiagnosticStatus, "executor/status", self._on_executor_status, LATCHED_QOS)):
            self.create_subscription(msg_type, topic, guard(callback), qos)
        subscribe_goals(self, guard(self._on_goal))  # volatile and latched readers
        self.create_service(Trigger, "~/reset", guard(self._on_reset))
        self.create_timer(DIAGNOSTICS_PERIOD_S, guard(self._on_timer), clock=self._steady)
        self._jump = on_clock_jump_back(self, guard(self._on_clock_jump))  # restarted clock
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
        outline = self._engine.outline
        try:
            params = PlannerNodeParams.from_values(parameter_values(self, PARAMETERS))
            self._model, self._planner, self._engine = episode_parts(params, self._model,
                                                                     self._engine.counts)
        except ValueError as exc:
            response.success = False
            response.message = f"reset refused: {exc}"
            self.get_logger().error(response.message)
            return response
        self.params = params
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
        text = conv.goal_log_text(goal, source)
        if switched:
            self.health.count("goal_switches")
            self._set_note(f"goal replaced by another publisher ({source or 'unknown'}; "
                           f"goal_pose publishers: {publishers_text(self, 'goal_pose')})",
                           DiagnosticStatus.WARN)
            self.health.log.warning("goal_switch", f"{text}; {self._note}")
        else:
            self.health.log.info("goal", text)
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
        self.health.log.info("outline", conv.outline_text(outline))
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

    def _on_refused(self, msg: DiagnosticStatus) -> None:  # noqa: RET503 - None either way
        try:
            refusal = read_refusal(msg)
        except ValueError as exc:
            self._refuse("pusher/refused", str(exc).removeprefix("pusher/refused: "))
            return
        if not (self._engine.in_flight and refusal.push_stamp == self._push_key):
            self.health.count("refusals_ignored")
            self.health.log.info("refusal_ignored", robot.ignored_refusal_text(refusal))
            self._publish_status()
            return
        note = robot.refusal_note(self._engine.steps, refusal)
        self.health.count("pushes_refused")
        waiting = self._robot.refused(self._engine, refusal, self._steady_s(),
                                      clock_seconds(self.get_clock()))
        self.health.log.warning("push_refused", f"{note}; {waiting or robot.REPLANNING}")
        if waiting:  # rule 9: paused until the executor is ready again
            self._push_key = ""
            self._set_note(waiting, DiagnosticStatus.WARN)
            return self._publish_status()
        self._lost(note, wait=refusal.kind in MOVING_KINDS)

    def _on_executor_status(self, msg: DiagnosticStatus) -> None:
        event = self._robot.status(self._engine, read_readiness(msg))
        if event == robot.RESTARTED:
            self.health.log.warning("executor_restart", event)
            self._lost(event, wait=True)
        elif event:  # RESUMED
            self.health.log.info("robot_ready", event)
            self._set_note("")
            self._try_plan()
            self._publish_status()

    def _on_clock_jump(self, delta: float) -> None:
        self._engine.clock_restarted()  # rule 10 of push_core.episode
        self._robot.clock_restarted()
        self._pairing.clear()
        self._publish_status()

    def _steady_s(self) -> float:
        return self._steady.now().nanoseconds * 1e-9

    def _on_timer(self) -> None:
        if self._engine.in_flight and (self._steady_s() - self._in_flight_since
                                       > self.params.push_timeout):
            note = robot.timeout_note(self._engine.steps, self.params.push_timeout)
            self.get_logger().warning(note)
            self._lost(note, after=False)
        if self._engine.robot_waited(self._steady_s()) is not None:  # rule 9's time-out
            self._level = DiagnosticStatus.ERROR
            self.get_logger().error(self._engine.status_text())
            self._publish_status()
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
            self.get_logger().warning(f"object {self._note}; reported only")
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
        self._in_flight_since = self._steady_s()
        self._robot.push_sent()
        self.get_logger().info(conv.push_log_text(self._engine.steps, plan))

    # ---- status ------------------------------------------------------------------------------
    def _status_text(self) -> tuple[str, dict[str, object]]:
        """``planner/status``'s message and values besides the health counters."""
        engine = self._engine
        message = conv.status_message(engine.status_text(), self._note, engine.goal is not None)
        return message, conv.status_values(engine, self.params.max_steps,
                                           self.params.after_goal, self._outline_stamp,
                                           self._goals.source)

    def _publish_status(self) -> None:
        status = self.health.status(self._level, *self._status_text())
        self._pub_status.publish(status)
        self.health.diagnostics.publisher.publish(self.health.diagnostics.array(status))


def main(args: list[str] | None = None) -> None:
    """Entry point of ``planner_node`` (``ros2 run push_planner planner_node`` / ``pushbot run
    planner_node``)."""
    run_node(PlannerNode, NODE_NAME, args)


if __name__ == "__main__":
    main()
