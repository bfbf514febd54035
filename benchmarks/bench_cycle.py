"""Robot time per push cycle: the arm without a park between pushes, today's arm
that parks after every push, and the free pusher, on the same trials; writes docs/RESULTS.md
section ``cycle``.

Every engine runs the same ``pushbot eval push --graph`` trials (full system: rendered RGB-D ->
CNN -> EKF -> planner; butter / tri1 / hex x mixed, state filter, random COM, ana, k = 3, seed
21, indices 0..n-1 per object) through :class:`pushbot.runner.episode.GraphRunner`:

- ``arm``: this checkout's nodes (push_executor_node withdrawing to a clear pose, chaining);
- ``arm, today``: the nodes of another installation (``--baseline-exe``: the ``pushbot``
  executable of a checkout of the commit this work started from, with its own venv), driven by
  this checkout's client, so that both are measured the same way;
- ``pusher``: the simulator's free pusher (this checkout).

Reported per engine: success by ground truth (95 % Wilson interval), mean pushes, mean true end
error of the successes, ``cycle_s`` (simulated seconds between successive pushes' commands, the
episode record's) median and 90th percentile over all cycles, ``robot_time_s`` (goal to the
final stop) median per episode; paired against today's arm: pushes, end error (mean paired
differences with 95 % t-intervals) and the robot time ratio. Then each cycle split into its
stages (medians over the cycles whose push was executed), in simulated seconds:

- arm (from ``executor/status``: the trajectory's start and its stages): ``start`` (push
  command -> the trajectory's first point: the executor's planning, ``start_delay``),
  ``transit``, ``descend``, ``push``, ``retreat`` (retreat, lift, withdraw), ``frame wait`` (the
  trajectory's end -> the stamp of the frame the next estimate came from: the simulator lets
  the arm and the object settle), ``plan`` (that frame -> the next push command: perception,
  estimation, planning; on the simulated graph resting time passes as wall time);
- pusher (from ``pusher/executed``): ``descend`` (command -> the push's start: the bridge's
  air transfer is instantaneous, then the finger is lowered), ``push``, ``retreat`` (retract,
  lift and the object settling, to the frame), ``plan``.

Usage::

    .venv/bin/python benchmarks/bench_cycle.py [--trials 20] [--objects butter tri1 hex]
        [--baseline-exe /tmp/cycle-base/.venv/bin/pushbot] [--engines arm today pusher]
        [--reuse arm] [--no-write]
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
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402
from bench_arm import paired  # noqa: E402

from pushbot.experiments.evaluate import EvalOptions, build_trials  # noqa: E402
from pushbot.experiments.pusht.adapter import wilson_interval  # noqa: E402
from pushbot.runner.episode import GraphRunner, run_graph_trials  # noqa: E402
from pushbot.runner.protocol import Trial  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "out" / "bench_cycle"
ARM_STAGES = ("start", "transit", "descend", "push", "retreat", "frame wait", "plan")
PUSHER_STAGES = ("descend", "push", "retreat", "plan")
#: Executor stages counted as each column (a lead-in of a chained push is the transit's).
COLUMNS = {"clear": "transit", "transit": "transit", "descend": "descend", "push": "push",
           "retreat": "retreat", "lift": "retreat", "withdraw": "retreat", "park": "retreat"}
ENGINES = {"arm": ("arm", False), "today": ("arm", True), "pusher": ("pusher", False)}
LABELS = {"arm": "arm", "today": "arm, today (park after every push)", "pusher": "pusher"}


def trials_for(objects: list[str], n: int) -> list[Trial]:
    """The trials of ``pushbot eval push --graph --robot arm --objects OBJECTS --tasks mixed
    --state filter --com random --trials N --seed 21``."""
    return build_trials(EvalOptions(objects=list(objects), tasks=["mixed"], state=["filter"],
                                    com=["random"], trials=n, seed=21))


def _first_after(stamps: list[float], t: float, until: float) -> float | None:
    return next((s for s in sorted(stamps) if t - 1e-6 <= s <= until + 1e-6), None)


def arm_stages(pushes: list[float], status: list[dict[str, str]], estimates: list[float]
               ) -> list[dict[str, float]]:
    """Per cycle (push k -> push k + 1) whose push was executed: seconds per stage."""
    plans = {}
    for s in status:
        if s.get("push") and s.get("stages") and s.get("plan_t0"):
            plans.setdefault(round(float(s["push"]), 6), s)
    out = []
    for c0, c1 in zip(pushes, pushes[1:], strict=False):
        plan = plans.get(round(c0, 6))
        if plan is None:
            continue
        t0 = float(plan["plan_t0"])
        spans = [(n, float(a), float(b)) for n, a, b in
                 (w.split(":") for w in plan["stages"].split())]
        end = t0 + spans[-1][2]
        frame = _first_after(estimates, end, c1)
        if frame is None:
            continue
        split = dict.fromkeys(ARM_STAGES, 0.0)
        split["start"] = t0 + spans[0][1] - c0
        for i, (name, a, b) in enumerate(spans):
            lead_in = i == 0 and name not in ("clear", "transit")  # a chained push's
            split["transit" if lead_in else COLUMNS.get(name, "retreat")] += b - a
        split["frame wait"], split["plan"] = frame - end, c1 - frame
        out.append(split)
    return out


def pusher_stages(pushes: list[float], executed: list[tuple[float, float]],
                  estimates: list[float]) -> list[dict[str, float]]:
    """Per cycle whose push was executed (``pusher/executed`` start and end in it)."""
    out = []
    for c0, c1 in zip(pushes, pushes[1:], strict=False):
        done = next(((a, b) for a, b in executed if c0 <= a and b <= c1), None)
        frame = None if done is None else _first_after(estimates, done[1], c1)
        if frame is None:
            continue
        out.append({"descend": done[0] - c0, "push": done[1] - done[0],
                    "retreat": frame - done[1], "plan": c1 - frame})
    return out


def run_engine(trials: list[Trial], engine: str, baseline_exe: Path | None, domain: int | None
               ) -> tuple[list[dict[str, Any]], list[dict[str, float]], float]:
    """The records, the stage splits of every cycle and the wall time of one engine."""
    robot, today = ENGINES[engine]
    if domain is not None:
        os.environ["ROS_DOMAIN_ID"] = str(domain)
    splits: list[dict[str, float]] = []

    def run(graph: GraphRunner, trial: Trial) -> dict[str, Any]:
        rec = graph.rec
        n_push, n_exec, n_status, n_est = (len(rec.push_stamps), len(rec.executed),
                                           len(rec.executor_status), len(rec.est))
        record = graph.run(trial)
        pushes, estimates = rec.push_stamps[n_push:], [s for s, _ in rec.est[n_est:]]
        splits.extend(arm_stages(pushes, rec.executor_status[n_status:], estimates)
                      if robot == "arm" else
                      pusher_stages(pushes, [(a, b) for _, a, b in rec.executed[n_exec:]],
                                    estimates))
        return record

    started = time.monotonic()
    records = run_graph_trials(trials, out_dir=OUT / engine, robot=robot,
                               node_exe=baseline_exe if today else None, run=run)
    return records, splits, time.monotonic() - started


def reuse_engine(trials: list[Trial], engine: str
                 ) -> tuple[list[dict[str, Any]], list[dict[str, float]], float]:
    """An earlier run's records and splits of ``engine`` (``--reuse``); the wall time is the
    sum of its episodes'. ``SystemExit`` unless they are of the same trials."""
    records = json.loads((OUT / engine / "records.json").read_text())
    splits = json.loads((OUT / engine / "splits.json").read_text())
    if [r["trial"] for r in records] != [t.as_dict() for t in trials]:
        raise SystemExit(f"--reuse {engine}: {OUT / engine / 'records.json'} holds other trials")
    return records, splits, float(sum(r.get("wall_s") or 0.0 for r in records))


def _row(label: str, records: list[dict[str, Any]]) -> str:
    n = len(records)
    ok = [r for r in records if r["success"]]
    lo, hi = wilson_interval(len(ok), n)
    cycles = [c for r in records for c in r.get("cycle_s") or []]
    robot = [r["robot_time_s"] for r in records if r.get("robot_time_s") is not None]
    err = (f"{1e3 * statistics.mean(r['end_error_xy'] for r in ok):.1f} mm / "
           f"{math.degrees(statistics.mean(r['end_error_theta'] for r in ok)):.2f} deg"
           if ok else "-")
    cyc = (f"{statistics.median(cycles):.2f} / {np.percentile(cycles, 90):.2f}" if cycles
           else "-")
    return (f"| {label} | {len(ok)}/{n} | [{lo:.2f}, {hi:.2f}] | "
            f"{statistics.mean(r['steps'] for r in records):.2f} | {err} | {cyc} | "
            f"{len(cycles)} | {statistics.median(robot):.1f} |" if robot else "")


def _split_table(splits: dict[str, list[dict[str, float]]]) -> str:
    lines = ["| engine | cycles | " + " | ".join(ARM_STAGES) + " | sum of medians |",
             "| --- | --- |" + " --- |" * (len(ARM_STAGES) + 1)]
    for engine, rows in splits.items():
        if not rows:
            continue
        cells = []
        for stage in ARM_STAGES:
            values = [r[stage] for r in rows if stage in r]
            cells.append(f"{statistics.median(values):.2f}" if values else "-")
        total = sum(float(c) for c in cells if c != "-")
        lines.append(f"| {LABELS[engine]} | {len(rows)} | " + " | ".join(cells)
                     + f" | {total:.2f} |")
    return "\n".join(lines)


def _verdicts(results: dict[str, list[dict[str, Any]]]) -> list[str]:
    out = []
    arm, today, pusher = results.get("arm"), results.get("today"), results.get("pusher")
    if arm:
        ok = sum(r["success"] for r in arm)
        cycles = [c for r in arm for c in r.get("cycle_s") or []]
        need = math.ceil(len(arm) * 59 / 60)
        out.append(f"success {ok}/{len(arm)} (target >= {need}): "
                   f"{'met' if ok >= need else 'NOT met'}")
        if cycles:
            med, p90 = statistics.median(cycles), float(np.percentile(cycles, 90))
            out.append(f"median cycle {med:.2f} s (target <= 5.0): "
                       f"{'met' if med <= 5.0 else 'NOT met'}; p90 {p90:.2f} s (target <= 7): "
                       f"{'met' if p90 <= 7.0 else 'NOT met'}")
    if arm and today:
        both = [(t, a) for t, a in zip(today, arm, strict=True)]
        dp = statistics.mean(a["steps"] - t["steps"] for t, a in both)
        out.append(f"mean pushes {statistics.mean(a['steps'] for a in arm):.2f} vs today's "
                   f"{statistics.mean(t['steps'] for t in today):.2f} (target within +0.3): "
                   f"{'met' if dp <= 0.3 else 'NOT met'} ({dp:+.2f})")
        ratio = [a["robot_time_s"] / t["robot_time_s"] for t, a in both
                 if a.get("robot_time_s") and t.get("robot_time_s")]
        if ratio:
            med = statistics.median(ratio)
            out.append(f"episode robot time / today's, median over paired trials {med:.2f} "
                       f"(target <= 0.4): {'met' if med <= 0.4 else 'NOT met'}")
    if pusher:
        cycles = [c for r in pusher for c in r.get("cycle_s") or []]
        if cycles:
            med = statistics.median(cycles)
            out.append(f"pusher median cycle {med:.2f} s (target <= 3.5): "
                       f"{'met' if med <= 3.5 else 'NOT met'}")
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20, help="trials per object (default 20)")
    parser.add_argument("--objects", nargs="+", default=["butter", "tri1", "hex"])
    parser.add_argument("--engines", nargs="+", default=["arm", "today", "pusher"],
                        choices=list(ENGINES))
    parser.add_argument("--baseline-exe", type=Path, default=None,
                        help="the pushbot executable of the installation whose nodes are "
                             "'today' (required with engine today)")
    parser.add_argument("--domain", type=int, default=None, help="ROS_DOMAIN_ID to run in")
    parser.add_argument("--reuse", nargs="+", default=[], choices=list(ENGINES),
                        help="engines whose records and splits are read from an earlier run's "
                             "out/bench_cycle/<engine>/ instead of run again (same trials)")
    parser.add_argument("--no-write", action="store_true", help="do not update docs/RESULTS.md")
    args = parser.parse_args()
    if "today" in args.engines and (args.baseline_exe is None or not args.baseline_exe.exists()):
        parser.error("engine 'today' needs --baseline-exe (an existing pushbot executable)")
    trials = trials_for(args.objects, args.trials)
    load_before = os.getloadavg()[0]
    results, splits, walls = {}, {}, {}
    for engine in args.engines:
        if engine in args.reuse:
            results[engine], splits[engine], walls[engine] = reuse_engine(trials, engine)
            continue
        results[engine], splits[engine], walls[engine] = run_engine(
            trials, engine, args.baseline_exe, args.domain)
        (OUT / engine).mkdir(parents=True, exist_ok=True)
        (OUT / engine / "records.json").write_text(json.dumps(results[engine], indent=1))
        (OUT / engine / "splits.json").write_text(json.dumps(splits[engine], indent=1))
    load_after = os.getloadavg()[0]

    header = ("| engine | success | 95 % Wilson | mean pushes | mean true end error (successes)"
              " | cycle s median / p90 | cycles | robot time per episode, median s |\n"
              "| --- | --- | --- | --- | --- | --- | --- | --- |")
    rows = []
    for engine in args.engines:
        for obj in args.objects:
            rows.append(_row(f"{LABELS[engine]}, {obj}",
                             [r for r in results[engine] if r["trial"]["object"] == obj]))
        rows.append(_row(f"**{LABELS[engine]}, all**", results[engine]))
    body = [f"Trials: {len(trials)} per engine ({', '.join(args.objects)} x {args.trials}; "
            f"mixed task, random COM, state filter, ana, k = 3, seed 21: the trials of "
            f"`pushbot eval push --graph --robot arm --objects {' '.join(args.objects)} --tasks "
            f"mixed --state filter --com random --trials {args.trials} --seed 21`); 'today' "
            f"is the nodes of {args.baseline_exe} driven by this checkout's client. Load "
            f"average (1 min) {load_before:.1f} before, {load_after:.1f} after (2 cores shared "
            f"with other jobs: the graph's resting time passes as wall time, so the machine's "
            f"load shows in `start` and `plan`); wall time "
            + ", ".join(f"{e} {walls[e] / 60:.1f} min" for e in args.engines) + ".",
            "", header, *[r for r in rows if r], ""]
    if "arm" in results and "today" in results:
        both = [(t, a) for t, a in zip(results["today"], results["arm"], strict=True)
                if t["success"] and a["success"]]
        body.append(f"Paired over the {len(both)} trials both succeeded, arm - today: pushes "
                    f"{paired([t['steps'] for t, _ in both], [a['steps'] for _, a in both])}, "
                    f"true end error mm "
                    f"{paired([1e3 * t['end_error_xy'] for t, _ in both], [1e3 * a['end_error_xy'] for _, a in both])}"  # noqa: E501
                    " (mean difference with its 95 % t-interval).")
        body.append("")
    body += ["**Stages of a cycle** (medians over the cycles whose push was executed, "
             "simulated s; the columns' medians need not add up to the cycle's):", "",
             _split_table(splits), "",
             "Acceptance (the cycle's goals): " + "; ".join(_verdicts(results)) + "."]
    failures = [f"{e}: {r['trial']['object']} #{r['trial']['index']}: {r['reason']}"
                for e in args.engines for r in results[e] if not r["success"]]
    body += ["", f"Failures: {'; '.join(failures) if failures else 'none'}."]
    command = (f"python benchmarks/bench_cycle.py --trials {args.trials} --objects "
               f"{' '.join(args.objects)} --engines {' '.join(args.engines)}"
               + (f" --baseline-exe {args.baseline_exe}" if args.baseline_exe else ""))
    text = format_section("Robot time per push cycle: no park between pushes (`cycle`)",
                          command, "\n".join(body))
    print(text)
    if not args.no_write:
        update_section("cycle", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
