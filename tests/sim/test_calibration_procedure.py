"""The calibration procedure of ``pushbot calibrate`` on the simulated arm and camera, in
process (pybullet; the moves planned and checked by the executor's joint-goal planner), and
its refusals; the extrinsics file and the printed static transform line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from push_core.calibration import BoardSpec, CalibrationRefused, SolveConfig
from push_core.geometry import quaternion_from_matrix
from push_executor.motion_types import MotionConfig
from pushbot.experiments.calibration_sim import SimCalibrationRobot, sim_arm
from pushbot.runner.calibrate import read_extrinsics, static_transform_line, write_extrinsics
from pushbot.runner.calibration import MAX_POSES, CalibrationSetup, run_calibration
from sim_bridge.calibration_board import board_mount
from sim_bridge.camera import CameraConfig, look_at_pose
from sim_bridge.world import PushWorld, WorldConfig

from .test_calibration_board import _placed_camera


@pytest.fixture(scope="module")
def placed() -> tuple[PushWorld, np.ndarray]:
    truth = _placed_camera(5)
    pose = (*truth[:3, 3], *quaternion_from_matrix(truth[:3, :3]))
    world = PushWorld(WorldConfig(robot="arm", calibration_board=True, camera_pose=pose))
    yield world, truth
    world.close()


def _setup(world: PushWorld, **kwargs) -> CalibrationSetup:
    kwargs.setdefault("camera", look_at_pose(CameraConfig()))  # the nominal viewpoint
    return CalibrationSetup(mount=board_mount(BoardSpec()), k=world.camera_matrix,
                            size=world.image_size, **kwargs)


def test_the_procedure_calibrates_a_moved_camera(placed, tmp_path: Path) -> None:
    world, truth = placed
    arm = sim_arm(world)
    robot = SimCalibrationRobot(world, arm, MotionConfig(), noise=2.0, seed=1)
    out = run_calibration(robot, arm, _setup(world, seed=2), MotionConfig())
    r = out.result
    assert out.moved <= MAX_POSES and len(out.views) >= 12
    dp = np.linalg.norm(r.world_camera[:3, 3] - truth[:3, 3]) * 1000
    dr = np.degrees(Rotation.from_matrix(r.world_camera[:3, :3].T @ truth[:3, :3]).magnitude())
    assert dp < 1.0 and dr < 0.1, (dp, dr)
    # the file: written, read back; the printed line carries the same pose
    path = tmp_path / "cal" / "camera_extrinsics.yaml"
    write_extrinsics(path, r, out.moved)
    t, parent, child = read_extrinsics(path)
    np.testing.assert_allclose(t, r.world_camera, atol=1e-9)
    assert (parent, child) == ("world", "camera_color_optical_frame")
    line = static_transform_line(t, parent, child)
    assert line.startswith("ros2 run tf2_ros static_transform_publisher --x ")
    assert f"--x {t[0, 3]:.6f}" in line and line.endswith("--child-frame-id "
                                                           "camera_color_optical_frame")


class _Refusing(SimCalibrationRobot):
    """The simulated arm behind an executor that answers every move with ``kind``."""

    def __init__(self, *args, kind: str, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.kind = kind

    def move(self, q):
        return self.kind, "executor disabled (dry run): planned, not moved"


def test_refusals(placed, tmp_path: Path) -> None:
    world, _ = placed
    arm = sim_arm(world)
    motion = MotionConfig()
    with pytest.raises(CalibrationRefused) as refused:  # executor not enabled
        run_calibration(_Refusing(world, arm, motion, kind="disabled"), arm, _setup(world),
                        motion)
    assert refused.value.kind == "robot" and "disabled" in str(refused.value)
    away = look_at_pose(CameraConfig())
    away[:3, :3] = Rotation.from_euler("x", 90, degrees=True).as_matrix() @ away[:3, :3]
    with pytest.raises(CalibrationRefused) as refused:  # the guess shows no board
        run_calibration(SimCalibrationRobot(world, arm, motion), arm,
                        _setup(world, camera=away), motion)
    assert refused.value.kind == "board"
    with pytest.raises(CalibrationRefused) as refused:  # too few poses for the solver
        run_calibration(SimCalibrationRobot(world, arm, motion), arm,
                        _setup(world, poses=3, solve=SolveConfig()), motion)
    assert refused.value.kind == "reach"
    # a refused calibration writes nothing: the previous file stays
    path = tmp_path / "camera_extrinsics.yaml"
    path.write_text("previous")
    with pytest.raises(ValueError, match="not an extrinsics file"):
        read_extrinsics(path)
    assert path.read_text() == "previous"
