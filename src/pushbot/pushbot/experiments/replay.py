"""``pushbot replay DIR [-o OUT] [--gif]``: a recorded episode bag -> video and plot.

Renders every distinct camera frame of the bag (``pushbot bag record`` or ``ros2 bag record
-s mcap`` of the graph's topics; ``pushbot demo`` records one under ``out/demo/episode_bag``),
merged in time order with the simulator's monitor frames of the pushes when the bag has
``sim/monitor/image_raw``, with the perception mask, the perceived outline at the estimate,
the affordance colouring, the chosen push and the goal, and a legend (:mod:`pushbot.viz.render`),
to ``OUT`` (default ``DIR.mp4`` next to the bag folder), with ``--gif`` also ``OUT`` with
suffix ``.gif``, and always a plot of the estimate against ground truth over time (``OUT`` stem +
``_estimate.png``).

Exit codes: 0 written, 1 the bag lacks what the video needs (camera images, camera_info,
extrinsics), 2 bad input (no bag folder, unreadable bag, bad options).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from pushbot.ros2cli.bag_store import BagError
from pushbot.viz.render import DEFAULT_FPS, MONITOR_SPEEDUP, RenderError, render_bag


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot replay``."""
    parser.add_argument("bag", type=Path, metavar="DIR", help="rosbag2 folder (MCAP)")
    parser.add_argument("-o", "--output", type=Path, default=None, metavar="OUT",
                        help="MP4 to write (default: DIR.mp4 next to the bag folder)")
    parser.add_argument("--gif", action="store_true",
                        help="also write a GIF (OUT with suffix .gif; at most 60 frames)")
    parser.add_argument("--fps", type=float, default=None,
                        help=f"video frame rate (default: {DEFAULT_FPS:g}, one camera frame per "
                        f"0.5 s; with monitor frames {MONITOR_SPEEDUP:g} x their rate, i.e. "
                        f"{MONITOR_SPEEDUP:g} x sim time)")


def outputs(bag: Path, output: Path | None) -> tuple[Path, Path, Path]:
    """The MP4, GIF and plot paths of ``pushbot replay`` for ``bag`` and ``-o``."""
    video = output if output is not None else bag.parent / f"{bag.resolve().name}.mp4"
    return (video, video.with_suffix(".gif"),
            video.with_name(f"{video.stem}_estimate.png"))


def run_replay(args: argparse.Namespace) -> int:
    """Handler of ``pushbot replay``."""
    if args.fps is not None and not (math.isfinite(args.fps) and 0 < args.fps <= 120):
        print(f"pushbot replay: --fps must be in (0, 120], got {args.fps}", file=sys.stderr)
        return 2
    video, gif, plot = outputs(args.bag, args.output)
    if video.suffix.lower() != ".mp4":
        print(f"pushbot replay: the output must be an .mp4 file, got {video}", file=sys.stderr)
        return 2
    try:
        done = render_bag(args.bag, video, gif=gif if args.gif else None, plot=plot,
                          fps=args.fps)
    except BagError as exc:
        print(f"pushbot replay: {exc}", file=sys.stderr)
        return 2
    except RenderError as exc:
        print(f"pushbot replay: {exc}", file=sys.stderr)
        return 1
    written = [str(p) for p in (done.video, done.gif, done.plot) if p is not None]
    print(f'rendered {done.frames} frames: wrote {", ".join(written)}')
    return 0
