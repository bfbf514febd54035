"""push_core.episode_record: the true end errors and success, orientation modulo the object's
symmetry (a disc's not counted), and the robot's time of an episode."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.episode_record import end_score, robot_times, true_errors
from push_core.objects import load_object


def test_end_score_counts_orientation_modulo_symmetry_and_not_for_a_disc() -> None:
    hexagon, disc = load_object("hex").polyline(), load_object("ellip1").polyline()
    goal = np.array([0.1, 0.0, 0.0])
    # hex (order 6): 61 deg off is 1 deg off
    xy, th = true_errors(np.array([0.1, 0.002, math.radians(61.0)]), goal, 6)
    assert xy == pytest.approx(0.002) and th == pytest.approx(math.radians(1.0))
    s = end_score(hexagon, [0.1, 0.0, math.radians(8.0)], goal, (0.0075, math.radians(5.0)))
    assert not s["success"] and not s["orientation_ignored"]
    s = end_score(disc, [0.1, 0.0, math.radians(80.0)], goal, (0.0075, math.radians(5.0)))
    assert s["success"] and s["orientation_ignored"]
    assert s["end_error_theta"] == pytest.approx(math.radians(90.0 - 80.0))  # order 12


def test_robot_times() -> None:
    times = robot_times(10.0, [10.5, 14.0, 18.5], 23.0)
    assert times == {"robot_time_s": 13.0, "cycle_s": [3.5, 4.5]}
    assert robot_times(4.0, [], 4.0) == {"robot_time_s": 0.0, "cycle_s": []}
    for args in ((10.0, [9.0], 20.0), (10.0, [12.0, 11.0], 20.0), (10.0, [12.0], 11.0),
                 (math.nan, [], 1.0)):
        with pytest.raises(ValueError, match="in order"):
            robot_times(*args)
