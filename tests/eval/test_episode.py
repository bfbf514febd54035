"""In-process episodes (pushbot.experiments.inprocess): record contents, success from ground
truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pushbot.experiments.inprocess import run_trial, true_errors
from pushbot.runner.protocol import Trial

RECORD_KEYS = {"trial", "success", "steps", "end_error_xy", "end_error_theta", "com_error",
               "planning_ms", "poses_true", "poses_est", "pushes", "wall_s", "reason"}


def test_true_errors_modulo_symmetry():
    goal = np.array([0.1, 0.0, 0.0])
    # hex (order 6): 61 deg off is 1 deg off; without symmetry it stays 61 deg
    pose = np.array([0.1, 0.003, math.radians(61.0)])
    xy, th = true_errors(pose, goal, 6)
    assert xy == pytest.approx(0.003)
    assert th == pytest.approx(math.radians(1.0))
    assert true_errors(pose, goal, 1)[1] == pytest.approx(math.radians(61.0))
    # order 2: 179 deg off is 1 deg off
    assert true_errors(np.array([0.1, 0, math.radians(179)]), goal, 2)[1] == \
        pytest.approx(math.radians(1.0))


@pytest.mark.parametrize("index", [0, 7])
def test_gt_ana_trial_on_rect1_succeeds(index):
    trial = Trial(object="rect1", task="mixed", method="ana", k=1, state="gt", index=index)
    rec = run_trial(trial)
    assert RECORD_KEYS <= set(rec)
    assert rec["trial"] == trial.as_dict()
    assert rec["success"] and rec["reason"] == "goal reached"
    assert 1 <= rec["steps"] <= 30
    assert len(rec["poses_true"]) == len(rec["poses_est"]) == rec["steps"] + 1
    assert len(rec["pushes"]) == len(rec["planning_ms"]) == len(rec["poses_predicted"]) \
        == rec["steps"]
    # each push's predicted pose: the model's guess of poses_true[i + 1], nearer to it than
    # the pose before the push (rect1 with the true COM and friction)
    pred, true = np.asarray(rec["poses_predicted"]), np.asarray(rec["poses_true"])
    moved = np.linalg.norm(true[1:, :2] - true[:-1, :2], axis=1)
    missed = np.linalg.norm(pred[:, :2] - true[1:, :2], axis=1)
    assert np.all(missed < moved), (missed, moved)
    assert rec["com_error"] is None
    # gt: the estimate is the truth, and the end error is measured against the true goal
    np.testing.assert_allclose(rec["poses_est"], rec["poses_true"])
    goal = np.array(rec["poses_true"][0]) + trial.goal_offset()
    end = np.array(rec["poses_true"][-1])
    assert rec["end_error_xy"] == pytest.approx(math.hypot(*(goal[:2] - end[:2])))
    assert rec["end_error_xy"] <= 0.0075
    # the object started at the protocol's initial orientation
    assert rec["poses_true"][0][2] == pytest.approx(trial.initial_yaw, abs=1e-3)
    # robot time: the simulated pusher's seconds; each cycle holds one push (20 mm/s) at least
    assert len(rec["cycle_s"]) == rec["steps"] - 1
    lengths = [math.dist(p[0], p[2]) for p in rec["pushes"]]
    assert all(c >= length / 0.02 for c, length in zip(rec["cycle_s"], lengths, strict=False))
    assert rec["robot_time_s"] >= sum(lengths) / 0.02 and rec["robot_time_s"] >= \
        sum(rec["cycle_s"])


def test_gt_trial_is_deterministic():
    trial = Trial(object="tri1", task="rotation", method="ana", k=3, state="gt", index=3)
    a, b = run_trial(trial), run_trial(trial)
    for key in ("success", "steps", "end_error_xy", "end_error_theta", "pushes", "poses_true"):
        assert a[key] == b[key], key


def test_max_steps_ends_the_episode_and_fails():
    trial = Trial(object="butter", task="translation", method="rdn", k=1, state="gt",
                  max_steps=1)
    rec = run_trial(trial)
    assert rec["steps"] == 1 and rec["reason"] == "max steps"
    assert not rec["success"]
    assert rec["end_error_xy"] > 0.05  # 20 cm task, one push


def test_filter_trial_perceives_estimates_and_reports_com_error():
    trial = Trial(object="butter", task="mixed", method="ana", k=3, state="filter",
                  com="random", max_steps=3, index=2)
    rec = run_trial(trial)
    assert rec["steps"] >= 1
    assert rec["perception_failures"] == 0
    # first perceived pose: yaw 0 in the episode frame, position close to the truth
    est0, true0 = np.array(rec["poses_est"][0]), np.array(rec["poses_true"][0])
    assert est0[2] == 0.0
    assert np.hypot(*(est0[:2] - true0[:2])) < 0.003
    # later estimates: yaw since the start tracks the true rotation
    est, true = np.array(rec["poses_est"][-1]), np.array(rec["poses_true"][-1])
    err = (est[2] + true0[2] - true[2] + math.pi / 2) % math.pi - math.pi / 2  # butter: order 2
    assert abs(err) < math.radians(3)
    assert np.hypot(*(est[:2] - true[:2])) < 0.005
    assert rec["com_error"] is not None and 0.0 <= rec["com_error"] < 0.05


def test_filter_without_com_estimation_keeps_the_com_at_the_centre():
    trial = Trial(object="tri1", task="mixed", method="ana", state="filter", com="random",
                  estimate_com=False, max_steps=2, index=4)
    rec = run_trial(trial)
    assert rec["steps"] >= 1
    # the pinned COM (0, 0) is off by exactly the randomised true COM's distance from the
    # centroid, which is > 0 for a random COM
    assert rec["com_error"] > 1e-4


def test_pushnet_trial_runs():
    trial = Trial(object="rect1", task="mixed", method="pushnet", state="gt", region="large")
    rec = run_trial(trial)
    assert rec["steps"] >= 1 and rec["reason"] in ("goal reached", "max steps")
    assert rec["success"] == (rec["end_error_xy"] <= 0.05
                              and rec["end_error_theta"] <= math.radians(10))


def test_bad_trial_type():
    with pytest.raises(ValueError, match="Trial"):
        run_trial({"object": "rect1"})
