"""push_executor_node in-process against a stand-in controller (real messages over DDS).

The stand-in behaves like the simulator's arm: it owns ``/clock`` (the executor runs on sim
time), publishes ``/joint_states`` every tick (extra finger joints included, names in another
order than the controller's), and advances its time **only while executing a trajectory**
(5x faster than the wall clock); while idle it keeps publishing the same stamp. It executes a
received trajectory by linear interpolation between its points, from its state at receipt to
the first point; a new trajectory replaces the running one.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros]

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from nav_msgs.msg import Path  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402

from push_executor.motion_types import PANDA_PARK  # noqa: E402
from push_executor.push_executor_node import JOINT_STATE_QOS, PushExecutorNode  # noqa: E402
from push_ros.paths import executed_push_from_path, push_path  # noqa: E402
from push_ros.qos import CLOCK_QOS, LATCHED_QOS, RELIABLE_QOS  # noqa: E402
from push_ros.refusal import read_refusal, stamp_key  # noqa: E402
from push_ros.stamps import seconds_from_stamp, stamp_from_seconds  # noqa: E402

from .test_kinematics import panda_urdf  # noqa: E402

TOPIC = "/joint_trajectory_controller/joint_trajectory"
ARM = [f"panda_joint{i}" for i in range(1, 8)]
#: Published order: fingers first, arm joints reversed (the executor maps by name).
PUBLISHED = ["panda_finger_joint1", *ARM[::-1], "panda_finger_joint2"]
SPEEDUP = 5.0
TICK = 0.01  # s of wall time per stand-in tick
PUSH = ((-0.055, 0.02), (-0.05, 0.02), (0.0, 0.02))


class StandInController(Node):
    """The stand-in arm (module docstring)."""

    def __init__(self, context: Any) -> None:
        super().__init__("stand_in_controller", context=context)
        self.q = np.array(PANDA_PARK, dtype=float)
        self.t = 100.0  # sim time, s
        self.received: list[JointTrajectory] = []
        self.received_at: list[float] = []  # wall time of each
        #: Every arm posture published on /joint_states (chain order).
        self.published: list[np.ndarray] = []
        self.traj: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None
        self.publishing = True
        self.executing = True  # False: receives trajectories but never moves
        self.create_subscription(JointTrajectory, TOPIC, self._on_traj, RELIABLE_QOS)
        self.clock = self.create_publisher(Clock, "/clock", CLOCK_QOS)
        self.states = self.create_publisher(JointState, "/joint_states", JOINT_STATE_QOS)
        self.description = self.create_publisher(String, "/robot_description", LATCHED_QOS)
        self.description.publish(String(data=panda_urdf()))
        self.create_timer(TICK, self._tick)

    def _on_traj(self, msg: JointTrajectory) -> None:
        self.received.append(msg)
        self.received_at.append(time.monotonic())
        order = [msg.joint_names.index(j) for j in ARM]
        times = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
                          for p in msg.points])
        qs = np.array([np.array(p.positions)[order] for p in msg.points])
        if self.executing:  # a non-zero stamp is the start (held until then), as JTC does
            start = seconds_from_stamp(msg.header.stamp) or self.t
            self.traj = (start, np.concatenate([[0.0], times]),
                         np.vstack([self.q, qs]), self.q.copy())

    def _tick(self) -> None:
        if self.traj is not None:
            self.t += TICK * SPEEDUP
            start, times, qs, _ = self.traj
            elapsed = self.t - start
            self.q = np.array([np.interp(elapsed, times, qs[:, j]) for j in range(7)])
            if elapsed >= times[-1]:
                self.traj = None
        self.clock.publish(Clock(clock=stamp_from_seconds(self.t)))
        if self.publishing:
            msg = JointState(name=PUBLISHED)
            msg.header.stamp = stamp_from_seconds(self.t)
            by_name = dict(zip(ARM, self.q, strict=True))
            msg.position = [0.02 if "finger" in n else float(by_name[n]) for n in PUBLISHED]
            self.states.publish(msg)
            self.published.append(self.q.copy())


class Graph:
    """The executor, the stand-in and a client node that records the executor's outputs."""

    def __init__(self, context: Any, enabled: bool = True, **overrides: Any) -> None:
        params = [Parameter("use_sim_time", value=True),
                  Parameter("start_enabled", value=enabled)]
        params += [Parameter(k.replace("__", "."), value=v) for k, v in overrides.items()]
        self.executor_node = PushExecutorNode(context=context, parameter_overrides=params)
        self.arm = StandInController(context)
        self.client = Node("executor_test_client", context=context)
        self.executed: list[Path] = []
        self.refused: list[DiagnosticStatus] = []
        self.paths: list[Path] = []
        self.status: list[DiagnosticStatus] = []
        c = self.client
        c.create_subscription(Path, "pusher/executed", self.executed.append, RELIABLE_QOS)
        c.create_subscription(DiagnosticStatus, "pusher/refused", self.refused.append,
                              RELIABLE_QOS)
        c.create_subscription(Path, "executor/path", self.paths.append, LATCHED_QOS)
        c.create_subscription(DiagnosticStatus, "executor/status", self.status.append,
                              LATCHED_QOS)
        self.push_pub = c.create_publisher(Path, "planner/push", RELIABLE_QOS)
        self.cancel = c.create_client(Trigger, "/push_executor_node/cancel")
        self.enable = c.create_client(SetBool, "/push_executor_node/enable")
        self.executor = SingleThreadedExecutor(context=context)
        for node in (self.executor_node, self.arm, self.client):
            self.executor.add_node(node)

    def spin_until(self, predicate: Callable[[], Any], timeout: float = 20.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return bool(predicate())

    def value(self, key: str) -> str:
        """``key`` of the newest executor/status ("" before any)."""
        if not self.status:
            return ""
        return {kv.key: kv.value for kv in self.status[-1].values}.get(key, "")

    def state(self) -> str:
        return self.value("state")

    def states(self) -> list[str]:
        """Every executor/status state received, in order."""
        return [{kv.key: kv.value for kv in s.values}.get("state", "") for s in self.status]

    def ready(self) -> bool:
        node = self.executor_node
        return (node._arm is not None and node.measured.q is not None
                and self.push_pub.get_subscription_count() > 0
                and node._pub_traj.get_subscription_count() > 0)

    def send_push(self, stamp: float = 7.25, points: tuple = PUSH) -> Time:
        msg = push_path(*points, stamp_seconds=stamp, speed=0.02)
        self.push_pub.publish(msg)
        self.sent = time.monotonic()
        return msg.header.stamp

    @property
    def sent_to_received(self) -> float | None:
        """Wall seconds from the last push sent to the first trajectory the stand-in got."""
        got = self.arm.received_at
        return None if not got else got[0] - self.sent

    def call(self, client: Any, request: Any) -> Any:
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(request)
        assert self.spin_until(future.done, 10.0)
        return future.result()

    def close(self) -> None:
        self.executor.shutdown()
        for node in (self.executor_node, self.arm, self.client):
            node.destroy_node()


@pytest.fixture
def graph(ros_context: Any) -> Iterator[Graph]:
    g = Graph(ros_context)
    try:
        assert g.spin_until(g.ready), "executor, stand-in and client did not connect"
        yield g
    finally:
        g.close()


def test_a_push_is_executed(graph: Graph) -> None:
    stamp = graph.send_push()
    assert graph.spin_until(lambda: graph.executed or graph.refused, 60.0)
    assert not graph.refused, read_refusal(graph.refused[0])
    traj = graph.arm.received[0]
    # Stamped with the controller's time (the newest joint state's stamp carried forward by
    # the wall time the node took to plan: the stand-in's idle clock stands still, so at most
    # that much later) + start_delay: it starts then, whatever the delivery latency.
    assert len(graph.arm.received) == 1
    start = seconds_from_stamp(traj.header.stamp)
    delay = graph.executor_node.params.values["start_delay"]
    assert 100.0 + delay <= start <= 100.0 + delay + (graph.sent_to_received or 0.0)
    assert traj.joint_names == ARM
    times = [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in traj.points]
    assert times[0] > 0 and np.all(np.diff(times) > 0)
    np.testing.assert_allclose(traj.points[0].positions, PANDA_PARK, atol=1e-9)
    assert all(len(p.velocities) == 7 for p in traj.points)
    assert traj.points[-1].velocities.tolist() == [0.0] * 7
    # pusher/executed: contact start and end from the measured joints, their stamps.
    done = executed_push_from_path(graph.executed[0])
    assert len(graph.executed[0].poses) == 2
    assert all(p.pose.position.z == 0.0 for p in graph.executed[0].poses)
    np.testing.assert_allclose(done.start, PUSH[1], atol=1.5e-3)  # stand-in's sampling
    np.testing.assert_allclose(done.end, PUSH[2], atol=1e-3)
    assert 100.0 < done.t_start < done.t_end
    assert done.t_end - done.t_start == pytest.approx(2.55, abs=0.1)
    assert graph.spin_until(lambda: graph.state() == "idle")
    values = {kv.key: kv.value for kv in graph.status[-1].values}
    assert values["executed"] == "1" and float(values["contact_line_error_mm"]) < 1.0
    assert graph.paths and len(graph.paths[-1].poses) == len(traj.points)
    del stamp


def test_a_refused_push_answers_with_its_stamp(graph: Graph) -> None:
    stamp = graph.send_push(12.5, ((0.20, 0.0), (0.21, 0.0), (0.26, 0.0)))
    assert graph.spin_until(lambda: graph.refused)
    refusal = read_refusal(graph.refused[0])
    assert refusal.push_stamp == stamp_key(stamp) == "12.500000000"
    assert (refusal.kind, refusal.stage) == ("workspace", "input")
    assert refusal.who == "/push_executor_node"
    assert not graph.arm.received


def test_dry_run_plans_and_moves_nothing(graph: Graph) -> None:
    assert graph.call(graph.enable, SetBool.Request(data=False)).success
    assert graph.spin_until(lambda: graph.state() == "disabled")
    graph.send_push()
    assert graph.spin_until(lambda: graph.refused and graph.paths)
    assert read_refusal(graph.refused[0]).kind == "disabled"
    path = graph.paths[-1]
    assert path.header.frame_id == "world" and len(path.poses) > 100
    z = [p.pose.position.z for p in path.poses]
    assert min(z) == pytest.approx(0.01, abs=1e-6)
    graph.spin_until(lambda: False, 0.5)
    assert not graph.arm.received and not graph.executed


def test_busy_and_cancel(graph: Graph) -> None:
    first = graph.send_push(1.0)
    assert graph.spin_until(lambda: graph.state() == "moving")
    graph.send_push(2.0)
    assert graph.spin_until(lambda: graph.refused)
    assert read_refusal(graph.refused[0]).kind == "busy"
    # cancelled on the way (the trajectory starts start_delay after it was sent)
    assert graph.spin_until(lambda: np.max(np.abs(graph.arm.q - PANDA_PARK)) > 0.05)
    q_before = graph.executor_node.measured.q.copy()
    response = graph.call(graph.cancel, Trigger.Request())
    assert response.success, response.message
    assert graph.spin_until(lambda: len(graph.arm.received) == 2)
    hold = graph.arm.received[1]
    assert len(hold.points) == 1 and hold.points[0].velocities.tolist() == [0.0] * 7
    # The hold decelerates from the commanded state (the arm tracks its plan) to rest at the
    # joints' acceleration limits over stop_s (>= the shortest hold, 0.05 s): ahead of the
    # posture the executor measured before the call along the motion, never back to it.
    assert graph.spin_until(lambda: graph.value("stop_s") != "")
    seconds = float(graph.value("stop_s"))
    assert 0.05 <= seconds <= 1.0
    assert hold.points[0].time_from_start.sec + hold.points[0].time_from_start.nanosec * 1e-9 \
        == pytest.approx(seconds, abs=1e-3)
    order = [hold.joint_names.index(j) for j in ARM]
    held = np.asarray(hold.points[0].positions)[order]
    step, motion = held - q_before, q_before - PANDA_PARK
    assert float(step @ motion) >= 0.0 and float(np.max(np.abs(step))) <= 0.2, step
    assert graph.spin_until(lambda: len(graph.refused) == 2)
    cancelled = read_refusal(graph.refused[1])
    assert cancelled.kind == "cancelled" and cancelled.push_stamp == stamp_key(first)
    assert graph.spin_until(lambda: "stopped" in graph.states())
    # Once the arm is held it parks (the planner's next frame must not show it over the
    # object): a third trajectory from the held posture to the park posture.
    assert graph.spin_until(lambda: len(graph.arm.received) == 3, 30.0)
    park = graph.arm.received[2]
    np.testing.assert_allclose(park.points[0].positions, hold.points[0].positions, atol=1e-9)
    order = [park.joint_names.index(j) for j in ARM]
    np.testing.assert_allclose(np.asarray(park.points[-1].positions)[order], PANDA_PARK,
                               atol=1e-9)
    assert graph.spin_until(lambda: graph.state() == "idle" and graph.value("at_park") == "true",
                            60.0)
    assert not graph.executed


def test_stale_joint_states_stop_the_arm(graph: Graph) -> None:
    graph.send_push(3.0)
    assert graph.spin_until(lambda: graph.state() == "moving")
    graph.spin_until(lambda: False, 0.3)
    graph.arm.publishing = False
    assert graph.spin_until(lambda: len(graph.arm.received) == 2, 10.0)
    assert len(graph.arm.received[1].points) == 1
    assert graph.spin_until(lambda: graph.refused)
    refusal = read_refusal(graph.refused[0])
    assert refusal.kind == "fault" and "stale" in refusal.reason
    assert graph.spin_until(lambda: graph.state() == "stopped")


def test_motion_that_does_not_start_stops(ros_context: Any) -> None:
    g = Graph(ros_context, start_timeout=0.5)
    try:
        g.arm.executing = False
        assert g.spin_until(g.ready)
        g.send_push(4.0)
        assert g.spin_until(lambda: g.refused, 10.0)
        assert "no_start" in read_refusal(g.refused[0]).reason
        assert g.spin_until(lambda: len(g.arm.received) == 2)
        assert len(g.arm.received[1].points) == 1
    finally:
        g.close()


def test_no_state_and_no_model(ros_context: Any) -> None:
    g = Graph(ros_context)
    try:
        g.arm.publishing = False
        assert g.spin_until(lambda: g.executor_node._arm is not None
                            and g.push_pub.get_subscription_count() > 0)
        g.send_push(5.0)
        assert g.spin_until(lambda: g.refused)
        assert read_refusal(g.refused[0]).kind == "no_state"
    finally:
        g.close()


def test_stamps_of_the_executed_push_are_the_joint_states(graph: Graph) -> None:
    graph.send_push(6.0)
    assert graph.spin_until(lambda: graph.executed, 60.0)
    poses = graph.executed[0].poses
    # Every stamp the stand-in publishes is a multiple of TICK * SPEEDUP after 100 s.
    for pose in poses:
        t = seconds_from_stamp(pose.header.stamp)
        assert math.isclose((t - 100.0) / (TICK * SPEEDUP), round((t - 100.0) / (TICK * SPEEDUP)),
                            abs_tol=1e-6)
