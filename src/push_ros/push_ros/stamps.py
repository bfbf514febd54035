"""``builtin_interfaces/Time`` <-> float seconds: the one time codec.

The rule, stated once, for every reader and writer: a time is **finite and in
[0, MAX_STAMP_SECONDS]**, ``MAX_STAMP_SECONDS = 2^31 - 1 us`` (``sec`` is an int32; a time
within 1 us of 2^31 s cannot round-trip through float seconds: the nearest doubles round to
2^31 s, which ``sec`` cannot hold). A stamp is rounded to the nearest nanosecond
(``nanosec < 1e9``) when written.

- Reading (:func:`seconds_from_stamp`): a stamp with ``sec < 0``, ``nanosec >= 1e9`` or a time
  above ``MAX_STAMP_SECONDS`` is rejected with ``ValueError`` naming the field, so a node never
  applies a time it could not write back.
- Writing (:func:`stamp_from_seconds`): a time outside the rule raises ``ValueError``; with
  ``clamp=True`` a finite time is clamped into the range instead (publishing an estimate then
  never raises; NaN still raises, it is a bug).
- A duration (``builtin_interfaces/Duration``, e.g. a trajectory point's ``time_from_start``) is
  written by :func:`duration_from_seconds` (finite, >= 0).

The clock rule, also stated once (:func:`clock_seconds`, :func:`check_not_ahead`): a node's
clock is *not valid* while it is a sim-time clock that has not received ``/clock`` yet (it reads
0); an input stamped more than ``max_ahead`` seconds ahead of a valid clock is refused, and no
future check is made while the clock is not valid (the simulator publishes ``/clock`` before any
frame, so nothing valid is lost). Whether a stamp may precede the episode is the node's rule;
the boundary an explicit ``~/reset`` draws is :func:`episode_boundary`'s (which inputs fall
before it: :func:`push_core.episode.precedes_episode`).
"""

from __future__ import annotations

import math
from typing import Any

from builtin_interfaces.msg import Duration, Time

__all__ = ["MAX_SECONDS", "MAX_STAMP_SECONDS", "check_not_ahead", "clock_seconds",
           "duration_from_seconds",
           "episode_boundary", "seconds_from_stamp", "stamp_from_seconds"]

_NS = 1_000_000_000
#: Exclusive upper bound of the int32 ``sec`` field, s.
MAX_SECONDS = 2.0**31
#: Largest stamp, ns (exact): 2^31 s - 1 us.
_MAX_NS = 2**31 * _NS - 1000
#: Largest time a stamp may carry, s: 2^31 s - 1 us (it still round-trips).
MAX_STAMP_SECONDS = _MAX_NS / _NS


def stamp_from_seconds(seconds: float, *, clamp: bool = False) -> Time:
    """Float seconds -> ``builtin_interfaces/Time`` (rounded to the nearest nanosecond).

    Parameters
    ----------
    seconds : float
    clamp : bool
        Clamp a finite time outside [0, ``MAX_STAMP_SECONDS``] into it instead of raising.

    Raises
    ------
    ValueError
        If the time is not finite, or (without ``clamp``) not in [0, ``MAX_STAMP_SECONDS``].
    """
    seconds = float(seconds)
    if clamp and math.isfinite(seconds):
        seconds = min(max(seconds, 0.0), MAX_STAMP_SECONDS)
    if not (math.isfinite(seconds) and 0.0 <= seconds <= MAX_STAMP_SECONDS):
        raise ValueError(f"stamp: time must be finite and in [0, 2^31 s - 1 us], got "
                         f"{seconds!r}")
    sec, nanosec = divmod(min(round(seconds * _NS), _MAX_NS), _NS)
    return Time(sec=int(sec), nanosec=int(nanosec))


def duration_from_seconds(seconds: float) -> Duration:
    """A ``builtin_interfaces/Duration`` of ``seconds`` (finite, in [0, MAX_STAMP_SECONDS]),
    rounded down to the nanosecond; ``ValueError`` otherwise."""
    if not (math.isfinite(seconds) and 0.0 <= seconds <= MAX_STAMP_SECONDS):
        raise ValueError(f"duration: expected finite seconds in [0, {MAX_STAMP_SECONDS}], got "
                         f"{seconds!r}")
    sec = math.floor(seconds)
    return Duration(sec=int(sec), nanosec=min(int(round((seconds - sec) * 1e9)), 999_999_999))


def seconds_from_stamp(stamp: Time) -> float:
    """``builtin_interfaces/Time`` -> float seconds, checked against the module's rule.

    Raises
    ------
    ValueError
        ``sec`` negative, ``nanosec >= 1e9``, or a time above ``MAX_STAMP_SECONDS`` (the
        message names the field and the value).
    """
    sec, nanosec = int(stamp.sec), int(stamp.nanosec)
    if sec < 0:
        raise ValueError(f"stamp: sec must be >= 0, got {sec}")
    if not 0 <= nanosec < _NS:
        raise ValueError(f"stamp: nanosec must be in [0, 1e9), got {nanosec}")
    if sec * _NS + nanosec > _MAX_NS:
        raise ValueError(f"stamp: {sec} s {nanosec} ns is within 1 us of 2^31 s (cannot "
                         "round-trip)")
    return sec + nanosec / _NS


def clock_seconds(clock: Any) -> float | None:
    """An rclpy clock's time, s; None while a sim-time clock has not started (reads 0)."""
    ns = clock.now().nanoseconds
    if getattr(clock, "ros_time_is_active", False) and ns <= 0:
        return None
    return ns * 1e-9


def episode_boundary(newest_input: float, clock: Any) -> float:
    """The time (s) at or before which inputs belong to the episode a ``~/reset`` ends.

    The newest input stamp seen before the reset, or the node's clock if that is a started
    sim-time clock and later: a frame stamped before the reset was taken of the scene before
    it (a camera streams, so the next frame comes soon). A node on wall time compares only
    stamps (its clock and the simulator's stamps are different time lines).

    Parameters
    ----------
    newest_input : float
        s (``-inf``: none seen).
    clock : rclpy.clock.Clock
    """
    if getattr(clock, "ros_time_is_active", False):
        now = clock_seconds(clock)
        if now is not None:
            return max(float(newest_input), now)
    return float(newest_input)


def check_not_ahead(stamp: float, now: float | None, max_ahead: float, what: str = "stamp"
                    ) -> None:
    """Refuse a time more than ``max_ahead`` s ahead of ``now`` (module docstring).

    Parameters
    ----------
    stamp : float
        The input's time, s.
    now : float or None
        The node's clock (:func:`clock_seconds`); None: no check.
    max_ahead : float
        Tolerance, s (>= 0).
    what : str
        Names the input in the message.

    Raises
    ------
    ValueError
        ``"<what> <stamp> s is <d> s ahead of the node's clock (max <max_ahead> s)"``.
    """
    if now is not None and stamp > now + max_ahead:
        raise ValueError(f"{what} {stamp:.6f} s is {stamp - now:.3f} s ahead of the node's "
                         f"clock {now:.6f} s (max {max_ahead:g} s)")
