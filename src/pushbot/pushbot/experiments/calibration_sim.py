"""The simulated arm and camera as the calibration procedure's robot, in process.

:class:`SimCalibrationRobot` is :class:`pushbot.runner.calibration.CalibrationRobot` over a
``sim_bridge.world.PushWorld`` in arm mode with the board on the tool: a move is planned and
checked by the executor's own :func:`push_executor.joint_goal.plan_joint_goal` from the
measured posture and then set in the world (the motion's time is the plan's duration, not
simulated: the evaluation measures the calibration, the arm's tracking is measured elsewhere);
a frame is the world's render, optionally with Gaussian colour noise. :func:`sim_arm` is the
executor's model of the simulated arm.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_executor.joint_goal import plan_joint_goal
from push_executor.kinematics import ArmKinematics, ToolSpec
from push_executor.motion_types import PANDA_SIM_BASE_POSE, MotionConfig, PushRefused

__all__ = ["FRAME_WAIT", "SimCalibrationRobot", "sim_arm"]

#: Robot time per view beyond the motion: the arm held for three joint states and a colour
#: frame taken after it (the graph's 30 Hz camera, 100 Hz joint states), s.
FRAME_WAIT = 0.1


def sim_arm(world: Any) -> ArmKinematics:
    """The executor's model of the world's arm (its URDF, the simulated base pose)."""
    return ArmKinematics(world.robot_description, "panda_link0", ToolSpec(),
                         PANDA_SIM_BASE_POSE)


class SimCalibrationRobot:
    """The world's arm and camera (module docstring).

    Parameters
    ----------
    world : sim_bridge.world.PushWorld
        Arm mode, ``calibration_board``.
    arm : ArmKinematics
    motion : MotionConfig
    noise : float
        Standard deviation of the colour noise, 8-bit levels (0: none).
    seed : int
        Seed of the noise.
    """

    def __init__(self, world: Any, arm: ArmKinematics, motion: MotionConfig,
                 noise: float = 0.0, seed: int = 0) -> None:
        self.world, self.arm, self.motion, self.noise = world, arm, motion, float(noise)
        self.rng = np.random.default_rng(seed)
        #: Robot time spent, s: the planned motions and :data:`FRAME_WAIT` per view.
        self.robot_time = 0.0

    def joints(self) -> NDArray[np.float64]:
        state = self.world.arm_state()
        by_name = dict(zip(state.names, state.positions, strict=True))
        return np.array([by_name[j] for j in self.arm.joint_names], dtype=float)

    def move(self, q: NDArray[np.float64]) -> tuple[str, str]:
        try:
            plan = plan_joint_goal(self.arm, self.motion, q, self.joints())
        except PushRefused as refusal:
            return refusal.kind, refusal.reason
        self.world.arm.set_positions(q)
        self.robot_time += plan.duration + FRAME_WAIT
        return "", ""

    def frame(self) -> NDArray[np.uint8]:
        rgb = self.world.render().rgb
        if self.noise <= 0:
            return rgb
        noisy = rgb.astype(np.float64) + self.rng.normal(0.0, self.noise, rgb.shape)
        return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
