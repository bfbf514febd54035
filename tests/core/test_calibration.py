"""push_core.calibration, the package's public face: generated poses, their exact corners and
the solve, through the names the package exports."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from push_core.calibration import BoardSpec, View, board_facing_poses, solve_eye_to_hand

K = np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]])


def test_generated_poses_and_their_exact_corners_recover_the_camera() -> None:
    board = BoardSpec()
    camera = np.eye(4)
    camera[:3, :3] = Rotation.from_euler("xyz", [-130.0, 3.0, 85.0], degrees=True).as_matrix()
    camera[:3, 3] = (0.5, 0.05, 0.6)
    mount = np.eye(4)
    mount[:3, :3] = np.diag([1.0, -1.0, -1.0])
    mount[:3, 3] = (0.02, 0.08, 0.005)
    views = []
    for tool in board_facing_poses(camera, mount, board.corners.mean(axis=0), K, (640, 480), 12,
                                   seed=4):
        seen = np.linalg.inv(camera) @ tool @ mount
        px, _ = cv2.projectPoints(board.corners, cv2.Rodrigues(seen[:3, :3])[0], seen[:3, 3],
                                  K, None)
        views.append(View(tool, np.arange(len(board.corners)), px.reshape(-1, 2)))
    result = solve_eye_to_hand(views, board.corners, K)
    np.testing.assert_allclose(result.world_camera, camera, atol=1e-6)
    np.testing.assert_allclose(result.tool_board, mount, atol=1e-6)
