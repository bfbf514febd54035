"""Latency of the perception pipeline per 640 x 480 RGB-D frame (target: median <= 30 ms).

Renders frames of the held-out objects (tri1, butter, hex) at random poses, half of them with
random appearance, camera jitter and depth noise, and times what ``segmentation_node`` does
for each frame, stage by stage, on one torch thread and one OpenCV thread:

- decode: ``sensor_msgs/Image`` (rgb8, 32FC1) -> arrays, with validation;
- segment: the two-stage CNN (:class:`push_perception.model.Segmenter`) incl. preprocessing;
- geometry: :meth:`push_perception.tracker.EpisodeTracker.update` (deprojection, top-down view,
  outline, rotation search against the episode's first frame, covariance);
- encode: the pose (PoseWithCovarianceStamped) and mask (mono8) messages.

The tracker's reference is the object's first frame, so every timed call runs the rotation
search. Writes ``docs/results/bench_perception.md``.

Usage::

    .venv/bin/python benchmarks/bench_perception.py [--frames N] [--repeats R] [--no-write]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from push_core.objects import TEST_OBJECTS  # noqa: E402
from push_perception.model import Segmenter  # noqa: E402
from push_perception.tracker import EpisodeTracker  # noqa: E402
from push_ros.images import (  # noqa: E402
    depth_image_msg,
    depth_to_metres,
    image_to_array,
    mask_image_msg,
    rgb_image_msg,
)
from push_ros.poses import pose_with_covariance_msg  # noqa: E402
from push_ros.stamps import stamp_from_seconds  # noqa: E402
from sim_bridge.world import PushWorld, WorldConfig  # noqa: E402

TARGET_MS = 30.0


def render_frames(n_per_object: int, seed: int) -> list[tuple[str, object, object]]:
    """(object, first frame, frame) triples: the first frame is the episode reference."""
    rng = np.random.default_rng(seed)
    out = []
    for obj in TEST_OBJECTS:
        for i in range(n_per_object):
            noisy = i % 2 == 1
            cfg = WorldConfig(object=obj, seed=int(rng.integers(2**31 - 1)),
                              object_pose=(rng.uniform(-0.15, 0.15), rng.uniform(-0.2, 0.2),
                                           rng.uniform(-np.pi, np.pi)),
                              randomize_appearance=noisy, randomize_camera=noisy,
                              depth_noise=noisy)
            with PushWorld(cfg) as world:
                first = world.render()
                pose = world.object_pose() + [rng.uniform(-0.03, 0.03),
                                              rng.uniform(-0.03, 0.03), rng.uniform(-0.4, 0.4)]
                world.set_object_pose(pose)
                out.append((obj, first, world.render()))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=8, help="frames per object (default 8)")
    parser.add_argument("--repeats", type=int, default=10,
                        help="timed runs per frame (default 10)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args(argv)

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    segmenter = Segmenter.load()
    frames = render_frames(args.frames, args.seed)
    stages = {"decode": [], "segment": [], "geometry": [], "encode": [], "total": []}
    per_object: dict[str, list[float]] = {o: [] for o in TEST_OBJECTS}
    failures = 0
    for rep in range(args.repeats + 1):  # the first pass warms up and is not counted
        for obj, first, frame in frames:
            tracker = EpisodeTracker()
            seg0 = segmenter(first.rgb, first.depth, first.camera_matrix, first.T_world_camera)
            tracker.update(seg0.mask, first.depth, first.camera_matrix, first.T_world_camera)
            stamp = stamp_from_seconds(1.0)
            rgb_msg = rgb_image_msg(frame.rgb, stamp)
            depth_msg = depth_image_msg(frame.depth, stamp)
            t0 = time.perf_counter()
            rgb = image_to_array(rgb_msg)
            depth = depth_to_metres(depth_msg)
            t1 = time.perf_counter()
            seg = segmenter(rgb, depth, frame.camera_matrix, frame.T_world_camera)
            t2 = time.perf_counter()
            try:
                meas = tracker.update(seg.mask, depth, frame.camera_matrix,
                                      frame.T_world_camera)
            except ValueError:
                failures += 1
                continue
            t3 = time.perf_counter()
            pose_with_covariance_msg(meas.pose, meas.covariance, stamp)
            mask_image_msg(seg.mask, stamp)
            t4 = time.perf_counter()
            if rep == 0:
                continue
            for key, dt in (("decode", t1 - t0), ("segment", t2 - t1), ("geometry", t3 - t2),
                            ("encode", t4 - t3), ("total", t4 - t0)):
                stages[key].append(1e3 * dt)
            per_object[obj].append(1e3 * (t4 - t0))

    def row(name: str, times: list[float], target: str = "for information") -> str:
        p10, p50, p90 = np.percentile(times, [10, 50, 90])
        return f"| {name} | {p50:.1f} | {p10:.1f} | {p90:.1f} | {len(times)} | {target} |"

    median = float(np.median(stages["total"]))
    verdict = "met" if median <= TARGET_MS else "NOT met"
    load = os.getloadavg()[0]
    body = "\n".join([
        f"What `segmentation_node` does per 640 x 480 frame, timed stage by stage: {len(frames)} "
        f"rendered frames of {', '.join(TEST_OBJECTS)} (half with random appearance, camera "
        f"jitter and depth noise) x {args.repeats} runs after a warm-up pass; every frame is "
        "measured against its episode's first frame (the rotation search runs). One torch "
        f"thread, one OpenCV thread; 1-minute load average {load:.1f} at the end (the machine "
        f"is shared; other training jobs may run). Frames without a pose: {failures}.",
        "",
        "| stage | median ms | p10 ms | p90 ms | samples | target |",
        "| --- | --- | --- | --- | --- | --- |",
        row("decode (Image rgb8 + 32FC1 -> arrays)", stages["decode"]),
        row("segment (two-stage CNN)", stages["segment"]),
        row("geometry (pose, rotation search, covariance)", stages["geometry"]),
        row("encode (pose + mask messages)", stages["encode"]),
        row("total", stages["total"], f"<= {TARGET_MS:g} ms: {verdict}"),
        *(row(f"total, {obj}", per_object[obj]) for obj in TEST_OBJECTS),
    ])
    command = " ".join(["python benchmarks/bench_perception.py", *(argv or sys.argv[1:])])
    section = format_section("Perception latency per frame (`bench_perception`)", command, body)
    print(section)
    if not args.no_write:
        update_section("bench_perception", section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
