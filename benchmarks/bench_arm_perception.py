"""Perception with the simulator's arm in view: the same scenes rendered in pusher mode and in
arm mode (arm parked), run through the committed segmentation model and the pose tracker.

For each held-out object and random pose (half with random appearance, camera jitter and depth
noise), an episode reference frame and a displaced frame are rendered in both modes; reported:
the fraction of pixels that differ between the modes, and the pose error (position, yaw) of
:class:`push_perception.tracker.EpisodeTracker` against the ground-truth displacement in each
mode. Writes the ``bench_arm_perception`` section of ``docs/RESULTS.md``.

Usage::

    .venv/bin/python benchmarks/bench_arm_perception.py [--frames N] [--no-write]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from push_core.objects import TEST_OBJECTS  # noqa: E402
from push_perception.model import Segmenter  # noqa: E402
from push_perception.tracker import EpisodeTracker  # noqa: E402
from sim_bridge.world import PushWorld, WorldConfig, quiet_stdout  # noqa: E402


def episode(cfg: WorldConfig, shift: np.ndarray) -> tuple:
    with quiet_stdout(), PushWorld(cfg) as world:
        first = world.render()
        world.set_object_pose(world.object_pose() + shift)
        return first, world.render()


def errors(segmenter: Segmenter, first: object, frame: object) -> tuple[float, float]:
    tracker = EpisodeTracker()
    for f in (first, frame):
        seg = segmenter(f.rgb, f.depth, f.camera_matrix, f.T_world_camera)
        meas = tracker.update(seg.mask, f.depth, f.camera_matrix, f.T_world_camera)
    truth = np.asarray(frame.object_pose) - np.asarray(first.object_pose)
    est = np.asarray(meas.pose) - tracker_origin(first, segmenter)
    dyaw = (est[2] - truth[2] + np.pi) % (2 * np.pi) - np.pi
    return float(np.linalg.norm(est[:2] - truth[:2])), float(abs(dyaw))


def tracker_origin(first: object, segmenter: Segmenter) -> np.ndarray:
    tracker = EpisodeTracker()
    seg = segmenter(first.rgb, first.depth, first.camera_matrix, first.T_world_camera)
    return np.asarray(tracker.update(seg.mask, first.depth, first.camera_matrix,
                                     first.T_world_camera).pose)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=4, help="episodes per object")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    segmenter = Segmenter.load()
    diff, err = [], {"pusher": [], "arm": []}
    for obj in TEST_OBJECTS:
        for i in range(args.frames):
            noisy = i % 2 == 1
            base = dict(object=obj, seed=int(rng.integers(2**31 - 1)),
                        object_pose=(rng.uniform(-0.15, 0.15), rng.uniform(-0.2, 0.2),
                                     rng.uniform(-np.pi, np.pi)),
                        randomize_appearance=noisy, randomize_camera=noisy, depth_noise=noisy)
            shift = np.array([rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03),
                              rng.uniform(-0.4, 0.4)])
            shots = {robot: episode(WorldConfig(robot=robot, **base), shift)
                     for robot in ("pusher", "arm")}
            diff.append(float(np.mean(np.any(shots["pusher"][1].rgb != shots["arm"][1].rgb,
                                             axis=2))))
            for robot, (first, frame) in shots.items():
                err[robot].append(errors(segmenter, first, frame))
    rows = []
    for robot, e in err.items():
        e = np.array(e)
        rows.append(f"| {robot} | {1e3 * np.median(e[:, 0]):.2f} | {1e3 * np.max(e[:, 0]):.2f} "
                    f"| {np.degrees(np.median(e[:, 1])):.2f} | {np.degrees(np.max(e[:, 1])):.2f} "
                    f"| {len(e)} |")
    body = "\n".join([
        f"Same scenes ({', '.join(TEST_OBJECTS)}, {args.frames} episodes each, half with random "
        "appearance, camera jitter and depth noise), displacement of the object between the "
        "episode's first frame and a second one as measured by the committed segmentation "
        "model + EpisodeTracker, against the ground truth. Pixels that differ between pusher "
        f"mode and arm mode (arm parked): median {100 * np.median(diff):.3f} %, max "
        f"{100 * np.max(diff):.3f} %.", "",
        "| robot | position error median mm | max mm | yaw error median deg | max deg | "
        "episodes |", "|---|---|---|---|---|---|", *rows])
    section = format_section("Perception with the arm in the scene (`bench_arm_perception`)",
                             "python benchmarks/bench_arm_perception.py", body)
    print(section)
    if not args.no_write:
        update_section("bench_arm_perception", section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
