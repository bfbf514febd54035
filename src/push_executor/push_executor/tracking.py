"""Watching a running push motion: measured joints against the plan, watchdogs, contact segment.

ROS-free. Times: ``elapsed`` = a measured joint state's stamp minus the trajectory's start
``t0`` (the node's clock when it published the trajectory; on the simulated graph both are sim
time, which advances only while the simulator executes a trajectory), s; ``steady`` = a
monotonic clock of the node's machine, s.

:class:`Execution` is one running plan. Feed it every measured joint state
(:meth:`Execution.on_state`) and poll it on a timer (:meth:`Execution.on_timer`); each returns
``None`` (keep going) or an :class:`Event`:

- ``done``: the measured stamp passed ``t0 + duration`` and every joint is within
  ``tracking_tolerance`` of the last point;
- ``deviation``: a joint off the plan (cubic Hermite interpolation of the points, as the
  controller interpolates them) by more than ``tracking_tolerance`` at every plan time within
  ``time_window`` s of ``elapsed`` (joint and amount reported). The window absorbs the unknown
  delay between publishing the trajectory and the controller starting it and the joint
  states' latency (both scale with the simulator's speed-up over real time); a stalled or
  blocked arm still leaves the plan, by more than the window, within a fraction of a second;
- ``stale``: no joint state for ``state_timeout`` s (steady), or, once the motion started, no
  *advancing* stamp for ``state_timeout`` s;
- ``no_start``: the motion did not start (no stamp past ``t0`` and no joint moved by
  :data:`START_MOTION`) within ``start_timeout`` s (steady).

It keeps the samples around the contact segment (bounded: :data:`MAX_SAMPLES`), from which
:meth:`Execution.contact_segment` gives the measured tool tip at the start and the end of the
contact segment with their stamps and the largest distance of the measured tip from the
commanded line in between.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_executor.kinematics import ArmKinematics
from push_executor.motion import MotionPlan

__all__ = ["MAX_SAMPLES", "START_MOTION", "ContactSegment", "Event", "Execution",
           "expected_positions", "segment_distance", "tracking_error"]

#: Joint motion (rad) that shows a trajectory started.
START_MOTION = 1e-3
#: Spacing of the plan times the tracking window tries, s, and their largest number.
WINDOW_STEP = 0.01
MAX_WINDOW_SAMPLES = 101
#: Samples kept around the contact segment (at 1 kHz a 100 s contact).
MAX_SAMPLES = 100_000
#: Largest gap between a planned contact time and the nearest joint state, s.
MAX_SAMPLE_GAP = 0.2
#: Samples this long (s) before and after the contact segment are kept too.
SAMPLE_MARGIN = 0.5


def expected_positions(plan: MotionPlan, elapsed: float) -> NDArray[np.float64]:
    """Planned joint positions at ``elapsed`` s from the start (cubic Hermite between points;
    the measured start posture before the first point, the last point after the end)."""
    times, q, qd = plan.times, plan.positions, plan.velocities
    if elapsed <= times[0]:
        return q[0].copy()
    if elapsed >= times[-1]:
        return q[-1].copy()
    i = int(np.searchsorted(times, elapsed)) - 1
    h = times[i + 1] - times[i]
    s = (elapsed - times[i]) / h
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    return h00 * q[i] + h10 * h * qd[i] + h01 * q[i + 1] + h11 * h * qd[i + 1]


def tracking_error(plan: MotionPlan, q_measured: ArrayLike, elapsed: float,
                   window: float = 0.0) -> tuple[int, float]:
    """(joint index, |measured - planned|) of the joint furthest off the plan.

    With ``window`` > 0 the plan is taken at the time within ``[elapsed - window, elapsed +
    window]`` (sampled every :data:`WINDOW_STEP` s at most, ``elapsed`` included) where it is
    closest to the measurement (smallest largest-joint error): a time-shift-tolerant tube
    around the plan.
    """
    q = np.asarray(q_measured, dtype=float)
    times = [elapsed]
    if window > 0.0:
        n = min(MAX_WINDOW_SAMPLES, 2 * int(np.ceil(window / WINDOW_STEP)) + 1)
        times += list(elapsed + np.linspace(-window, window, n))
    dev = np.abs(np.array([expected_positions(plan, t) for t in times]) - q)
    best = int(np.argmin(dev.max(axis=1)))
    j = int(np.argmax(dev[best]))
    return j, float(dev[best, j])


def segment_distance(points: ArrayLike, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Distances of (N, 3) points from the segment a -> b, m."""
    p, a, b = (np.asarray(v, dtype=float) for v in (points, a, b))
    d = b - a
    s = np.clip(((p - a) @ d) / max(float(d @ d), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * d), axis=1)


@dataclass(frozen=True)
class Event:
    """Why an execution ended: ``kind`` (done | deviation | stale | no_start) and words."""

    kind: str
    reason: str


@dataclass(frozen=True)
class ContactSegment:
    """The measured contact segment.

    Attributes
    ----------
    start, end : (3,) ndarray
        Measured tool tip (FK of the measured joints) in ``world`` at the samples nearest the
        planned contact start and end (plan times), m.
    stamp_start, stamp_end : float
        Those samples' stamps, s (the joint states' own clock).
    line_error : float
        Largest distance of the measured tip from the commanded line between them, m.
    """

    start: NDArray[np.float64]
    end: NDArray[np.float64]
    stamp_start: float
    stamp_end: float
    line_error: float


class Execution:
    """One running plan and its watchdogs (module docstring).

    Parameters
    ----------
    plan : MotionPlan
    t0 : float
        The trajectory's start: the node's clock when it was published, s.
    steady : float
        The steady clock at the same moment, s.
    last_stamp : float
        Stamp of the newest joint state before publishing, s (-inf: none).
    tracking_tolerance, state_timeout, start_timeout : float
        rad, s, s.
    time_window : float
        s of plan time either side of ``elapsed`` the deviation check may match (module
        docstring; 0: the plan exactly at ``elapsed``).
    """

    def __init__(self, plan: MotionPlan, t0: float, steady: float, last_stamp: float,
                 tracking_tolerance: float, state_timeout: float, start_timeout: float,
                 time_window: float = 0.0) -> None:
        self.plan, self.t0 = plan, float(t0)
        self.time_window = float(time_window)
        self.tolerance = float(tracking_tolerance)
        self.state_timeout, self.start_timeout = float(state_timeout), float(start_timeout)
        self._start_steady = steady
        self._last_sample = steady
        self._last_advance = steady
        self._stamp = max(float(last_stamp), self.t0)
        self.started = False
        self._times: list[float] = []
        self._qs: list[NDArray[np.float64]] = []
        self._keep = (plan.contact_start - SAMPLE_MARGIN, plan.contact_end + SAMPLE_MARGIN)

    def elapsed(self, stamp: float) -> float:
        """Seconds of the plan at a joint state stamped ``stamp``."""
        return float(stamp) - self.t0

    def on_state(self, stamp: float, q: NDArray[np.float64], steady: float) -> Event | None:
        """A measured joint state (chain order); returns an ending event or None."""
        self._last_sample = steady
        if stamp > self._stamp:
            self._stamp = stamp
            self._last_advance = steady
            self.started = True
        elif not self.started and float(np.max(np.abs(q - self.plan.positions[0]))) \
                > START_MOTION:
            self.started = True
            self._last_advance = steady
        elapsed = self.elapsed(stamp)
        if self._keep[0] <= elapsed <= self._keep[1] and len(self._times) < MAX_SAMPLES:
            self._times.append(float(stamp))
            self._qs.append(np.array(q, dtype=float))
        j, dev = tracking_error(self.plan, q, elapsed, self.time_window)
        if dev > self.tolerance:
            return Event("deviation", f"{self.plan.joint_names[j]} {dev:.4f} off the plan at "
                         f"t = {elapsed:.2f} s ({self.plan.stage_at(elapsed)}), tolerance "
                         f"{self.tolerance}")
        if elapsed >= self.plan.duration:
            return Event("done", f"finished after {elapsed:.2f} s")
        return None

    def on_timer(self, steady: float) -> Event | None:
        """Watchdogs on the steady clock; returns an ending event or None."""
        if steady - self._last_sample > self.state_timeout:
            return Event("stale", f"no joint state for {steady - self._last_sample:.2f} s")
        if self.started and steady - self._last_advance > self.state_timeout:
            return Event("stale", f"joint state stamps stopped advancing "
                         f"{steady - self._last_advance:.2f} s ago")
        if not self.started and steady - self._start_steady > self.start_timeout:
            return Event("no_start", f"the motion did not start within {self.start_timeout} s "
                         "(controller inactive or not receiving?)")
        return None

    @property
    def samples(self) -> int:
        """Samples kept for the contact segment."""
        return len(self._times)

    def contact_segment(self, arm: ArmKinematics) -> ContactSegment:
        """The measured contact segment (:class:`ContactSegment`).

        Raises
        ------
        ValueError
            No sample within ``MAX_SAMPLE_GAP`` of the contact start or end.
        """
        times = np.array(self._times) - self.t0
        plan = self.plan
        index = []
        for label, t in (("start", plan.contact_start), ("end", plan.contact_end)):
            i = int(np.argmin(np.abs(times - t))) if len(times) else -1
            if i < 0 or abs(times[i] - t) > MAX_SAMPLE_GAP:
                held = (f"{len(times)} samples at {times.min():.3f}-{times.max():.3f} s"
                        if len(times) else "no samples")
                raise ValueError(f"no joint state recorded within {MAX_SAMPLE_GAP} s of the "
                                 f"contact segment's {label} ({t:.3f} s of the plan; {held})")
            index.append(i)
        i0, i1 = index
        tips = arm.tip_positions(np.array(self._qs[i0:i1 + 1]))
        error = segment_distance(tips, plan.line[0], plan.line[1])
        return ContactSegment(start=tips[0], end=tips[-1], stamp_start=self._times[i0],
                              stamp_end=self._times[i1], line_error=float(np.max(error)))
