"""Push-T (gym-pusht) success of the push_core planner next to Diffusion Policy (issue 16).

Runs ``pushbot eval pusht`` for both observations (the env state; the env's 96 x 96 image +
agent position) over the benchmark's protocol (episodes with seeds 0..N-1, 300 control steps),
keeps each run's ``results.json`` under ``--out``, and writes the ``eval_pusht`` section of
``docs/RESULTS.md`` with LeRobot's Diffusion Policy figures beside them and what each method is
given.

Usage::

    nice -n 5 .venv/bin/python benchmarks/eval_pusht.py [--episodes 500] [--workers 2]
        [--obs state pixels] [--out out/eval_pusht] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from pushbot.experiments.pusht_adapter import evaluate  # noqa: E402

#: LeRobot's Diffusion Policy on gym-pusht (its model card / the issue): 500 episodes.
DIFFUSION_POLICY = {"success_rate": 0.638, "avg_max_reward": 0.959}

GIVEN = {
    "state": "the env state (agent xy, block xy and angle); the T's outline, COM, mass and "
             "moment read from the env's pymunk body; no demonstrations, no training",
    "pixels": "the env's 96 x 96 RGB image + agent xy (Diffusion Policy's observation); the "
              "T's outline, COM, mass and moment from the env's body; no demonstrations, no "
              "training",
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=500)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--obs", nargs="+", choices=("state", "pixels"),
                        default=["state", "pixels"])
    parser.add_argument("--out", type=Path, default=Path("out/eval_pusht"))
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    rows = []
    for obs in args.obs:
        t0 = time.perf_counter()
        r = evaluate(args.episodes, 0, 300, obs, args.out / obs, video=2,
                     workers=args.workers, progress=True)
        wall = time.perf_counter() - t0
        lo, hi = r["success_wilson_95"]
        given = GIVEN[obs]
        if r["pose_error_mm_median"] is not None:
            given += (f" (pose estimate error at planning: median {r['pose_error_mm_median']:.2f}"
                      f", 95th percentile {r['pose_error_mm_p95']:.2f} units)")
        rows.append(
            f"| push_core planner, {obs} | {r['success_rate']:.3f} [{lo:.3f}, {hi:.3f}] | "
            f"{r['avg_max_reward']:.3f} | {r['mean_max_coverage']:.3f} | "
            f"{r['steps_mean']:.1f} | {r['pushes_mean']:.1f} | "
            f"{r['planning_ms_median']:.0f} ms | {r['episode_wall_s_mean']:.2f} s "
            f"({wall / 60:.1f} min, {args.workers} workers) | {given} |")
        print(json.dumps({k: v for k, v in r.items() if k != "episodes"}), flush=True)
    rows.append(
        f"| LeRobot Diffusion Policy (reference, not re-run) | "
        f"{DIFFUSION_POLICY['success_rate']:.3f} | {DIFFUSION_POLICY['avg_max_reward']:.3f} | - "
        f"| - | - | - | - | 96 x 96 images + agent xy; 206 human demonstrations; about 7 "
        f"GPU-hours of training |")
    body = "\n".join([
        f"gym-pusht 0.1.8 `gym_pusht/PushT-v0`, {args.episodes} episodes (seeds 0-"
        f"{args.episodes - 1}), 300 control steps, the env's own dynamics, reward and success "
        "(coverage > 0.95). Success with its 95 % Wilson interval; avg max reward = mean over "
        "episodes of max clip(coverage / 0.95, 0, 1) (LeRobot's metric); steps = control steps "
        "until success or 300; planning = one `Planner.plan` + transit path. Adapter, frames "
        "and units: `pushbot.experiments.pusht_adapter`; per-episode records in "
        f"`{args.out}/<obs>/results.json`.",
        "",
        "| method | success [95 % CI] | avg max reward | mean max coverage | steps mean | "
        "pushes mean | planning median | wall per episode | given |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        *rows,
    ])
    command = ("nice -n 5 .venv/bin/python benchmarks/eval_pusht.py "
               + " ".join(sys.argv[1:])).strip()
    load = os.getloadavg()[0]
    body += (f"\n\nThe machine was shared with other jobs (1-minute load average {load:.1f} at "
             "the end); wall times are indicative only.")
    print(body)
    if not args.no_write:
        update_section("eval_pusht", format_section(
            "Push-T: push_core planner vs Diffusion Policy (`eval_pusht`)", command, body))
        print("wrote section eval_pusht of docs/RESULTS.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
