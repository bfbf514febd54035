"""The input rules of ``segmentation_node``, ROS-free: which messages make a frame, when a frame
is consistent, and when the first frame after a restart waits for the estimator (re-anchoring).

Everything here takes plain values (stamps as ``(sec, nanosec)`` or float seconds, shapes,
frame ids, arrays), so it is tested without rclpy (``tests/perception/test_inputs.py``); the
node converts messages with :mod:`push_ros`'s codecs and calls these rules.

- **Refusal or outcome.** A problem of the *input* (a message or a frame the node cannot use)
  raises :class:`InputError`; the node counts it as ``refused_<kind>`` (:data:`REFUSAL_KINDS`).
  A problem of the *scene* (an empty mask, an object out of view, too little depth) is a
  :class:`~push_perception.perception_config.PerceptionError` of the measurement and counted
  under its kind.
- **Pairing** (:class:`FrameSync`): colour, depth and camera_info belong together when their
  header stamps are identical; a complete stamp makes every stamp that arrived before it stale
  (dropped; a colour + depth pair among them is reported: ``missing_camera_info``); at most
  ``queue`` incomplete stamps are kept (the oldest is dropped). Bounded memory.
- **Consistency** (:func:`check_frame_inputs`): colour and depth of the same size (depth aligned
  to colour), camera_info of that size, one frame id for colour, depth and the extrinsics'
  child frame. Depth coverage (:func:`check_depth_coverage`) below ``MIN_VALID_DEPTH`` is an
  outcome (``no_depth``): the camera is blind, the message is not wrong.
- **Episodes** (:class:`AnchorWait`): the rules of re-anchoring after a restart and of frames of
  the previous episode, stated in ``segmentation_node``'s module docstring.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Hashable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_core.episode import precedes_episode
from push_perception.perception_config import PerceptionError

__all__ = [
    "COLOR_ENCODINGS",
    "DEPTH_ENCODINGS",
    "MIN_VALID_DEPTH",
    "REFUSAL_KINDS",
    "STREAMS",
    "AnchorWait",
    "FrameSync",
    "InputError",
    "check_depth_coverage",
    "check_frame_ids",
    "check_frame_inputs",
    "check_stamp",
    "rgb_from_color",
]

#: Encodings of the colour and of the depth stream.
COLOR_ENCODINGS = ("rgb8", "bgr8")
DEPTH_ENCODINGS = ("32FC1", "16UC1", "mono16")
#: Smallest fraction of valid depth pixels in a frame (below it the camera is blind).
MIN_VALID_DEPTH = 0.05
#: The streams of one frame, in the order :meth:`FrameSync.add` returns them.
STREAMS = ("rgb", "depth", "info")
#: Kinds of :class:`InputError`: counted as ``refused_<kind>`` by the node.
REFUSAL_KINDS = ("color", "depth", "camera_info", "extrinsics", "stamp", "size_mismatch",
                 "frame_mismatch", "missing_camera_info", "no_extrinsics",
                 "estimator_outline", "estimator_pose", "joint_states", "robot_description",
                 "no_robot_model", "no_joint_state", "stale_joint_state", "robot_pose")
#: Characters of a frame id quoted in a message (an attacker's frame id may be 1 MB).
_QUOTE = 64


class InputError(PerceptionError):
    """A message or frame the node refuses; ``kind`` is one of :data:`REFUSAL_KINDS`."""

    def __init__(self, kind: str, message: str) -> None:
        if kind not in REFUSAL_KINDS:
            raise ValueError(f"unknown refusal kind {kind!r}; one of {REFUSAL_KINDS}")
        super().__init__(kind, message)


def check_stamp(sec: int, nanosec: int) -> tuple[int, int]:
    """The stamp key ``(sec, nanosec)`` of a header stamp, or raise.

    Raises
    ------
    InputError
        kind ``"stamp"``: ``sec`` negative or ``nanosec`` outside [0, 1e9) (not a time in
        [0, 2^31) s).
    """
    if not (0 <= sec and 0 <= nanosec < 1_000_000_000):
        raise InputError("stamp", f"header.stamp ({sec} s, {nanosec} ns) is not a time in "
                         "[0, 2^31) s")
    return int(sec), int(nanosec)


class FrameSync:
    """Colour, depth and camera_info matched by identical stamps (module docstring).

    Parameters
    ----------
    queue : int
        Incomplete stamps kept, >= 1.

    Raises
    ------
    ValueError
        ``queue`` < 1.
    """

    def __init__(self, queue: int) -> None:
        if isinstance(queue, bool) or int(queue) != queue or queue < 1:
            raise ValueError(f"queue must be an integer >= 1, got {queue!r}")
        self.queue = int(queue)
        self._pending: OrderedDict[Hashable, dict[str, Any]] = OrderedDict()

    def add(self, stream: str, key: Hashable, msg: Any
            ) -> tuple[tuple[Any, Any, Any] | None, list[Hashable]]:
        """Add ``msg`` of ``stream`` (one of :data:`STREAMS`) at stamp ``key``.

        Returns
        -------
        frame : tuple or None
            ``(rgb, depth, info)`` once all three of ``key`` are in (they leave the queue).
        missing_info : list
            Keys of dropped colour + depth pairs that had no camera_info, oldest first.

        Raises
        ------
        ValueError
            ``stream`` not one of :data:`STREAMS`.
        """
        if stream not in STREAMS:
            raise ValueError(f"stream must be one of {STREAMS}, got {stream!r}")
        entry = self._pending.setdefault(key, {})
        entry[stream] = msg
        dropped: list[Hashable] = []
        if len(entry) == len(STREAMS):
            for old in list(self._pending):  # everything that arrived before is stale
                if old == key:
                    break
                dropped += self._drop(old)
            del self._pending[key]
            return tuple(entry[s] for s in STREAMS), dropped  # type: ignore[return-value]
        while len(self._pending) > self.queue:
            dropped += self._drop(next(iter(self._pending)))
        return None, dropped

    def _drop(self, key: Hashable) -> list[Hashable]:
        entry = self._pending.pop(key)
        return [key] if "rgb" in entry and "depth" in entry else []

    def snapshot(self) -> tuple[tuple[Hashable, tuple[str, ...]], ...]:
        """The pending stamps (arrival order) with their streams (for tests and status)."""
        return tuple((key, tuple(sorted(entry))) for key, entry in self._pending.items())

    def clear(self) -> None:
        """Forget every pending message."""
        self._pending.clear()


def rgb_from_color(pixels: NDArray[np.uint8], encoding: str) -> NDArray[np.uint8]:
    """(H, W, 3) RGB pixels of a colour image decoded as ``encoding`` (channels as stored).

    Raises
    ------
    InputError
        kind ``"color"``: ``encoding`` not one of :data:`COLOR_ENCODINGS`, or pixels not
        (H, W, 3).
    """
    if encoding not in COLOR_ENCODINGS:
        raise InputError("color", f"colour image encoding {encoding[:_QUOTE]!r}; expected "
                         "rgb8 or bgr8")
    pixels = np.asarray(pixels)
    if pixels.ndim != 3 or pixels.shape[2] != 3:
        raise InputError("color", f"colour pixels of shape {pixels.shape}; expected (H, W, 3)")
    return np.ascontiguousarray(pixels[:, :, ::-1]) if encoding == "bgr8" else pixels


def check_depth_coverage(depth: NDArray[np.floating]) -> float:
    """The fraction of valid (finite) depth pixels, or raise when the camera is blind.

    Parameters
    ----------
    depth : (H, W) float array
        Metres, NaN where there is no depth (:func:`push_ros.images.depth_to_metres`).

    Raises
    ------
    PerceptionError
        kind ``"no_depth"`` (an outcome, not a refusal): fewer than ``MIN_VALID_DEPTH`` of the
        pixels are valid, or the image is empty.
    """
    depth = np.asarray(depth)
    valid = np.count_nonzero(np.isfinite(depth)) / depth.size if depth.size else 0.0
    if valid < MIN_VALID_DEPTH:
        raise PerceptionError("no_depth", f"only {100 * valid:.1f} % of the depth image is "
                              f"valid (NaN, zero or negative elsewhere; need "
                              f"{100 * MIN_VALID_DEPTH:.0f} %)")
    return valid


def check_frame_inputs(color_size: tuple[int, int], depth_size: tuple[int, int],
                       info_size: tuple[int, int]) -> None:
    """The size rules of one frame; sizes are ``(width, height)``, pixels.

    Raises
    ------
    InputError
        kind ``"size_mismatch"``: colour and depth of different sizes (depth must be aligned
        to colour); kind ``"camera_info"``: camera_info for another size than the images.
    """
    if tuple(color_size) != tuple(depth_size):
        raise InputError("size_mismatch", f"colour is {color_size[0]}x{color_size[1]} but "
                         f"depth is {depth_size[0]}x{depth_size[1]}; depth must be aligned "
                         "to colour")
    if tuple(info_size) != tuple(depth_size):
        raise InputError("camera_info", f"camera_info is for {info_size[0]}x{info_size[1]} "
                         f"images, the images are {depth_size[0]}x{depth_size[1]}")


def check_frame_ids(color_frame: str, depth_frame: str, extrinsics_frame: str) -> None:
    """One frame id for colour, depth and the extrinsics' child (``""``: no child to check,
    e.g. tf2 looked the transform up for the colour frame).

    Raises
    ------
    InputError
        kind ``"frame_mismatch"``.
    """
    if color_frame != depth_frame or (extrinsics_frame and color_frame != extrinsics_frame):
        raise InputError("frame_mismatch", f"colour frame {color_frame[:_QUOTE]!r}, depth frame "
                         f"{depth_frame[:_QUOTE]!r} and extrinsics child "
                         f"{extrinsics_frame[:_QUOTE]!r} must be the same frame")


@dataclass(frozen=True)
class AnchorOutline:
    """The estimator's episode outline (``object`` frame, m) and what to re-publish."""

    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    stamp: float
    payload: Any = None


class AnchorWait:
    """Re-anchoring after a restart and the previous-episode rule (``segmentation_node``).

    Until the first ``~/reset`` (:meth:`reset`), a node that starts waits at most ``timeout``
    seconds (from ``now``, a steady clock) for the estimator's outline and an estimate stamped
    no earlier than it; :meth:`decide` says what a frame does meanwhile. After a reset, frames
    stamped at or before the newest frame before it (or the reset's sim time) are of the
    previous episode (:meth:`admit`).

    Parameters
    ----------
    timeout : float
        s, >= 0 (0: never re-anchor).
    now : float
        Start-up time, s of the steady clock.
    """

    def __init__(self, timeout: float, now: float) -> None:
        if not (math.isfinite(timeout) and timeout >= 0.0):
            raise ValueError(f"timeout must be a finite number >= 0 s, got {timeout!r}")
        self.until: float | None = now + timeout if timeout > 0.0 else None
        self.outline: AnchorOutline | None = None
        self.estimate: tuple[float, float] | None = None  # (stamp s, yaw rad)
        self.last_frame = -math.inf  # stamp (s) of the last frame processed
        self.episode_after = -math.inf  # frames with this stamp belong to the last episode

    @property
    def waiting(self) -> bool:
        """Whether a re-anchoring can still happen."""
        return self.until is not None

    def offer_outline(self, points: NDArray[np.float64], normals: NDArray[np.float64],
                      stamp: float, payload: Any = None) -> None:
        """The estimator's latched outline (already checked by its codec)."""
        self.outline = AnchorOutline(points, normals, float(stamp), payload)

    def offer_estimate(self, stamp: float, yaw: float) -> None:
        """The estimator's latched estimate: stamp s, yaw rad in the episode frame.

        Raises
        ------
        ValueError
            ``stamp`` or ``yaw`` not finite.
        """
        if not (math.isfinite(stamp) and math.isfinite(yaw)):
            raise ValueError(f"estimate stamp {stamp!r} s and yaw {yaw!r} rad must be finite")
        self.estimate = (float(stamp), float(yaw))

    def decide(self, has_reference: bool, now: float) -> str:
        """What the next frame does: ``"anchor"`` (match it against :attr:`outline` near
        :attr:`estimate`'s yaw; the wait ends), ``"wait"`` (skip it) or ``"go"`` (process it as
        usual; the wait ended or never was).

        Parameters
        ----------
        has_reference : bool
            The tracker has an episode reference already (the wait is over).
        now : float
            s of the steady clock.
        """
        if self.until is None or has_reference:
            self.until = None
            return "go"
        if (self.outline is not None and self.estimate is not None
                and self.estimate[0] >= self.outline.stamp):
            self.until = None
            return "anchor"
        if now < self.until:
            return "wait"
        self.until = None
        return "go"

    def admit(self, stamp: float, has_reference: bool, now: float) -> str:
        """What the frame stamped ``stamp`` (s) does: ``"previous"`` (taken before the last
        ``~/reset``: skipped), else :meth:`decide`'s answer; a frame that is not
        skipped becomes the newest frame processed."""
        if precedes_episode(stamp, self.episode_after):
            return "previous"
        action = self.decide(has_reference, now)
        if action != "wait":
            self.last_frame = stamp
        return action

    def reset(self, boundary: float = -math.inf) -> None:
        """``~/reset``: an explicit new episode ends the wait; frames stamped at or shortly
        before the newest frame so far or ``boundary`` (s;
        :func:`push_ros.stamps.episode_boundary`, :func:`push_core.episode.precedes_episode`)
        are of the previous episode."""
        self.until = None
        self.episode_after = max(self.last_frame, float(boundary))
