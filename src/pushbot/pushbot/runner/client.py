"""The graph runner's hidden client node: what it hears, how it waits, what it calls.

:class:`GraphClient` records the pipeline's public outputs in :class:`Recorded` (ground truth
from ``sim/object_pose``, estimates, the COM, pushes, executed pushes, ``planner/status``, and
with ``record_frames`` the camera frames, masks, camera matrix, extrinsics and outline), waits
on conditions with deadlines (:meth:`GraphClient.wait`: spins its own executor, fails as soon
as a node process exits), and drives the nodes through their services (``~/reset``,
``set_parameters``) and ``goal_pose``. It runs in its own rclpy context.
"""

from __future__ import annotations

import os
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from push_ros.dds import apply_default_profile
from pushbot.runner.graph_nodes import EXECUTOR_NODE, NODES, GraphError, graph_node_names

#: Newest ``/joint_states`` samples a client keeps (100 Hz of sim time while the arm moves).
JOINT_STATES_KEPT = 20000
#: The simulated arm's controller topic (push_executor_node's and sim_bridge_node's default).
ARM_TRAJECTORY_TOPIC = "/joint_trajectory_controller/joint_trajectory"

__all__ = ["SERVICE_TIMEOUT", "STARTUP_TIMEOUT", "GraphClient", "Recorded"]

#: Seconds for the four processes to start and discover each other (torch, pybullet, DDS).
STARTUP_TIMEOUT = 180.0
#: Seconds for a service call (the bridge's reset rebuilds the pybullet scene).
SERVICE_TIMEOUT = 60.0


@dataclass
class Recorded:
    """What the client received, in arrival order (wall time of arrival in ``*_t``)."""

    true: list[tuple[float, np.ndarray]] = field(default_factory=list)  # (stamp, x y theta)
    est: list[tuple[float, np.ndarray]] = field(default_factory=list)
    com: list[tuple[float, np.ndarray]] = field(default_factory=list)
    pushes: list[tuple[float, np.ndarray]] = field(default_factory=list)  # (wall, 3x2)
    #: Header stamps of the pushes (s of the planner's clock), one per entry of ``pushes``.
    push_stamps: list[float] = field(default_factory=list)
    #: The newest ``/clock`` (s; -inf before the first): the simulated time now.
    clock: float = -float("inf")
    executed: list[tuple[float, float, float]] = field(default_factory=list)  # (wall, t0, t1)
    status: list[dict[str, str]] = field(default_factory=list)
    #: ``executor/status`` values as they came (``robot`` arm).
    executor_status: list[dict[str, str]] = field(default_factory=list)
    #: ``sim/tool_tip`` (``robot`` arm): (run end stamp, (K,) sample stamps, (K, 3) true tip).
    tool_tip: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)
    #: ``/joint_states`` (``robot`` arm): (stamp s, positions, velocities), the newest kept.
    joint_states: deque[tuple[float, np.ndarray, np.ndarray]] = field(
        default_factory=lambda: deque(maxlen=JOINT_STATES_KEPT))
    #: ``pusher/refused`` values (``push_ros.refusal``) with ``who`` and ``reason``.
    refusals: list[dict[str, str]] = field(default_factory=list)
    #: ``executor/path`` messages received (the executor's planned tool paths).
    executor_paths: int = 0
    #: The last ``/diagnostics`` values per status name (``/sim_bridge_node: simulation``...).
    diagnostics: dict[str, dict[str, str]] = field(default_factory=dict)
    frames: dict[float, np.ndarray] = field(default_factory=dict)  # stamp -> rgb
    masks: dict[float, np.ndarray] = field(default_factory=dict)  # stamp -> bool mask
    outline: np.ndarray | None = None
    #: Stamps of the ``perception/outline`` messages (each episode reference frame's), s.
    outline_stamps: list[float] = field(default_factory=list)
    camera_matrix: np.ndarray | None = None
    t_world_camera: np.ndarray | None = None

    def forget_stamps(self) -> None:
        """Forget what is matched by stamps (ground truth, estimates, the COM, executed pushes,
        tool tips, outline stamps, joint states) and the newest ``/clock``: after the
        simulator's clock restarted, the old clock's stamps would match a later episode's by
        mistake (and its time would start the next episode's robot time)."""
        for items in (self.true, self.est, self.com, self.executed, self.tool_tip,
                      self.outline_stamps, self.joint_states):
            items.clear()
        self.clock = -float("inf")


class GraphClient:
    """The client node (module docstring).

    Parameters
    ----------
    rec : Recorded
        Where the received messages go.
    check_alive : callable
        Raises :class:`GraphError` when a node process has exited (checked while waiting).
    log_dir : Path
        Named in timeout messages (the node logs).
    record_frames : bool
        Also subscribe to the camera, the mask, the camera info, the extrinsics and the
        outline.
    robot : str
        ``pusher`` or ``arm`` (then ``push_executor_node`` takes ``planner/push`` and the
        bridge the joint trajectories).
    """

    def __init__(self, rec: Recorded, check_alive: Callable[[], None], log_dir: Path,
                 record_frames: bool = False, robot: str = "pusher") -> None:
        self.robot = robot
        self.names = graph_node_names(robot)
        self.rec = rec
        self.check_alive = check_alive
        self.log_dir = log_dir
        self.record_frames = record_frames
        self._context: Any = None
        self._node: Any = None
        self._executor: Any = None

    def start(self) -> None:
        """Create the context, the node, its subscriptions, publisher and service clients."""
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
        from geometry_msgs.msg import (
            PointStamped,
            PoseStamped,
            PoseWithCovarianceStamped,
            TransformStamped,
        )
        from nav_msgs.msg import Path as PathMsg
        from rclpy.context import Context
        from rclpy.event_handler import PublisherEventCallbacks
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.qos import (
            DurabilityPolicy,
            QoSProfile,
            ReliabilityPolicy,
            qos_profile_sensor_data,
        )
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import CameraInfo, Image, PointCloud2

        from push_ros.qos import CLOCK_QOS, GOAL_QOS, latched_reader_qos

        apply_default_profile()
        self._context = Context()
        rclpy.init(args=[], context=self._context)
        node = Node(f"_pushbot_graph_{os.getpid()}", context=self._context,
                    enable_rosout=False, start_parameter_services=False)
        self._node = node
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(node)
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        sub = node.create_subscription
        sub(PoseStamped, "sim/object_pose", self._on_true, reliable)
        estimates = latched_reader_qos(100)  # the estimator's outputs are latched
        sub(PoseWithCovarianceStamped, "estimator/object_pose", self._on_est, estimates)
        sub(PointStamped, "estimator/center_of_mass", self._on_com, estimates)
        sub(PathMsg, "planner/push", self._on_push, reliable)
        sub(Clock, "/clock", self._on_clock, CLOCK_QOS)
        sub(PathMsg, "pusher/executed", self._on_executed, reliable)
        sub(DiagnosticStatus, "planner/status", self._on_status, latched)
        sub(DiagnosticArray, "/diagnostics", self._on_diagnostics, reliable)
        sub(PointCloud2, "perception/outline", self._on_outline, latched)
        if self.record_frames:
            sub(Image, "camera/color/image_raw", self._on_rgb, qos_profile_sensor_data)
            sub(Image, "perception/mask", self._on_mask, qos_profile_sensor_data)
            sub(CameraInfo, "camera/color/camera_info", self._on_info, qos_profile_sensor_data)
            sub(TransformStamped, "camera/color/extrinsics", self._on_extrinsics, latched)
        # Latched (push_ros.qos.GOAL_QOS): a planner_node restarted mid-episode gets the goal.
        self._pub_goal = node.create_publisher(PoseStamped, "goal_pose", GOAL_QOS)
        # Fault scenarios (pushbot.runner.faults): a second, volatile goal sender (another
        # client, like RViz) and the bridge's knock topic.
        self._pub_other_goal = node.create_publisher(
            PoseStamped, "goal_pose", reliable, event_callbacks=PublisherEventCallbacks(
                incompatible_qos=lambda event: None))  # planner_node's latched goal reader
        self._pub_knock = node.create_publisher(PoseStamped, "sim/knock", reliable)
        self._pub_push = node.create_publisher(PathMsg, "planner/push", reliable)
        from rcl_interfaces.srv import SetParameters
        from std_srvs.srv import Trigger

        self._reset = {n: node.create_client(Trigger, f"/{n}/reset") for n in NODES}
        if self.robot == "arm":  # the executor has ~/cancel and ~/enable, no ~/reset
            sub(DiagnosticStatus, "executor/status", self._on_executor_status, latched)
            sub(PathMsg, "sim/tool_tip", self._on_tool_tip, reliable)
            sub(PathMsg, "executor/path", self._on_executor_path, latched)
            sub(DiagnosticStatus, "pusher/refused", self._on_refused, reliable)
            from sensor_msgs.msg import JointState
            from std_srvs.srv import SetBool

            sub(JointState, "/joint_states", self._on_joint_state, reliable)
            from trajectory_msgs.msg import JointTrajectory

            self._pub_trajectory = node.create_publisher(  # a foreign commander (faults)
                JointTrajectory, ARM_TRAJECTORY_TOPIC, reliable)
            self._executor_enable = node.create_client(SetBool, f"/{EXECUTOR_NODE}/enable")
            self._executor_cancel = node.create_client(Trigger, f"/{EXECUTOR_NODE}/cancel")
        self._set_params = {n: node.create_client(SetParameters, f"/{n}/set_parameters")
                            for n in ("sim_bridge_node", "ekf_node", "planner_node")}

    def close(self) -> None:
        """Destroy the node and shut its context down (idempotent)."""
        try:
            if self._executor is not None:
                self._executor.shutdown(timeout_sec=1.0)
            if self._node is not None:
                self._node.destroy_node()
            if self._context is not None:
                import rclpy

                rclpy.try_shutdown(context=self._context)
        finally:
            self._executor = self._node = self._context = None

    # ---- callbacks ---------------------------------------------------------------------------
    def _on_true(self, msg: Any) -> None:
        from push_ros.poses import xytheta_from_pose
        from push_ros.stamps import seconds_from_stamp

        self.rec.true.append((seconds_from_stamp(msg.header.stamp), xytheta_from_pose(msg)))

    def _on_est(self, msg: Any) -> None:
        from push_ros.poses import xytheta_from_pose
        from push_ros.stamps import seconds_from_stamp

        self.rec.est.append((seconds_from_stamp(msg.header.stamp),
                             xytheta_from_pose(msg.pose.pose)))

    def _on_com(self, msg: Any) -> None:
        from push_ros.stamps import seconds_from_stamp

        self.rec.com.append((seconds_from_stamp(msg.header.stamp),
                             np.array([msg.point.x, msg.point.y])))

    def _on_push(self, msg: Any) -> None:
        from push_ros.paths import points_from_path
        from push_ros.stamps import seconds_from_stamp

        self.rec.pushes.append((time.monotonic(), np.asarray(points_from_path(msg))[:, :2]))
        self.rec.push_stamps.append(seconds_from_stamp(msg.header.stamp))

    def _on_clock(self, msg: Any) -> None:
        from push_ros.stamps import seconds_from_stamp

        self.rec.clock = max(self.rec.clock, seconds_from_stamp(msg.clock))

    def _on_executed(self, msg: Any) -> None:
        from push_ros.stamps import seconds_from_stamp

        stamps = [seconds_from_stamp(p.header.stamp) for p in msg.poses]
        if stamps:
            self.rec.executed.append((time.monotonic(), stamps[0], stamps[-1]))

    def _on_status(self, msg: Any) -> None:
        values = {kv.key: kv.value for kv in msg.values}
        values["_message"] = msg.message
        values["_wall"] = f"{time.monotonic():.6f}"  # when it arrived here
        self.rec.status.append(values)

    def _on_tool_tip(self, msg: Any) -> None:
        from push_ros.stamps import seconds_from_stamp

        stamps = np.array([seconds_from_stamp(p.header.stamp) for p in msg.poses])
        points = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z]
                           for p in msg.poses], dtype=float).reshape(-1, 3)
        self.rec.tool_tip.append((seconds_from_stamp(msg.header.stamp), stamps, points))

    def _on_executor_path(self, msg: Any) -> None:
        self.rec.executor_paths += 1

    def _on_refused(self, msg: Any) -> None:
        self.rec.refusals.append({kv.key: kv.value for kv in msg.values[:16]}
                                 | {"who": msg.name, "reason": msg.message})

    def _on_joint_state(self, msg: Any) -> None:
        from push_ros.stamps import seconds_from_stamp

        self.rec.joint_states.append((seconds_from_stamp(msg.header.stamp),
                                      np.asarray(msg.position, dtype=float),
                                      np.asarray(msg.velocity, dtype=float)))

    def _on_executor_status(self, msg: Any) -> None:
        self.rec.executor_status.append({kv.key: kv.value for kv in msg.values}
                                        | {"_message": msg.message})

    def _on_diagnostics(self, msg: Any) -> None:
        for status in msg.status:
            self.rec.diagnostics[status.name] = {kv.key: kv.value for kv in status.values}

    def _on_rgb(self, msg: Any) -> None:
        from push_ros.images import image_to_array
        from push_ros.stamps import seconds_from_stamp

        stamp = seconds_from_stamp(msg.header.stamp)
        if stamp not in self.rec.frames:
            self.rec.frames[stamp] = image_to_array(msg).copy()

    def _on_mask(self, msg: Any) -> None:
        from push_ros.images import image_to_array
        from push_ros.stamps import seconds_from_stamp

        stamp = seconds_from_stamp(msg.header.stamp)
        if stamp not in self.rec.masks:
            self.rec.masks[stamp] = image_to_array(msg) > 0

    def _on_info(self, msg: Any) -> None:
        from push_ros.images import camera_matrix_from_info

        self.rec.camera_matrix = camera_matrix_from_info(msg)

    def _on_extrinsics(self, msg: Any) -> None:
        from push_ros.poses import matrix_from_transform

        self.rec.t_world_camera = matrix_from_transform(msg)

    def _on_outline(self, msg: Any) -> None:
        from push_ros.outline import outline_from_cloud
        from push_ros.stamps import seconds_from_stamp

        self.rec.outline_stamps.append(seconds_from_stamp(msg.header.stamp))
        if self.record_frames:
            self.rec.outline = outline_from_cloud(msg)[0]

    # ---- waiting -----------------------------------------------------------------------------
    def wait(self, predicate: Callable[[], Any], timeout: float, what: str) -> Any:
        """Spin until ``predicate()`` returns something other than None or False;
        :class:`GraphError` after ``timeout`` s or as soon as a node process exits."""
        deadline = time.monotonic() + timeout
        while True:
            value = predicate()
            if value is not None and value is not False:
                return value
            self.check_alive()
            if time.monotonic() > deadline:
                raise GraphError(f"timed out after {timeout:.0f} s waiting for {what}; node "
                                 f"logs in {self.log_dir}")
            self._executor.spin_once(timeout_sec=0.05)

    def wait_ready(self) -> None:
        """Wait until every endpoint of the pipeline is discovered."""
        node = self._node
        links = {  # topic -> node names that must subscribe to it
            "camera/color/image_raw": ["segmentation_node"],
            "perception/object_pose": ["ekf_node"],
            "perception/outline": ["ekf_node", "planner_node"],
            "pusher/executed": ["ekf_node", "planner_node"],
            "estimator/object_pose": ["planner_node"],
            "estimator/state": ["planner_node"],
            "planner/push": [EXECUTOR_NODE if self.robot == "arm" else "sim_bridge_node"],
            "goal_pose": ["planner_node"],
        }
        if self.robot == "arm":
            links[ARM_TRAJECTORY_TOPIC] = ["sim_bridge_node"]
            links["/joint_states"] = [EXECUTOR_NODE]

        def missing() -> list[str]:
            out = [f"/{n}/reset" for n, c in self._reset.items() if not c.service_is_ready()]
            out += [f"/{n}/set_parameters" for n, c in self._set_params.items()
                    if not c.service_is_ready()]
            for topic, subscribers in links.items():
                have = {i.node_name for i in node.get_subscriptions_info_by_topic(topic)}
                out += [f"{s} on {topic}" for s in subscribers if s not in have]
            if self._pub_goal.get_subscription_count() == 0:
                out.append("goal_pose matched")
            for topic in ("sim/object_pose", "estimator/object_pose", "planner/status"):
                if node.count_publishers(topic) == 0:
                    out.append(f"publisher of {topic}")
            return out

        self.wait(lambda: not missing(), STARTUP_TIMEOUT,
                  f"the {len(self.names)} nodes to start and discover each other (still missing: "
                  f"{', '.join(missing()) or 'nothing'})")

    def planner_estimates(self) -> int:
        """Estimates planner_node has counted (its status)."""
        return max((int(s.get("estimates", 0)) for s in self.rec.status), default=0)

    # ---- service calls -----------------------------------------------------------------------
    def _call(self, client: Any, request: Any, what: str) -> Any:
        """Call an idempotent service (a reset, set_parameters), sending the request again
        after ``RESEND_AFTER`` s without an answer
        (:func:`pushbot.ros2cli.discovery.call_until_answered` says why)."""
        from pushbot.ros2cli.discovery import RESEND_AFTER

        deadline = time.monotonic() + SERVICE_TIMEOUT
        while True:
            future = client.call_async(request)
            left = deadline - time.monotonic()
            try:
                self.wait(future.done, min(RESEND_AFTER, max(left, 0.0)),
                          f"the response of {what}")
                break
            except GraphError:
                self.check_alive()  # a node that exited is reported at once
                client.remove_pending_request(future)
                if left <= RESEND_AFTER:
                    raise
        if future.exception() is not None:
            raise GraphError(f"{what} failed: {future.exception()}")
        return future.result()

    def reset(self, node_name: str) -> str:
        from std_srvs.srv import Trigger

        response = self._call(self._reset[node_name], Trigger.Request(), f"/{node_name}/reset")
        if not response.success:
            raise GraphError(f"/{node_name}/reset refused: {response.message}")
        return response.message

    def set_parameters(self, node_name: str, values: dict[str, Any]) -> None:
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        params = []
        for name, value in values.items():
            if isinstance(value, list | tuple):
                param = Parameter(name, Parameter.Type.DOUBLE_ARRAY, [float(v) for v in value])
            else:
                param = Parameter(name, value=value)
            params.append(param.to_parameter_msg())
        response = self._call(self._set_params[node_name],
                              SetParameters.Request(parameters=params),
                              f"/{node_name}/set_parameters")
        for name, result in zip(values, response.results, strict=True):
            if not result.successful:
                raise GraphError(f"{node_name} refused parameter {name!r} = {values[name]!r}: "
                                 f"{result.reason}")

    def executor_enable(self, enable: bool) -> str:
        """``/push_executor_node/enable`` (``robot`` arm); returns its message."""
        from std_srvs.srv import SetBool

        response = self._call(self._executor_enable, SetBool.Request(data=bool(enable)),
                              f"/{EXECUTOR_NODE}/enable")
        if not response.success:
            raise GraphError(f"/{EXECUTOR_NODE}/enable refused: {response.message}")
        return response.message

    def executor_cancel(self) -> str:
        """``/push_executor_node/cancel`` (``robot`` arm); returns its message."""
        from std_srvs.srv import Trigger

        response = self._call(self._executor_cancel, Trigger.Request(),
                              f"/{EXECUTOR_NODE}/cancel")
        if not response.success:
            raise GraphError(f"/{EXECUTOR_NODE}/cancel refused: {response.message}")
        return response.message

    def publish_goal(self, goal: np.ndarray, other: bool = False) -> str:
        """Send ``goal`` (x, y, theta) on ``goal_pose`` (``other``: from the second, volatile
        sender); returns the text planner_node's status shows for it."""
        from push_ros.poses import pose_stamped_msg
        from push_ros.stamps import stamp_from_seconds

        msg = pose_stamped_msg(np.asarray(goal, dtype=float), stamp_from_seconds(0.0))
        (self._pub_other_goal if other else self._pub_goal).publish(msg)
        from push_core.geometry import wrap_angle

        # planner_node reports the goal it works on in its status, 4 decimals (theta wrapped).
        return " ".join(f"{v:.4f}" for v in (goal[0], goal[1], float(wrap_angle(goal[2]))))

    def publish_knock(self, delta: np.ndarray) -> None:
        """Displace the object by ``delta`` (dx, dy m, dyaw rad) on ``sim/knock``."""
        from push_ros.poses import pose_stamped_msg
        from push_ros.stamps import stamp_from_seconds

        self._pub_knock.publish(pose_stamped_msg(np.asarray(delta, dtype=float),
                                                 stamp_from_seconds(0.0)))

    def publish_trajectory(self, names: list[str], positions: list[float], seconds: float
                           ) -> None:
        """Send a one-point ``JointTrajectory`` to ``positions`` in ``seconds`` on the arm's
        controller topic, as another node commanding the arm would (``robot`` arm)."""
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        from push_ros.stamps import duration_from_seconds, stamp_from_seconds

        point = JointTrajectoryPoint(positions=[float(v) for v in positions],
                                     velocities=[0.0] * len(positions),
                                     time_from_start=duration_from_seconds(seconds))
        msg = JointTrajectory(joint_names=list(names), points=[point])
        msg.header.stamp = stamp_from_seconds(0.0)  # start now
        self._pub_trajectory.publish(msg)

    def publish_push(self, points: np.ndarray) -> None:
        """Send a push (approach, contact, end: (3, 2) m in ``world``) on ``planner/push``, as
        another client would (``push_ros.paths.push_path``, 0.02 m/s)."""
        from push_ros.paths import push_path

        a, c, e = (np.asarray(p, dtype=float) for p in points)
        self._pub_push.publish(push_path(a, c, e, stamp_seconds=0.0, speed=0.02))

    def matched(self) -> bool:
        """Whether the fault publishers (second goal sender, knock, push) have subscribers."""
        return all(p.get_subscription_count() > 0
                   for p in (self._pub_other_goal, self._pub_knock, self._pub_push))
