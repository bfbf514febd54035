"""push_core.estimator.process_model: predict_push against hand-derived pushes of a square and its
Jacobian against central differences."""

from __future__ import annotations

import numpy as np
import pytest

from push_core.estimator.contact import ContactOutline
from push_core.estimator.process_model import predict_push

#: A 10 cm square, centred on its COM.
SQUARE = np.array([[0.05, -0.05], [0.05, 0.05], [-0.05, 0.05], [-0.05, -0.05]])
OUTLINE = ContactOutline.from_points(SQUARE)
STATE = np.array([0.0, 0.0, 0.0, 0.0, 0.0, OUTLINE.limit_surface, 0.3])
R = 0.01  # pusher radius, m


def test_a_push_that_misses_changes_nothing() -> None:
    pred = predict_push(STATE, OUTLINE, [-0.2, 0.3], [0.0, 0.3], pusher_radius=R)
    np.testing.assert_array_equal(pred.state, STATE)
    assert not pred.touched and pred.contact_length == 0.0
    np.testing.assert_allclose(pred.jacobian, np.eye(7))


def test_a_push_through_the_com_translates_by_the_travel_in_contact() -> None:
    # The pusher centre touches the face x = -0.05 at x = -0.05 - R and goes on to x = 0: the
    # object, pushed through its COM along the face normal, follows by 0.05 + R, no turn.
    pred = predict_push(STATE, OUTLINE, [-0.2, 0.0], [0.0, 0.0], pusher_radius=R, substep=0.01)
    expected = STATE.copy()
    expected[0] = 0.05 + R
    np.testing.assert_allclose(pred.state, expected, atol=1e-12)
    assert pred.touched and pred.contact_length == pytest.approx(0.05 + R)
    assert pred.n_substeps == 20  # 0.2 m in steps of at most 0.01 m


def test_max_substeps_bounds_the_work_not_the_result_of_a_straight_push() -> None:
    pred = predict_push(STATE, OUTLINE, [-0.2, 0.0], [0.0, 0.0], pusher_radius=R, substep=0.01,
                        max_substeps=5)
    assert pred.n_substeps == 5
    assert pred.state[0] == pytest.approx(0.05 + R)


def test_an_off_centre_push_turns_the_object_away_from_the_pusher() -> None:
    # Pushing the face x = -0.05 at y = +0.03 (above the COM) in +x turns it clockwise.
    pred = predict_push(STATE, OUTLINE, [-0.1, 0.03], [0.0, 0.03], pusher_radius=R)
    assert pred.touched and pred.state[0] > 0.0 and pred.state[2] < 0.0
    np.testing.assert_array_equal(pred.state[3:], STATE[3:])  # only the pose changes


def test_jacobian_matches_central_differences() -> None:
    state = np.array([0.01, -0.005, 0.2, 0.004, -0.003, OUTLINE.limit_surface, 0.4])
    start, end = np.array([-0.12, 0.02]), np.array([0.0, 0.03])
    pred = predict_push(state, OUTLINE, start, end, pusher_radius=R)
    numeric = np.zeros((7, 7))
    for k in range(7):
        h = np.zeros(7)
        h[k] = 1e-6
        plus = predict_push(state + h, OUTLINE, start, end, pusher_radius=R, jacobian=False)
        minus = predict_push(state - h, OUTLINE, start, end, pusher_radius=R, jacobian=False)
        numeric[:, k] = (plus.state - minus.state) / 2e-6
    assert pred.jacobian is not None
    np.testing.assert_allclose(pred.jacobian, numeric, atol=2e-4)
    assert predict_push(state, OUTLINE, start, end, jacobian=False).jacobian is None


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"state": np.zeros(6)}, "state"),
    ({"state": np.r_[np.nan, STATE[1:]]}, "state"),
    ({"pusher_start": [np.inf, 0.0]}, "pusher_start"),
    ({"pusher_end": [0.0]}, "pusher_end"),
    ({"substep": 0.0}, "substep must be > 0, got 0.0"),
    ({"pusher_radius": -0.01}, "pusher_radius must be >= 0, got -0.01"),
    ({"contact_tol": -1e-3}, "contact_tol must be >= 0"),
    ({"max_substeps": 0}, "max_substeps must be an integer >= 1 or None, got 0"),
    ({"max_substeps": 2.5}, "max_substeps must be an integer >= 1 or None"),
    ({"outline": SQUARE}, "outline must be a ContactOutline, got ndarray"),
])
def test_predict_push_checks_its_inputs(kwargs: dict, match: str) -> None:
    args = {"state": STATE, "outline": OUTLINE, "pusher_start": [-0.2, 0.0],
            "pusher_end": [0.0, 0.0], **kwargs}
    with pytest.raises(ValueError, match=match):
        predict_push(**args)
