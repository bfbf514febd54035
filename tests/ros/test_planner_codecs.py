"""push_ros codecs the planner uses and its own affordance markers: messages built directly,
no rclpy.init."""

from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Quaternion
from nav_msgs.msg import Path

from push_core.objects import load_object
from push_core.planner import Planner, PlannerConfig, prepare_outline
from push_planner.conversions import affordance_markers, executed_end, goal_from_msg
from push_ros.diagnostics import status_msg
from push_ros.outline import outline_cloud_msg as outline_cloud
from push_ros.outline import outline_from_cloud
from push_ros.paths import push_path
from push_ros.poses import pose_with_covariance_from_msg, yaw_from_quaternion
from push_ros.stamps import seconds_from_stamp, stamp_from_seconds
from push_ros.state import state_array_msg as state_msg
from push_ros.state import state_from_array_msg as state_from_msg

WORKSPACE = ((-0.25, 0.25), (-0.3, 0.3))


def yaw_q(theta: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=math.sin(theta / 2), w=math.cos(theta / 2))


def test_stamps_round_trip():
    for t in (0.0, 1.5, 12.000000001, 1e6 + 0.25):
        assert seconds_from_stamp(stamp_from_seconds(t)) == pytest.approx(t, abs=1e-9)
    with pytest.raises(ValueError, match="stamp"):
        stamp_from_seconds(-1.0)


def test_yaw_from_planar_quaternions():
    for theta in (0.0, 0.3, -2.0, math.pi):
        assert math.isclose(math.cos(yaw_from_quaternion(yaw_q(theta)) - theta), 1.0)
    assert yaw_from_quaternion(Quaternion(x=0.0, y=0.0, z=-0.0, w=-1.0)) == pytest.approx(0.0)
    with pytest.raises(ValueError, match="unit"):
        yaw_from_quaternion(Quaternion(x=0.0, y=0.0, z=0.0, w=2.0))
    with pytest.raises(ValueError, match="about z"):
        yaw_from_quaternion(Quaternion(x=0.6, y=0.0, z=0.0, w=0.8))
    with pytest.raises(ValueError, match="finite"):
        yaw_from_quaternion(Quaternion(x=0.0, y=0.0, z=math.nan, w=1.0))


def test_executed_end_is_the_latest_stamp_of_any_executor() -> None:
    msg = Path()
    msg.header.frame_id = "world"
    msg.header.stamp = stamp_from_seconds(10.0)
    for t in (10.5, 12.25, 11.0):  # not in order: the latest counts
        pose = PoseStamped()
        pose.header.stamp = stamp_from_seconds(t)
        msg.poses.append(pose)
    assert executed_end(msg) == pytest.approx(12.25)
    msg.header.stamp = stamp_from_seconds(20.0)  # a header later than every pose
    assert executed_end(msg) == pytest.approx(20.0)
    msg.header.frame_id = "object"
    with pytest.raises(ValueError, match="expected poses in 'world', got 3 poses in 'object'"):
        executed_end(msg)
    msg.header.frame_id, msg.poses = "world", []
    with pytest.raises(ValueError, match="got 0 poses"):
        executed_end(msg)


def test_goal_checks_frame_values_and_workspace():
    msg = PoseStamped()
    msg.header.frame_id = "world"
    msg.pose.position.x, msg.pose.position.y = 0.1, -0.2
    msg.pose.orientation = yaw_q(0.5)
    np.testing.assert_allclose(goal_from_msg(msg, WORKSPACE), [0.1, -0.2, 0.5], atol=1e-12)
    msg.pose.position.x = 0.3
    with pytest.raises(ValueError, match="workspace"):
        goal_from_msg(msg, WORKSPACE)
    msg.pose.position.x = math.inf
    with pytest.raises(ValueError, match="finite"):
        goal_from_msg(msg, WORKSPACE)
    msg.pose.position.x = 0.1
    msg.header.frame_id = "map"
    with pytest.raises(ValueError, match="frame_id"):
        goal_from_msg(msg, WORKSPACE)


def test_estimate_pose_and_stamp():
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = "world"
    msg.header.stamp = stamp_from_seconds(3.25)
    msg.pose.pose.position.x = 0.02
    msg.pose.pose.orientation = yaw_q(-1.0)
    estimate = pose_with_covariance_from_msg(msg)
    np.testing.assert_allclose(estimate.pose, [0.02, 0.0, -1.0], atol=1e-12)
    assert estimate.stamp == 3.25


def test_state_round_trip_and_layout_checks():
    state = np.arange(7.0) + 0.5
    cov = np.arange(49.0).reshape(7, 7)
    got, got_cov = state_from_msg(state_msg(state, cov))
    np.testing.assert_array_equal(got, state)
    np.testing.assert_array_equal(got_cov, cov)
    short = state_msg(state)
    short.data = short.data[:-1]
    with pytest.raises(ValueError, match="55 values"):
        state_from_msg(short)
    relabel = state_msg(state)
    relabel.layout.dim[1].label = "cov"
    with pytest.raises(ValueError, match="layout"):
        state_from_msg(relabel)
    with pytest.raises(ValueError, match="not finite"):
        state_from_msg(state_msg([0, 0, 0, 0, 0, math.inf, 0]))


def test_outline_codec_round_trips_and_refuses_nan():
    # The codec is push_perception's (tests/perception/test_conversions.py); the planner's
    # names for it, and the NaN check its own reader used to lack.
    points, normals = load_object("hex").outline(0.002)
    p, n = outline_from_cloud(outline_cloud(points, normals))
    np.testing.assert_allclose(p, points, atol=1e-7)  # float32 on the wire
    np.testing.assert_allclose(n, normals, atol=1e-7)
    msg = outline_cloud(points, normals)
    msg.data = np.full(6, np.nan, dtype="<f4").tobytes() + bytes(msg.data)[24:]
    with pytest.raises(ValueError, match="NaN"):
        outline_from_cloud(msg)


def test_push_path_points_orientation_and_stamps():
    msg = push_path([0.0, 0.0], [0.005, 0.0], [0.045, 0.0], stamp_seconds=2.0, speed=0.02)
    assert msg.header.frame_id == "world"
    pts = [(p.pose.position.x, p.pose.position.y, p.pose.position.z) for p in msg.poses]
    assert pts == [(0.0, 0.0, 0.0), (0.005, 0.0, 0.0), (0.045, 0.0, 0.0)]
    stamps = [seconds_from_stamp(p.header.stamp) for p in msg.poses]
    np.testing.assert_allclose(stamps, [2.0, 2.25, 4.25], atol=1e-9)
    assert yaw_from_quaternion(msg.poses[0].pose.orientation) == pytest.approx(0.0)
    up = push_path([0.0, 0.0], [0.0, 0.01], [0.0, 0.03], 0.0, 0.02)
    assert yaw_from_quaternion(up.poses[2].pose.orientation) == pytest.approx(math.pi / 2)


def test_markers_and_status():
    spec = load_object("rect1")
    outline = prepare_outline(*spec.outline(0.004))
    pose = np.array([0.05, 0.0, 0.5])
    plan = Planner(PlannerConfig(k=3)).plan(outline, [*pose, 0.0, 0.0, 0.0345, 0.25],
                                           [0.1, 0.05, 0.5])
    msg = affordance_markers(outline, pose, plan, stamp_from_seconds(1.0))
    outline_m, cand, arrow, approach = msg.markers
    assert all(m.header.frame_id == "world" for m in msg.markers)
    assert len(outline_m.points) == len(outline_m.colors) == len(outline.points)
    best = int(np.argmin(plan.scores))
    assert outline_m.colors[best].g == 1.0 and outline_m.colors[best].r == 0.0
    assert len(cand.points) == len(plan.candidates)
    assert (arrow.points[0].x, arrow.points[1].y) == (plan.contact[0], plan.end[1])
    assert approach.pose.position.x == plan.approach[0]
    status = status_msg("/planner_node", DiagnosticStatus.WARN, "waiting", {"step": 0})
    assert status.level == DiagnosticStatus.WARN and status.values[0].value == "0"
