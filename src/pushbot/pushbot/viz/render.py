"""The episode renderer of ``pushbot replay`` and ``pushbot demo``: a recorded bag -> video.

The video frames are the distinct camera frames (``camera/color/image_raw``, one per header
stamp; a frame delivered twice is shown once; the simulator's still frames of a resting scene
count as frames, as a real camera's would) and, when
the bag holds them, the simulator's *monitor* frames (``sim/monitor/image_raw``: rendered
during each push at a fixed sim-time rate, the pusher visible; sim_bridge_node), merged in
header-stamp order, each shown once. Each is drawn with what the graph had published by the
time the next video frame arrived (bag receive times):

- the perception mask of that frame (``perception/mask``, same stamp; camera frames only),
  tinted green;
- the perceived outline (``perception/outline``, object frame) at the latest estimate
  (``estimator/object_pose``), yellow;
- the affordance colouring of the outline (``planner/affordances``, marker ``planner/outline``:
  green = best to red = worst score) and the sampled contact points (blue dots);
- the chosen push (``planner/push``: approach -> end arrow, contact dot), cyan;
- the goal (``goal_pose``): the perceived outline at the goal pose, magenta;
- a top bar with the time since the first frame and the planner's status, a legend below.

Frame rate: without monitor frames :data:`DEFAULT_FPS` (the simulated camera has no fixed
rate: one new frame per reset and per push), so each is shown 0.5 s. With them,
:data:`MONITOR_SPEEDUP` times the monitor rate (the median stamp spacing of the monitor
frames): the video then runs at ``MONITOR_SPEEDUP`` x sim time during pushes, i.e. it lasts
the pushes' sim duration / ``MONITOR_SPEEDUP`` (plus one frame per camera frame; sim time
stands still between pushes). A monitor frame has the camera's pose and intrinsics scaled to
its size (the bridge's contract), so it is resized to the camera's size and drawn like a
camera frame.

Frames are cropped to the region of the poses, goal and pushes and scaled to at least 480 px
wide. Reading the bag (topics, decoding, the frames in stamp order): :mod:`pushbot.viz.episode_bag`.

Outputs: an H.264 MP4 (imageio with the ffmpeg binary of imageio-ffmpeg), optionally a GIF
(Pillow; at most :data:`GIF_MAX_FRAMES` frames, 360 px wide) and a PNG plot of the estimate
against ground truth (``sim/object_pose``) over time.
"""

from __future__ import annotations

import itertools
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pushbot.ros2cli.bag_store import BagError
from pushbot.viz.episode_bag import (
    CAMERA_INFO,
    ESTIMATE,
    EXTRINSICS,
    IMAGE,
    MONITOR,
    TRUTH,
    Episode,
    iter_frames,
    latest_before,
    load_episode,
)

__all__ = ["CANDIDATE_RGB", "DEFAULT_FPS", "GIF_MAX_FRAMES", "GOAL_RGB", "MASK_RGB",
           "MONITOR_SPEEDUP", "OUTLINE_RGB", "PUSH_RGB", "BagError", "Episode", "RenderError",
           "Rendered", "closed_ring", "in_world", "label", "overlay", "plot_estimate",
           "render_bag", "with_legend"]

#: Colours (RGB) of the overlays, also used by the legend.
MASK_RGB = (40, 200, 80)
OUTLINE_RGB = (255, 220, 0)
GOAL_RGB = (255, 40, 200)
PUSH_RGB = (0, 200, 255)
CANDIDATE_RGB = (25, 75, 255)
#: Frames per second of the video without monitor frames: one video frame per camera frame,
#: and the simulated camera renders one frame per reset and per push and streams still frames
#: at its idle rate (2 Hz of sim time) in between, so each is shown 0.5 s.
DEFAULT_FPS = 2.0
#: With monitor frames the video runs at this multiple of sim time (fps = this x their rate).
MONITOR_SPEEDUP = 2.0
#: The GIF's limits: frames, width (px), palette colours.
GIF_MAX_FRAMES, GIF_WIDTH, GIF_COLOURS = 60, 360, 96
#: Extra space (m) around the poses, goal and pushes in the crop (an object's size).
CROP_MARGIN = 0.08


class RenderError(ValueError):
    """The bag lacks what a video needs; the message says what."""


# --------------------------------------------------------------------------------------------
# Drawing
# --------------------------------------------------------------------------------------------
def closed_ring(points: np.ndarray) -> np.ndarray:
    """The outline ``points`` (N, 2) closed: the first point repeated at the end."""
    return np.vstack([points, points[:1]])


def in_world(pose: Any, points: np.ndarray) -> np.ndarray:
    """Object-frame ``points`` (N, 2) placed at ``pose`` (x, y, theta) in ``world``, m."""
    from push_core.geometry import object_to_world

    return np.asarray(object_to_world(np.asarray(pose, dtype=float), points))


def overlay(rgb: np.ndarray, k: np.ndarray, t_world_camera: np.ndarray, *,
            mask: np.ndarray | None = None, outline: np.ndarray | None = None,
            estimate: Any = None, goal: Any = None, push: np.ndarray | None = None,
            affordances: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
            ) -> np.ndarray:
    """The camera image with the episode drawn on it (module docstring).

    Parameters
    ----------
    rgb : ndarray, shape (H, W, 3), uint8
    k : ndarray, shape (3, 3)
        Camera intrinsics.
    t_world_camera : ndarray, shape (4, 4)
        Pose of the optical frame in ``world``.
    mask : ndarray, shape (H, W), bool, optional
    outline : ndarray, shape (N, 2), optional
        Perceived outline, object frame, m.
    estimate, goal : array_like, shape (3,), optional
        ``(x, y, theta)`` in ``world`` (m, rad).
    push : ndarray, shape (3, 2), optional
        Approach, contact and end point in ``world``.
    affordances : tuple, optional
        World xy (N, 2) and RGB (N, 3) of the scored outline, world xy (M, 2) of candidates.
    """
    import cv2

    from sim_bridge.camera import project

    img = np.array(rgb, dtype=np.uint8, copy=True)

    def pixels(xy: np.ndarray) -> np.ndarray:
        uv = project(np.column_stack([xy, np.zeros(len(xy))]), k, t_world_camera)
        return np.round(uv).astype(np.int32)

    if mask is not None and mask.shape == img.shape[:2]:
        img[mask] = (0.55 * img[mask] + 0.45 * np.asarray(MASK_RGB)).astype(np.uint8)
    if affordances is not None:
        pts, cols, cand = affordances
        for (u, v), c in zip(pixels(pts), cols, strict=True):
            cv2.circle(img, (int(u), int(v)), 3, tuple(int(x) for x in c), -1, cv2.LINE_AA)
    if outline is not None and goal is not None:
        cv2.polylines(img, [pixels(in_world(goal, closed_ring(outline)))], False, GOAL_RGB,
                      2, cv2.LINE_AA)
    if outline is not None and estimate is not None:  # thin: the affordance band shows
        cv2.polylines(img, [pixels(in_world(estimate, closed_ring(outline)))], False,
                      OUTLINE_RGB, 1 if affordances is not None else 2, cv2.LINE_AA)
    if affordances is not None:
        for u, v in pixels(affordances[2]):
            cv2.circle(img, (int(u), int(v)), 4, CANDIDATE_RGB, -1, cv2.LINE_AA)
    if push is not None:
        a, c, e = (tuple(int(v) for v in p) for p in pixels(np.asarray(push)))
        cv2.arrowedLine(img, a, e, PUSH_RGB, 3, cv2.LINE_AA, tipLength=0.25)
        cv2.circle(img, c, 5, PUSH_RGB, -1, cv2.LINE_AA)
    return img


def label(img: np.ndarray, text: str) -> np.ndarray:
    """``text`` in white on a dark bar along the top of ``img`` (a copy)."""
    import cv2

    img = np.array(img)
    img[:30] = (0.35 * img[:30]).astype(np.uint8)
    cv2.putText(img, text[:90], (8, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1,
                cv2.LINE_AA)
    return img


LEGEND = (
    (MASK_RGB, "mask"),
    (OUTLINE_RGB, "outline at estimate"),
    (GOAL_RGB, "goal"),
    (PUSH_RGB, "push"),
    (CANDIDATE_RGB, "contacts"),
    (None, "affordance best..worst"),
)


def with_legend(img: np.ndarray) -> np.ndarray:
    """``img`` with a legend of the overlay colours appended below (as many rows as the
    width needs)."""
    import cv2

    font, size, row_h = cv2.FONT_HERSHEY_SIMPLEX, 0.4, 22
    items, x, row = [], 8, 0
    for colour, text in LEGEND:
        width = 26 + cv2.getTextSize(text, font, size, 1)[0][0]
        if x + width > img.shape[1] and x > 8:
            x, row = 8, row + 1
        items.append((colour, text, x, row))
        x += width
    bar = np.full((row_h * (row + 1) + 4, img.shape[1], 3), 30, dtype=np.uint8)
    for colour, text, x, row in items:
        y = 6 + row * row_h
        if colour is None:  # the affordance ramp: green (best) to red (worst)
            for i in range(14):
                f = i / 13
                cv2.rectangle(bar, (x + i, y), (x + i, y + 12),
                              (int(255 * f), int(255 * (1 - f)), 0), -1)
        else:
            cv2.rectangle(bar, (x, y), (x + 13, y + 12), colour, -1)
        cv2.putText(bar, text, (x + 18, y + 11), font, size, (235, 235, 235), 1, cv2.LINE_AA)
    return np.vstack([img, bar])


def crop_box(ep: Episode, size: tuple[int, int]) -> tuple[int, int, int, int] | None:
    """Pixel box ``(left, top, right, bottom)`` around the poses, goals and pushes (None:
    keep the whole frame)."""
    from sim_bridge.camera import project

    xy = [p[:2] for _, p in ep.truth] or [p[:2] for _, p in ep.estimates]
    xy += [g[:2] for _, g in ep.goals] + [q for _, push in ep.pushes for q in push]
    if not xy or ep.camera_matrix is None or ep.t_world_camera is None:
        return None
    xy = np.asarray(xy, dtype=float)
    lo, hi = xy.min(axis=0) - CROP_MARGIN, xy.max(axis=0) + CROP_MARGIN
    corners = np.array([[lo[0], lo[1], 0], [lo[0], hi[1], 0], [hi[0], lo[1], 0],
                        [hi[0], hi[1], 0]])
    uv = project(corners, ep.camera_matrix, ep.t_world_camera)
    width, height = size
    left, top = (max(0, int(v)) for v in uv.min(axis=0))
    right, bottom = int(min(width, uv[:, 0].max())), int(min(height, uv[:, 1].max()))
    if right - left < 64 or bottom - top < 48:
        return None
    return left, top, right, bottom


def _fit(img: np.ndarray, box: tuple[int, int, int, int] | None) -> np.ndarray:
    """Crop to ``box``, scale to at least 480 px wide, pad to a multiple of 16 (H.264)."""
    import cv2

    if box is not None:
        left, top, right, bottom = box
        img = img[top:bottom, left:right]
    scale = max(1.0, 480.0 / img.shape[1])
    if scale > 1.0:
        img = cv2.resize(img, (int(img.shape[1] * scale), int(img.shape[0] * scale)),
                         interpolation=cv2.INTER_LANCZOS4)
    return img


def _pad16(img: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    return np.pad(img, ((0, -h % 16), (0, -w % 16), (0, 0)), constant_values=30)


@dataclass
class Rendered:
    """What :func:`render_bag` wrote: ``frames`` video frames (``monitor_frames`` of them from
    the monitor), at ``fps``."""

    frames: int
    video: Path
    gif: Path | None
    plot: Path | None
    monitor_frames: int = 0
    fps: float = DEFAULT_FPS


def render_bag(bag: Path, video: Path, *, gif: Path | None = None, plot: Path | None = None,
               fps: float | None = None, start: float = -math.inf) -> Rendered:
    """Render the episode in ``bag`` to ``video`` (MP4), optionally ``gif`` and ``plot``.

    Camera and monitor frames stamped before ``start`` (s; default: none) are left out.
    ``fps`` None: the module docstring's rate (:data:`DEFAULT_FPS`, or
    :data:`MONITOR_SPEEDUP` x the monitor rate when the bag has monitor frames).

    Raises
    ------
    RenderError
        No camera frame, no camera_info or no extrinsics in the bag.
    BagError
        The bag cannot be read.
    """
    imageio = _imageio()
    ep = load_episode(bag, start)
    if not ep.frame_times:
        raise RenderError(f"{bag} has no {IMAGE} messages (at or after the start): nothing "
                          "to render")
    if ep.camera_matrix is None or ep.t_world_camera is None:
        raise RenderError(f"{bag} lacks {CAMERA_INFO} or {EXTRINSICS}: cannot draw the "
                          "overlays (record them too)")
    schedule = ep.schedule()
    rate = ep.monitor_rate()
    if fps is None:
        fps = DEFAULT_FPS if rate is None else min(120.0, round(MONITOR_SPEEDUP * rate, 3))
    # What the graph had published before the next video frame came in is drawn on a frame.
    until = {(f[0], f[2]): max(f[1], nxt[1]) for f, nxt in itertools.pairwise(schedule)}
    n_frames = len(schedule)
    t0 = schedule[0][0]
    size = ep.image_size
    video.parent.mkdir(parents=True, exist_ok=True)
    gif_frames: list[np.ndarray] = []
    stride = max(1, math.ceil(n_frames / GIF_MAX_FRAMES))
    box: tuple[int, int, int, int] | None = None
    count = monitored = 0
    writer = imageio.get_writer(video, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                quality=7, macro_block_size=16, pixelformat="yuv420p")
    try:
        for i, (stamp, topic, rgb, mask) in enumerate(iter_frames(bag, schedule)):
            if topic == MONITOR:  # the camera's pose, intrinsics scaled: back to its size
                rgb = _resize(rgb, size)
                monitored += 1
            elif size is None or (rgb.shape[1], rgb.shape[0]) != size:
                size = (rgb.shape[1], rgb.shape[0])
            if box is None and size is not None:
                box = crop_box(ep, size)
            t_end = until.get((stamp, topic), math.inf)
            img = overlay(rgb, ep.camera_matrix, ep.t_world_camera, mask=mask,
                          outline=ep.outline, estimate=latest_before(ep.estimates, t_end),
                          goal=latest_before(ep.goals, t_end), push=latest_before(ep.pushes, t_end),
                          affordances=latest_before(ep.affordances, t_end))
            status = latest_before(ep.status, t_end) or ""
            frame = _pad16(with_legend(label(_fit(img, box),
                                             f"t = {stamp - t0:.1f} s  {status}")))
            writer.append_data(frame)
            count += 1
            if gif is not None and (i % stride == 0 or i == n_frames - 1):
                gif_frames.append(frame)
    finally:
        writer.close()
    if gif is not None:
        _write_gif(gif_frames, gif, 1000.0 * stride / fps)
    if plot is not None:
        plot = plot_estimate(ep, plot)
    return Rendered(count, video, gif, plot, monitored, fps)


def _resize(rgb: np.ndarray, size: tuple[int, int] | None) -> np.ndarray:
    """``rgb`` scaled to ``size`` = (width, height) (unchanged when None or equal)."""
    import cv2

    if size is None or (rgb.shape[1], rgb.shape[0]) == size:
        return rgb
    return cv2.resize(rgb, size, interpolation=cv2.INTER_LINEAR)


def _imageio() -> Any:
    """``imageio`` with its ffmpeg plugin (pip-only dependencies, hence checked here)."""
    try:
        import imageio.v2 as imageio
        import imageio_ffmpeg  # noqa: F401  (the ffmpeg binary)
    except ImportError as exc:
        raise RenderError(f"imageio / imageio-ffmpeg are not installed ({exc}): run make venv"
                          ) from exc
    return imageio


def _write_gif(frames: list[np.ndarray], path: Path, frame_ms: float) -> None:
    """The GIF: frames scaled to :data:`GIF_WIDTH`, one palette of :data:`GIF_COLOURS` for all
    (from a few frames spread over the episode), each frame stored as its change to the
    previous one (``disposal=1``): consecutive monitor frames differ only where things move."""
    from PIL import Image

    images = []
    for f in frames:
        im = Image.fromarray(f)
        scale = GIF_WIDTH / im.width
        images.append(im.resize((GIF_WIDTH, max(1, int(im.height * scale))),
                                Image.Resampling.LANCZOS))
    picks = np.unique(np.linspace(0, len(images) - 1, min(6, len(images))).round().astype(int))
    sample = Image.fromarray(np.vstack([np.asarray(images[i]) for i in picks]))
    palette = sample.quantize(colors=GIF_COLOURS, method=Image.Quantize.MEDIANCUT,
                              dither=Image.Dither.NONE)
    images = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    durations = [int(frame_ms)] * (len(images) - 1) + [2500]
    images[0].save(path, save_all=True, append_images=images[1:], duration=durations, loop=0,
                   disposal=1)


def plot_estimate(ep: Episode, path: Path) -> Path | None:
    """PNG of the estimated pose (with 2-sigma band) against ground truth over time."""
    if not ep.estimate_stamps and not ep.truth:
        print(f"pushbot replay: no {ESTIMATE} nor {TRUTH} in the bag; no plot written",
              file=sys.stderr)
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    starts = [s[0] for s in ep.estimate_stamps[:1]] + [s[0] for s in ep.truth[:1]]
    t0 = min(starts)
    fig, axes = plt.subplots(3, 1, figsize=(7, 6.5), sharex=True)
    scale = (1e3, 1e3, math.degrees(1.0))
    names = ("x [mm]", "y [mm]", "theta [deg]")
    if ep.truth:
        tt = np.array([s for s, _ in ep.truth]) - t0
        true = np.array([p for _, p in ep.truth])
        true[:, 2] = np.unwrap(true[:, 2])
    if ep.estimate_stamps:
        te = np.array([s for s, _, _ in ep.estimate_stamps]) - t0
        est = np.array([p for _, p, _ in ep.estimate_stamps])
        est[:, 2] = np.unwrap(est[:, 2])
        sig = np.array([np.sqrt(np.clip(np.diag(c), 0, None)) if c is not None
                        else np.full(3, np.nan) for _, _, c in ep.estimate_stamps])
    for j, ax in enumerate(axes):
        if ep.truth:
            ax.plot(tt, scale[j] * true[:, j], "o-", color="k", lw=1.2, ms=3,
                    label="ground truth (sim/object_pose)")
        if ep.estimate_stamps:
            ax.plot(te, scale[j] * est[:, j], ".-", color="tab:red", lw=1, ms=3,
                    label="estimate (estimator/object_pose)")
            ax.fill_between(te, scale[j] * (est[:, j] - 2 * sig[:, j]),
                            scale[j] * (est[:, j] + 2 * sig[:, j]), color="tab:red",
                            alpha=0.15, label="estimate +- 2 sigma")
        # The goal's yaw is relative to the episode's first frame
        # (docs/design/evaluation.md#goal-frame), so only its position is drawn.
        for g in {tuple(g) for _, g in ep.goals} if j < 2 else ():
            ax.axhline(scale[j] * g[j], color="m", ls="--", lw=1,
                       label="goal" if j == 0 else None)
        ax.set_ylabel(names[j])
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=7)
    axes[-1].set_xlabel("time [s] (header stamps)")
    axes[0].set_title("object pose: estimate vs ground truth", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
