"""planner_node and the robot's availability (in-process, one rclpy context, real DDS).

A refusal that says the robot is not available pauses the episode (``robot unavailable:
<kind>: <reason>`` on planner/status and /diagnostics, no step spent, nothing planned from new
estimates); ``executor/status`` saying ``ready`` resumes it from the newest estimate stamped
since the wait began (none: the next one); a status of another executor session while a push
is in flight counts that push lost at once (the restarted executor has forgotten it); the wait
fails after ``robot_timeout``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from push_ros.qos import LATCHED_QOS
from push_ros.refusal import readiness_values, refusal_msg

from .test_planner_node import Harness, make_harness, pushing_rect1

pytestmark = pytest.mark.ros


def executor_status(ready: bool, session: str, unavailable: tuple[str, str] | None = None
                    ) -> DiagnosticStatus:
    values = readiness_values(ready, unavailable, session)
    return DiagnosticStatus(name="/push_executor_node: push executor",
                            values=[KeyValue(key=k, value=v) for k, v in values.items()])


def wall_now() -> float:
    return time.time()  # the harness node runs on wall time: its clock stamps "fresh"


def test_an_unavailable_robot_pauses_the_episode_until_it_is_ready(
        ros_context: Any, wait_for: Callable[..., bool]) -> None:
    with pushing_rect1(ros_context, wait_for, 1000.0) as (h, _):
        status_pub = h.client.create_publisher(DiagnosticStatus, "executor/status", LATCHED_QOS)
        assert h.spin_until(lambda: status_pub.get_subscription_count() > 0)
        status_pub.publish(executor_status(True, "s1"))
        assert h.spin_until(lambda: len(h.pushes) == 1)
        # Dry run: the push is refused as disabled, the robot says it is not available.
        h.pubs["refused"].publish(refusal_msg("/push_executor_node", h.pushes[0].header.stamp,
                                              "disabled", "executor disabled (dry run)",
                                              available=False))
        assert h.spin_until(lambda: h.values().get("state") == "unavailable")
        assert h.status[-1].message.startswith(
            "robot unavailable: disabled: executor disabled (dry run)")
        values = h.values()
        assert values["step"] == "0" and values["robot_unavailable"].startswith("disabled: ")
        # The executor is ready again, with no estimate since the wait began: nothing is
        # planned from the one before the wait (the world may have changed meanwhile) ...
        status_pub.publish(executor_status(True, "s1"))
        assert h.spin_until(lambda: h.values().get("state") == "waiting")
        assert len(h.pushes) == 1
        # ... the next estimate is used.
        h.publish_estimate((0.0, 0.0, 0.0), stamp=wall_now())
        assert h.spin_until(lambda: len(h.pushes) == 2)
        assert h.spin_until(lambda: h.values().get("step") == "1")
        # Unavailable again: new estimates are taken but nothing is planned while waiting; the
        # newest since the wait began is used at once when the robot is ready (a simulator
        # publishes no frame until the arm moves).
        h.pubs["refused"].publish(refusal_msg("/push_executor_node", h.pushes[1].header.stamp,
                                              "no_state", "no joint state", available=False))
        assert h.spin_until(lambda: h.values().get("state") == "unavailable")
        n_estimates = h.count("estimates")
        h.publish_estimate((0.0, 0.0, 0.0), stamp=wall_now())  # before the ready
        assert h.spin_until(lambda: h.count("estimates") > n_estimates)
        assert len(h.pushes) == 2 and h.values()["state"] == "unavailable"
        status_pub.publish(executor_status(True, "s1"))
        assert h.spin_until(lambda: len(h.pushes) == 3)
        assert h.spin_until(lambda: h.values().get("step") == "1")  # the refused one given back
        # The executor restarts (a new session) with the push in flight: lost at once, and
        # planned again from a newer estimate (the arm may have been moving).
        status_pub.publish(executor_status(True, "s2"))
        assert h.spin_until(lambda: h.count("lost") == 1)
        assert h.spin_until(lambda: "executor restarted" in h.status[-1].message)
        h.publish_estimate((0.0, 0.0, 0.0), stamp=wall_now() + 3.0)
        assert h.spin_until(lambda: len(h.pushes) == 4)
        assert h.spin_until(lambda: h.values().get("step") == "2")


def test_the_wait_fails_after_robot_timeout(ros_context: Any,
                                            wait_for: Callable[..., bool]) -> None:
    from rclpy.parameter import Parameter

    h: Harness = make_harness(ros_context, wait_for, [
        Parameter("k", value=1), Parameter("seed", value=3),
        Parameter("robot_timeout", value=0.5)])
    try:
        from .test_planner_node import rect1_outline

        h.publish_outline(*rect1_outline())
        h.publish_goal(0.1, 0.0, 0.0)
        h.publish_estimate((0.0, 0.0, 0.0), stamp=10.0)
        assert h.spin_until(lambda: len(h.pushes) == 1)
        h.pubs["refused"].publish(refusal_msg("/push_executor_node", h.pushes[0].header.stamp,
                                              "no_controller", "no controller subscribes"))
        assert h.spin_until(lambda: h.values().get("state") == "failed", timeout=15.0)
        assert h.status[-1].message.startswith("failed: robot unavailable for ")
        assert "no_controller: no controller subscribes" in h.status[-1].message
        assert h.status[-1].level == DiagnosticStatus.ERROR and h.values()["step"] == "0"
    finally:
        h.executor.shutdown()
        h.client.destroy_node()
        h.node.destroy_node()
