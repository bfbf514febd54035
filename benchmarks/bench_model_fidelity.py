"""How well push_core's analytical model predicts pybullet pushes (a measurement, not a test).

For each object (rect1 and butter by default), ``--pushes`` random pushes (seeded) are run in
the in-process pybullet world (``sim_bridge.world.PushWorld``, default physics settings, the
library object's nominal mass/COM/friction, object at the origin): a contact point drawn
uniformly along the outline, a direction within +-60 deg of the inward normal, a length of
1-5 cm, the pusher lowered 1 cm before the contact point. Each push starts from the same
resting pose. The object's final pose is compared with
``push_core.rollout.rollout_push`` (the analytical quasi-static model, 5 mm substeps) driven by
the pusher's *executed* straight motion (what the estimator receives), with
``l = spec.limit_surface_guess()`` (uniform pressure) and ``m = spec.friction_pusher`` (the
simulated value). Reported: median / mean / 90th percentile of the translation error (mm, object
frame origin) and the rotation error (deg); the same relative to the true motion (error divided
by the true translation resp. rotation, over pushes that moved the object by at least 1 mm resp.
1 deg); the same figures for the trivial "no motion" predictor as a reference; and how often
model and simulation agree on whether the pusher touched the object.

Usage::

    .venv/bin/python benchmarks/bench_model_fidelity.py [--pushes N] [--objects a,b] [--no-write]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from push_core.geometry import wrap_angle  # noqa: E402
from push_core.rollout import rollout_push  # noqa: E402
from sim_bridge.world import PushResult, PushWorld, WorldConfig, push_points  # noqa: E402

SEED = 2020
MAX_ANGLE = np.radians(60.0)
LENGTHS = (0.01, 0.05)
GAP = 0.01


def random_pushes(world: PushWorld, n: int,
                  rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``n`` random valid pushes (approach, contact, end) at the world's current object pose.

    Contact point uniform along the outline (2 mm spacing), direction uniform within +-60 deg
    of the inward normal, length uniform in [1, 5] cm, approach 1 cm before the contact.
    Pushes the world rejects (approach point too close to another part of the outline) are
    redrawn.
    """
    points, normals = world.object_spec.outline(0.002)
    pose = world.object_pose()
    out = []
    while len(out) < n:
        i = rng.integers(len(points))
        angle = rng.uniform(-MAX_ANGLE, MAX_ANGLE)
        length = rng.uniform(*LENGTHS)
        push = push_points(pose, points[i], normals[i], angle, length,
                           world.config.pusher_radius, GAP)
        try:
            world.check_push(*push)
        except ValueError:
            continue
        out.append(push)
    return out


def run_object(name: str, n: int, seed: int) -> dict[str, object]:
    """Simulate ``n`` random pushes on ``name`` and predict them with the rollout."""
    world = PushWorld(WorldConfig(object=name))
    rng = np.random.default_rng([seed, sum(name.encode())])
    pushes = random_pushes(world, n, rng)
    start_pose = world.object_pose()
    results: list[PushResult] = []
    t0 = time.perf_counter()
    for push in pushes:
        world.set_object_pose(start_pose)
        results.append(world.execute_push(*push))
    sim_s = time.perf_counter() - t0
    spec = world.object_spec
    world.close()

    before = np.array([r.pose_before for r in results])
    after = np.array([r.pose_after for r in results])
    starts = np.array([r.pusher_start for r in results])
    moves = np.array([r.pusher_end for r in results]) - starts
    radius = world.config.pusher_radius

    def predict(l_value: float) -> tuple[np.ndarray, np.ndarray]:
        roll = rollout_push(spec.polyline(), before, spec.com, l_value, spec.friction_pusher,
                            starts, moves, pusher_radius=radius)
        return roll.poses[:, -1], roll.contact.any(axis=1)

    t0 = time.perf_counter()
    predicted, model_touch = predict(spec.limit_surface_guess())
    model_s = time.perf_counter() - t0
    true_dt = np.linalg.norm(after[:, :2] - before[:, :2], axis=1)
    true_signed = wrap_angle(after[:, 2] - before[:, 2])
    true_dr = np.abs(true_signed)
    err_t = np.linalg.norm(predicted[:, :2] - after[:, :2], axis=1)
    err_r = np.abs(wrap_angle(predicted[:, 2] - after[:, 2]))
    turning = true_dr >= np.radians(1.0)
    ratio = wrap_angle(predicted[:, 2] - before[:, 2])[turning] / true_signed[turning]
    # Effective l of the simulation: the value on a grid that minimises the mean rotation error.
    grid = np.linspace(0.5, 2.5, 21) * spec.limit_surface_guess()
    fits = [(float(np.mean(np.abs(wrap_angle(predict(g)[0][:, 2] - after[:, 2])))), g)
            for g in grid]
    best_err, best_l = min(fits)
    best_pred = predict(best_l)[0]
    sim_touch = np.array([r.touched for r in results])
    return dict(name=name, n=n, sim_s=sim_s, model_s=model_s, true_dt=true_dt, true_dr=true_dr,
                err_t=err_t, err_r=err_r, sim_touch=sim_touch, model_touch=model_touch,
                l=spec.limit_surface_guess(), m=spec.friction_pusher, mu=spec.friction_table,
                rot_ratio=float(np.median(ratio)) if ratio.size else float("nan"),
                best_l=best_l, best_err_r=best_err,
                best_err_t=float(np.median(np.linalg.norm(best_pred[:, :2] - after[:, :2],
                                                          axis=1))))


def _stats(x: np.ndarray) -> tuple[float, float, float]:
    return float(np.median(x)), float(np.mean(x)), float(np.percentile(x, 90))


def _relative(err: np.ndarray, motion: np.ndarray, floor: float) -> tuple[str, int]:
    keep = motion >= floor
    if not keep.any():
        return "n/a", 0
    med, mean, p90 = _stats(err[keep] / motion[keep])
    return f"{med:.2f} / {mean:.2f} / {p90:.2f}", int(keep.sum())


def format_results(runs: list[dict[str, object]]) -> str:
    """Markdown table of the figures of every object."""
    rows = [
        "| object | predictor | translation error mm (median / mean / p90) | rotation error deg "
        "(median / mean / p90) | relative translation error (median / mean / p90; n) | "
        "relative rotation error (median / mean / p90; n) |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    notes = []
    for r in runs:
        for label, et, er in (("analytical model (rollout)", r["err_t"], r["err_r"]),
                              ("no motion", r["true_dt"], r["true_dr"])):
            t_med, t_mean, t_p90 = _stats(1e3 * et)
            r_med, r_mean, r_p90 = _stats(np.degrees(er))
            rel_t, n_t = _relative(et, r["true_dt"], 1e-3)
            rel_r, n_r = _relative(er, r["true_dr"], np.radians(1.0))
            rows.append(f"| {r['name']} | {label} | {t_med:.1f} / {t_mean:.1f} / {t_p90:.1f} | "
                        f"{r_med:.1f} / {r_mean:.1f} / {r_p90:.1f} | {rel_t}; {n_t} | "
                        f"{rel_r}; {n_r} |")
        st, mt = r["sim_touch"], r["model_touch"]
        t_med, _, t_p90 = _stats(1e3 * r["true_dt"])
        r_med, _, r_p90 = _stats(np.degrees(r["true_dr"]))
        notes.append(
            f"- {r['name']}: {r['n']} pushes; true motion median {t_med:.1f} mm (p90 "
            f"{t_p90:.1f}), {r_med:.1f} deg (p90 {r_p90:.1f}); model parameters l = "
            f"{1e3 * r['l']:.1f} mm (uniform-pressure guess), m = {r['m']:.2f}, table friction "
            f"{r['mu']:.2f}; contact agreement: both touched {int(np.sum(st & mt))}, sim only "
            f"{int(np.sum(st & ~mt))}, model only {int(np.sum(~st & mt))}, neither "
            f"{int(np.sum(~st & ~mt))}; median ratio of predicted to true rotation "
            f"{r['rot_ratio']:.2f}; the l that fits the simulation best (grid 0.5-2.5 x the "
            f"guess, least mean rotation error) is {1e3 * r['best_l']:.1f} mm, with mean "
            f"rotation error {np.degrees(r['best_err_r']):.1f} deg and median translation "
            f"error {1e3 * r['best_err_t']:.1f} mm; wall time: simulation {r['sim_s']:.1f} s, "
            f"rollout {1e3 * r['model_s']:.0f} ms for the batch."
        )
    return "\n".join(rows) + "\n\n" + "\n".join(notes)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pushes", type=int, default=100, help="random pushes per object")
    parser.add_argument("--objects", default="rect1,butter", help="comma-separated objects")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--repeats", type=int, default=None, help="ignored (run_all.py)")
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args(argv)

    runs = [run_object(name, args.pushes, args.seed) for name in args.objects.split(",")]
    table = format_results(runs)
    print(table)
    body = (
        "How well `push_core.rollout.rollout_push` (analytical quasi-static model) predicts the "
        "final object pose of random pybullet pushes (contact uniform on the outline, direction "
        "within +-60 deg of the inward normal, length 1-5 cm, 20 mm/s, object at rest at the "
        "origin; model driven by the executed pusher motion with l = "
        "`spec.limit_surface_guess()` and m = the simulated pusher friction). A measurement, "
        'not a pass/fail test; the "no motion" row is the error of predicting that nothing '
        "moves (= the true motion). Relative errors divide by the true translation (rotation) "
        "over the n pushes that moved the object by at least 1 mm (1 deg).\n\n" + table
    )
    command = "benchmarks/bench_model_fidelity.py " + " ".join(
        a for a in (argv if argv is not None else sys.argv[1:]) if a != "--no-write")
    if not args.no_write:
        update_section("bench_model_fidelity", format_section(
            "Analytical model vs pybullet (bench_model_fidelity)", command.strip(), body))
    return 0


if __name__ == "__main__":
    sys.exit(main())
