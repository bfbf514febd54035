"""pushbot eval estimator: one short pybullet episode, the report and the argument checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator import EKFConfig
from push_core.estimator.active import informative_push
from pushbot.experiments.estimator_episodes import run_physics_episode
from pushbot.experiments.estimator_evaluation import main


def test_physics_episode_starts_at_the_centroid_and_learns() -> None:
    episode = run_physics_episode("tri1", seed=3, n_pushes=4, config=EKFConfig(),
                                  position_noise=0.002, angle_noise=math.radians(1.5))
    assert episode.com.shape == (5, 2) and episode.nees.shape == (4,)
    # The COM starts at the area centroid, so the first error is |c_true|.
    assert episode.com_error[0] == pytest.approx(float(np.hypot(*episode.com_true)))
    assert episode.touched == 4
    assert np.all(np.isfinite(episode.l)) and np.all(episode.m > 0)


def test_push_policies_draw_the_same_candidates() -> None:
    """``random`` executes the first valid draw; ``active`` the most informative of several
    draws, so its first push differs but both learn; an unknown policy is refused."""
    kwargs = dict(config=EKFConfig(), position_noise=0.002, angle_noise=math.radians(1.5))
    active = run_physics_episode("butter", seed=5, n_pushes=3, policy="active", **kwargs)
    rand = run_physics_episode("butter", seed=5, n_pushes=3, policy="random", **kwargs)
    assert (active.policy, rand.policy) == ("active", "random")
    assert active.touched == rand.touched == 3
    np.testing.assert_array_equal(active.com_true, rand.com_true)  # same randomised object
    assert not np.allclose(active.com[1], rand.com[1])
    with pytest.raises(ValueError, match="policy"):
        run_physics_episode("butter", seed=5, n_pushes=1, policy="greedy", **kwargs)


def test_informative_push_is_collinear_and_points_into_the_object() -> None:
    from push_core.objects import load_object

    points, normals = load_object("butter").outline(0.002)
    rng = np.random.default_rng(0)
    pose = np.array([0.05, -0.02, 0.7])
    towards = np.array([-1.0, 0.0])
    for _ in range(20):
        start, contact, end = informative_push(points, normals, pose, rng)
        d = (end - start) / np.linalg.norm(end - start)
        off_line = d[0] * (contact - start)[1] - d[1] * (contact - start)[0]
        assert abs(off_line) < 1e-12
        assert 0.025 - 1e-9 <= np.linalg.norm(end - start) <= 0.055 + 1e-9
        start, _, end = informative_push(points, normals, pose, rng, towards=towards)
        assert (end - start) @ towards > 0.0  # recentring pushes move the object back


def test_cli_prints_the_report(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--objects", "hex", "--episodes", "1", "--pushes", "2", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "| hex | 1 |" in out and "NEES" in out and "ground truth + Gaussian noise" in out
    assert "does not exist" not in out


def test_perception_episode_compares_in_the_perception_frame() -> None:
    """Poses from rendered frames: the filter works in the perception's object frame (yaw
    relative to the first frame), so the true COM is the library COM turned by the first
    frame's true yaw, and the filter tracks the true relative orientation."""
    from push_core.geometry import rot2, wrap_angle

    episode = run_physics_episode("tri1", seed=3, n_pushes=2, config=EKFConfig(),
                                  position_noise=0.002, angle_noise=math.radians(1.5),
                                  observations="perception")
    assert episode.observations == "perception" and episode.missed == 0
    assert episode.touched == 2 and np.all(np.isfinite(episode.nis))
    # Same seed, same initial yaw as the gt-noise episode (the seeded draw comes first).
    theta0 = float(np.random.default_rng([3, sum(b"tri1")]).uniform(-np.pi, np.pi))
    np.testing.assert_allclose(episode.com_reference[0], rot2(theta0) @ episode.com_true,
                               atol=1e-3)  # the world settles the object by < 1 mrad
    assert episode.com_error[0] == pytest.approx(float(np.hypot(*episode.com_true)), abs=1e-9)
    # NEES compares the filter with the truth in that frame: a wrong frame (e.g. the absolute
    # yaw) would give an angle error of theta0 and a NEES in the thousands.
    assert abs(float(wrap_angle(theta0))) > 0.1
    assert np.all(episode.nees < 100.0), episode.nees


@pytest.mark.parametrize("argv", [["--observations", "camera"], ["--observations", ","],
                                  ["--episodes", "0"], ["--objects", "no_such_object"],
                                  ["--iterations", "0"], ["--push-policy", "greedy"],
                                  ["--push-policy", ","]])
def test_cli_rejects_what_it_cannot_do(argv: list[str]) -> None:
    assert main([*argv, "--no-progress"]) == 2
