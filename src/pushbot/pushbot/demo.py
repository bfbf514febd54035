"""``pushbot demo`` (what ``make demo`` runs): the closed loop through the real ROS graph.

1. ``pushbot doctor`` (versions, DDS settings, a two-process publish/subscribe round trip;
   about 7 s; ``--skip-doctor`` leaves it out).
2. The four nodes start as separate processes over DDS with simulated time
   (:mod:`pushbot.graph_episode`): ``sim_bridge_node`` (pybullet, camera, ``/clock``),
   ``segmentation_node``, ``ekf_node`` and ``planner_node``.
3. One protocol trial (:class:`pushbot.protocol.Trial`; default: the *mixed* task, 10 cm and
   0.35 rad, on the held-out ``butter`` object with a random centre of mass, method ``ana``,
   k = 3): the scene is set through the bridge's parameters and ``~/reset``, the goal
   (first estimate + the task's offset) is sent on ``goal_pose``, and the graph pushes until
   ``planner/status`` says ``goal reached`` or ``failed``.
4. A summary from ground truth: steps, the true end-pose error against the goal region,
   the estimated centre of mass next to the true one, wall times.
5. Under ``--out`` (default ``out/demo``): ``episode.gif`` (the camera frame before the first
   push and after every push, with the perception mask, the perceived outline at the estimated
   pose, the goal outline and the next push overlaid), ``trajectory.png`` (true and estimated
   poses, goal, pushes; top view), ``episode.json`` (the episode record of
   docs/ARCHITECTURE.md) and the node logs (``graph_logs/``).

Ctrl-C (or SIGTERM) stops every node process (SIGINT, then SIGTERM, then SIGKILL to each
process group) and exits with status 130.
"""

from __future__ import annotations

import argparse
import faulthandler
import json
import math
import signal
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from pushbot.doctor import add_arguments as add_doctor_arguments
from pushbot.doctor import run_doctor
from pushbot.protocol import METHODS, TASKS, Trial

#: Colours (RGB) of the overlays.
MASK_RGB = (40, 200, 80)
OUTLINE_RGB = (255, 220, 0)
GOAL_RGB = (255, 40, 200)
PUSH_RGB = (0, 200, 255)
EXIT_INTERRUPTED = 130


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot demo``."""
    add_doctor_arguments(parser)
    parser.add_argument('--object', default='butter',
                        help='library object name or object specification file (default butter)')
    parser.add_argument('--task', default='mixed', choices=sorted(TASKS),
                        help='SPEC §5 task (default mixed: 10 cm and 0.35 rad)')
    methods = sorted(m for m in METHODS if m != 'pushnet')
    parser.add_argument('--method', default='ana', choices=methods,
                        help='planner method (default ana)')
    parser.add_argument('--k', type=int, default=3, help='contact points sampled per step '
                        '(default 3)')
    parser.add_argument('--com', default='random', choices=('centre', 'random'),
                        help='centre of mass at the geometric centre or randomised from the '
                        'seed (default random)')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the scene, goal direction and planner (default 0)')
    parser.add_argument('--index', type=int, default=0,
                        help='trial index: initial orientation 18 deg x (index mod 20) '
                        '(default 0)')
    parser.add_argument('--max-steps', type=int, default=30, help='pushes allowed (default 30)')
    parser.add_argument('--out', default='out/demo', type=Path,
                        help='output directory (default out/demo)')
    parser.add_argument('--skip-doctor', action='store_true', help='do not run doctor first')
    parser.add_argument('--pause', type=float, default=0.0,
                        help='seconds to wait with the graph up before the episode, e.g. to '
                        'attach a viewer to the topics; Ctrl-C works meanwhile (default 0)')


def run_demo(args: argparse.Namespace) -> int:
    """Run the demo; see the module docstring. Returns the exit code."""
    started = time.monotonic()
    # `kill -USR1 <pid>` prints every thread's stack to stderr (a hung shutdown can be seen).
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    try:
        trial = Trial(object=args.object, task=args.task, method=args.method, k=args.k,
                      state='filter', com=args.com, index=args.index, seed=args.seed,
                      max_steps=args.max_steps)
        from push_core.objects import load_object

        spec = load_object(args.object)
    except ValueError as exc:
        print(f'pushbot demo: {exc}', file=sys.stderr)
        return 2
    if not (math.isfinite(args.pause) and args.pause >= 0.0):
        print(f'pushbot demo: --pause must be a finite number of seconds >= 0, got '
              f'{args.pause}', file=sys.stderr)
        return 2
    if not args.skip_doctor:
        status = run_doctor(args)
        if status != 0:
            print('pushbot demo: doctor failed (see above); fix the install first.')
            return status
        print()
    from pushbot.graph_episode import GraphError, GraphRunner, sigterm_as_keyboard_interrupt

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    print(f'pushbot demo: {trial.task} task on {spec.name} ({trial.com} COM), method '
          f'{trial.method}, k = {trial.k}, seed {trial.seed}, index {trial.index}; starting '
          f'sim_bridge_node, segmentation_node, ekf_node and planner_node (logs in '
          f'{out / "graph_logs"})', flush=True)
    try:
        with sigterm_as_keyboard_interrupt(), GraphRunner(log_dir=out / 'graph_logs',
                                                           record_frames=True) as graph:
            t_ready = time.monotonic()
            if args.pause > 0.0:
                print(f'graph up after {t_ready - started:.1f} s; pausing {args.pause:g} s '
                      f'before the episode', flush=True)
                time.sleep(args.pause)
                print('running the episode', flush=True)
            else:
                print(f'graph up after {t_ready - started:.1f} s; running the episode',
                      flush=True)
            record = graph.run(trial)
            recorded = graph.rec
    except KeyboardInterrupt:
        print('\npushbot demo: interrupted; every node process was stopped', file=sys.stderr)
        return EXIT_INTERRUPTED
    except GraphError as exc:
        print(f'pushbot demo: {exc}', file=sys.stderr)
        return 1
    wall = time.monotonic() - started
    record['demo_wall_s'] = wall
    (out / 'episode.json').write_text(json.dumps(record, indent=1))
    gif = _write_gif(record, recorded, out / 'episode.gif')
    plot = out / 'trajectory.png'
    _plot(record, recorded, spec, plot)
    _summary(record, trial, wall, [out / 'episode.json', gif, plot])
    return 0


def _summary(rec: dict[str, Any], trial: Trial, wall: float, files: list[Path | None]) -> None:
    tol_xy, tol_theta = trial.tolerances
    print(f'\nresult: {rec["reason"]} after {rec["steps"]} pushes '
          f'({"success" if rec["success"] else "FAILURE"} by ground truth)')
    print(f'true end-pose error: {1e3 * rec["end_error_xy"]:.1f} mm, '
          f'{math.degrees(rec["end_error_theta"]):.1f} deg (goal region {1e3 * tol_xy:.1f} mm, '
          f'{math.degrees(tol_theta):.1f} deg)'
          + (' - orientation ignored: rotationally symmetric object'
             if rec.get('orientation_ignored') else ''))
    est, true = rec.get('com_est'), rec.get('com_true_episode')
    if est is not None and true is not None:
        print(f'centre of mass (object frame, mm): estimated ({1e3 * est[0]:.1f}, '
              f'{1e3 * est[1]:.1f}), true ({1e3 * true[0]:.1f}, {1e3 * true[1]:.1f}), error '
              f'{1e3 * rec["com_error"]:.1f} mm')
    lat = rec.get('step_latency_ms') or []
    lat_text = f'; push executed -> next plan {np.median(lat):.0f} ms median' if lat else ''
    print(f'wall time: {wall:.1f} s in all, episode {rec["wall_s"]:.1f} s{lat_text}')
    written = ', '.join(str(f) for f in files if f is not None)
    print(f'wrote {written}')


# --------------------------------------------------------------------------------------------
# Video and plot
# --------------------------------------------------------------------------------------------
def _ring(points: np.ndarray) -> np.ndarray:
    return np.vstack([points, points[:1]])


def _world(pose: Any, points: np.ndarray) -> np.ndarray:
    from push_core.geometry import object_to_world

    return np.asarray(object_to_world(np.asarray(pose, dtype=float), points))


def _overlay(rgb: np.ndarray, mask: np.ndarray | None, outline: np.ndarray | None,
             est: Any, goal: Any, push: np.ndarray | None, k: np.ndarray, t: np.ndarray
             ) -> np.ndarray:
    import cv2

    from sim_bridge.camera import project

    img = rgb.copy()
    if mask is not None and mask.shape == img.shape[:2]:
        tint = np.zeros_like(img)
        tint[:] = MASK_RGB
        img[mask] = (0.55 * img[mask] + 0.45 * tint[mask]).astype(np.uint8)

    def poly(xy: np.ndarray, colour: tuple[int, int, int], thickness: int = 2) -> None:
        uv = project(np.column_stack([xy, np.zeros(len(xy))]), k, t)
        cv2.polylines(img, [np.round(uv).astype(np.int32)], False, colour, thickness,
                      cv2.LINE_AA)

    if outline is not None:
        poly(_world(goal, _ring(outline)), GOAL_RGB)
        poly(_world(est, _ring(outline)), OUTLINE_RGB)
    if push is not None:
        uv = project(np.column_stack([push, np.zeros(3)]), k, t)
        a, c, e = (tuple(int(round(v)) for v in p) for p in uv)
        cv2.arrowedLine(img, a, e, PUSH_RGB, 3, cv2.LINE_AA, tipLength=0.25)
        cv2.circle(img, c, 5, PUSH_RGB, -1, cv2.LINE_AA)
    return img


def _label(img: np.ndarray, text: str) -> np.ndarray:
    """``text`` in white on a dark bar along the top of ``img``."""
    import cv2

    img = np.array(img)  # a writable copy (arrays of PIL images are read-only)
    img[:30] = (0.35 * img[:30]).astype(np.uint8)
    cv2.putText(img, text, (8, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1,
                cv2.LINE_AA)
    return img


def _write_gif(rec: dict[str, Any], recorded: Any, path: Path) -> Path | None:
    """Animated GIF of the frames the pipeline used, with overlays (Pillow)."""
    from PIL import Image as PILImage

    if recorded.camera_matrix is None or recorded.t_world_camera is None:
        print('pushbot demo: no camera_info/extrinsics received; no video written',
              file=sys.stderr)
        return None
    images, labels = [], []
    pushes = rec['pushes']
    for i, stamp in enumerate(rec['frame_stamps']):
        rgb = recorded.frames.get(stamp)
        if rgb is None:  # a frame lost in transport (best effort): skip it
            continue
        push = np.asarray(pushes[i]) if i < len(pushes) else None
        true_err = _true_error_text(rec, i)
        label = (f'step {i}/{rec["steps"]}' + (f'  true error {true_err}' if true_err else '')
                 + ('  next push' if push is not None else f'  {rec["reason"]}'))
        img = _overlay(rgb, recorded.masks.get(stamp), recorded.outline, rec['poses_est'][i],
                       rec['goal'], push, recorded.camera_matrix, recorded.t_world_camera)
        images.append(PILImage.fromarray(img))
        labels.append(label)
    if not images:
        print('pushbot demo: no camera frame received; no video written', file=sys.stderr)
        return None
    images = [PILImage.fromarray(_label(np.asarray(im), text))
              for im, text in zip(_crop(images, rec, recorded), labels, strict=True)]
    durations = [900] * (len(images) - 1) + [2500]
    images[0].save(path, save_all=True, append_images=images[1:], duration=durations, loop=0,
                   disposal=2,
                   optimize=False)
    return path


def _crop(images: list[Any], rec: dict[str, Any], recorded: Any) -> list[Any]:
    """The same window of every frame around the poses, goal and pushes, scaled up to at
    least 480 px wide (the object covers a small part of the 640 x 480 view)."""
    from PIL import Image as PILImage

    from sim_bridge.camera import project

    xy = [np.asarray(p)[:2] for p in rec['poses_true']] + [np.asarray(rec['goal'])[:2]]
    xy += [p for push in rec['pushes'] for p in np.asarray(push)]
    xy = np.asarray(xy)
    lo, hi = xy.min(axis=0) - 0.08, xy.max(axis=0) + 0.08  # object size + margin, metres
    corners = np.array([[lo[0], lo[1], 0], [lo[0], hi[1], 0], [hi[0], lo[1], 0],
                        [hi[0], hi[1], 0]])
    uv = project(corners, recorded.camera_matrix, recorded.t_world_camera)
    width, height = images[0].size
    left, top = (max(0, int(v)) for v in uv.min(axis=0))
    right, bottom = int(min(width, uv[:, 0].max())), int(min(height, uv[:, 1].max()))
    if right - left < 64 or bottom - top < 48:
        return images
    box = (left, top, right, bottom)
    scale = max(1.0, 480.0 / (right - left))
    size = (int((right - left) * scale), int((bottom - top) * scale))
    return [im.crop(box).resize(size, PILImage.Resampling.LANCZOS) for im in images]


def _true_error_text(rec: dict[str, Any], i: int) -> str:
    trial = Trial(**rec['trial'])
    pose0 = np.asarray(rec['poses_true'][0])
    goal = pose0 + trial.goal_offset()
    pose = np.asarray(rec['poses_true'][i])
    dxy = 1e3 * math.hypot(*(goal[:2] - pose[:2]))
    return f'{dxy:.0f} mm'


def _plot(rec: dict[str, Any], recorded: Any, spec: Any, path: Path) -> None:
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    trial = Trial(**rec['trial'])
    true = np.asarray(rec['poses_true'])
    est = np.asarray(rec['poses_est'])
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    lib = _ring(spec.polyline())
    goal_true = true[0] + trial.goal_offset()
    for j, pose in enumerate(true):
        ax.plot(*_world(pose, lib).T, color=plt.cm.viridis(j / max(1, len(true) - 1)), lw=1,
                label='true outline (after each push)' if j == 0 else None)
    ax.plot(*_world(goal_true, lib).T, color='m', lw=2, ls='--', label='goal (true frame)')
    if recorded.outline is not None:
        ax.plot(*_world(est[-1], _ring(recorded.outline)).T, color='orange', lw=1.5,
                label='perceived outline at the final estimate')
    ax.plot(true[:, 0], true[:, 1], 'k.-', label='true position')
    ax.plot(est[:, 0], est[:, 1], 'x--', color='tab:red', label='estimated position')
    for j, push in enumerate(rec['pushes']):
        a, c, e = np.asarray(push)
        ax.annotate('', xy=e, xytext=a, arrowprops={'arrowstyle': '->', 'color': 'tab:blue'})
        ax.text(*a, str(j + 1), fontsize=7, color='tab:blue')
    ax.set_aspect('equal')
    ax.set_xlabel('world x [m]')
    ax.set_ylabel('world y [m]')
    ax.set_title(f'{spec.name}, {trial.task}, {trial.method} k={trial.k}: {rec["reason"]} after '
                 f'{rec["steps"]} pushes\ntrue end error {1e3 * rec["end_error_xy"]:.1f} mm, '
                 f'{math.degrees(rec["end_error_theta"]):.1f} deg (pushes: blue arrows)',
                 fontsize=9)
    ax.legend(loc='best', fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
