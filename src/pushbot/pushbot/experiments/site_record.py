"""``pushbot data record``: a site's training frames from live camera topics, labelled by the
depth segmentation and checked across frames.

It subscribes to the camera of the running graph (or of a real driver) as segmentation_node
does: ``camera/color/image_raw``, ``camera/aligned_depth_to_color/image_raw`` and
``camera/color/camera_info`` matched by identical stamps
(:class:`push_perception.inputs.FrameSync`), colour encodings, depth units and distortion by
the node's codecs (:class:`push_perception.camera_input.FrameRectifier`), the extrinsics from
tf2 or the latched ``camera/color/extrinsics`` (:class:`push_ros.extrinsics.CameraExtrinsics`).
Each frame goes to :class:`push_perception.site_labels.SiteLabeller`; kept frames are written
per scene in the site data format (docs/design/site-adaptation.md#the-site-data-format), the
format ``pushbot train segmentation`` reads. Dropped frames are counted by reason, printed and
written to ``meta.json``.

Scenes: with ``--sim`` the graph's simulator is asked for each new scene (its parameters
``initial_pose.*`` and ``seed`` set, then ``/sim_bridge_node/reset``; a random pose in the
workspace from ``--seed``); without it the scene is whatever the camera sees, and a person moves
the object between scenes (the labeller notices the change).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from push_perception.site_labels import DROP_REASONS, LabelledFrame, LabelRule, SiteLabeller

__all__ = ["FORMAT_VERSION", "SiteWriter", "add_arguments", "record", "run"]

#: Version of the site data format written into meta.json.
FORMAT_VERSION = 1
#: Simulator node asked for new scenes with ``--sim``.
SIM_NODE = "sim_bridge_node"


class SiteWriter:
    """Writes labelled frames as one shard per scene into ``out`` (the site data format).

    Parameters
    ----------
    out : pathlib.Path
        Output directory (created; an existing site data set there is refused unless
        ``overwrite``).
    rule : LabelRule
    source : dict
        What was recorded (topics, options), stored in ``meta.json``.
    overwrite : bool
    """

    def __init__(self, out: Path, rule: LabelRule, source: dict[str, Any],
                 overwrite: bool = False) -> None:
        self.out = Path(out)
        if any(self.out.glob("shard_*.npz")) and not overwrite:
            raise ValueError(f"{self.out} already holds shards; use another directory or "
                             "--overwrite")
        self.out.mkdir(parents=True, exist_ok=True)
        for old in self.out.glob("shard_*.npz"):
            old.unlink()
        self.rule, self.source = rule, source
        self.shards = 0
        self.frames = 0
        self._scene: list[LabelledFrame] = []

    @property
    def pending(self) -> int:
        """Frames of the current scene not yet written."""
        return len(self._scene)

    def add(self, frames: list[LabelledFrame]) -> None:
        """Add kept frames; a frame of a new scene writes the previous scene's shard."""
        for f in frames:
            if self._scene and f.scene != self._scene[-1].scene:
                self.flush()
            self._scene.append(f)

    def flush(self) -> None:
        """Write the current scene's frames as the next shard."""
        from pushbot.experiments.perception_data import encode_depth, shard_path

        if not self._scene:
            return
        s = self._scene
        arrays = {"rgb": np.stack([f.rgb for f in s]),
                  "depth": np.stack([encode_depth(f.depth) for f in s]),
                  "mask": np.stack([f.mask for f in s]),
                  "camera_matrix": np.stack([f.camera_matrix for f in s]),
                  "T_world_camera": np.stack([f.T_world_camera for f in s]),
                  "stamp": np.array([f.stamp for f in s]),
                  "scene": np.array([f.scene for f in s], dtype=np.int64)}
        path = shard_path(self.out, self.shards)
        partial = path.with_suffix(".tmp.npz")
        np.savez_compressed(partial, **arrays)
        partial.replace(path)
        self.shards += 1
        self.frames += len(s)
        self._scene = []

    def close(self, labeller: SiteLabeller) -> dict[str, Any]:
        """Write the last shard and ``meta.json``; returns the meta data."""
        self.flush()
        meta = {"format_version": FORMAT_VERSION, "kind": "site",
                "rule": dataclasses.asdict(self.rule), "frames": self.frames,
                "shards": self.shards, "scenes_seen": labeller.scene + 1,
                "dropped": dict(labeller.dropped), "source": self.source}
        (self.out / "meta.json").write_text(json.dumps(meta, indent=2) + "\n")
        return meta


def _frame_arrays(node: Any, rgb_msg: Any, depth_msg: Any, info: Any
                  ) -> tuple[Any, Any, Any, Any] | None:
    """(rgb, depth, K, T_world_camera) of one message triple by segmentation_node's codecs, or
    None (no extrinsics yet); ``ValueError`` for a message the node would refuse."""
    from push_perception.camera_input import CameraModel
    from push_perception.inputs import check_frame_inputs, rgb_from_color
    from push_ros.images import (
        camera_matrix_from_info,
        depth_to_metres,
        distortion_from_info,
        image_to_array,
    )

    rgb = rgb_from_color(image_to_array(rgb_msg), rgb_msg.encoding)
    depth = depth_to_metres(depth_msg)
    model = CameraModel(camera_matrix_from_info(info), distortion_from_info(info)[1],
                        (int(info.width), int(info.height)))
    check_frame_inputs(rgb.shape[1::-1], depth.shape[::-1], (info.width, info.height))
    rgb, depth = node.rectifier.color(rgb, model), node.rectifier.depth(depth, model)
    t, child = node.extrinsics.lookup(rgb_msg.header.frame_id)
    if t is None or child != rgb_msg.header.frame_id:
        return None
    return rgb, depth, model.k, t


def record(out: Path, frames: int, scenes: int, rule: LabelRule, sim: bool, seed: int,
           timeout: float, overwrite: bool = False,
           objects: tuple[str, ...] = ()) -> dict[str, Any]:
    """Record ``frames`` labelled frames over ``scenes`` scenes (module docstring).

    Returns
    -------
    dict
        The ``meta.json`` contents (frames, shards, dropped counts, ...).

    Raises
    ------
    TimeoutError
        No camera frame, or no progress, within ``timeout`` s of wall time (what was kept is
        written first).
    """
    import rclpy
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import CameraInfo, Image
    from std_srvs.srv import Trigger

    from push_perception.camera_input import FrameRectifier
    from push_perception.inputs import STREAMS, FrameSync, check_stamp
    from push_ros.extrinsics import CameraExtrinsics
    from push_ros.qos import SENSOR_QOS

    topics = {"rgb": "camera/color/image_raw",
              "depth": "camera/aligned_depth_to_color/image_raw",
              "info": "camera/color/camera_info"}
    labeller = SiteLabeller(rule)
    writer = SiteWriter(out, rule, {"topics": topics, "sim": sim, "seed": seed,
                                    "frames": frames, "scenes": scenes,
                                    "objects": list(objects)}, overwrite)
    refused: dict[str, int] = {}
    rclpy.init()
    node = rclpy.create_node("pushbot_data_record")
    node.rectifier = FrameRectifier()
    node.extrinsics = CameraExtrinsics(node, lambda exc: None)
    sync = FrameSync(8, STREAMS)

    def on_message(stream: str, msg: Any) -> None:
        try:
            triple, _ = sync.add(stream, check_stamp(msg.header.stamp.sec,
                                                     msg.header.stamp.nanosec), msg)
            if triple is None:
                return
            arrays = _frame_arrays(node, *triple)
        except ValueError as exc:
            refused[type(exc).__name__] = refused.get(type(exc).__name__, 0) + 1
            node.get_logger().warning(f"frame refused: {exc}", throttle_duration_sec=2.0)
            return
        if arrays is None:
            refused["no_extrinsics"] = refused.get("no_extrinsics", 0) + 1
            return
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        writer.add(labeller.add(*arrays, stamp))

    for stream, topic in topics.items():
        node.create_subscription(CameraInfo if stream == "info" else Image, topic,
                                 lambda m, s=stream: on_message(s, m), SENSOR_QOS)
    set_params = node.create_client(SetParameters, f"/{SIM_NODE}/set_parameters")
    reset = node.create_client(Trigger, f"/{SIM_NODE}/reset")
    rng = np.random.default_rng(seed)
    per_scene = math.ceil(frames / scenes)

    def call(client: Any, request: Any, what: str) -> Any:
        if not client.wait_for_service(timeout_sec=timeout):
            raise TimeoutError(f"{what}: no such service within {timeout:.0f} s (is the "
                               "graph's simulator running?)")
        future = client.call_async(request)
        rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
        if future.result() is None:
            raise TimeoutError(f"{what}: no answer within {timeout:.0f} s")
        return future.result()

    def next_scene(scene: int) -> None:
        pose: dict[str, Any] = {"object": objects[scene % len(objects)]} if objects else {}
        pose |= {"initial_pose.x": float(rng.uniform(-0.15, 0.15)),
                "initial_pose.y": float(rng.uniform(-0.2, 0.2)),
                "initial_pose.theta": float(rng.uniform(-math.pi, math.pi)),
                "seed": int(rng.integers(2**31 - 1))}
        msgs = [Parameter(k, value=v).to_parameter_msg() for k, v in pose.items()]
        result = call(set_params, SetParameters.Request(parameters=msgs),
                      f"/{SIM_NODE}/set_parameters")
        bad = [r.reason for r in result.results if not r.successful]
        if bad:
            raise ValueError(f"{SIM_NODE} refused the scene parameters: {bad[0]}")
        answer = call(reset, Trigger.Request(), f"/{SIM_NODE}/reset")
        if not answer.success:
            raise ValueError(f"/{SIM_NODE}/reset refused: {answer.message}")

    try:
        for scene in range(scenes):
            if sim and (scene > 0 or objects):
                next_scene(scene)
            goal = min(frames, (scene + 1) * per_scene)
            last, progress = time.monotonic(), writer.frames + writer.pending
            while writer.frames + writer.pending < goal:
                rclpy.spin_once(node, timeout_sec=0.1)
                now = writer.frames + writer.pending
                if now != progress:
                    last, progress = time.monotonic(), now
                elif time.monotonic() - last > timeout:
                    raise TimeoutError(f"no labelled frame for {timeout:.0f} s ({writer.frames} "
                                       f"written, dropped {labeller.dropped}, refused "
                                       f"{refused}); is the camera publishing?")
    finally:
        labeller.finish()
        meta = writer.close(labeller)
        meta["refused"] = refused
        (Path(out) / "meta.json").write_text(json.dumps(meta, indent=2) + "\n")
        node.destroy_node()
        rclpy.try_shutdown()
    return meta


# --------------------------------------------------------------------------------------------
# Command line: pushbot data record
# --------------------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot data record``."""
    d = LabelRule()
    parser.add_argument("--frames", type=int, required=True, help="labelled frames to keep")
    parser.add_argument("--scenes", type=int, default=10,
                        help="scenes to spread them over (default 10; one shard each)")
    parser.add_argument("--out", type=Path, required=True,
                        help="output directory (e.g. out/site_data; keep it out of git)")
    parser.add_argument("--sim", action="store_true",
                        help="ask the graph's simulator for each new scene (a random object "
                             "pose and seed, then /sim_bridge_node/reset)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the --sim scenes")
    parser.add_argument("--objects", nargs="+", default=[],
                        help="with --sim: the objects of the scenes, in turn (default: the "
                             "simulator's object)")
    parser.add_argument("--window", type=int, default=d.window,
                        help=f"frames of a resting scene per label (default {d.window})")
    parser.add_argument("--min-iou", type=float, default=d.min_iou,
                        help=f"mask agreement of consecutive frames (default {d.min_iou})")
    parser.add_argument("--max-plane-rms", type=float, default=d.max_plane_rms,
                        help=f"largest table-plane residual, m (default {d.max_plane_rms})")
    parser.add_argument("--timeout", type=float, default=30.0,
                        help="seconds without a labelled frame before giving up (default 30)")
    parser.add_argument("--overwrite", action="store_true", help="replace shards in --out")


def run(args: argparse.Namespace) -> int:
    """Run ``pushbot data record``; returns the exit code.

    Raises
    ------
    ValueError
        An option out of range, or ``--out`` already holding shards (before anything runs).
    """
    if args.frames < 2 or args.scenes < 1 or args.scenes > args.frames:
        raise ValueError(f"--frames {args.frames} --scenes {args.scenes}: need frames >= 2 "
                         "and 1 <= scenes <= frames")
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        raise ValueError(f"--timeout {args.timeout}: expected a positive number of seconds")
    rule = LabelRule(min_iou=args.min_iou, max_plane_rms=args.max_plane_rms, window=args.window)
    if args.objects and not args.sim:
        raise ValueError("--objects needs --sim (a real scene's objects are placed by hand)")
    meta = record(args.out, args.frames, args.scenes, rule, args.sim, args.seed, args.timeout,
                  args.overwrite, tuple(args.objects))
    dropped = ", ".join(f"{k} {meta['dropped'].get(k, 0)}" for k in DROP_REASONS)
    print(f"wrote {meta['frames']} labelled frames in {meta['shards']} shard(s) to {args.out}; "
          f"dropped: {dropped}; refused messages: {meta['refused'] or 'none'}")
    return 0
