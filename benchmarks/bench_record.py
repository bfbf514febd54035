"""Recording and replay, measured: ``pushbot bag record`` completeness and cost, the demo's bag,
and the renderer's speed.

1. **Recorder completeness.** A publisher in this process sends 640x480 rgb8 camera images
   (best effort, ``qos_profile_sensor_data``, as ``sim_bridge_node``) at each ``--rates`` Hz
   for ``--seconds`` s, together with a reliable 100 Hz PoseStamped stream, to
   ``pushbot bag record`` running as its own process (as a user runs it); publishing starts
   once the recorder's subscriptions are matched and the recorder is stopped with SIGINT
   after the reliable stream is acknowledged. Reported: images recorded / published, poses
   recorded / published, bag size, the recorder's CPU time (user + system) per second.
2. **Demo bag and renderer.** ``pushbot demo --skip-doctor`` (the bridge's monitor on at the
   demo's default 10 Hz of sim time): the bag's size, messages and topics, then
   ``pushbot.viz.render.render_bag`` on it timed (ms per video frame), MP4 and GIF sizes.
3. **What the monitor costs.** The same demo with ``--monitor-rate 10`` (default) and
   ``--monitor-rate 0`` (camera frames only), alternating, ``--demo-runs`` times each: the
   demo process's wall time (start to exit: graph, episode, recording, rendering), the
   episode's wall time (goal to end),
   the MP4's frame count and duration (``imageio_ffmpeg.count_frames_and_secs``), the render
   time and the MP4 / GIF sizes. The first monitored run is part 2's.

Usage::

    .venv/bin/python benchmarks/bench_record.py [--rates 5 15 30] [--seconds 10]
        [--demo-runs 2] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

PUSHBOT = str(Path(sys.executable).parent / "pushbot")


def _dir_size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.iterdir() if p.is_file())


def record_rate(rate: float, seconds: float, tmp: Path) -> dict[str, float]:
    """One recording of images at ``rate`` Hz and poses at 100 Hz (module docstring)."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.context import Context
    from rclpy.duration import Duration
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Image

    from push_ros.images import rgb_image_msg
    from push_ros.poses import pose_stamped_msg
    from push_ros.qos import RELIABLE_QOS, SENSOR_QOS
    from push_ros.stamps import stamp_from_seconds
    from pushbot.ros2cli.discovery import spin_until

    bag = tmp / f"bag_{rate:g}"
    context = Context()
    rclpy.init(args=[], context=context)
    node = rclpy.create_node("bench_record_talker", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    rgb = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    try:
        cam = node.create_publisher(Image, "bench/image", SENSOR_QOS)
        pose = node.create_publisher(PoseStamped, "bench/pose", RELIABLE_QOS)
        before = os.times()
        proc = subprocess.Popen([PUSHBOT, "bag", "record", "-o", str(bag), "bench/image",
                                 "bench/pose"], stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        if not spin_until(executor, lambda: cam.get_subscription_count() > 0
                          and pose.get_subscription_count() > 0, time.monotonic() + 60):
            raise RuntimeError("the recorder did not subscribe")
        n_img = n_pose = 0
        t0 = time.monotonic()
        next_img = next_pose = t0
        while (now := time.monotonic()) < t0 + seconds:
            if now >= next_img:
                cam.publish(rgb_image_msg(rgb, stamp_from_seconds(now - t0 + 1.0)))
                n_img += 1
                next_img += 1.0 / rate
            if now >= next_pose:
                pose.publish(pose_stamped_msg([0.01 * n_pose, 0, 0],
                                              stamp_from_seconds(now - t0 + 1.0)))
                n_pose += 1
                next_pose += 0.01
            time.sleep(max(0.0, min(next_img, next_pose) - time.monotonic()))
        pose.wait_for_all_acked(Duration(seconds=10))
        time.sleep(0.5)  # best-effort images in flight
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
        after = os.times()
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    counts = {m.group(1): int(m.group(2))
              for m in re.finditer(r"^\s+(/\S+) \[\S+\]: (\d+)$", out, re.M)}
    if proc.returncode != 0 or not counts:
        raise RuntimeError(f"pushbot bag record failed ({proc.returncode}):\n{out[-3000:]}")
    cpu = (after.children_user - before.children_user) + (after.children_system
                                                          - before.children_system)
    return {"rate": rate, "images": n_img, "images_rec": counts.get("/bench/image", 0),
            "poses": n_pose, "poses_rec": counts.get("/bench/pose", 0),
            "mb": _dir_size(bag) / 1e6, "cpu_per_s": cpu / seconds}


def demo_bag(tmp: Path, monitor_rate: float = 10.0) -> dict[str, float]:
    """Run the demo once; measure its bag, the renderer and the MP4."""
    import imageio_ffmpeg

    from pushbot.ros2cli.bag_store import open_reader
    from pushbot.viz.render import render_bag

    out = tmp / f"demo_{monitor_rate:g}"
    shutil.rmtree(out, ignore_errors=True)
    started = time.perf_counter()
    result = subprocess.run([PUSHBOT, "demo", "--skip-doctor", "--out", str(out),
                             "--monitor-rate", str(monitor_rate)],
                            capture_output=True, text=True, timeout=600)
    demo_wall = time.perf_counter() - started
    if result.returncode != 0:
        raise RuntimeError(result.stdout[-2000:] + result.stderr[-2000:])
    bag = out / "episode_bag"
    record = json.loads((out / "episode.json").read_text())
    with open_reader(bag) as reader:
        messages, topics = reader.message_count, len(reader.connections)
    t = time.perf_counter()  # the demo rendered it too; timed again here, in this process
    done = render_bag(bag, tmp / "r.mp4", gif=tmp / "r.gif", plot=tmp / "r.png",
                      start=min(record["frame_stamps"]))
    wall = time.perf_counter() - t
    mp4_frames, mp4_s = imageio_ffmpeg.count_frames_and_secs(str(out / "episode.mp4"))
    return {"steps": record["steps"], "mb": _dir_size(bag) / 1e6, "messages": messages,
            "topics": topics, "frames": done.frames, "render_s": wall,
            "mp4_kb": done.video.stat().st_size / 1e3, "gif_kb": done.gif.stat().st_size / 1e3,
            "monitor_rate": monitor_rate, "monitor_frames": done.monitor_frames,
            "fps": done.fps, "demo_wall_s": demo_wall,
            "episode_wall_s": record["wall_s"], "mp4_frames": mp4_frames, "mp4_s": mp4_s}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[5.0, 15.0, 30.0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--no-demo", action="store_true", help="skip parts 2 and 3")
    parser.add_argument("--demo-runs", type=int, default=2,
                        help="demo runs with and without the monitor each (part 3)")
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args(argv)
    from push_ros import dds

    dds.apply_default_profile()  # as every pushbot process (the graph's nodes, the recorder)

    rows = ["| images Hz | images recorded / published | poses (100 Hz, reliable) recorded / "
            "published | bag MB | MB/s | recorder CPU s per s |",
            "| --- | --- | --- | --- | --- | --- |"]
    with tempfile.TemporaryDirectory(prefix="bench_record_") as tmp_name:
        tmp = Path(tmp_name)
        for rate in args.rates:
            r = record_rate(rate, args.seconds, tmp)
            rows.append(f"| {r['rate']:g} | {r['images_rec']} / {r['images']} | "
                        f"{r['poses_rec']} / {r['poses']} | {r['mb']:.1f} | "
                        f"{r['mb'] / args.seconds:.1f} | {r['cpu_per_s']:.2f} |")
            print(rows[-1], flush=True)
        runs = [] if args.no_demo else [demo_bag(tmp, rate) for _ in range(args.demo_runs)
                                         for rate in (10.0, 0.0)]
        demo = runs[0] if runs else None
    body = (f"Part 1: {args.seconds:g} s per row, random 640x480 rgb8 images (best effort) "
            "and a reliable 100 Hz PoseStamped stream from this process to `pushbot bag "
            "record` (own process, zstd-compressed MCAP chunks; random pixels are the worst case "
            "for the compression: compare the demo's bag in part 2).\n\n"
            + "\n".join(rows) + "\n")
    if demo is not None:
        line = (f"\nPart 2: `pushbot demo --skip-doctor` (default trial, {demo['steps']} pushes):"
                f" bag {demo['mb']:.2f} MB, {demo['messages']} messages on {demo['topics']} "
                f"topics (raw depth not recorded); rendering {demo['frames']} video frames "
                f"(MP4 + GIF + plot) took {demo['render_s']:.1f} s "
                f"({1e3 * demo['render_s'] / max(1, demo['frames']):.0f} ms per frame, plot "
                f"included); MP4 {demo['mp4_kb']:.0f} kB, GIF {demo['gif_kb']:.0f} kB.\n")
        body += line
        body += ("\nPart 3: the monitor's cost, the same demo with the bridge's monitor at 10 Hz "
                 "of sim time (320x240, the video shows the pushes) and off (camera frames "
                 f"only), alternating, {args.demo_runs} runs each (machine shared; load "
                 f"average {os.getloadavg()[0]:.1f} at the end).\n\n"
                 "| monitor Hz | pushes | demo process wall s | episode wall s | video frames "
                 "(camera + monitor) | MP4 frames | MP4 s (fps) | render s | MP4 kB | GIF kB |\n"
                 "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n")
        for r in sorted(runs, key=lambda r: -r["monitor_rate"]):
            body += (f"| {r['monitor_rate']:g} | {r['steps']} | {r['demo_wall_s']:.1f} | "
                     f"{r['episode_wall_s']:.1f} | {r['frames']} "
                     f"({r['frames'] - r['monitor_frames']} + {r['monitor_frames']}) | "
                     f"{r['mp4_frames']} | {r['mp4_s']:.1f} "
                     f"({r['fps']:g}) | {r['render_s']:.1f} | {r['mp4_kb']:.0f} | "
                     f"{r['gif_kb']:.0f} |\n")
    print(body)
    if not args.no_write:
        cmd = "python benchmarks/bench_record.py " + " ".join(sys.argv[1:] if argv is None
                                                              else argv)
        update_section("record", format_section("Recording and replay (bench_record)",
                                                cmd.strip(), body))
    return 0


if __name__ == "__main__":
    sys.exit(main())
