"""Arm episodes on a loaded machine: no tracking, start or joint-state-window fault of the
executor while two benchmark processes compete for the CPU; writes docs/results/arm_load.md.

The graph with ``robot arm`` (full system: rendered RGB-D -> CNN -> EKF -> planner ->
push_executor_node -> the simulated Panda; ``state filter``, ana, k = 3, mixed task, random
COM, seed 21, indices 0..n-1 per object) runs its trials while ``--load`` processes (default 2)
run in-process protocol evaluations (``pushbot eval push --workers 1``: pybullet, the CNN, the
EKF and the planner, the work of a benchmark) beside it. Every stop of
the arm the executor reports is counted by its kind, from ``pusher/refused`` (kind ``fault``,
reason ``stopped (<kind>): ...``): ``deviation`` (a joint off the plan), ``no_start``,
``stale`` (the joint states' window). Reported: success by ground truth with its 95 % Wilson
interval, the faults by kind, other refusals by kind, the load average before, during and after.

Usage::

    .venv/bin/python benchmarks/bench_arm_load.py [--trials 20] [--objects butter tri1 hex]
        [--load 2] [--no-write]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from pushbot.experiments.evaluate import EvalOptions, build_trials  # noqa: E402
from pushbot.experiments.pusht.adapter import wilson_interval  # noqa: E402
from pushbot.runner.episode import GraphRunner, run_graph_trials  # noqa: E402
from pushbot.runner.protocol import Trial  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "out" / "bench_arm_load"
#: The executor's stop kinds that are robot faults: none may appear under load.
FAULT_KINDS = ("deviation", "no_start", "stale")
_STOPPED = re.compile(r"stopped \((\w+)\)")


def start_load(n: int, out: Path) -> list[subprocess.Popen]:
    """``n`` in-process evaluations of many trials (each far longer than the arm's run)."""
    exe = Path(sys.executable).parent / "pushbot"
    procs = []
    for i in range(n):
        procs.append(subprocess.Popen(
            [str(exe), "eval", "push", "--objects", "rect1", "hex", "--tasks", "mixed",
             "--state", "filter", "--com", "random", "--trials", "500", "--seed", str(100 + i),
             "--workers", "1", "--no-progress", "--out", str(out / f"load_{i}")],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
    return procs


def stop_load(procs: list[subprocess.Popen]) -> None:
    for proc in procs:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
    for proc in procs:
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=20, help="trials per object (default 20)")
    ap.add_argument("--objects", nargs="+", default=["butter", "tri1", "hex"])
    ap.add_argument("--load", type=int, default=2, help="benchmark processes beside (default 2)")
    ap.add_argument("--no-write", action="store_true", help="do not write docs/results")
    args = ap.parse_args()

    trials: list[Trial] = build_trials(EvalOptions(
        objects=args.objects, tasks=["mixed"], methods=["ana"], k=[3], state=["filter"],
        com=["random"], trials=args.trials, seed=21))
    faults: collections.Counter[str] = collections.Counter()
    refusals: collections.Counter[str] = collections.Counter()
    per_trial: list[dict[str, Any]] = []

    def run(graph: GraphRunner, trial: Trial) -> dict[str, Any]:
        n = len(graph.rec.refusals)
        record = graph.run(trial)
        mine = collections.Counter()
        for r in graph.rec.refusals[n:]:
            kind = r.get("kind", "")
            match = _STOPPED.search(r.get("reason", "")) if kind == "fault" else None
            if match:
                faults[match.group(1)] += 1
                mine[match.group(1)] += 1
            else:
                refusals[kind] += 1
        per_trial.append({"trial": trial.as_dict(), "success": record["success"],
                          "faults": dict(mine)})
        return record

    OUT.mkdir(parents=True, exist_ok=True)
    load_dir = Path(tempfile.mkdtemp(prefix="arm_load_"))
    load0 = os.getloadavg()[0]
    procs = start_load(args.load, load_dir)
    loads: list[float] = []
    started = time.monotonic()
    try:
        time.sleep(5.0)  # the load processes are past their start-up
        records = run_graph_trials(trials, out_dir=OUT, robot="arm", run=run)
        loads.append(os.getloadavg()[0])
        alive = sum(p.poll() is None for p in procs)
    finally:
        stop_load(procs)
    wall = time.monotonic() - started
    load1 = os.getloadavg()[0]
    (OUT / "records.json").write_text(json.dumps(records, indent=1, default=str))
    (OUT / "faults.json").write_text(json.dumps(per_trial, indent=1))

    n = len(records)
    ok = sum(r["success"] for r in records)
    lo, hi = wilson_interval(ok, n)
    robot_faults = sum(faults[k] for k in FAULT_KINDS)
    body = "\n".join([
        f"Arm graph, {n} trials ({', '.join(args.objects)} x {args.trials}; mixed, filter, ana, "
        f"k = 3, random COM, seed 21) with {args.load} in-process protocol evaluations "
        f"(`pushbot eval push --workers 1`) beside it; {alive} of them still running at the "
        f"end (each runs far longer than the arm's trials).",
        "",
        "| trials | success | 95 % Wilson | faults deviation / no_start / stale | other stops "
        "| other refusals | load avg (1 min) before / at the end / after |",
        "| --- | --- | --- | --- | --- | --- | --- |",
        f"| {n} | {ok}/{n} | [{lo:.2f}, {hi:.2f}] | "
        f"{faults['deviation']} / {faults['no_start']} / {faults['stale']} | "
        f"{dict((k, v) for k, v in faults.items() if k not in FAULT_KINDS) or '-'} | "
        f"{dict(refusals) or '-'} | {load0:.1f} / {loads[-1]:.1f} / {load1:.1f} |",
        "",
        f"Wall time {wall / 60:.1f} min. Verdict: "
        + ("no deviation, no_start or joint-state-window fault"
           if robot_faults == 0 else f"{robot_faults} robot fault(s) under load")
        + f"; {ok}/{n} reached the goal.",
    ])
    command = "python benchmarks/bench_arm_load.py " + " ".join(sys.argv[1:])
    section = format_section("Arm episodes on a loaded machine", command, body)
    print(section)
    if not args.no_write:
        update_section("arm_load", section,
                       summary=f"arm graph under load: {ok}/{n}, robot faults {robot_faults}")


if __name__ == "__main__":
    main()
