"""push_estimator.inputs and the run-time parameter rule of push_estimator.config, without
rclpy: hand-worked positions, lengths, stamps and covariances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator.replay import Rejected
from push_estimator.config import PARAMETERS, changed_values, check_parameter_set
from push_estimator.inputs import (
    COVARIANCE_RANGE,
    MAX_POSITION,
    SAME_OUTLINE_TOL,
    check_outline_extent,
    check_position,
    check_push_length,
    check_stamp_order,
    same_outline,
    usable_covariance,
)

DEFAULTS = {spec.name: spec.default for spec in PARAMETERS}
SQUARE = np.array([[0.05, 0.05], [-0.05, 0.05], [-0.05, -0.05], [0.05, -0.05]])


def _square_outline(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """A 10 cm square, ``n`` points counter-clockwise, outward normals (object frame, m)."""
    t = np.linspace(0.0, 4.0, n, endpoint=False)
    side, f = np.floor(t).astype(int), t - np.floor(t)
    start, end = SQUARE[side], SQUARE[(side + 1) % 4]
    points = start + (end - start) * f[:, None]
    normals = np.array([[0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]])[side]
    return points, normals


def test_check_position_at_the_bound() -> None:
    check_position([MAX_POSITION, -MAX_POSITION, 0.0])
    with pytest.raises(Rejected, match=r"a coordinate of 100\.5 m, more than MAX_POSITION = "
                                       r"100 m") as info:
        check_position([0.0, -100.5])
    assert info.value.kind == "out_of_range"


def test_check_outline_extent() -> None:
    check_outline_extent(np.array([[100.0, -100.0]]))
    with pytest.raises(ValueError, match=r"a point 1e\+30 m from the object origin"):
        check_outline_extent(np.array([[0.0, 0.0], [1e30, 0.0]]))


def test_check_push_length_is_the_euclidean_travel() -> None:
    assert check_push_length(np.array([0.0, 0.0]), np.array([0.3, 0.4]), 1.0) == \
        pytest.approx(0.5)  # 3-4-5
    assert check_push_length([1.0, 1.0], [1.0, 1.5], 0.5) == pytest.approx(0.5)  # at the bound
    with pytest.raises(Rejected, match=r"the pusher travels 0\.5 m, more than max_push_length "
                                       r"= 0\.4 m") as info:
        check_push_length([0.0, 0.0], [0.3, 0.4], 0.4)
    assert info.value.kind == "out_of_range"


def test_check_stamp_order() -> None:
    check_stamp_order(5.0, -math.inf)  # no episode yet
    check_stamp_order(5.0, 5.0)  # the initialising observation itself
    with pytest.raises(Rejected, match=r"ending 4\.000000 s: before the episode \(its first "
                                       r"observation at 5\.000000 s\)") as info:
        check_stamp_order(4.0, 5.0, "ending")
    assert info.value.kind == "out_of_order"


def test_usable_covariance_by_eigenvalues() -> None:
    assert not usable_covariance(None)
    assert usable_covariance(np.diag([1e-6, 1e-6, 1e6]))  # perception: yaw not observed
    assert usable_covariance(np.diag([COVARIANCE_RANGE[0]] * 3))
    assert not usable_covariance(np.diag([1e-6, 1e-6, 1e9]))
    assert not usable_covariance(np.diag([1e-6, 0.0, 1e-6]))  # singular
    # Positive diagonal, but eigenvalues 1 +- 2: indefinite.
    assert not usable_covariance(np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))


def test_same_outline_within_the_tolerance() -> None:
    a = SQUARE.copy()
    assert not same_outline(None, a)
    assert same_outline(a, a + 0.9 * SAME_OUTLINE_TOL)
    assert not same_outline(a, a + 2 * SAME_OUTLINE_TOL)
    assert not same_outline(a, a[:3])


def test_changed_values_names_what_differs() -> None:
    values = {"substep": 0.01, "iterations": 2, "new": 1}
    assert changed_values(values, {"substep": 0.01, "iterations": 1}) == "iterations=2"
    assert changed_values(values, values) == ""


def test_check_parameter_set() -> None:
    points, normals = _square_outline()
    assert check_parameter_set(DEFAULTS, {"use_sim_time": True}, points, normals) == ""
    assert check_parameter_set(DEFAULTS, {"iterations": 3}, points, normals) == ""
    reason = check_parameter_set(DEFAULTS, {"limits.m_min": 2.0, "limits.m_max": 1.0}, None,
                                 None)
    assert reason.startswith("parameter 'limits.m_min/limits.m_max'")
    assert "max_push_length" in check_parameter_set(DEFAULTS, {"max_push_length": "far"},
                                                    None, None)
    # An outline that builds no filter (a flat, self-intersecting polygon): every set refused,
    # naming the outline; without an outline only the values are checked.
    flat = np.column_stack([np.linspace(0.0, 0.1, 20), np.zeros(20)])
    reason = check_parameter_set(DEFAULTS, {"iterations": 2}, flat, np.tile([0.0, 1.0], (20, 1)))
    assert reason.startswith("the current outline does not build a filter with these values: "
                             "points: polygon is self-intersecting")
    assert check_parameter_set(DEFAULTS, {"iterations": 2}, None, None) == ""


def test_episode_inputs_drop_repeats_and_what_precedes_the_episode() -> None:
    from push_estimator.inputs import REFERENCE_MARGIN, EpisodeInputs

    e = EpisodeInputs()
    assert not e.old(0.1) and e.reset() == ""  # nothing seen: every stamp is new
    e.last = 5.0
    assert e.old(5.0) and not e.old(5.5)  # a repeat of the last stamp
    assert e.reset() == " (inputs after 5.000000000 s)"
    assert e.last == -math.inf
    assert e.old(5.0) and e.old(4.5)  # in flight at the reset
    assert not e.old(5.5)  # the camera's next frame
    assert not e.old(0.2)  # a restarted clock (more than the window before)
    e.new_outline(6.0)  # perception's episode begins at its outline's frame
    assert e.old(5.5) and not e.old(6.0) and e.boundary == 6.0 - REFERENCE_MARGIN
    e.new_outline(1.0)  # an older outline never moves the boundary back
    assert e.boundary == 6.0 - REFERENCE_MARGIN


def test_relearn_parameters_build_the_filter_config() -> None:
    from push_estimator.config import EkfNodeParams

    values = {**DEFAULTS, "relearn.enabled": True, "relearn.window": 5,
              "relearn.probability": 0.95}
    cfg = EkfNodeParams.from_values(values).config
    assert (cfg.relearn, cfg.relearn_window, cfg.relearn_probability) == (True, 5, 0.95)
    assert not EkfNodeParams.from_values(DEFAULTS).config.relearn  # off by default
    assert check_parameter_set(DEFAULTS, {"relearn.enabled": True}, *_square_outline()) == ""


def test_observation_problem_and_outline_summary_texts() -> None:
    from types import SimpleNamespace

    from push_estimator.inputs import observation_problem, outline_summary

    ok = SimpleNamespace(nis=2.0, reinitialized=False)
    gated = SimpleNamespace(nis=81.9, reinitialized=True)
    assert observation_problem(1.0, ok, False, 21.1) == ""
    assert observation_problem(1.5, gated, False, 21.1) == (
        "observation at 1.500 s failed the gate (NIS 81.9 > 21.1): pose re-initialised, c, l, "
        "m kept")
    assert observation_problem(2.0, gated, True, 21.1).endswith(
        "c, l, m re-learnt from the prior; pose re-initialised")
    outline = SimpleNamespace(vertices=[0] * 20, limit_surface=0.0343, symmetry_order=4)
    assert outline_summary(outline, 176, 176, True) == (
        "new outline: 176 points -> 20 contact vertices, l_0 = 34.3 mm, symmetry order 4; new "
        "episode")
    assert "(decimated from 900)" in outline_summary(outline, 400, 900, False)
