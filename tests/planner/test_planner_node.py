"""In-process tests of planner_node: publish an outline, estimates and goals, watch the plans.

The node and a client node share one rclpy context and a single-threaded executor; every wait
is bounded and event-driven (matched endpoints, received messages, status counters). "No second
plan" is asserted after the node has *reported* handling the message (its status counters),
then once more after a bounded extra spin.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path as FilePath
from typing import Any

import numpy as np
import pytest
import yaml
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Path
from rclpy.exceptions import ParameterException
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from push_core.geometry import closest_point_on_polyline
from push_core.objects import load_object
from push_core.planner import AVOID_RADIUS
from push_planner.models import default_weights
from push_planner.planner_node import PARAMETERS, PlannerNode
from push_ros.outline import outline_cloud_msg as outline_cloud
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS
from push_ros.stamps import stamp_from_seconds
from push_ros.state import state_array_msg as state_msg

pytestmark = pytest.mark.ros

SPEC = load_object("rect1")
L_GUESS = SPEC.limit_surface_guess()
R_P = 0.0048
REPO = FilePath(__file__).resolve().parents[2]


@dataclass
class Harness:
    node: PlannerNode
    client: Node
    executor: SingleThreadedExecutor
    wait_for: Callable[..., bool]
    pubs: dict[str, Any]
    pushes: list[Path] = field(default_factory=list)
    markers: list[MarkerArray] = field(default_factory=list)
    status: list[DiagnosticStatus] = field(default_factory=list)

    def spin_until(self, predicate: Callable[[], bool], timeout: float = 10.0) -> bool:
        return self.wait_for(predicate, timeout=timeout, executor=self.executor)

    def values(self) -> dict[str, str]:
        return {kv.key: kv.value for kv in self.status[-1].values} if self.status else {}

    def count(self, key: str) -> int:
        return int(self.values().get(key, -1))

    def publish_outline(self, points: np.ndarray, normals: np.ndarray) -> None:
        self.pubs["outline"].publish(outline_cloud(points, normals))

    def publish_goal(self, x: float, y: float, theta: float, frame: str = "world",
                     quaternion: tuple[float, float, float, float] | None = None) -> None:
        msg = PoseStamped()
        msg.header.frame_id = frame
        msg.pose.position.x, msg.pose.position.y = float(x), float(y)
        qx, qy, qz, qw = quaternion or (0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2))
        o = msg.pose.orientation
        o.x, o.y, o.z, o.w = qx, qy, qz, qw
        self.pubs["goal"].publish(msg)

    def publish_estimate(self, pose: tuple[float, float, float], stamp: float,
                         state_first: bool = True, state: list[float] | None = None,
                         covariance: np.ndarray | None = None) -> None:
        x, y, theta = pose
        pose_msg = PoseWithCovarianceStamped()
        pose_msg.header.frame_id = "world"
        pose_msg.header.stamp = stamp_from_seconds(stamp)
        pose_msg.pose.pose.position.x, pose_msg.pose.pose.position.y = float(x), float(y)
        pose_msg.pose.pose.orientation.z = math.sin(theta / 2)
        pose_msg.pose.pose.orientation.w = math.cos(theta / 2)
        values = state if state is not None else [x, y, theta, 0.0, 0.0, L_GUESS, 0.25]
        s_msg = state_msg(values, covariance)
        first, second = (("state", s_msg), ("pose", pose_msg)) if state_first else (
            ("pose", pose_msg), ("state", s_msg))
        self.pubs[first[0]].publish(first[1])
        self.pubs[second[0]].publish(second[1])

    def publish_executed(self, t_start: float, t_end: float) -> None:
        msg = Path()
        msg.header.frame_id = "world"
        msg.header.stamp = stamp_from_seconds(t_end)
        for t in (t_start, t_end):
            p = PoseStamped()
            p.header.frame_id = "world"
            p.header.stamp = stamp_from_seconds(t)
            msg.poses.append(p)
        self.pubs["executed"].publish(msg)


def make_harness(ros_context: Any, wait_for: Callable[..., bool],
                 overrides: list[Parameter] | None = None) -> Harness:
    node = PlannerNode(context=ros_context, parameter_overrides=overrides or [])
    client = Node("planner_test_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(client)
    pubs = {
        "outline": client.create_publisher(PointCloud2, "perception/outline", LATCHED_QOS),
        "goal": client.create_publisher(PoseStamped, "goal_pose", RELIABLE_QOS),
        # The estimator's outputs are latched (what ekf_node offers; the planner subscribes
        # transient local, which a volatile publisher cannot serve).
        "state": client.create_publisher(Float64MultiArray, "estimator/state", LATCHED_QOS),
        "pose": client.create_publisher(PoseWithCovarianceStamped, "estimator/object_pose",
                                        LATCHED_QOS),
        "executed": client.create_publisher(Path, "pusher/executed", RELIABLE_QOS),
        "refused": client.create_publisher(DiagnosticStatus, "pusher/refused", RELIABLE_QOS),
    }
    h = Harness(node, client, executor, wait_for, pubs)
    client.create_subscription(Path, "planner/push", h.pushes.append, RELIABLE_QOS)
    client.create_subscription(MarkerArray, "planner/affordances", h.markers.append,
                               RELIABLE_QOS)
    client.create_subscription(DiagnosticStatus, "planner/status", h.status.append, LATCHED_QOS)
    subs = ("planner/push", "planner/affordances", "planner/status")
    assert h.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs.values())
                        and all(client.count_publishers(t) > 0 for t in subs)
                        and len(h.status) > 0)
    return h


@pytest.fixture
def harness(ros_context: Any, wait_for: Callable[..., bool]) -> Iterator[Harness]:
    h = make_harness(ros_context, wait_for, [Parameter("k", value=1), Parameter("seed", value=3)])
    yield h
    h.executor.shutdown()
    h.client.destroy_node()
    h.node.destroy_node()


def rect1_outline() -> tuple[np.ndarray, np.ndarray]:
    return SPEC.outline(0.002)


def check_push(path: Path, pose: tuple[float, float, float]) -> np.ndarray:
    """Assert that ``path`` is a valid push against rect1 at ``pose``; return its points."""
    assert path.header.frame_id == "world"
    assert len(path.poses) == 3
    pts = np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])
    assert np.all(np.isfinite(pts))
    a, c, e = pts
    stroke = e - a
    assert abs(stroke[0] * (c - a)[1] - stroke[1] * (c - a)[0]) / np.linalg.norm(stroke) < 1e-6
    assert 0.0099 <= np.linalg.norm(e - c) <= 0.0501
    x, y, th = pose
    rot = np.array([[math.cos(th), math.sin(th)], [-math.sin(th), math.cos(th)]])
    local = (pts - [x, y]) @ rot.T
    _, _, dist, _ = closest_point_on_polyline(SPEC.polyline(), local)
    assert dist[0] >= R_P + 5e-4  # approach clear of the object
    assert abs(dist[1] - R_P) < 1.5e-3  # contact: the pusher touches the outline
    stamps = [p.header.stamp.sec + 1e-9 * p.header.stamp.nanosec for p in path.poses]
    assert stamps[0] < stamps[1] < stamps[2]  # reached in order at push_speed
    assert (stamps[2] - stamps[0]) == pytest.approx(np.linalg.norm(e - a) / 0.02, rel=1e-6)
    return pts


def test_stop_rule_uses_the_covariance_and_ignores_a_discs_orientation(harness: Harness
                                                                        ) -> None:
    h = harness
    h.publish_outline(*rect1_outline())
    h.publish_goal(0.005, 0.0, 0.0)  # 5 mm away: inside the 7.5 mm region
    assert h.spin_until(lambda: h.status[-1].message == "waiting for estimate")
    # sigma 2 mm: 5 + 2.33 * 2 > 7.5 mm, not confidently there: push
    h.publish_estimate((0.0, 0.0, 0.0), stamp=10.0,
                       covariance=np.diag([4e-6, 4e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6]))
    assert h.spin_until(lambda: len(h.pushes) == 1)
    assert h.spin_until(lambda: h.status[-1].message == "pushing step 1")
    # sigma 0.5 mm, same pose: 5 + 1.16 <= 7.5 mm, reached
    h.publish_executed(11.0, 12.0)
    h.publish_estimate((0.0, 0.0, 0.0), stamp=13.0,
                       covariance=np.diag([2.5e-7, 2.5e-7, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6]))
    assert h.spin_until(lambda: h.status[-1].message == "goal reached")
    assert h.values()["orientation"] == "used" and len(h.pushes) == 1
    # A disc's outline: a goal 1 rad away at the same position is reached at once.
    h.publish_outline(*load_object("ellip1").outline(0.002))
    assert h.spin_until(lambda: h.values().get("orientation") == "ignored")
    h.publish_goal(0.0, 0.0, 1.0)
    assert h.spin_until(lambda: h.status[-1].message.startswith("goal reached ("))
    assert h.status[-1].message == ("goal reached (orientation ignored: rotationally "
                                    "symmetric outline)")
    assert len(h.pushes) == 1
    # A covariance with NaN is refused with a reason, the node keeps running.
    bad = np.full((7, 7), np.nan)
    h.publish_estimate((0.0, 0.0, 0.0), stamp=14.0, covariance=bad)
    assert h.spin_until(lambda: "covariance" in h.values().get("last_refusal", ""))


def test_plans_once_per_fresh_estimate(harness: Harness) -> None:
    h = harness
    h.publish_outline(*rect1_outline())
    h.publish_goal(0.1, 0.0, 0.0)
    assert h.spin_until(lambda: h.status[-1].message == "waiting for estimate")
    h.publish_estimate((0.0, 0.0, 0.0), stamp=10.0)
    assert h.spin_until(lambda: len(h.pushes) == 1 and len(h.markers) == 1)
    pts = check_push(h.pushes[0], (0.0, 0.0, 0.0))
    assert (pts[2] - pts[1])[0] > 0.0  # towards the goal in +x
    assert [m.ns for m in h.markers[0].markers] == [
        "planner/outline", "planner/candidates", "planner/push", "planner/approach"]
    assert len(h.markers[0].markers[0].points) == len(rect1_outline()[0])
    assert h.spin_until(lambda: h.status[-1].message == "pushing step 1")

    # The same estimate again (pose first this time): no second plan.
    h.publish_estimate((0.0, 0.0, 0.0), stamp=10.0, state_first=False)
    assert h.spin_until(lambda: h.count("estimates") == 2)
    assert h.count("ignored_busy") + h.count("ignored_duplicate") == 1
    assert not h.spin_until(lambda: len(h.pushes) > 1, timeout=0.5)

    # The push is reported (ended at 12 s): the estimate of 10 s predates it, no plan.
    h.publish_executed(11.0, 12.0)
    assert h.spin_until(lambda: h.values().get("last_push_end") == "12.000000")
    h.publish_estimate((0.0, 0.0, 0.0), stamp=11.5)  # also stale
    assert h.spin_until(lambda: h.count("ignored_stale") == 1)
    assert not h.spin_until(lambda: len(h.pushes) > 1, timeout=0.5)

    # A fresh estimate: exactly one new plan.
    h.publish_estimate((0.03, 0.0, 0.0), stamp=13.0, state_first=False)
    assert h.spin_until(lambda: len(h.pushes) == 2)
    check_push(h.pushes[1], (0.03, 0.0, 0.0))
    assert h.spin_until(lambda: h.status[-1].message == "pushing step 2")

    # A fresh estimate that arrives before its push is reported is used when the report comes.
    h.publish_estimate((0.05, 0.0, 0.0), stamp=16.0)
    assert h.spin_until(lambda: h.count("ignored_busy") + h.count("ignored_duplicate") == 2)
    assert len(h.pushes) == 2
    h.publish_executed(14.0, 15.0)
    assert h.spin_until(lambda: len(h.pushes) == 3)
    check_push(h.pushes[2], (0.05, 0.0, 0.0))
    assert h.spin_until(lambda: h.count("planned") == 3)
    assert h.values()["step"] == "3"

    # At the goal: no push, status goal reached.
    h.publish_executed(16.5, 17.0)
    h.publish_estimate((0.098, 0.002, 0.01), stamp=18.0)
    assert h.spin_until(lambda: h.status[-1].message == "goal reached")
    assert h.status[-1].level == DiagnosticStatus.OK
    assert len(h.pushes) == 3

    # A new goal starts a new episode and re-opens the newest (still fresh) estimate once.
    h.publish_goal(0.0, 0.0, 0.0)
    assert h.spin_until(lambda: len(h.pushes) == 4)
    assert h.spin_until(lambda: h.status[-1].message == "pushing step 1")


@contextmanager
def pushing_rect1(ros_context: Any, wait_for: Callable[..., bool], push_timeout: float
                  ) -> Iterator[tuple[Harness, np.ndarray]]:
    """A harness (k 1, seed 3, ``push_timeout``) sent rect1's outline, a goal 10 cm along +x
    and the estimate (0, 0, 0) at 10 s; yields it and the outline points."""
    h = make_harness(ros_context, wait_for, [Parameter("k", value=1), Parameter("seed", value=3),
                                             Parameter("push_timeout", value=push_timeout)])
    try:
        points, normals = rect1_outline()
        h.publish_outline(points, normals)
        h.publish_goal(0.1, 0.0, 0.0)
        h.publish_estimate((0.0, 0.0, 0.0), stamp=10.0)
        yield h, points
    finally:
        h.executor.shutdown()
        h.client.destroy_node()
        h.node.destroy_node()


def contact_feet(pushes: list[Path], points: np.ndarray) -> list[np.ndarray]:
    """The outline point of each push against rect1 at (0, 0, 0) (world = object frame): the
    one nearest to its contact (the pusher axis, R_P outside the outline)."""
    return [points[np.argmin(np.linalg.norm(points - check_push(p, (0.0, 0.0, 0.0))[1],
                                            axis=1))] for p in pushes]


def test_a_lost_push_is_not_planned_again(ros_context: Any,
                                          wait_for: Callable[..., bool]) -> None:
    """A push not reported within push_timeout (e.g. refused by the robot) counts as a step;
    the next plans from the same estimate avoid its contact region until a push is executed."""
    with pushing_rect1(ros_context, wait_for, 0.5) as (h, points):
        assert h.spin_until(lambda: len(h.pushes) == 3, timeout=20.0)  # two pushes lost
        feet = contact_feet(h.pushes, points)
        for i, j in ((0, 1), (0, 2), (1, 2)):
            assert np.linalg.norm(feet[i] - feet[j]) > AVOID_RADIUS - 2e-3, (i, j, feet)
        assert h.spin_until(lambda: h.values().get("step") == "3")


def test_a_refused_push_is_lost_at_once_and_the_planner_plans_again(
        ros_context: Any, wait_for: Callable[..., bool]) -> None:
    """A pusher/refused naming the push in flight counts as a lost push at once (no
    wait for push_timeout, here 1000 s) and the next push avoids its contact region; a refusal
    of another push, and a malformed one, change nothing."""
    from push_ros.refusal import refusal_msg

    with pushing_rect1(ros_context, wait_for, 1000.0) as (h, points):
        assert h.spin_until(lambda: len(h.pushes) == 1)
        first = h.pushes[0]
        # Another push's refusal (1 ns off the push in flight): ignored.
        other = Time(sec=first.header.stamp.sec, nanosec=(first.header.stamp.nanosec + 1)
                     % 1_000_000_000)
        h.pubs["refused"].publish(refusal_msg("/other", other, "busy", "not yours"))
        assert h.spin_until(lambda: h.count("refusals_ignored") == 1)
        # Malformed: refused with the reason.
        bad = refusal_msg("/other", first.header.stamp, "busy", "no stamp")
        bad.values = [kv for kv in bad.values if kv.key != "push_stamp"]
        h.pubs["refused"].publish(bad)
        assert h.spin_until(lambda: h.count("refused") == 1)
        assert h.values()["last_refusal"].startswith("pusher/refused: push_stamp")
        assert len(h.pushes) == 1 and h.count("step") == 1 and h.count("pushes_refused") == 0
        # The push in flight refused: a new push at once, away from the refused contact.
        h.pubs["refused"].publish(refusal_msg("/executor", first.header.stamp, "ik",
                                              "no IK solution at the contact point"))
        assert h.spin_until(lambda: len(h.pushes) == 2, timeout=20.0)
        assert h.spin_until(lambda: h.count("pushes_refused") == 1 and h.count("step") == 2)
        assert h.count("lost") == 1 and h.status[-1].level == DiagnosticStatus.WARN
        assert h.status[-1].message == ("pushing step 2 - push of step 1 refused by /executor "
                                        "(ik): no IK solution at the contact point")
        feet = contact_feet(h.pushes, points)
        assert np.linalg.norm(feet[0] - feet[1]) > AVOID_RADIUS - 2e-3
        key = [(p.header.stamp.sec, p.header.stamp.nanosec) for p in h.pushes]
        assert key[1] > key[0]
        # The same refusal again names a push no longer in flight: ignored.
        h.pubs["refused"].publish(refusal_msg("/executor", first.header.stamp, "ik", "again"))
        assert h.spin_until(lambda: h.count("refusals_ignored") == 2)
        assert len(h.pushes) == 2 and h.count("step") == 2 and h.count("pushes_refused") == 1


def test_bad_inputs_are_refused_and_the_node_keeps_working(harness: Harness) -> None:
    h = harness
    refused = 0

    def expect_refusal(what: str) -> None:
        nonlocal refused
        refused += 1
        assert h.spin_until(lambda: h.count("refused") == refused), what
        assert h.status[-1].level == DiagnosticStatus.WARN
        assert f"refused {what}" in h.status[-1].message
        assert h.values()["last_refusal"].startswith(what)

    points, normals = rect1_outline()
    h.pubs["outline"].publish(outline_cloud(points[:0], normals[:0]))
    expect_refusal("perception/outline")
    assert "empty" in h.status[-1].message
    h.publish_outline(points[::-1], -normals[::-1])  # clockwise
    expect_refusal("perception/outline")
    h.pubs["outline"].publish(outline_cloud(points, normals, frame_id="world"))
    expect_refusal("perception/outline")

    h.publish_goal(math.nan, 0.0, 0.0)
    expect_refusal("goal_pose")
    h.publish_goal(0.1, 0.0, 0.0, quaternion=(0.0, 0.0, 0.0, 2.0))
    expect_refusal("goal_pose")
    assert "unit" in h.status[-1].message
    h.publish_goal(0.1, 0.0, 0.0, quaternion=(0.7071068, 0.0, 0.0, 0.7071068))  # tilted
    expect_refusal("goal_pose")
    h.publish_goal(0.9, 0.0, 0.0)  # off the table
    expect_refusal("goal_pose")
    assert "workspace" in h.status[-1].message
    h.publish_goal(0.1, 0.0, 0.0, frame="camera_color_optical_frame")
    expect_refusal("goal_pose")

    h.pubs["state"].publish(state_msg([0.0, 0.0, math.nan, 0.0, 0.0, L_GUESS, 0.25]))
    expect_refusal("estimator/state")
    bad_layout = state_msg([0.0] * 7)
    bad_layout.layout.dim[0].label = "x"
    h.pubs["state"].publish(bad_layout)
    expect_refusal("estimator/state")

    # Valid input still works, and an estimate a plan cannot use (l = 0) is refused too.
    h.publish_outline(points, normals)
    h.publish_goal(0.1, 0.0, 0.0)
    assert h.spin_until(lambda: h.status[-1].message == "waiting for estimate")
    h.publish_estimate((0.0, 0.0, 0.0), stamp=5.0, state=[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25])
    expect_refusal("estimate")
    assert not h.pushes
    h.publish_estimate((0.0, 0.0, 0.0), stamp=6.0)
    assert h.spin_until(lambda: len(h.pushes) == 1)
    check_push(h.pushes[0], (0.0, 0.0, 0.0))
    assert h.spin_until(lambda: h.status[-1].message == "pushing step 1")
    assert h.status[-1].level == DiagnosticStatus.OK


def test_max_steps_and_reset(ros_context: Any, wait_for: Callable[..., bool]) -> None:
    h = make_harness(ros_context, wait_for, [Parameter("max_steps", value=1)])
    try:
        h.publish_outline(*rect1_outline())
        h.publish_goal(0.1, 0.0, 0.0)
        h.publish_estimate((0.0, 0.0, 0.0), stamp=1.0)
        assert h.spin_until(lambda: len(h.pushes) == 1)
        h.publish_executed(1.5, 2.0)
        h.publish_estimate((0.02, 0.0, 0.0), stamp=3.0)
        assert h.spin_until(lambda: h.status[-1].message == "failed after max steps")
        assert h.status[-1].level == DiagnosticStatus.ERROR
        assert h.values()["state"] == "failed" and h.values()["max_steps"] == "1"
        assert len(h.pushes) == 1

        reset = h.client.create_client(Trigger, "planner_node/reset")
        assert reset.wait_for_service(timeout_sec=10.0)
        future = reset.call_async(Trigger.Request())
        assert h.spin_until(future.done)
        assert future.result().success
        # The goal is forgotten (an episode is one goal), the outline kept.
        assert h.spin_until(lambda: h.status[-1].message.startswith(
            "waiting for goal, estimate on goal_pose"))
        h.publish_estimate((0.02, 0.0, 0.0), stamp=4.0)
        assert h.spin_until(lambda: h.count("estimates") == 2)
        assert len(h.pushes) == 1  # no plan against the previous episode's goal
        h.publish_goal(0.1, 0.0, 0.0)
        assert h.spin_until(lambda: len(h.pushes) == 2)
    finally:
        h.executor.shutdown()
        h.client.destroy_node()
        h.node.destroy_node()


def test_episode_parameters_apply_on_reset(ros_context: Any,
                                           wait_for: Callable[..., bool]) -> None:
    h = make_harness(ros_context, wait_for, [Parameter("k", value=1), Parameter("seed", value=3)])
    try:
        reset = h.client.create_client(Trigger, "planner_node/reset")
        assert reset.wait_for_service(timeout_sec=10.0)

        def call_reset() -> Any:
            future = reset.call_async(Trigger.Request())
            assert h.spin_until(future.done)
            return future.result()

        results = h.node.set_parameters([Parameter("k", value=5), Parameter("seed", value=11),
                                         Parameter("max_steps", value=7),
                                         Parameter("goal_tolerance.xy", value=0.02)])
        assert all(r.successful for r in results)
        assert h.node.params.planner.k == 1  # applied on the next reset, not mid-episode
        result = call_reset()
        assert result.success and "k 5" in result.message and "seed 11" in result.message
        cfg = h.node.params.planner
        assert (cfg.k, cfg.seed, cfg.tolerance_xy, h.node.params.max_steps) == (5, 11, 0.02, 7)
        # Structural parameters stay read-only.
        assert not h.node.set_parameters([Parameter("push_speed", value=0.05)])[0].successful
        # An invalid value is refused when set (push_ros.node's on-set validation), with the
        # reason, and the previous values kept.
        refused = h.node.set_parameters([Parameter("method", value="best")])[0]
        assert not refused.successful and "parameter 'method'" in refused.reason
        assert h.node.get_parameter("method").value == "ana"
        assert call_reset().success
        assert h.node.params.planner.method == "ana" and h.node.params.planner.k == 5
    finally:
        h.executor.shutdown()
        h.client.destroy_node()
        h.node.destroy_node()


def test_lookahead_and_contradicted_push_parameters_reach_the_planner(
        ros_context: Any, wait_for: Callable[..., bool]) -> None:
    h = make_harness(ros_context, wait_for, [
        Parameter("lookahead.horizon", value=2), Parameter("lookahead.beam", value=4),
        Parameter("lookahead.push_cost", value=15.0),
        Parameter("avoid_contradicted", value=True)])
    try:
        cfg = h.node.params.planner
        assert (cfg.horizon, cfg.beam, cfg.push_cost, cfg.avoid_contradicted) == (2, 4, 15.0,
                                                                                  True)
        summary = h.node.params.summary()
        assert "lookahead 2 pushes (beam 4, push cost 15.0 mm)" in summary
        assert "contradicted pushes avoided" in summary
    finally:
        h.executor.shutdown()
        h.client.destroy_node()
        h.node.destroy_node()


@pytest.mark.parametrize(("name", "value", "match"), [
    ("method", "best", "parameter 'method'"),
    ("temperature", 0.0, "parameter 'temperature'"),
    ("workspace.x_min", 0.5, "parameter 'workspace"),
    ("lrn_weights", "/nonexistent/weights.pt", "lrn"),
])
def test_bad_parameters_fail_at_start_up(ros_context: Any, name: str, value: Any,
                                         match: str) -> None:
    overrides = [Parameter(name, value=value)]
    if name == "lrn_weights":
        overrides.append(Parameter("method", value="lrn"))
    with pytest.raises(ValueError, match=match):
        PlannerNode(context=ros_context, parameter_overrides=overrides)


def test_parameter_ranges_are_declared(ros_context: Any) -> None:
    with pytest.raises(ParameterException):
        PlannerNode(context=ros_context, parameter_overrides=[Parameter("k", value=0)])


def test_parameter_yaml_documents_every_parameter_with_its_default() -> None:
    path = REPO / "src/pushbot_bringup/config/push_planner.yaml"
    text = path.read_text()
    params = yaml.safe_load(text)["planner_node"]["ros__parameters"]
    assert params["use_sim_time"] is True
    flat = {f"{k}.{kk}": vv for k, v in params.items() if isinstance(v, dict)
            for kk, vv in v.items()}
    flat.update({k: v for k, v in params.items() if not isinstance(v, dict)})
    for spec in PARAMETERS:
        assert spec.name in flat, f"{spec.name} is not in {path.name}"
        value = flat[spec.name]
        assert value == spec.default and type(value) is type(spec.default), spec.name
    assert set(flat) == {s.name for s in PARAMETERS} | {"use_sim_time"}


@pytest.mark.graph
@pytest.mark.slow
def test_node_process_starts_with_the_yaml_and_refuses_bad_parameters(
        ros_context: Any, wait_for: Callable[..., bool], processes: Any) -> None:
    config = str(REPO / "src/pushbot_bringup/config/push_planner.yaml")
    bad = processes.node("planner_node", "--ros-args", "--params-file", config,
                         "-p", "method:=best")
    assert bad.wait(timeout=60) == 2
    assert "parameter 'method'" in processes.output(bad)

    proc = processes.node("planner_node", "--ros-args", "--params-file", config,
                          "-p", "use_sim_time:=false")
    client = Node("planner_status_probe", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    status: list[DiagnosticStatus] = []
    client.create_subscription(DiagnosticStatus, "planner/status", status.append, LATCHED_QOS)
    try:
        assert wait_for(lambda: bool(status), timeout=60.0, executor=executor), \
            processes.output(proc)
        message = status[-1].message
        assert message.startswith("waiting for goal, outline, estimate on goal_pose")
        # what a goal is and how a (re)started planner still gets one, with both CLIs
        assert "transient_local" in message and "pushbot goal" in message
        assert status[-1].name == "/planner_node"
        assert proc.poll() is None
    finally:
        executor.shutdown()
        client.destroy_node()
    assert processes.stop(proc) == 0


@pytest.mark.skipif(not default_weights().exists(), reason="no bundled weights")
def test_lrn_method_plans_with_the_bundled_model(ros_context: Any,
                                                 wait_for: Callable[..., bool]) -> None:
    h = make_harness(ros_context, wait_for, [Parameter("method", value="lrn")])
    try:
        h.publish_outline(*rect1_outline())
        h.publish_goal(0.0, 0.1, 0.3)
        h.publish_estimate((0.0, 0.0, 0.0), stamp=1.0)
        assert h.spin_until(lambda: len(h.pushes) == 1)
        check_push(h.pushes[0], (0.0, 0.0, 0.0))
    finally:
        h.executor.shutdown()
        h.client.destroy_node()
        h.node.destroy_node()


def call_reset(h: Harness) -> Any:
    reset = h.client.create_client(Trigger, "planner_node/reset")
    assert reset.wait_for_service(timeout_sec=10.0)
    future = reset.call_async(Trigger.Request())
    assert h.spin_until(future.done)
    return future.result()


def test_far_future_stamps_are_refused(harness: Harness) -> None:
    h = harness
    h.publish_outline(*rect1_outline())
    h.publish_goal(0.1, 0.0, 0.0)
    assert h.spin_until(lambda: h.status[-1].message == "waiting for estimate")
    h.publish_executed(2147483645.0, 2147483646.0)  # wall clock + far more than 10 s
    assert h.spin_until(lambda: h.count("refused") == 1)
    assert "ahead of the node's clock" in h.values()["last_refusal"]
    assert h.values()["last_push_end"] == "-inf"  # no state change
    h.publish_estimate((0.0, 0.0, 0.0), stamp=2147483646.0)
    assert h.spin_until(lambda: h.count("refused") == 2)
    assert h.values()["last_refusal"].startswith("estimator/object_pose")
    assert h.count("estimates") == 0
    h.publish_estimate((0.0, 0.0, 0.0), stamp=5.0)  # the node still plans
    assert h.spin_until(lambda: len(h.pushes) == 1)


def test_reset_clears_a_wedge_accepted_before_the_clock_started(
        ros_context: Any, wait_for: Callable[..., bool]) -> None:
    # use_sim_time without /clock: the clock reads 0, the future rule cannot apply, the
    # far-future push end is accepted and makes every estimate stale; ~/reset forgets it.
    h = make_harness(ros_context, wait_for, [Parameter("use_sim_time", value=True)])
    try:
        h.publish_outline(*rect1_outline())
        h.publish_goal(0.1, 0.0, 0.0)
        h.publish_executed(2147483645.0, 2147483646.0)
        assert h.spin_until(lambda: h.values().get("last_push_end") == "2147483646.000000")
        h.publish_estimate((0.0, 0.0, 0.0), stamp=5.0)
        assert h.spin_until(lambda: h.count("ignored_stale") == 1)
        assert not h.pushes
        assert call_reset(h).success
        assert h.spin_until(lambda: h.values().get("last_push_end") == "-inf"
                            and h.status[-1].message.startswith("waiting for goal, estimate"))
        h.publish_goal(0.1, 0.0, 0.0)
        h.publish_estimate((0.0, 0.0, 0.0), stamp=6.0)
        assert h.spin_until(lambda: len(h.pushes) == 1)
    finally:
        h.executor.shutdown()
        h.client.destroy_node()
        h.node.destroy_node()


@pytest.mark.parametrize("after_goal", ["resume", "report"])
def test_after_the_goal_a_displaced_object_is_reported_and_pushed_again(
        ros_context: Any, wait_for: Callable[..., bool], after_goal: str) -> None:
    h = make_harness(ros_context, wait_for, [Parameter("k", value=1), Parameter("seed", value=3),
                                             Parameter("after_goal", value=after_goal)])
    try:
        h.publish_outline(*rect1_outline())
        h.publish_goal(0.1, 0.0, 0.0)
        h.publish_estimate((0.099, 0.0, 0.0), stamp=1.0)
        assert h.spin_until(lambda: h.status[-1].message == "goal reached")
        # Another client pushes the object 3 cm off (its pusher/executed), the next estimate
        # shows it.
        h.publish_executed(2.0, 3.0)
        assert h.spin_until(lambda: h.values().get("last_push_end") == "3.000000")
        h.publish_estimate((0.07, 0.0, 0.0), stamp=4.0)
        assert h.spin_until(lambda: h.values().get("left_goal") == "1")
        message = h.status[-1].message
        assert h.status[-1].level == DiagnosticStatus.WARN and "left the goal region" in message
        if after_goal == "resume":
            assert h.spin_until(lambda: len(h.pushes) == 1)
            assert message.startswith("pushing step 1 - left the goal region") and \
                "pushing again" in message
        else:
            assert message.startswith("goal left - left the goal region")
            assert h.values()["state"] == "left" and not h.pushes
            h.publish_estimate((0.1, 0.0, 0.0), stamp=5.0)  # put back
            assert h.spin_until(lambda: h.status[-1].message == "goal reached")
    finally:
        h.executor.shutdown()
        h.client.destroy_node()
        h.node.destroy_node()


def test_a_new_goal_after_the_last_one_finished_is_no_switch(harness: Harness) -> None:
    # The same user sending `pushbot goal` twice: two processes, so two publishers, but the
    # second goal comes after the first was reached: a new request, not a rival client.
    h = harness
    other = h.client.create_publisher(PoseStamped, "goal_pose", RELIABLE_QOS)
    assert h.spin_until(lambda: other.get_subscription_count() > 0)
    h.publish_outline(*rect1_outline())
    h.publish_goal(0.1, 0.0, 0.0)
    h.publish_estimate((0.1, 0.0, 0.0), stamp=1.0)  # at the goal
    assert h.spin_until(lambda: h.status[-1].message.startswith("goal reached"))
    msg = PoseStamped()
    msg.header.frame_id = "world"
    msg.pose.position.x, msg.pose.orientation.w = -0.1, 1.0
    other.publish(msg)
    assert h.spin_until(lambda: h.values().get("goal") == "-0.1000 0.0000 0.0000")
    assert h.values()["goal_switches"] == "0"
    assert "another publisher" not in h.status[-1].message


def test_a_goal_from_another_publisher_is_noted(harness: Harness) -> None:
    h = harness
    other = h.client.create_publisher(PoseStamped, "goal_pose", RELIABLE_QOS)
    assert h.spin_until(lambda: other.get_subscription_count() > 0)
    h.publish_outline(*rect1_outline())
    h.publish_goal(0.1, 0.0, 0.0)
    assert h.spin_until(lambda: h.values().get("goal") == "0.1000 0.0000 0.0000")
    h.publish_goal(0.1, 0.05, 0.0)  # the same publisher again: not a switch
    assert h.spin_until(lambda: h.values().get("goal") == "0.1000 0.0500 0.0000")
    assert h.values()["goal_switches"] == "0"
    msg = PoseStamped()
    msg.header.frame_id = "world"
    msg.pose.position.x, msg.pose.orientation.w = -0.1, 1.0
    other.publish(msg)
    assert h.spin_until(lambda: h.values().get("goal_switches") == "1")
    assert h.values()["goal"] == "-0.1000 0.0000 0.0000"  # taken, but not silently
    assert "goal replaced by another publisher" in h.status[-1].message
    assert "planner_test_client (gid" in h.status[-1].message
    assert h.status[-1].level == DiagnosticStatus.WARN


def test_an_exception_in_a_callback_is_counted_and_the_node_keeps_working(
        harness: Harness) -> None:
    h = harness
    planner, original = h.node._planner, h.node._planner.plan

    def broken(*args: Any, **kwargs: Any) -> Any:
        raise RuntimeError("injected fault")

    planner.plan = broken
    h.publish_outline(*rect1_outline())
    h.publish_goal(0.1, 0.0, 0.0)
    h.publish_estimate((0.0, 0.0, 0.0), stamp=1.0)
    assert h.spin_until(lambda: h.values().get("callback_errors") == "1")
    assert "injected fault" in h.values()["last_error"]
    assert h.status[-1].level == DiagnosticStatus.WARN
    planner.plan = original
    h.publish_estimate((0.0, 0.0, 0.0), stamp=2.0)
    assert h.spin_until(lambda: len(h.pushes) == 1)


def test_a_restarted_planner_resumes_from_the_latched_goal_and_estimate(
        ros_context: Any, wait_for: Callable[..., bool], harness: Harness) -> None:
    # Goal senders publish latched (push_ros.qos.GOAL_QOS) and the planner reads
    # goal_pose volatile *and* transient local, so a planner started after the goal still gets
    # it; a sample of a latched sender arrives on both readers and is taken once.
    from push_ros.qos import GOAL_QOS

    h = harness
    latched_goal = h.client.create_publisher(PoseStamped, "goal_pose", GOAL_QOS)
    assert h.spin_until(lambda: latched_goal.get_subscription_count() > 0)
    h.publish_outline(*rect1_outline())
    h.publish_estimate((0.0, 0.0, 0.0), stamp=10.0)
    msg = PoseStamped()
    msg.header.frame_id = "world"
    msg.pose.position.x, msg.pose.orientation.w = 0.1, 1.0
    latched_goal.publish(msg)
    assert h.spin_until(lambda: len(h.pushes) == 1)
    h.spin_until(lambda: False, timeout=0.5)  # the second reader's copy has arrived meanwhile
    assert len(h.pushes) == 1 and h.count("goal_switches") == 0 and h.count("step") == 1
    # The planner process dies; a new one starts (same name) and continues from latched data.
    h.executor.remove_node(h.node)
    h.node.destroy_node()
    h.node = PlannerNode(context=ros_context, parameter_overrides=[Parameter("k", value=1)])
    h.executor.add_node(h.node)
    assert h.spin_until(lambda: len(h.pushes) == 2, timeout=20.0), [s.message for s in h.status]
    check_push(h.pushes[-1], (0.0, 0.0, 0.0))
    assert h.spin_until(lambda: h.values().get("goal") == "0.1000 0.0000 0.0000"
                        and h.count("step") == 1)
    assert h.count("goal_switches") == 0


def test_a_busy_refusal_waits_for_a_newer_estimate(ros_context: Any,
                                                   wait_for: Callable[..., bool]) -> None:
    """A push refused while the robot may still move ("busy", "fault", "cancelled") is a lost
    step, but the next push waits for a newer estimate: planning again from the same one would
    meet the busy robot again, a loop of refusals that burns every step."""
    from push_ros.refusal import refusal_msg

    with pushing_rect1(ros_context, wait_for, 1000.0) as (h, _):
        assert h.spin_until(lambda: len(h.pushes) == 1)
        h.pubs["refused"].publish(refusal_msg("/executor", h.pushes[0].header.stamp, "busy",
                                              "the arm is executing a push"))
        assert h.spin_until(lambda: h.count("pushes_refused") == 1 and h.count("lost") == 1)
        h.spin_until(lambda: len(h.pushes) > 1, timeout=1.0)  # give it the chance to err
        assert len(h.pushes) == 1 and h.count("step") == 1
        h.publish_estimate((0.0, 0.0, 0.0), stamp=11.0)  # the robot's motion ended: a new frame
        assert h.spin_until(lambda: len(h.pushes) == 2, timeout=20.0)
        assert h.spin_until(lambda: h.count("step") == 2)
