"""push_core.calibration.poses: the generated poses show the board with rotation spread, and
the camera guess of one view."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from push_core.calibration.charuco import BoardSpec
from push_core.calibration.handeye import SolveConfig, rotation_spread_deg
from push_core.calibration.poses import board_facing_poses, camera_guess

K = np.array([[615.0, 0.0, 319.5], [0.0, 615.0, 239.5], [0.0, 0.0, 1.0]])
SIZE = (640, 480)
BOARD = BoardSpec()


def _pose(rotation: np.ndarray, translation) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = rotation
    t[:3, 3] = translation
    return t


CAMERA = _pose(Rotation.from_euler("xyz", [-145.0, 0.0, 90.0], degrees=True).as_matrix(),
               [0.49, 0.0, 0.66])
MOUNT = _pose(Rotation.from_euler("xyz", [10.0, -5.0, 30.0], degrees=True).as_matrix(),
              [0.06, -0.02, 0.04])


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
    tool = _pose(Rotation.from_euler("xyz", [170.0, -40.0, 5.0], degrees=True).as_matrix(),
                 [0.1, -0.05, 0.3])
    camera_board = np.linalg.inv(CAMERA) @ tool @ MOUNT
    np.testing.assert_allclose(camera_guess(tool, MOUNT, camera_board), CAMERA, atol=1e-12)
