"""push_core.estimator.ekf: the push EKF's mechanics against hand-written Kalman algebra (first
observation, Joseph-form update, gating, clipping, iterated update, the expected covariance,
snapshots, resets, refusals)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator import active
from push_core.estimator.config import STATE_LABELS, EKFConfig
from push_core.estimator.contact import ContactOutline, limit_surface_of_polygon
from push_core.estimator.ekf import PushEKF
from push_core.estimator.process_model import predict_push
from push_core.objects import load_object


def square(half: float, n_per_side: int = 1) -> np.ndarray:
    """Counter-clockwise square outline, optionally with extra points along the sides."""
    corners = np.array([[half, -half], [half, half], [-half, half], [-half, -half]])
    t = np.arange(n_per_side)[:, None] / n_per_side
    return np.concatenate([a + t * (b - a) for a, b in zip(corners, np.roll(corners, -1, 0),
                                                             strict=True)])


def library_outline(name: str) -> tuple[np.ndarray, np.ndarray]:
    return load_object(name).outline(0.002)


def informative_push(points: np.ndarray, normals: np.ndarray, pose: np.ndarray,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Pusher start and end (world): toward the object's centre +-30 deg, 2-4 cm, random gap."""
    start, _, end = active.informative_push(points, normals, pose, rng)
    return start, end


def square_ekf(**config: object) -> PushEKF:
    return PushEKF(square(0.03, 10), config=EKFConfig(**config))


def test_first_observation_initialises_the_state() -> None:
    ekf = square_ekf()
    assert STATE_LABELS == ("x", "y", "theta", "c_x", "c_y", "l", "m")
    result = ekf.update_pose([0.1, -0.02, 0.5])
    assert result.initialized and not result.reinitialized
    l0 = limit_surface_of_polygon(square(0.03))
    np.testing.assert_allclose(ekf.state, [0.1, -0.02, 0.5, 0.0, 0.0, l0, 0.3])
    cfg = ekf.config
    # COM prior: a point uniform over the 6 cm square, variance 0.06^2 / 12 per axis.
    np.testing.assert_allclose(ekf.covariance, np.diag([
        cfg.position_sigma**2, cfg.position_sigma**2, cfg.angle_sigma**2, 0.06**2 / 12,
        0.06**2 / 12, (cfg.l_sigma_fraction * l0) ** 2, cfg.m_sigma**2]), atol=1e-18)


def test_update_is_the_kalman_update_in_joseph_form() -> None:
    ekf = square_ekf()
    ekf.update_pose([0.0, 0.0, 0.0])
    rng = np.random.default_rng(4)
    a = rng.normal(size=(7, 7)) * 0.01
    p = a @ a.T + 1e-6 * np.eye(7)
    ekf.P = p.copy()
    x0 = ekf.state
    r = np.diag([1e-6, 2e-6, 1e-4])
    z = np.array([0.003, -0.001, 0.02])
    ekf.update_pose(z, r)
    h = np.eye(3, 7)
    k = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
    expected_x = x0 + k @ (z - x0[:3])
    ikh = np.eye(7) - k @ h
    expected_p = ikh @ p @ ikh.T + k @ r @ k.T
    expected_x[5] = np.clip(expected_x[5], *ekf.l_bounds)
    expected_x[6] = np.clip(expected_x[6], *ekf.m_bounds)
    np.testing.assert_allclose(ekf.state, expected_x, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(ekf.covariance, expected_p, rtol=1e-10, atol=1e-16)


def test_update_sets_filterpy_attributes_like_filterpy_update() -> None:
    from filterpy.kalman import ExtendedKalmanFilter

    ekf = square_ekf()
    ekf.update_pose([0.01, 0.0, 0.1])
    ekf.predict_push([-0.06, 0.0], [-0.02, 0.0])
    reference = ExtendedKalmanFilter(7, 3)
    reference.x, reference.P = ekf.x.copy(), ekf.P.copy()
    r = np.diag([4e-6, 4e-6, 1e-3])
    z = ekf.state[:3] + [0.001, -0.002, 0.01]
    ekf.config = EKFConfig(iterations=1)  # one update: compare with one filterpy update
    ekf.update_pose(z, r)
    reference.update(z[:, None], lambda x: np.eye(3, 7), lambda x: x[:3], R=r)
    for name in ("x", "P", "y", "S", "SI", "K", "z", "x_post", "P_post"):
        np.testing.assert_allclose(getattr(ekf, name), getattr(reference, name), rtol=1e-9,
                                   atol=1e-15, err_msg=name)


def test_covariance_stays_symmetric_positive_definite() -> None:
    points, normals = library_outline("tri1")
    ekf = PushEKF(points, normals, EKFConfig(gate_probability=1.0))
    rng = np.random.default_rng(5)
    ekf.update_pose([0.0, 0.0, 0.0])
    for _ in range(200):
        start, end = informative_push(points, normals, ekf.state[:3], rng)
        ekf.predict_push(start, end)
        # Very precise observations drive P toward singular: the Joseph form keeps it PD.
        precision = 10.0 ** rng.uniform(-9, -3)
        z = ekf.state[:3] + rng.normal(size=3) * math.sqrt(precision)
        ekf.update_pose(z, np.diag([precision, precision, precision]))
        p = ekf.covariance
        assert np.array_equal(p, p.T)
        assert np.linalg.eigvalsh(p).min() > 0.0
        assert ekf.l_bounds[0] <= ekf.state[5] <= ekf.l_bounds[1]
        assert ekf.m_bounds[0] <= ekf.state[6] <= ekf.m_bounds[1]


def test_innovation_angle_is_wrapped_and_theta_stays_continuous() -> None:
    ekf = square_ekf(symmetry_order=1)
    ekf.update_pose([0.0, 0.0, math.pi - 0.01])
    result = ekf.update_pose([0.0, 0.0, -math.pi + 0.01])  # 0.02 rad further, across +-pi
    assert result.innovation[2] == pytest.approx(0.02)
    assert not result.reinitialized
    assert math.pi - 0.01 < ekf.state[2] < math.pi + 0.01  # not wrapped to -pi


def test_symmetric_object_takes_the_closest_equivalent_orientation() -> None:
    points, normals = library_outline("hex")
    ekf = PushEKF(points, normals, EKFConfig(symmetry_order=0))
    assert ekf.outline.symmetry_order == 6
    ekf.update_pose([0.0, 0.0, 0.0])
    result = ekf.update_pose([0.0, 0.0, math.pi / 3 + 0.01])  # 60 deg + 0.01: looks the same
    assert result.innovation[2] == pytest.approx(0.01)
    assert not result.reinitialized and 0.0 < ekf.state[2] < 0.01
    # Without the symmetry the same observation is a 1.06 rad surprise: gated.
    plain = PushEKF(points, normals, EKFConfig(symmetry_order=1))
    plain.update_pose([0.0, 0.0, 0.0])
    assert plain.update_pose([0.0, 0.0, math.pi / 3 + 0.01]).reinitialized


def test_gating_reinitialises_the_pose_and_keeps_the_parameters() -> None:
    ekf = square_ekf()
    ekf.update_pose([0.0, 0.0, 0.0])
    ekf.x[3:7, 0] = [0.004, -0.002, 0.028, 0.45]
    before = ekf.covariance
    result = ekf.update_pose([0.10, 0.05, 0.4])  # knocked by hand
    assert result.reinitialized and result.nis > ekf.config.gate_threshold
    np.testing.assert_allclose(ekf.state, [0.10, 0.05, 0.4, 0.004, -0.002, 0.028, 0.45])
    p = ekf.covariance
    np.testing.assert_array_equal(p[3:, 3:], before[3:, 3:])
    np.testing.assert_array_equal(p[0:3, 3:], 0.0)
    np.testing.assert_allclose(p[0:3, 0:3], ekf.config.observation_noise)
    # A plausible observation is fused, not gated.
    assert not ekf.update_pose([0.101, 0.049, 0.41]).reinitialized


def test_parameters_are_clipped_to_physical_ranges() -> None:
    ekf = square_ekf()
    ekf.update_pose([0.0, 0.0, 0.0])
    # x, l and m almost perfectly correlated: an x innovation of -3 sigma drags l and m down
    # by about 3 of their sigmas, below their lower bounds.
    v = np.zeros(7)
    v[[0, 5, 6]] = [0.002, 0.3 * ekf.state[5], 0.15]
    ekf.P = np.diag(np.diag(ekf.covariance)) * 1e-3 + np.outer(v, v)
    result = ekf.update_pose([-0.006, 0.0, 0.0], np.diag([1e-10, 1e-10, 1e-10]))
    assert not result.reinitialized
    assert ekf.state[5] == pytest.approx(ekf.l_bounds[0])
    assert ekf.state[6] == pytest.approx(ekf.m_bounds[0])


def test_com_is_clipped_to_the_convex_hull_of_the_outline() -> None:
    # Right triangle with legs 0.12 m, centroid at the origin: vertices (-0.04, -0.04),
    # (0.08, -0.04), (-0.04, 0.08); hypotenuse x + y = 0.04.
    tri = np.array([[-0.04, -0.04], [0.08, -0.04], [-0.04, 0.08]])
    outline = ContactOutline.from_points(tri)
    assert outline.clip_to_hull(0.01, -0.02) == (0.01, -0.02)  # inside: unchanged
    np.testing.assert_allclose(outline.clip_to_hull(0.05, 0.05), [0.02, 0.02], atol=1e-15)
    np.testing.assert_allclose(outline.clip_to_hull(0.0, -0.1), [0.0, -0.04], atol=1e-15)
    np.testing.assert_allclose(outline.clip_to_hull(0.2, -0.2), [0.08, -0.04], atol=1e-15)
    # A non-convex outline: the hull bridges the notch (COM of an L-shape may lie in it).
    ell = np.array([[0, 0], [0.1, 0], [0.1, 0.03], [0.03, 0.03], [0.03, 0.1], [0, 0.1]]) - 0.03
    notch = ContactOutline.from_points(ell).clip_to_hull(0.02, 0.02)
    assert notch == (0.02, 0.02)
    # The filter applies it after an update that drags the COM out of the triangle.
    ekf = PushEKF(tri)
    ekf.update_pose([0.0, 0.0, 0.0])
    v = np.zeros(7)
    v[[0, 3, 4]] = [0.002, 0.03, 0.03]
    ekf.P = np.diag(np.diag(ekf.covariance)) * 1e-3 + np.outer(v, v)
    ekf.update_pose([0.006, 0.0, 0.0], np.diag([1e-10, 1e-10, 1e-10]))
    np.testing.assert_allclose(ekf.state[3:5], [0.02, 0.02], atol=1e-12)


def test_process_noise_grows_with_the_push() -> None:
    cfg = EKFConfig()
    q0, q1 = cfg.process_noise(0.0), cfg.process_noise(0.03)
    assert q0[0, 0] == pytest.approx(cfg.position_noise_min**2)
    assert q1[0, 0] == pytest.approx((cfg.position_noise_min + 0.03 * cfg.position_noise_per_metre)
                                     ** 2)
    assert q1[2, 2] > q0[2, 2] and q1[3, 3] == q0[3, 3] == cfg.com_noise**2


def test_predict_uses_the_model_and_propagates_the_covariance() -> None:
    ekf = square_ekf()
    ekf.update_pose([0.0, 0.0, 0.0])
    p0 = ekf.covariance
    start = np.array([-0.03 - 0.0048 - 0.005, 0.01])
    pred = ekf.predict_push(start, start + [0.025, 0.0])
    assert pred.touched
    ref = predict_push(np.r_[0, 0, 0, 0, 0, ekf.state[5], 0.3], ekf.outline, start,
                       start + [0.025, 0.0])
    np.testing.assert_allclose(ekf.state, ref.state)
    expected = ref.jacobian @ p0 @ ref.jacobian.T + ekf.config.process_noise(pred.contact_length)
    np.testing.assert_allclose(ekf.covariance, expected, rtol=1e-12, atol=1e-18)


def test_iterated_update_relinearises_at_the_smoothed_pre_push_state() -> None:
    points, normals = library_outline("tri1")
    plain = PushEKF(points, normals, EKFConfig(iterations=1))
    iterated = PushEKF(points, normals, EKFConfig(iterations=2))
    for ekf in (plain, iterated):
        ekf.update_pose([0.0, 0.0, 0.4])
    x_prev, p_prev = plain.state, plain.covariance
    rng = np.random.default_rng(6)
    start, end = informative_push(points, normals, x_prev[:3], rng)
    z = predict_push(x_prev, plain.outline, start, end).state[:3] + [0.003, -0.002, 0.03]
    for ekf in (plain, iterated):
        ekf.predict_push(start, end)
        assert not ekf.update_pose(z).reinitialized
    # Iteration 1 is the plain EKF; iteration 2 by hand: smoothed pre-push state, prediction
    # linearised there, Kalman update from the pre-push estimate.
    cfg = iterated.config
    first = predict_push(x_prev, plain.outline, start, end)
    f1 = first.jacobian
    p_prior = f1 @ p_prev @ f1.T + cfg.process_noise(first.contact_length)
    x_lin = x_prev + p_prev @ f1.T @ np.linalg.solve(p_prior, plain.state - first.state)
    second = predict_push(x_lin, plain.outline, start, end)
    f2 = second.jacobian
    x_bar = second.state + f2 @ (x_prev - x_lin)
    p_bar = f2 @ p_prev @ f2.T + cfg.process_noise(second.contact_length)
    k = p_bar[:, :3] @ np.linalg.inv(p_bar[:3, :3] + cfg.observation_noise)
    np.testing.assert_allclose(iterated.state, x_bar + k @ (z - x_bar[:3]), rtol=1e-9,
                               atol=1e-12)
    ikh = np.eye(7) - k @ np.eye(3, 7)
    expected_p = ikh @ p_bar @ ikh.T + k @ cfg.observation_noise @ k.T
    np.testing.assert_allclose(iterated.covariance, expected_p, rtol=1e-8, atol=1e-16)
    assert not np.allclose(iterated.state, plain.state)


def test_expected_covariance_is_the_plain_update_covariance_and_changes_nothing() -> None:
    """The forecast for a push equals the covariance the plain EKF has after executing that
    push and fusing any observation (the Kalman covariance does not depend on the value)."""
    points, normals = library_outline("tri1")
    ekf = PushEKF(points, normals, EKFConfig(iterations=1))
    ekf.update_pose([0.02, -0.01, 0.4])
    rng = np.random.default_rng(11)
    start, end = informative_push(points, normals, ekf.state[:3], rng)
    x0, p0 = ekf.state, ekf.covariance
    forecast = ekf.expected_covariance(start, end)
    np.testing.assert_array_equal(ekf.state, x0)
    np.testing.assert_array_equal(ekf.covariance, p0)
    # By hand: P_pred = F P F^T + Q, then (I - K H) P_pred with K = P_pred H^T S^-1.
    pred = predict_push(x0, ekf.outline, start, end)
    p_pred = pred.jacobian @ p0 @ pred.jacobian.T + ekf.config.process_noise(
        pred.contact_length)
    k = p_pred[:, :3] @ np.linalg.inv(p_pred[:3, :3] + ekf.config.observation_noise)
    np.testing.assert_allclose(forecast, (np.eye(7) - k @ np.eye(3, 7)) @ p_pred, rtol=1e-9,
                               atol=1e-16)
    ekf.predict_push(start, end)
    assert not ekf.update_pose(pred.state[:3] + [0.001, 0.002, -0.01]).reinitialized
    np.testing.assert_allclose(ekf.covariance, forecast, rtol=1e-9, atol=1e-16)
    # A push that touches tells the filter about the COM; one that misses does not.
    assert np.trace(forecast[3:5, 3:5]) < 0.9 * np.trace(p0[3:5, 3:5])
    start, end = informative_push(points, normals, ekf.state[:3], rng)
    hit = ekf.expected_covariance(start, end)
    miss = ekf.expected_covariance(ekf.state[:2] + [0.2, 0.2], ekf.state[:2] + [0.2, 0.25])
    assert np.trace(hit[3:5, 3:5]) < np.trace(miss[3:5, 3:5])
    fresh = PushEKF(points, normals)
    with pytest.raises(RuntimeError, match="initialize"):
        fresh.expected_covariance(start, end)


def test_snapshot_and_restore_replay_exactly() -> None:
    ekf = square_ekf()
    ekf.update_pose([0.0, 0.0, 0.0])
    saved = ekf.snapshot()
    start = np.array([-0.03 - 0.0048 - 0.005, 0.01])
    ekf.predict_push(start, start + [0.025, 0.0])
    ekf.update_pose([0.02, -0.003, -0.05])
    after = (ekf.state, ekf.covariance)
    ekf.restore(saved)
    np.testing.assert_array_equal(ekf.state, saved[0][:, 0])
    ekf.predict_push(start, start + [0.025, 0.0])
    ekf.update_pose([0.02, -0.003, -0.05])
    np.testing.assert_array_equal(ekf.state, after[0])
    np.testing.assert_array_equal(ekf.covariance, after[1])


def test_reset_starts_a_new_episode() -> None:
    ekf = square_ekf()
    ekf.update_pose([0.1, 0.0, 0.0])
    ekf.reset()
    assert not ekf.initialized
    with pytest.raises(RuntimeError, match="initialize"):
        ekf.predict_push([0.0, 0.0], [0.01, 0.0])
    assert ekf.update_pose([0.0, 0.2, 1.0]).initialized
    assert ekf.state[1] == pytest.approx(0.2)


@pytest.mark.parametrize(("call", "match"), [
    (lambda f: f.update_pose([0.0, 0.0]), "pose"),
    (lambda f: f.update_pose([0.0, np.nan, 0.0]), "pose"),
    (lambda f: f.update_pose([0.0, 0.0, 0.0], np.eye(2)), "R"),
    (lambda f: f.update_pose([0.0, 0.0, 0.0], -np.eye(3)), "R"),
    (lambda f: f.update_pose([0.0, 0.0, 0.0], [[1, 1, 0], [0, 1, 0], [0, 0, 1]]), "R"),
    (lambda f: f.predict_push([0.0, np.nan], [0.01, 0.0]), "pusher_start"),
    (lambda f: f.predict_push([0.0, 0.0], [0.01]), "pusher_end"),
])
def test_filter_rejects_bad_inputs(call: object, match: str) -> None:
    ekf = square_ekf()
    ekf.update_pose([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=match):
        call(ekf)  # type: ignore[operator]


def test_unobserved_orientation_fuses_the_position_only() -> None:
    # A yaw variance of 1e6 rad^2 (push_core.symmetry.UNOBSERVED_VARIANCE, a disc) means "not
    # observed": the first observation starts yaw at its value with the configured noise, a
    # later one updates x and y like a 2-D Kalman update and leaves theta alone.
    ekf = square_ekf()
    cfg = ekf.config
    r = np.diag([1e-6, 1e-6, 1e6])
    first = ekf.update_pose([0.0, 0.0, 0.0], r)
    assert first.initialized and not first.orientation_observed
    assert ekf.covariance[2, 2] == pytest.approx(cfg.angle_sigma**2)
    ekf.predict_push([-0.05, 0.0], [-0.02, 0.001])
    x_prior, p_prior = ekf.state, ekf.covariance
    result = ekf.update_pose([x_prior[0] + 1e-3, x_prior[1], 2.5], r)
    assert not result.orientation_observed and not result.reinitialized
    assert result.innovation[2] == 0.0
    # one iteration of the update = the closed-form 2-D update on the prior (iterations = 1)
    ekf1 = square_ekf(iterations=1)
    ekf1.update_pose([0.0, 0.0, 0.0], r)
    ekf1.predict_push([-0.05, 0.0], [-0.02, 0.001])
    x0, p0 = ekf1.state, ekf1.covariance
    ekf1.update_pose([x0[0] + 1e-3, x0[1], 2.5], r)
    gain = p0[:, :2] @ np.linalg.inv(p0[:2, :2] + r[:2, :2])
    expected = x0 + gain @ np.array([1e-3, 0.0])
    expected[3:5] = ekf1.state[3:5]  # the COM is clipped to the hull afterwards
    np.testing.assert_allclose(ekf1.state[[0, 1, 2, 5, 6]], expected[[0, 1, 2, 5, 6]],
                               atol=1e-12)
    assert abs(ekf.state[2] - x_prior[2]) < 0.5  # the observed 2.5 rad was not fused
    assert ekf.covariance[0, 0] < p_prior[0, 0]
