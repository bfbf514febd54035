"""The robot model's view of the simulated Panda against the simulator's own render.

push_core.robot_view poses the URDF's collision geometry with the joint positions and
rasterises it; pybullet renders the visual geometry and labels every pixel with its body. With
the arm in view, the two masks agree (IoU >= 0.9 at 640 x 480), the depths agree, and the link
poses are pybullet's.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from push_core.robot_view import RobotGeometry
from sim_bridge.world import PushWorld, WorldConfig, quiet_stdout

#: Tool tips (world, m) that put the forearm, wrist and rod in the camera's view: over the
#: workspace at push height, after a retreat and lift, and higher above it.
TIPS = [(0.0, 0.0, 0.05), (0.1, 0.1, 0.1), (0.05, -0.1, 0.03), (0.15, 0.05, 0.06),
        (0.1, -0.15, 0.08), (0.2, 0.0, 0.15), (0.1, 0.2, 0.04)]


@pytest.fixture(scope="module")
def world() -> Iterator[PushWorld]:
    with quiet_stdout():
        w = PushWorld(WorldConfig(robot="arm", object="butter", object_pose=(0.2, 0.25, 0.0)))
    yield w
    w.close()


@pytest.fixture(scope="module")
def robot(world: PushWorld) -> RobotGeometry:
    return RobotGeometry.from_urdf(world.robot_description, base_pose=world.config.arm_base_pose)


def test_the_robot_mask_matches_the_simulators_arm_pixels(world: PushWorld,
                                                          robot: RobotGeometry) -> None:
    arm = world.arm
    w, h = world.image_size
    assert (w, h) == (640, 480)
    for tip in TIPS:
        q = arm.inverse_kinematics(tip)
        arm.set_positions(q)
        true = world.arm_mask()
        assert true.sum() > 5000, tip  # the arm is in view
        mask, depth = robot.render(world.camera_matrix, world.T_world_camera, w, h,
                                   list(arm.state().names), arm.state().positions)
        iou = np.count_nonzero(mask & true) / np.count_nonzero(mask | true)
        assert iou >= 0.9, (tip, iou)
        frame = world.render()  # depth_noise is off: the renderer's depth
        both = mask & true & np.isfinite(frame.depth)
        assert np.median(np.abs(depth[both] - frame.depth[both])) < 1e-3, tip


def test_the_link_poses_are_the_simulators(world: PushWorld, robot: RobotGeometry) -> None:
    arm = world.arm
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.uniform(arm.limits[:, 0], arm.limits[:, 1])
        arm.set_positions(q)
        poses = robot.link_poses(list(arm.state().names), q)
        tip = poses["pusher_tip"]
        assert np.allclose(tip[:3, 3], arm.tip_position(), atol=1e-6)
        assert np.allclose(tip[:3, 2], arm.rod_axis(), atol=1e-6)


def test_the_parked_arm_is_out_of_view(world: PushWorld, robot: RobotGeometry) -> None:
    arm = world.arm
    arm.set_positions(world.config.arm_park)
    w, h = world.image_size
    mask, _ = robot.render(world.camera_matrix, world.T_world_camera, w, h,
                           list(arm.state().names), arm.state().positions)
    assert not world.arm_mask().any()
    assert not mask.any()
