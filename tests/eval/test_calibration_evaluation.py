"""``pushbot eval calibrate``'s placements and summary (the runs themselves are the
``calibrate`` benchmark's; the procedure is tested in tests/sim/test_calibration_procedure.py)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pushbot.experiments.calibration_evaluation import SHIFT, TURN_DEG, placement, summary
from sim_bridge.camera import CameraConfig, look_at_pose


def test_placements_stay_within_the_ranges_and_repeat_from_the_seed() -> None:
    default = look_at_pose(CameraConfig())
    for trial in range(30):
        t = placement(4, trial)
        assert np.all(np.abs(t[:3, 3] - default[:3, 3]) <= SHIFT)
        turn = Rotation.from_matrix(t[:3, :3] @ default[:3, :3].T).magnitude()
        assert np.degrees(turn) <= TURN_DEG + 1e-9
    np.testing.assert_array_equal(placement(4, 7), placement(4, 7))
    assert not np.allclose(placement(4, 7), placement(5, 7))


def test_summary_counts_refusals_and_pairs() -> None:
    trials = [{"trial": 0, "noise": 0.0, "position_error_mm": 0.2, "rotation_error_deg": 0.01,
               "poses": 16, "robot_time_s": 12.0},
              {"trial": 0, "noise": 3.0, "position_error_mm": 0.4, "rotation_error_deg": 0.03,
               "poses": 18, "robot_time_s": 14.0},
              {"trial": 1, "noise": 0.0, "refused": "board: not seen", "robot_time_s": 1.0}]
    episodes = [{"trial": 0, "true": {"success": True}, "calibrated": {"success": False}}]
    s = summary(trials, episodes)
    assert (s["calibrations"], s["refused"]) == (3, 1)
    assert abs(s["median_position_error_mm"] - 0.3) < 1e-12
    assert (s["max_poses"], s["max_robot_time_s"]) == (18.0, 14.0)
    assert (s["success_true"], s["success_calibrated"], s["discordant"]) == (1, 0, 1)
