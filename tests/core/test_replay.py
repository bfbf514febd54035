"""push_core.estimator.replay: inputs in stamp order and the late push re-filtered (real PushEKF,
no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from push_core.estimator import EKFConfig, PushEKF
from push_core.estimator.replay import Rejected, ReplayHistory


def square(half: float = 0.03, n: int = 10) -> np.ndarray:
    corners = np.array([[half, -half], [half, half], [-half, half], [-half, -half]])
    t = np.arange(n)[:, None] / n
    return np.concatenate([a + t * (b - a) for a, b in zip(corners, np.roll(corners, -1, 0),
                                                             strict=True)])


def ekf() -> PushEKF:
    return PushEKF(square(), config=EKFConfig())


OBS0 = np.array([0.0, 0.0, 0.0])
OBS1 = np.array([0.012, 0.001, 0.02])
#: A 2 cm push in +x from the left side, through the object's centre line.
START, END = np.array([-0.045, 0.0]), np.array([-0.025, 0.0])


def test_an_observation_after_a_push_is_filtered_on_top_of_it() -> None:
    h = ReplayHistory(ekf())
    assert h.observe(1.0, OBS0, None).initialized
    done = h.insert_push(2.0, 3.0, START, END)
    assert done.replayed == 0 and done.nis is None and done.prediction.touched
    moved = h.filter.state[0]
    assert moved > 0.005  # the push moved the object along +x
    h.observe(4.0, OBS1, None)
    assert [e.key for e in h.entries] == [1.0, 3.0, 4.0]
    assert [e.push for e in h.entries] == [None, (2.0, 3.0), None]
    assert h.has_push(2.0, 3.0) and not h.has_push(2.0, 3.5)
    with pytest.raises(Rejected, match="older than the last applied input") as info:
        h.observe(3.5, OBS1, None)
    assert info.value.kind == "out_of_order"


def test_a_late_push_is_inserted_before_newer_observations_and_they_are_replayed() -> None:
    in_order = ReplayHistory(ekf())
    in_order.observe(1.0, OBS0, None)
    in_order.insert_push(2.0, 3.0, START, END)
    in_order.observe(4.0, OBS1, None)

    late = ReplayHistory(ekf())
    late.observe(1.0, OBS0, None)
    late.observe(4.0, OBS1, None)  # overtook its push
    without_push = late.filter.snapshot()
    done = late.insert_push(2.0, 3.0, START, END)
    assert done.replayed == 1 and done.nis is not None
    assert [e.key for e in late.entries] == [1.0, 3.0, 4.0]
    # the same estimate as if the inputs had arrived in stamp order, not as without the push
    np.testing.assert_allclose(late.filter.state, in_order.filter.state, rtol=0, atol=1e-12)
    np.testing.assert_allclose(late.filter.covariance, in_order.filter.covariance, rtol=0,
                               atol=1e-15)
    assert not np.allclose(late.filter.state, without_push[0])


def test_a_push_that_cannot_be_placed_or_applied_changes_nothing() -> None:
    h = ReplayHistory(ekf())
    h.observe(1.0, OBS0, None)
    h.observe(4.0, OBS1, None)
    before, keys = h.filter.snapshot(), [e.key for e in h.entries]
    for t0, t1 in ((3.5, 4.5), (0.5, 0.8)):  # overlaps the observation at 4 s; before all
        with pytest.raises(Rejected, match="cannot be placed") as info:
            h.insert_push(t0, t1, START, END)
        assert info.value.kind == "out_of_order"
    with pytest.raises(Rejected, match="cannot apply") as info:
        h.insert_push(2.0, 3.0, START, np.array([np.nan, 0.0]))
    assert info.value.kind == "filter_error"
    assert [e.key for e in h.entries] == keys
    for a, b in zip(h.filter.snapshot(), before, strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_history_is_bounded_and_clear_forgets() -> None:
    h = ReplayHistory(ekf(), size=3)
    for i in range(10):
        h.observe(float(i), OBS0 + [1e-4 * i, 0.0, 0.0], None)
    assert [e.key for e in h.entries] == [7.0, 8.0, 9.0]
    # older than every kept input: it cannot be replayed any more
    with pytest.raises(Rejected, match="cannot be placed"):
        h.insert_push(5.0, 6.0, START, END)
    h.clear()
    assert h.entries == [] and h.last_key == -np.inf
    with pytest.raises(ValueError, match="size"):
        ReplayHistory(ekf(), size=0)
