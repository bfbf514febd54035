"""``pushbot eval calibrate``: the calibration against the simulator's truth, and what it does to
pushing.

Per trial ``i`` (seeded from ``--seed`` and ``i``): the camera placed at the default viewpoint
moved by up to 5 cm per axis and rotated by up to 5 degrees (uniform), the simulated arm with
the board on its tool (``sim_bridge.world.PushWorld``, arm mode, ``calibration_board``), the
procedure of ``pushbot calibrate`` (:func:`pushbot.runner.calibration.run_calibration`; the
moves planned and checked by the executor's joint-goal planner, then set in the world:
:class:`pushbot.experiments.calibration_sim.SimCalibrationRobot`) without and with colour
noise (``--noise``, 8-bit levels, Gaussian per pixel and channel). The camera's guess is the
default viewpoint, the board's mounting as designed is the simulated one 1 cm and 2 degrees
off. Each calibration's errors are against the placed camera (position, mm; rotation angle,
deg).

Then, for the first ``--episodes`` trials, one pushing episode (``pushbot eval push``'s
in-process loop, :func:`pushbot.experiments.inprocess.run_trial`, the ``filter`` state source:
rendered frames, segmentation, EKF) twice in the same scene and goal: perception using the
true extrinsics, and the noisy calibration's (paired).

``DIR/results.json``: ``trials`` (``trial``, ``noise``, ``position_error_mm``,
``rotation_error_deg``, ``poses``, ``robot_time_s``, ``rms_px``, ``position_sigma_mm``,
``rotation_sigma_deg``, or ``refused``), ``episodes`` (``trial``, ``true`` and ``calibrated``:
``success``, ``steps``, end errors), ``summary``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["add_arguments", "placement", "run"]

#: Placement ranges around the default viewpoint: position per axis (m) and rotation (deg).
SHIFT, TURN_DEG = 0.05, 5.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--trials", type=int, default=20, help="camera placements")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--poses", type=int, default=15,
                        help="generated views per calibration after the first")
    parser.add_argument("--noise", type=float, default=3.0,
                        help="colour noise of the noisy calibrations, 8-bit levels (1 sigma)")
    parser.add_argument("--episodes", type=int, default=None,
                        help="paired pushing episodes (default: one per trial; 0: none)")
    parser.add_argument("--object", default="butter", help="the pushed object")
    parser.add_argument("--max-steps", type=int, default=15, help="pushes per episode")


def placement(seed: int, trial: int) -> np.ndarray:
    """``T_world_camera`` (4, 4) of trial ``trial``: the default viewpoint moved by up to
    :data:`SHIFT` m per axis and turned by up to :data:`TURN_DEG` about a random axis."""
    from scipy.spatial.transform import Rotation

    from sim_bridge.camera import CameraConfig, look_at_pose

    rng = np.random.default_rng([seed, trial])
    t = look_at_pose(CameraConfig())
    t[:3, 3] += rng.uniform(-SHIFT, SHIFT, 3)
    axis = rng.normal(size=3)
    turn = Rotation.from_rotvec(np.radians(rng.uniform(0, TURN_DEG)) * axis
                                / np.linalg.norm(axis))
    t[:3, :3] = turn.as_matrix() @ t[:3, :3]
    return t


def _pose7(t: np.ndarray) -> tuple[float, ...]:
    from push_core.geometry import quaternion_from_matrix

    return tuple(float(v) for v in (*t[:3, 3], *quaternion_from_matrix(t[:3, :3])))


def _calibrate(world: Any, truth: np.ndarray, noise: float, poses: int, seed: int
               ) -> tuple[dict[str, Any], np.ndarray | None]:
    from scipy.spatial.transform import Rotation

    from push_core.calibration import BoardSpec, CalibrationRefused
    from push_executor.motion_types import MotionConfig
    from pushbot.experiments.calibration_sim import SimCalibrationRobot, sim_arm
    from pushbot.runner.calibration import CalibrationSetup, run_calibration
    from sim_bridge.calibration_board import board_mount
    from sim_bridge.camera import CameraConfig, look_at_pose

    motion = MotionConfig()
    world.arm.set_positions(motion.park_positions)
    arm = sim_arm(world)
    mount = board_mount(BoardSpec())
    mount[:3, 3] += (0.01, 0.0, 0.0)
    mount[:3, :3] = Rotation.from_euler("z", 2, degrees=True).as_matrix() @ mount[:3, :3]
    robot = SimCalibrationRobot(world, arm, motion, noise=noise, seed=seed)
    setup = CalibrationSetup(mount=mount, camera=look_at_pose(CameraConfig()),
                             k=world.camera_matrix, size=world.image_size, poses=poses,
                             seed=seed)
    try:
        out = run_calibration(robot, arm, setup, motion)
    except CalibrationRefused as refusal:
        return {"refused": f"{refusal.kind}: {refusal}", "robot_time_s": robot.robot_time}, None
    r = out.result
    rotation = Rotation.from_matrix(r.world_camera[:3, :3].T @ truth[:3, :3]).magnitude()
    return {"position_error_mm": float(np.linalg.norm(r.world_camera[:3, 3] - truth[:3, 3])
                                       * 1e3),
            "rotation_error_deg": float(np.degrees(rotation)), "poses": int(out.moved),
            "views_used": int(r.used.sum()), "robot_time_s": float(robot.robot_time),
            "rms_px": float(r.rms_px), "position_sigma_mm": float(r.position_sigma_mm),
            "rotation_sigma_deg": float(r.rotation_sigma_deg)}, r.world_camera


def _episode(record: dict[str, Any]) -> dict[str, Any]:
    keys = ("success", "steps", "reason", "position_error", "orientation_error")
    return {k: record.get(k) for k in keys}


def summary(trials: list[dict[str, Any]], episodes: list[dict[str, Any]]) -> dict[str, Any]:
    """Medians and maxima of the calibrations, the paired episodes' successes."""
    done = [t for t in trials if "position_error_mm" in t]
    out: dict[str, Any] = {"calibrations": len(trials), "refused": len(trials) - len(done)}
    for key in ("position_error_mm", "rotation_error_deg", "poses", "robot_time_s"):
        values = np.array([t[key] for t in done], dtype=float)
        if len(values):
            out[f"median_{key}"], out[f"max_{key}"] = float(np.median(values)), float(values.max())
    if episodes:
        out["episodes"] = len(episodes)
        for side in ("true", "calibrated"):
            out[f"success_{side}"] = int(sum(bool(e[side]["success"]) for e in episodes))
        out["discordant"] = int(sum(bool(e["true"]["success"]) != bool(e["calibrated"]["success"])
                                    for e in episodes))
    return out


def run(args: argparse.Namespace) -> int:
    from pushbot.experiments.inprocess import run_trial
    from pushbot.runner.protocol import Trial
    from sim_bridge.world import PushWorld, WorldConfig, quiet_stdout

    if args.trials < 1 or args.poses < 1:
        raise ValueError("--trials and --poses must be >= 1")
    episodes_n = args.trials if args.episodes is None else min(args.episodes, args.trials)
    args.out.mkdir(parents=True, exist_ok=True)
    trials: list[dict[str, Any]] = []
    episodes: list[dict[str, Any]] = []
    for i in range(args.trials):
        truth = placement(args.seed, i)
        with quiet_stdout():
            world = PushWorld(WorldConfig(robot="arm", calibration_board=True,
                                          camera_pose=_pose7(truth)))
        calibrated = None
        try:
            for noise in (0.0, args.noise):
                row, solved = _calibrate(world, truth, noise, args.poses, args.seed + i)
                trials.append({"trial": i, "noise": noise, **row})
                calibrated = solved
                print(f"trial {i} noise {noise:g}: " + ", ".join(
                    f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}"
                    for k, v in row.items()), flush=True)
        finally:
            world.close()
        if i < episodes_n and calibrated is not None:
            trial = Trial(object=args.object, state="filter", index=i, seed=args.seed,
                          max_steps=args.max_steps)
            pair = {side: _episode(run_trial(trial, camera_pose=_pose7(truth),
                                             extrinsics=extrinsics))
                    for side, extrinsics in (("true", None), ("calibrated", calibrated))}
            episodes.append({"trial": i, **pair})
            print(f"trial {i} episodes: true {pair['true']['success']}, calibrated "
                  f"{pair['calibrated']['success']}", flush=True)
    result = {"trials": trials, "episodes": episodes,
              "summary": summary(trials, episodes), "config": {
                  k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()
                  if isinstance(v, (int, float, str, Path, type(None)))}}
    (args.out / "results.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result["summary"], indent=1))
    return 0
