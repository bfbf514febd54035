"""Unit tests of push_core.stopping: the stop rule with the estimate's covariance."""

import math

import numpy as np
import pytest

from push_core.stopping import goal_reached


def test_stop_rule_shrinks_the_region_by_z_standard_deviations() -> None:
    tol_xy, tol_th = 0.0075, math.radians(5.0)
    z = 2.3263478740408408  # Phi^-1(0.99)
    goal = [0.005, 0.0, 0.0]  # 5 mm away
    # sigma 1 mm: 5 + 2.33 = 7.33 mm <= 7.5; sigma 1.1 mm: 5 + 2.56 > 7.5
    for sigma, expected in ((1e-3, True), (1.1e-3, False)):
        cov = np.diag([sigma**2, sigma**2, 0.0])
        assert goal_reached([0, 0, 0], goal, tol_xy, tol_th, cov) is expected
        assert (5e-3 + z * sigma <= tol_xy) is expected
    # the worst direction counts: the larger eigenvalue of the position block
    aniso = np.array([[0.25e-6, 0.0, 0.0], [0.0, 1.21e-6, 0.0], [0.0, 0.0, 0.0]])
    assert not goal_reached([0, 0, 0], goal, tol_xy, tol_th, aniso)
    # orientation: 4 deg off with sigma 0.5 deg -> 5.16 deg > 5
    cov = np.diag([0.0, 0.0, math.radians(0.5) ** 2])
    assert not goal_reached([0, 0, 0], [0, 0, math.radians(4.0)], tol_xy, tol_th, cov)
    assert goal_reached([0, 0, 0], [0, 0, math.radians(4.0)], tol_xy, tol_th, cov,
                        orientation=False)
    # confidence 0.5 (z = 0) and no covariance are the point rule; the 7 x 7 state
    # covariance is accepted (its pose block)
    big = np.diag([1e-4, 1e-4, 1.0, 1, 1, 1, 1])
    assert goal_reached([0, 0, 0], goal, tol_xy, tol_th, big, confidence=0.5)
    assert goal_reached([0, 0, 0], goal, tol_xy, tol_th, None)
    assert not goal_reached([0, 0, 0], goal, tol_xy, tol_th, big)

def test_stop_rule_bad_arguments_name_themselves() -> None:
    with pytest.raises(ValueError, match="covariance"):
        goal_reached([0, 0, 0], [0, 0, 0], 0.0075, 0.08, np.eye(2))
    with pytest.raises(ValueError, match="covariance"):
        goal_reached([0, 0, 0], [0, 0, 0], 0.0075, 0.08, np.full((3, 3), np.nan))
    with pytest.raises(ValueError, match="confidence"):
        goal_reached([0, 0, 0], [0, 0, 0], 0.0075, 0.08, np.eye(3), confidence=1.0)
