"""The demo, repeated: does ``pushbot demo`` succeed by ground truth every time?

Runs ``pushbot demo --object OBJECT --com COM`` ``--runs`` times in a row (default 20, rect1 with
the COM at the centre: the command that ended "goal reached by the estimate, 7.6 mm by ground
truth" in 1 of 7 runs before the confident stop rule), each a fresh graph of four node
processes, and reads every run's ``episode.json``: success by ground truth, pushes, true end
error, reason, wall time. Graph runs are not bit-reproducible (DDS timing), so the runs differ.

Writes ``docs/results/demo_repeat.md`` (with the load average: the machine
is shared).

Usage::

    .venv/bin/python benchmarks/demo_repeat.py [--runs N] [--object NAME] [--com centre|random]
                                               [--no-write]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
PUSHBOT = REPO / ".venv" / "bin" / "pushbot"


def run_demo(out: Path, obj: str, com: str) -> dict:
    """One ``pushbot demo`` run; its episode record plus ``wall_process_s`` and ``exit``."""
    t0 = time.perf_counter()
    proc = subprocess.run([str(PUSHBOT), "demo", "--object", obj, "--com", com, "--out",
                           str(out)], capture_output=True, text=True, timeout=600, check=False)
    wall = time.perf_counter() - t0
    path = out / "episode.json"
    if not path.is_file():
        return {"success": False, "reason": f"no episode.json (exit {proc.returncode}): "
                f"{proc.stderr.strip()[-300:]}", "steps": 0, "end_error_xy": math.nan,
                "end_error_theta": math.nan, "wall_process_s": wall, "exit": proc.returncode}
    rec = json.loads(path.read_text())
    rec["wall_process_s"], rec["exit"] = wall, proc.returncode
    return rec


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--object", default="rect1")
    parser.add_argument("--com", default="centre", choices=("centre", "random"))
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    if args.runs < 1:
        parser.error("--runs must be >= 1")
    load_before = os.getloadavg()
    records = []
    with tempfile.TemporaryDirectory(prefix="pushbot-demo-") as tmp:
        for i in range(args.runs):
            rec = run_demo(Path(tmp) / f"run{i}", args.object, args.com)
            records.append(rec)
            print(f"run {i + 1}: success {rec['success']}, {rec['steps']} pushes, "
                  f"{1e3 * rec['end_error_xy']:.1f} mm / "
                  f"{math.degrees(rec['end_error_theta']):.1f} deg, {rec['reason']}, "
                  f"{rec['wall_process_s']:.1f} s", flush=True)
    load_after = os.getloadavg()
    ok = sum(bool(r["success"]) for r in records)
    consecutive = 0
    for r in records:
        if not r["success"]:
            break
        consecutive += 1
    rows = ["| run | success (ground truth) | pushes | end error mm | end error deg | reason | "
            "wall s |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for i, r in enumerate(records, 1):
        rows.append(f"| {i} | {'yes' if r['success'] else 'NO'} | {r['steps']} | "
                    f"{1e3 * r['end_error_xy']:.1f} | {math.degrees(r['end_error_theta']):.1f} | "
                    f"{r['reason']} | {r['wall_process_s']:.1f} |")
    walls = [r["wall_process_s"] for r in records]
    steps = [r["steps"] for r in records]
    body = "\n".join([
        f"`pushbot demo --object {args.object} --com {args.com}` run {args.runs} times in a row "
        "(each: doctor, four node processes, one mixed-task episode; the confident stop rule "
        "of [Stopping](../design/stopping.md)).",
        "",
        f"**{ok} of {args.runs} succeeded by ground truth; {consecutive} consecutive from the "
        f"first** (target: 20 of 20). Pushes median {statistics.median(steps):g} "
        f"(range {min(steps)}-{max(steps)}); wall time per run median "
        f"{statistics.median(walls):.1f} s (range {min(walls):.1f}-{max(walls):.1f}); "
        f"1/5/15-minute load average {[round(v, 2) for v in load_before]} before and "
        f"{[round(v, 2) for v in load_after]} after.",
        "",
        *rows,
    ])
    print(body)
    if not args.no_write:
        command = "python benchmarks/demo_repeat.py" + (
            f" --runs {args.runs}" if args.runs != 20 else "") + (
            f" --object {args.object}" if args.object != "rect1" else "") + (
            f" --com {args.com}" if args.com != "centre" else "")
        update_section("demo_repeat", format_section(
            "The demo repeated (`demo_repeat`)", command, body))
        print("wrote section demo_repeat")
    return 0 if ok == args.runs else 1


if __name__ == "__main__":
    raise SystemExit(main())
