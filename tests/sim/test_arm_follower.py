"""The ROS-free trajectory follower: acceptance rules, interpolation, replacement, hold."""

from __future__ import annotations

import numpy as np
import pytest

from sim_bridge.arm import (
    TrajectoryCommand,
    TrajectoryFollower,
    TrajectoryRejected,
    check_trajectory,
    hermite,
)

JOINTS = ("a", "b")


def cmd(**kw: object) -> TrajectoryCommand:
    base = dict(joint_names=["a", "b"], stamp=0.0, times=[1.0, 2.0],
                positions=[[1.0, 2.0], [3.0, 4.0]], velocities=[])
    base.update(kw)
    return TrajectoryCommand(**base)


@pytest.mark.parametrize(("kind", "change"), [
    ("joints", {"joint_names": ["a"]}),
    ("joints", {"joint_names": ["a", "c"]}),
    ("joints", {"joint_names": ["a", "a"]}),
    ("empty", {"times": [], "positions": []}),
    ("time", {"times": [1.0, 1.0]}),
    ("time", {"times": [2.0, 1.0]}),
    ("size", {"positions": [[1.0], [3.0, 4.0]]}),
    ("size", {"velocities": [[0.0], [0.0, 0.0]]}),
    ("final_velocity", {"velocities": [[1.0, 1.0], [0.0, 0.5]]}),
    ("past", {"stamp": 5.0}),
    ("finite", {"positions": [[np.nan, 2.0], [3.0, 4.0]]}),
    ("duration", {"times": [1.0, 1000.0]}),
])
def test_rejections(kind: str, change: dict) -> None:
    with pytest.raises(TrajectoryRejected) as info:
        check_trajectory(cmd(**change), JOINTS, now=10.0)
    assert info.value.kind == kind


def test_stamp_in_the_future_or_zero_is_accepted_and_names_are_resorted() -> None:
    t = check_trajectory(cmd(joint_names=["b", "a"], stamp=9.5), JOINTS, now=10.0)
    np.testing.assert_array_equal(t.positions, [[2.0, 1.0], [4.0, 3.0]])
    assert t.velocities is None
    assert check_trajectory(cmd(), JOINTS, now=10.0).stamp == 0.0


def test_linear_interpolation_from_the_state_at_receipt() -> None:
    t = check_trajectory(cmd(), JOINTS, now=0.0)
    q0 = np.array([0.0, 0.0])
    q, v = t.sample(3.5, 3.0, q0, [9.0, 9.0])  # 0.5 s into the segment state -> point 0
    np.testing.assert_allclose(q, [0.5, 1.0])
    np.testing.assert_allclose(v, [1.0, 2.0])
    q, v = t.sample(4.25, 3.0, q0, q0)  # a quarter into point 0 -> point 1
    np.testing.assert_allclose(q, [1.5, 2.5])
    np.testing.assert_allclose(v, [2.0, 2.0])
    q, v = t.sample(2.0, 3.0, q0, q0)  # before the start: the state at receipt
    np.testing.assert_allclose(q, q0)


def test_a_future_stamp_goes_on_from_the_state_at_receipt() -> None:
    """Received at 1 s, stamped 3 s, first point at 3.5 s: the segment to the first point
    starts at the receipt from the measured state (moving at 2 rad/s), not at the stamp from
    a standstill (the Jazzy controller's interpolation before the first point)."""
    t = check_trajectory(cmd(stamp=3.0, velocities=[[1.0, 1.0], [0.0, 0.0]],
                             times=[0.5, 1.0]), JOINTS, now=1.0)
    q0, v0 = np.array([0.0, 0.0]), np.array([2.0, 2.0])
    q, v = t.sample(1.0, 3.0, q0, v0, received=1.0)
    np.testing.assert_allclose(q, q0)
    np.testing.assert_allclose(v, v0)  # no stop at the receipt
    q, _ = t.sample(2.0, 3.0, q0, v0, received=1.0)  # 1 s into the 2.5 s to the first point
    expect, _ = hermite(1.0, 2.5, q0, v0, [1.0, 2.0], [1.0, 1.0])
    np.testing.assert_allclose(q, expect)
    q, _ = t.sample(0.5, 3.0, q0, v0, received=1.0)  # before the receipt: its state
    np.testing.assert_allclose(q, q0)


def test_first_point_at_zero_jumps() -> None:
    t = check_trajectory(cmd(times=[0.0, 1.0]), JOINTS, now=0.0)
    q, _ = t.sample(0.0, 0.0, [0.0, 0.0], [0.0, 0.0])
    np.testing.assert_allclose(q, [1.0, 2.0])


def test_cubic_hermite_against_hand_derived_values() -> None:
    # 0 -> 1 over h = 2 with zero end velocities: q(s) = 3 u^2 - 2 u^3, u = s / h.
    q, v = hermite(1.0, 2.0, [0.0], [0.0], [1.0], [0.0])
    np.testing.assert_allclose(q, [0.5])
    np.testing.assert_allclose(v, [0.75])  # (6u - 6u^2) / h at u = 0.5
    # start velocity 1, everything else 0, h = 1: q = u^3 - 2u^2 + u; q(0.5) = 0.125
    q, v = hermite(0.5, 1.0, [0.0], [1.0], [0.0], [0.0])
    np.testing.assert_allclose(q, [0.125])
    np.testing.assert_allclose(v, [-0.25])  # 3u^2 - 4u + 1
    t = check_trajectory(cmd(velocities=[[1.0, 0.0], [0.0, 0.0]]), JOINTS, now=0.0)
    q, _ = t.sample(1.5, 0.0, [0.0, 0.0], [0.0, 0.0])
    expect, _ = hermite(0.5, 1.0, [1.0, 2.0], [1.0, 0.0], [3.0, 4.0], [0.0, 0.0])
    np.testing.assert_allclose(q, expect)


def test_replacement_and_hold_after_the_end() -> None:
    f = TrajectoryFollower(JOINTS)
    assert not f.offer(check_trajectory(cmd(), JOINTS, now=0.0))
    f.open()
    q, _ = f.target(0.0, [0.0, 0.0], [0.0, 0.0])  # picked up at t = 0
    np.testing.assert_allclose(q, [0.0, 0.0])
    assert f.end_time == 2.0
    assert f.offer(check_trajectory(cmd(positions=[[5.0, 5.0], [6.0, 6.0]]), JOINTS, 0.5))
    q, _ = f.target(1.0, [1.0, 2.0], [0.0, 0.0])  # replaced at t = 1, from the measured state
    np.testing.assert_allclose(q, [1.0, 2.0])
    q, _ = f.target(1.5, [0.0, 0.0], [0.0, 0.0])
    np.testing.assert_allclose(q, [3.0, 3.5])
    assert not f.close_if_done(2.9)
    q, v = f.target(10.0, [0.0, 0.0], [0.0, 0.0])  # after the end: hold the last point
    np.testing.assert_allclose(q, [6.0, 6.0])
    np.testing.assert_allclose(v, [0.0, 0.0])
    assert f.close_if_done(10.0)
    assert not f.running
