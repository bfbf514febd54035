"""The Push-T adapter (``pushbot eval pusht``) against the real gym-pusht env (no mock).

Frames and units (a pose round-trips; a known push moves the block as the env does), the agent
controller model, the image fit, that whole episodes reach success from state and pixels, and
that the adapter uses only public push_core API.
"""

import ast
import importlib
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gym_pusht")

from pushbot.experiments.pusht import adapter as P  # noqa: E402
from pushbot.experiments.pusht import world as W  # noqa: E402

ADAPTER_FILES = [Path(P.__file__),
                 Path(P.__file__).with_name("vision.py"),
                 Path(P.__file__).with_name("estimated.py"),
                 Path(P.__file__).with_name("guard.py"),
                 Path(P.__file__).with_name("cli.py"),
                 Path(W.__file__)]


@pytest.fixture(scope="module")
def runner() -> P.PushTRunner:
    r = P.PushTRunner("state")
    yield r
    r.close()


def _reset_to(runner: P.PushTRunner, agent, body) -> np.ndarray:
    """Reset the env with the agent at ``agent`` and the block's body frame at ``body``
    (env units). gym-pusht sets the position and *then* the angle about the centre of gravity
    (its legacy order), so the position handed in is corrected for that rotation."""
    cog = np.array(tuple(runner.env.unwrapped.block.center_of_gravity))
    c, s = math.cos(body[2]), math.sin(body[2])
    position = np.asarray(body[:2]) - cog + np.array([c * cog[0] - s * cog[1],
                                                      s * cog[0] + c * cog[1]])
    obs, _ = runner.env.reset(options={"reset_to_state": [agent[0], agent[1], position[0],
                                                          position[1], body[2]]})
    return obs


def test_tee_as_the_env_builds_it(runner: P.PushTRunner) -> None:
    obj = runner.obj
    assert obj.shape.area == pytest.approx((120 * 30 + 30 * 90) * 1e-6)  # bar + stem
    # area centroid (0, 40.71) of the body frame; pymunk's COG (0, 45) is 4.29 mm along the stem
    assert obj.origin == pytest.approx([0.0, -0.04071428], abs=1e-7)
    assert obj.com == pytest.approx([0.0, 0.045 - 0.04071428], abs=1e-7)
    assert obj.friction == 0.0  # pymunk's default shape friction: frictionless contact
    assert obj.limit_surface == pytest.approx(math.sqrt(3000.0) * 1e-3)
    assert runner.pusher.radius == pytest.approx(0.015)


def test_pose_round_trips(runner: P.PushTRunner) -> None:
    rng = np.random.default_rng(0)
    for body in rng.uniform([50, 50, -np.pi], [450, 450, np.pi], size=(20, 3)):
        pose = runner.frames.object_pose(body)
        assert runner.frames.body_pose(pose) == pytest.approx(body, abs=1e-9)
        # the object frame origin is the area centroid: the mean of the T's world polygon
        world = runner.obj.world_polygon(pose)
        assert np.isclose(np.ptp(world, axis=0).max(), 0.130, atol=0.011)


def test_goal_is_the_env_goal(runner: P.PushTRunner) -> None:
    goal_body = runner.env.unwrapped.goal_pose
    assert runner.frames.body_pose(runner.goal) == pytest.approx(goal_body, abs=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_planned_push_moves_the_block_as_the_env_does(runner: P.PushTRunner,
                                                        seed: int) -> None:
    """Place the disc at a planned push's approach point, drive it along the push line in the
    real env and compare the block's pose with push_core's prediction (model + frames)."""
    obs, _ = runner.env.reset(seed=seed)
    body = np.asarray(obs[2:5], dtype=float)
    pose = runner.frames.object_pose(body)
    planner = P._settings_planner(runner.pusher, runner.obj, seed)
    plan = planner.plan(runner.obj.outline, runner.obj.state(pose), runner.goal)
    start = runner.frames.to_env(plan.approach)
    obs = _reset_to(runner, start, body)
    assert obs[2:5] == pytest.approx(body, abs=1e-6)
    end = runner.frames.to_env(plan.end)
    n = int(math.ceil(np.linalg.norm(end - start) / 2.0))
    for i in range(1, n + 1):
        obs, *_ = runner.env.step(start + (end - start) * i / n)
    for _ in range(10):
        obs, *_ = runner.env.step(end)
    moved = runner.frames.object_pose(obs[2:5])
    assert np.hypot(*(moved[:2] - pose[:2])) > 0.01  # it did move
    assert np.hypot(*(moved[:2] - plan.predicted_pose[:2])) < 0.003  # 3 mm for an 8 cm push
    assert abs(math.remainder(moved[2] - plan.predicted_pose[2], 2 * math.pi)) < math.radians(2.0)


def test_agent_model_replicates_the_pd_control(runner: P.PushTRunner) -> None:
    obs, info = runner.env.reset(seed=3)
    model = W.AgentModel.of_env(runner.env)
    model.reset(obs[:2])
    rng = np.random.default_rng(1)
    for action in rng.uniform(30, 480, size=(8, 2)):
        obs, _, _, _, info = runner.env.step(action)
        model.step(action)
        assert model.x == pytest.approx(obs[:2], abs=1e-6)
        assert model.v == pytest.approx(info["vel_agent"], abs=1e-6)


def test_timed_path_hits_every_waypoint() -> None:
    way = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 25.0]])
    t = W.timed_path(way, np.array([4.0, 10.0]))
    for w in way:
        assert np.min(np.linalg.norm(t - w, axis=1)) < 1e-12
    steps = np.linalg.norm(np.diff(t, axis=0), axis=1)
    assert steps[:3].max() <= 4.0 + 1e-12 and steps.max() <= 10.0 + 1e-12


def test_an_episode_reaches_success_from_state(runner: P.PushTRunner) -> None:
    rec = runner.run(seed=0)
    assert rec.success and rec.steps < 300 and rec.max_reward == 1.0
    assert rec.max_coverage > 0.95 and rec.failures == 0


@pytest.mark.slow
def test_image_fit_is_sub_pixel() -> None:
    r = P.PushTRunner("pixels")
    try:
        for seed in range(3):
            obs, info = r.env.reset(seed=seed)
            truth = info["block_pose"]
            fitted = r.vision.fit(obs["pixels"], obs["agent_pos"], None)  # no prior
            assert np.hypot(*(fitted[:2] - truth[:2])) < 1.5  # render pixels (96 px image: 5.3)
            assert abs(math.remainder(fitted[2] - truth[2], 2 * math.pi)) < math.radians(1.0)
    finally:
        r.close()


@pytest.mark.slow
def test_an_episode_reaches_success_from_pixels() -> None:
    r = P.PushTRunner("pixels")
    try:
        rec = r.run(seed=4)
    finally:
        r.close()
    assert rec.success and rec.steps < 300
    assert max(rec.pose_error) < 2.0  # mm (= render pixels) at every planning step


@pytest.mark.slow
def test_evaluate_writes_lerobot_metrics(tmp_path: Path) -> None:
    result = P.evaluate(2, seed0=0, obs="state", out=tmp_path, video=1)
    keys = list(result)
    assert keys[:5] == ["success_rate", "success_wilson_95", "avg_max_reward",
                        "mean_max_coverage", "steps_mean"]
    assert keys[-1] == "episodes" and len(result["episodes"]) == 2
    assert (tmp_path / "results.json").is_file()
    assert (tmp_path / "videos" / "episode_0000.mp4").stat().st_size > 10_000


def test_evaluate_reports_progress_from_the_start(capsys) -> None:
    # A long run (the README's 500 episodes) says at once what it runs and then how far it is.
    assert [P.progress_interval(n) for n in (1, 2, 40, 100, 500, 5000)] == [1, 1, 2, 5, 25, 25]
    P.evaluate(2, seed0=0, max_steps=3, obs="state", progress=True)
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "  2 episodes (state, 1 worker(s)); progress every 1"
    assert [line.split(",")[0] for line in lines[1:]] == ["  1/2 episodes", "  2/2 episodes"]
    assert all("s left" in line for line in lines[1:])


def test_wilson_interval() -> None:
    lo, hi = P.wilson_interval(500, 500)
    assert hi == 1.0 and lo == pytest.approx(0.99238, abs=1e-4)
    lo, hi = P.wilson_interval(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.27753, abs=1e-4)


def test_adapter_uses_only_public_push_core_api() -> None:
    """Library ergonomics: the adapter imports from push_core only names in a module's
    ``__all__`` and touches no ``_private`` attribute of anything but itself."""
    offenders = []
    for path in ADAPTER_FILES:
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("push_core"):
                module = importlib.import_module(node.module)
                public = set(getattr(module, "__all__", ()))
                offenders += [f"{path.name}: {node.module}.{a.name}" for a in node.names
                              if a.name.startswith("_") or a.name not in public]
            elif isinstance(node, ast.Import):
                offenders += [f"{path.name}: import {a.name}" for a in node.names
                              if a.name.startswith("push_core") and "._" in a.name]
            elif isinstance(node, ast.Attribute) and node.attr.startswith("_") \
                    and not node.attr.startswith("__"):
                owner = node.value
                if not (isinstance(owner, ast.Name) and owner.id in ("self", "P")):
                    offenders.append(f"{path.name}:{node.lineno}: .{node.attr}")
    assert not offenders, offenders
