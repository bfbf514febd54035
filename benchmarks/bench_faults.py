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

With ``--robot arm`` the graph is the arm's (``push_executor_node`` and the simulated Panda)
and the scenarios are :data:`pushbot.runner.arm_faults.ARM_SCENARIOS` (with ``none``): the
executor killed mid-push and restarted 3 s later, the simulated arm (``sim_bridge_node``)
likewise, a 6 s hang of the simulator (SIGSTOP, SIGCONT), another client commanding the arm for
5 s, and the dry run. Judged by ground truth like the others; per scenario also the time from
the process being back (or the hang ending) to the next push (target <= 10 s) and how long the
planner waited for the robot; the dry run passes when it ends waiting (``robot unavailable:
disabled``) with 0 steps spent and a planned path published.

Writes ``docs/results/faults.md`` (``docs/results/faults_arm.md`` with ``--robot arm``;
``--no-write`` to only print). The machine is shared (2 cores): the load average is recorded
with the figures.

Usage::

    .venv/bin/python benchmarks/bench_faults.py [--runs N] [--frame-drop-runs N]
                                                [--objects a,b] [--scenarios a,b,...]
                                                [--robot pusher|arm] [--json FILE]
                                                [--no-write]
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


ARM_SUMMARY = ("Fault scenarios of the arm graph: executor and simulated-arm kills, a driver "
               "hang, a foreign trajectory publisher and the dry run.")
ARM_INTRO = " ".join("""Fault scenarios of the arm graph (five node processes over DDS:
push_executor_node drives the simulated Panda behind the controller's interface,
`pushbot.runner.arm_faults`): {objects}, mixed task (10 cm, 0.35 rad), random COM, ana, k = 3,
perception + EKF, trial indices 0..n-1. Success = the true end pose within 0.75 cm / 5 deg of
the true initial pose + the goal offset, 95 % Wilson interval. Mid-push scenarios act 1 s after
the first push that follows the episode's first executed push: `kill-executor` (SIGKILL of
push_executor_node, started again 3 s later), `kill-arm-sim` (SIGKILL of sim_bridge_node, started
again 3 s later with the scene and the object at its true pose; its clock starts again near 0),
`arm-hang` (sim_bridge_node stopped with SIGSTOP for 6 s, then SIGCONT), `foreign-trajectory`
(another client sends a one-point trajectory to a posture with the tool tip 1.5 cm above the
table every 0.2 s for 5 s on the controller topic); `dry-run`: the executor disabled before the
goal, which must end with the planner waiting (`robot unavailable: disabled`), 0 steps spent and
a planned path published. "back -> next push": wall time from the process being started again
(or the hang ending, or the foreign commands stopping) to the planner's next push (target
<= 10 s); "waited": wall time the planner said `robot unavailable`.""".split())


def wilson(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """95 % Wilson score interval of a binomial proportion."""
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def run_scenario(graph, name: str, n: int, obj: str, make_fault) -> list[dict]:
    """``n`` trials of scenario ``name`` (``make_fault(name)``) with object ``obj`` on
    ``graph``; one record each."""
    from push_core.episode import new_record
    from pushbot.runner.episode import GraphError
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
              + (f"recovery {rec['recovery_s']:.1f} s, " if rec.get("recovery_s") is not None
                 else "")
              + f"{rec['wall_s']:.0f} s", file=sys.stderr, flush=True)
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
    if name == "dry-run":
        ok_dry = sum(r["reason"].startswith("robot unavailable: disabled") and r["steps"] == 0
                     and r.get("executor_paths", 0) >= 1 for r in records)
        extra.append(f"ended waiting with 0 steps and a planned path {ok_dry}/{n}")
    recoveries = [r["recovery_s"] for r in records if r.get("recovery_s") is not None]
    if recoveries:
        extra.append(f"back -> next push {statistics.median(recoveries):.1f} s median, max "
                     f"{max(recoveries):.1f} s ({sum(v <= 10.0 for v in recoveries)}/"
                     f"{len(recoveries)} <= 10 s)")
    waits = [r["unavailable_s"] for r in records if r.get("unavailable_s")]
    if waits and name != "dry-run":  # the dry run ends as the wait begins
        extra.append(f"planner waited for the robot {statistics.median(waits):.1f} s median "
                     f"(max {max(waits):.1f} s) in {len(waits)}/{n}")
    ends = ", ".join(f"{k[:80]} {v}" for k, v in sorted(reasons.items()))
    return (f"| {name} | {obj} | {n} | {injected}/{n} | {ok}/{n} = {ok / n:.2f} "
            f"[{lo:.2f}, {hi:.2f}] | {err} | {push_text} | "
            f"{'; '.join([ends, *extra])} |")


def main() -> int:
    # Its own DDS domain (outside the test sessions' 1-100) unless the caller chose one.
    os.environ.setdefault("ROS_DOMAIN_ID", str(200 + os.getpid() % 30))
    from pushbot.ros2cli.discovery import sigterm_as_keyboard_interrupt
    from pushbot.runner.arm_faults import ARM_SCENARIOS, make_arm_fault
    from pushbot.runner.episode import GraphRunner
    from pushbot.runner.faults import SCENARIOS, make_fault

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per scenario (default 3)")
    parser.add_argument("--frame-drop-runs", type=int, default=20,
                        help="runs of the frame-drop scenario (default 20)")
    parser.add_argument("--robot", default="pusher", choices=("pusher", "arm"),
                        help="the graph: pusher (the simulator's finger) or arm (the executor "
                             "and the simulated Panda, with the arm scenarios)")
    parser.add_argument("--scenarios", default="",
                        help="comma-separated scenarios (default: all of the robot's)")
    parser.add_argument("--objects", default="butter",
                        help="comma-separated objects, each runs every scenario (default butter)")
    parser.add_argument("--json", type=Path, help="also write every record to this file")
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args()
    arm = args.robot == "arm"
    known = {"none": SCENARIOS["none"], **ARM_SCENARIOS} if arm else SCENARIOS
    names = [s for s in args.scenarios.split(",") if s] or list(known)
    unknown = [s for s in names if s not in known]
    if unknown:
        parser.error(f"unknown scenarios {unknown}; known: {', '.join(known)}")

    def factory(name: str):
        return make_arm_fault(name) if arm and name != "none" else make_fault(name)
    load_before = os.getloadavg()
    t0 = time.monotonic()
    results: dict[tuple[str, str], list[dict]] = {}
    objects = [o for o in args.objects.split(",") if o]
    with tempfile.TemporaryDirectory(prefix="bench_faults_") as tmp, \
            sigterm_as_keyboard_interrupt(), GraphRunner(log_dir=Path(tmp),
                                                         robot=args.robot) as graph:
        for obj in objects:
            for name in names:
                n = args.frame_drop_runs if name == "frame-drop" else args.runs
                results[name, obj] = run_scenario(graph, name, n, obj, factory)
    wall = time.monotonic() - t0
    load_after = os.getloadavg()
    if args.json:
        args.json.write_text(json.dumps({f"{k[0]} {k[1]}": v for k, v in results.items()},
                                        indent=1, default=str))
    rows = [summary_row(name, obj, recs) for (name, obj), recs in results.items()]
    intro = ARM_INTRO.format(objects=", ".join(objects)) if arm else " ".join(f"""Fault
        scenarios through the real graph (four node processes over DDS,
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
        episode (1 Hz: approximate).""".split())
    body = [
        intro,
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
        section = "faults_arm" if arm else "faults"
        title = ("Fault scenarios of the arm graph (`faults_arm`)" if arm
                 else "Fault scenarios in graph mode (`faults`)")
        update_section(section, format_section(title, command, "\n".join(body)),
                       summary=ARM_SUMMARY if arm else None,
                       data=f"every record in `{args.json}` (no render path)" if args.json
                       else None)
    return 0


if __name__ == "__main__":
    sys.exit(main())
