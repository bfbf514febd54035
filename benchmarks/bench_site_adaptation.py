"""Site adaptation of the segmentation CNN: the unseen look before and after fine-tuning.

1. Starts ``sim_bridge_node`` (a real node process on DDS) in the site look
   (``appearance.look site``: textured tables, metallic or camouflaged objects, coloured light,
   strong shadows), with depth noise and camera jitter, and records ``--frames`` frames over
   ``--scenes`` scenes of the *training* objects with ``pushbot data record --sim`` (labels from
   the depth segmentation, checked across frames).
2. Fine-tunes the bundled network on them: ``pushbot train segmentation --init bundled``
   (seeded, CPU), the last ``--val-shards`` scenes held out.
3. Runs ``pushbot eval perception``'s protocol on the held-out objects (tri1, butter, hex) in
   the site look and in the default look, with the bundled and the adapted weights: mask IoU
   against the simulator's truth, position and orientation error.

Writes the ``site_adaptation`` section of ``docs/RESULTS.md``. Usage (ROS_DOMAIN_ID from the
environment)::

    .venv/bin/python benchmarks/bench_site_adaptation.py [--frames 160] [--scenes 16]
        [--steps 300] [--episodes 6] [--eval-frames 5] [--out out/site_adaptation] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

SECTION_ID = "site_adaptation"
#: Objects of the recorded scenes: training objects, never the held-out test objects.
RECORD_OBJECTS = ("rect1", "rect2", "rect3", "tri2", "tri3", "ellip1", "ellip2", "ellip3")
TARGETS = {"iou": 0.95, "position_mm": 1.0}


def _pushbot(*args: str) -> None:
    cmd = [sys.executable, "-m", "pushbot.cli", *args]
    print("$", "pushbot", " ".join(args), flush=True)
    subprocess.run(cmd, check=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=160)
    parser.add_argument("--scenes", type=int, default=16)
    parser.add_argument("--val-shards", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--episodes", type=int, default=6, help="per held-out object and look")
    parser.add_argument("--eval-frames", type=int, default=5, help="frames per episode")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("out/site_adaptation"))
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    from pushbot.experiments.perception_evaluation import EvalConfig, evaluate, summary

    data, weights = args.out / "data", args.out / "segmentation_site.pt"
    started = time.monotonic()
    sim = subprocess.Popen(
        [sys.executable, "-m", "sim_bridge.sim_bridge_node", "--ros-args", "-p",
         "appearance.look:=site", "-p", "depth_noise:=true", "-p", "randomize_camera:=true",
         "-p", "idle_frame_rate:=5.0", "-p", f"object:={RECORD_OBJECTS[0]}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _pushbot("data", "record", "--sim", "--frames", str(args.frames), "--scenes",
                 str(args.scenes), "--objects", *RECORD_OBJECTS, "--seed", str(args.seed),
                 "--out", str(data), "--overwrite", "--timeout", "60")
    finally:
        sim.terminate()
        sim.wait(timeout=30)
    record_min = (time.monotonic() - started) / 60.0
    meta = json.loads((data / "meta.json").read_text())
    _pushbot("train", "segmentation", "--init", "bundled", "--data", str(data), "--steps",
             str(args.steps), "--val-shards", str(args.val_shards), "--seed", str(args.seed),
             "--out", str(weights), "--no-progress")
    report = json.loads(weights.with_suffix(".json").read_text())
    rows = {}
    for look in ("site", "default"):
        for name, path in (("bundled", ""), ("adapted", str(weights))):
            cfg = EvalConfig(episodes=args.episodes, frames=args.eval_frames, seed=args.seed,
                             weights=path, look=look)
            rows[(look, name)] = summary(evaluate(cfg, progress=False))["all"]
            print(look, name, {k: round(rows[(look, name)][k], 4)
                               for k in ("iou", "position_mm", "orientation_deg")}, flush=True)
    body = _report(args, meta, report, rows, record_min)
    print(body)
    if not args.no_write:
        command = "python benchmarks/bench_site_adaptation.py " + " ".join(
            argv if argv is not None else sys.argv[1:])
        update_section(SECTION_ID, format_section(
            "Site adaptation of the segmentation CNN (`site_adaptation`)", command.strip(), body),
            summary="The bundled CNN and the CNN fine-tuned on recorded, self-labelled site "
                    "frames, on a look it never saw and on the default look.")
    return 0


def _report(args: argparse.Namespace, meta: dict, report: dict, rows: dict,
            record_min: float) -> str:
    dropped = ", ".join(f"{k} {v}" for k, v in meta["dropped"].items())
    v = report["validation"]
    lines = [
        f"Recorded through a running `sim_bridge_node` in the site look (depth noise, camera "
        f"jitter): {meta['frames']} labelled frames of the training objects in "
        f"{meta['shards']} shards ({record_min:.1f} min with the node's start); dropped by the "
        f"consistency rule: {dropped}. Fine-tuned from the bundled weights: "
        f"{report['train_config']['steps']} steps, seed {report['train_config']['seed']}, "
        f"{report['train_minutes']} min on one CPU thread; {report['train_frames']} training "
        f"frames, the last {args.val_shards} scenes held out (IoU against their depth labels: "
        f"median {v['iou_median']:.4f} over {v['frames']} frames).",
        "",
        f"Evaluation: `pushbot eval perception`'s protocol on the held-out objects tri1, "
        f"butter, hex, {args.episodes} episodes x {args.eval_frames} frames each per look "
        "(half of them with camera jitter and depth noise), against the simulator's truth. "
        "Medians over frames.",
        "",
        "| look | weights | frames (posed) | mask IoU (p10) | position mm (p90) | "
        "orientation deg (p90) |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for (look, name), g in rows.items():
        lines.append(f"| {look} | {name} | {g['frames']} ({g['posed']}) | {g['iou']:.4f} "
                     f"({g['iou_p10']:.3f}) | {g['position_mm']:.2f} ({g['position_p90_mm']:.2f})"
                     f" | {g['orientation_deg']:.2f} ({g['orientation_p90_deg']:.2f}) |")
    after = rows[("site", "adapted")]
    lines += ["", "| target (site look, adapted) | measured | target | met |",
              "| --- | --- | --- | --- |",
              f"| mask IoU | {after['iou']:.4f} | >= {TARGETS['iou']} | "
              f"{'yes' if after['iou'] >= TARGETS['iou'] else 'NO'} |",
              f"| position error median | {after['position_mm']:.2f} mm | <= "
              f"{TARGETS['position_mm']} mm | "
              f"{'yes' if after['position_mm'] <= TARGETS['position_mm'] else 'NO'} |"]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
