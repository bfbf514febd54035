"""The estimator re-learns c, l, m when a push contradicts its prediction.

The documented test of "a push's observed motion contradicts its prediction": an EKF that has
converged on a wrong COM (confident, small covariance: what evaluation showed after a push that
turned the object far more than predicted) is fed pushes whose outcome comes from the true
COM (the filter's own process model as the world, exact observations): the object lands
5-18 mm and 6-18 degrees from every prediction, NIS 5-12 each time, inside the gate (21.1), so
without re-learning the filter keeps the wrong COM for ever (its covariance says it is sure).
With ``EKFConfig(relearn=True)`` the windowed test (3 observations, NIS sum above the 0.99
quantile of chi-square with 9 dof, 21.7) finds the contradiction, the parameters' covariance is
restarted, the observation is fused and the COM moves to the truth.
"""

from __future__ import annotations

import numpy as np
import pytest

from push_core.estimator import EKFConfig, PushEKF, active, predict_push
from push_core.objects import load_object

TRUE_COM = np.array([0.03, -0.01])
WRONG_COM = np.array([-0.03, 0.02])


def converged_on_a_wrong_com(relearn: bool) -> PushEKF:
    points, normals = load_object("butter").outline(0.002)
    ekf = PushEKF(points, normals, EKFConfig(relearn=relearn))
    ekf.update_pose([0.0, 0.0, 0.3])
    ekf.x[3:5, 0] = WRONG_COM
    ekf.P[3:5, :] = ekf.P[:, 3:5] = 0.0
    ekf.P[3:5, 3:5] = np.eye(2) * 1e-4**2  # confident: 0.1 mm
    return ekf


def run(ekf: PushEKF, pushes: int = 8) -> tuple[int, int, float]:
    """Pushes with outcomes from the true COM; returns (gated, relearned, final COM error m)."""
    points, normals = load_object("butter").outline(0.002)
    rng = np.random.default_rng(22)
    truth = ekf.state.copy()
    truth[3:5] = TRUE_COM
    gated = relearned = 0
    for _ in range(pushes):
        start, _, end = active.informative_push(points, normals, truth[:3], rng)
        truth = predict_push(truth, ekf.outline, start, end).state
        ekf.predict_push(start, end)
        result = ekf.update_pose(truth[:3])
        gated += result.reinitialized
        relearned += result.relearned
    return gated, relearned, float(np.linalg.norm(ekf.state[3:5] - TRUE_COM))


def test_without_relearning_the_wrong_com_is_kept() -> None:
    gated, relearned, error = run(converged_on_a_wrong_com(relearn=False))
    assert relearned == 0
    assert error > 0.05  # still the wrong COM (63 mm off)


def test_relearning_corrects_the_com() -> None:
    ekf = converged_on_a_wrong_com(relearn=True)
    gated, relearned, error = run(ekf)
    assert relearned >= 1
    assert gated == 0
    assert error < 0.02  # 67 mm off before; 15 mm after 8 pushes (exact poses, noisy model)


def test_relearning_restarts_the_parameter_covariance_at_the_prior() -> None:
    ekf = converged_on_a_wrong_com(relearn=True)
    points, normals = load_object("butter").outline(0.002)
    start, _, end = active.informative_push(points, normals, ekf.state[:3],
                                            np.random.default_rng(1))
    ekf.predict_push(start, end)
    # an observation 5 cm and 30 degrees from any prediction fails the gate both times: the pose
    # is re-initialised and c, l, m stay at the prior covariance (means kept)
    far = ekf.state[:3] + [0.05, 0.0, 0.5]
    result = ekf.update_pose(far)
    assert result.relearned and result.reinitialized
    _, prior = ekf.initial_state(far)
    q = ekf.config.process_noise(ekf.last_prediction.contact_length)  # the push predicted again
    np.testing.assert_allclose(ekf.covariance[3:, 3:], prior[3:, 3:] + q[3:, 3:], rtol=1e-12)
    np.testing.assert_allclose(ekf.state[3:5], WRONG_COM)
    np.testing.assert_allclose(ekf.covariance[:3, 3:], 0.0)


def test_relearn_must_be_a_bool() -> None:
    with pytest.raises(ValueError, match="relearn"):
        EKFConfig(relearn=1)
