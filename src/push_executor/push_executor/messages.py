"""push_executor_node's outgoing messages built from plans (the conversion half of the node).

- :func:`trajectory_msg`: a :class:`push_executor.motion.MotionPlan` as the controller's
  ``trajectory_msgs/JointTrajectory`` (header stamp = the start, s of the node's clock; the
  joints in the commanded order; positions and velocities per point);
- :func:`hold_msg`: the one-point "hold here" trajectory of a stop (stamp 0: now);
- :func:`path_msg`: the planned tool tip path as ``executor/path`` (nav_msgs/Path, z = the tip's
  height);
- :func:`stage_text`: a plan's stages as ``name:start:end`` words for ``executor/status``;
- :func:`executed_msg`: a measured contact segment as ``pusher/executed``;
- the incoming ones, checked: :func:`push_from_msg` (``planner/push``) and
  :func:`joint_state_from_msg` (``/joint_states``), each raising ``ValueError`` with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from push_core.robot_view import joint_positions
from push_executor.motion import MotionPlan
from push_executor.tracking import ContactSegment
from push_ros.paths import path_from_points, push_points_from_path
from push_ros.poses import pose_msg
from push_ros.stamps import check_not_ahead, seconds_from_stamp, stamp_from_seconds

__all__ = ["HOLD_TIME", "MAX_JOINTS", "executed_msg", "hold_msg", "joint_state_from_msg",
           "path_msg", "push_from_msg", "stage_text", "trajectory_msg"]

#: ``time_from_start`` of the one-point hold trajectory, s.
HOLD_TIME = 0.05
#: Most joints a joint state may name (a bigger message is refused before any work).
MAX_JOINTS = 1000


def push_from_msg(msg: Path, world_frame: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(approach, contact, end) of a ``planner/push`` in ``world_frame``; ``ValueError``."""
    seconds_from_stamp(msg.header.stamp)
    if msg.header.frame_id != world_frame:
        raise ValueError(f"frame {msg.header.frame_id[:64]!r} is not {world_frame!r}")
    return push_points_from_path(msg)


def joint_state_from_msg(msg: JointState, chain: Sequence[str], clock: float | None,
                         max_future: float) -> tuple[float, np.ndarray]:
    """(stamp s, chain positions) of a joint state; ``ValueError`` for too many joints, a bad
    stamp or one more than ``max_future`` s ahead of ``clock``, missing or bad positions."""
    if len(msg.name) > MAX_JOINTS:
        raise ValueError(f"{len(msg.name)} joints")
    stamp = seconds_from_stamp(msg.header.stamp)
    check_not_ahead(stamp, clock, max_future, "joint state stamp")
    return stamp, joint_positions(chain, list(msg.name), msg.position)


def executed_msg(segment: ContactSegment, frame_id: str) -> Path:
    """``pusher/executed``: the measured contact segment's ends (x, y) with their stamps."""
    stamps = [stamp_from_seconds(s, clamp=True) for s in (segment.stamp_start,
                                                          segment.stamp_end)]
    return path_from_points(np.array([segment.start[:2], segment.end[:2]]), stamps, frame_id)


def duration_msg(seconds: float) -> Duration:
    """A ``builtin_interfaces/Duration`` of ``seconds`` (>= 0)."""
    sec = math.floor(seconds)
    return Duration(sec=int(sec), nanosec=min(int(round((seconds - sec) * 1e9)), 999_999_999))


def trajectory_msg(plan: MotionPlan, joints: Sequence[str], start: float) -> JointTrajectory:
    """``plan`` for a controller of ``joints`` (any order of the chain's), starting at
    ``start`` (s)."""
    order = [plan.joint_names.index(j) for j in joints]
    msg = JointTrajectory(joint_names=list(joints))
    msg.header.stamp = stamp_from_seconds(start, clamp=True)
    msg.points = [JointTrajectoryPoint(positions=q[order].tolist(), velocities=v[order].tolist(),
                                       time_from_start=duration_msg(t))
                  for t, q, v in zip(plan.times, plan.positions, plan.velocities, strict=True)]
    return msg


def hold_msg(joints: Sequence[str], positions: dict[str, float],
             seconds: float = HOLD_TIME) -> JointTrajectory:
    """Hold ``positions`` (joint name -> rad) of ``joints``, at rest ``seconds`` from now on
    (the controller interpolates from its state on receipt)."""
    msg = JointTrajectory(joint_names=list(joints))
    msg.points = [JointTrajectoryPoint(positions=[float(positions[j]) for j in joints],
                                       velocities=[0.0] * len(joints),
                                       time_from_start=duration_msg(seconds))]
    return msg


def path_msg(plan: MotionPlan, frame_id: str, stamp: Time) -> Path:
    """The planned tip positions of ``plan`` as a Path in ``frame_id``."""
    msg = Path()
    msg.header.frame_id, msg.header.stamp = frame_id, stamp
    for x, y, z in np.asarray(plan.tip):
        msg.poses.append(PoseStamped(header=msg.header, pose=pose_msg(x, y, 0.0, z)))
    return msg


def stage_text(plan: MotionPlan) -> str:
    """``name:start:end`` per stage (s of the plan), space-separated."""
    return " ".join(f"{s.name}:{s.t_start:.3f}:{s.t_end:.3f}" for s in plan.stages)
