"""The shape-class benchmark (every flat object the library can make), written to docs/results/.

The full system (``state filter``: rendered 640 x 480 RGB-D -> segmentation CNN -> perception
core -> EKF with COM estimation -> planner), method ana, k = 3, the translation and mixed tasks,
small goal region, 30 pushes max, on every object of ``benchmarks/objects/<class>/`` (spec files
written by ``benchmarks/make_shape_objects.py``). Mass and frictions are randomised per trial;
the COM is random (``com random``: uniform over the outline shrunk by 30 %) except for the
``com_edge`` class, whose COM is the spec's (``com spec``: 80-90 % of the way from the centroid
to the outline). ``--trials`` trials per object and task (protocol index i: initial orientation
2 pi (i mod 20) / 20), seed 0.

Runs through the in-process evaluation API (:class:`pushbot.experiments.evaluate.EvalOptions`,
:func:`pushbot.experiments.evaluate.evaluate`) like ``benchmarks/eval_push.py``; the objects are
given as spec-file paths relative to the repository root (the script works from there). Output:
``--out`` (default ``out/eval/shapes``) holds ``com_random/`` and ``com_spec/`` (the
``results.json`` of each evaluation) and ``summary.md``; the page
``docs/results/eval_shapes.md`` gets a table per class (per object and task: success with its
Wilson 95 % interval, mean steps of the successful trials, true end error mm / deg over all trials,
trials whose *estimate* reached the goal but whose true pose did not, failure reasons), an overall
table and the comparison with the source's 10.6-13.9 pushes (Table 5.2).

With ``--horizon H`` (H > 1), ``--avoid-contradicted`` or ``--relearn`` the planner and filter
variants run (lookahead, contradicted pushes avoided, re-learning; ``pushbot eval push`` has
the same options); their results go to the section ``eval_shapes_variant`` and ``--out``'s
``variant/`` folder, so the greedy section stays.

Usage::

    .venv/bin/python benchmarks/eval_shapes.py [--trials 10] [--workers N]
        [--classes disc u_shape ...] [--seed 0] [--no-write] [--out out/eval/shapes]
        [--horizon H] [--avoid-contradicted] [--relearn]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _pushes import pushes_over_minimum  # noqa: E402
from _results import format_section, update_section  # noqa: E402
from bench_graph import wilson  # noqa: E402

from push_core.procedural import SHAPE_CLASSES  # noqa: E402
from pushbot.experiments.eval_report import stats, write_outputs  # noqa: E402
from pushbot.experiments.evaluate import EvalOptions, evaluate, usable_cores  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OBJECTS_DIR = Path("benchmarks") / "objects"  # relative to ROOT
TASKS = ("translation", "mixed")
#: The source's mean pushes with random COM (Table 5.2: ana / lrn, with and without COM
#: estimation, on butter, tri1 and hex), mixed task.
SOURCE_STEPS = (10.6, 13.9)
ESTIMATE_NOT_TRUE = "estimate within tolerance, truth not"


def class_objects(classes: list[str]) -> dict[str, list[str]]:
    """class -> spec-file paths (relative to the repository root), sorted by name."""
    out = {}
    for cls in classes:
        paths = sorted((ROOT / OBJECTS_DIR / cls).glob("*.yaml"))
        if not paths:
            raise ValueError(f"--classes: no spec files in {OBJECTS_DIR / cls} (run "
                             "benchmarks/make_shape_objects.py)")
        out[cls] = [str(p.relative_to(ROOT)) for p in paths]
    return out


def run(classes: list[str], trials: int, workers: int, seed: int, out: Path,
        variant: dict | None = None) -> tuple[list[dict], dict[str, str], list[dict]]:
    """Evaluate the classes (one evaluation per COM mode); returns the records, the class of
    every object path and the evaluations' timing records. ``variant``: ``horizon``,
    ``avoid_contradicted``, ``relearn`` of :class:`EvalOptions` (default: the greedy loop)."""
    objects = class_objects(classes)
    of_class = {path: cls for cls, paths in objects.items() for path in paths}
    groups = {"random": [p for c, ps in objects.items() if c != "com_edge" for p in ps],
              "spec": objects.get("com_edge", [])}
    records, timings = [], []
    for com, paths in groups.items():
        if not paths:
            continue
        opts = EvalOptions(objects=paths, tasks=TASKS, methods=["ana"], k=[3],
                           state=["filter"], com=[com], trials=trials, seed=seed,
                           **(variant or {}))
        doc = evaluate(opts, workers=workers, progress=True)
        doc["timing"]["command"] = "benchmarks/eval_shapes.py"
        write_outputs(doc, out / f"com_{com}")
        records += doc["trials"]
        timings.append(doc["timing"])
    return records, of_class, timings


# --------------------------------------------------------------------------------------------
def _f(x: float | None, fmt: str = ".1f", scale: float = 1.0) -> str:
    return "-" if x is None else f"{x * scale:{fmt}}"


def failure_reasons(records: list[dict]) -> dict[str, int]:
    """Counts of the reasons of the failed trials (an estimate inside the goal region whose
    true pose is not: :data:`ESTIMATE_NOT_TRUE`; error texts kept)."""
    out: dict[str, int] = {}
    for r in records:
        if r["success"]:
            continue
        key = ESTIMATE_NOT_TRUE if r["reason"] == "goal reached" else r["reason"]
        out[key] = out.get(key, 0) + 1
    return dict(sorted(out.items()))


def row(label: str, records: list[dict]) -> str:
    """One table row: trials, success [Wilson 95 %], steps, end errors, estimate-not-truth,
    failure reasons."""
    s = stats(records)
    lo, hi = wilson(s["successes"], s["n"])
    # Orientation errors of discs are meaningless (their orientation is not observed).
    theta = [r["end_error_theta"] for r in records
             if r.get("end_error_theta") is not None and not r.get("orientation_ignored")]
    deg = _f(float(np.mean(theta)), scale=180 / math.pi) if theta else "(ignored)"
    fails = failure_reasons(records)
    est = fails.get(ESTIMATE_NOT_TRUE, 0)
    reasons = ", ".join(f"{k} {v}" for k, v in fails.items() if k != ESTIMATE_NOT_TRUE)
    return (f"| {label} | {s['n']} | {s['success_rate']:.2f} [{lo:.2f}, {hi:.2f}] | "
            f"{_f(s['steps_mean'])} | {_f(pushes_over_minimum(records), '.2f')} | "
            f"{_f(s['end_error_xy_mean'], scale=1e3)} | "
            f"{deg} | {est} | "
            f"{reasons or '-'} |")


HEAD = ("| {} | trials | success [95 % CI] | steps | pushes / min | end mm | end deg | "
        "estimate in, truth out | other failures |\n"
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |")


def summary(records: list[dict], of_class: dict[str, str]) -> str:
    """The markdown tables (per class, overall, source comparison)."""
    by_class: dict[str, list[dict]] = {}
    for r in records:
        by_class.setdefault(of_class[r["trial"]["object"]], []).append(r)
    parts = []
    for cls in (c for c in SHAPE_CLASSES if c in by_class):
        recs = by_class[cls]
        lines = [f"**{cls}** (COM {recs[0]['trial']['com']})", "", HEAD.format("object, task")]
        for obj in sorted({r["trial"]["object"] for r in recs}):
            for task in TASKS:
                sel = [r for r in recs if r["trial"]["object"] == obj
                       and r["trial"]["task"] == task]
                if sel:
                    lines.append(row(f"{Path(obj).stem}, {task}", sel))
        lines.append(row("**all**", recs))
        parts.append("\n".join(lines))
    overall = [HEAD.format("class")]
    overall += [row(cls, by_class[cls]) for cls in SHAPE_CLASSES if cls in by_class]
    overall.append(row("**all classes**", records))
    for task in TASKS:
        overall.append(row(f"all, {task}", [r for r in records if r["trial"]["task"] == task]))
    mixed = stats([r for r in records if r["trial"]["task"] == "mixed" and r["success"]])
    per_class = [stats([r for r in by_class[c] if r["trial"]["task"] == "mixed"])["steps_mean"]
                 for c in SHAPE_CLASSES if c in by_class]
    per_class = [v for v in per_class if v is not None]
    compare = (f"Source comparison (mixed task): the source's full system needed "
               f"{SOURCE_STEPS[0]}-{SOURCE_STEPS[1]} pushes on average with a random COM "
               "(Table 5.2, butter, tri1 and hex, ana and lrn with and without COM estimation). "
               f"Here: {_f(mixed['steps_mean'])} pushes over the successful mixed-task trials "
               "of all classes" + (f", class means {min(per_class):.1f}-{max(per_class):.1f}"
                                   if per_class else "") + ".")
    return "\n\n".join(["Overall:", "\n".join(overall), compare, *parts])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=10, help="trials per object and task")
    ap.add_argument("--workers", type=int, default=None,
                    help="worker processes (default: the usable cores)")
    ap.add_argument("--classes", nargs="+", default=list(SHAPE_CLASSES),
                    choices=list(SHAPE_CLASSES), metavar="CLASS",
                    help=f"shape classes (default: all: {' '.join(SHAPE_CLASSES)})")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-write", action="store_true", help="do not write the result page")
    ap.add_argument("--out", type=Path, default=Path("out/eval/shapes"),
                    help="output directory, relative to the repository root")
    ap.add_argument("--horizon", type=int, default=1,
                    help="pushes the planner looks ahead (default 1: greedy)")
    ap.add_argument("--avoid-contradicted", action="store_true",
                    help="avoid the contact regions of pushes that contradicted the model")
    ap.add_argument("--relearn", action="store_true",
                    help="the filter re-learns c, l, m when pushes contradict the model")
    args = ap.parse_args(argv)
    workers = usable_cores() if args.workers is None else args.workers
    variant = {"horizon": args.horizon, "avoid_contradicted": args.avoid_contradicted,
               "relearn": args.relearn}
    flags = (f" --horizon {args.horizon}" if args.horizon != 1 else "") + \
        (" --avoid-contradicted" if args.avoid_contradicted else "") + \
        (" --relearn" if args.relearn else "")
    out = args.out / "variant" if flags else args.out
    os.chdir(ROOT)  # the spec-file paths in the records are relative to the repository root
    t0 = time.perf_counter()
    records, of_class, timings = run(args.classes, args.trials, workers, args.seed, out, variant)
    wall = time.perf_counter() - t0
    loads = "; ".join(f"{t['load_before']} before, {t['load_after']} after" for t in timings)
    body = "\n".join([
        "Full system (`filter`: rendered 640 x 480 RGB-D -> segmentation CNN -> perception core "
        "-> EKF with COM estimation -> planner), ana, k = 3, tasks translation (20 cm) and "
        "mixed (10 cm, 0.35 rad), small goal region (0.75 cm, 5 deg), 30 pushes max, "
        f"{args.trials} trials per object and task"
        + (f"; planner and filter variant:{flags}" if flags else "; greedy planner")
        + "; random COM (uniform over the outline "
        "shrunk by 30 %) except `com_edge` (the spec's COM, 80-90 % of the way to the "
        "outline); randomised mass and frictions. Objects: `benchmarks/objects/<class>/` "
        "(`benchmarks/make_shape_objects.py`, seed 0). Success and end errors from ground "
        "truth (orientation modulo the object's symmetry; for discs not counted and left out of "
        'the mean end deg). Steps: mean over the successful trials. "estimate in, truth '
        'out": the estimate reached the goal region, the true pose did not.',
        "",
        summary(records, of_class),
        "",
        f"{len(records)} trials in {wall / 60:.1f} min with {workers} worker(s); load average "
        f"{loads}.",
    ])
    (out / "summary.md").write_text(body + "\n", encoding="utf-8")
    print(body)
    if not args.no_write:
        command = (f"python benchmarks/eval_shapes.py --trials {args.trials} --workers {workers}"
                   + (f" --classes {' '.join(args.classes)}"
                      if list(args.classes) != list(SHAPE_CLASSES) else "") + flags)
        name = "eval_shapes_variant" if flags else "eval_shapes"
        title = ("Shape classes with the lookahead planner and adaptation (`eval_shapes_variant`)"
                 if flags else "Shape classes: the full system on every flat object "
                 "(`eval_shapes`)")
        update_section(name, format_section(title, command, body),
                       data=f"`{out}/com_<com>/results.json` and `{out}/summary.md` (kept outside "
                            "the repository; no render path)")
        print(f"wrote section {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
