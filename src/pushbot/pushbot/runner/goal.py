"""``pushbot goal X Y YAW``: send a goal to ``planner_node`` and, with ``--wait``, follow it.

The goal goes out once on ``goal_pose`` (geometry_msgs/PoseStamped, built by
``push_ros.poses.pose_stamped_msg``; QoS ``push_ros.qos.GOAL_QOS``, reliable + transient
local, which matches the planner's subscription whether it is volatile or transient local) in
``--frame`` (default ``world``). X and Y are the goal position in metres in that frame; YAW is
the rotation in radians wanted since the episode's first camera frame
(docs/design/evaluation.md#goal-frame), e.g.::

    pushbot goal 0.05 0.03 0.3 --wait

It waits (at most 20 s, or ``--timeout`` if shorter) for planner_node's subscription and its
latched ``planner/status`` first. With ``--wait`` it then follows ``planner/status`` and prints
a line whenever it changes (step, state, and the distance and yaw left from the latest
``estimator/object_pose``), until the status shows this goal ``goal reached`` (exit 0), or
``failed``, a refusal of the goal (e.g. off the workspace) or ``--timeout`` (exit 1; the goal
stays with the planner, and the message says how to drop it). A new goal from another client
ends the wait with exit 1 too. While the robot is not available (``robot unavailable: <kind>:
<reason>``: no joint states, no controller, ...) the planner waits without spending steps and
so does ``--wait``; the executor disabled for a dry run (kind ``disabled``) is the dry run's
expected end: the push was planned (``executor/path``), nothing moved, no step spent; ``--wait``
says so and exits 3 (the goal stays with the planner and runs once the executor is enabled).

Exit codes: 0 sent (reached with ``--wait``), 1 no planner, refused, failed or timed out, 2 bad
input (non-finite numbers, empty frame), 3 a dry run (``--wait``: the executor is disabled).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from pushbot.ros2cli.discovery import EXIT_USAGE, cli_node, run_graph_command, spin_until

DEFAULT_TIMEOUT = 300.0
"""Seconds ``--wait`` follows the episode (30 pushes take about a minute in simulation)."""
STAYS = ("the goal stays with planner_node and runs as soon as it has estimates; drop it "
         "with: pushbot service call /planner_node/reset std_srvs/srv/Trigger")
"""What a timed-out ``--wait`` says about its goal (a planner keeps a goal until reset)."""
LINGER = 2.0
"""Seconds ``goal`` (without ``--wait``) keeps its latched publisher after sending: DDS
discovery of this new process by a running ``bag record`` or ``view`` takes a moment."""
LATE_SUBSCRIBER_WAIT = 5.0
"""Seconds, after ``LINGER``, that ``goal`` waits at most for the subscribers of ``goal_pose``
the graph knows of (one that found the topic during the linger) to match its publisher and
acknowledge the latched goal; a subscriber whose QoS never matches costs this bound."""
EXIT_DRY_RUN = 3
"""Exit status of ``--wait`` when the executor is disabled (a dry run: planned, not moved)."""
DRY_RUN = ("dry run: the executor is disabled, so the push was planned (executor/path) and "
           "nothing moved, no step spent; the goal stays with the planner and runs once the "
           "executor is enabled: pushbot service call /push_executor_node/enable "
           "std_srvs/srv/SetBool '{data: true}'")
"""What ``--wait`` says at the end of a dry run."""
PLANNER_TIMEOUT = 20.0
"""Longest wait for planner_node (its goal subscription and latched status), seconds: enough
for a graph that ``pushbot up`` is still starting (the nodes import torch)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pushbot goal``."""
    parser.add_argument("x", type=float, help="goal x in metres (--frame)")
    parser.add_argument("y", type=float, help="goal y in metres (--frame)")
    parser.add_argument("yaw", type=float,
                        help="goal yaw in radians: the rotation since the episode's first "
                             "frame")
    parser.add_argument("--frame", default="world",
                        help="frame of the goal position (default: %(default)s; planner_node "
                             "takes world)")
    parser.add_argument("--wait", action="store_true",
                        help="follow planner/status until the goal is reached (exit 0), "
                             "failed (exit 1) or planned in a dry run (the executor disabled: "
                             "exit 3)")
    parser.add_argument("--linger", type=float, default=LINGER,
                        help="seconds the latched goal stays available after it was sent "
                             "(without --wait): a recorder or viewer that discovers the topic "
                             "meanwhile still receives it; then up to "
                             f"{LATE_SUBSCRIBER_WAIT:g} s more until every subscriber the "
                             "graph knows has it (default: %(default)s)")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT,
                        help="seconds to wait, with --wait, for the end of the episode "
                             "(default: %(default)s; planner_node itself is waited for at most "
                             f"{PLANNER_TIMEOUT:g} s)")


def goal_delivered(node: Any, publisher: Any) -> bool:
    """True when every subscriber of the publisher's topic in the graph is matched and has
    acknowledged the published samples (reliable readers; best-effort ones count as matched)."""
    from rclpy.duration import Duration

    return (publisher.get_subscription_count() >= node.count_subscribers(publisher.topic_name)
            and publisher.wait_for_all_acked(Duration(seconds=0)))


def status_values(msg: Any) -> dict[str, str]:
    """``planner/status`` (diagnostic_msgs/DiagnosticStatus) ``values`` as a dict."""
    return {kv.key: kv.value for kv in msg.values}


def goal_text(x: float, y: float, yaw: float) -> str:
    """How planner_node's status writes a goal: ``x y theta``, 4 decimals, theta in (-pi, pi]."""
    from push_core.geometry import wrap_angle

    return " ".join(f"{v:.4f}" for v in (x, y, float(wrap_angle(yaw))))


def _progress(msg: Any, estimate: tuple[float, float, float] | None,
              goal: tuple[float, float, float]) -> str:
    values = status_values(msg)
    line = f"step {values.get('step', '?')}/{values.get('max_steps', '?')}: {msg.message}"
    if estimate is not None:
        from push_core.geometry import wrap_angle

        distance = math.hypot(goal[0] - estimate[0], goal[1] - estimate[1])
        yaw = float(wrap_angle(goal[2] - estimate[2]))
        line += f" (left: {distance * 1000:.1f} mm, {math.degrees(yaw):.1f} deg)"
    return line


def run_goal(args: argparse.Namespace) -> int:
    """Handler of ``pushbot goal``."""
    goal = (args.x, args.y, args.yaw)
    if not all(math.isfinite(v) for v in goal):
        print(f"pushbot goal: X, Y and YAW must be finite numbers, got {args.x} {args.y} "
              f"{args.yaw}", file=sys.stderr)
        return EXIT_USAGE
    if not args.frame.strip():
        print("pushbot goal: --frame must not be empty", file=sys.stderr)
        return EXIT_USAGE
    if not args.linger >= 0:
        print("pushbot goal: --linger must be >= 0", file=sys.stderr)
        return EXIT_USAGE
    if not args.timeout > 0:
        print("pushbot goal: --timeout must be > 0", file=sys.stderr)
        return EXIT_USAGE
    return run_graph_command(args, lambda a: _send(a, goal), "goal")


def _send(args: argparse.Namespace, goal: tuple[float, float, float]) -> int:
    from diagnostic_msgs.msg import DiagnosticStatus
    from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
    from rclpy.duration import Duration

    from push_ros.poses import pose_stamped_msg, xytheta_from_pose
    from push_ros.qos import GOAL_QOS, latched_reader_qos

    deadline = time.monotonic() + args.timeout
    statuses: list[Any] = []
    estimate: list[tuple[float, float, float]] = []

    def on_estimate(msg: Any) -> None:
        try:
            estimate[:] = [tuple(float(v) for v in xytheta_from_pose(msg.pose.pose))]
        except ValueError:
            pass  # not a planar pose: no distance shown

    with cli_node("goal") as (node, executor):
        publisher = node.create_publisher(PoseStamped, "goal_pose", GOAL_QOS)
        node.create_subscription(DiagnosticStatus, "planner/status", statuses.append,
                                 latched_reader_qos(100))
        node.create_subscription(PoseWithCovarianceStamped, "estimator/object_pose",
                                 on_estimate, latched_reader_qos(1))
        # Discovery first: the planner's goal subscription and its latched status (whose
        # refusal counter tells a refused goal from an older refusal).
        wait = min(args.timeout, PLANNER_TIMEOUT)
        if not spin_until(executor, lambda: publisher.get_subscription_count() > 0 and statuses,
                          time.monotonic() + wait):
            print("pushbot goal: no planner_node: nothing subscribes to goal_pose or publishes "
                  f"planner/status (waited {wait:g} s; is the graph up? pushbot up)",
                  file=sys.stderr)
            return 1
        refused_before = int(status_values(statuses[-1]).get("refused", 0) or 0)
        seen = len(statuses)
        msg = pose_stamped_msg(goal, node.get_clock().now().to_msg(), args.frame)
        publisher.publish(msg)
        mine = goal_text(*goal)
        print(f"goal sent: x {goal[0]:g} m, y {goal[1]:g} m, yaw {goal[2]:g} rad in "
              f"{args.frame}", flush=True)
        if not args.wait:
            sent = time.monotonic()
            publisher.wait_for_all_acked(Duration(seconds=2.0))
            spin_until(executor, lambda: False, sent + args.linger)
            spin_until(executor, lambda: goal_delivered(node, publisher),
                       time.monotonic() + LATE_SUBSCRIBER_WAIT)
            return 0
        last_line = ""
        accepted = False
        while True:
            if not spin_until(executor, lambda n=seen: len(statuses) > n, deadline):
                print(f"pushbot goal: timed out after {args.timeout:g} s"
                      + (f" ({last_line})" if last_line else "")
                      + (f"; {STAYS}" if status_values(statuses[-1]).get("goal") == mine
                         else ""), file=sys.stderr)
                return 1
            status = statuses[seen]
            seen += 1
            values = status_values(status)
            if values.get("goal") != mine:
                refused = int(values.get("refused", 0) or 0)
                if not accepted and refused > refused_before \
                        and "refused goal_pose" in status.message:
                    print(f"pushbot goal: planner_node refused the goal: "
                          f"{values.get('last_refusal', status.message)}", file=sys.stderr)
                    return 1
                if accepted:
                    print(f"pushbot goal: the goal was replaced ({values.get('goal') or 'none'})"
                          f": {status.message}", file=sys.stderr)
                    return 1
                continue
            accepted = True
            line = _progress(status, estimate[0] if estimate else None, goal)
            if line != last_line:
                print(line, flush=True)
                last_line = line
            state = values.get("state")
            if state == "reached":
                return 0
            if state == "unavailable" and values.get("robot_unavailable", "").startswith(
                    "disabled:"):
                print(f"pushbot goal: {DRY_RUN}", file=sys.stderr)
                return EXIT_DRY_RUN
            if state == "failed":
                print(f"pushbot goal: {status.message}", file=sys.stderr)
                return 1
