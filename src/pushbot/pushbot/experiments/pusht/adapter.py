"""The Push-T adapter of ``pushbot eval pusht``: the push_core planner on ``gym_pusht/PushT-v0``.

The learned-pushing benchmark of Diffusion Policy (Chi et al. 2023): a disc pusher must push a
T-shaped block into a fixed goal pose in a 2-D pymunk world; success = the block covers more
than 95 % of the goal T; 300 control steps per episode. This adapter drives the env's own
dynamics, reward and success with push_core's *public* library API only
(:mod:`push_core.pushable`, :mod:`push_core.planner`, :mod:`push_core.transit`; a test parses
this module for private names) and writes LeRobot-style metrics.

Units, frames, the T and the agent's controller (the env as push_core sees it):
:mod:`pushbot.experiments.pusht.world`.

Each push is planned in closed loop from the observed pose (the state, or the pose fitted to
the 96 x 96 image, :mod:`pushbot.experiments.pusht.vision`), with the disc's position as the
start of the transit planner: the disc cannot lift, so it travels around the T to the approach
point, pushes, and the next push is planned from the new observation.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from push_core.planner import NoFeasiblePush, Planner, PushPlan
from push_core.pushable import Pusher, PushObject
from pushbot.experiments.pusht.world import (
    ENV_ID,
    METRES_PER_UNIT,
    MISSING,
    AgentModel,
    PushTFrames,
    make_tee,
    tee_body,
    timed_path,
)

#: Pusher-centre workspace margin inside the walls (env units): tracking error headroom.
WALL_MARGIN = 4.0
#: Pusher speeds, env units per control step (transit / pushing).
TRANSIT_SPEED = 45.0
PUSH_SPEED = 25.0
#: Rollouts with both contacts of a pusher in one of the T's inner corners (frictionless).
TWO_FACES = True
#: Extra clearance of the pusher from the T while it travels (env units), for tracking error.
TRANSIT_MARGIN = 4.0
#: ``--object-model``: ``env`` reads the T from the env's body (outline, COM, mass, moment,
#: friction); ``estimated`` perceives the outline and estimates the rest online
#: (:mod:`pushbot.experiments.pusht.estimated`), the env's bodies and shapes sealed.
OBJECT_MODELS = ("env", "estimated")
#: The pusher's radius (env units) with the estimated object model: the robot's own pusher, a
#: known fact of the setup (the env's agent shape stays sealed; a test checks it agrees).
PUSHER_RADIUS_UNITS = 15.0
#: Observation noise of the filter with the estimated model: the fit to the image (about 0.5
#: unit and 0.3 degrees rms) or the state (exact; a floor for the filter's conditioning).
PIXELS_SIGMA = (0.6, 0.4)
STATE_SIGMA = (0.1, 0.1)
#: Step back (env units) of the agent before perceiving when it hides or touches the block.
STEP_BACK = 40.0
#: From pixels, a goal fit whose mean absolute residual exceeds this (a good one leaves about
#: 0.02-0.05; the block hid much of the goal region) is fitted again at every planning step,
#: the best fit kept.
GOAL_REFIT_RESIDUAL = 0.1


# ------------------------------------------------------------------------------ episode
@dataclass
class EpisodeRecord:
    """One episode's outcome (LeRobot-style fields plus the planner's)."""

    seed: int
    success: bool
    steps: int
    max_reward: float
    max_coverage: float
    pushes: int
    planning_ms: list[float] = field(default_factory=list)
    failures: int = 0
    wall_s: float = 0.0
    #: ``--obs pixels``: position error (mm = env units) of the estimate each push was planned
    #: from, against the env's block pose (diagnostics only; never given to the planner).
    pose_error: list[float] = field(default_factory=list)
    #: Why the episode stopped early, if it did ("" = it ran to success or the step limit).
    error: str = ""
    #: ``--object-model estimated`` diagnostics against the true T (never given to the
    #: planner): mean and largest distance between the perceived and the true outline (mm),
    #: the COM error (mm) at the prior (the outline's centroid) and at the end, the final ``l``
    #: (mm) and ``m``, the position error (mm) of the goal fitted in the image (from pixels; the
    #: last fit, see :data:`GOAL_REFIT_RESIDUAL`).
    outline_error_mm: float | None = None
    outline_max_error_mm: float | None = None
    com_error_prior_mm: float | None = None
    com_error_mm: float | None = None
    l_mm: float | None = None
    m: float | None = None
    goal_error_mm: float | None = None


def _settings_planner(pusher: Pusher, obj: PushObject, seed: int) -> Planner:
    ws = ((7.0 + WALL_MARGIN) * METRES_PER_UNIT + pusher.radius,
          (504.0 - WALL_MARGIN) * METRES_PER_UNIT - pusher.radius)
    return pusher.planner(
        workspace=(ws, ws), k=3, lam=1.0, temperature=2.0, seed=seed,
        approach_clearance=0.008, min_push_length=0.005, max_push_length=0.08,
        substep=0.005, travel_weight=0.05, two_faces=TWO_FACES,
        transit_clearance=pusher.radius + TRANSIT_MARGIN * METRES_PER_UNIT)


class PushTRunner:
    """Runs episodes of one env (``obs`` ``state`` or ``pixels``; ``object_model`` ``env`` or
    ``estimated``)."""

    def __init__(self, obs: str = "state", max_steps: int = 300, object_model: str = "env"
                 ) -> None:
        os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # pygame without a display
        try:  # optional extra pushbot[pusht] (no rosdep key)
            import gym_pusht  # noqa: F401  (registers the env)
            import gymnasium as gym
        except ImportError as exc:
            raise ImportError(MISSING + str(exc)) from exc

        if obs not in ("state", "pixels"):
            raise ValueError(f"obs: expected 'state' or 'pixels', got {obs!r}")
        if object_model not in OBJECT_MODELS:
            raise ValueError(f"object_model: expected one of {OBJECT_MODELS}, got "
                             f"{object_model!r}")
        self.obs = obs
        self.object_model = object_model
        self.max_steps = int(max_steps)
        self.vision = None
        if object_model == "estimated":
            self._init_estimated(gym)
            return
        self.env = gym.make(ENV_ID, obs_type="state" if obs == "state" else "pixels_agent_pos",
                            max_episode_steps=self.max_steps)
        self.env.reset(seed=0)  # builds the pymunk space the T is read from
        self.obj, self.pusher, self.frames = make_tee(self.env)
        self.agent = AgentModel.of_env(self.env)
        self.control_hz = float(self.env.unwrapped.control_hz)
        self.goal = self.frames.object_pose(self.env.unwrapped.goal_pose)
        if obs == "pixels":
            from pushbot.experiments.pusht.vision import TeeFitter
            ring = tee_body(self.env)[0]
            self.vision = TeeFitter(ring, agent_radius=self.pusher.radius / METRES_PER_UNIT)

    def _estimator(self) -> object:
        """The EKF for ``--obs pixels``: known COM, ``l`` and friction 0 (:meth:`Pusher.estimator`),
        noise levels of the image fit (about 0.5 unit and 0.3 degrees rms) and of the model
        (about 1 unit per 8 cm push)."""
        return self.pusher.estimator(
            self.obj, position_sigma=0.6 * METRES_PER_UNIT, angle_sigma=math.radians(0.4),
            position_noise_min=0.2 * METRES_PER_UNIT, position_noise_per_metre=0.02,
            angle_noise_min=math.radians(0.2), angle_noise_per_metre=0.3)

    def _perceive(self, obs: object, ekf: object, push: PushPlan | None) -> NDArray[np.float64]:
        """Object pose (world, m) from a pixels observation: the EKF predicted through the last
        push gives the fit's start, the fitted pose updates the EKF."""
        agent = np.asarray(obs["agent_pos"], dtype=np.float64)
        if push is None or not ekf.initialized:
            body = self.vision.fit(obs["pixels"], agent, None)
            ekf.initialize(self.frames.object_pose(body))
        else:
            ekf.predict_push(push.approach, push.end)
            guess = self.frames.body_pose(ekf.state[:3])
            body = self.vision.fit(obs["pixels"], agent, guess)
            ekf.update_pose(self.frames.object_pose(body))
        return ekf.state[:3]

    def _init_estimated(self, gym: object) -> None:
        """The env for ``--object-model estimated``: images in both observation modes (the
        outline comes from the first one), the bodies and shapes sealed
        (:class:`pushbot.experiments.pusht.guard.SealedEnv`); the true T for the diagnostics
        from a second env that the episodes never see."""
        from pushbot.experiments.pusht.guard import SealedEnv

        truth_env = gym.make(ENV_ID)
        truth_env.reset(seed=0)
        ring, cog = tee_body(truth_env)[:2]
        truth_env.close()
        self.truth = (ring, cog)  # diagnostics only
        self.env = SealedEnv(gym.make(ENV_ID, obs_type="pixels_agent_pos",
                                      max_episode_steps=self.max_steps))
        self.env.reset(seed=0)
        self.pusher = Pusher(radius=PUSHER_RADIUS_UNITS * METRES_PER_UNIT)
        self.agent = AgentModel.of_env(self.env)
        self.control_hz = float(self.env.unwrapped.control_hz)
        self.obj = self.frames = self.goal = None

    def run(self, seed: int, frames: list | None = None) -> EpisodeRecord:
        """One episode with seed ``seed``; ``frames`` collects the rendered frames (video)."""
        if self.object_model == "estimated":
            return self._run_estimated(seed, frames)
        t_start = time.perf_counter()
        obs, info = self.env.reset(seed=seed)
        planner = _settings_planner(self.pusher, self.obj, seed)
        ekf = self._estimator() if self.obs == "pixels" else None
        rec = EpisodeRecord(seed=seed, success=False, steps=0, max_reward=0.0,
                            max_coverage=0.0, pushes=0)
        self.agent.reset(self._agent(obs))
        if frames is not None:
            frames.append(self.env.render())
        done, push = False, None
        while not done and rec.steps < self.max_steps:
            agent = self._agent(obs)
            if ekf is None:
                pose = self.frames.object_pose(np.asarray(obs, dtype=np.float64)[2:5])
            else:
                pose = self._perceive(obs, ekf, push)
                truth = self.frames.object_pose(info["block_pose"])  # diagnostics only
                rec.pose_error.append(1e3 * float(np.hypot(*(pose[:2] - truth[:2]))))
            push, obs, info, done = self._push_step(planner, self.obj.state(pose), agent, rec,
                                                    obs, info, frames)
        rec.wall_s = time.perf_counter() - t_start
        return rec

    def _run_estimated(self, seed: int, frames: list | None) -> EpisodeRecord:
        """One episode with the estimated object model (module
        :mod:`pushbot.experiments.pusht.estimated`)."""
        from pushbot.experiments.pusht import estimated as E

        t_start = time.perf_counter()
        obs, info = self.env.reset(seed=seed)
        rec = EpisodeRecord(seed=seed, success=False, steps=0, max_reward=0.0,
                            max_coverage=0.0, pushes=0)
        self.agent.reset(self._agent(obs))
        if frames is not None:
            frames.append(self.env.render())
        radius = PUSHER_RADIUS_UNITS
        away = E.agent_near(obs["pixels"], self._agent(obs), radius)
        done = False
        if away is not None:  # look before pushing: the disc hides or touches the block
            agent = self._agent(obs)
            back = np.clip(agent + STEP_BACK * away, 30.0, 482.0)
            obs, info, done = self._follow(np.stack([agent, back]) * METRES_PER_UNIT, None,
                                           rec, obs, info, frames)
        seen = E.perceive_tee(obs["pixels"], self._agent(obs), radius)
        s = METRES_PER_UNIT
        self.obj = PushObject.from_polygon(seen.outline * s)
        self.frames = PushTFrames(self.obj)
        b0 = np.asarray(info["block_pose"], dtype=np.float64)
        offset = E.compose(E.inverse(b0), seen.pose)  # the perceived frame in the state's
        truth_goal = E.compose(info["goal_pose"], offset)  # diagnostics (pixels) / goal (state)
        goal, goal_residual = truth_goal, 0.0
        if self.obs == "pixels":
            fitter = E.tracker(seen.outline, radius)
            goal, goal_residual = E.fit_goal(obs["pixels"], self._agent(obs), fitter)
        self.goal = self.frames.object_pose(goal)
        ring, cog = self.truth
        c, si = math.cos(b0[2]), math.sin(b0[2])
        rot = np.array([[c, -si], [si, c]])
        true_world = ring @ rot.T + b0[:2]
        rec.outline_error_mm, rec.outline_max_error_mm = E.outline_error(
            seen.outline + seen.pose[:2], true_world)
        true_com = (rot @ cog + b0[:2] - seen.pose[:2]) * s  # perceived frame, m
        ekf = self.pusher.estimator(
            self.obj, known_com=None, known_l=None, known_m=None,
            position_sigma=(PIXELS_SIGMA if self.obs == "pixels" else STATE_SIGMA)[0] * s,
            angle_sigma=math.radians((PIXELS_SIGMA if self.obs == "pixels"
                                      else STATE_SIGMA)[1]))
        planner = _settings_planner(self.pusher, self.obj, seed)
        push = None
        while not done and rec.steps < self.max_steps:
            agent = self._agent(obs)
            truth = self.frames.object_pose(E.compose(info["block_pose"], offset))
            if goal_residual > GOAL_REFIT_RESIDUAL:  # the goal was hidden: look again
                again, residual = E.fit_goal(obs["pixels"], agent, fitter)
                if residual < goal_residual:
                    goal, goal_residual = again, residual
                    self.goal = self.frames.object_pose(goal)
            if self.obs == "pixels":
                guess = None
                if ekf.initialized:
                    if push is not None:
                        ekf.predict_push(push.approach, push.end)
                    guess = self.frames.body_pose(ekf.state[:3])
                body = fitter.fit(obs["pixels"], agent, guess)
                observed = self.frames.object_pose(body)
            else:
                observed = truth
            if not ekf.initialized:
                ekf.initialize(observed)
            else:
                if self.obs == "state" and push is not None:
                    ekf.predict_push(push.approach, push.end)
                ekf.update_pose(observed)
            state = ekf.state
            if rec.com_error_prior_mm is None:
                rec.com_error_prior_mm = 1e3 * float(np.hypot(*(state[3:5] - true_com)))
            rec.pose_error.append(1e3 * float(np.hypot(*(state[:2] - truth[:2]))))
            push, obs, info, done = self._push_step(planner, state, agent, rec, obs, info,
                                                    frames)
        state = ekf.state
        if self.obs == "pixels":
            rec.goal_error_mm = float(np.hypot(*(goal[:2] - truth_goal[:2])))
        rec.com_error_mm = 1e3 * float(np.hypot(*(state[3:5] - true_com)))
        rec.l_mm, rec.m = 1e3 * float(state[5]), float(state[6])
        rec.wall_s = time.perf_counter() - t_start
        return rec

    def _agent(self, obs: object) -> NDArray[np.float64]:
        """The agent position (env units) of an observation."""
        if isinstance(obs, dict):
            return np.asarray(obs["agent_pos"], dtype=np.float64)
        return np.asarray(obs, dtype=np.float64)[0:2]

    def _escape(self, agent: NDArray[np.float64]) -> NDArray[np.float64]:
        """No plan: move the disc a little towards the workspace centre (world, m)."""
        centre = np.array([256.0, 256.0])
        d = centre - agent
        step = agent + 40.0 * d / max(float(np.linalg.norm(d)), 1e-9)
        return self.frames.to_world(np.stack([agent, step]))

    def _push_step(self, planner: Planner, state: NDArray[np.float64],
                   agent: NDArray[np.float64], rec: EpisodeRecord, obs: object, info: dict,
                   frames: list | None) -> tuple[PushPlan | None, object, dict, bool]:
        """Plan a push and its transit from ``state`` (7,) and follow them (or escape when no
        push is feasible); timed into ``rec.planning_ms``. Returns (push or None, obs, info,
        done)."""
        t0 = time.perf_counter()
        try:
            push = planner.plan(self.obj.outline, state, self.goal,
                                pusher=self.frames.to_world(agent))
            path = planner.transit(self.obj.outline, state[:3], self.frames.to_world(agent),
                                   push.approach)
        except NoFeasiblePush:
            push, path = None, None
        rec.planning_ms.append(1e3 * (time.perf_counter() - t0))
        if push is None or path is None:
            rec.failures += 1
            path, push = self._escape(agent), None
        obs, info, done = self._follow(path, push, rec, obs, info, frames)
        rec.pushes += push is not None
        return push, obs, info, done

    def _follow(self, path: NDArray[np.float64], push: PushPlan | None, rec: EpisodeRecord,
                obs: object, info: dict, frames: list | None) -> tuple[object, dict, bool]:
        """Drive the disc along the transit path (world, m) and then the push; returns the
        last observation and info and whether the episode ended."""
        way = np.asarray(path, dtype=np.float64) / METRES_PER_UNIT  # = PushTFrames.to_env
        speeds = [TRANSIT_SPEED] * (len(way) - 1)
        if push is not None:
            way = np.vstack([way, np.asarray(push.end, dtype=np.float64)[None] / METRES_PER_UNIT])
            speeds.append(PUSH_SPEED)
        targets = timed_path(way, np.array(speeds))[1:]
        targets = np.vstack([targets, targets[-1:], targets[-1:]])
        for k in range(len(targets) - 2):
            v2 = (targets[k + 2] - targets[k + 1]) * self.control_hz  # units per second
            action = self.agent.action(targets[k + 1], v2)
            obs, reward, terminated, truncated, info = self.env.step(action)
            rec.steps += 1
            rec.max_reward = max(rec.max_reward, float(reward))
            rec.max_coverage = max(rec.max_coverage, float(info["coverage"]))
            if frames is not None:
                frames.append(self.env.render())
            self.agent.step(action, self._agent(obs))
            rec.success = rec.success or bool(terminated)
            if terminated or truncated or rec.steps >= self.max_steps:
                return obs, info, True
        return obs, info, False

    def close(self) -> None:
        self.env.close()


# ------------------------------------------------------------------------------ evaluation
def wilson_interval(successes: int, n: int, z: float = 1.959963984540054
                    ) -> tuple[float, float]:
    """95 % Wilson score interval of a binomial proportion (``(0, 1)`` for ``n = 0``)."""
    if n <= 0:
        return 0.0, 1.0
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def summarize(records: Sequence[EpisodeRecord], config: dict) -> dict:
    """results.json: LeRobot-style metrics first, then the configuration and the episodes."""
    n = len(records)
    wins = sum(r.success for r in records)
    lo, hi = wilson_interval(wins, n)
    planning = [t for r in records for t in r.planning_ms]
    errors = [e for r in records for e in r.pose_error]

    def mean_of(name: str) -> float | None:
        values = [getattr(r, name) for r in records if getattr(r, name) is not None]
        return float(np.mean(values)) if values else None

    def p95_of(name: str) -> float | None:
        values = [getattr(r, name) for r in records if getattr(r, name) is not None]
        return float(np.percentile(values, 95)) if values else None

    return {
        "success_rate": wins / n if n else 0.0,
        "success_wilson_95": [lo, hi],
        "avg_max_reward": float(np.mean([r.max_reward for r in records])) if n else 0.0,
        "mean_max_coverage": float(np.mean([r.max_coverage for r in records])) if n else 0.0,
        "steps_mean": float(np.mean([r.steps for r in records])) if n else 0.0,
        "steps_mean_success": float(np.mean([r.steps for r in records if r.success]))
        if wins else 0.0,
        "pushes_mean": float(np.mean([r.pushes for r in records])) if n else 0.0,
        "planning_ms_median": float(np.median(planning)) if planning else 0.0,
        "pose_error_mm_median": float(np.median(errors)) if errors else None,
        "pose_error_mm_p95": float(np.percentile(errors, 95)) if errors else None,
        "episode_wall_s_mean": float(np.mean([r.wall_s for r in records])) if n else 0.0,
        "n_episodes": n,
        "episodes_with_error": sum(bool(r.error) for r in records),
        "outline_error_mm_mean": mean_of("outline_error_mm"),
        "outline_max_error_mm_mean": mean_of("outline_max_error_mm"),
        "outline_max_error_mm_p95": p95_of("outline_max_error_mm"),
        "com_error_prior_mm_mean": mean_of("com_error_prior_mm"),
        "com_error_mm_mean": mean_of("com_error_mm"),
        "com_error_mm_p95": p95_of("com_error_mm"),
        "l_mm_mean": mean_of("l_mm"),
        "m_mean": mean_of("m"),
        "goal_error_mm_mean": mean_of("goal_error_mm"),
        "config": config,
        "episodes": [asdict(r) for r in records],
    }


_RUNNER: PushTRunner | None = None


def _run_one(job: tuple[str, int, int, str | None, str]) -> EpisodeRecord:
    """Worker: one episode (a runner per process, reused); writes the video if asked."""
    global _RUNNER
    obs, max_steps, seed, video, model = job
    if _RUNNER is None or (_RUNNER.obs, _RUNNER.max_steps, _RUNNER.object_model) != \
            (obs, max_steps, model):
        _RUNNER = PushTRunner(obs, max_steps, model)
    frames: list | None = [] if video else None
    try:
        rec = _RUNNER.run(seed, frames)
    except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:  # a failed episode, not a
        # failed evaluation: recorded with its reason (the env is reset by the next episode)
        rec = EpisodeRecord(seed=seed, success=False, steps=0, max_reward=0.0,
                            max_coverage=0.0, pushes=0, error=f"{type(exc).__name__}: {exc}")
    if video and frames:
        write_video(Path(video), frames)
    return rec


def write_video(path: Path, frames: Sequence[np.ndarray], fps: int = 10) -> None:
    """RGB frames (H, W, 3) uint8 -> an mp4 (OpenCV's mp4v codec)."""
    import cv2

    path.parent.mkdir(parents=True, exist_ok=True)
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    try:
        for f in frames:
            writer.write(np.ascontiguousarray(f[:, :, ::-1]))
    finally:
        writer.release()


def _write(out: Path, result: dict) -> None:
    """``out/results.json``: the summary; while a run is under way, of the episodes so far
    (``n_episodes`` below ``config["episodes"]``), the seeds in order from ``seed0``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(result, indent=1) + "\n")


def progress_interval(episodes: int) -> int:
    """Episodes between two progress lines: about 20 lines per run, at least every 25
    episodes, every episode for short runs."""
    return max(1, min(25, episodes // 20))


def evaluate(episodes: int, seed0: int = 0, max_steps: int = 300, obs: str = "state",
             out: Path | None = None, video: int = 0, workers: int = 1,
             progress: bool = False, object_model: str = "env") -> dict:
    """Run ``episodes`` episodes with seeds ``seed0 ...``; return (and write to
    ``out/results.json``) the summary of :func:`summarize`."""
    if episodes < 1 or max_steps < 1 or workers < 1 or video < 0:
        raise ValueError("episodes, max-steps and workers must be >= 1, video >= 0")
    if object_model not in OBJECT_MODELS:
        raise ValueError(f"object_model: expected one of {OBJECT_MODELS}, got {object_model!r}")
    jobs = [(obs, max_steps, seed0 + i,
             str(out / "videos" / f"episode_{seed0 + i:04d}.mp4") if out and i < video else None,
             object_model)
            for i in range(episodes)]
    records: list[EpisodeRecord] = []
    every = progress_interval(episodes)
    started = time.monotonic()
    config = {"env": ENV_ID, "obs": obs, "episodes": episodes, "seed0": seed0,
              "max_steps": max_steps, "metres_per_unit": METRES_PER_UNIT,
              "object_model": object_model}
    if progress:
        model = "" if object_model == "env" else f", {object_model} object model"
        print(f"  {episodes} episodes ({obs}{model}, {workers} worker(s)); progress every "
              f"{every}", flush=True)
    if workers == 1:
        it = map(_run_one, jobs)
        pool = None
    else:
        pool = ProcessPoolExecutor(max_workers=workers)
        it = pool.map(_run_one, jobs, chunksize=4)
    try:
        for rec in it:
            records.append(rec)
            if len(records) % every == 0 and len(records) < episodes and out is not None:
                _write(out, summarize(records, config))  # a cut run keeps what it did
            if progress and (len(records) % every == 0 or len(records) == episodes):
                wins = sum(r.success for r in records)
                elapsed = time.monotonic() - started
                left = elapsed / len(records) * (episodes - len(records))
                print(f"  {len(records)}/{episodes} episodes, {wins} successes, "
                      f"{elapsed:.0f} s, about {left:.0f} s left", flush=True)
    finally:
        if pool is not None:
            pool.shutdown()
    result = summarize(records, config)
    if out is not None:
        _write(out, result)
    return result
