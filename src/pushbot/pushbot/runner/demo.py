"""``pushbot demo`` (what ``make demo`` runs): the closed loop through the real ROS graph.

1. ``pushbot doctor`` (versions, DDS settings, a two-process publish/subscribe round trip;
   about 7 s; ``--skip-doctor`` leaves it out).
2. The four nodes start as separate processes over DDS with simulated time
   (:mod:`pushbot.runner.episode`): ``sim_bridge_node`` (pybullet, camera, ``/clock``),
   ``segmentation_node``, ``ekf_node`` and ``planner_node``.
3. One protocol trial (:class:`pushbot.runner.protocol.Trial`; default: the *mixed* task, 10 cm
   and 0.35 rad, on the held-out ``butter`` object with a random centre of mass, method ``ana``,
   k = 3): the scene is set through the bridge's parameters and ``~/reset``, the goal
   (first estimate + the task's offset) is sent on ``goal_pose``, and the graph pushes until
   ``planner/status`` says ``goal reached`` or ``failed``.
4. A summary from ground truth: steps, the true end-pose error against the goal region,
   the estimated centre of mass next to the true one, wall times.
5. Under ``--out`` (default ``out/demo``): ``episode_bag/`` (a rosbag2 folder in MCAP
   storage, :mod:`pushbot.ros2cli.bag`, of every topic of the graph from just before the episode to
   its end, except the raw depth images: 1.2 MB each, ``--record-depth`` keeps
   them), ``episode.mp4`` (every camera frame of the recording and, merged in time order, the
   bridge's monitor frames rendered during each push (``sim/monitor/image_raw``, turned on
   at ``--monitor-rate`` Hz of sim time, 320 x 240), so the pusher is seen moving the object;
   with the perception mask, the perceived outline at the estimate, the affordance colouring,
   the chosen push, the goal and a legend: :mod:`pushbot.viz.render`, the renderer of ``pushbot
   replay``; it runs at twice sim time during pushes), ``episode.gif`` (the same, at most 60
   frames, smaller), ``episode_estimate.png`` (estimate vs ground truth over
   time), ``trajectory.png`` (true and estimated poses, goal, pushes; top view),
   ``episode.json`` (the episode record of docs/design/evaluation.md) and the node logs
   (``graph_logs/``). ``--no-record`` skips the recording and the video.

Ctrl-C (or SIGTERM) stops every node process (SIGINT, then SIGTERM, then SIGKILL to each
process group) and exits with status 130.
"""

from __future__ import annotations

import argparse
import faulthandler
import json
import math
import re
import shutil
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from pushbot.ros2cli.bag_record import BagRecorder, TopicSelection
from pushbot.ros2cli.bag_store import BagError
from pushbot.runner.doctor import add_arguments as add_doctor_arguments
from pushbot.runner.doctor import run_doctor
from pushbot.runner.protocol import METHODS, TASKS, Trial
from pushbot.viz.episode_bag import DEPTH, TOPICS, load_episode
from pushbot.viz.render import RenderError, closed_ring, in_world, render_bag

EXIT_INTERRUPTED = 130
#: Seconds the recording waits for the graph's topics before the episode starts.
RECORD_START_TIMEOUT = 20.0
#: The bridge's monitor stream for the video: Hz of sim time, image size (px).
MONITOR_RATE, MONITOR_SIZE = 10.0, (320, 240)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot demo`` (its own first, then the doctor's)."""
    parser.add_argument("--object", default="butter",
                        help="library object name or object specification file (default butter)")
    parser.add_argument("--task", default="mixed", choices=sorted(TASKS),
                        help="task of the evaluation protocol (default mixed: 10 cm and 0.35 rad)")
    methods = sorted(m for m in METHODS if m != "pushnet")
    parser.add_argument("--method", default="ana", choices=methods,
                        help="planner method (default ana)")
    parser.add_argument("--k", type=int, default=3, help="contact points sampled per step "
                        "(default 3)")
    parser.add_argument("--com", default="random", choices=("centre", "random"),
                        help="centre of mass at the geometric centre or randomised from the "
                        "seed (default random)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the scene, goal direction and planner (default 0)")
    parser.add_argument("--index", type=int, default=0,
                        help="trial index: initial orientation 18 deg x (index mod 20) "
                        "(default 0)")
    parser.add_argument("--max-steps", type=int, default=30, help="pushes allowed (default 30)")
    parser.add_argument("--robot", default="pusher", choices=("pusher", "arm"),
                        help="what pushes: the simulator's free pusher, or the simulated "
                             "Panda arm driven by push_executor_node (default %(default)s)")
    parser.add_argument("--out", default="out/demo", type=Path,
                        help="output directory (default out/demo)")
    parser.add_argument("--skip-doctor", action="store_true", help="do not run doctor first")
    parser.add_argument("--pause", type=float, default=0.0,
                        help="seconds to wait with the graph up before the episode, e.g. to "
                        "attach a viewer to the topics; Ctrl-C works meanwhile (default 0)")
    parser.add_argument("--no-record", action="store_true",
                        help="do not record the episode bag nor render the video")
    parser.add_argument("--record-depth", action="store_true",
                        help="also record the raw depth images (about 1.2 MB per frame)")
    parser.add_argument("--monitor-rate", type=float, default=MONITOR_RATE, metavar="HZ",
                        help="frames per second of sim time the bridge renders during each "
                        "push for the video (sim/monitor/image_raw, 320 x 240); 0 = off, "
                        "the video then has the camera frames only (default %(default)s; "
                        "off with --no-record)")
    doctor = parser.add_argument_group("doctor options (the check run before the demo)")
    add_doctor_arguments(doctor)


def run_demo(args: argparse.Namespace) -> int:
    """Run the demo; see the module docstring. Returns the exit code."""
    started = time.monotonic()
    # `kill -USR1 <pid>` prints every thread's stack to stderr (a hung shutdown can be seen).
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    try:
        trial = Trial(object=args.object, task=args.task, method=args.method, k=args.k,
                      state="filter", com=args.com, index=args.index, seed=args.seed,
                      max_steps=args.max_steps)
        from push_core.objects import load_object

        spec = load_object(args.object)
    except ValueError as exc:
        print(f"pushbot demo: {exc}", file=sys.stderr)
        return 2
    if not (math.isfinite(args.pause) and args.pause >= 0.0):
        print(f"pushbot demo: --pause must be a finite number of seconds >= 0, got "
              f"{args.pause}", file=sys.stderr)
        return 2
    if not (math.isfinite(args.monitor_rate) and 0.0 <= args.monitor_rate <= 60.0):
        print(f"pushbot demo: --monitor-rate must be in [0, 60] Hz, got {args.monitor_rate}",
              file=sys.stderr)
        return 2
    if not args.skip_doctor:
        status = run_doctor(args)
        if status != 0:
            print("pushbot demo: doctor failed (see above); fix the install first.")
            return status
        print()
    from pushbot.ros2cli.discovery import sigterm_as_keyboard_interrupt
    from pushbot.runner.domain import claim_domain
    from pushbot.runner.episode import GraphError, GraphRunner
    from pushbot.runner.graph_nodes import graph_node_names

    claim, refusal = claim_domain("demo")  # one graph per ROS domain
    if claim is None:
        print(refusal, file=sys.stderr)
        return 1

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    print(f'pushbot demo: {trial.task} task on {spec.name} ({trial.com} COM), method '
          f'{trial.method}, k = {trial.k}, seed {trial.seed}, index {trial.index}; starting '
          f'{", ".join(graph_node_names(args.robot))} (logs in {out / "graph_logs"})',
          flush=True)
    bag_dir = out / "episode_bag"
    try:
        with claim, sigterm_as_keyboard_interrupt(), GraphRunner(
                log_dir=out / "graph_logs", node_args=_bridge_args(args),
                robot=args.robot) as graph:
            t_ready = time.monotonic()
            if args.pause > 0.0:
                print(f"graph up after {t_ready - started:.1f} s; pausing {args.pause:g} s "
                      f"before the episode", flush=True)
                time.sleep(args.pause)
                print("running the episode", flush=True)
            else:
                print(f"graph up after {t_ready - started:.1f} s; running the episode",
                      flush=True)
            with _recording(None if args.no_record else bag_dir, args.record_depth):
                record = graph.run(trial)
    except KeyboardInterrupt:
        print("\npushbot demo: interrupted; every node process was stopped", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (GraphError, BagError) as exc:
        print(f"pushbot demo: {exc}", file=sys.stderr)
        return 1
    wall = time.monotonic() - started
    record["demo_wall_s"] = wall
    (out / "episode.json").write_text(json.dumps(record, indent=1))
    files: list[Path | None] = [out / "episode.json"]
    outline = None
    if not args.no_record:
        files.append(bag_dir)
        try:
            # From the episode's first frame (the recording may start with the old scene).
            start = min(record["frame_stamps"], default=-math.inf)
            done = render_bag(bag_dir, out / "episode.mp4", gif=out / "episode.gif",
                              plot=out / "episode_estimate.png", start=start)
            files += [done.video, done.gif, done.plot]
            outline = load_episode(bag_dir).outline
            print(f"rendered {done.frames} video frames ({done.frames - done.monitor_frames} "
                  f"camera, {done.monitor_frames} monitor) at {done.fps:g} fps", flush=True)
        except (BagError, RenderError) as exc:
            print(f"pushbot demo: no video: {exc}", file=sys.stderr)
    plot = out / "trajectory.png"
    _plot(record, outline, spec, plot)
    _summary(record, trial, wall, [*files, plot])
    return 0


#: Topics the demo's recording must have subscribed before the episode starts: the video's
#: (the bridge always offers the monitor topic; it carries frames only when the monitor is on).
RECORDED_TOPICS = TOPICS


def _bridge_args(args: argparse.Namespace) -> dict[str, list[str]]:
    """The bridge's monitor parameters for the video (none with ``--no-record``)."""
    if args.no_record or args.monitor_rate <= 0.0:
        return {}
    width, height = MONITOR_SIZE
    return {"sim_bridge_node": [f"monitor.rate:={float(args.monitor_rate)}",
                                f"monitor.width:={width}", f"monitor.height:={height}"]}


@contextmanager
def _recording(bag_dir: Path | None, depth: bool) -> Iterator[None]:
    """Record every topic of the graph (raw depth only with ``depth``) into ``bag_dir``
    (replaced) while the block runs; ``None``: record nothing."""
    if bag_dir is None:
        yield
        return
    if bag_dir.exists():
        shutil.rmtree(bag_dir)
    exclude = None if depth else re.compile(re.escape(DEPTH))
    with BagRecorder(bag_dir, TopicSelection(all_topics=True, exclude=exclude)) as recorder:
        # perception/outline and estimator/* are latched: their last samples are recorded
        # even though they were published before the recorder subscribed.
        missing = recorder.wait_for_topics(RECORDED_TOPICS, RECORD_START_TIMEOUT)
        if missing:
            print(f'pushbot demo: recording without {", ".join(missing)} (no publisher '
                  f'after {RECORD_START_TIMEOUT:g} s)', file=sys.stderr)
        yield
    counts = recorder.counts()
    print(f"recorded {sum(counts.values())} messages on {len(counts)} topics to {bag_dir}",
          flush=True)


def _summary(rec: dict[str, Any], trial: Trial, wall: float, files: list[Path | None]) -> None:
    tol_xy, tol_theta = trial.tolerances
    print(f'\nresult: {rec["reason"]} after {rec["steps"]} pushes '
          f'({"success" if rec["success"] else "FAILURE"} by ground truth)')
    print(f'true end-pose error: {1e3 * rec["end_error_xy"]:.1f} mm, '
          f'{math.degrees(rec["end_error_theta"]):.1f} deg (goal region {1e3 * tol_xy:.1f} mm, '
          f'{math.degrees(tol_theta):.1f} deg)'
          + (" - orientation ignored: rotationally symmetric object"
             if rec.get("orientation_ignored") else ""))
    est, true = rec.get("com_est"), rec.get("com_true_episode")
    if est is not None and true is not None:
        print(f'centre of mass (object frame, mm): estimated ({1e3 * est[0]:.1f}, '
              f'{1e3 * est[1]:.1f}), true ({1e3 * true[0]:.1f}, {1e3 * true[1]:.1f}), error '
              f'{1e3 * rec["com_error"]:.1f} mm')
    cycles = rec.get("cycle_s") or []
    print(f'robot time: {rec.get("robot_time_s", math.nan):.1f} s from the goal to the final '
          f'stop (simulated)' + (f"; {np.median(cycles):.1f} s between pushes, median"
                                 if cycles else ""))
    lat = rec.get("step_latency_ms") or []
    lat_text = f"; push executed -> next plan {np.median(lat):.0f} ms median" if lat else ""
    print(f'wall time: {wall:.1f} s in all, episode {rec["wall_s"]:.1f} s{lat_text}')
    written = ", ".join(str(f) for f in files if f is not None)
    print(f"wrote {written}")


# --------------------------------------------------------------------------------------------
# Plot
# --------------------------------------------------------------------------------------------
def _plot(rec: dict[str, Any], outline: np.ndarray | None, spec: Any, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trial = Trial(**rec["trial"])
    true = np.asarray(rec["poses_true"])
    est = np.asarray(rec["poses_est"])
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    lib = closed_ring(spec.polyline())
    goal_true = true[0] + trial.goal_offset()
    for j, pose in enumerate(true):
        ax.plot(*in_world(pose, lib).T, color=plt.cm.viridis(j / max(1, len(true) - 1)), lw=1,
                label="true outline (after each push)" if j == 0 else None)
    ax.plot(*in_world(goal_true, lib).T, color="m", lw=2, ls="--", label="goal (true frame)")
    if outline is not None:
        ax.plot(*in_world(est[-1], closed_ring(outline)).T, color="orange", lw=1.5,
                label="perceived outline at the final estimate")
    ax.plot(true[:, 0], true[:, 1], "k.-", label="true position")
    ax.plot(est[:, 0], est[:, 1], "x--", color="tab:red", label="estimated position")
    for j, push in enumerate(rec["pushes"]):
        a, c, e = np.asarray(push)
        ax.annotate("", xy=e, xytext=a, arrowprops={"arrowstyle": "->", "color": "tab:blue"})
        ax.text(*a, str(j + 1), fontsize=7, color="tab:blue")
    ax.set_aspect("equal")
    ax.set_xlabel("world x [m]")
    ax.set_ylabel("world y [m]")
    ax.set_title(f'{spec.name}, {trial.task}, {trial.method} k={trial.k}: {rec["reason"]} after '
                 f'{rec["steps"]} pushes\ntrue end error {1e3 * rec["end_error_xy"]:.1f} mm, '
                 f'{math.degrees(rec["end_error_theta"]):.1f} deg (pushes: blue arrows)',
                 fontsize=9)
    ax.legend(loc="best", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
