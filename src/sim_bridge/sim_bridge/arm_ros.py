"""The arm mode's ROS endpoints of ``sim_bridge_node`` (composed by the node; no physics here).

Endpoints (only with ``robot: arm``; docs/design/arm.md#arm-mode-of-the-simulator):

- ``/joint_states`` (sensor_msgs/JointState; reliable, depth 10): the 7 Panda joints
  (positions rad, velocities rad/s, efforts N m), stamp = sim time. At ``arm.joint_state_rate``
  Hz of sim time while a trajectory runs (from the physics thread), and at
  ``IDLE_JOINT_STATE_RATE`` Hz of wall time while idle (at the current time: it runs while the
  world rests), and after every camera frame at the frame's time.
- ``/robot_description`` (std_msgs/String; reliable, transient local): the URDF the arm was
  loaded from (Panda + pusher rod, absolute mesh paths).
- ``sim/tool_tip`` (nav_msgs/Path; reliable): ground truth for benchmarks, after every run of
  trajectories (published before its camera frame): frame ``world``, the true tool tip
  positions (x, y, z, m; orientation identity) sampled at ``arm.joint_state_rate`` Hz of sim
  time during the run, each pose stamped with its sim time, header stamp = the run's end.
- ``<arm.controller_topic>`` (in; trajectory_msgs/JointTrajectory; reliable, depth 10): checked
  with :func:`sim_bridge.arm.check_trajectory` at the current sim time; a rejected message is
  logged and counted (``trajectories_rejected``, reason in ``last_error``), nothing moves.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rclpy.clock import Clock, ClockType
from sensor_msgs.msg import JointState as JointStateMsg
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from push_ros.frames import WORLD_FRAME
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS
from push_ros.stamps import seconds_from_stamp, stamp_from_seconds
from sim_bridge.arm import (
    TrajectoryCommand,
    TrajectoryFollower,
    TrajectoryRejected,
    check_trajectory,
)
from sim_bridge.arm_motion import ArmRun
from sim_bridge.arm_robot import ARM_JOINTS, JointState
from sim_bridge.worker import Timeline, Worker

__all__ = ["IDLE_JOINT_STATE_RATE", "ArmEndpoints", "command_from_msg"]

#: /joint_states rate while no trajectory runs, Hz of wall time.
IDLE_JOINT_STATE_RATE = 10.0
#: Most points / joints read from one JointTrajectory (bounded work per message).
MAX_POINTS = 100000
MAX_JOINTS = 64


def _seconds(duration: Duration) -> float:
    return float(duration.sec) + 1e-9 * float(duration.nanosec)


def command_from_msg(msg: JointTrajectory) -> TrajectoryCommand:
    """A ``JointTrajectory`` as a :class:`TrajectoryCommand` (float seconds).

    Raises
    ------
    TrajectoryRejected
        ``stamp``: a header stamp :func:`push_ros.stamps.seconds_from_stamp` refuses;
        ``size``: more than ``MAX_POINTS`` points or ``MAX_JOINTS`` joint names.
    """
    if len(msg.points) > MAX_POINTS or len(msg.joint_names) > MAX_JOINTS:
        raise TrajectoryRejected("size", f"{len(msg.points)} points / {len(msg.joint_names)} "
                                         f"joints: at most {MAX_POINTS} / {MAX_JOINTS}")
    try:
        stamp = seconds_from_stamp(msg.header.stamp)
    except ValueError as exc:
        raise TrajectoryRejected("stamp", str(exc)) from None
    return TrajectoryCommand(
        joint_names=[str(n)[:256] for n in msg.joint_names],
        stamp=stamp,
        times=[_seconds(pt.time_from_start) for pt in msg.points],
        positions=[list(pt.positions) for pt in msg.points],
        velocities=[list(pt.velocities) for pt in msg.points],
        accelerations=[list(pt.accelerations) for pt in msg.points])


class ArmEndpoints:
    """Publishers, the trajectory subscription and the follower of the arm mode.

    Parameters
    ----------
    node : rclpy.node.Node
    controller_topic : str
    max_duration : float
        Longest accepted trajectory, s (:func:`check_trajectory`).
    timeline : sim_bridge.worker.Timeline
        Published time = ``epoch + sim_time``.
    sim_time : callable
        The world's current sim time, s (no epoch).
    health : push_ros.health.NodeHealth
        The node's health: counts ``trajectories_accepted``, logs joint states that could
        not be published.
    guard : callable
        Wraps a callback so that nothing escapes it (the node's guard).
    on_rejected : callable
        ``on_rejected(kind, reason)``: count and report a rejected trajectory (``kind``: the
        :class:`TrajectoryRejected` kind, or ``busy``).
    worker : sim_bridge.worker.Worker
        An accepted trajectory (its stamp in the world's sim time, without the epoch) goes to
        the running physics loop, or ``run`` is started in it (:meth:`Worker.start_arm`); a
        busy worker rejects it (kind ``busy``).
    run : callable
        The worker job that steps the physics while the arm follows trajectories.
    closing : callable
        True once the node is being destroyed (nothing is published then).
    scene : sim_bridge.scene_ros.SceneEndpoints, optional
        Its frames are followed by the arm's joint state at their time (a perception
        self-filter pairs each frame with the joint state at its stamp; the idle stream's
        10 Hz of wall time thins out on a loaded machine).
    """

    def __init__(self, node: Any, controller_topic: str, max_duration: float,
                 timeline: Timeline, sim_time: Callable[[], float], health: Any,
                 guard: Callable[..., Any], on_rejected: Callable[[str, str], None],
                 worker: Worker, run: Callable[[], Any], closing: Callable[[], bool],
                 scene: Any = None) -> None:
        self.follower = TrajectoryFollower(ARM_JOINTS)
        self._node = node
        self._timeline, self._sim_time, self._closing = timeline, sim_time, closing
        self._health, self._worker, self._run = health, worker, run
        self._max_duration = max_duration
        self._on_rejected = on_rejected
        self._last: tuple[float, JointState] | None = None
        self.pub_joint_states = node.create_publisher(JointStateMsg, "/joint_states",
                                                      RELIABLE_QOS)
        self.pub_description = node.create_publisher(String, "/robot_description", LATCHED_QOS)
        self.pub_tool_tip = node.create_publisher(Path, "sim/tool_tip", RELIABLE_QOS)
        self.on_trajectory = guard(self._on_trajectory)
        node.create_subscription(JointTrajectory, controller_topic, self.on_trajectory,
                                 RELIABLE_QOS)
        node.create_timer(1.0 / IDLE_JOINT_STATE_RATE, guard(self._on_idle_timer),
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        if scene is not None:
            scene.after_frame = self._at_frame

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        try:
            trajectory = check_trajectory(command_from_msg(msg), ARM_JOINTS,
                                          self._timeline.at(self._sim_time()),
                                          self._max_duration)
        except TrajectoryRejected as exc:
            self._on_rejected(exc.kind, f"({exc.kind}) {exc}")
            return
        if trajectory.stamp != 0.0:  # the world's sim_time has no epoch
            trajectory = replace(trajectory,
                                 stamp=max(trajectory.stamp - self._timeline.epoch, 1e-9))
        follower = self.follower
        reason = self._worker.start_arm(lambda: follower.offer(trajectory), follower.open,
                                        self._run)
        if reason:
            self._on_rejected("busy", reason)
        else:
            self._health.count("trajectories_accepted")

    def run(self, world: Any, joint_state_rate: float, monitor: Any,
            on_monitor: Callable[[Any], None], real_time_factor: float) -> ArmRun:
        """Step ``world`` (:class:`sim_bridge.world.PushWorld`, worker thread) while the arm
        follows the trajectories: ``/joint_states`` every ``1 / joint_state_rate`` s of sim
        time (whole physics steps), monitor frames to ``on_monitor`` when ``monitor`` is set."""
        steps = max(1, round(1.0 / (joint_state_rate * world.config.time_step)))
        return world.run_arm(self.follower, steps, self.joint_state, monitor,
                             None if monitor is None else on_monitor, real_time_factor)

    def joint_state(self, sim_time: float, state: JointState) -> None:
        """``/joint_states`` at the published time of the world's ``sim_time`` (s); any thread,
        never raises (the physics loop calls it)."""
        if self._closing():
            return
        try:
            self.publish_state(self._timeline.at(sim_time), state)
        except Exception as exc:  # e.g. the context shut down meanwhile
            self._health.log.warning("joint_states", f"joint state not published: {exc}")

    def publish_state(self, time: float, state: JointState) -> None:
        """Publish ``/joint_states`` at sim time ``time`` (s) and keep it for the idle timer."""
        self._last = (time, state)
        msg = JointStateMsg(name=list(state.names), position=state.positions.tolist(),
                            velocity=state.velocities.tolist(), effort=state.efforts.tolist())
        msg.header.stamp = stamp_from_seconds(time)
        self.pub_joint_states.publish(msg)

    def _on_idle_timer(self) -> None:
        """The resting arm's state again, at the current time (the clock runs while the world
        rests)."""
        last = self._last
        if last is not None and not self.follower.running:
            self.publish_state(max(last[0], self._timeline.last), last[1])

    def _at_frame(self, time: float) -> None:
        """The arm's newest state again at a frame's time (s), unless newer ones exist."""
        last = self._last
        if last is not None and time >= last[0]:
            self.publish_state(time, last[1])

    def publish_description(self, urdf: str) -> None:
        """Latch the URDF on ``/robot_description``."""
        self.pub_description.publish(String(data=urdf))

    def publish_tool_tip(self, run: ArmRun) -> None:
        """``sim/tool_tip`` of one run (module docstring); times are ``epoch + sim_time``."""
        epoch = self._timeline.epoch
        path = Path()
        path.header.frame_id = WORLD_FRAME
        path.header.stamp = stamp_from_seconds(epoch + run.t_done)
        for t, xyz in zip(run.tip_times, np.asarray(run.tip_positions), strict=True):
            pose = PoseStamped()
            pose.header.frame_id = WORLD_FRAME
            pose.header.stamp = stamp_from_seconds(epoch + float(t))
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = map(float, xyz)
            pose.pose.orientation.w = 1.0
            path.poses.append(pose)
        self.pub_tool_tip.publish(path)
