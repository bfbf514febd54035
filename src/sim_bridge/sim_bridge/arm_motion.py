"""Stepping the physics while the arm follows joint trajectories (the arm mode's push).

ROS-free; :meth:`sim_bridge.world.PushWorld.run_arm` is the entry point. One call runs the
physics from the moment a trajectory was offered to the :class:`sim_bridge.arm.TrajectoryFollower`
until (1) the follower has no pending trajectory and the current one has ended, (2) the arm
is still (every joint slower than ``ARM_STILL``) and (3) the object is at rest
(``REST_SPEED`` / ``REST_ANGULAR`` for ``REST_STEPS`` steps, as after a push); or until
``settle_timeout`` after the trajectory's end. A trajectory offered meanwhile (any thread)
replaces the running one and the run goes on. Every step: the follower's target at the step's
sim time becomes the joints' ``POSITION_CONTROL`` target (velocity feed-forward), then one
physics step. Every ``sample_every`` steps the joint state and the true tool tip are sampled.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_bridge.arm import TrajectoryFollower
from sim_bridge.arm_robot import ArmRobot, JointState
from sim_bridge.physics import REST_ANGULAR, REST_SPEED, REST_STEPS, Physics

__all__ = ["ARM_STILL", "MAX_TIP_SAMPLES", "ArmRun", "run_arm"]

#: Joint speed below which the arm counts as still, rad/s.
ARM_STILL = 2e-3
#: Most tool tip samples kept per run (a longer run keeps the first ones).
MAX_TIP_SAMPLES = 20000


@dataclass(frozen=True)
class ArmRun:
    """Outcome of :func:`run_arm`. Times in s of ``sim_time``; points in ``world``, m.

    Attributes
    ----------
    t_start, t_done : float
        When the run started and ended (arm still, object settled).
    tip_times : (K,) ndarray
        Times of the tool tip samples.
    tip_positions : (K, 3) ndarray
        True tool tip positions (forward kinematics of the simulated arm).
    pose_before, pose_after : (3,) ndarray
        Object pose (x, y, theta) at the start and at the end.
    settled : bool
        False if the run ended on ``settle_timeout`` instead.
    """

    t_start: float
    t_done: float
    tip_times: NDArray[np.float64]
    tip_positions: NDArray[np.float64]
    pose_before: NDArray[np.float64]
    pose_after: NDArray[np.float64]
    settled: bool


def run_arm(physics: Physics, arm: ArmRobot, follower: TrajectoryFollower, object_id: int,
            settle_timeout: float, sample_every: int = 1,
            on_sample: Callable[[float, JointState], None] | None = None,
            on_step: Callable[[], None] | None = None) -> ArmRun:
    """Run the physics while ``follower`` has work (module docstring).

    Parameters
    ----------
    physics : Physics
    arm : ArmRobot
    follower : TrajectoryFollower
        Opened here; closed when the run ends.
    object_id : int
        pybullet body of the object (rest detection).
    settle_timeout : float
        Longest time after the trajectory's end to wait for the arm and the object, s.
    sample_every : int
        Physics steps between two samples of the joint state and the tool tip (>= 1).
    on_sample : callable, optional
        ``on_sample(sim_time, joint_state)`` at every sample (publishing ``/joint_states``);
        must not raise.
    on_step : callable, optional
        Called after every physics step (the monitor); read-only, must not raise.
    """
    client = physics._client
    follower.open()
    t_start = physics.sim_time
    pose_before = physics.object_pose()
    times: list[float] = []
    tips: list[NDArray[np.float64]] = []
    calm, first, settled = 0, physics.steps, True
    while True:
        t = physics.sim_time
        state = arm.state()
        q, v = follower.target(t, state.positions, state.velocities)
        arm.command(q, v)
        physics.step(1)
        if on_step is not None:
            on_step()
        t = physics.sim_time
        if (physics.steps - first) % sample_every == 0:
            if on_sample is not None:
                on_sample(t, arm.state())
            if len(times) < MAX_TIP_SAMPLES:
                times.append(t)
                tips.append(arm.tip_position())
        end = follower.end_time
        if t < end:
            calm = 0
            continue
        lin, ang = client.getBaseVelocity(object_id)
        still = np.max(np.abs(arm.state().velocities)) < ARM_STILL
        rest = np.linalg.norm(lin) < REST_SPEED and np.linalg.norm(ang) < REST_ANGULAR
        calm = calm + 1 if still and rest else 0
        timed_out = t > max(end, t_start) + settle_timeout
        if (calm >= REST_STEPS or timed_out) and follower.close_if_done(t):
            settled = not timed_out or calm >= REST_STEPS
            break
    return ArmRun(t_start=t_start, t_done=physics.sim_time, tip_times=np.array(times),
                  tip_positions=np.array(tips).reshape(-1, 3), pose_before=pose_before,
                  pose_after=physics.object_pose(), settled=settled)
