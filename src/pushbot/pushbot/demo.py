"""``pushbot demo`` (what ``make demo`` runs): the most complete real thing that exists today.

The closed-loop demo (perception, estimator and planner pushing an object to a goal) replaces
this once those nodes land (issue 7). Until then the demo runs the parts that exist, for real:

1. ``pushbot doctor``: versions and a two-process publish/subscribe round trip;
2. the pybullet ``sim_bridge_node`` as a separate process (``pushbot run``), driven over DDS
   like a planner would drive it: a few straight pushes on ``planner/push`` (through the
   centre, off-centre to rotate, and one that misses), each answered by ``pusher/executed``,
   the ground-truth ``sim/object_pose`` and a fresh camera frame;
3. for every push, the analytical pushing model of ``push_core`` (SPEC §3, rolled out on the
   true outline with the true COM, the uniform-pressure limit surface and the true friction)
   predicts the object's motion, printed next to what the physics did;
4. the last colour image and a top-down plot of the poses are written under ``--out``.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from pushbot.doctor import add_arguments as add_doctor_arguments
from pushbot.doctor import run_doctor

#: Pushes of the demo: (side of the object in the object frame, offset of the push line from
#: the COM in metres, push angle to the inward normal in degrees, length in metres, label).
PUSHES = (
    ((-1.0, 0.0), 0.0, 0.0, 0.04, 'through the COM'),
    ((0.0, -1.0), 0.025, 0.0, 0.04, '2.5 cm off the COM'),
    ((-1.0, 0.0), 0.0, 30.0, 0.03, 'at 30 deg to the normal'),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot demo``."""
    add_doctor_arguments(parser)
    parser.add_argument('--object', default='butter',
                        help='library object name or object specification file (default butter)')
    parser.add_argument('--out', default='out/demo', type=Path,
                        help='output directory for the image and plot (default out/demo)')
    parser.add_argument('--skip-doctor', action='store_true', help='do not run doctor first')
    parser.add_argument('--step-timeout', type=float, default=60.0,
                        help='seconds to wait for the bridge at each step (default 60)')


def run_demo(args: argparse.Namespace) -> int:
    """Run the demo; see the module docstring. Returns the exit code."""
    started = time.monotonic()
    if not args.skip_doctor:
        status = run_doctor(args)
        if status != 0:
            print('pushbot demo: doctor failed (see above); fix the install first.')
            return status
        print()
    from push_core.objects import load_object

    try:
        spec = load_object(args.object)
    except ValueError as exc:
        print(f'pushbot demo: {exc}', file=sys.stderr)
        return 2
    print(f'pushbot demo: sim_bridge_node with {spec.name} ({spec.source}), pushes over DDS; '
          'the closed loop (perception, estimator, planner) is not built yet.')
    bridge = _start_bridge(args.object, args.out)
    try:
        return _drive(spec, bridge, args, started)
    finally:
        _stop(bridge)


def _start_bridge(obj: str, out: Path) -> subprocess.Popen:
    out.mkdir(parents=True, exist_ok=True)
    log = open(out / 'sim_bridge.log', 'w')  # noqa: SIM115 - closed with the process
    cmd = [sys.executable, '-m', 'pushbot.cli', 'run', 'sim_bridge_node', '--ros-args',
           '-p', f'object:={obj}']
    return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                            env=dict(os.environ, PYTHONUNBUFFERED='1'))


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _drive(spec: Any, bridge: subprocess.Popen, args: argparse.Namespace,
           started: float) -> int:
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path as PathMsg
    from rclpy.qos import QoSProfile, qos_profile_sensor_data
    from sensor_msgs.msg import Image

    from push_core.rollout import rollout_push
    from pushbot.graph import cli_node, spin_until
    from sim_bridge.conversions import (
        image_to_array,
        path_from_points,
        stamp_from_seconds,
        xytheta_from_pose,
    )
    from sim_bridge.world import push_points

    latest: dict[str, Any] = {}
    executed: list[Any] = []
    with cli_node('demo') as (node, executor):
        node.create_subscription(PoseStamped, 'sim/object_pose',
                                 lambda m: latest.__setitem__('pose', m), QoSProfile(depth=10))
        node.create_subscription(PathMsg, 'pusher/executed', executed.append,
                                 QoSProfile(depth=10))
        node.create_subscription(Image, 'camera/color/image_raw',
                                 lambda m: latest.__setitem__('rgb', m), qos_profile_sensor_data)
        push_pub = node.create_publisher(PathMsg, 'planner/push', QoSProfile(depth=10))

        def alive() -> bool:
            if bridge.poll() is not None:
                raise RuntimeError(f'sim_bridge_node exited with status {bridge.returncode}; '
                                   f'see {args.out / "sim_bridge.log"}')
            return True

        def wait(predicate: Any, what: str) -> None:
            ok = spin_until(executor, lambda: alive() and predicate(),
                            time.monotonic() + args.step_timeout)
            if not ok:
                raise TimeoutError(f'no {what} within {args.step_timeout:.0f} s; see '
                                   f'{args.out / "sim_bridge.log"}')

        try:
            wait(lambda: 'pose' in latest and push_pub.get_subscription_count() > 0,
                 'ground-truth pose from sim_bridge_node')
            rows, poses = [], [xytheta_from_pose(latest['pose'])]
            outline = spec.polyline()
            l_guess = spec.limit_surface_guess()
            for side, offset, angle_deg, length, label in PUSHES:
                pose = poses[-1]
                point, normal = _outline_point(spec, np.asarray(side), offset)
                approach, contact, end = push_points(pose, point, normal,
                                                     math.radians(angle_deg), length)
                count = len(executed)
                stamp = stamp_from_seconds(0.0)
                push_pub.publish(path_from_points(np.stack([approach, contact, end]),
                                                  [stamp] * 3))
                wait(lambda n=count: len(executed) > n, 'pusher/executed')
                latest.pop('pose', None)
                wait(lambda: 'pose' in latest, 'pose after the push')
                after = xytheta_from_pose(latest['pose'])
                prediction = rollout_push(outline, pose, spec.com, l_guess, spec.friction_pusher,
                                          approach[None], (end - approach)[None]).poses[0, -1]
                rows.append((label, pose, after, prediction))
                poses.append(after)
            wait(lambda: 'rgb' in latest, 'camera frame')
            rgb = image_to_array(latest['rgb'])
        except (RuntimeError, TimeoutError) as exc:
            print(f'pushbot demo: {exc}', file=sys.stderr)
            return 1
    _report(rows, rgb, np.array(poses), spec, args.out, time.monotonic() - started)
    return 0


def _outline_point(spec: Any, side: np.ndarray, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Outline point on ``side`` (outward normal within 30 deg of it, object frame) whose
    inward normal line passes closest to ``offset`` metres from the COM."""
    points, normals = spec.outline(0.002)
    facing = normals @ (side / np.linalg.norm(side)) > math.cos(math.radians(30))
    rel = spec.com - points
    lever = np.abs(normals[:, 0] * rel[:, 1] - normals[:, 1] * rel[:, 0])
    i = int(np.argmin(np.where(facing, np.abs(lever - offset), np.inf)))
    return points[i], normals[i]


def _report(rows: list, rgb: np.ndarray, poses: np.ndarray, spec: Any, out: Path,
            wall: float) -> None:
    import cv2

    print(f'\n{"push":<26} {"physics dx, dy mm, dtheta deg":>32} {"model":>26} '
          f'{"error mm / deg":>15}')
    for label, before, after, pred in rows:
        true = after - before
        model = pred - before
        err_t = 1000 * float(np.linalg.norm(true[:2] - model[:2]))
        err_r = math.degrees(abs(math.remainder(true[2] - model[2], 2 * math.pi)))
        print(f'{label:<26} {_fmt(true):>32} {_fmt(model):>26} {err_t:>8.1f} / {err_r:4.1f}')
    image = out / 'last_frame.png'
    cv2.imwrite(str(image), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    plot = out / 'poses.png'
    _plot(poses, spec, plot)
    print(f'\nwrote {image} and {plot}; wall time {wall:.1f} s')


def _fmt(delta: np.ndarray) -> str:
    return (f'{1000 * delta[0]:6.1f}, {1000 * delta[1]:6.1f}, '
            f'{math.degrees(math.remainder(delta[2], 2 * math.pi)):6.1f}')


def _plot(poses: np.ndarray, spec: Any, path: Path) -> None:
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from push_core.geometry import object_to_world

    fig, ax = plt.subplots(figsize=(5, 5))
    ring = np.vstack([spec.polyline(), spec.polyline()[:1]])
    for k, pose in enumerate(poses):
        xy = object_to_world(pose, ring)
        ax.plot(xy[:, 0], xy[:, 1], color=plt.cm.viridis(k / max(1, len(poses) - 1)))
    ax.plot(poses[:, 0], poses[:, 1], 'k.-', label='object origin (ground truth)')
    ax.set_aspect('equal')
    ax.set_xlabel('world x [m]')
    ax.set_ylabel('world y [m]')
    ax.set_title(f'{spec.name}: poses after each push')
    ax.legend(loc='upper left', fontsize=8)
    fig.savefig(path, dpi=100)
    plt.close(fig)
