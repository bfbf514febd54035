"""Learned affordances (``lrn``): accuracy against pybullet next to ``ana``, speed, closed loop.

1. **Accuracy** on held-out objects (tri1, butter, hex; randomised physics): the bundled model
   (``push_planner/models/affordances.pt``) vs the analytical one-step model (true COM and
   pusher friction, ``l`` of uniform pressure) vs "no motion", against the object motion that
   pybullet produces for the 10 representative pushes at 20 random contact points per sample
   (:mod:`pushbot.experiments.affordance_data`, ``--test``; generated into ``--test-data`` if
   missing, seed 1, so it differs from any test set used while training).
2. **Speed**: affordances for butter's outline sampled every 1.5 mm (302 points x 10 pushes),
   torch with one thread; target median <= 20 ms (cached shape encoding, i.e. every planning
   step after the first of an episode); the first call with the encoding for information.
3. **Closed loop** on the held-out objects with ground-truth state (as ``bench_planner``):
   ana vs lrn, k = 1 and 3, and lrn direct.

Writes ``docs/results/bench_lrn.md``.

Usage::

    .venv/bin/python benchmarks/bench_lrn.py [--test-data DIR] [--samples N] [--trials N]
                                             [--no-write]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402
from bench_planner import TASKS, closed_loop, summarise, time_ms  # noqa: E402

from push_core.affordances import analytical_affordances  # noqa: E402
from push_core.learned import load_affordance_model  # noqa: E402
from push_core.objects import TEST_OBJECTS, load_object  # noqa: E402
from push_core.planner import Planner, PlannerConfig  # noqa: E402
from push_planner.models import default_weights  # noqa: E402
from pushbot.experiments.affordance_data import DataConfig, generate, load  # noqa: E402
from pushbot.experiments.affordance_training import evaluate, metrics_table  # noqa: E402
from sim_bridge.world import PushWorld, WorldConfig  # noqa: E402

TARGET_MS = 20.0
REPO = Path(__file__).resolve().parents[1]


def aggregate(metrics: dict[str, dict[str, float]]) -> list[str]:
    """Rows over all test objects (pushes weighted by count) per push length and predictor."""
    rows = []
    keys = sorted({tuple(k.split("|")[1:]) for k in metrics})
    for length, name in keys:
        parts = [m for k, m in metrics.items() if k.endswith(f"|{length}|{name}")]
        n = sum(m["n"] for m in parts)
        t = sum(m["trans_mean_mm"] * m["n"] for m in parts) / n
        r = sum(m["rot_mean_deg"] * m["n"] for m in parts) / n
        rows.append(f"| all | {length} | {name} | {n} | - / {t:.1f} | - / {r:.1f} |")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--test-data", type=Path,
                        default=REPO / "out" / "affordance_data" / "bench_test")
    parser.add_argument("--samples", type=int, default=30,
                        help="held-out samples to generate if the test data is missing")
    parser.add_argument("--trials", type=int, default=5, help="closed-loop trials per object "
                        "and task")
    parser.add_argument("--weights", type=Path, default=None)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    t_start = time.perf_counter()
    weights = args.weights or default_weights()
    model = load_affordance_model(weights)

    if not (args.test_data / "meta.json").exists() or not list(
            args.test_data.glob("shard_*.npz")):
        generate(DataConfig(n_samples=args.samples, seed=1, shard_size=5, test=True),
                 args.test_data)
    data = load(args.test_data)
    metrics = evaluate(model, data)
    table = metrics_table(metrics).splitlines()
    table += aggregate(metrics)
    print("\n".join(table), flush=True)

    spec = load_object("butter")
    points, normals = spec.outline(0.0015)
    com = np.asarray(spec.com)
    lrn_ms = time_ms(lambda: model(points, normals, com), 200)

    def first_call() -> None:
        model._cache.clear()
        model(points, normals, com)

    first_ms = time_ms(first_call, 20, warmup=2)
    ana_ms = time_ms(lambda: analytical_affordances(points, normals, com, 0.045, 0.25), 200)
    verdict = "met" if np.median(lrn_ms) <= TARGET_MS else "NOT met"

    world = PushWorld(WorldConfig(object="butter"))
    loop = []
    for method, k, direct in (("ana", 1, False), ("lrn", 1, False), ("ana", 3, False),
                              ("lrn", 3, False), ("lrn", 3, True)):
        def config(i: int, method: str = method, k: int = k, direct: bool = direct
                   ) -> PlannerConfig:
            return PlannerConfig(method=method, k=k, direct=direct, seed=i)

        res = closed_loop(world, args.trials, TEST_OBJECTS, config,
                          planner=lambda cfg: Planner(cfg, model if cfg.method == "lrn"
                                                      else None))
        every = [r for rs in res.values() for r in rs]
        per_task = " | ".join(f"{np.mean([r.success for r in rs]):.2f}" for rs in res.values())
        loop.append(f"| {method}{' direct' if direct else ''}, k = {k} | {per_task} | "
                    f"{summarise(every)} |")
        print(loop[-1], flush=True)
    world.close()
    minutes = (time.perf_counter() - t_start) / 60.0

    meta = model.meta
    body = "\n".join([
        f"Model: `{weights.relative_to(REPO) if weights.is_relative_to(REPO) else weights}` "
        f"(model card beside it; trained on {meta.get('samples', '?')} object samples, "
        f"{meta.get('executed_pushes', '?')} pushes, {meta.get('train_minutes', '?')} min).",
        "",
        f"**Accuracy against pybullet** on held-out objects ({len(data['com'])} samples of "
        f"{', '.join(TEST_OBJECTS)} with randomised physics, 20 contact points x 10 "
        "representative pushes each; test data seed 1). Errors of the predicted object-frame "
        "origin motion over the pushes the world executed. ana = analytical one-step model with "
        "the true COM and pusher friction and l of uniform pressure (what the planner uses with "
        "ground-truth state); lrn uses the true COM and no l, m.",
        "",
        *table,
        "",
        f"**Speed** (butter, {len(points)} points x 10 pushes, torch 1 thread): lrn median "
        f"**{np.median(lrn_ms):.2f} ms** (p90 {np.percentile(lrn_ms, 90):.2f}; target <= "
        f"{TARGET_MS:g} ms: {verdict}; shape encoding cached per outline), first call with the "
        f"encoding {np.median(first_ms):.2f} ms, ana {np.median(ana_ms):.2f} ms.",
        "",
        f"**Closed loop** on the held-out objects, ground-truth state, randomised physics, "
        f"{args.trials} trials per object and task ({args.trials * len(TEST_OBJECTS)} per "
        "task), lambda 2 mm/deg, T 2 mm (protocol of bench_planner):",
        "",
        "| method | " + " | ".join(TASKS) + " | success (all) | steps | final error mm | "
        "final error deg |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
        *loop,
        "",
        f"Wall time: {minutes:.1f} min.",
    ])
    command = " ".join(["python benchmarks/bench_lrn.py", *(argv or sys.argv[1:])])
    section = format_section("Learned affordances (`bench_lrn`)", command, body)
    print(section)
    if not args.no_write:
        update_section("bench_lrn", section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
