"""Camera profiles and depth-only segmentation through the real graph (docs/design/cameras.md).

For each simulated camera profile (``default``, ``d415``, ``d435``, ``orbbec``, ``zed``:
sim_bridge.camera_profiles) it runs ``pushbot eval push --graph --state filter`` on the mixed
task (butter, random COM, ana, k = 3, small region, seed 0, indices 0..n-1: the same scenes and
goals for every profile) and reports success and the true end error; then the depth-only
segmentation (``--segmentation depth``) on the default camera. Writes ``docs/results/cameras.md``
(``--no-write``: only print).

Usage::

    .venv/bin/python benchmarks/bench_cameras.py [--trials N] [--depth-trials N]
                                                 [--profiles a,b] [--no-write]
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
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
PUSHBOT = REPO / ".venv" / "bin" / "pushbot"


def _run(out: Path, trials: int, camera: str, segmentation: str) -> list[dict]:
    cmd = [str(PUSHBOT), "eval", "push", "--graph", "--state", "filter", "--objects", "butter",
           "--tasks", "mixed", "--com", "random", "--trials", str(trials), "--camera", camera,
           "--segmentation", segmentation, "--out", str(out), "--no-progress"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return json.loads((out / "results.json").read_text())["trials"]


def _row(name: str, records: list[dict]) -> tuple[str, float]:
    ok = [r for r in records if r.get("success")]
    pos = [1e3 * float(r["end_error_xy"]) for r in records
           if r.get("end_error_xy") is not None]
    deg = [math.degrees(abs(float(r["end_error_theta"]))) for r in records
           if r.get("end_error_theta") is not None]
    med = statistics.median(pos) if pos else float("nan")
    steps = statistics.mean(r.get("steps", 0) for r in records)
    return (f"| {name} | {len(ok)}/{len(records)} | {len(ok) / len(records):.2f} | {steps:.1f} | "
            f"{med:.2f} | {statistics.mean(pos) if pos else float('nan'):.2f} | "
            f"{statistics.median(deg) if deg else float('nan'):.2f} |", med)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--depth-trials", type=int, default=60)
    parser.add_argument("--profiles", default="default,d415,d435,orbbec,zed")
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    header = ("| camera / segmentation | success | rate | mean steps | median true end error "
              "mm | mean mm | median deg |\n| --- | --- | --- | --- | --- | --- | --- |")
    rows, medians = [], {}
    with tempfile.TemporaryDirectory(prefix="bench_cameras_") as tmp:
        for name in args.profiles.split(","):
            records = _run(Path(tmp) / name, args.trials, name, "cnn")
            row, medians[name] = _row(f"{name} / cnn", records)
            rows.append(row)
            print(row, flush=True)
        if args.depth_trials > 0:
            records = _run(Path(tmp) / "depth", args.depth_trials, "default", "depth")
            row, _ = _row("default / depth", records)
            rows.append(row)
            print(row, flush=True)
    base = medians.get("default")
    delta = "; ".join(f"{n} {m - base:+.2f} mm" for n, m in medians.items()
                      if n != "default" and base is not None)
    load = os.getloadavg()[0]
    body = (f"Trials: butter, mixed task, random COM, ana, k = 3, small goal region (7.5 mm, "
            f"5 deg), seed 0, indices 0..n-1, through the graph (4 node processes); success by "
            f"ground truth. Load average (1 min) at the end: {load:.1f} (2 shared cores).\n\n"
            f"{header}\n" + "\n".join(rows) + "\n\n"
            f"Median true end error against the default camera's: {delta or 'n/a'}.\n")
    command = "python benchmarks/bench_cameras.py " + " ".join(argv or sys.argv[1:])
    text = format_section("Camera profiles and depth-only segmentation (`cameras`)",
                          command.strip(), body)
    print(text)
    if not args.no_write:
        update_section("cameras", text, summary="The graph on camera streams shaped like a "
                       "RealSense D415 / D435, an Orbbec and a ZED, and with the depth-only "
                       "segmentation.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
