"""Pushing with the arm: the graph with push_executor_node and the simulated Panda
against the free pusher, on the same trials; writes docs/results/arm.md.

Both engines run ``pushbot eval push --graph`` trials (full system: rendered RGB-D -> CNN ->
EKF -> planner; ``state filter``, ana, k = 3, mixed task, random COM, seed 0, indices
0..n-1 per object), first with ``robot pusher`` and then with ``robot arm``. Reported per
engine and object: success by ground truth with its 95 % Wilson interval, mean pushes, mean true
end error of the successes, wall time per trial; for the arm, the tool tip's largest distance
from the commanded push line during contact (forward kinematics of the measured joints,
``executor/status`` ``contact_line_error_mm``, one value per executed push). Trial by trial:
the paired differences arm - pusher of pushes and end error with their 95 % intervals
(t-interval of the mean paired difference; "within noise" when the interval holds 0).

Usage::

    .venv/bin/python benchmarks/bench_arm.py [--trials 20] [--objects butter tri1 hex]
        [--no-write]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from pushbot.experiments.evaluate import EvalOptions, build_trials  # noqa: E402
from pushbot.experiments.pusht.adapter import wilson_interval  # noqa: E402
from pushbot.runner.episode import run_graph_trials  # noqa: E402
from pushbot.runner.protocol import Trial  # noqa: E402, F401 - the trials' type

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "out" / "bench_arm"
#: Two-sided 97.5 % quantiles of Student's t for the paired-difference intervals, by df.
_T975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
         9: 2.262, 10: 2.228, 15: 2.131, 20: 2.086, 30: 2.042, 40: 2.021, 60: 2.000}


def t975(df: int) -> float:
    """Student's t quantile 0.975 for ``df`` degrees of freedom (table, rounded down in df)."""
    if df <= 0:
        return math.inf
    return _T975[max(k for k in _T975 if k <= df)] if df < 120 else 1.96


def paired(a: list[float], b: list[float]) -> str:
    """Mean of ``b - a`` with its 95 % t-interval, and whether the interval holds 0."""
    diffs = [y - x for x, y in zip(a, b, strict=True)]
    if len(diffs) < 2:
        return "-"
    mean = statistics.mean(diffs)
    half = t975(len(diffs) - 1) * statistics.stdev(diffs) / math.sqrt(len(diffs))
    verdict = "within noise" if mean - half <= 0.0 <= mean + half else "differs"
    return f"{mean:+.2f} [{mean - half:+.2f}, {mean + half:+.2f}] ({verdict})"


def trials_for(objects: list[str], n: int) -> list[Trial]:
    """The trials of ``pushbot eval push --graph --robot arm --objects OBJECTS --tasks mixed
    --state filter --com random --trials N`` (the arm's acceptance command), built by the
    same function the command uses."""
    return build_trials(EvalOptions(objects=list(objects), tasks=["mixed"], state=["filter"],
                                    com=["random"], trials=n))


def _row(label: str, records: list[dict]) -> str:
    n = len(records)
    ok = [r for r in records if r["success"]]
    lo, hi = wilson_interval(len(ok), n)
    pushes = statistics.mean(r["steps"] for r in records)
    err = (f"{1e3 * statistics.mean(r['end_error_xy'] for r in ok):.1f} mm / "
           f"{math.degrees(statistics.mean(r['end_error_theta'] for r in ok)):.2f} deg"
           if ok else "-")
    wall = statistics.median(r["wall_s"] for r in records)
    lines = [e for r in records for e in r.get("contact_line_error_mm") or []]
    line = (f"{statistics.median(lines):.3f} / {max(lines):.3f}" if lines else "-")
    return (f"| {label} | {len(ok)}/{n} ({len(ok) / n:.3f}) | [{lo:.2f}, {hi:.2f}] | "
            f"{pushes:.2f} | {err} | {wall:.1f} | {line} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20, help="trials per object (default 20)")
    parser.add_argument("--objects", nargs="+", default=["butter", "tri1", "hex"])
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args()
    trials = trials_for(args.objects, args.trials)
    load_before = os.getloadavg()[0]
    results: dict[str, list[dict]] = {}
    walls: dict[str, float] = {}
    for robot in ("pusher", "arm"):
        t0 = time.monotonic()
        results[robot] = run_graph_trials(trials, out_dir=OUT / robot, progress=True,
                                          robot=robot)
        walls[robot] = time.monotonic() - t0
        (OUT / robot).mkdir(parents=True, exist_ok=True)
        (OUT / robot / "records.json").write_text(json.dumps(results[robot], indent=1))
    load_after = os.getloadavg()[0]

    header = ("| engine | success | 95 % Wilson | mean pushes | mean true end error (successes) "
              "| median wall s / trial | tool tip off the line, mm (median / max over pushes) |"
              "\n| --- | --- | --- | --- | --- | --- | --- |")
    rows = []
    for obj in args.objects:
        for robot in ("pusher", "arm"):
            rows.append(_row(f"{robot}, {obj}",
                             [r for r in results[robot] if r["trial"]["object"] == obj]))
    for robot in ("pusher", "arm"):
        rows.append(_row(f"**{robot}, all**", results[robot]))
    pusher, arm = results["pusher"], results["arm"]
    both = [(p, a) for p, a in zip(pusher, arm, strict=True) if p["success"] and a["success"]]
    same = sum(p["success"] == a["success"] for p, a in zip(pusher, arm, strict=True))
    failures = [f"{a['trial']['object']} #{a['trial']['index']}: {a['reason']}"
                for a in arm if not a["success"]]
    paired_errors = paired([1e3 * p["end_error_xy"] for p, _ in both],
                           [1e3 * a["end_error_xy"] for _, a in both])
    body = (
        f"Trials: {len(trials)} per engine ({', '.join(args.objects)} x {args.trials}; mixed "
        f"task, random COM, state filter, ana, k = 3, seed 0, indices 0..{args.trials - 1}: "
        f"the trials of `pushbot eval push --graph --robot arm --objects "
        f"{' '.join(args.objects)} --tasks mixed --state filter --com random --trials "
        f"{args.trials}`); "
        f"load average (1 min) {load_before:.1f} before, {load_after:.1f} after; wall time "
        f"pusher {walls['pusher'] / 60:.1f} min, arm {walls['arm'] / 60:.1f} min.\n\n"
        f"{header}\n" + "\n".join(rows) + "\n\n"
        f"Trial by trial: same outcome in {same}/{len(trials)}; over the {len(both)} trials "
        f"both succeeded, arm - pusher: pushes "
        f"{paired([p['steps'] for p, _ in both], [a['steps'] for _, a in both])}, true end "
        f"error mm "
        f"{paired_errors}"
        f" (mean difference with its 95 % t-interval).\n\n"
        f"Arm failures: {'; '.join(failures) if failures else 'none'}.\n")
    command = ("python benchmarks/bench_arm.py --trials "
               f"{args.trials} --objects {' '.join(args.objects)}")
    text = format_section("Pushing with the arm: push_executor_node and the simulated Panda "
                          "vs the free pusher (`arm`)", command, body)
    print(text)
    if not args.no_write:
        update_section("arm", text, data="every record in `out/bench_arm/<robot>/records.json` "
                                         "(kept outside the repository; no render path)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
