"""push_core.estimator.pairing: estimator pose + state messages paired into estimates (no rclpy)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator.pairing import EstimatePairing


def state(x: float, y: float, theta: float) -> np.ndarray:
    return np.array([x, y, theta, 0.001, -0.002, 0.03, 0.25])


COV = np.eye(7) * 1e-6


def test_a_pose_and_the_state_of_the_same_pose_pair_in_either_order() -> None:
    p = EstimatePairing()
    assert p.add_pose(10.0, [0.1, 0.2, 0.3]) is None
    est = p.add_state(state(0.1, 0.2, 0.3), COV)
    assert est is not None and est.stamp == 10.0
    np.testing.assert_array_equal(est.state, state(0.1, 0.2, 0.3))
    np.testing.assert_array_equal(est.covariance, COV)
    assert not p.poses  # the pose is done
    # state first; theta equal modulo 2 pi
    assert p.add_state(state(0.0, 0.0, math.pi - 1e-9), COV) is None
    est = p.add_pose(11.0, [0.0, 0.0, -math.pi + 1e-9])
    assert est is not None and est.stamp == 11.0


def test_tolerances_are_one_micrometre_and_one_microradian() -> None:
    p = EstimatePairing()
    p.add_state(state(0.1, 0.0, 0.0), COV)
    assert p.add_pose(1.0, [0.1 + 2e-6, 0.0, 0.0]) is None  # 2 um off
    assert p.add_pose(2.0, [0.1, 0.0, 2e-6]) is None  # 2 urad off
    est = p.add_pose(3.0, [0.1 + 0.5e-6, 0.0, 0.5e-6])
    # the newest matching pose is taken; it and the older, unmatched ones are done
    assert est is not None and est.stamp == 3.0 and not p.poses


def test_the_newest_matching_pose_wins_and_newer_unmatched_poses_wait() -> None:
    p = EstimatePairing()
    p.add_pose(1.0, [0.0, 0.0, 0.0])
    p.add_pose(2.0, [0.01, 0.0, 0.0])
    p.add_pose(3.0, [0.02, 0.0, 0.0])
    est = p.add_state(state(0.01, 0.0, 0.0), COV)
    assert est is not None and est.stamp == 2.0
    assert [s for s, _ in p.poses] == [3.0]  # newer than the pair: still waiting
    assert p.add_state(state(0.02, 0.0, 0.0), COV).stamp == 3.0


def test_memory_is_bounded_and_clear_forgets() -> None:
    p = EstimatePairing(kept=3)
    for i in range(100):
        p.add_pose(float(i), [float(i), 0.0, 0.0])
        p.add_state(state(-float(i) - 1.0, 0.0, 0.0), COV)
    assert len(p.poses) == 3 and len(p.states) == 3
    assert [s for s, _ in p.poses] == [97.0, 98.0, 99.0]
    assert p.add_state(state(0.0, 0.0, 0.0), COV) is None  # pose 0 was dropped long ago
    p.clear()
    assert not p.poses and not p.states
    with pytest.raises(ValueError, match="kept"):
        EstimatePairing(kept=0)
