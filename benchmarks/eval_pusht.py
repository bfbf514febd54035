"""Push-T (gym-pusht) success of the push_core planner next to Diffusion Policy.

Runs ``pushbot eval pusht`` for both observations (the env state; the env's 96 x 96 image +
agent position) and both object models (``env``: the T read from the env's body; ``estimated``:
the T unknown, its outline from the image, COM, limit surface and friction estimated online)
over the benchmark's protocol (episodes with seeds 0..N-1, 300 control steps), keeps each run's
``results.json`` under ``--out`` (``<obs>`` for the env model, ``<obs>-estimated``), and writes
``docs/results/eval_pusht.md`` with LeRobot's Diffusion Policy figures beside
them and what each method is given.

Usage::

    nice -n 5 .venv/bin/python benchmarks/eval_pusht.py [--episodes 500] [--workers 2]
        [--obs state pixels] [--object-model env estimated] [--out out/eval_pusht]
        [--reuse] [--no-write]
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

from pushbot.experiments.pusht.adapter import evaluate  # noqa: E402

#: LeRobot's Diffusion Policy on gym-pusht (its model card): 500 episodes.
DIFFUSION_POLICY = {"success_rate": 0.638, "avg_max_reward": 0.959}

GIVEN = {
    ("state", "env"): "the env state (agent xy, block xy and angle); the T's outline, COM, mass "
                      "and moment read from the env's pymunk body; no demonstrations, no "
                      "training",
    ("pixels", "env"): "the env's 96 x 96 RGB image + agent xy (Diffusion Policy's "
                       "observation); the T's outline, COM, mass and moment from the env's "
                       "body; no demonstrations, no training",
    ("state", "estimated"): "the env state's agent xy and block pose (of an unknown reference "
                            "point) + the first 96 x 96 image for the outline; COM, l and "
                            "friction estimated online from the robot graph's priors; the "
                            "env's bodies and shapes sealed; no demonstrations, no training",
    ("pixels", "estimated"): "the env's 96 x 96 RGB image + agent xy only (Diffusion Policy's "
                             "observation): outline, pose and goal from the image, COM, l and "
                             "friction estimated online from the robot graph's priors; the "
                             "env's bodies and shapes sealed; no demonstrations, no training",
}


def _folder(out: Path, obs: str, model: str) -> Path:
    return out / (obs if model == "env" else f"{obs}-{model}")



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
    from pushbot.experiments.pusht.adapter import PushTRunner
    from pushbot.experiments.pusht.world import tee_body

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


def failures(r: dict, obs: str, model: str) -> str:
    """One line naming the failed episodes of a run (results.json) with what they reached, or
    "" when every episode succeeded."""
    failed = [e for e in r["episodes"] if not e["success"]]
    if not failed:
        return ""
    parts = []
    for e in failed:
        extra = []
        if e.get("goal_error_mm") is not None:
            extra.append(f"goal fitted {e['goal_error_mm']:.1f} mm off")
        if e.get("outline_error_mm") is not None:
            extra.append(f"outline error {e['outline_error_mm']:.2f} mm")
        parts.append(f"seed {e['seed']} (max coverage {e['max_coverage']:.3f} after "
                     f"{e['steps']} steps, {e['pushes']} pushes" +
                     "".join(f", {x}" for x in extra) + ")")
    return f"- {obs}, {model} model: {len(failed)} failed: " + "; ".join(parts) + "."


def _row(args: argparse.Namespace, obs: str, model: str, reused: list[str],
         failed: list[str]) -> str:
    """One table row: the run of (obs, model), run now or read back (``--reuse``); the run's
    failures are appended to ``failed``."""
    t0 = time.perf_counter()
    folder = _folder(args.out, obs, model)
    saved = folder / "results.json"
    if args.reuse and saved.is_file():
        r = json.loads(saved.read_text())
        c = r["config"]
        if c["episodes"] != args.episodes or c["seed0"] != 0 or c["max_steps"] != 300:
            raise SystemExit(f"{saved}: not a run of {args.episodes} episodes from seed 0")
        if c.get("object_model", "env") != model or c["obs"] != obs:
            raise SystemExit(f"{saved}: not a run of --obs {obs} --object-model {model}")
        wall = None
        n = r["n_episodes"]
        reused.append(f"{obs}/{model}" + ("" if n == args.episodes else
                                          f" (cut after {n} of {args.episodes} episodes: "
                                          f"seeds 0-{n - 1})"))
    else:
        r = evaluate(args.episodes, 0, 300, obs, folder, video=2, workers=args.workers,
                     progress=True, object_model=model)
        wall = time.perf_counter() - t0
    print(json.dumps({k: v for k, v in r.items() if k != "episodes"}), flush=True)
    if failures(r, obs, model):
        failed.append(failures(r, obs, model))
    lo, hi = r["success_wilson_95"]
    given = GIVEN[(obs, model)]
    if r["pose_error_mm_median"] is not None:
        given += (f" (pose estimate error at planning: median {r['pose_error_mm_median']:.2f}"
                  f", 95th percentile {r['pose_error_mm_p95']:.2f} units)")
    outline = "-" if r.get("outline_error_mm_mean") is None else \
        (f"{r['outline_error_mm_mean']:.2f} / {r['outline_max_error_mm_mean']:.1f} mm (95th "
         f"pct of the largest: {r['outline_max_error_mm_p95']:.1f} mm)")
    com = "-" if r.get("com_error_mm_mean") is None else \
        (f"{r['com_error_prior_mm_mean']:.1f} -> {r['com_error_mm_mean']:.1f} mm (end: l "
         f"{r['l_mm_mean']:.1f} mm, m {r['m_mean']:.2f})")
    goal = "-" if r.get("goal_error_mm_mean") is None else f"{r['goal_error_mm_mean']:.2f} mm"
    cut = "" if r["n_episodes"] == args.episodes else f" ({r['n_episodes']} episodes)"
    return (f"| push_core planner, {obs}, {model} model{cut} | {r['success_rate']:.3f} "
            f"[{lo:.3f}, "
            f"{hi:.3f}] | {r['avg_max_reward']:.3f} | {r['mean_max_coverage']:.3f} | "
            f"{r['steps_mean']:.1f} | {r['pushes_mean']:.1f} | {outline} | {com} | {goal} | "
            f"{r['planning_ms_median']:.0f} ms | {r['episode_wall_s_mean']:.2f} s"
            + (f" ({wall / 60:.1f} min, {args.workers} workers)" if wall is not None else "")
            + f" | {given} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=500)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--obs", nargs="+", choices=("state", "pixels"),
                        default=["state", "pixels"])
    parser.add_argument("--object-model", nargs="+", choices=("env", "estimated"),
                        default=["env", "estimated"])
    parser.add_argument("--out", type=Path, default=Path("out/eval_pusht"))
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument("--reuse", action="store_true",
                        help="read OUT/<obs>[-estimated]/results.json of an earlier run (of this "
                             "script or `pushbot eval pusht --out` to that folder) with the same "
                             "--episodes from seed 0 where it exists instead of running the "
                             "episodes again")
    args = parser.parse_args()
    rows, reused, failed = [], [], []
    for model in args.object_model:
        for obs in args.obs:
            rows.append(_row(args, obs, model, reused, failed))
    rows.append(
        f"| LeRobot Diffusion Policy (reference, not re-run) | "
        f"{DIFFUSION_POLICY['success_rate']:.3f} | {DIFFUSION_POLICY['avg_max_reward']:.3f} | - "
        f"| - | - | - | - | - | - | - | 96 x 96 images + agent xy; 206 human "
        f"demonstrations; about 7 GPU-hours of training |")
    body = "\n".join([
        f"gym-pusht 0.1.8 `gym_pusht/PushT-v0`, {args.episodes} episodes (seeds 0-"
        f"{args.episodes - 1}), 300 control steps, the env's own dynamics, reward and success "
        "(coverage > 0.95). Success with its 95 % Wilson interval; avg max reward = mean over "
        "episodes of max clip(coverage / 0.95, 0, 1) (LeRobot's metric); steps = control steps "
        "until success or 300; planning = one `Planner.plan` + transit path. Adapter, frames "
        "and units: `pushbot.experiments.pusht.adapter`, `pushbot.experiments.pusht.world`; "
        "per-episode records in "
        f"`{args.out}/<obs>[-estimated]/results.json`.",
        "",
        "Object model `env`: the T read from the env's body. `estimated` ("
        "`pushbot eval pusht --object-model estimated`, `pushbot.experiments.pusht.estimated`): "
        "the T unknown; its outline from the episode's first 96 x 96 image (the perception "
        "core's mask -> footprint step on the block-colour mask, then every polygon vertex "
        "fitted sub-pixel by least squares through a model of the renderer: the 512 x 512 "
        "render with the block drawn 2 units fat, sampled bilinearly by the resize to 96 x 96); "
        "COM, limit surface l and friction m estimated online by push_core's EKF from the "
        "pushes, from the robot graph's priors (`EKFConfig` defaults: COM at the outline's "
        "centroid, l_0 the uniform-pressure guess +-25 %, m = 0.3 +- 0.15 clipped to [0.05, "
        "1.2]; the true contact is frictionless, m = 0; the graph's process noise; "
        "observation noise 0.6 mm / 0.4 deg from pixels, 0.1 mm / 0.1 deg from the state); "
        "pose from the image (pixels) or the state's block pose through the perceived frame "
        "(state); from pixels the goal is the "
        "green goal region fitted with the perceived outline. The env's bodies and shapes are "
        "sealed (`pusht.guard.SealedEnv`: any read from outside the env raises); the true T is "
        "read from a second env for the error columns only. Outline error = mean distance "
        "between the perceived and the true outline / largest (Hausdorff), mean over episodes; "
        "COM error = distance of the filter's COM from the true centre of gravity at the prior "
        "(the centroid) -> at the episode's end, with the filter's mean l and m at the end (true: "
        "l = 54.8 mm, m = 0); goal = position error of the goal fitted in the image.",
        "",
        *([f"Rows read from earlier runs' `results.json` (same protocol, `--reuse`; written by "
           f"`pushbot eval pusht --obs OBS --object-model MODEL --episodes {args.episodes} "
           f"--out {args.out}/OBS[-estimated]`, which saves its episodes so far at every "
           f"progress line): {', '.join(reused)}; the fidelity table below is measured again.",
           ""] if reused else []),
        "| method | success [95 % CI] | avg max reward | mean max coverage | steps mean | "
        "pushes mean | outline error mean / max | COM error prior -> end | goal error | "
        "planning median | wall per episode | given |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        *rows,
        "",
        "Failures:" if failed else "Failures: none.",
        *failed,
    ])
    body += ("\n\nModel fidelity on the T (a check of the contact model): push_core's rollout "
             "(frictionless, l = sqrt(I/M), the adapter's frames) against the env for straight "
             "60-unit pushes of a T at a random orientation, 300 tries, pushes that moved it "
             "by 5 mm or more; 'nearest face' is the default rollout (one contact per substep), "
             "'two faces' the frictionless two-contact option (`two_faces`) that the Push-T "
             "planner above uses.\n\n" + contact_fidelity())
    command = ("nice -n 5 .venv/bin/python benchmarks/eval_pusht.py "
               + " ".join(sys.argv[1:])).strip()
    load = os.getloadavg()[0]
    body += (f"\n\n1-minute load average at the end: {load:.1f} on {os.cpu_count()} logical cores "
             "(the machine is shared; wall times are indicative only).")
    print(body)
    if not args.no_write:
        data = (f"`{args.out}/<obs>[-estimated]/results.json` (kept outside the repository); "
                "`--reuse` renders the table rows again from them (the fidelity table is "
                "measured again)")
        update_section("eval_pusht", format_section(
            "Push-T: push_core planner vs Diffusion Policy (`eval_pusht`)", command, body),
            data=data)
        print("wrote docs/results/eval_pusht.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
