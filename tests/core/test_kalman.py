"""Unit tests of push_core.estimator.kalman.EKFBase: the textbook equations, written out."""

from __future__ import annotations

import numpy as np
import pytest

from push_core.estimator.kalman import EKFBase


class ConstantVelocity(EKFBase):
    """x = (position, velocity, bias); predict_x integrates one time step ``u`` (s)."""

    def predict_x(self, u: object = None) -> None:
        dt = float(u)  # type: ignore[arg-type]
        self.F = np.array([[1.0, dt, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        self.Q = np.diag([1e-4, 1e-3, 1e-6]) * dt
        self.x = self.F @ self.x


def random_spd(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


def test_predict_propagates_the_covariance_and_keeps_the_prior() -> None:
    rng = np.random.default_rng(0)
    kf = ConstantVelocity(3, 2)
    kf.x, kf.P = rng.normal(size=(3, 1)), random_spd(rng, 3)
    x0, p0 = kf.x.copy(), kf.P.copy()
    kf.predict(0.1)
    f = kf.F
    np.testing.assert_allclose(kf.x, f @ x0, rtol=1e-15)
    np.testing.assert_allclose(kf.P, f @ p0 @ f.T + kf.Q, rtol=1e-12)
    assert np.array_equal(kf.P, kf.P.T)
    assert np.array_equal(kf.x_prior, kf.x) and np.array_equal(kf.P_prior, kf.P)


@pytest.mark.parametrize("n", [1, 2])
def test_update_is_the_joseph_form_for_the_leading_entries(n: int) -> None:
    rng = np.random.default_rng(n)
    kf = ConstantVelocity(3, 2)
    kf.x, kf.P = rng.normal(size=(3, 1)), random_spd(rng, 3)
    x0, p0 = kf.x.copy(), kf.P.copy()
    z, r = rng.normal(size=(2, 1)), random_spd(rng, 2)
    kf.update_leading(z, r, n)
    h = np.eye(n, 3)
    s = h @ p0 @ h.T + r[:n, :n]
    k = p0 @ h.T @ np.linalg.inv(s)
    ikh = np.eye(3) - k @ h
    np.testing.assert_allclose(kf.x, x0 + k @ (z[:n] - x0[:n]), rtol=1e-12)
    np.testing.assert_allclose(kf.P, ikh @ p0 @ ikh.T + k @ r[:n, :n] @ k.T, rtol=1e-12)
    assert np.array_equal(kf.P, kf.P.T)
    np.testing.assert_allclose(kf.S, s, rtol=1e-15)
    np.testing.assert_allclose(kf.K, k, rtol=1e-12)
    assert kf.y.shape == (n, 1) and kf.K.shape == (3, n)
    assert np.array_equal(kf.x_post, kf.x) and np.array_equal(kf.P_post, kf.P)
    assert np.array_equal(kf.z, z) and kf.z is not z


def test_constrain_runs_before_the_posterior_is_recorded() -> None:
    class NonNegativeBias(ConstantVelocity):
        def constrain(self) -> None:
            self.x[2, 0] = max(self.x[2, 0], 0.0)

    kf = NonNegativeBias(3, 2)
    kf.x = np.array([[0.0], [0.0], [0.01]])
    kf.P = np.array([[1.0, 0.0, 0.9], [0.0, 1.0, 0.0], [0.9, 0.0, 1.0]])
    kf.update_leading(np.array([[-5.0], [0.0]]), np.eye(2))  # pulls the bias far below 0
    assert kf.x[2, 0] == 0.0 and kf.x_post[2, 0] == 0.0


def test_predict_x_must_be_implemented() -> None:
    with pytest.raises(NotImplementedError):
        EKFBase(2, 1).predict()
