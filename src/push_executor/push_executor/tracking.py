"""Watching a running push motion: measured joints against the plan, watchdogs, contact segment.

ROS-free. Times: ``elapsed`` = a measured joint state's stamp minus the trajectory's start
``t0`` (the node's clock when it published the trajectory; on the simulated graph both are sim
time, which advances only while the simulator executes a trajectory), s; ``steady`` = a
monotonic clock of the node's machine, s.

:class:`Execution` is one running plan. Feed it every measured joint state
(:meth:`Execution.on_state`) and poll it on a timer (:meth:`Execution.on_timer`); each returns
``None`` (keep going) or an :class:`Event`. A chained execution (``previous``) is checked
against the plan it replaced until its own first point:

- ``done``: the measured stamp passed ``t0 + duration`` and every joint is within
  ``tracking_tolerance`` of the last point;
- ``executed`` (does not end it): the first measured stamp at or after the contact segment's
  end (a push plan, once): the contact segment can be reported while the arm retreats;
- ``deviation``: a joint off the plan (cubic Hermite interpolation of the points, as the
  controller interpolates them) by more than ``tracking_tolerance`` at every plan time within
  ``time_window`` s of ``elapsed`` (joint and amount reported). The window absorbs the unknown
  delay between publishing the trajectory and the controller starting it and the joint
  states' latency (both scale with the simulator's speed-up over real time); a stalled or
  blocked arm still leaves the plan, by more than the window, within a fraction of a second;
- ``stale``: no joint state for ``state_timeout`` s (steady), or, once the motion started, no
  *advancing* stamp for ``state_timeout`` s;
- ``no_start``: the motion did not start (no stamp past ``t0`` and no joint moved by
  :data:`START_MOTION`) within ``start_timeout`` s of the controller's time (the stamps
  advanced that far past the newest one at sending), or the stamps did not advance at all for
  ``start_timeout`` s (steady). A controller whose clock runs slowly (a simulator starved of
  CPU) is not a fault: its stamps advance, and it starts when its time reaches ``t0``.

All windows are judged on the joint states' stamps (the controller's time; simulated time in
simulation), the steady clock only where nothing arrives or the stamps stand still, so CPU
load, late or bursty delivery never read as a robot fault while a real delay still does.

It keeps the samples around the contact segment (bounded: :data:`MAX_SAMPLES`), from which
:meth:`Execution.contact_segment` gives the measured tool tip at the start and the end of the
contact segment with their stamps and the largest distance of the measured tip from the
commanded line in between.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_executor.kinematics import ArmKinematics
from push_executor.motion import MotionPlan, MotionState, PushRefused, chain_point

__all__ = ["CLOCK_RESTART", "MAX_SAMPLES", "START_MOTION", "ContactSegment", "Event",
           "Execution", "MeasuredArm", "StampClock", "expected_positions", "segment_distance",
           "start_plan", "stopping_point", "tracking_error"]

#: Joint motion (rad) that shows a trajectory started.
START_MOTION = 1e-3
#: Joint states stamped less than this (s) after the last checked one are recorded but not
#: checked against the plan (one with the same or an older stamp is): a blocked arm still
#: leaves it within a fraction of a second, and at 500 states a second the check alone took
#: a core.
CHECK_PERIOD = 0.02
#: Spacing of the plan times the tracking window tries, s, and their largest number.
WINDOW_STEP = 0.01
MAX_WINDOW_SAMPLES = 101
#: Samples kept around the contact segment (at 1 kHz a 100 s contact).
MAX_SAMPLES = 100_000
#: Largest gap between a planned contact time and the nearest joint state, s.
MAX_SAMPLE_GAP = 0.2
#: Longest gap between two samples either side of the contact start or end that they are
#: interpolated across when none lies within MAX_SAMPLE_GAP of it, s.
MAX_BRACKET = 0.6
#: Samples this long (s) before and after the contact segment are kept too.
SAMPLE_MARGIN = 0.5
#: A joint state stamped this long (s) before the newest one comes from a restarted clock.
CLOCK_RESTART = 2.0


def expected_positions(plan: MotionPlan, elapsed: float) -> NDArray[np.float64]:
    """Planned joint positions at ``elapsed`` s from the start (cubic Hermite between points;
    the start state before the first point, the last point after the end)."""
    return plan.positions_at([elapsed])[0]


def tracking_error(plan: MotionPlan, q_measured: ArrayLike, elapsed: float,
                   window: float = 0.0) -> tuple[int, float]:
    """(joint index, |measured - planned|) of the joint furthest off the plan.

    With ``window`` > 0 the plan is taken at the time within ``[elapsed - window, elapsed +
    window]`` (sampled every :data:`WINDOW_STEP` s at most, ``elapsed`` included) where it is
    closest to the measurement (smallest largest-joint error): a time-shift-tolerant tube
    around the plan.
    """
    return _window_error(plan.positions_at, q_measured, elapsed, window)


def _window_error(expected: Callable[[NDArray[np.float64]], NDArray[np.float64]],
                  q_measured: ArrayLike, elapsed: float, window: float) -> tuple[int, float]:
    """:func:`tracking_error` with ``expected(times) -> (T, n)`` positions (vectorised: the
    node checks every joint state, hundreds a second)."""
    q = np.asarray(q_measured, dtype=float)
    times = np.array([elapsed])
    if window > 0.0:
        n = min(MAX_WINDOW_SAMPLES, 2 * int(np.ceil(window / WINDOW_STEP)) + 1)
        times = np.concatenate([times, elapsed + np.linspace(-window, window, n)])
    dev = np.abs(expected(times) - q)
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
    """What happened to an execution: ``kind`` (done | deviation | stale | no_start end it;
    executed does not) and words."""

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
    previous : Execution, optional
        The execution this one replaces: until this plan's first point the arm follows that
        one's plan, and the measured joints are checked against it.
    moving : bool
        The arm is moving at the start (a chained motion: started at once).
    """

    def __init__(self, plan: MotionPlan, t0: float, steady: float, last_stamp: float,
                 tracking_tolerance: float, state_timeout: float, start_timeout: float,
                 time_window: float = 0.0, previous: Execution | None = None,
                 moving: bool = False) -> None:
        self.plan, self.t0 = plan, float(t0)
        self.time_window = float(time_window)
        self.tolerance = float(tracking_tolerance)
        self.state_timeout, self.start_timeout = float(state_timeout), float(start_timeout)
        self._previous = None if previous is None else (previous.plan, previous.t0)
        self._last_sample = steady
        self._last_advance = steady
        self._stamp = self._stamp0 = float(last_stamp)
        self._sent_stamp = self._stamp0 if math.isfinite(self._stamp0) else None
        self.started = moving  # a chained motion starts on a moving arm
        self._checked = -math.inf  # stamp of the last tracking check
        #: Whether the contact segment has been reported (``executed``; a push plan only).
        self.reported = not plan.is_push
        self._contact_over = False
        self._times: list[float] = []
        self._qs: list[NDArray[np.float64]] = []
        self._keep = (plan.contact_start - SAMPLE_MARGIN, plan.contact_end + SAMPLE_MARGIN)

    def elapsed(self, stamp: float) -> float:
        """Seconds of the plan at a joint state stamped ``stamp``."""
        return float(stamp) - self.t0

    def commanded(self, elapsed: float) -> MotionState:
        """The commanded state at plan time ``elapsed`` (the replaced plan's before this one's
        first point)."""
        if self._previous is not None and elapsed < self.plan.times[0]:
            plan, t0 = self._previous
            return plan.state_at(elapsed + self.t0 - t0)
        return self.plan.state_at(elapsed)

    def stop(self, stamp: float, measured: NDArray[np.float64], arm: ArmKinematics,
             min_time: float) -> tuple[NDArray[np.float64], float] | None:
        """The decelerating stop (:func:`stopping_point` at ``arm``'s acceleration limits,
        inside its position limits) from the commanded state at the controller's time
        ``stamp`` (s), or None when the ``measured`` posture (chain order, rad) is off the
        commanded one by more than the tracking tolerance: the arm is not where its plan is
        (hold the measured posture instead)."""
        commanded = self.commanded(self.elapsed(stamp))
        if float(np.max(np.abs(commanded.q - np.asarray(measured, dtype=float)))) \
                > self.tolerance:
            return None
        q, seconds = stopping_point(commanded, arm.acceleration_limits, min_time)
        return np.clip(q, arm.lower, arm.upper), seconds

    def expected(self, elapsed: ArrayLike) -> NDArray[np.float64]:
        """Planned positions (T, n) at plan times ``elapsed`` (T,) (the replaced plan's before
        this one's first point)."""
        t = np.asarray(elapsed, dtype=float).ravel()
        out = self.plan.positions_at(t)
        if self._previous is not None:
            early = t < self.plan.times[0]
            if np.any(early):
                plan, t0 = self._previous
                out[early] = plan.positions_at(t[early] + self.t0 - t0)
        return out

    @property
    def chainable(self) -> bool:
        """Whether a next motion may take over: the contact segment (if any) is reported."""
        return self.reported

    def on_state(self, stamp: float, q: NDArray[np.float64], steady: float) -> Event | None:
        """A measured joint state (chain order); returns an event or None.

        ``done`` (at the end, within tolerance), ``deviation`` end the execution;
        ``executed`` (the first state at or after the contact segment's end, once) does not.
        """
        self._last_sample = steady
        if self._sent_stamp is None:  # no state before the trajectory: count from this one
            self._sent_stamp = float(stamp)
        if stamp > self._stamp:  # the stamps advance (also before the start: a queue)
            self._stamp = stamp
            self._last_advance = steady
        if not self.started and (stamp > self.t0 or (
                stamp <= self._stamp0 and float(np.max(np.abs(q - self.plan.positions[0])))
                > START_MOTION)):
            self.started = True
            self._last_advance = steady
        elapsed = self.elapsed(stamp)
        if self._keep[0] <= elapsed <= self._keep[1] and len(self._times) < MAX_SAMPLES:
            self._times.append(float(stamp))
            self._qs.append(np.array(q, dtype=float))
        if self._checked < stamp < self._checked + CHECK_PERIOD and \
                elapsed < self.plan.duration:
            dev = 0.0  # checked a moment ago (joint states may come at hundreds of hertz)
        else:
            self._checked = float(stamp)
            j, dev = _window_error(self.expected, q, elapsed, 0.0)
            if dev > self.tolerance:  # off the plan at this time: within the window's times?
                j, dev = _window_error(self.expected, q, elapsed, self.time_window)
        if dev > self.tolerance:
            return Event("deviation", f"{self.plan.joint_names[j]} {dev:.4f} off the plan at "
                         f"t = {elapsed:.2f} s ({self.plan.stage_at(elapsed)}), tolerance "
                         f"{self.tolerance}")
        if elapsed >= self.plan.duration:
            return Event("done", f"finished after {elapsed:.2f} s")
        if not (self.reported or self._contact_over) and elapsed >= self.plan.contact_end:
            self._contact_over = True
            return Event("executed", f"contact segment ended at {elapsed:.2f} s")
        return None

    def on_timer(self, steady: float) -> Event | None:
        """Watchdogs on the steady clock; returns an ending event or None."""
        if steady - self._last_sample > self.state_timeout:
            return Event("stale", f"no joint state for {steady - self._last_sample:.2f} s")
        if self.started and steady - self._last_advance > self.state_timeout:
            return Event("stale", f"joint state stamps stopped advancing "
                         f"{steady - self._last_advance:.2f} s ago")
        if not self.started and (steady - self._last_advance > self.start_timeout
                                 or (self._sent_stamp is not None
                                     and self._stamp - self._sent_stamp > self.start_timeout)):
            return Event("no_start", f"the motion did not start within {self.start_timeout} s "
                         "of the controller's time, or its joint-state stamps stood still "
                         "that long (controller inactive or not receiving?)")
        return None

    @property
    def samples(self) -> int:
        """Samples kept for the contact segment."""
        return len(self._times)

    def report(self, arm: ArmKinematics) -> ContactSegment:
        """:meth:`contact_segment`, marking the execution reported (also when it raises)."""
        self.reported = True
        return self.contact_segment(arm)

    def contact_segment(self, arm: ArmKinematics) -> ContactSegment:
        """The measured contact segment (:class:`ContactSegment`): at the samples nearest the
        planned start and end, or -- joint states lost around one -- the joint positions
        interpolated there between the samples either side (at most ``MAX_BRACKET`` apart),
        stamped with the planned time.

        Raises
        ------
        ValueError
            Neither for the contact start or end.
        """
        times = np.array(self._times) - self.t0
        plan = self.plan
        qs = np.array(self._qs, dtype=float).reshape(len(times), self.plan.positions.shape[1])
        ends = []
        for label, t in (("start", plan.contact_start), ("end", plan.contact_end)):
            i = int(np.argmin(np.abs(times - t))) if len(times) else -1
            if i >= 0 and abs(times[i] - t) <= MAX_SAMPLE_GAP:
                ends.append((i, qs[i], self._times[i]))
                continue
            # joint states lost around it (a loaded machine): between the samples either side
            before, after = np.flatnonzero(times < t), np.flatnonzero(times > t)
            if len(before) and len(after) and times[after[0]] - times[before[-1]] \
                    <= MAX_BRACKET:
                a, b = before[-1], after[0]
                w = (t - times[a]) / (times[b] - times[a])
                ends.append((b if label == "start" else a, (1 - w) * qs[a] + w * qs[b],
                             t + self.t0))
                continue
            held = (f"{len(times)} samples at {times.min():.3f}-{times.max():.3f} s"
                    if len(times) else "no samples")
            raise ValueError(f"no joint state recorded within {MAX_SAMPLE_GAP} s of the "
                             f"contact segment's {label} ({t:.3f} s of the plan; {held})")
        (i0, q0, e0), (i1, q1, e1) = ends
        tips = arm.tip_positions(np.vstack([q0, qs[i0:i1 + 1], q1]))
        error = segment_distance(tips, plan.line[0], plan.line[1])
        return ContactSegment(start=tips[0], end=tips[-1], stamp_start=e0, stamp_end=e1,
                              line_error=float(np.max(error)))


class StampClock:
    """The controller's time now, from the joint states' stamps and the steady clock.

    A node's ROS clock is not updated while one of its callbacks runs (planning a push takes a
    fifth of a second and more), and on a simulated graph time passes at a rate unknown to the
    node (wall rate while the world rests, several times faster while the arm moves). So the
    newest joint state's stamp is carried forward at the rate at which the stamps advanced
    against the steady clock over the last ``window`` seconds (at least 1: never slower than
    real time), s. The window is short, so that the rate is the current one: a window that
    still held the end of a fast run overestimated the time after it by seconds (the arm then
    waited that long before each push).
    """

    def __init__(self, window: float = 0.1) -> None:
        self.window = float(window)
        self._samples: deque[tuple[float, float]] = deque()  # (steady, stamp)
        self.rate = 1.0

    def update(self, stamp: float, steady: float) -> None:
        """A joint state stamped ``stamp`` arrived at ``steady`` (s)."""
        samples = self._samples
        if samples and stamp < samples[-1][1]:
            return  # an older state: nothing new about the time
        samples.append((float(steady), float(stamp)))
        while len(samples) > 2 and steady - samples[0][0] > self.window:
            samples.popleft()
        (s0, t0), (s1, t1) = samples[0], samples[-1]
        if s1 - s0 > 0.5 * self.window:
            self.rate = max(1.0, (t1 - t0) / (s1 - s0))

    def now(self, steady: float) -> float:
        """The stamp a joint state would carry at ``steady`` (s; -inf before the first)."""
        if not self._samples:
            return -math.inf
        s1, t1 = self._samples[-1]
        return t1 + self.rate * max(0.0, steady - s1)


class MeasuredArm:
    """The newest measured chain posture (``q``, rad), its ``stamp`` and steady arrival time
    (s), the controller's time (:class:`StampClock`) and whether the arm is held: its last
    ``held_states`` postures within ``held`` rad of each other, or no state for ``quiet`` s
    (an arm moving streams its states; a resting simulator sends a few a second, fewer on a
    loaded machine).

    ``problem`` is non-empty while the newest joint state was not a posture the arm can be in
    (non-finite, outside the limits: :mod:`push_executor.state_check`); such a state never
    becomes ``q`` (a stop holds the last plausible one), and the next plausible state that
    becomes the newest clears it."""

    def __init__(self, held_states: int = 3, held: float = 1e-4, quiet: float = 0.5) -> None:
        self.q: NDArray[np.float64] | None = None
        self.stamp = self.steady = -math.inf
        self.problem = ""
        self.clock = StampClock()
        self._recent: deque[NDArray[np.float64]] = deque(maxlen=held_states)
        self._held, self._quiet = float(held), float(quiet)

    def update(self, stamp: float, q: NDArray[np.float64], steady: float,
               replace: bool = False) -> bool:
        """A joint state; it becomes the newest unless older than it (``replace``: anyway).
        Returns whether it comes from a restarted clock (stamped more than
        :data:`CLOCK_RESTART` s before the newest: a restarted driver or simulator, whose
        clock starts again): the old clock's stamps and rate are then forgotten."""
        restarted = stamp < self.stamp - CLOCK_RESTART
        if restarted:
            self.stamp, self.clock = -math.inf, StampClock(self.clock.window)
            self._recent.clear()
        if stamp >= self.stamp or replace:
            self.q, self.stamp, self.steady = q, float(stamp), float(steady)
            self.problem = ""
            self._recent.append(q)
        self.clock.update(stamp, steady)
        return restarted

    def moved(self) -> None:
        """The arm was sent moving: held again only once new states show it."""
        self._recent.clear()

    def held(self, steady: float) -> bool:
        """Whether the arm stands still at ``steady`` (s; class docstring)."""
        recent = list(self._recent)
        if recent and steady - self.steady > self._quiet:
            return True
        return len(recent) == self._recent.maxlen and float(
            np.ptp(np.array(recent), axis=0).max()) <= self._held

    def at(self, posture: ArrayLike, tolerance: float) -> bool:
        """Whether the newest posture is within ``tolerance`` (rad) of ``posture``."""
        return self.q is not None and bool(
            np.max(np.abs(self.q - np.asarray(posture, dtype=float))) <= tolerance)


#: ``make(start, previous plan or None, first)``: a motion from ``start`` (its first point at
#: the previous plan's time ``first``, led in by that plan's points up to its chain point).
PlanMaker = Callable[[MotionState, MotionPlan | None, float], MotionPlan]


def start_plan(make: PlanMaker, running: Execution | None, q: NDArray[np.float64],
               now: Callable[[], float], start_delay: float, first_delay: float
               ) -> tuple[MotionPlan, float, bool]:
    """Plan the next motion from the arm at rest at ``q`` or chained to ``running``.

    The trajectory starts (header stamp) ``start_delay`` after ``now()`` (the controller's
    time, s) and its first point ``first_delay`` later. Chained, that first point lies on the
    running plan, the motion takes over at :func:`push_executor.motion.chain_point` and the
    new trajectory repeats the running one until then, so the controller's switch is seamless
    whenever it receives the trajectory before that point; when planning took so long that the
    arm has passed it (``now()`` + ``start_delay`` beyond it), the motion is planned once more
    from later on. A running plan that will have ended by the first point is not chained to:
    the motion starts at rest from its last posture.

    Returns
    -------
    plan : MotionPlan
    t0 : float
        The trajectory's start (header stamp), s.
    chained : bool
        Whether ``plan`` takes over from ``running`` while it moves.

    Raises
    ------
    PushRefused
        ``make``'s refusal, or ``busy`` when the second plan came too late as well.
    """
    extra = 0.0
    for _ in range(2):
        began = now()
        t0 = began + start_delay + extra
        if running is None:
            return make(MotionState.at_rest(q), None, 0.0), now() + start_delay, False
        previous = running.plan
        first = t0 + first_delay - running.t0
        if first >= previous.duration:  # nothing left to chain to
            plan = make(MotionState.at_rest(previous.positions[-1]), None, 0.0)
            return plan, now() + start_delay, False
        take_over = chain_point(previous, first)
        plan = make(previous.state_at(take_over), previous, first)
        done = now()
        if done + start_delay <= running.t0 + take_over:
            return plan, t0, True
        extra = 2.0 * (done - began)
    raise PushRefused("busy", previous.stage_at(first), "the arm passed the chain point while "
                      "the motion was planned")


def stopping_point(state: MotionState, max_acceleration: ArrayLike, min_time: float
                   ) -> tuple[NDArray[np.float64], float]:
    """Where and when a stop from the moving ``state`` ends: every joint decelerates uniformly
    to rest over the same ``T = max(min_time, max_j |v_j| / a_j)`` (the joint slowest to stop
    at its acceleration limit sets it; the others decelerate less), so the hold point is
    ``q + v T / 2``: the point a controller's cubic from ``(q, v)`` to rest at it over ``T``
    reaches at uniform deceleration (ros2_controllers' decelerate-to-hold on cancel, one point).
    The state's acceleration is not carried over.

    Parameters
    ----------
    state : MotionState
        Positions (rad) and velocities (rad/s) at the stop.
    max_acceleration : float or (n,) array_like
        Joint acceleration limits, rad/s^2 (> 0).
    min_time : float
        Shortest stop, s (> 0): a one-point trajectory's ``time_from_start``.

    Returns
    -------
    q_stop : (n,) ndarray
        The hold positions, rad.
    seconds : float
        ``T``, s.
    """
    q = np.asarray(state.q, dtype=float)
    v = np.asarray(state.qd, dtype=float)
    a = np.broadcast_to(np.asarray(max_acceleration, dtype=float), v.shape)
    if not (np.all(a > 0.0) and min_time > 0.0):
        raise ValueError(f"acceleration limits and min_time must be > 0, got {a}, {min_time}")
    seconds = max(float(min_time), float(np.max(np.abs(v) / a)))
    return q + 0.5 * seconds * v, seconds
