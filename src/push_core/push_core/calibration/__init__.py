"""Camera-to-world calibration with the arm: the board, its detection and the solver."""

from push_core.calibration.charuco import BoardSpec as BoardSpec
from push_core.calibration.charuco import detect_board as detect_board
from push_core.calibration.handeye import CalibrationRefused as CalibrationRefused
from push_core.calibration.handeye import HandEyeResult as HandEyeResult
from push_core.calibration.handeye import SolveConfig as SolveConfig
from push_core.calibration.handeye import View as View
from push_core.calibration.handeye import solve_eye_to_hand as solve_eye_to_hand
from push_core.calibration.poses import board_facing_poses as board_facing_poses
from push_core.calibration.poses import camera_guess as camera_guess
