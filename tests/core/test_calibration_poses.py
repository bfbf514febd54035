"""push_core.calibration.poses: the generated poses show the board with rotation spread, and
the camera guess of one view."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from push_core.calibration.charuco import BoardSpec
from push_core.calibration.handeye import SolveConfig, rotation_spread_deg
from push_core.calibration.poses import board_facing_poses, camera_guess

K = np.array([[500.0, 0.0, 330.0], [0.0, 510.0, 250.0], [0.0, 0.0, 1.0]])
SIZE = (640, 480)
BOARD = BoardSpec()
#: A camera on the table's left, looking down at 50 degrees; a board on the tool's rod side.
CAMERA = np.eye(4)
CAMERA[:3, :3] = Rotation.from_euler("xyz", [-140.0, 0.0, 180.0], degrees=True).as_matrix()
CAMERA[:3, 3] = (0.0, 0.55, 0.6)
MOUNT = np.eye(4)
MOUNT[:3, :3] = np.diag([1.0, -1.0, -1.0])
MOUNT[:3, 3] = (0.025, 0.075, 0.005)


def test_generated_poses_show_the_board_and_spread_over_three_axes() -> None:
    poses = board_facing_poses(CAMERA, MOUNT, BOARD.corners.mean(axis=0), K, SIZE, 15, seed=0)
    centres = []
    for tool in poses:
        board = np.linalg.inv(CAMERA) @ tool @ MOUNT
        c = board[:3, :3] @ BOARD.corners.mean(axis=0) + board[:3, 3]
        centres.append(K @ (c / c[2]))
        # The board faces the camera: its z within the tilt (20 deg and a third) of the axis.
        assert np.degrees(np.arccos(board[2, 2])) < 20.0 * (1 + np.sqrt(2) / 3) + 1e-9
    uv = np.array(centres)[:, :2]
    assert np.all((uv >= 0.25 * np.array(SIZE)) & (uv <= 0.75 * np.array(SIZE)))
    spread = rotation_spread_deg(np.stack([t[:3, :3] for t in poses]))
    assert spread[2] > SolveConfig().min_spread_deg


def test_the_camera_guess_of_one_exact_view_is_the_camera() -> None:
    tool = np.eye(4)
    tool[:3, :3] = Rotation.from_euler("xyz", [170.0, -40.0, 5.0], degrees=True).as_matrix()
    tool[:3, 3] = (0.1, -0.05, 0.3)
    camera_board = np.linalg.inv(CAMERA) @ tool @ MOUNT
    np.testing.assert_allclose(camera_guess(tool, MOUNT, camera_board), CAMERA, atol=1e-12)
