"""A planner started after the estimator has published still gets the estimate.

Started by hand in the README's order (bridge, perception, estimator, planner), the planner
used to wait forever: the estimator published its estimate once, on volatile topics, before
the planner subscribed. The estimator's outputs are now latched (reliable, transient local,
depth 1) and the planner subscribes transient local, so DDS hands a late subscriber the last
estimate. Here, in one process with real DDS: ``ekf_node`` gets an outline and an observation
and publishes its estimate; only then is ``planner_node`` created; its status counts the
estimate.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2

from push_core.objects import load_object
from push_estimator.ekf_node import EkfNode
from push_planner.planner_node import PlannerNode
from push_ros.outline import outline_cloud_msg
from push_ros.poses import pose_with_covariance_msg
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS
from push_ros.stamps import stamp_from_seconds

pytestmark = pytest.mark.ros

TIMEOUT = 20.0


def test_a_planner_started_after_the_estimate_still_gets_it(
        ros_context: Any, wait_for: Callable[..., bool]) -> None:
    executor = SingleThreadedExecutor(context=ros_context)
    ekf = EkfNode(context=ros_context)
    client = Node("late_subscriber_client", context=ros_context)
    for node in (ekf, client):
        executor.add_node(node)
    planner = None
    try:
        outline = client.create_publisher(PointCloud2, "perception/outline", LATCHED_QOS)
        observation = client.create_publisher(PoseWithCovarianceStamped,
                                              "perception/object_pose", RELIABLE_QOS)
        estimates: list[PoseWithCovarianceStamped] = []
        client.create_subscription(PoseWithCovarianceStamped, "estimator/object_pose",
                                   estimates.append, RELIABLE_QOS)
        assert wait_for(lambda: outline.get_subscription_count() > 0
                        and observation.get_subscription_count() > 0
                        and client.count_publishers("estimator/object_pose") > 0,
                        timeout=TIMEOUT, executor=executor)
        points, normals = load_object("rect1").outline(0.004)
        outline.publish(outline_cloud_msg(points, normals, stamp_from_seconds(0.0)))
        assert wait_for(lambda: ekf._ekf is not None, timeout=TIMEOUT, executor=executor)
        observation.publish(pose_with_covariance_msg((0.01, -0.02, 0.1), np.diag(
            [1e-6, 1e-6, 1e-4]), stamp_from_seconds(1.0)))
        assert wait_for(lambda: estimates, timeout=TIMEOUT, executor=executor), \
            "ekf_node published no estimate"
        n_published = len(estimates)

        # Only now does the planner subscribe: the latched estimate must still reach it.
        planner = PlannerNode(context=ros_context)
        executor.add_node(planner)
        status: list[DiagnosticStatus] = []
        client.create_subscription(DiagnosticStatus, "planner/status", status.append,
                                   LATCHED_QOS)

        def counted() -> bool:
            values = {kv.key: kv.value for kv in status[-1].values} if status else {}
            return values.get("estimates") == "1"

        assert wait_for(counted, timeout=TIMEOUT, executor=executor), (
            f"planner_node never counted the estimate; last status: "
            f"{status[-1] if status else None}")
        assert len(estimates) == n_published  # nothing was re-sent: it was the latched sample
        assert "estimate" not in status[-1].message  # no longer "waiting for ..., estimate"
    finally:
        executor.shutdown()
        for node in (planner, ekf, client):
            if node is not None:
                node.destroy_node()
