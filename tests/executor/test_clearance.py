"""push_executor.clearance: the object's region and silhouette, the candidates, the clear pose.

Geometry by hand (a camera looking straight down); the clear pose against the simulator's own
rendering: pushes planned with a real :class:`ClearView` (the robot image of
push_core.robot_view) and executed in pybullet end with the object's visible pixels the same
as with the arm parked.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.geometry import object_to_world
from push_core.objects import load_object
from push_executor.clearance import (
    CameraView,
    ClearView,
    clear_candidates,
    fill_convex,
    object_region,
    robot_mask_factory,
    silhouette,
)
from push_executor.kinematics import ArmKinematics, ToolSpec
from push_executor.motion import MotionConfig, plan_push

SQUARE = np.array([[-0.02, -0.02], [0.02, -0.02], [0.02, 0.02], [-0.02, 0.02]])


def down_camera(height: float = 1.0, f: float = 100.0, size: int = 101) -> CameraView:
    """A camera ``height`` m above the origin looking straight down: optical x = world x,
    optical y = world -y, optical z = world -z; 1 px = height / f m on the table."""
    t = np.eye(4)
    t[:3, :3] = np.diag([1.0, -1.0, -1.0])
    t[:3, 3] = (0.0, 0.0, height)
    c = (size - 1) / 2
    return CameraView(np.array([[f, 0.0, c], [0.0, f, c], [0.0, 0.0, 1.0]]), size, size, t)


def test_fill_convex_counts_the_pixel_centres_inside() -> None:
    mask = fill_convex([[1.5, 1.5], [5.5, 1.5], [5.5, 3.5], [1.5, 3.5]], 10, 8)
    assert mask.sum() == 4 * 2 and mask[2:4, 2:6].all()
    assert not fill_convex([[0, 0], [1, 1]], 5, 5).any()  # fewer than 3 vertices
    # vertices beyond the integer range: the box is clipped before the cast, not wrapped
    huge = fill_convex([[-1e19, -1e19], [1e19, -1e19], [0.0, 1e19]], 10, 8)
    assert huge[4:, 3:7].all()


def test_projection_and_silhouette_of_a_square() -> None:
    cam = down_camera()
    uv, z = cam.project([[0.0, 0.0, 0.0], [0.1, 0.2, 0.0]])
    np.testing.assert_allclose(uv, [[50.0, 50.0], [60.0, 30.0]])
    np.testing.assert_allclose(z, [1.0, 1.0])
    mask = silhouette(cam, SQUARE * 5, 0.0)  # 0.2 m side: 20 px
    assert mask.sum() == pytest.approx(21 * 21, abs=2 * 21)
    # a prism 0.5 m tall seen from 1 m above: its top is twice as large
    tall = silhouette(cam, SQUARE * 5, 0.5)
    assert tall.sum() == pytest.approx(41 * 41, abs=2 * 41)
    # a camera inside the prism, or a corner beside the camera's plane: all of the image
    assert silhouette(cam, SQUARE * 5, 1.5).all()
    beside = CameraView(cam.camera_matrix, cam.width, cam.height,
                        np.array([[1.0, 0, 0, 0], [0, 0, 1, 0.3], [0, -1, 0, 0], [0, 0, 0, 1]]))
    assert silhouette(beside, SQUARE * 5 + [0.0, 0.2], 0.0).all()
    half = cam.scaled(0.5)
    assert (half.width, half.height) == (50, 50)
    np.testing.assert_allclose(half.project([[0.1, 0.2, 0.0]])[0], [[29.75, 14.75]])


def test_object_region_holds_where_the_object_may_be() -> None:
    region = object_region(SQUARE, (0.1, 0.0, 0.0), (0.07, 0.0), (0.12, 0.0), margin=0.0,
                           turn=0.0)
    xs = region[:, 0]
    assert xs.min() == pytest.approx(0.08) and xs.max() == pytest.approx(0.17)  # swept 5 cm
    grown = object_region(SQUARE, (0.1, 0.0, 0.0), (0.07, 0.0), (0.12, 0.0), margin=0.01,
                          turn=0.0)
    assert grown[:, 0].min() == pytest.approx(0.07, abs=1e-3)
    turned = object_region(SQUARE, (0.0, 0.0, 0.0), (0.0, 0.0), (0.0, 0.0), margin=0.0,
                           turn=math.pi / 4)
    assert np.max(np.linalg.norm(turned, axis=1)) == pytest.approx(0.02 * math.sqrt(2))
    assert turned[:, 0].max() == pytest.approx(0.02 * math.sqrt(2))  # a corner turned onto x


def test_candidates_start_at_the_lift_and_ring_the_region() -> None:
    top = np.array([0.2, 0.0, 0.11])
    region = SQUARE + [0.1, 0.0]
    candidates = clear_candidates(top, region, distance=0.05, rise=0.1)
    np.testing.assert_allclose(candidates[0], top)
    ring = np.array(candidates[1:])
    assert len(ring) == 32 and set(np.round(ring[:, 2], 6)) == {0.11, 0.21}
    radius = np.linalg.norm(ring[:, :2] - [0.1, 0.0], axis=1)
    assert set(np.round(radius - 0.02 * math.sqrt(2), 6)) == {0.025, 0.05}
    steps = np.linalg.norm(ring - top, axis=1)
    assert np.all(np.diff(steps) >= -1e-12)  # nearest to the lift's end first


@pytest.fixture(scope="module")
def world():
    from sim_bridge.world import PushWorld, WorldConfig, quiet_stdout

    with quiet_stdout():
        w = PushWorld(WorldConfig(object="butter", robot="arm"))
    yield w
    w.close()


def _visible(world, q: np.ndarray) -> int:
    """The object's visible pixels with the arm at ``q`` (the arm restored afterwards)."""
    now = np.array(world.arm_state().positions)
    world.arm.set_positions(q)
    pixels = int(world.render().mask.sum())
    world.arm.set_positions(now)
    return pixels


def test_pushes_end_at_poses_clear_of_the_object(world) -> None:
    """Three pushes at the butter from different sides (one from the camera's side, where the
    arm over the object hides it), planned with the clear view and executed: each ends
    withdrawn, not parked, and the camera sees as much of the object as with the arm parked."""
    from sim_bridge.arm import TrajectoryCommand, TrajectoryFollower, check_trajectory
    from sim_bridge.arm_robot import ARM_JOINTS

    arm = ArmKinematics(world.robot_description, "panda_link0", ToolSpec(),
                        world.config.arm_base_pose)
    factory, why = robot_mask_factory(world.robot_description, world.config.arm_base_pose,
                                      arm.joint_names)
    assert factory is not None, why
    frame = world.render()
    camera = CameraView(frame.camera_matrix, frame.rgb.shape[1], frame.rgb.shape[0],
                        frame.T_world_camera).scaled(0.25)
    outline = load_object("butter").polyline()
    finals = []
    for direction in ((-1.0, 0.0), (0.0, 1.0), (1.0, 0.0)):  # pushing toward -x: from +x
        pose = world.object_pose()
        d = np.array(direction)
        # the pusher axis on the line through the centre, clear of the object's back
        back = float(np.max((pose[:2] - object_to_world(pose, outline)) @ d))
        contact = pose[:2] - (back + 0.0048) * d
        approach, end = contact - 0.005 * d, contact + 0.03 * d
        region = object_region(outline, pose, contact, end, 0.02, 0.35)
        view = ClearView(camera, region, 0.03, factory(camera), 0.05, 0.1)
        plan = plan_push(arm, MotionConfig(), approach, contact, end,
                         np.array(world.arm_state().positions), view)
        assert plan.final in ("lift", "withdraw"), plan.stages
        assert view.covered(plan.positions[-1]) == 0
        follower = TrajectoryFollower(ARM_JOINTS)
        cmd = TrajectoryCommand(joint_names=list(plan.joint_names), stamp=0.0,
                                times=plan.times.tolist(), positions=plan.positions.tolist(),
                                velocities=plan.velocities.tolist())
        follower.offer(check_trajectory(cmd, ARM_JOINTS, world.sim_time))
        follower.open()
        world.run_arm(follower, 4, None, None, None, 0.0)
        q = np.array(world.arm_state().positions)
        assert _visible(world, q) == _visible(world, world.config.arm_park)
        finals.append(plan.final)
    print(f"final stages: {finals}")
