"""push_executor_node's outgoing messages built from plans (the conversion half of the node).

- :func:`trajectory_msg`: a :class:`push_executor.motion.MotionPlan` as the controller's
  ``trajectory_msgs/JointTrajectory`` (header stamp = the start, s of the node's clock; the
  joints in the commanded order; positions and velocities per point);
- :func:`hold_msg`: the one-point "hold here" trajectory of a stop (stamp 0: now);
- :func:`path_msg`: the planned tool tip path as ``executor/path`` (nav_msgs/Path, z = the tip's
  height);
- :func:`stage_text`: a plan's stages as ``name:start:end`` words for ``executor/status``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from push_executor.motion import MotionPlan
from push_ros.poses import pose_msg
from push_ros.stamps import stamp_from_seconds

__all__ = ["HOLD_TIME", "hold_msg", "path_msg", "stage_text", "trajectory_msg"]

#: ``time_from_start`` of the one-point hold trajectory, s.
HOLD_TIME = 0.05


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


def hold_msg(joints: Sequence[str], positions: dict[str, float]) -> JointTrajectory:
    """Hold ``positions`` (joint name -> rad) of ``joints`` from now on."""
    msg = JointTrajectory(joint_names=list(joints))
    msg.points = [JointTrajectoryPoint(positions=[float(positions[j]) for j in joints],
                                       velocities=[0.0] * len(joints),
                                       time_from_start=duration_msg(HOLD_TIME))]
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
