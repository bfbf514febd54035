"""push_executor.tracking: joint-state mapping, the tracking monitor, watchdogs, contact segment.

No rclpy. A small hand-made plan (two joints of the planar arm of test_kinematics) so that the
expected values can be derived by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_executor.kinematics import ArmKinematics, ToolSpec
from push_executor.motion import MotionPlan, MotionState, StageSpan
from push_executor.tracking import (
    START_MOTION,
    Execution,
    MeasuredArm,
    StampClock,
    expected_positions,
    segment_distance,
    stopping_point,
    tracking_error,
)

from .test_kinematics import PLANAR


def straight_plan() -> MotionPlan:
    """Joint 1 from 0 to 1 rad at 1 rad/s over t = 1 ... 2 s, joint 2 fixed; contact 1.2-1.8 s."""
    times = np.array([1.0, 1.5, 2.0])
    q = np.array([[0.0, 0.5], [0.5, 0.5], [1.0, 0.5]])
    qd = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    return MotionPlan(joint_names=("j1", "j2"), times=times, positions=q, velocities=qd,
                      accelerations=np.zeros_like(q), tip=np.zeros((3, 3)),
                      stages=(StageSpan("push", 1.0, 2.0),),
                      contact_start=1.2, contact_end=1.8,
                      line=np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))


def test_expected_positions_hermite() -> None:
    plan = straight_plan()
    # Linear motion with matching velocities: the cubic Hermite is exact.
    for t in (1.0, 1.25, 1.5, 1.9, 2.0):
        np.testing.assert_allclose(expected_positions(plan, t), [t - 1.0, 0.5], atol=1e-12)
    np.testing.assert_allclose(expected_positions(plan, 0.0), [0.0, 0.5])  # before: start
    np.testing.assert_allclose(expected_positions(plan, 9.0), [1.0, 0.5])  # after: the end


def test_tracking_error_names_the_joint() -> None:
    j, dev = tracking_error(straight_plan(), [0.5, 0.56], 1.5)
    assert j == 1 and dev == pytest.approx(0.06)


def test_tracking_window_tolerates_a_time_shift_only() -> None:
    plan = straight_plan()  # joint a: t - 1 on [1, 2] s, joint b: 0.5
    late = [0.3, 0.5]  # where the plan is at 1.3 s, measured at 1.5 s: 0.2 s behind
    assert tracking_error(plan, late, 1.5) == (0, pytest.approx(0.2))
    assert tracking_error(plan, late, 1.5, window=0.3)[1] < 1e-9
    assert tracking_error(plan, late, 1.5, window=0.1)[1] == pytest.approx(0.1, abs=0.02)
    # off the path at every time of the window: the deviation stays
    off = [0.5, 0.6]
    assert tracking_error(plan, off, 1.5, window=0.3) == (1, pytest.approx(0.1))


def execution(**kw: float) -> Execution:
    args = {"tracking_tolerance": 0.05, "state_timeout": 1.0, "start_timeout": 3.0, **kw}
    return Execution(straight_plan(), t0=100.0, steady=0.0, last_stamp=100.0, **args)


def test_execution_done_and_deviation() -> None:
    run = execution()
    assert run.on_state(100.0, np.array([0.0, 0.5]), 0.1) is None and not run.started
    assert run.on_state(101.5, np.array([0.5, 0.5]), 0.2) is None and run.started
    event = run.on_state(101.6, np.array([0.6, 0.58]), 0.3)
    assert event.kind == "deviation" and "j2 0.0800" in event.reason
    run = execution()
    assert run.on_state(102.0, np.array([0.99, 0.5]), 0.5).kind == "done"
    # Past the end but not there yet: a deviation, not done.
    assert execution().on_state(102.5, np.array([0.9, 0.5]), 0.5).kind == "deviation"


def test_the_contact_segment_is_reported_once_it_has_ended() -> None:
    """``executed`` at the first state at or after the contact end (1.8 s), once; the motion
    goes on to ``done``."""
    run = execution()
    assert run.on_state(101.7, np.array([0.7, 0.5]), 0.1) is None and not run.reported
    event = run.on_state(101.85, np.array([0.85, 0.5]), 0.2)
    assert event is not None and event.kind == "executed"
    with pytest.raises(ValueError):  # no sample near the contact start was kept
        run.report(ArmKinematics(PLANAR, "base", ToolSpec("flange", 0.0, 0.1)))
    assert run.reported and run.chainable
    assert run.on_state(101.9, np.array([0.9, 0.5]), 0.3) is None
    assert run.on_state(102.0, np.array([1.0, 0.5]), 0.4).kind == "done"


def test_a_chained_execution_follows_the_replaced_plan_until_its_first_point() -> None:
    """A plan sent at 100.5 s whose first point (at 101.5 s) lies on the running plan: joint
    states in between are checked against the running plan, later ones against the new."""
    old = execution()
    plan = straight_plan()
    hold = MotionPlan(**{**plan.__dict__, "positions": np.array([[0.5, 0.5]] * 3),
                         "velocities": np.zeros((3, 2)), "times": np.array([1.0, 1.5, 2.0])})
    new = Execution(hold, 100.5, 0.0, 100.5, 0.05, 1.0, 3.0, previous=old, moving=True)
    assert new.started  # the arm moves already
    # At 101.2 s the running plan is at 0.2 rad: fine for the chained one too.
    assert new.on_state(101.2, np.array([0.2, 0.5]), 0.1) is None
    # ... while the new plan alone (held at 0.5 rad from its first point) would object.
    assert Execution(hold, 100.5, 0.0, 100.5, 0.05, 1.0, 3.0).on_state(
        101.2, np.array([0.2, 0.5]), 0.1).kind == "deviation"
    assert new.on_state(101.7, np.array([0.2, 0.5]), 0.2).kind == "deviation"


def test_watchdogs() -> None:
    run = execution()
    assert run.on_timer(0.9) is None
    assert run.on_timer(1.1).kind == "stale"  # no joint state at all
    run = execution()
    for k in range(30):  # frozen stamps, not started: only the start timeout applies
        assert run.on_state(100.0, np.array([0.0, 0.5]), 0.1 * k) is None
        assert run.on_timer(0.1 * k) is None
    assert run.on_timer(3.05).kind == "no_start"
    run = execution()
    run.on_state(100.0, np.array([0.0, 0.5]), 2.9)
    assert run.on_timer(3.1).kind == "no_start"
    # Started, then the stamps stop advancing while samples keep coming.
    run = execution()
    run.on_state(101.0, np.array([0.0, 0.5]), 0.1)
    for k in range(1, 12):
        run.on_state(101.0, np.array([0.0, 0.5]), 0.1 + 0.1 * k)
    assert run.on_timer(1.2).kind == "stale" and "stopped advancing" in run.on_timer(1.2).reason
    # Motion alone (a robot whose stamps do not pass t0) also counts as started.
    run = execution()
    run.on_state(99.0, np.array([2 * START_MOTION, 0.5]), 0.1)
    assert run.started


def test_contact_segment() -> None:
    arm = ArmKinematics(PLANAR, "base", ToolSpec("flange", 0.0, 0.1))
    plan = straight_plan()
    tips = arm.tip_positions(plan.positions)
    plan = MotionPlan(**{**plan.__dict__, "line": np.array([tips[0], tips[-1]])})
    run = Execution(plan, 100.0, 0.0, 100.0, 0.05, 1.0, 3.0)
    for k in range(0, 21):
        t = 1.0 + 0.05 * k
        run.on_state(100.0 + t, expected_positions(plan, t), 0.01 * k)
    seg = run.contact_segment(arm)
    assert seg.stamp_start == pytest.approx(101.2) and seg.stamp_end == pytest.approx(101.8)
    np.testing.assert_allclose(seg.start, arm.tip_pose(expected_positions(plan, 1.2))[0])
    np.testing.assert_allclose(seg.end, arm.tip_pose(expected_positions(plan, 1.8))[0])
    # The tip moves on an arc, the line is its chord: the largest gap is the arc's sagitta
    # between the sampled points.
    between = arm.tip_positions([expected_positions(plan, t) for t in
                                 np.arange(1.2, 1.8001, 0.05)])
    expected = np.max(segment_distance(between, tips[0], tips[-1]))
    assert seg.line_error == pytest.approx(expected) and seg.line_error > 0.01
    empty = Execution(plan, 100.0, 0.0, 100.0, 0.05, 1.0, 3.0)
    with pytest.raises(ValueError, match="contact segment's start"):
        empty.contact_segment(arm)
    # Joint states lost from 0.95 s to 1.5 s (a loaded machine): the start is interpolated
    # between the samples either side, at the planned time; a longer gap is refused.
    gappy = Execution(plan, 100.0, 0.0, 100.0, 0.05, 1.0, 3.0)
    for t in (0.95, 1.5, 1.8):
        gappy.on_state(100.0 + t, expected_positions(plan, t), t)
    seg = gappy.contact_segment(arm)
    assert seg.stamp_start == pytest.approx(101.2) and seg.stamp_end == pytest.approx(101.8)
    w = (1.2 - 0.95) / (1.5 - 0.95)
    between = (1 - w) * expected_positions(plan, 0.95) + w * expected_positions(plan, 1.5)
    np.testing.assert_allclose(seg.start, arm.tip_pose(between)[0], atol=1e-12)
    far = Execution(plan, 100.0, 0.0, 100.0, 0.05, 1.0, 3.0)
    for t in (0.75, 1.8):
        far.on_state(100.0 + t, expected_positions(plan, t), t)
    with pytest.raises(ValueError, match="contact segment's start"):
        far.contact_segment(arm)


def test_segment_distance() -> None:
    d = segment_distance([[0.5, 1.0, 0.0], [-1.0, 0.0, 0.0], [3.0, 0.0, 4.0]], [0, 0, 0],
                         [1, 0, 0])
    np.testing.assert_allclose(d, [1.0, 1.0, math.hypot(2.0, 4.0)])


def test_the_stamp_clock_carries_the_newest_stamp_forward_at_the_observed_rate() -> None:
    clock = StampClock(window=0.1)
    assert clock.now(0.0) == -math.inf
    for k in range(11):  # stamps advance 5x faster than the steady clock (a fast simulation)
        clock.update(100.0 + 0.05 * k, 0.01 * k)
    assert clock.rate == pytest.approx(5.0)
    assert clock.now(0.12) == pytest.approx(100.5 + 5.0 * 0.02)
    clock.update(99.0, 0.13)  # an older stamp changes nothing
    assert clock.now(0.12) == pytest.approx(100.6)
    # The run ends; the resting world's states advance at the wall clock's rate, 10 a second:
    # the rate is the new one as soon as the window has passed.
    for k in range(1, 4):
        clock.update(100.5 + 0.1 * k, 0.1 + 0.1 * k)
    assert clock.rate == pytest.approx(1.0)
    slow = StampClock(window=0.1)
    for k in range(11):  # stamps standing still (a paused clock): never slower than 1x
        slow.update(7.0, 0.01 * k)
    assert slow.rate == 1.0 and slow.now(0.3) == pytest.approx(7.2)


def test_the_measured_arm_is_held_when_its_last_postures_agree() -> None:
    arm = MeasuredArm(held_states=3, held=1e-4, quiet=0.5)
    assert not arm.held(0.0) and not arm.at([0.0, 0.0], 1.0)
    for k in range(3):
        arm.update(1.0 + k, np.array([0.1 * k, 0.0]), 0.01 * k)
    assert not arm.held(0.03) and arm.at([0.2, 0.0], 1e-9)
    assert arm.held(0.6)  # no state for half a second: nothing streams, the arm rests
    for k in range(3, 6):
        arm.update(1.0 + k, np.array([0.5, 5e-5 * (k % 2)]), 0.01 * k)
    assert arm.held(0.06)
    arm.moved()
    assert not arm.held(0.06)
    arm.update(5.5, np.array([9.0, 9.0]), 7.0)  # older than the newest: kept out
    assert arm.at([0.5, 5e-5], 1e-9)


def test_a_restarted_clock_is_taken_at_its_word() -> None:
    """A driver or simulator started again: its stamps start near 0. The old clock's newest
    stamp and rate are forgotten (the controller's time is the new clock's), the arm is not
    held until new states show it; a state a little older than the newest stays out."""
    arm = MeasuredArm(held_states=3, held=1e-4, quiet=0.5)
    for k in range(3):
        assert not arm.update(500.0 + 0.1 * k, np.array([0.1, 0.0]), 0.1 * k)
    assert arm.held(0.25) and arm.clock.now(0.3) == pytest.approx(500.3)
    assert not arm.update(499.0, np.array([0.3, 0.0]), 0.3)  # 1.2 s older: late, not new
    np.testing.assert_allclose(arm.q, [0.1, 0.0])
    assert arm.update(0.5, np.array([0.2, 0.0]), 0.4)  # the restarted clock
    assert arm.stamp == 0.5 and arm.clock.now(0.5) == pytest.approx(0.6)
    np.testing.assert_allclose(arm.q, [0.2, 0.0])
    assert not arm.held(0.45)


# ---- the robot's time base under load ----------------------------------------------------------
def load_plan() -> MotionPlan:
    """Joint 1 from 0 to 1.5 rad at 1 rad/s from plan time 0.05 s (the start delay) to 1.55 s;
    the contact segment 0.3-1.3 s."""
    times = np.array([0.05, 0.55, 1.05, 1.55])
    q = np.column_stack([[0.0, 0.5, 1.0, 1.5], [0.5] * 4])
    qd = np.column_stack([[1.0] * 4, [0.0] * 4])
    return MotionPlan(joint_names=("j1", "j2"), times=times, positions=q, velocities=qd,
                      accelerations=np.zeros_like(q), tip=np.zeros((4, 3)),
                      stages=(StageSpan("push", 0.05, 1.55),), contact_start=0.3,
                      contact_end=1.3, line=np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))


def run_under_load(rates: list[tuple[float, float]], *, seed: int = 0,
                   stall: tuple[float, float] = (4.3, 4.6),
                   lost: tuple[float, float] = (0.2, 0.45), follows: bool = True,
                   frozen: bool = False) -> list[str]:
    """One motion of :func:`load_plan` through a simulated controller and a late, bursty
    joint-state stream; the executor's side as the node does it (the trajectory's start from
    StampClock, Execution fed every delivered state, its timer every 50 ms). Returns the
    events' kinds (``executed`` reports the contact segment; ``no contact sample`` when that
    fails, which the node answers with a fault).

    ``rates``: (wall s from which, the controller's clock rate against the wall clock), the
    first from 0; the trajectory is sent at wall 0.5 s. The controller holds until the
    trajectory's stamp, then follows it (``follows``; else the arm stays put); ``frozen``: its
    clock stops at the send (its states keep coming, 10 a second, with that stamp). Joint
    states every 0.02 s of the controller's time, delivered 0-40 ms late (seeded), 10 % lost,
    those of the wall interval ``stall`` all at its end (a reader that fell behind), none of
    plan times ``lost`` (around the contact start)."""
    rng = np.random.default_rng(seed)
    plan, send = load_plan(), 0.5

    def clock_at(w: float) -> float:
        t, w0, rate = 100.0, 0.0, rates[0][1]
        for start, r in rates[1:]:
            if w <= start:
                break
            t, w0, rate = t + (start - w0) * rate, start, r
        return t + (w - w0) * rate

    deliveries, stamp_pub, wall_pub, delivered = [], -math.inf, -math.inf, 0.0
    for w in np.arange(0.0, 40.0, 1e-3):
        t = clock_at(min(w, send) if frozen else w)
        if not (t >= stamp_pub + 0.02 - 1e-9 or (frozen and w >= wall_pub + 0.1)):
            continue
        stamp_pub, wall_pub = t, w
        delivery = w + rng.uniform(0.0, 0.04)
        if stall[0] <= delivery < stall[1]:
            delivery = stall[1]
        delivered = max(delivered, delivery)  # reliable: in order
        if rng.random() >= 0.1:
            deliveries.append((delivered, t))
    clock, run, events = StampClock(), None, []
    timers = [(w, None) for w in np.arange(0.0, 40.0, 0.05)]
    for w, stamp in sorted(deliveries + timers, key=lambda e: e[0]):
        if run is None and w >= send:  # the node sends the trajectory
            newest = max((s for d, s in deliveries if d < send), default=-math.inf)
            t0 = clock.now(send) + 0.05
            run = Execution(plan, t0, send, newest, tracking_tolerance=0.05, state_timeout=1.0,
                            start_timeout=1.0, time_window=0.3)
        event = None
        if stamp is None:
            event = run.on_timer(w) if run is not None else None
        else:
            clock.update(stamp, w)
            elapsed = stamp - t0 if run is not None else -math.inf
            if run is not None and not lost[0] <= elapsed <= lost[1]:
                moving = follows and elapsed >= 0.0  # held until the stamp, then follows
                q = plan.positions_at([elapsed])[0] if moving else plan.positions[0]
                event = run.on_state(stamp, q, w)
        if event is not None:
            events.append(event.kind)
            if event.kind != "executed":
                break
            try:
                run.report(ArmKinematics(PLANAR, "base", ToolSpec("flange", 0.0, 0.1)))
            except ValueError:  # the node answers the push with a fault
                events.append("no contact sample")
                break
    return events


#: The controller's clock: at rest at the wall rate, then starved of CPU (a twentieth of real
#: time: the trajectory's start is reached 1 s of wall time after the send, the start timeout),
#: then at 5x real time (the simulator catching up).
LOADED = [(0.0, 1.0), (0.5, 0.05), (2.5, 5.0)]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cpu_load_never_reads_as_a_robot_fault(seed: int) -> None:
    """The failures of a loaded machine -- a deviation in the transit, ``no_start``, no joint
    state near the contact start -- are not raised when the controller's clock is slow, the
    joint states arrive late and in bursts and some are lost: the windows are judged on the
    stamps. (The start watchdog on the wall clock alone said no_start here.)"""
    assert run_under_load(LOADED, seed=seed) == ["executed", "done"]


def test_real_faults_under_the_same_load_still_stop_the_arm() -> None:
    """A controller that does not move (its clock running), a clock that stands still, joint
    states lost over more than MAX_BRACKET around the contact start: still faults."""
    assert run_under_load(LOADED, follows=False) == ["deviation"]
    assert run_under_load(LOADED, frozen=True) == ["no_start"]
    fast = [(0.0, 1.0), (0.5, 5.0)]
    assert run_under_load(fast) == ["executed", "done"]
    assert run_under_load(fast, lost=(-0.1, 0.6)) == ["executed", "no contact sample"]


def test_a_stop_decelerates_uniformly_at_the_slowest_joints_limit() -> None:
    """From v = (1, -0.2) rad/s at a = 5 rad/s^2: joint 1 needs 1/5 = 0.2 s, so both stop over
    T = 0.2 s, at q + v T / 2 = (0.1, 0.48); the controller's cubic from (q, v) to rest there
    is q + v T (u - u^2 / 2) (u = s / T): uniform deceleration, 0.375 v T at u = 1/2."""
    state = MotionState(np.array([0.0, 0.5]), np.array([1.0, -0.2]), np.zeros(2))
    q_stop, seconds = stopping_point(state, 5.0, 0.05)
    assert seconds == pytest.approx(0.2)
    np.testing.assert_allclose(q_stop, [0.1, 0.48], atol=1e-12)
    stop = MotionPlan(joint_names=("j1", "j2"), times=np.array([1.0, 1.2]),
                      positions=np.array([state.q, q_stop]),
                      velocities=np.array([state.qd, [0.0, 0.0]]),
                      accelerations=np.zeros((2, 2)), tip=np.zeros((2, 3)),
                      stages=(StageSpan("stop", 1.0, 1.2),), contact_start=math.nan,
                      contact_end=math.nan, line=np.full((2, 3), math.nan))
    np.testing.assert_allclose(expected_positions(stop, 1.1), [0.075, 0.485], atol=1e-12)
    # slow: the shortest stop (a one-point trajectory's time) sets T
    slow = MotionState(np.zeros(2), np.array([0.1, 0.0]), np.zeros(2))
    q_stop, seconds = stopping_point(slow, [5.0, 5.0], 0.05)
    assert seconds == 0.05 and q_stop.tolist() == pytest.approx([0.0025, 0.0])
    at_rest = MotionState.at_rest([0.3, 0.4])
    assert stopping_point(at_rest, 5.0, 0.05)[0].tolist() == [0.3, 0.4]
    with pytest.raises(ValueError):
        stopping_point(state, 0.0, 0.05)


def test_stopping_a_run_decelerates_from_its_commanded_state_unless_the_arm_is_off_it() -> None:
    """The straight plan at 101.5 s (t0 = 100 s): joint 1 at 0.5 rad moving at 1 rad/s, so at
    5 rad/s^2 the stop takes 0.2 s and ends at 0.6 rad; an arm measured 0.1 rad off the plan
    (tolerance 0.05) is not where its plan is: no decelerating stop."""
    arm = ArmKinematics(PLANAR, "base", ToolSpec("flange", 0.0, 0.1), acceleration_limits=5.0)
    run = execution()
    q_stop, seconds = run.stop(101.5, np.array([0.49, 0.5]), arm, 0.05)
    assert seconds == pytest.approx(0.2)
    np.testing.assert_allclose(q_stop, [0.6, 0.5], atol=1e-12)
    assert run.stop(101.5, np.array([0.4, 0.5]), arm, 0.05) is None
    # after the end the plan is at rest: the shortest stop at the last point
    q_stop, seconds = run.stop(103.0, np.array([1.0, 0.5]), arm, 0.05)
    assert seconds == 0.05 and q_stop.tolist() == [1.0, 0.5]
