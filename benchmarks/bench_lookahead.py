"""Lookahead and adaptation: planning time and closed-loop pushes against greedy.

1. **Planning time** per step (``Planner.plan``) with ``horizon`` 1 (greedy), 2 and 3 on
   butter's and tri1's outlines (1.5 mm spacing), random poses and goals as
   ``bench_planner`` (its timing harness); target: median <= 100 ms per step.
2. **Closed loop** in-process (``pushbot.experiments.inprocess.EpisodeRunner``: the
   protocol's trials of ``pushbot.runner.protocol``, the same scenes and goals for every
   variant), tri1, butter and hex x translation, mixed and rotation, COM at the centre; variants:

   - ``greedy``: the current planner (``horizon = 1``), the estimator as it is;
   - ``lookahead``: ``horizon`` H (``--horizon``, default 2), beam 8, push cost 20 mm;
   - ``lookahead+adapt``: the same with ``avoid_contradicted`` (push_core.episode rule 8) and
     the estimator's ``relearn``.

   Columns: success, mean pushes of the successful trials, the physical minimum,
   ``pushes / min`` (benchmarks/_pushes.py) and the median planning time in the loop.

Writes ``docs/results/bench_lookahead.md`` (``bench_lookahead_gt`` with
``--state gt``; ``bench_lookahead_speed`` with ``--speed-only``).

Usage::

    .venv/bin/python benchmarks/bench_lookahead.py [--state gt|filter] [--trials N]
        [--repeats N] [--horizon H] [--variants ...] [--no-write]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _pushes import pushes_over_minimum, trial_minimum  # noqa: E402
from _results import format_section, update_section  # noqa: E402
from bench_planner import planning_cases, time_ms  # noqa: E402

from push_core.objects import load_object  # noqa: E402
from push_core.planner import Planner, PlannerConfig, prepare_outline  # noqa: E402
from pushbot.experiments.inprocess import EpisodeRunner  # noqa: E402
from pushbot.runner.protocol import make_trials  # noqa: E402

TARGET_MS = 100.0
OBJECTS = ("tri1", "butter", "hex")
TASKS = ("translation", "mixed", "rotation")
VARIANTS = ("greedy", "lookahead", "lookahead+adapt")


def speed_rows(repeats: int, horizons: tuple[int, ...]) -> list[str]:
    """Timing rows: object, horizon, median / p10 / p90 ms, median over the greedy median."""
    rows = []
    for obj in ("butter", "tri1"):
        spec = load_object(obj)
        outline = prepare_outline(*spec.outline(0.0015))
        cases = planning_cases(spec)
        greedy = None
        for h in horizons:
            planner = Planner(PlannerConfig(horizon=h))
            it = iter(range(10**9))

            def step(planner: Planner = planner, it=it, outline=outline, cases=cases) -> None:
                state, goal = cases[next(it) % len(cases)]
                planner.plan(outline, state, goal)

            ms = time_ms(step, repeats, warmup=5)
            p10, p50, p90 = np.percentile(ms, [10, 50, 90])
            greedy = p50 if greedy is None else greedy
            verdict = f"<= {TARGET_MS:g} ms: {'met' if p50 <= TARGET_MS else 'NOT met'}"
            rows.append(f"| {obj} | {h}{' (greedy)' if h == 1 else ''} | {p50:.1f} | "
                        f"{p10:.1f} | {p90:.1f} | {p50 / greedy:.2f} | {repeats} | {verdict} |")
            print(rows[-1], flush=True)
    return rows


def variant_fields(variant: str, horizon: int) -> dict[str, object]:
    """The :class:`pushbot.runner.protocol.Trial` fields of a variant (module docstring)."""
    if variant not in VARIANTS:
        raise ValueError(f"variant: expected one of {VARIANTS}, got {variant!r}")
    if variant == "greedy":
        return {}
    adapt = variant == "lookahead+adapt"
    return {"horizon": horizon, "avoid_contradicted": adapt, "relearn": adapt}


def closed_loop(variant: str, horizon: int, state: str, trials: int) -> list[dict]:
    runner = EpisodeRunner()
    records = []
    for trial in make_trials(list(OBJECTS), list(TASKS), ["ana"], [3], trials, state=state,
                             **variant_fields(variant, horizon)):
        rec = runner.run(trial)
        records.append(rec)
        print(f"{variant} {trial.object} {trial.task} #{trial.index}: {rec['steps']} pushes, "
              f"{'ok' if rec['success'] else 'FAILED ' + rec['reason']}", flush=True)
    runner.close()
    return records


def table(results: dict[str, list[dict]]) -> list[str]:
    lines = ["| task | object | min | variant | success | pushes | pushes / min | "
             "planning ms (median) |", "| --- " * 8 + "|"]
    for task in TASKS:
        for obj in OBJECTS:
            for variant, records in results.items():
                recs = [r for r in records
                        if r["trial"]["task"] == task and r["trial"]["object"] == obj]
                if not recs:
                    continue
                ok = [r for r in recs if r["success"]]
                pushes = f"{np.mean([r['steps'] for r in ok]):.2f}" if ok else "-"
                ratio = pushes_over_minimum(recs)
                ms = [m for r in recs for m in r["planning_ms"]]
                lines.append(f"| {task} | {obj} | {trial_minimum(recs[0]['trial'])} | "
                             f"{variant} | {len(ok)}/{len(recs)} | {pushes} | "
                             f"{'-' if ratio is None else f'{ratio:.2f}'} | "
                             f"{np.median(ms):.1f} |")
    for variant, records in results.items():
        ok = [r for r in records if r["success"]]
        ratio = pushes_over_minimum(records)
        lines.append(f"| **all** | | | {variant} | {len(ok)}/{len(records)} | "
                     f"{np.mean([r['steps'] for r in ok]):.2f} | "
                     f"{'-' if ratio is None else f'{ratio:.2f}'} | "
                     f"{np.median([m for r in records for m in r['planning_ms']]):.1f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--state", default="filter", choices=("gt", "filter"))
    parser.add_argument("--trials", type=int, default=4, help="trials per object and task")
    parser.add_argument("--repeats", type=int, default=100, help="timed planning calls")
    parser.add_argument("--horizon", type=int, default=2)
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    parser.add_argument("--speed-only", action="store_true",
                        help="only the planning time (section bench_lookahead_speed)")
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    load_before = " ".join(f"{v:.2f}" for v in os.getloadavg())
    speed = speed_rows(args.repeats, (1, 2, 3))
    command = " ".join(["python benchmarks/bench_lookahead.py", *(argv or sys.argv[1:])])
    speed_text = [
        f"**Planning time per step** (`Planner.plan`, ana, k = 3; horizon H: "
        f"push_core.lookahead, beam 8; random poses and goals as bench_planner); target: "
        f"median <= {TARGET_MS:g} ms. `x greedy`: median over the greedy median of the same "
        "run (less sensitive to the machine's load than the milliseconds).",
        "",
        "| object | horizon | median ms | p10 ms | p90 ms | x greedy | calls | target |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
        *speed]
    if args.speed_only:
        load_after = " ".join(f"{v:.2f}" for v in os.getloadavg())
        section = format_section(
            "Lookahead planning time (`bench_lookahead_speed`)", command,
            "\n".join([f"1/5/15-minute load average {load_before} before, {load_after} after "
                       "(2 cores shared with other sessions' jobs).", "", *speed_text]))
        print(section)
        if not args.no_write:
            update_section("bench_lookahead_speed", section)
        return 0
    results = {v: closed_loop(v, args.horizon, args.state, args.trials) for v in args.variants}
    load_after = " ".join(f"{v:.2f}" for v in os.getloadavg())
    minutes = (time.perf_counter() - t0) / 60
    n = args.trials * len(OBJECTS) * len(TASKS)
    body = "\n".join([
        f"1/5/15-minute load average {load_before} before, "
        f"{load_after} after (2 cores shared with other sessions' jobs: the medians are the "
        "figure, the tails noise).",
        "",
        *speed_text,
        "",
        f"**Closed loop** ({args.state}, in-process; {', '.join(OBJECTS)} x "
        f"{', '.join(TASKS)} x {args.trials} trials = {n} per variant, the protocol's "
        "trials (COM at the centre, randomised mass and frictions, 0.75 cm / 5 deg, 30 pushes"
        f" max); lookahead H = {args.horizon}. `min` is the physical minimum "
        "([physical minimum](../design/physical-minimum.md)), `pushes / min` the mean of "
        "pushes / min over the successes.",
        "",
        *table(results),
        "",
        f"Wall time {minutes:.1f} min.",
    ])
    section_id = "bench_lookahead" + ("" if args.state == "filter" else f"_{args.state}")
    section = format_section(f"Lookahead and adaptation, state {args.state} (`{section_id}`)",
                             command, body)
    print(section)
    if not args.no_write:
        update_section(section_id, section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
