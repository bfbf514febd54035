"""Push-T with the object unknown (``--object-model estimated``), on the real env.

The outline perceived in the 96 x 96 image against the true T (stated tolerance), the goal
fitted in the image, the perceived frame's pose algebra, the seal on the env's bodies and
shapes (it trips on a read from outside the env; episodes run under it) and that episodes with
the estimated model succeed from state and from pixels.
"""

import math

import numpy as np
import pytest

pytest.importorskip("gym_pusht")

import gymnasium as gym  # noqa: E402

from pushbot.experiments.pusht import adapter as P  # noqa: E402
from pushbot.experiments.pusht import estimated as E  # noqa: E402
from pushbot.experiments.pusht import world as W  # noqa: E402
from pushbot.experiments.pusht.guard import EnvInternalsAccess, Sealed, SealedEnv  # noqa: E402
from pushbot.experiments.pusht.vision import fit_outline  # noqa: E402

#: Stated tolerance of the perceived outline against the true T (env units = mm) on the seeds
#: below: the mean distance between the two outlines and the largest (Hausdorff). Over the
#: first frames of seeds 0-399 the mean was 0.58 mm median, 1.04 mm 95th percentile, 1.64 mm at
#: most, the largest 2.7 / 5.7 / 13 mm (a corner hidden by the agent disc or cut by the walls);
#: the benchmark's figures are in docs/results/eval_pusht.md.
OUTLINE_MEAN_TOL = 1.0
OUTLINE_MAX_TOL = 6.0


@pytest.fixture(scope="module")
def truth():
    """The env (not sealed: the test's ground truth) and the true T (body frame, units)."""
    env = gym.make(W.ENV_ID, obs_type="pixels_agent_pos")
    env.reset(seed=0)
    ring, cog = W.tee_body(env)[:2]
    yield env, ring, cog
    env.close()


def _placed(ring, pose):
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return ring @ np.array([[c, s], [-s, c]]) + pose[:2]


def test_pose_algebra_by_hand() -> None:
    a, b = np.array([1.0, 2.0, math.pi / 2]), np.array([3.0, 0.0, 0.25])
    # b's x axis along a's y axis: 3 units along +y from (1, 2)
    assert E.compose(a, b) == pytest.approx([1.0, 5.0, math.pi / 2 + 0.25])
    assert E.compose(E.inverse(a), a) == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    assert E.compose(a, E.inverse(a)) == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    assert E.inverse([0.0, 0.0, 1.0]) == pytest.approx([0.0, 0.0, -1.0])


def test_outline_error_by_hand() -> None:
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    mean, largest = E.outline_error(square + [0.5, 0.0], square)
    # two sides coincide (0 off over their overlap), two are 0.5 apart: about 0.25 on average
    assert largest == pytest.approx(0.5, abs=1e-9)
    assert 0.2 < mean < 0.3
    assert E.outline_error(square, square) == pytest.approx((0.0, 0.0), abs=1e-12)


@pytest.mark.parametrize("seed", [0, 2, 3, 7, 8])
def test_outline_from_the_image_is_within_tolerance_of_the_true_tee(truth, seed) -> None:
    env, ring, _ = truth
    obs, info = env.reset(seed=seed)
    poly, residual = fit_outline(obs["pixels"], obs["agent_pos"])
    mean, largest = E.outline_error(poly, _placed(ring, info["block_pose"]))
    assert mean < OUTLINE_MEAN_TOL and largest < OUTLINE_MAX_TOL, (mean, largest)
    assert 8 <= len(poly) <= 10  # the T's 8 corners (a rounded corner may keep one more)
    assert residual < 0.05


@pytest.mark.slow
def test_goal_is_fitted_in_the_image(truth) -> None:
    env, ring, _ = truth
    obs, info = env.reset(seed=3)
    seen = E.perceive_tee(obs["pixels"], obs["agent_pos"], P.PUSHER_RADIUS_UNITS)
    goal, _ = E.fit_goal(obs["pixels"], obs["agent_pos"],
                         E.tracker(seen.outline, P.PUSHER_RADIUS_UNITS))
    # the perceived frame's true goal: its pose in the T's body frame, placed at the goal
    offset = E.compose(E.inverse(info["block_pose"]), seen.pose)
    expected = E.compose(info["goal_pose"], offset)
    assert np.hypot(*(goal[:2] - expected[:2])) < 2.0  # units (= mm); a pixel is 5.3
    assert abs(math.remainder(goal[2] - expected[2], 2 * math.pi)) < math.radians(1.5)
    # seed 21 starts with the block over most of the goal region: the fit says so by its
    # residual, which makes the runner fit the goal again at later frames (the episode test)
    obs, info = env.reset(seed=21)
    seen = E.perceive_tee(obs["pixels"], obs["agent_pos"], P.PUSHER_RADIUS_UNITS)
    _, residual = E.fit_goal(obs["pixels"], obs["agent_pos"],
                             E.tracker(seen.outline, P.PUSHER_RADIUS_UNITS))
    assert residual > P.GOAL_REFIT_RESIDUAL


def test_the_pusher_radius_is_the_envs_agent(truth) -> None:
    env, _, _ = truth
    assert P.PUSHER_RADIUS_UNITS == W.tee_body(env)[5]


def test_the_seal_trips_on_a_read_from_outside_the_env() -> None:
    env = SealedEnv(gym.make(W.ENV_ID, obs_type="pixels_agent_pos"))
    try:
        obs, info = env.reset(seed=1)
        u = env.unwrapped
        for name in ("block", "agent", "space"):
            assert isinstance(u.__dict__[name], Sealed)
        with pytest.raises(EnvInternalsAccess, match="block.center_of_gravity is sealed"):
            _ = u.block.center_of_gravity
        with pytest.raises(EnvInternalsAccess, match="block.shapes"):
            W.tee_body(env)
        with pytest.raises(EnvInternalsAccess, match="agent.position"):
            u.agent.position = (100.0, 100.0)
        with pytest.raises(EnvInternalsAccess):
            list(u._block_shapes)
        # the env's own code still runs through the seal: it steps, reports and renders
        before = info["block_pose"]
        for _ in range(20):
            obs, _, _, _, info = env.step(np.asarray(before[:2], dtype=np.float32))
        assert not np.allclose(info["block_pose"], before)  # the agent pushed it
        assert env.render().shape == (680, 680, 3)
        # a new reset builds new bodies: sealed again
        env.reset(seed=2)
        with pytest.raises(EnvInternalsAccess):
            _ = env.unwrapped.block.mass
    finally:
        env.close()


# pixels seed 21: the goal hidden by the block at the start (fitted again later)
@pytest.mark.slow
@pytest.mark.parametrize("obs,seeds", [("state", (0, 1, 2)), ("pixels", (3, 21))])
def test_estimated_model_episodes_succeed_under_the_seal(obs, seeds) -> None:
    runner = P.PushTRunner(obs, object_model="estimated")
    try:
        assert isinstance(runner.env, SealedEnv)
        for seed in seeds:
            rec = runner.run(seed)
            assert isinstance(runner.env.unwrapped.__dict__["block"], Sealed)
            assert rec.success and rec.steps < 300 and rec.error == "", rec
            assert rec.outline_error_mm < OUTLINE_MEAN_TOL
            assert rec.com_error_mm is not None and rec.l_mm > 0.0
            assert 0.05 <= rec.m <= 1.2  # the filter's clip range of the robot graph
            if obs == "pixels":
                assert rec.goal_error_mm < 2.0 and max(rec.pose_error) < 3.0
            else:
                assert rec.goal_error_mm is None
    finally:
        runner.close()


@pytest.mark.slow
def test_evaluate_records_the_object_model(tmp_path) -> None:
    result = P.evaluate(1, seed0=2, obs="state", out=tmp_path, object_model="estimated")
    assert result["config"]["object_model"] == "estimated"
    assert result["success_rate"] == 1.0
    assert result["outline_error_mm_mean"] < OUTLINE_MEAN_TOL
    assert result["com_error_mm_mean"] is not None
    with pytest.raises(ValueError, match="object_model"):
        P.evaluate(1, object_model="exact")
