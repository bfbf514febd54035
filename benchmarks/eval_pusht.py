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


def contact_fidelity(trials: int = 300, seed: int = 0) -> str:
    """Markdown table of :func:`fidelity_errors` with one contact and with ``two_faces``."""
    import numpy as np

    lines = ["| push aimed at | rollout contacts | pushes | position error median / 95th pct "
             "| angle error median / 95th pct |", "| --- | --- | --- | --- | --- |"]
    for two_faces in (False, True):
        rows = fidelity_errors(trials, seed, two_faces)
        for corner, label in ((True, "an inner corner (two faces)"),
                              (False, "an outline point")):
            e = np.array(rows[corner])
            lines.append(f"| {label} | {'two faces' if two_faces else 'nearest face'} | "
                         f"{len(e)} | {np.median(e[:, 0]):.1f} / "
                         f"{np.percentile(e[:, 0], 95):.1f} mm | {np.median(e[:, 1]):.1f} / "
                         f"{np.percentile(e[:, 1], 95):.1f} deg |")
    return "\n".join(lines)


def fidelity_errors(trials: int, seed: int, two_faces: bool) -> dict[bool, list]:
    """Errors (mm, deg) of push_core's rollout prediction vs the env for straight 60-unit pushes of
    the T (frictionless, the adapter's frames), aimed into an inner corner (the disc touches
    the bar and the stem at once) or at a random outline point (one face)."""
    import math

    import numpy as np

    from push_core.rollout import rollout_push
    from push_core.transit import point_polygon_distance
    from pushbot.experiments.pusht_adapter import PushTRunner, tee_body

    r = PushTRunner("state")
    ring = tee_body(r.env)[0]
    cog = np.array(tuple(r.env.unwrapped.block.center_of_gravity))
    corners = [(np.array([15.0, 30.0]), np.array([1.0, 1.0]) / math.sqrt(2.0)),
               (np.array([-15.0, 30.0]), np.array([-1.0, 1.0]) / math.sqrt(2.0))]
    rng = np.random.default_rng(seed)
    rows = {True: [], False: []}
    for trial in range(trials):
        body = np.array([256.0, 256.0, rng.uniform(-math.pi, math.pi)])
        corner = trial % 2 == 0
        if corner:  # along the inner corner's bisector, +-0.5 rad
            point, out = corners[int(rng.integers(2))]
            a = rng.uniform(-0.5, 0.5)
            back = 40.0
        else:  # at a random outline point, +-0.6 rad from its normal
            i = int(rng.integers(len(r.obj.outline.points)))
            point = (r.obj.outline.points[i] - r.obj.origin) / 1e-3
            out, a, back = r.obj.outline.normals[i], rng.uniform(-0.6, 0.6), 25.0
        c, s = math.cos(a), math.sin(a)
        d = -np.array([c * out[0] - s * out[1], s * out[0] + c * out[1]])
        start_b = point - d * back
        if point_polygon_distance(start_b[None], ring)[0] < 16.5:
            continue
        ct, st = math.cos(body[2]), math.sin(body[2])
        rot = np.array([[ct, -st], [st, ct]])
        start, end = body[:2] + rot @ start_b, body[:2] + rot @ (start_b + 60.0 * d)
        position = body[:2] - cog + rot @ cog  # gym-pusht sets the angle about the COG
        obs, _ = r.env.reset(options={"reset_to_state": [*start, *position, body[2]]})
        pose0 = r.frames.object_pose(obs[2:5])
        pred = rollout_push(r.obj.outline.polyline, pose0, r.obj.com, r.obj.limit_surface,
                            r.obj.friction, r.frames.to_world(start),
                            r.frames.to_world(end - start),
                            pusher_radius=r.pusher.radius, two_faces=two_faces).poses[0, -1]
        for k in range(1, 31):
            obs, *_ = r.env.step(start + (end - start) * k / 30)
        for _ in range(5):
            obs, *_ = r.env.step(end)
        moved = r.frames.object_pose(obs[2:5])
        if np.hypot(*(moved[:2] - pose0[:2])) < 0.005:
            continue
        rows[corner].append((1e3 * np.hypot(*(moved[:2] - pred[:2])),
                             abs(math.degrees(math.remainder(moved[2] - pred[2], 2 * math.pi)))))
    r.close()
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=500)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--obs", nargs="+", choices=("state", "pixels"),
                        default=["state", "pixels"])
    parser.add_argument("--out", type=Path, default=Path("out/eval_pusht"))
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument("--reuse", action="store_true",
                        help="read OUT/<obs>/results.json of an earlier run of this script with "
                             "the same --episodes instead of running the episodes again")
    args = parser.parse_args()
    rows = []
    for obs in args.obs:
        t0 = time.perf_counter()
        saved = args.out / obs / "results.json"
        if args.reuse:
            r = json.loads(saved.read_text())
            if r["n_episodes"] != args.episodes or r["config"]["seed0"] != 0:
                raise SystemExit(f"{saved}: not a run of {args.episodes} episodes from seed 0")
            wall = None
        else:
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
            f"{r['planning_ms_median']:.0f} ms | {r['episode_wall_s_mean']:.2f} s"
            + (f" ({wall / 60:.1f} min, {args.workers} workers)" if wall is not None else "")
            + f" | {given} |")
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
        *(["With `--reuse` the episodes are read from the `results.json` files written by "
           "earlier runs of this script (same protocol); only the fidelity table below is "
           "measured again.", ""] if args.reuse else []),
        "| method | success [95 % CI] | avg max reward | mean max coverage | steps mean | "
        "pushes mean | planning median | wall per episode | given |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        *rows,
    ])
    body += ("\n\nModel fidelity on the T (contact-model check of issue 16): push_core's rollout "
             "(frictionless, l = sqrt(I/M), the adapter's frames) against the env for straight "
             "60-unit pushes of a T at a random orientation, 300 tries, pushes that moved it "
             "by 5 mm or more; 'nearest face' is the default rollout (one contact per substep), "
             "'two faces' the frictionless two-contact option (`two_faces`) that the Push-T "
             "planner above uses.\n\n" + contact_fidelity())
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
