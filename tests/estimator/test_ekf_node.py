"""ekf_node: in-process tests over real DDS messages, plus one test of the node process.

Each test starts the node and a tester node in the session's isolated domain (conftest), waits
for matched endpoints, publishes outline / observations / executed pushes and checks what comes
out on the estimator topics and /diagnostics.
"""

from __future__ import annotations

import math
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path as FilePath
from typing import Any

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Path
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from push_core.estimator import EKFConfig, PushEKF, predict_push
from push_estimator.ekf_node import EkfNode
from push_ros.outline import outline_cloud_msg
from push_ros.poses import pose_with_covariance_msg, yaw_from_quaternion
from push_ros.qos import LATCHED_QOS as LATCHED
from push_ros.qos import RELIABLE_QOS as RELIABLE
from push_ros.stamps import stamp_from_seconds
from push_ros.state import state_from_array_msg
from push_ros.tf import TFMessage

HALF = 0.03
#: A 6 cm square, 10 points per side, counter-clockwise, with outward normals.
_CORNERS = np.array([[HALF, -HALF], [HALF, HALF], [-HALF, HALF], [-HALF, -HALF]])
SQUARE = np.concatenate([a + np.arange(10)[:, None] / 10 * (b - a)
                         for a, b in zip(_CORNERS, np.roll(_CORNERS, -1, 0), strict=True)])
SQUARE_NORMALS = np.repeat([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]], 10, axis=0)
TIMEOUT = 10.0
CONFIG = FilePath(__file__).resolve().parents[2] / "src/pushbot_bringup/config/push_estimator.yaml"

pytestmark = pytest.mark.ros


class EkfHarness:
    """Publishes the estimator's inputs and records its outputs."""

    def __init__(self, context: Any, wait_for: Callable[..., bool]) -> None:
        self.node = Node("ekf_tester", context=context)
        self.ekf = EkfNode(context=context,
                           parameter_overrides=[Parameter("use_sim_time", value=False)])
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.ekf)
        self._wait_for = wait_for
        n = self.node
        self.pub_outline = n.create_publisher(PointCloud2, "perception/outline", LATCHED)
        self.pub_obs = n.create_publisher(PoseWithCovarianceStamped, "perception/object_pose",
                                          RELIABLE)
        self.pub_push = n.create_publisher(Path, "pusher/executed", RELIABLE)
        self.poses: list[PoseWithCovarianceStamped] = []
        self.coms: list[PointStamped] = []
        self.states: list[Float64MultiArray] = []
        self.status: DiagnosticStatus | None = None
        n.create_subscription(PoseWithCovarianceStamped, "estimator/object_pose",
                              self.poses.append, RELIABLE)
        n.create_subscription(PointStamped, "estimator/center_of_mass", self.coms.append,
                              RELIABLE)
        n.create_subscription(Float64MultiArray, "estimator/state", self.states.append,
                              RELIABLE)
        n.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, RELIABLE)
        self.reset_client = n.create_client(Trigger, "/ekf_node/reset")
        matched = [lambda: self.pub_obs.get_subscription_count() > 0,
                   lambda: self.pub_push.get_subscription_count() > 0,
                   lambda: self.pub_outline.get_subscription_count() > 0]
        for topic in ("/estimator/object_pose", "/estimator/center_of_mass", "/estimator/state",
                      "/diagnostics"):
            matched.append(lambda t=topic: n.count_publishers(t) > 0)
        assert self.wait(lambda: all(m() for m in matched)), "endpoints did not match"
        assert self.wait(lambda: self.status is not None)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if "ekf_node" in status.name:
                self.status = status

    def wait(self, predicate: Callable[[], Any], timeout: float = TIMEOUT) -> bool:
        return self._wait_for(predicate, timeout=timeout, executor=self.executor)

    def value(self, key: str) -> str:
        assert self.status is not None
        return {kv.key: kv.value for kv in self.status.values}[key]

    def count(self, key: str) -> int:
        return int(self.value(key)) if self.status is not None else -1

    def wait_count(self, key: str, expected: int) -> None:
        assert self.wait(lambda: self.count(key) == expected), (key, self.count(key),
                                                                self.status)

    def outline(self, points: np.ndarray = SQUARE, normals: np.ndarray = SQUARE_NORMALS,
                frame: str = "object") -> PointCloud2:
        msg = outline_cloud_msg(points, normals, stamp_from_seconds(0.0), frame)
        self.pub_outline.publish(msg)
        return msg

    def observe(self, pose: Any, stamp: float, frame: str = "world",
                covariance: np.ndarray | None = None) -> None:
        cov = np.zeros((3, 3)) if covariance is None else covariance
        finite = np.all(np.isfinite(pose))
        msg = pose_with_covariance_msg(pose if finite else (0.0, 0.0, 0.0), cov,
                                       stamp_from_seconds(stamp), frame)
        if not finite:  # the codec refuses to write NaN; another publisher might not
            msg.pose.pose.position.x, msg.pose.pose.position.y = (float(v) for v in pose[:2])
        self.pub_obs.publish(msg)

    def push(self, start: Any, end: Any, t_start: float, t_end: float,
             n_poses: int = 2) -> None:
        msg = Path()
        msg.header.frame_id = "world"
        msg.header.stamp = stamp_from_seconds(t_end)
        for point, t in list(zip((start, end), (t_start, t_end), strict=True))[:n_poses]:
            pose = PoseStamped()
            pose.header.frame_id = "world"
            pose.header.stamp = stamp_from_seconds(t)
            pose.pose.position.x, pose.pose.position.y = (float(v) for v in point)
            msg.poses.append(pose)
        self.pub_push.publish(msg)

    def initialised(self, pose: Any = (0.0, 0.0, 0.0), stamp: float = 1.0) -> None:
        """Outline and a first observation; wait for the first estimate."""
        self.outline()
        self.wait_count("outlines", 1)
        self.observe(pose, stamp)
        assert self.wait(lambda: self.poses and self.coms and self.states
                         and self.value("state") == "tracking")

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.ekf.destroy_node()
        self.node.destroy_node()


@pytest.fixture
def tester(ros_context: Any, wait_for: Callable[..., bool]) -> Iterator[EkfHarness]:
    t = EkfHarness(ros_context, wait_for)
    try:
        yield t
    finally:
        t.close()


def planar(msg: PoseWithCovarianceStamped) -> np.ndarray:
    p = msg.pose.pose
    return np.array([p.position.x, p.position.y, yaw_from_quaternion(p.orientation)])


# --------------------------------------------------------------------------------------------
def test_topics_types_qos_and_service(tester: EkfHarness) -> None:
    n = tester.node
    expected = {
        "/estimator/object_pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
        "/estimator/center_of_mass": "geometry_msgs/msg/PointStamped",
        "/estimator/state": "std_msgs/msg/Float64MultiArray",
        "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    }
    for topic, kind in expected.items():
        infos = [i for i in n.get_publishers_info_by_topic(topic) if i.node_name == "ekf_node"]
        assert [i.topic_type for i in infos] == [kind], topic
        assert infos[0].qos_profile.reliability == ReliabilityPolicy.RELIABLE
        # The estimates are latched (a late subscriber gets the last one); diagnostics not.
        latched = topic.startswith("/estimator/")
        assert infos[0].qos_profile.durability == (
            DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE), topic
    subs = {"/perception/outline": DurabilityPolicy.TRANSIENT_LOCAL,
            "/perception/object_pose": DurabilityPolicy.VOLATILE,
            "/pusher/executed": DurabilityPolicy.VOLATILE}
    for topic, durability in subs.items():
        infos = [i for i in n.get_subscriptions_info_by_topic(topic)
                 if i.node_name == "ekf_node"]
        assert len(infos) == 1 and infos[0].qos_profile.durability == durability, topic
        assert infos[0].qos_profile.reliability == ReliabilityPolicy.RELIABLE
    assert tester.reset_client.wait_for_service(timeout_sec=TIMEOUT)
    tf_publishers = [i for i in n.get_publishers_info_by_topic("/tf")
                     if i.node_name == "ekf_node"]
    assert bool(tf_publishers) == (TFMessage is not None)  # no tf2_msgs: no /tf
    assert tester.value("state") == "waiting for outline"


def test_first_observation_initialises_and_publishes_the_estimate(tester: EkfHarness) -> None:
    tester.initialised(pose=(0.05, -0.02, 0.4), stamp=1.5)
    assert tester.wait(lambda: tester.coms and tester.states)
    pose = tester.poses[-1]
    assert pose.header.frame_id == "world"
    assert (pose.header.stamp.sec, pose.header.stamp.nanosec) == (1, 500_000_000)
    np.testing.assert_allclose(planar(pose), [0.05, -0.02, 0.4], atol=1e-12)
    cov = np.asarray(pose.pose.covariance).reshape(6, 6)
    sigma = EKFConfig().position_sigma
    assert cov[0, 0] == pytest.approx(sigma**2) and cov[5, 5] > 0.0
    com = tester.coms[-1]
    assert com.header.frame_id == "object" and (com.point.x, com.point.y) == (0.0, 0.0)
    x, p = state_from_array_msg(tester.states[-1])
    np.testing.assert_allclose(x[:3], [0.05, -0.02, 0.4])
    assert x[6] == pytest.approx(0.3) and x[5] > 0.0
    np.testing.assert_array_equal(p, p.T)
    assert tester.wait(lambda: tester.value("state") == "tracking")
    assert tester.status.level == DiagnosticStatus.OK


def test_push_then_observation_fuses_the_pushing_model(tester: EkfHarness) -> None:
    tester.initialised()
    _, p0 = state_from_array_msg(tester.states[-1])
    # The pusher closes a 5 mm gap and pushes 2.5 cm along +x, 1 cm off the centre line.
    start = np.array([-HALF - 0.0048 - 0.005, 0.01])
    end = start + [0.03, 0.0]
    truth = np.array([0.0, 0.0, 0.0, 0.004, -0.006, 0.03, 0.3])
    reference = PushEKF(SQUARE, SQUARE_NORMALS)
    observed = predict_push(truth, reference.outline, start, end).state[:3]
    tester.push(start, end, 2.0, 3.25)
    tester.wait_count("pushes", 1)
    assert len(tester.poses) == 1  # predictions are not published, estimates are
    tester.observe(observed, 4.0)
    assert tester.wait(lambda: len(tester.poses) == 2 and len(tester.states) == 2)
    pose = tester.poses[-1]
    assert seconds_from(pose) == 4.0
    assert planar(pose)[0] > 0.015  # pushed forward
    np.testing.assert_allclose(planar(pose), observed, atol=3e-3)
    x, p = state_from_array_msg(tester.states[-1])
    assert np.trace(p[3:5, 3:5]) < np.trace(p0[3:5, 3:5])  # learned something about c
    assert np.linalg.eigvalsh(p).min() > 0.0
    tester.wait_count("observations", 2)


def seconds_from(msg: Any) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def test_bad_inputs_are_dropped_diagnosed_and_the_node_keeps_working(tester: EkfHarness) -> None:
    tester.observe((0.0, 0.0, 0.0), 0.5)  # before any outline
    tester.wait_count("refused_before_outline", 1)
    assert tester.status.level == DiagnosticStatus.WARN
    tester.outline(SQUARE[::-1], SQUARE_NORMALS[::-1])  # clockwise
    tester.wait_count("refused_outline", 1)
    tester.outline(frame="world")  # wrong frame
    tester.wait_count("refused_outline", 2)
    tester.outline()
    tester.wait_count("outlines", 1)
    assert tester.status.level == DiagnosticStatus.OK
    tester.push((-0.05, 0.0), (0.0, 0.0), 0.6, 0.7)  # before the first observation
    tester.wait_count("refused_before_init", 1)
    tester.observe((math.nan, 0.0, 0.0), 0.8)
    tester.wait_count("refused_nan", 1)
    tester.observe((0.0, 0.0, 0.0), 0.9, frame="map")
    tester.wait_count("refused_invalid", 1)
    assert not tester.poses

    tester.observe((0.0, 0.0, 0.0), 1.0)  # good: initialises
    assert tester.wait(lambda: len(tester.poses) == 1)
    tester.observe((0.0, 0.0, 0.0), 1.0)  # the same stamp again
    tester.wait_count("refused_duplicate", 1)
    tester.observe((0.0, 0.0, 0.0), 0.95)  # older than the last applied input
    tester.wait_count("refused_out_of_order", 1)
    tester.push((-0.05, 0.0), (0.0, 0.0), 2.0, 3.0, n_poses=1)
    tester.wait_count("refused_invalid", 2)
    tester.push((-0.05, math.inf), (0.0, 0.0), 2.0, 3.0)
    tester.wait_count("refused_nan", 2)
    tester.push((-0.05, 0.0), (0.0, 0.0), 0.9, 1.2)  # starts before the last observation
    tester.wait_count("refused_out_of_order", 2)
    assert tester.status.level == DiagnosticStatus.WARN
    assert "refused pusher/executed" in tester.value("last_problem")
    assert len(tester.poses) == 1

    start = np.array([-HALF - 0.0048 - 0.005, 0.0])
    tester.push(start, start + [0.02, 0.0], 2.0, 3.0)  # good
    tester.wait_count("pushes", 1)
    tester.observe((0.015, 0.0, 0.0), 4.0)
    assert tester.wait(lambda: len(tester.poses) == 2)
    tester.wait_count("observations", 2)
    assert tester.status.level == DiagnosticStatus.OK and tester.count("gated") == 0


def test_a_push_arriving_after_its_observation_is_re_filtered(tester: EkfHarness) -> None:
    tester.initialised()
    start = np.array([-HALF - 0.0048 - 0.005, 0.01])
    end = start + [0.03, 0.0]
    # The node's outline went through float32 (PointCloud2): the reference uses the same.
    reference = PushEKF(SQUARE.astype(np.float32), SQUARE_NORMALS.astype(np.float32))
    truth = np.array([0.0, 0.0, 0.0, 0.004, -0.006, 0.03, 0.3])
    observed = predict_push(truth, reference.outline, start, end).state[:3]
    tester.observe(observed, 4.0)  # overtakes its pusher/executed (DDS does not order topics)
    tester.wait_count("gated", 1)  # without the push the observation is a surprise
    tester.push(start, end, 2.0, 3.25)
    tester.wait_count("replayed", 1)
    assert tester.count("gated") == 0 and tester.count("pushes") == 1
    assert tester.wait(lambda: len(tester.states) == 3)
    assert seconds_from(tester.poses[-1]) == 4.0
    # The same as if the push had arrived first.
    reference.update_pose([0.0, 0.0, 0.0])
    reference.predict_push(start, end)
    reference.update_pose(observed)
    x, p = state_from_array_msg(tester.states[-1])
    np.testing.assert_allclose(x, reference.state, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(p, reference.covariance, rtol=1e-9, atol=1e-15)
    tester.push(start, end, 2.0, 3.25)  # the same push again
    tester.wait_count("refused_duplicate", 1)
    tester.push(start, end, 3.5, 4.5)  # overlaps the observation at 4.0: cannot be placed
    tester.wait_count("refused_out_of_order", 1)
    assert tester.count("pushes") == 1


def test_gating_reinitialises_the_pose_and_reports_it(tester: EkfHarness) -> None:
    tester.initialised()
    tester.observe((0.0005, 0.0, 0.0), 2.0)
    assert tester.wait(lambda: len(tester.states) == 2)
    params_before = state_from_array_msg(tester.states[-1])[0][3:]
    tester.observe((0.12, 0.05, 1.0), 3.0)  # knocked by hand
    assert tester.wait(lambda: len(tester.states) == 3)
    x, p = state_from_array_msg(tester.states[-1])
    # The square looks the same every 90 deg (symmetry detected from the outline): theta is
    # the observed orientation's equivalent closest to the prediction, 1.0 - pi/2.
    np.testing.assert_allclose(x[:3], [0.12, 0.05, 1.0 - math.pi / 2])
    np.testing.assert_allclose(x[3:], params_before)
    np.testing.assert_array_equal(p[:3, 3:], 0.0)
    tester.wait_count("gated", 1)
    assert tester.status.level == DiagnosticStatus.WARN
    assert "gate" in tester.status.message


def test_reset_service_starts_a_new_episode(tester: EkfHarness) -> None:
    tester.initialised()
    assert tester.reset_client.wait_for_service(timeout_sec=TIMEOUT)
    future = tester.reset_client.call_async(Trigger.Request())
    assert tester.wait(future.done)
    assert future.result().success
    assert "first observation" in future.result().message
    assert tester.wait(lambda: tester.value("state") == "waiting for first observation")
    tester.observe((0.0, 0.0, 0.0), 1.0)  # the previous episode's frame, repeated: dropped
    tester.wait_count("refused_duplicate", 1)
    assert len(tester.poses) == 1 and tester.value("state") == "waiting for first observation"
    tester.observe((0.3, 0.1, 1.0), 0.9)  # taken before the reset (in flight): dropped too
    tester.wait_count("refused_duplicate", 2)
    assert len(tester.poses) == 1
    tester.observe((0.2, -0.1, -2.0), 1.5)  # the camera's next frame, far away: a new episode
    assert tester.wait(lambda: len(tester.poses) == 2)
    np.testing.assert_allclose(planar(tester.poses[-1]), [0.2, -0.1, -2.0], atol=1e-12)
    tester.wait_count("observations", 2)
    assert tester.count("gated") == 0 and tester.count("resets") == 1


def test_a_different_outline_starts_a_new_episode(tester: EkfHarness) -> None:
    tester.initialised()
    tester.outline()  # the same outline again (latched re-publication): ignored
    tester.outline(1.5 * SQUARE)
    tester.wait_count("outlines", 2)
    assert tester.value("state") == "waiting for first observation"


@pytest.mark.parametrize(("name", "value"), [
    ("substep", -0.01),  # outside the declared range
    ("initial.m", 2.0),  # outside limits.m_min .. limits.m_max
    ("limits.m_min", 1.5),
    ("iterations", 0),
])
def test_invalid_parameters_fail_at_construction(ros_context: Any, name: str,
                                                 value: Any) -> None:
    from rclpy.exceptions import ParameterException

    with pytest.raises((ValueError, ParameterException), match=name.split(".")[-1]):
        EkfNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])


@pytest.mark.graph
def test_node_process_exits_2_on_a_bad_parameter_and_runs_with_the_yaml(
        processes: Any, tester: EkfHarness) -> None:
    bad = processes.node("ekf_node", "--ros-args", "-r", "__node:=ekf_bad", "-p",
                         "limits.m_max:=0.01")
    assert bad.wait(timeout=60) == 2
    assert "invalid configuration" in processes.output(bad)
    good = processes.node("ekf_node", "--ros-args", "-r", "__node:=ekf_process",
                          "--params-file", str(CONFIG),
                          "-p", "ekf_process.use_sim_time:=false")
    seen: list[str] = []
    tester.node.create_subscription(
        DiagnosticArray, "/diagnostics",
        lambda m: seen.extend(s.name for s in m.status if "ekf_process" in s.name), RELIABLE)
    assert tester.wait(lambda: seen or good.poll() is not None, timeout=60), \
        processes.output(good)
    assert good.poll() is None, processes.output(good)
    assert processes.stop(good) in (0, -2, 130)
    assert isinstance(good, subprocess.Popen)
