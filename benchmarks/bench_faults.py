"""Fault scenarios in graph mode, repeated (docs/design/faults.md).

Every scenario of :data:`pushbot.runner.faults.SCENARIOS` runs protocol trials (each object of
``--objects``, default butter; mixed task, random COM, ana, k = 3, state ``filter``, trial
indices 0, 1, 2, ...: seeded scenes, goals and planner seeds; the bridge's fault draws seeded
from the trial) through the real graph
(:class:`pushbot.runner.episode.GraphRunner`: four node processes over DDS, one graph for the
whole run, restarted after a trial that broke it). Per scenario: runs, success by ground truth
(the true end pose against the true initial pose + the goal offset, the task's 0.75 cm / 5 deg
region), true end errors, pushes sent, how many runs the fault was injected in, and
scenario-specific counts (goal switches noted by the planner, goal left after a knock, the
bridge's dropped / delayed / reordered frames and refused pushes, re-anchored perceptions).
Scenarios are described in :mod:`pushbot.runner.faults`.

Writes ``docs/results/faults.md`` (``--no-write`` to only print). The
machine is shared (2 cores): the load average is recorded with the figures.

Usage::

    .venv/bin/python benchmarks/bench_faults.py [--runs N] [--frame-drop-runs N]
                                                [--objects a,b] [--scenarios a,b,...]
                                                [--json FILE] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def wilson(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """95 % Wilson score interval of a binomial proportion."""
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def run_scenario(graph, name: str, n: int, obj: str) -> list[dict]:
    """``n`` trials of scenario ``name`` with object ``obj`` on ``graph``; one record each."""
    from push_core.episode import new_record
    from pushbot.runner.episode import GraphError
    from pushbot.runner.faults import make_fault
    from pushbot.runner.protocol import Trial

    records = []
    before = dict(getattr(graph, "_bench_counts", {}))
    for i in range(n):
        trial = Trial(object=obj, task="mixed", method="ana", k=3, state="filter",
                      com="random", index=i, seed=0)
        fault = make_fault(name)
        t0 = time.monotonic()
        try:
            rec = graph.run(trial, fault)
        except GraphError as exc:
            rec = new_record(trial.as_dict(), reason=f"graph error: {exc}", engine="graph")
            rec.update(fault="error", fault_injected=fault.injected, pushes_sent=None)
            graph.restart()
        rec["wall_s"] = time.monotonic() - t0
        # The bridge's counters are cumulative over its process (reset by a graph restart).
        counts = rec.get("bridge_counts") or {}
        rec["bridge_events"] = {k: v - before.get(k, 0) if v >= before.get(k, 0) else v
                                for k, v in counts.items()}
        before = counts or before
        graph._bench_counts = before
        records.append(rec)
        err = rec.get("end_error_xy")
        print(f"{name} {obj} #{i}: {rec['reason'][:200]}, success {rec['success']}, "
              + (f"end {1e3 * err:.1f} mm / {math.degrees(rec['end_error_theta']):.1f} deg, "
                 if err is not None else "")
              + f"pushes {rec.get('pushes_sent')}, injected {rec.get('fault_injected')}, "
              f"{rec['wall_s']:.0f} s", file=sys.stderr, flush=True)
    return records


def summary_row(name: str, obj: str, records: list[dict]) -> str:
    n = len(records)
    ok = sum(bool(r["success"]) for r in records)
    lo, hi = wilson(ok, n)
    errs = [r for r in records if r.get("end_error_xy") is not None]
    err = ("-" if not errs else
           f"{1e3 * statistics.median(r['end_error_xy'] for r in errs):.1f} mm / "
           f"{math.degrees(statistics.median(r['end_error_theta'] for r in errs)):.1f} deg "
           f"(max {1e3 * max(r['end_error_xy'] for r in errs):.1f} mm / "
           f"{math.degrees(max(r['end_error_theta'] for r in errs)):.1f} deg)")
    pushes = [r["pushes_sent"] for r in records if r.get("pushes_sent") is not None]
    push_text = (f"{statistics.median(pushes):g} ({min(pushes)}-{max(pushes)})" if pushes
                 else "-")
    injected = sum(bool(r.get("fault_injected")) for r in records)
    reasons: dict[str, int] = {}
    for r in records:
        key = r["reason"] if not r["reason"].startswith("graph error") else "graph error"
        reasons[key] = reasons.get(key, 0) + 1
    extra = []
    events: dict[str, int] = {}
    for r in records:
        for k, v in (r.get("bridge_events") or {}).items():
            events[k] = events.get(k, 0) + v
    shown = {"frame-drop": "frames_dropped", "frame-delay": "frames_delayed",
             "push-refusal": "pushes_refused_fault", "knock": "knocks"}
    if name in shown:
        extra.append(f"{shown[name]} {events.get(shown[name], 0)} (of "
                     f"{events.get('pushes_executed', 0)} pushes executed)")
    if name == "frame-delay":
        extra.append(f"frames_reordered {events.get('frames_reordered', 0)}")
    if name == "kill-segmentation":
        extra.append(f"re-anchored {sum(r.get('perception_anchored', 0) >= 1 for r in records)}"
                     f"/{n}")
    if name == "kill-ekf":
        gaps = [r["first_estimate_after_restart_s"] for r in records
                if r.get("first_estimate_after_restart_s") is not None]
        if gaps:
            extra.append(f"first estimate {statistics.median(gaps):.1f} s after the restart "
                         f"(median; max {max(gaps):.1f} s; process start included)")
    if name == "second-goal":
        extra.append(f"goal switch noted {sum(r.get('goal_switches', 0) >= 1 for r in records)}"
                     f"/{n}")
    if name == "knock":
        extra.append(f"left the goal seen {sum(r.get('left_goal', 0) >= 1 for r in records)}"
                     f"/{n}")
    ends = ", ".join(f"{k} {v}" for k, v in sorted(reasons.items()))
    return (f"| {name} | {obj} | {n} | {injected}/{n} | {ok}/{n} = {ok / n:.2f} "
            f"[{lo:.2f}, {hi:.2f}] | {err} | {push_text} | "
            f"{'; '.join([ends, *extra])} |")


def main() -> int:
    # Its own DDS domain (outside the test sessions' 1-100) unless the caller chose one.
    os.environ.setdefault("ROS_DOMAIN_ID", str(200 + os.getpid() % 30))
    from pushbot.ros2cli.discovery import sigterm_as_keyboard_interrupt
    from pushbot.runner.episode import GraphRunner
    from pushbot.runner.faults import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per scenario (default 3)")
    parser.add_argument("--frame-drop-runs", type=int, default=20,
                        help="runs of the frame-drop scenario (default 20)")
    parser.add_argument("--scenarios", default=",".join(SCENARIOS),
                        help="comma-separated scenarios (default: all)")
    parser.add_argument("--objects", default="butter",
                        help="comma-separated objects, each runs every scenario (default butter)")
    parser.add_argument("--json", type=Path, help="also write every record to this file")
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args()
    names = [s for s in args.scenarios.split(",") if s]
    unknown = [s for s in names if s not in SCENARIOS]
    if unknown:
        parser.error(f"unknown scenarios {unknown}; known: {', '.join(SCENARIOS)}")
    load_before = os.getloadavg()
    t0 = time.monotonic()
    results: dict[tuple[str, str], list[dict]] = {}
    objects = [o for o in args.objects.split(",") if o]
    with tempfile.TemporaryDirectory(prefix="bench_faults_") as tmp, \
            sigterm_as_keyboard_interrupt(), GraphRunner(log_dir=Path(tmp)) as graph:
        for obj in objects:
            for name in names:
                n = args.frame_drop_runs if name == "frame-drop" else args.runs
                results[name, obj] = run_scenario(graph, name, n, obj)
    wall = time.monotonic() - t0
    load_after = os.getloadavg()
    if args.json:
        args.json.write_text(json.dumps({f"{k[0]} {k[1]}": v for k, v in results.items()},
                                        indent=1, default=str))
    rows = [summary_row(name, obj, recs) for (name, obj), recs in results.items()]
    body = [
        " ".join(f"""Fault scenarios through the real graph (four node processes over DDS,
        `pushbot.runner.faults`): {', '.join(objects)}, mixed task (10 cm, 0.35 rad), random COM,
        ana, k = 3, perception + EKF, trial indices 0..n-1 (seeded scenes, goals, planner seeds
        and fault draws). Success = the true end pose within 0.75 cm / 5 deg of the true
        initial pose + the goal offset (for `second-goal`: the second goal's), 95 % Wilson
        interval. Scenarios: `none` (no fault), `kill-<node>` (SIGKILL after the first executed
        push, started again), `frame-drop` (20 % of camera frame publications dropped),
        `frame-delay` (30 % held back and published right after the next newer frame: late and
        out of order), `push-refusal` (20 % of valid pushes refused by the
        bridge), `knock` (object displaced by (30, -20) mm and 0.25 rad on `sim/knock` after
        `goal reached`; the episode must reach the goal again), `foreign-push` (after `goal
        reached` another client sends a push on `planner/push` through the object, from 2 cm
        outside its circumscribed circle to 2 cm past its origin; the same end rule; pushes sent
        include it), `second-goal` (another, volatile
        client sends a goal shifted by (-40, 30) mm and -0.2 rad after the first push). Event
        counts are the bridge's and the perception's /diagnostics counters at the end of each
        episode (1 Hz: approximate).""".split()),
        "",
        "| scenario | object | runs | fault injected | success (ground truth) | median end "
        "error (max) | pushes sent, median (range) | ends |",
        "|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Wall time {wall / 60:.1f} min; load average {load_before[0]:.1f} before, "
        f"{load_after[0]:.1f} after.",
    ]
    print("\n".join(body))
    if not args.no_write:
        command = ("python benchmarks/bench_faults.py " + " ".join(sys.argv[1:])).strip()
        update_section("faults", format_section(
            "Fault scenarios in graph mode (`faults`)", command, "\n".join(body)),
            data=f"every record in `{args.json}` (no render path)" if args.json else None)
    return 0


if __name__ == "__main__":
    sys.exit(main())
