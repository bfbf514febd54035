"""Speed of the analytical pushing model: affordances (300 contact points x 10 pushes) and rollouts.

Times ``push_core.model.predict_motion`` for 300 outline points x the 10 representative pushes of
the analytical pushing model (numpy, the target: median <= 1 ms), the same call through torch
(float64, for information), and ``push_core.rollout.rollout_push`` for B = 15 pushes of 10 substeps
against the 637-vertex butter outline (for information: the planner's per-direction rollouts).
Reports medians over many repeats (wall clock, one call per repeat, after a warm-up) and writes
them to ``docs/results/bench_model.md``, rendered from the figures saved beside it
(``bench_model.json``; ``--render`` writes the page again from them without measuring).

Usage::

    .venv/bin/python benchmarks/bench_model.py [--repeats N] [--no-write]
    .venv/bin/python benchmarks/bench_model.py --render
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
import _results  # noqa: E402

from push_core.geometry import closest_point_on_polyline  # noqa: E402
from push_core.model import predict_motion, representative_pushes  # noqa: E402
from push_core.rollout import rollout_push  # noqa: E402

TARGET_MS = 1.0
N_POINTS = 300
BATCH = 15
SECTION = "bench_model"
TITLE = "Pushing model speed (`bench_model`)"
RENDER = "python benchmarks/bench_model.py --render"


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


def stats(times: np.ndarray) -> dict[str, float]:
    """Median, 10th and 90th percentile (ms) and the number of timed calls."""
    p10, p50, p90 = np.percentile(times, [10, 50, 90])
    return {"p10": float(p10), "p50": float(p50), "p90": float(p90), "n": len(times)}


def render(figures: dict) -> str:
    """The page's text from the saved figures (:func:`measure`)."""
    def row(name: str, s: dict, target: str) -> str:
        return (f"| {name} | {s['p50']:.3f} | {s['p10']:.3f} | {s['p90']:.3f} | {s['n']} | "
                f"{target} |")

    n_points, batch, n_sub, target = (figures[k] for k in ("n_points", "batch", "n_sub",
                                                           "target_ms"))
    verdict = "met" if figures["numpy"]["p50"] <= target else "NOT met"
    return "\n".join([
        f"Affordances: `predict_motion` for {n_points} contact points x 10 representative pushes "
        f"(one call, float64). Rollout: `rollout_push`, B = {batch}, {n_sub} substeps, "
        f"{figures['outline_vertices']}-vertex butter outline. Wall clock per call in ms; one "
        f"call per repeat after a warm-up; torch with {figures['torch_threads']} intra-op "
        "thread. The machine is shared, so the tails (p90) are noisy; the median is the figure.",
        "",
        "| case | median ms | p10 ms | p90 ms | repeats | target |",
        "| --- | --- | --- | --- | --- | --- |",
        row(f"predict_motion numpy {n_points} x 10", figures["numpy"],
            f"<= {target:g} ms: {verdict}"),
        row(f"predict_motion torch {n_points} x 10", figures["torch"], "for information"),
        row(f"rollout_push numpy B={batch}, {n_sub} substeps", figures["rollout"],
            "for information"),
    ])


def measure(repeats: int) -> dict:
    """Time the three cases; the figures :func:`render` writes the page from."""
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

    np_ms = time_ms(lambda: predict_motion(points, normals, pushes, com, l, m), repeats)
    # One intra-op thread: 3000-element ops gain nothing from more, and on a shared machine extra
    # threads only add scheduling stalls to the tail.
    torch.set_num_threads(1)
    tp, tn, tu, tc = (torch.tensor(a) for a in (points, normals, pushes, com))
    with torch.no_grad():
        torch_ms = time_ms(lambda: predict_motion(tp, tn, tu, tc, l, m), repeats)

    # B = 15 pushes of 5 cm (10 substeps of 5 mm) from 15 outline points along 5 directions.
    idx = np.arange(BATCH) * (N_POINTS // BATCH)
    starts = points[idx] + 0.0048 * normals[idx]
    push = pushes[idx, 5 + np.arange(BATCH) % 5]  # the 5 cm pushes
    pose0 = np.zeros(3)
    rollout_repeats = max(repeats // 10, 20)
    roll_ms = time_ms(lambda: rollout_push(outline, pose0, com, l, m, starts, push),
                      rollout_repeats, warmup=5)
    n_sub = int(rollout_push(outline, pose0, com, l, m, starts, push).n_steps.max())
    return {"n_points": N_POINTS, "batch": BATCH, "n_sub": n_sub, "target_ms": TARGET_MS,
            "outline_vertices": len(outline), "torch_threads": torch.get_num_threads(),
            "numpy": stats(np_ms), "torch": stats(torch_ms), "rollout": stats(roll_ms)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2000, help="timed calls per case")
    _results.add_page_options(parser)
    args = parser.parse_args(argv)
    if args.render:
        print(_results.publish(SECTION, TITLE, render, RENDER))
        return 0
    figures = measure(args.repeats)
    print(render(figures))
    if not args.no_write:
        command = " ".join(["python benchmarks/bench_model.py", *(argv or sys.argv[1:])])
        print(_results.publish(SECTION, TITLE, render, RENDER, command=command, figures=figures))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
