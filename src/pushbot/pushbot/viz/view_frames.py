"""Times and frames of ``pushbot view`` (ROS-free; :mod:`pushbot.viz.view` is the wiring).

- :func:`header_stamp_ns`: the ``header.stamp`` of a CDR-serialized message whose first field
  is a ``std_msgs/Header``, read from the bytes (the view never decodes what it forwards).
- :class:`SimTime`: the graph's time from ``/clock``; :meth:`SimTime.log_time` is the log time
  of a forwarded message: its header stamp, else the last ``/clock``, else the wall clock. So
  on a sim-time graph Foxglove's timeline and the message stamps agree.
- :class:`FrameTree`: the latest transform per child frame (parent, translation in metres,
  rotation as a unit quaternion (x, y, z, w)), what the view sends as Foxglove
  ``FrameTransforms`` so a 3D panel places the ``object``, ``pusher`` and camera frames in
  ``world`` on the pip install (no ``/tf`` there: docs/design/topics.md#tf-note).
"""

from __future__ import annotations

import math
import struct
import time
from dataclasses import dataclass, field

#: CDR encapsulation kinds (second byte of the 4-byte header) that are little endian:
#: CDR_LE, PL_CDR_LE, CDR2_LE, PL_CDR2_LE, D_CDR2_LE.
_LITTLE_ENDIAN = {0x01, 0x03, 0x07, 0x09, 0x0B}
_BIG_ENDIAN = {0x00, 0x02, 0x06, 0x08, 0x0A}
NS_PER_S = 1_000_000_000


def header_stamp_ns(cdr: bytes | memoryview) -> int | None:
    """``header.stamp`` in ns of a CDR message whose first field is ``std_msgs/Header``.

    Parameters
    ----------
    cdr : bytes
        The serialized message: 4-byte encapsulation header, then ``int32 sec``, ``uint32
        nanosec``.

    Returns
    -------
    int or None
        ``sec * 1e9 + nanosec``; None for a too short buffer, an unknown encapsulation, a
        negative ``sec``, ``nanosec >= 1e9`` or a zero stamp (unset).
    """
    if len(cdr) < 12 or cdr[0] != 0:
        return None
    if cdr[1] in _LITTLE_ENDIAN:
        sec, nsec = struct.unpack_from("<iI", cdr, 4)
    elif cdr[1] in _BIG_ENDIAN:
        sec, nsec = struct.unpack_from(">iI", cdr, 4)
    else:
        return None
    if sec < 0 or nsec >= NS_PER_S or (sec == 0 and nsec == 0):
        return None
    return sec * NS_PER_S + nsec


@dataclass
class SimTime:
    """The graph's time as ``/clock`` says (None until a ``/clock`` message arrived)."""

    clock_ns: int | None = None

    def on_clock(self, ns: int) -> None:
        """A ``/clock`` message with time ``ns`` (ns) arrived."""
        self.clock_ns = int(ns)

    def log_time(self, stamp_ns: int | None) -> int:
        """Log time (ns) of a message with header stamp ``stamp_ns`` (None: none/unset): the
        stamp, else the last ``/clock``, else the wall clock (ns since the Unix epoch)."""
        if stamp_ns is not None and stamp_ns > 0:
            return int(stamp_ns)
        return self.clock_ns if self.clock_ns is not None else time.time_ns()


@dataclass(frozen=True)
class Transform:
    """Pose of frame ``child`` in frame ``parent`` at ``stamp_ns``.

    Attributes
    ----------
    parent, child : str
        Frame ids.
    stamp_ns : int
        Time of the transform, ns (the source message's header stamp).
    translation : tuple of 3 float
        Origin of ``child`` in ``parent``, metres.
    rotation : tuple of 4 float
        Orientation of ``child`` in ``parent``, unit quaternion (x, y, z, w).
    """

    parent: str
    child: str
    stamp_ns: int
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


def make_transform(parent: str, child: str, stamp_ns: int, translation: tuple[float, ...],
                   rotation: tuple[float, ...]) -> Transform:
    """A checked :class:`Transform`: non-empty, different frame ids, finite values, a non-zero
    quaternion (normalised here).

    Raises
    ------
    ValueError
        Naming what is wrong.
    """
    if not parent or not child or parent == child:
        raise ValueError(f"a transform needs two different frame ids, got {parent!r} -> "
                         f"{child!r}")
    values = [float(v) for v in (*translation, *rotation)]
    if len(translation) != 3 or len(rotation) != 4 or not all(map(math.isfinite, values)):
        raise ValueError(f"{parent} -> {child}: translation (3) and rotation (4) must be "
                         f"finite, got {translation}, {rotation}")
    norm = math.sqrt(sum(q * q for q in values[3:]))
    if norm < 1e-9:
        raise ValueError(f"{parent} -> {child}: zero quaternion")
    x, y, z = values[:3]
    qx, qy, qz, qw = (q / norm for q in values[3:])
    return Transform(parent, child, int(stamp_ns), (x, y, z), (qx, qy, qz, qw))


@dataclass
class FrameTree:
    """The last received transform per child frame (a frame has one parent)."""

    transforms: dict[str, Transform] = field(default_factory=dict)

    def update(self, transform: Transform) -> None:
        """Keep ``transform`` as the one of its child frame (replacing the previous)."""
        self.transforms[transform.child] = transform

    def latest_ns(self) -> int:
        """The newest stamp of the kept transforms, ns (0 when there are none)."""
        return max((t.stamp_ns for t in self.transforms.values()), default=0)
