"""``push_executor_node``: executes planned pushes on a ros2_control arm.

Role: turns each ``planner/push`` into one checked joint trajectory for the arm's
joint_trajectory_controller (transit, descend, push, retreat, lift, park), watches it on
``/joint_states`` and reports the executed contact segment on ``pusher/executed`` from forward
kinematics of the *measured* joints, or refuses the push on ``pusher/refused``. The maths is the
ROS-free core: :mod:`push_executor.kinematics`, :mod:`push_executor.motion`,
:mod:`push_executor.tracking`; parameters: :mod:`push_executor.parameters`.

Invariants: one motion at a time; a push ended by a stop (watchdog, ``~/cancel``, disable: a
one-point hold trajectory) is answered on ``pusher/refused`` so the planner re-plans at once; the
watchdogs run on the steady clock; no exception leaves a callback; it never imports pybullet or
sim_bridge.

Topics, services and parameters: docs/INTERFACES.md; states, refusal kinds and timing:
docs/design/arm.md.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path as FilePath
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from push_executor.kinematics import ArmKinematics
from push_executor.motion import MotionPlan, PushRefused, plan_push
from push_executor.parameters import NODE_NAME, PARAMETERS, ExecutorParams
from push_executor.state_check import (
    MeasuredPosture,
    StuckPosture,
    check_before_planning,
    check_plan,
    nonfinite_joints,
    posture_problem,
    unavailable,
)
from push_executor.tracking import Event, Execution, chain_positions
from push_ros.health import NodeHealth
from push_ros.node import declare_config, run_node
from push_ros.paths import path_from_points, push_points_from_path
from push_ros.poses import pose_msg
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS
from push_ros.refusal import readiness_values, refusal_msg
from push_ros.stamps import check_not_ahead, clock_seconds, seconds_from_stamp, stamp_from_seconds
from push_ros.stamps import duration_from_seconds as duration

__all__ = ["PARAMETERS", "ExecutorParams", "PushExecutorNode", "main"]

#: Joint states: reliable, depth 50 (docs/design/arm.md#push_executor).
JOINT_STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)
#: ``time_from_start`` of the one-point hold trajectory, s.
HOLD_TIME = 0.05
#: Most joints a joint state may name (a bigger message is refused before any work).
MAX_JOINTS = 1000
#: Watchdog timer and /diagnostics periods, s.
WATCHDOG_PERIOD, DIAGNOSTICS_PERIOD = 0.05, 1.0
COUNTERS = ("pushes", "executed", "stopped", "models", "joint_states")
class PushExecutorNode(Node):
    """The node (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.params = declare_config(self, PARAMETERS, ExecutorParams.from_values)
        p = self.params.values
        self.health = NodeHealth(self, "push executor", "arm", COUNTERS)
        guard = self.health.guard
        self._arm: ArmKinematics | None = None
        self._urdf = ""
        self._joints: tuple[str, ...] = ()
        self._q: np.ndarray | None = None
        self._q_stamp = -math.inf
        self._q_steady = -math.inf
        self._enabled = bool(p["start_enabled"])
        self._run: Execution | None = None
        self._push_stamp: Any = None
        self._stopped = False
        self._line_error_mm = math.nan
        self._q_problem, self._stuck = "", StuckPosture()  # push_executor.state_check
        self._session, self._readiness = f"{os.getpid()}-{time.time_ns()}", None
        self._pub_traj = self.create_publisher(JointTrajectory, p["controller_topic"],
                                               RELIABLE_QOS)
        self._pub_executed = self.create_publisher(Path, "pusher/executed", RELIABLE_QOS)
        self._pub_refused = self.create_publisher(DiagnosticStatus, "pusher/refused",
                                                  RELIABLE_QOS)
        self._pub_path = self.create_publisher(Path, "executor/path", LATCHED_QOS)
        self._pub_status = self.create_publisher(DiagnosticStatus, "executor/status",
                                                 LATCHED_QOS)
        self.create_subscription(Path, "planner/push", guard(self._on_push), RELIABLE_QOS)
        self.create_subscription(JointState, "/joint_states", guard(self._on_joint_state),
                                 JOINT_STATE_QOS)
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
                                p["acceleration_limits"])
            joints = tuple(p["joints"]) if p["joints"] else arm.joint_names
            if sorted(joints) != sorted(arm.joint_names):
                raise ValueError(f"parameter joints {list(joints)[:16]} is not the chain "
                                 f"{list(arm.joint_names)}")
            self.params.motion.check_chain(arm.joint_names)
        except ValueError as exc:
            self.health.refuse("robot_description", str(exc), "model")
            return
        self._arm, self._urdf, self._joints = arm, urdf, joints
        self._q = None
        self.health.count("models")
        self._publish_status()

    def _on_description(self, msg: String) -> None:
        if msg.data == self._urdf:
            return
        if self._run is not None:
            self.health.refuse("robot_description", "arm is moving; model kept", "busy")
            return
        self._load_model(msg.data)

    def _on_joint_state(self, msg: JointState) -> None:  # noqa: RET503 - None either way
        if self._arm is None:
            return
        if len(msg.name) > MAX_JOINTS:
            self.health.refuse("/joint_states", f"{len(msg.name)} joints", "invalid")
            return
        try:
            stamp = seconds_from_stamp(msg.header.stamp)
            check_not_ahead(stamp, clock_seconds(self.get_clock()),
                            self.params.values["max_future_stamp"], "joint state stamp")
            q = chain_positions(self._arm.joint_names, list(msg.name), msg.position)
            problem = posture_problem(self._arm, q, self.params.checks.state_margin)
        except ValueError as exc:
            problem = nonfinite_joints(self._arm.joint_names, msg.name, msg.position)
            self.health.refuse("/joint_states", str(exc), "state" if problem else "invalid")
            self._q_problem = problem or self._q_problem
            return
        if problem:  # not a posture the arm can be in: the last plausible one is kept
            self._q_problem = problem
            return self.health.refuse("/joint_states", problem, "state")
        steady = time.monotonic()
        if stamp >= self._q_stamp or self._run is None:
            self._q, self._q_stamp, self._q_steady, self._q_problem = q, stamp, steady, ""
        self.health.count("joint_states")
        if self._run is not None:
            self._finish(self._run.on_state(stamp, q, steady))

    def _on_push(self, msg: Path) -> None:
        self.health.count("pushes")
        stamp = msg.header.stamp
        if self._run is not None:
            return self._refuse(stamp, "busy", "", "the arm is executing a push")
        try:
            seconds_from_stamp(stamp)
            if msg.header.frame_id != self.params.values["world_frame"]:
                raise ValueError(f"frame {msg.header.frame_id[:64]!r} is not "
                                 f"{self.params.values['world_frame']!r}")
            approach, contact, end = push_points_from_path(msg)
        except ValueError as exc:
            return self._refuse(stamp, "invalid", "input", str(exc))
        if self._arm is None:
            return self._refuse(stamp, "no_model", "", "no robot description yet")
        try:
            q = check_before_planning(self._arm, self._posture(), self.params.checks,
                                      self.params.motion, time.monotonic(),
                                      clock_seconds(self.get_clock()))
            plan = plan_push(self._arm, self.params.motion, approach, contact, end, q)
            check_plan(plan, self.params.checks)
        except PushRefused as refusal:
            refusal = self._stuck.classify(refusal, self._arm, self._q, self.params.motion)
            return self._refuse(stamp, refusal.kind, refusal.stage, refusal.reason)
        self._pub_path.publish(self._path_msg(plan))
        t0 = clock_seconds(self.get_clock())
        if t0 is not None:  # the measured state's stamp is the controller's time now, at least
            t0 = max(t0, self._q_stamp)
        if not self._enabled:
            return self._refuse(stamp, "disabled", "", "executor disabled (dry run): planned, "
                                "not moved")
        if self._pub_traj.get_subscription_count() == 0:
            return self._refuse(stamp, "no_controller", "", "no controller subscribes "
                                f"{self._pub_traj.topic_name}")
        if t0 is None:
            return self._refuse(stamp, "no_state", "", "the node's clock has not started")
        t0 += self.params.values["start_delay"]  # the motion starts then, not on receipt
        self._pub_traj.publish(self._trajectory_msg(plan, t0))
        self._run = Execution(plan, t0, time.monotonic(), self._q_stamp,
                              self.params.values["tracking_tolerance"],
                              self.params.values["state_timeout"],
                              self.params.values["start_timeout"],
                              self.params.values["tracking_window"])
        self._push_stamp, self._stopped = stamp, False
        self._publish_status()
        return None

    # ---- execution ---------------------------------------------------------------------------
    def _on_watchdog(self) -> None:
        if self._run is not None:
            self._finish(self._run.on_timer(time.monotonic()))
        if self._unavailable() != self._readiness:  # executor/status says when it changes
            self._publish_status()

    def _posture(self) -> MeasuredPosture:
        return MeasuredPosture(self._q, self._q_stamp, self._q_steady, self._q_problem)

    def _unavailable(self) -> tuple[str, str] | None:
        """Why no push can be taken now (push_executor.state_check.unavailable), or None."""
        return unavailable(model=self._arm is not None, enabled=self._enabled, arm=self._arm,
                           posture=self._posture(), stuck=self._stuck,
                           config=self.params.checks, motion=self.params.motion,
                           controller=self._pub_traj.get_subscription_count() > 0,
                           steady=time.monotonic(), clock=clock_seconds(self.get_clock()))

    def _finish(self, event: Event | None) -> None:
        if event is None or self._run is None:
            return
        run, self._run = self._run, None
        if event.kind == "done":
            try:
                seg = run.contact_segment(self._arm)
            except ValueError as exc:
                self._refuse(self._push_stamp, "fault", "push", str(exc))
            else:
                self._line_error_mm = seg.line_error * 1e3
                stamps = [stamp_from_seconds(s, clamp=True) for s in (seg.stamp_start,
                                                                       seg.stamp_end)]
                self._pub_executed.publish(path_from_points(
                    np.array([seg.start[:2], seg.end[:2]]), stamps,
                    self.params.values["world_frame"]))
                self.health.count("executed")
        else:
            self._stop(f"{event.kind}: {event.reason}")
            self._refuse(self._push_stamp, "fault", run.plan.stage_at(
                run.elapsed(self._q_stamp)), f"stopped ({event.kind}): {event.reason}")
        self._publish_status()

    def _stop(self, reason: str) -> bool:
        """Send the one-point hold trajectory at the measured posture; False without one."""
        if self._q is None or self._arm is None:
            return False
        msg = JointTrajectory(joint_names=list(self._joints))
        q = dict(zip(self._arm.joint_names, self._q, strict=True))
        msg.points = [JointTrajectoryPoint(positions=[float(q[j]) for j in self._joints],
                                           velocities=[0.0] * len(self._joints),
                                           time_from_start=duration(HOLD_TIME))]
        self._pub_traj.publish(msg)
        self._stopped = True
        self.health.count("stopped")
        self.health.log.warning("stop", f"arm stopped: {reason}")
        return True

    def _on_cancel(self, request: Trigger.Request, response: Trigger.Response
                   ) -> Trigger.Response:
        run, self._run = self._run, None
        response.success = self._stop("~/cancel")
        if run is not None:
            self._refuse(self._push_stamp, "cancelled", run.plan.stage_at(
                run.elapsed(self._q_stamp)), "cancelled by ~/cancel")
        response.message = "holding" if response.success else "no joint state: nothing to hold"
        self._publish_status()
        return response

    def _on_enable(self, request: SetBool.Request, response: SetBool.Response
                   ) -> SetBool.Response:
        self._enabled = bool(request.data)
        if not self._enabled and self._run is not None:
            self._on_cancel(Trigger.Request(), Trigger.Response())
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

    def _trajectory_msg(self, plan: MotionPlan, start: float) -> JointTrajectory:
        order = [plan.joint_names.index(j) for j in self._joints]
        msg = JointTrajectory(joint_names=list(self._joints))
        msg.header.stamp = stamp_from_seconds(start, clamp=True)
        msg.points = [JointTrajectoryPoint(positions=q[order].tolist(),
                                           velocities=v[order].tolist(),
                                           time_from_start=duration(t))
                      for t, q, v in zip(plan.times, plan.positions, plan.velocities,
                                         strict=True)]
        return msg

    def _path_msg(self, plan: MotionPlan) -> Path:
        msg = Path()
        msg.header.frame_id = self.params.values["world_frame"]
        msg.header.stamp = self.get_clock().now().to_msg()
        for x, y, z in plan.tip:
            pose = PoseStamped(header=msg.header, pose=pose_msg(x, y, 0.0, z))
            msg.poses.append(pose)
        return msg

    def _publish_status(self) -> None:
        state = ("moving" if self._run is not None else "disabled" if not self._enabled
                 else "stopped" if self._stopped else "idle")
        level = DiagnosticStatus.WARN if self._arm is None or self._stopped \
            else DiagnosticStatus.OK
        model = "no robot description" if self._arm is None else f"{len(self._joints)} joints"
        readiness, self._readiness = self._readiness, self._unavailable()
        if readiness != self._readiness:  # the log says why it cannot take a push, and since when
            self.health.log.info("readiness", f"not ready: {': '.join(self._readiness)}"
                                 if self._readiness else "ready for a push")
        extra = {"state": state, "model": model,
                 "contact_line_error_mm": f"{self._line_error_mm:.4f}",
                 **readiness_values(self._run is None and self._readiness is None,
                                    self._readiness, self._session)}
        self._pub_status.publish(self.health.status(level, f"{state}, {model}", extra))
        self.health.publish(level, f"{state}, {model}", extra)


def main(args: list[str] | None = None) -> None:
    """``ros2 run push_executor push_executor_node``."""
    run_node(lambda: PushExecutorNode(), NODE_NAME, args)


if __name__ == "__main__":
    main()
