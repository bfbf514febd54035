"""``push_executor_node``: executes planned pushes on a ros2_control arm.

Role: turns each ``planner/push`` into one checked joint trajectory for the arm's
joint_trajectory_controller (transit, descend, push, retreat, lift, withdraw to a clear pose
near the work), watches it on ``/joint_states``, reports the executed contact segment on
``pusher/executed`` from forward kinematics of the *measured* joints as soon as it has ended
(the arm is still withdrawing), or refuses the push on ``pusher/refused``. A push that arrives
while the previous motion withdraws chains from its planned state. The arm parks at the end of
an episode (``planner/status``), after ``~/cancel`` and on disable. A posture on
``executor/joint_goal`` (a calibration view) is planned and checked like a park
(:mod:`push_executor.joint_goal`) and answered once on ``executor/goal_result``. The maths is
the ROS-free core: :mod:`push_executor.kinematics`, :mod:`push_executor.motion`,
:mod:`push_executor.clearance`, :mod:`push_executor.tracking`; the measured state before
planning, the plan's bounds and the readiness on ``executor/status``:
:mod:`push_executor.state_check`; camera, object and episode inputs:
:mod:`push_executor.scene_inputs`; parameters: :mod:`push_executor.parameters`.

Invariants: an impossible or non-finite joint state is never the measured posture (refused
with kind ``state``, never tracked or held); nothing is published for a plan beyond
``max_trajectory_duration`` / ``max_trajectory_points``; one motion at a time (a chained one
replaces it from the chain point on); a push
ended by a stop before its contact segment was reported (watchdog, ``~/cancel``, disable: a
one-point hold trajectory) is answered on ``pusher/refused`` so the planner re-plans at once;
the watchdogs run on the steady clock; no exception leaves a callback; it never imports
pybullet or sim_bridge.

Topics, services and parameters: docs/INTERFACES.md; states, refusal kinds and timing:
docs/design/arm.md and docs/design/cycle.md.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path as FilePath
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory

from push_executor import messages as m
from push_executor.clearance import robot_mask_factory
from push_executor.joint_goal import GOAL, goal_positions, plan_joint_goal
from push_executor.kinematics import ArmKinematics
from push_executor.motion import PushRefused, plan_park, plan_push
from push_executor.parameters import NODE_NAME, PARAMETERS, ExecutorParams
from push_executor.scene_inputs import SceneInputs
from push_executor.state_check import (
    StuckPosture,
    check_before_planning,
    check_plan,
    nonfinite_joints,
    posture_problem,
    unavailable,
)
from push_executor.tracking import (
    Event,
    Execution,
    MeasuredArm,
    PlanMaker,
    start_plan,
)
from push_ros.health import NodeHealth
from push_ros.node import declare_config, run_node
from push_ros.qos import JOINT_STATE_QOS, LATCHED_QOS, RELIABLE_QOS
from push_ros.refusal import readiness_values, refusal_msg, stamp_key
from push_ros.stamps import clock_seconds

__all__ = ["PARAMETERS", "ExecutorParams", "PushExecutorNode", "main"]

#: Watchdog timer and /diagnostics periods, s.
WATCHDOG_PERIOD, DIAGNOSTICS_PERIOD = 0.05, 1.0
#: The arm is parked within this of ``park_positions`` (every joint), rad; held (a pending park
#: may start) when its last ``HELD_STATES`` joint states lie within ``HELD`` rad of each other.
PARKED, HELD, HELD_STATES = 0.01, 1e-4, 3
COUNTERS = ("pushes", "executed", "chained", "stopped", "parks", "goals", "models",
            "joint_states")


class PushExecutorNode(Node):
    """The node (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.params = declare_config(self, PARAMETERS, ExecutorParams.from_values)
        p = self.params.values
        self.health = NodeHealth(self, "push executor", "arm", COUNTERS)
        guard = self.health.guard
        self._arm: ArmKinematics | None = None
        self._robot, self._urdf, self._joints = None, "", ()
        self.measured = MeasuredArm(HELD_STATES, HELD)
        self._enabled = bool(p["start_enabled"])
        self._run: Execution | None = None
        self._push_stamp: Any = None
        self._deferred: tuple[Path, float] | None = None  # a push waiting for the arm at rest
        self._park_pending, self._stopped, self._line_error_mm = "", False, math.nan
        self._stop_values: dict[str, str] = {}
        self._plan_values: dict[str, str] = {}
        self._stuck = StuckPosture()  # a posture it could not leave (push_executor.state_check)
        self._session, self._readiness = f"{os.getpid()}-{time.time_ns()}", None
        self._pub_traj = self.create_publisher(JointTrajectory, p["controller_topic"],
                                               RELIABLE_QOS)
        self._pub_executed = self.create_publisher(Path, "pusher/executed", RELIABLE_QOS)
        self._pub_refused = self.create_publisher(DiagnosticStatus, "pusher/refused",
                                                  RELIABLE_QOS)
        self._pub_path = self.create_publisher(Path, "executor/path", LATCHED_QOS)
        self._pub_status = self.create_publisher(DiagnosticStatus, "executor/status",
                                                 LATCHED_QOS)
        self._pub_goal = self.create_publisher(DiagnosticStatus, "executor/goal_result",
                                               RELIABLE_QOS)
        self._goal_stamp: Any = None  # the joint goal the running motion goes to
        self.create_subscription(Path, "planner/push", guard(self._on_push), RELIABLE_QOS)
        self.create_subscription(JointState, "/joint_states", guard(self._on_joint_state),
                                 JOINT_STATE_QOS)
        self.create_subscription(JointState, "executor/joint_goal", guard(self._on_joint_goal),
                                 RELIABLE_QOS)
        self.scene = SceneInputs(self, guard, lambda what, why: self.health.refuse(
            what, why, "invalid"), self.params.clear, lambda: self._request_park("episode over"))
        if p["robot_description_file"]:
            self._load_model(FilePath(p["robot_description_file"]).read_text())
            if self._arm is None:
                raise ValueError(f"parameter robot_description_file: {self.health.last_refusal}")
        else:
            self.create_subscription(String, "/robot_description",
                                     guard(self._on_description), LATCHED_QOS)
        self.create_service(Trigger, "~/cancel", guard(self._on_cancel))
        self.create_service(SetBool, "~/enable", guard(self._on_enable))
        steady = Clock(clock_type=ClockType.STEADY_TIME)  # sim time stops while idle
        self.create_timer(WATCHDOG_PERIOD, guard(self._on_watchdog), clock=steady)
        self.create_timer(DIAGNOSTICS_PERIOD, guard(self._publish_status), clock=steady)
        self._publish_status()
        self.get_logger().info("push executor ready")

    # ---- inputs ------------------------------------------------------------------------------
    def _load_model(self, urdf: str) -> None:
        p = self.params.values
        try:
            arm = ArmKinematics(urdf, p["base_frame"], self.params.tool, p["base_pose"],
                                p["acceleration_limits"], p["jerk_limits"])
            joints = tuple(p["joints"]) if p["joints"] else arm.joint_names
            if sorted(joints) != sorted(arm.joint_names):
                raise ValueError(f"parameter joints {list(joints)[:16]} is not the chain "
                                 f"{list(arm.joint_names)}")
            self.params.motion.check_chain(arm.joint_names)
        except ValueError as exc:
            self.health.refuse("robot_description", str(exc), "model")
            return
        robot, why = robot_mask_factory(urdf, p["base_pose"], arm.joint_names) \
            if self.params.clear["enabled"] else (None, "")
        if why:  # the arm still works: it parks after every push
            self.health.refuse("robot_description", f"{why}; parking after every push", "model")
        self._arm, self._robot, self._urdf, self._joints = arm, robot, urdf, joints
        self.measured = MeasuredArm(HELD_STATES, HELD)
        self.health.count("models")
        self._publish_status()

    def _on_description(self, msg: String) -> None:
        if msg.data == self._urdf:
            return
        if self._run is not None:
            self.health.refuse("robot_description", "arm is moving; model kept", "busy")
            return
        self._load_model(msg.data)

    def _on_joint_state(self, msg: JointState) -> None:
        if self._arm is None:
            return
        try:
            stamp, q = m.joint_state_from_msg(msg, self._arm.joint_names,
                                            clock_seconds(self.get_clock()),
                                            self.params.values["max_future_stamp"])
        except ValueError as exc:  # non-finite chain positions: a posture, but an unknown one
            problem = nonfinite_joints(self._arm.joint_names, msg.name, msg.position) \
                if len(msg.name) <= m.MAX_JOINTS else ""
            self.health.refuse("/joint_states", str(exc), "state" if problem else "invalid")
            self.measured.problem = problem or self.measured.problem
            return
        problem = posture_problem(self._arm, q, self.params.checks.state_margin)
        if problem:  # not a posture the arm can be in: the last plausible one is kept
            self.measured.problem = problem
            self.health.refuse("/joint_states", problem, "state")
            return
        steady = time.monotonic()
        restarted = self.measured.update(stamp, q, steady, replace=self._run is None)
        self.health.count("joint_states")
        if restarted:  # a restarted driver or simulator: the running plan's times are gone
            self.health.log.warning("clock", f"joint-state stamps jumped back to {stamp:.3f} s: "
                                    "the controller's clock restarted")
        if self._run is not None:
            self._finish(Event("restarted", "the controller's clock restarted") if restarted
                         else self._run.on_state(stamp, q, steady))
        else:
            self._when_held(steady)

    def _on_push(self, msg: Path) -> None:
        self.health.count("pushes")
        self._take_push(msg)

    def _take_push(self, msg: Path, waited: bool = False) -> None:
        stamp = msg.header.stamp
        run = self._run
        if run is not None and self._enabled and not run.chainable:
            return self._refuse(stamp, "busy", run.plan.stage_at(run.elapsed(self.measured.stamp)),
                                "the arm is executing a push")
        try:
            approach, contact, end = m.push_from_msg(msg, self.params.values["world_frame"])
        except ValueError as exc:
            return self._refuse(stamp, "invalid", "input", str(exc))
        if self._arm is None:
            return self._refuse(stamp, "no_model", "", "no robot description yet")
        try:
            check_before_planning(self._arm, self.measured, self.params.checks,
                                  self.params.motion, time.monotonic(),
                                  clock_seconds(self.get_clock()))
        except PushRefused as refusal:
            return self._refuse(stamp, refusal.kind, refusal.stage, refusal.reason)
        if self._run is None and self._enabled and not waited \
                and not self.measured.held(time.monotonic()):
            self._deferred = (msg, time.monotonic())  # planned once the states show it held
            return None
        view, why = self.scene.view(contact, end, self._robot)
        self._plan_values = {"view": why or "clear pose"}
        try:
            self._start(lambda start, lead, first: plan_push(
                self._arm, self.params.motion, approach, contact, end, start, view, lead,
                first), stamp)
        except PushRefused as refusal:
            if self._run is None:  # planned from the measured posture: can it be left?
                refusal = self._stuck.classify(refusal, self._arm, self.measured.q,
                                               self.params.motion)
            return self._refuse(stamp, refusal.kind, refusal.stage, refusal.reason)
        self._plan_values["clear_checked"] = str(getattr(view, "checked", 0))
        return self._publish_status()

    def _on_joint_goal(self, msg: JointState) -> None:
        """Move to the goal posture (push_executor.joint_goal), answered on
        ``executor/goal_result``: ``reached``, or a refusal kind (``disabled``: planned,
        its path published, nothing moved)."""
        stamp = msg.header.stamp
        self.health.count("goals")
        try:
            if self._run is not None:
                raise PushRefused("busy", "", "the arm is moving")
            if self._arm is None:
                raise PushRefused("no_model", "", "no robot description yet")
            goal = goal_positions(msg.name, msg.position, self._arm.joint_names)
            check_before_planning(self._arm, self.measured, self.params.checks,
                                  self.params.motion, time.monotonic(),
                                  clock_seconds(self.get_clock()))
            if not self.measured.held(time.monotonic()):
                raise PushRefused("settling", "", "the arm is still moving")
            self._plan_values = {"goal": stamp_key(stamp)}
            self._start(lambda start, lead, first: plan_joint_goal(
                self._arm, self.params.motion, goal, start, lead, first), stamp)
        except PushRefused as refusal:
            return self._answer_goal(stamp, refusal.kind, refusal.stage, refusal.reason)
        self._goal_stamp = stamp
        return self._publish_status()

    def _answer_goal(self, stamp: Any, kind: str, stage: str, reason: str) -> None:
        if kind != "reached":
            self.health.refuse("joint goal", f"{kind} ({stage}): {reason}" if stage else reason,
                               kind)
        msg = refusal_msg(self.get_fully_qualified_name(), stamp, kind, reason, stage, "arm")
        if kind == "reached":
            msg.level = DiagnosticStatus.OK
        self._pub_goal.publish(msg)

    # ---- execution ---------------------------------------------------------------------------
    def _start(self, make: PlanMaker, stamp: Any) -> None:
        """Plan (from the measured state, or chained from the running plan) and send; raises
        :class:`PushRefused` (also ``disabled``, ``no_controller``, ``busy``)."""
        p = self.params.values
        run = self._run if self._enabled or stamp is None else None  # a dry run: from here
        plan, t0, chained = start_plan(make, run, self.measured.q, self._now, p["start_delay"],
                                       self.params.motion.start_delay)
        check_plan(plan, self.params.checks)
        self._pub_path.publish(m.path_msg(plan, p["world_frame"], self.get_clock().now().to_msg()))
        if not self._enabled and stamp is not None:
            raise PushRefused("disabled", "", "executor disabled (dry run): planned, not moved")
        if self._pub_traj.get_subscription_count() == 0:
            raise PushRefused("no_controller", "", "no controller subscribes "
                              f"{self._pub_traj.topic_name}")
        self._pub_traj.publish(m.trajectory_msg(plan, self._joints, t0))
        self.get_logger().info(f"{'chained' if chained else 'sent'}: {m.stage_text(plan)}; starts "
                               f"{t0:.3f} s (measured {self.measured.stamp:.3f} s)")
        if run is not None:
            self.health.count("chained")
        self._run = Execution(plan, t0, time.monotonic(), self.measured.stamp,
                              p["tracking_tolerance"], p["state_timeout"], p["start_timeout"],
                              p["tracking_window"], previous=run, moving=chained)
        self._push_stamp, self._stopped, self._park_pending = stamp, False, ""
        self._plan_values.update(plan_t0=f"{t0:.6f}", final=plan.final, stages=m.stage_text(plan),
                                 push="" if stamp is None else stamp_key(stamp))

    def _now(self) -> float:
        """The controller's time now at least: the node's clock or the newest joint state's
        stamp carried forward (:class:`StampClock`), s (``PushRefused`` before the clock)."""
        clock = clock_seconds(self.get_clock())
        if clock is None:
            raise PushRefused("no_state", "", "the node's clock has not started")
        return max(clock, self.measured.clock.now(time.monotonic()))

    def _request_park(self, reason: str) -> None:
        """Park once the arm is free: now if idle, after the running motion otherwise."""
        self._park_pending = reason
        if self._run is None and self.measured.held(time.monotonic()):
            self._park()

    def _park(self) -> None:
        """Plan and send the park motion (only the disable's own while disabled)."""
        reason, self._park_pending = self._park_pending, ""
        if self._arm is None or self.measured.q is None or self._parked() \
                or not (self._enabled or reason == "disabled"):
            return
        try:
            self._start(lambda start, lead, first: plan_park(
                self._arm, self.params.motion, start, lead, first), None)
        except PushRefused as refusal:
            self.health.refuse("park", f"{refusal.kind} ({refusal.stage}): {refusal.reason}",
                               refusal.kind)
            return
        self.health.count("parks")
        self.health.log.warning("park", f"parking: {reason}")
        self._publish_status()

    def _parked(self) -> bool:
        return self.measured.at(self.params.motion.park_positions, PARKED)

    def _when_held(self, steady: float) -> None:
        """A push waiting for the arm to rest (planned at the latest after state_timeout),
        else a pending park, once the arm is held."""
        if self._run is not None:
            return
        held = self.measured.held(steady)
        if self._deferred is not None and (held or steady - self._deferred[1] >
                                           self.params.values["state_timeout"]):
            msg, self._deferred = self._deferred[0], None
            self._take_push(msg, waited=True)
        elif self._park_pending and held:
            self._park()

    def _on_watchdog(self) -> None:
        self._when_held(time.monotonic())
        if self._run is not None:
            self._finish(self._run.on_timer(time.monotonic()))
        if self._unavailable() != self._readiness:  # executor/status says when it changes
            self._publish_status()

    def _unavailable(self) -> tuple[str, str] | None:
        """Why no push can be taken now (push_executor.state_check.unavailable), or None."""
        return unavailable(model=self._arm is not None, enabled=self._enabled, arm=self._arm,
                           measured=self.measured, stuck=self._stuck, config=self.params.checks,
                           motion=self.params.motion, moving=self._run is not None,
                           controller=self._pub_traj.get_subscription_count() > 0,
                           steady=time.monotonic(), clock=clock_seconds(self.get_clock()))

    def _report(self, run: Execution) -> None:
        """Publish the run's measured contact segment (or answer its push with a fault)."""
        try:
            seg = run.report(self._arm)
        except ValueError as exc:
            self._refuse(self._push_stamp, "fault", "push", str(exc))
            return
        self._line_error_mm = seg.line_error * 1e3
        self._pub_executed.publish(m.executed_msg(seg, self.params.values["world_frame"]))
        self.health.count("executed")

    def _finish(self, event: Event | None) -> None:
        if event is None or self._run is None:
            return
        run = self._run
        if event.kind in ("executed", "done") and not run.reported:
            self._report(run)
        if event.kind == "executed":
            return self._publish_status()
        self._run = None
        if run.plan.final == GOAL and self._goal_stamp is not None:
            self._answer_goal(self._goal_stamp, "reached" if event.kind == "done" else "fault",
                              GOAL, "at the goal" if event.kind == "done"
                              else f"stopped ({event.kind}): {event.reason}")
            self._goal_stamp = None
        if event.kind != "done":
            self._stop(f"{event.kind}: {event.reason}")
            if not run.reported:
                self._refuse(self._push_stamp, "fault", run.plan.stage_at(
                    run.elapsed(self.measured.stamp)), f"stopped ({event.kind}): {event.reason}")
        elif self._park_pending:
            self._park()
        self._publish_status()
        return None

    def _stop(self, reason: str, run: Execution | None = None) -> bool:
        """Send the one-point hold trajectory; False without a measured posture. Stopping a
        ``run`` that tracks its plan (``~/cancel``, disable; the measured posture within the
        tracking tolerance of the commanded one) decelerates from the commanded state now to
        rest at the joints' acceleration limits (:meth:`Execution.stop`); any other stop (a
        fault: the plan may not be where the arm is) holds the measured posture."""
        if self.measured.q is None or self._arm is None:
            return False
        try:
            stop_time = self._now()
        except PushRefused:
            stop_time = self.measured.stamp
        names, q, seconds = self._arm.joint_names, self.measured.q, m.HOLD_TIME
        stop = None if run is None else run.stop(stop_time, self.measured.q, self._arm,
                                                 m.HOLD_TIME)
        if stop is not None:
            names, (q, seconds) = run.plan.joint_names, stop
        self._pub_traj.publish(m.hold_msg(self._joints, dict(zip(names, q, strict=True)),
                                          seconds))
        self._stop_values = {"stop_time": f"{stop_time:.6f}", "stop_s": f"{seconds:.3f}"}
        self._stopped = True
        self.measured.moved()
        self.health.count("stopped")
        self.health.log.warning("stop", f"arm stopped: {reason}")
        return True

    def _on_cancel(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        run, self._run = self._run, None
        response.success = self._stop("~/cancel", run)
        if run is not None and not run.reported:
            self._refuse(self._push_stamp, "cancelled", run.plan.stage_at(
                run.elapsed(self.measured.stamp)), "cancelled by ~/cancel")
        if run is not None and run.plan.final == GOAL and self._goal_stamp is not None:
            self._answer_goal(self._goal_stamp, "cancelled", GOAL, "cancelled by ~/cancel")
            self._goal_stamp = None
        response.message = "holding, then parking" if response.success \
            else "no joint state: nothing to hold"
        self._park_pending = "~/cancel" if response.success else ""
        self._publish_status()
        return response

    def _on_enable(self, request: SetBool.Request, response: SetBool.Response
                   ) -> SetBool.Response:
        was, self._enabled = self._enabled, bool(request.data)
        if not self._enabled and was:
            if self._run is not None and (self._run.plan.is_push
                                          or self._run.plan.final == GOAL):
                self._on_cancel(Trigger.Request(), Trigger.Response())
            self._request_park("disabled")
        response.success, response.message = True, "enabled" if self._enabled else "disabled"
        self._publish_status()
        return response

    # ---- outputs -----------------------------------------------------------------------------
    def _refuse(self, stamp: Any, kind: str, stage: str, reason: str) -> None:
        self.health.refuse("push", f"{kind} ({stage}): {reason}" if stage else reason, kind)
        self._pub_refused.publish(refusal_msg(self.get_fully_qualified_name(), stamp, kind,
                                              reason, stage, "arm",
                                              available=self._unavailable() is None))
        self._publish_status()

    def _publish_status(self) -> None:
        run = self._run
        state = ("disabled" if not self._enabled and run is None
                 else "goal" if run is not None and run.plan.final == GOAL
                 else "parking" if run is not None and not run.plan.is_push
                 else "moving" if run is not None else "stopped" if self._stopped else "idle")
        level = DiagnosticStatus.WARN if self._arm is None or self._stopped \
            else DiagnosticStatus.OK
        model = "no robot description" if self._arm is None else f"{len(self._joints)} joints"
        readiness, self._readiness = self._readiness, self._unavailable()
        if readiness != self._readiness:  # the log says why it cannot take a push, and since when
            self.health.log.info("readiness", f"not ready: {': '.join(self._readiness)}"
                                 if self._readiness else "ready for a push")
        extra = {"state": state, "model": model, "at_park": str(self._parked()).lower(),
                 "contact_line_error_mm": f"{self._line_error_mm:.4f}", **self._plan_values,
                 **self._stop_values,
                 **readiness_values(run is None and self._readiness is None, self._readiness,
                                    self._session)}
        self._pub_status.publish(self.health.status(level, f"{state}, {model}", extra))
        self.health.publish(level, f"{state}, {model}", extra)


def main(args: list[str] | None = None) -> None:
    """``ros2 run push_executor push_executor_node``."""
    run_node(lambda: PushExecutorNode(), NODE_NAME, args)


if __name__ == "__main__":
    main()
