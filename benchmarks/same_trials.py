"""Same trials before and after a change: a sample of the protocol's trials, in-process.

Behaviour-unchanged check of a refactor: run ``record`` at two commits (a checkout each, same
machine), then ``compare`` the two files; ``compare`` writes ``docs/results/same_trials.md``.
The sample: the first ``--per-cell`` trials of every cell of the full protocol (tri1, butter,
hex x translation, rotation, mixed, full system ``filter``, COM at the centre), every Table 5.2
cell's first trial (ana and lrn, with and without COM estimation, random COM), and the first
trial of every fourth shape-benchmark object on translation and mixed. A trial is the same when
its pushes (approach, contact and end points, bit for bit) and its true end error are. Works
with the older ``pushbot`` layouts too (the trial definition in ``pushbot.experiments.protocol``,
or the flat ``pushbot.episode`` / ``pushbot.protocol``).

Usage::

    .venv/bin/python benchmarks/same_trials.py record OUT.json [--per-cell N]
    .venv/bin/python benchmarks/same_trials.py compare BEFORE.json AFTER.json [--no-write]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OBJECTS = ("tri1", "butter", "hex")


def sample(per_cell: int) -> list[dict]:
    """The sampled trials as Trial keyword arguments (module docstring)."""
    base = dict(k=3, state="filter", region="small", seed=0, max_steps=30, estimate_com=True)
    trials = [dict(base, object=o, task=t, method="ana", com="centre", index=i)
              for o in OBJECTS for t in ("translation", "rotation", "mixed")
              for i in range(per_cell)]
    trials += [dict(base, object=o, task="mixed", method=m, com="random", index=0,
                    estimate_com=e) for o in OBJECTS for m in ("ana", "lrn") for e in (True, False)]
    shapes = sorted((ROOT / "benchmarks" / "objects").glob("*/*.yaml"))[::4]
    trials += [dict(base, object=str(p.relative_to(ROOT)), task=t, method="ana",
                    com="spec" if p.parent.name == "com_edge" else "random", index=0)
               for p in shapes for t in ("translation", "mixed")]
    return trials


def record(out: Path, per_cell: int) -> int:
    try:
        from pushbot.experiments.inprocess import run_trial
    except ImportError:  # the flat layout, before pushbot's subpackages
        from pushbot.episode import run_trial
    try:
        from pushbot.runner.protocol import Trial
    except ImportError:  # older layouts: the trial definition in experiments, or flat
        try:
            from pushbot.experiments.protocol import Trial
        except ImportError:
            from pushbot.protocol import Trial
    rows = []
    for kw in sample(per_cell):
        rec = run_trial(Trial(**{**kw, "object": str(ROOT / kw["object"])
                                 if kw["object"].endswith(".yaml") else kw["object"]}))
        rows.append({"trial": kw, "steps": rec["steps"], "pushes": rec["pushes"],
                     "end_error_xy": rec["end_error_xy"], "success": rec["success"]})
        print(kw["object"], kw["task"], kw["method"], kw["index"], rec["steps"], flush=True)
    out.write_text(json.dumps(rows))
    return 0


def compare(before: Path, after: Path, write: bool) -> int:
    a, b = json.loads(before.read_text()), json.loads(after.read_text())
    if [r["trial"] for r in a] != [r["trial"] for r in b]:
        print("the two files hold different trial samples", file=sys.stderr)
        return 2
    same = [x["pushes"] == y["pushes"] and x["end_error_xy"] == y["end_error_xy"]
            for x, y in zip(a, b, strict=True)]
    groups = {"full protocol (COM centre)": lambda t: t["com"] == "centre",
              "Table 5.2 cells (random COM)": lambda t: t["com"] == "random"
              and not t["object"].endswith(".yaml"),
              "shape benchmark objects": lambda t: t["object"].endswith(".yaml")}
    lines = ["| trials | sampled | identical |", "| --- | --- | --- |"]
    for name, keep in groups.items():
        idx = [i for i, r in enumerate(a) if keep(r["trial"])]
        lines.append(f"| {name} | {len(idx)} | {sum(same[i] for i in idx)} |")
    lines.append(f"| **all** | {len(a)} | {sum(same)} |")
    body = (f"Trials recorded at two commits with `same_trials.py record` ({before.name} before, "
            f"{after.name} after) and compared trial by trial (pushes bit for bit, true end "
            "error): the sample is in the script's docstring.\n\n" + "\n".join(lines))
    print(body)
    if write:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from _results import format_section, update_section

        command = f"python benchmarks/same_trials.py compare {before.name} {after.name}"
        update_section("same_trials", format_section(
            "Same trials before and after a refactor (`same_trials`)", command, body),
            data=f"`{before.name}` and `{after.name}` (`same_trials.py record`), rendered by "
                 f"`{command}`")
    return 0 if all(same) else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("out", type=Path)
    r.add_argument("--per-cell", type=int, default=2)
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    c.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    if args.cmd == "record":
        return record(args.out, args.per_cell)
    return compare(args.before, args.after, not args.no_write)


if __name__ == "__main__":
    sys.exit(main())
