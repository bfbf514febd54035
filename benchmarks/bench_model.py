"""Speed of the analytical pushing model: affordances (300 contact points x 10 pushes) and rollouts.

Times ``push_core.model.predict_motion`` for 300 outline points x the 10 representative pushes of
the analytical pushing model (numpy, the target: median <= 1 ms), the same call through torch
(float64, for information), and ``push_core.rollout.rollout_push`` for B = 15 pushes of 10 substeps
against the 637-vertex butter outline (for information: the planner's per-direction rollouts).
Reports medians over many repeats (wall clock, one call per repeat, after a warm-up) and writes
them to ``docs/results/bench_model.md``.

Usage::

    .venv/bin/python benchmarks/bench_model.py [--repeats N] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from push_core.geometry import closest_point_on_polyline  # noqa: E402
from push_core.model import predict_motion, representative_pushes  # noqa: E402
from push_core.rollout import rollout_push  # noqa: E402

TARGET_MS = 1.0
N_POINTS = 300
BATCH = 15


def time_ms(fn: Callable[[], object], repeats: int, warmup: int = 20) -> np.ndarray:
    """Wall-clock times of ``repeats`` single calls, in milliseconds."""
    for _ in range(warmup):
        fn()
    times = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        fn()
        times[i] = time.perf_counter() - t0
    return 1e3 * times


def butter_outline() -> np.ndarray:
    path = resources.files("push_core") / "data" / "mit_push_objects.json"
    return np.array(json.loads(path.read_text())["objects"]["butter"]["polygon_m"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2000, help="timed calls per case")
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args(argv)

    outline = butter_outline()
    outline = outline - outline.mean(axis=0)
    # 300 contact points spread over the outline, with outward normals from the outline itself.
    t = np.linspace(0.0, len(outline), N_POINTS, endpoint=False)
    i = t.astype(int)
    frac = (t - i)[:, None]
    points = (1 - frac) * outline[i] + frac * outline[(i + 1) % len(outline)]
    _, normals, _, _ = closest_point_on_polyline(outline, points)
    pushes = representative_pushes(normals)
    com, l, m = np.array([0.003, -0.002]), 0.04, 0.3  # noqa: E741
    assert predict_motion(points, normals, pushes, com, l, m).shape == (N_POINTS, 10, 3)

    np_ms = time_ms(lambda: predict_motion(points, normals, pushes, com, l, m), args.repeats)
    # One intra-op thread: 3000-element ops gain nothing from more, and on a shared machine extra
    # threads only add scheduling stalls to the tail.
    torch.set_num_threads(1)
    tp, tn, tu, tc = (torch.tensor(a) for a in (points, normals, pushes, com))
    with torch.no_grad():
        torch_ms = time_ms(lambda: predict_motion(tp, tn, tu, tc, l, m), args.repeats)

    # B = 15 pushes of 5 cm (10 substeps of 5 mm) from 15 outline points along 5 directions.
    idx = np.arange(BATCH) * (N_POINTS // BATCH)
    starts = points[idx] + 0.0048 * normals[idx]
    push = pushes[idx, 5 + np.arange(BATCH) % 5]  # the 5 cm pushes
    pose0 = np.zeros(3)
    rollout_repeats = max(args.repeats // 10, 20)
    roll_ms = time_ms(lambda: rollout_push(outline, pose0, com, l, m, starts, push),
                      rollout_repeats, warmup=5)
    n_sub = int(rollout_push(outline, pose0, com, l, m, starts, push).n_steps.max())

    def row(name: str, times: np.ndarray, target: str) -> str:
        p10, p50, p90 = np.percentile(times, [10, 50, 90])
        return f"| {name} | {p50:.3f} | {p10:.3f} | {p90:.3f} | {len(times)} | {target} |"

    verdict = "met" if np.median(np_ms) <= TARGET_MS else "NOT met"
    body = "\n".join([
        f"Affordances: `predict_motion` for {N_POINTS} contact points x 10 representative pushes "
        f"(one call, float64). Rollout: `rollout_push`, B = {BATCH}, {n_sub} substeps, "
        f"{len(outline)}-vertex butter outline. Wall clock per call in ms; one call per repeat "
        f"after a warm-up; torch with {torch.get_num_threads()} intra-op thread. The machine is "
        "shared, so the tails (p90) are noisy; the median is the figure.",
        "",
        "| case | median ms | p10 ms | p90 ms | repeats | target |",
        "| --- | --- | --- | --- | --- | --- |",
        row(f"predict_motion numpy {N_POINTS} x 10", np_ms, f"<= {TARGET_MS:g} ms: {verdict}"),
        row(f"predict_motion torch {N_POINTS} x 10", torch_ms, "for information"),
        row(f"rollout_push numpy B={BATCH}, {n_sub} substeps", roll_ms, "for information"),
    ])
    command = " ".join(["python benchmarks/bench_model.py", *(argv or sys.argv[1:])])
    section = format_section("Pushing model speed (`bench_model`)", command, body)
    print(section)
    if not args.no_write:
        update_section("bench_model", section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
