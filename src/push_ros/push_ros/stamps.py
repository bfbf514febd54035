"""``builtin_interfaces/Time`` <-> float seconds: the one time codec.

The rule, stated once: a time is **finite and in [0, 2^31) s** (``sec`` is an int32); it is
rounded to the nearest nanosecond (``nanosec < 1e9``).
"""

from __future__ import annotations

import math

from builtin_interfaces.msg import Time

__all__ = ["MAX_SECONDS", "seconds_from_stamp", "stamp_from_seconds"]

_NS = 1_000_000_000
#: Exclusive upper bound of a representable time, s.
MAX_SECONDS = 2.0**31


def stamp_from_seconds(seconds: float) -> Time:
    """Float seconds -> ``builtin_interfaces/Time`` (rounded to the nearest nanosecond).

    Raises
    ------
    ValueError
        If the time is not finite or not in [0, 2^31) s.
    """
    seconds = float(seconds)
    if not (math.isfinite(seconds) and 0.0 <= seconds < MAX_SECONDS):
        raise ValueError(f"stamp: time must be finite and in [0, 2^31) s, got {seconds!r}")
    sec, nanosec = divmod(round(seconds * _NS), _NS)
    return Time(sec=int(sec), nanosec=int(nanosec))


def seconds_from_stamp(stamp: Time) -> float:
    """``builtin_interfaces/Time`` -> float seconds."""
    return stamp.sec + stamp.nanosec / _NS
