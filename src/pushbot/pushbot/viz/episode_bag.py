"""What the episode renderer reads from a recorded bag: everything but the images into an
:class:`Episode`, then the video frames in stamp order, one pass, bounded memory.

The topics are the graph's defaults (README topic table), absolute; :data:`TOPICS` is what a
bag needs for a video (``pushbot demo`` records them). Messages are deserialised with
``rclpy.serialization`` (real CDR) and decoded with the ``push_ros`` codecs; a message the
codecs refuse is counted in :attr:`Episode.skipped`, not fatal. :mod:`pushbot.viz.render` draws
and writes the video.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pushbot.ros2cli.bag_store import open_reader, read_messages

__all__ = ["AFFORDANCES", "CAMERA_INFO", "DEPTH", "ESTIMATE", "EXTRINSICS", "GOAL", "IMAGE",
           "MASK", "MAX_PENDING", "MONITOR", "OUTLINE", "PUSH", "STATUS", "TOPICS", "TRUTH",
           "Episode", "iter_frames", "latest_before", "load_episode"]

IMAGE = "/camera/color/image_raw"
MONITOR = "/sim/monitor/image_raw"
DEPTH = "/camera/aligned_depth_to_color/image_raw"
MASK = "/perception/mask"
CAMERA_INFO = "/camera/color/camera_info"
EXTRINSICS = "/camera/color/extrinsics"
OUTLINE = "/perception/outline"
ESTIMATE = "/estimator/object_pose"
GOAL = "/goal_pose"
PUSH = "/planner/push"
AFFORDANCES = "/planner/affordances"
STATUS = "/planner/status"
TRUTH = "/sim/object_pose"
#: Every topic a video is drawn from (the depth image is not drawn).
TOPICS = (IMAGE, MASK, CAMERA_INFO, EXTRINSICS, OUTLINE, ESTIMATE, GOAL, PUSH, AFFORDANCES,
          STATUS, TRUTH, MONITOR)

#: At most this many frames that arrived ahead of their turn (stamp order) are held back while
#: the video waits for an earlier one (bounded memory); beyond it the awaited one is skipped.
MAX_PENDING = 64


@dataclass
class Episode:
    """What the bag holds besides the images (time-ordered lists of ``(t, value)``).

    ``t`` is the bag receive time in seconds for the event lists (``estimates``, ``goals``,
    ``pushes``, ``affordances``, ``status``); ``truth`` and ``estimate_stamps`` carry header
    stamps (s) for the plot.
    """

    camera_matrix: np.ndarray | None = None
    t_world_camera: np.ndarray | None = None
    outline: np.ndarray | None = None
    estimates: list[tuple[float, np.ndarray]] = field(default_factory=list)
    estimate_stamps: list[tuple[float, np.ndarray, np.ndarray | None]] = field(
        default_factory=list)
    truth: list[tuple[float, np.ndarray]] = field(default_factory=list)
    goals: list[tuple[float, np.ndarray]] = field(default_factory=list)
    pushes: list[tuple[float, np.ndarray]] = field(default_factory=list)
    affordances: list[tuple[float, tuple[np.ndarray, np.ndarray, np.ndarray]]] = field(
        default_factory=list)
    status: list[tuple[float, str]] = field(default_factory=list)
    frame_times: list[tuple[float, float]] = field(default_factory=list)  # (stamp, first t)
    monitor_times: list[tuple[float, float]] = field(default_factory=list)  # (stamp, t)
    image_size: tuple[int, int] | None = None  # camera (width, height) from camera_info
    skipped: dict[str, int] = field(default_factory=dict)

    def schedule(self) -> list[tuple[float, float, str]]:
        """The video frames ``(stamp, receive time, topic)`` in stamp order: every camera
        frame and every monitor frame whose stamp no camera frame has (camera first)."""
        camera = {stamp for stamp, _ in self.frame_times}
        frames = [(s, t, IMAGE) for s, t in self.frame_times]
        frames += [(s, t, MONITOR) for s, t in self.monitor_times if s not in camera]
        return sorted(frames, key=lambda f: (f[0], f[2] != IMAGE))

    def monitor_rate(self) -> float | None:
        """Monitor frames per second of sim time (median stamp spacing), None without."""
        stamps = np.array(sorted(s for s, _ in self.monitor_times))
        steps = np.diff(stamps)
        steps = steps[steps > 0]
        return float(1.0 / np.median(steps)) if len(steps) else None


def _decode(data: bytes, msgtype: str) -> Any:
    from rclpy.serialization import deserialize_message

    from pushbot.ros2cli.discovery import import_message_class

    return deserialize_message(bytes(data), import_message_class(msgtype))


def _affordance_points(msg: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World xy (N, 2) and RGB (N, 3) of the scored outline, world xy (M, 2) of the
    candidates (``planner/affordances``, push_planner.conversions.affordance_markers)."""
    pts, cols, cand = np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 2))
    for m in msg.markers:
        xy = np.array([[p.x, p.y] for p in m.points], dtype=float).reshape(-1, 2)
        if m.ns == "planner/outline":
            pts = xy
            cols = np.array([[c.r, c.g, c.b] for c in m.colors], dtype=float).reshape(-1, 3)
            if len(cols) != len(pts):
                cols = np.tile([m.color.r, m.color.g, m.color.b], (len(pts), 1))
        elif m.ns == "planner/candidates":
            cand = xy
    return pts, np.clip(255.0 * cols, 0, 255).astype(np.uint8), cand


def load_episode(bag: Path, start: float = -math.inf) -> Episode:
    """Read every topic except the images (and depth) of ``bag``.

    Camera frames, ground truth and estimates with a header stamp before ``start`` (s) are
    left out of ``frame_times``, ``truth`` and ``estimate_stamps`` (e.g. the previous scene's
    frames before the episode's reset).
    """
    from push_ros.images import camera_matrix_from_info
    from push_ros.outline import outline_from_cloud
    from push_ros.paths import push_points_from_path
    from push_ros.poses import matrix_from_transform, pose_with_covariance_from_msg
    from push_ros.poses import xytheta_from_pose as xytheta
    from push_ros.stamps import seconds_from_stamp

    ep = Episode()
    def on_info(m: Any, t: float) -> None:
        ep.camera_matrix = camera_matrix_from_info(m)
        ep.image_size = (int(m.width), int(m.height))

    handlers = {
        CAMERA_INFO: on_info,
        EXTRINSICS: lambda m, t: setattr(ep, "t_world_camera", matrix_from_transform(m)),
        OUTLINE: lambda m, t: setattr(ep, "outline", outline_from_cloud(m)[0]),
        GOAL: lambda m, t: ep.goals.append((t, xytheta(m.pose))),
        PUSH: lambda m, t: ep.pushes.append((t, np.stack(push_points_from_path(m)))),
        AFFORDANCES: lambda m, t: ep.affordances.append((t, _affordance_points(m))),
        STATUS: lambda m, t: ep.status.append((t, m.message)),
        TRUTH: lambda m, t: ep.truth.append((seconds_from_stamp(m.header.stamp),
                                             xytheta(m.pose))),
    }

    def on_estimate(m: Any, t: float) -> None:
        est = pose_with_covariance_from_msg(m)
        ep.estimates.append((t, est.pose))
        if est.stamp >= start:
            ep.estimate_stamps.append((est.stamp, est.pose, est.covariance))

    handlers[ESTIMATE] = on_estimate
    with open_reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic in handlers]
        for conn, t_ns, data in read_messages(reader, conns):
            try:
                handlers[conn.topic](_decode(data, conn.msgtype), t_ns / 1e9)
            except (ValueError, LookupError):  # a message the codecs refuse: count, go on
                ep.skipped[conn.topic] = ep.skipped.get(conn.topic, 0) + 1
        images = [c for c in reader.connections if c.topic in (IMAGE, MONITOR)]
        seen: set[tuple[str, float]] = set()
        for conn, t_ns, data in read_messages(reader, images):
            try:
                stamp = _image_stamp(data, conn.msgtype)
            except ValueError:
                continue
            if (conn.topic, stamp) not in seen and stamp >= start:
                seen.add((conn.topic, stamp))
                times = ep.frame_times if conn.topic == IMAGE else ep.monitor_times
                times.append((stamp, t_ns / 1e9))
    ep.frame_times.sort()
    ep.monitor_times.sort()
    ep.truth = sorted((x for x in ep.truth if x[0] >= start), key=lambda x: x[0])
    ep.estimate_stamps.sort(key=lambda x: x[0])
    return ep


def _image_stamp(data: bytes, msgtype: str) -> float:
    from push_ros.stamps import seconds_from_stamp

    return seconds_from_stamp(_decode(data, msgtype).header.stamp)


def iter_frames(bag: Path, schedule: list[tuple[float, float, str]]
                ) -> Iterator[tuple[float, str, np.ndarray, np.ndarray | None]]:
    """``(stamp, topic, rgb, mask or None)`` of the video frames of ``schedule``
    (:meth:`Episode.schedule`), in its order. One pass over the bag: a frame that arrives
    ahead of its turn is held (at most :data:`MAX_PENDING`; then the awaited frame is
    skipped). Masks (camera frames only) are kept bit-packed until their frame comes."""
    wanted = {(topic, stamp) for stamp, _, topic in schedule}
    pending: dict[tuple[str, float], tuple[np.ndarray, np.ndarray | None]] = {}
    turn = 0
    for key, rgb, mask in _decoded_frames(bag, wanted):
        pending[key] = (rgb, mask)
        while turn < len(schedule):
            stamp, _, topic = schedule[turn]
            if (topic, stamp) in pending:
                rgb, mask = pending.pop((topic, stamp))
                yield stamp, topic, rgb, mask
            elif len(pending) <= MAX_PENDING:
                break
            turn += 1
    for stamp, _, topic in schedule[turn:]:  # the bag has ended: what is still held
        if (topic, stamp) in pending:
            rgb, mask = pending.pop((topic, stamp))
            yield stamp, topic, rgb, mask


def _decoded_frames(bag: Path, wanted: set[tuple[str, float]]
                    ) -> Iterator[tuple[tuple[str, float], np.ndarray, np.ndarray | None]]:
    """``((topic, stamp), rgb, mask or None)`` of the ``wanted`` camera and monitor frames,
    first occurrence of each, in bag order."""
    from push_ros.images import image_to_array
    from push_ros.stamps import seconds_from_stamp

    masks: dict[float, tuple[np.ndarray, tuple[int, int]]] = {}
    with open_reader(bag) as reader:
        mask_conns = [c for c in reader.connections if c.topic == MASK]
        for conn, _, data in read_messages(reader, mask_conns):
            try:
                msg = _decode(data, conn.msgtype)
                mask = image_to_array(msg) > 0
            except ValueError:
                continue
            masks[seconds_from_stamp(msg.header.stamp)] = (np.packbits(mask), mask.shape)
        seen: set[tuple[str, float]] = set()
        image_conns = [c for c in reader.connections if c.topic in (IMAGE, MONITOR)]
        for conn, _, data in read_messages(reader, image_conns):
            try:
                msg = _decode(data, conn.msgtype)
                key = (conn.topic, seconds_from_stamp(msg.header.stamp))
                if key in seen or key not in wanted:
                    continue
                rgb = image_to_array(msg)
            except ValueError:
                continue
            seen.add(key)
            packed = masks.pop(key[1], None) if conn.topic == IMAGE else None
            mask = None
            if packed is not None:
                bits, shape = packed
                mask = np.unpackbits(bits, count=shape[0] * shape[1]).reshape(shape).astype(bool)
            yield key, rgb, mask


def latest_before(events: list[tuple[float, Any]], t: float) -> Any:
    """The value of the last event with time < ``t`` (None before the first)."""
    i = bisect.bisect_left([e[0] for e in events], t)
    return events[i - 1][1] if i > 0 else None
