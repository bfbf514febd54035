"""The ROS graph, measured: camera frames across processes, the demo, per-step latency, and
graph vs in-process agreement.

1. **Camera frames across processes.** ``sim_bridge_node`` (640 x 480, re-publishing its frame
   at 5 Hz while idle) in one process, a subscriber counting ``camera/color/image_raw`` (rgb8,
   0.9 MB) and ``camera/aligned_depth_to_color/image_raw`` (32FC1, 1.2 MB) in another, for
   ``--seconds``, with the DDS profile before this fix (Fast DDS's default transports + 100 ms
   heartbeats, the previous ``pushbot/data/fastdds.xml``) and with the bundled profile, each
   with and without ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4`` (what the tests set).
2. **Demo wall time.** ``make demo`` (doctor + graph start-up + one episode + outputs) run
   ``--demo-runs`` times with the venv built; the median of the process wall times.
3. **Per-step latency** of the graph: wall time from ``pusher/executed`` to the next
   ``planner/push`` as seen by a client process (perception of the new frame, EKF update,
   planning, DDS), over every step of the agreement trials.
4. **Agreement.** ``--trials`` protocol trials (butter, mixed task, random COM, ana, k = 3,
   state ``filter``) through the graph (:func:`pushbot.runner.episode.run_graph_trials`) and
   in-process (:func:`pushbot.experiments.inprocess.run_trial`): success rates with 95 % Wilson
   intervals and a two-sided two-proportion z-test, trial-by-trial outcome agreement, steps and true
   end errors.

Writes ``docs/results/graph.md``. The machine is shared (2 cores): the load
average is recorded with the figures.

Usage::

    .venv/bin/python benchmarks/bench_graph.py [--trials N] [--demo-runs R] [--seconds S]
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

REPO = Path(__file__).resolve().parents[1]
PUSHBOT = Path(sys.executable).parent / "pushbot"
RATE = 5.0
#: The profile before the fix (commit 39d02f9): default transports, 100 ms heartbeats.
OLD_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <data_writer profile_name="pushbot_default_writer" is_default_profile="true">
      <times><heartbeatPeriod><sec>0</sec><nanosec>100000000</nanosec></heartbeatPeriod></times>
    </data_writer>
  </profiles>
</dds>
"""
COUNTER = """
import json, sys, time
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image
from pushbot.ros2cli.discovery import cli_node, spin_until
seconds = float(sys.argv[1])
arrivals = {"rgb": [], "depth": []}
with cli_node("bench_graph") as (node, executor):
    for key, topic in (("rgb", "camera/color/image_raw"),
                       ("depth", "camera/aligned_depth_to_color/image_raw")):
        node.create_subscription(Image, topic, lambda m, k=key: arrivals[k].append(
            time.monotonic()), qos_profile_sensor_data)
    spin_until(executor, lambda: arrivals["rgb"] or arrivals["depth"], time.monotonic() + 120)
    start = time.monotonic()
    spin_until(executor, lambda: False, start + seconds)
print(json.dumps({k: sum(1 for t in v if start < t <= start + seconds)
                  for k, v in arrivals.items()}))
"""


def frame_rates(profile: str, builtin: str | None, seconds: float, domain: int) -> dict:
    """Delivered frames/s of rgb and depth from a bridge process to a counter process."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               FASTRTPS_DEFAULT_PROFILES_FILE=profile, PYTHONUNBUFFERED="1")
    env.pop("FASTDDS_BUILTIN_TRANSPORTS", None)
    if builtin:
        env["FASTDDS_BUILTIN_TRANSPORTS"] = builtin
    bridge = subprocess.Popen([str(PUSHBOT), "run", "sim_bridge_node", "--ros-args", "-p",
                               f"idle_frame_rate:={RATE}"], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    try:
        out = subprocess.run([sys.executable, "-c", COUNTER, str(seconds)], env=env,
                             capture_output=True, text=True, timeout=seconds + 180, check=True)
        counts = json.loads(out.stdout.strip().splitlines()[-1])
    finally:
        bridge.send_signal(2)
        try:
            bridge.wait(timeout=20)
        except subprocess.TimeoutExpired:
            bridge.kill()
            bridge.wait()
    return {k: v / seconds for k, v in counts.items()}


def demo_runs(n: int) -> list[tuple[float, str]]:
    """(wall seconds of `make demo`, its summary lines) per run."""
    runs = []
    for _ in range(n):
        t0 = time.monotonic()
        out = subprocess.run(["make", "demo"], cwd=REPO, capture_output=True, text=True,
                             timeout=600, check=False)
        wall = time.monotonic() - t0
        if out.returncode != 0:
            raise RuntimeError(f"make demo failed:\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}")
        lines = [ln for ln in out.stdout.splitlines()
                 if ln.startswith(("result:", "true end-pose", "centre of mass", "wall time"))]
        runs.append((wall, "; ".join(lines)))
    return runs


def wilson(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def two_proportion_p(s1: int, s2: int, n: int) -> float:
    """Two-sided p-value of the pooled two-proportion z-test (1.0 when both rates are 0 or 1)."""
    pooled = (s1 + s2) / (2 * n)
    if pooled in (0.0, 1.0):
        return 1.0
    z = (s1 - s2) / n / math.sqrt(pooled * (1 - pooled) * 2 / n)
    return math.erfc(abs(z) / math.sqrt(2))


def agreement(n: int, out_dir: Path) -> tuple[list[dict], list[dict]]:
    from pushbot.experiments.inprocess import run_trial
    from pushbot.runner.episode import run_graph_trials
    from pushbot.runner.protocol import Trial

    trials = [Trial(object="butter", task="mixed", method="ana", k=3, state="filter",
                    com="random", index=i, seed=0) for i in range(n)]
    graph = run_graph_trials(trials, out_dir=out_dir, progress=True)
    in_process = [run_trial(t) for t in trials]
    return graph, in_process


def _mean_mm(records: list[dict]) -> str:
    ok = [r for r in records if r["success"]]
    if not ok:
        return "-"
    return (f"{1e3 * statistics.mean(r['end_error_xy'] for r in ok):.1f} mm / "
            f"{math.degrees(statistics.mean(r['end_error_theta'] for r in ok)):.1f} deg")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20, help="agreement trials (default 20)")
    parser.add_argument("--demo-runs", type=int, default=3, help="make demo runs (default 3)")
    parser.add_argument("--seconds", type=float, default=10.0,
                        help="seconds of frame counting per configuration (default 10)")
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    args = parser.parse_args()
    load_before = os.getloadavg()
    domain = 150 + os.getpid() % 50

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "old_fastdds.xml"
        old.write_text(OLD_PROFILE)
        from push_ros.dds import profile_path

        for label, profile in (("before (default transports)", str(old)),
                               ("after (bundled profile)", str(profile_path()))):
            for builtin in (None, "UDPv4"):
                rates = frame_rates(profile, builtin, args.seconds, domain)
                rows.append((label, builtin or "unset", rates))
                print(label, builtin, rates, flush=True)

        demos = demo_runs(args.demo_runs)
        for wall, text in demos:
            print(f"make demo: {wall:.1f} s; {text}", flush=True)

        graph, in_process = agreement(args.trials, Path(tmp))
    load_after = os.getloadavg()

    n = args.trials
    s_g = sum(r["success"] for r in graph)
    s_p = sum(r["success"] for r in in_process)
    lo_g, hi_g = wilson(s_g, n)
    lo_p, hi_p = wilson(s_p, n)
    same = sum(a["success"] == b["success"] for a, b in zip(graph, in_process, strict=True))
    same_steps = sum(a["steps"] == b["steps"] for a, b in zip(graph, in_process, strict=True))
    latencies = [v for r in graph for v in r.get("step_latency_ms", [])]
    lat_text = (f"median {statistics.median(latencies):.0f} ms, 90th percentile "
                f"{sorted(latencies)[int(0.9 * (len(latencies) - 1))]:.0f} ms over "
                f"{len(latencies)} steps" if latencies else "no steps measured")
    walls = [w for w, _ in demos]
    body = [
        f"Load average (1 min) {load_before[0]:.1f} before, {load_after[0]:.1f} after "
        "(2 cores shared with other jobs: wall times are noisy).",
        "",
        f"**Camera frames delivered across processes** (bridge re-publishing at {RATE:.0f} Hz, "
        f"counted for {args.seconds:.0f} s in a second process; 640 x 480, rgb8 0.9 MB + "
        "32FC1 1.2 MB per frame):",
        "",
        "| DDS profile | FASTDDS_BUILTIN_TRANSPORTS | rgb frames/s | depth frames/s |",
        "| --- | --- | --- | --- |",
        *[f"| {label} | {b} | {r['rgb']:.2f} | {r['depth']:.2f} |" for label, b, r in rows],
        "",
        f"**`make demo`** (venv built; doctor + four node processes + one mixed-task episode on "
        f"butter with random COM + GIF and plot): median {statistics.median(walls):.1f} s "
        f"wall over {len(walls)} runs ({', '.join(f'{w:.1f}' for w in walls)} s); target "
        "<= 120 s. Last run: " + demos[-1][1],
        "",
        f"**Per-step latency of the graph** (wall time from `pusher/executed` to the next "
        f"`planner/push` at a client process: perception of the new frame, EKF update, "
        f"planning, DDS): {lat_text}.",
        "",
        f"**Graph vs in-process** ({n} trials: butter, mixed task, random COM, ana, k = 3, "
        "state filter, small goal region, seed 0, indices 0..n-1; the same scenes, goals and "
        "planner seeds):",
        "",
        "| engine | success | 95 % Wilson interval | mean steps | mean true end error "
        "(successes) | mean wall s per trial |",
        "| --- | --- | --- | --- | --- | --- |",
        f"| graph (4 processes, DDS) | {s_g}/{n} | [{lo_g:.2f}, {hi_g:.2f}] | "
        f"{statistics.mean(r['steps'] for r in graph):.1f} | {_mean_mm(graph)} | "
        f"{statistics.mean(r['wall_s'] for r in graph):.1f} |",
        f"| in-process (`pushbot.experiments.inprocess`) | {s_p}/{n} | [{lo_p:.2f}, {hi_p:.2f}] | "
        f"{statistics.mean(r['steps'] for r in in_process):.1f} | {_mean_mm(in_process)} | "
        f"{statistics.mean(r['wall_s'] for r in in_process):.1f} |",
        "",
        f"Intervals overlap: {'yes' if lo_g <= hi_p and lo_p <= hi_g else 'NO'}; two-proportion "
        f"z-test p = {two_proportion_p(s_g, s_p, n):.2f}. Same outcome in {same}/{n} trials, "
        f"same number of steps in {same_steps}/{n}. Steps per trial, graph: "
        f"{[r['steps'] for r in graph]}; in-process: {[r['steps'] for r in in_process]}. "
        "Failures, graph: "
        f"{[r['reason'] for r in graph if not r['success']] or 'none'}; in-process: "
        f"{[r['reason'] for r in in_process if not r['success']] or 'none'}.",
    ]
    command = ("python benchmarks/bench_graph.py" + (f" --trials {n}" if n != 20 else "")
               + (f" --demo-runs {args.demo_runs}" if args.demo_runs != 3 else ""))
    section = format_section("ROS graph: DDS transport, demo, latency, agreement (`graph`)",
                             command, "\n".join(body))
    print(section)
    if not args.no_write:
        update_section("graph", section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
