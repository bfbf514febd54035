"""Unit tests of push_core.estimator: geometry, process model, Jacobian, EKF mechanics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core import active
from push_core.estimator import (
    STATE_LABELS,
    ContactOutline,
    EKFConfig,
    PushEKF,
    limit_surface_of_polygon,
    predict_push,
    symmetry_order_of_polygon,
)
from push_core.estimator import _twist_with_jacobian as twist_with_jacobian
from push_core.geometry import object_to_world
from push_core.model import push_twist
from push_core.objects import load_object
from push_core.rollout import rollout_push


def square(half: float, n_per_side: int = 1) -> np.ndarray:
    """Counter-clockwise square outline, optionally with extra points along the sides."""
    corners = np.array([[half, -half], [half, half], [-half, half], [-half, -half]])
    t = np.arange(n_per_side)[:, None] / n_per_side
    return np.concatenate([a + t * (b - a) for a, b in zip(corners, np.roll(corners, -1, 0),
                                                             strict=True)])


#: Outward normals of ``square(h, 4)``: right, top, left, bottom side, four points each.
SQUARE_NORMALS = np.repeat([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]], 4, axis=0)


def regular_polygon(radius: float, n: int) -> np.ndarray:
    phi = 2 * np.pi * np.arange(n) / n
    return radius * np.stack([np.cos(phi), np.sin(phi)], axis=1)


def library_outline(name: str) -> tuple[np.ndarray, np.ndarray]:
    return load_object(name).outline(0.002)


# --------------------------------------------------------------------------------------------
# Outline geometry
# --------------------------------------------------------------------------------------------
def test_limit_surface_of_a_square_and_a_disc_is_the_mean_distance() -> None:
    # Mean distance of a square of side s from its centre: s (sqrt 2 + ln(1 + sqrt 2)) / 6.
    s = 0.09
    expected = s * (math.sqrt(2.0) + math.log(1.0 + math.sqrt(2.0))) / 6.0
    assert limit_surface_of_polygon(square(s / 2)) == pytest.approx(expected, rel=1e-12)
    # Disc of radius R: 2 R / 3 (a 720-gon differs by O(1/n^2), about 1e-5 relative).
    assert limit_surface_of_polygon(regular_polygon(0.05, 720)) == pytest.approx(
        2 * 0.05 / 3, rel=3e-5)


def test_limit_surface_about_an_offset_com_matches_a_grid_integral() -> None:
    # Rectangle 0.1 x 0.06 about (0.02, -0.01): midpoint rule on a fine grid.
    verts = np.array([[0.05, -0.03], [0.05, 0.03], [-0.05, 0.03], [-0.05, -0.03]])
    com = np.array([0.02, -0.01])
    n = 2000
    xs = -0.05 + (np.arange(n) + 0.5) * 0.1 / n
    ys = -0.03 + (np.arange(n) + 0.5) * 0.06 / n
    gx, gy = np.meshgrid(xs, ys)
    grid = float(np.mean(np.hypot(gx - com[0], gy - com[1])))
    assert limit_surface_of_polygon(verts, com) == pytest.approx(grid, rel=1e-6)


def test_limit_surface_of_butter_matches_the_sampled_guess() -> None:
    spec = load_object("butter")  # non-convex, 636 vertices
    sampled = spec.limit_surface_guess(n=200_000)
    assert limit_surface_of_polygon(spec.polyline()) == pytest.approx(sampled, rel=3e-3)


@pytest.mark.parametrize(("name", "order"), [("tri1", 1), ("rect1", 4), ("rect2", 2),
                                             ("hex", 6), ("butter", 2)])
def test_symmetry_order_of_library_outlines(name: str, order: int) -> None:
    assert symmetry_order_of_polygon(load_object(name).polyline()) == order
    points, normals = library_outline(name)
    assert ContactOutline.from_points(points, normals, symmetry_order=0).symmetry_order == order


def test_contact_outline_decimates_and_keeps_the_outline() -> None:
    points, normals = library_outline("butter")
    outline = ContactOutline.from_points(points, normals, tolerance=5e-4)
    assert 10 < len(outline.vertices) < len(points) / 2
    # Every original point within the tolerance of the decimated polygon.
    from push_core.geometry import closest_point_on_polyline

    dist = closest_point_on_polyline(outline.vertices, points)[2]
    assert np.max(np.abs(dist)) <= 5e-4 + 1e-12
    np.testing.assert_allclose(np.hypot(*outline.normals.T), 1.0)
    assert outline.limit_surface == pytest.approx(limit_surface_of_polygon(points))


def test_closest_feature_loop_equals_the_vectorised_search(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import push_core.contact as estimator

    outline = ContactOutline.from_points(*library_outline("tri1"), tolerance=5e-4)
    assert len(outline.vertices) <= estimator._SMALL_POLYGON  # the loop is used for tri1
    queries = np.random.default_rng(7).uniform(-0.12, 0.12, size=(500, 2))
    queries = np.concatenate([queries, outline.vertices, outline.vertices + 0.01])
    looped = [outline.closest_feature(*q) for q in queries.tolist()]
    monkeypatch.setattr(estimator, "_SMALL_POLYGON", 0)
    assert [outline.closest_feature(*q) for q in queries.tolist()] == looped


@pytest.mark.parametrize(("points", "normals", "match"), [
    (square(0.04)[::-1], None, "points"),  # clockwise
    (square(0.04)[:2], None, "points"),
    (np.array([[0.0, 0.0], [1.0, np.nan], [0.0, 1.0]]), None, "points"),
    (np.array([[0, 0], [1, 1], [1, 0], [0, 1]], dtype=float), None, "points"),  # bow tie
    (square(0.04, 4), -SQUARE_NORMALS, "normals"),  # inward
    (square(0.04, 4), np.ones((16, 2)), "normals"),  # not unit
    (square(0.04, 4), np.zeros((3, 2)), "normals"),  # wrong shape
])
def test_bad_outlines_raise_naming_the_argument(points: np.ndarray, normals: np.ndarray | None,
                                                 match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ContactOutline.from_points(points, normals)


# --------------------------------------------------------------------------------------------
# The pushing model and its Jacobian
# --------------------------------------------------------------------------------------------
def random_twist_inputs(rng: np.random.Generator) -> tuple[float, ...]:
    u = rng.normal(size=2) * 0.01
    r = rng.normal(size=2) * 0.04
    a = rng.uniform(0, 2 * np.pi)
    c = rng.normal(size=2) * 0.01
    return (*u, *r, math.cos(a), math.sin(a), *c, rng.uniform(0.01, 0.06),
            rng.uniform(0.05, 1.2))


def twist_mode(ux: float, uy: float, rx: float, ry: float, nx: float, ny: float, cx: float,
               cy: float, l: float, m: float) -> str:  # noqa: E741
    """Which branch of the model applies (for coverage of the tests)."""
    if ux * nx + uy * ny <= 0:
        return "off"
    k = twist_with_jacobian(ux, uy, rx, ry, nx, ny, cx, cy, l, m, False)
    stick = push_twist([ux, uy], [rx, ry], [nx, ny], [cx, cy], l, 1e6)  # huge cone: sticks
    return "stick" if np.allclose(k[:3], stick, atol=1e-15) else "slide"


def test_scalar_twist_equals_the_model() -> None:
    rng = np.random.default_rng(0)
    modes = set()
    for _ in range(500):
        args = random_twist_inputs(rng)
        vx, vy, w, _ = twist_with_jacobian(*args, False)
        ref = push_twist(args[0:2], args[2:4], args[4:6], args[6:8], args[8], args[9])
        np.testing.assert_allclose([vx, vy, w], ref, rtol=1e-12, atol=1e-15)
        modes.add(twist_mode(*args))
    assert modes == {"off", "stick", "slide"}


def test_twist_jacobian_equals_autodiff_of_the_model() -> None:
    torch = pytest.importorskip("torch")

    def model(v: torch.Tensor) -> torch.Tensor:
        return push_twist(v[0:2], v[2:4], v[4:6], v[6:8], v[8], v[9])

    jac_model = torch.func.jacfwd(model)
    rng = np.random.default_rng(1)
    modes = set()
    for _ in range(60):
        args = random_twist_inputs(rng)
        mode = twist_mode(*args)
        if mode == "off":
            continue
        modes.add(mode)
        jac = np.array(twist_with_jacobian(*args, True)[3])
        ref = jac_model(torch.tensor(args, dtype=torch.float64)).numpy()
        # The normal columns are exact for tangent changes (n stays a unit vector).
        n = np.array(args[4:6])
        tangent = np.eye(2) - np.outer(n, n)
        jac[:, 4:6] = jac[:, 4:6] @ tangent
        ref[:, 4:6] = ref[:, 4:6] @ tangent
        np.testing.assert_allclose(jac, ref, rtol=1e-10, atol=1e-12)
    assert modes == {"stick", "slide"}


def test_one_push_against_a_face_is_hand_derived() -> None:
    # Square of half-width 3 cm, COM at the centre, l = 3 cm, m = 1 (sticks). The pusher
    # (radius 4.8 mm) touches the face x = -0.03 at r = (-0.03, 0.01) and pushes 1 cm along +x.
    # SPEC section 3 with r' = (-0.03, 0.01), l^2 = 9e-4, D = l^2 + r'^2 = 1.9e-3:
    #   v_ox = (l^2 + r'_x^2) u / D = 0.01 * 18/19,  v_oy = r'_x r'_y u / D = -0.01 * 3/19,
    #   omega = (r'_x v_oy - r'_y v_ox) / l^2 = -1/19 rad.
    outline = ContactOutline.from_points(square(0.03))
    state = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.03, 1.0])
    expected = [0.01 * 18 / 19, -0.01 * 3 / 19, -1 / 19]
    r_p = 0.0048
    start = np.array([-0.03 - r_p, 0.01])
    pred = predict_push(state, outline, start, start + [0.01, 0.0], substep=0.1)
    np.testing.assert_allclose(pred.state[:3], expected, rtol=1e-12)
    assert pred.touched and pred.n_substeps == 1
    assert pred.contact_length == pytest.approx(0.01)
    # Starting 5 mm before the face, 15 mm long: the gap is closed first, same motion.
    pred = predict_push(state, outline, start - [0.005, 0.0], start + [0.01, 0.0], substep=0.1)
    np.testing.assert_allclose(pred.state[:3], expected, rtol=1e-12)
    np.testing.assert_allclose(pred.state[3:], state[3:])  # parameters are not predicted


def test_push_that_misses_changes_nothing() -> None:
    outline = ContactOutline.from_points(square(0.03))
    state = np.array([0.1, -0.05, 0.3, 0.002, 0.001, 0.03, 0.3])
    start = object_to_world(state[:3], [-0.05, 0.06])  # passes beside the object
    end = object_to_world(state[:3], [0.05, 0.06])
    pred = predict_push(state, outline, start, end)
    np.testing.assert_array_equal(pred.state, state)
    np.testing.assert_array_equal(pred.jacobian, np.eye(7))
    assert not pred.touched and pred.contact_length == 0.0 and pred.n_substeps == 10


def informative_push(points: np.ndarray, normals: np.ndarray, pose: np.ndarray,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Pusher start and end (world): toward the object's centre +-30 deg, 2-4 cm, random gap."""
    start, _, end = active.informative_push(points, normals, pose, rng)
    return start, end


@pytest.mark.parametrize("name", ["tri1", "butter", "ellip2"])
def test_push_jacobian_matches_finite_differences(name: str) -> None:
    points, normals = library_outline(name)
    outline = ContactOutline.from_points(points, normals)
    rng = np.random.default_rng(2)
    smooth = 0
    n_cases = 40
    for _ in range(n_cases):
        pose = np.array([*rng.uniform(-0.1, 0.1, 2), rng.uniform(-3, 3)])
        state = np.r_[pose, rng.normal(size=2) * 0.01, rng.uniform(0.02, 0.05),
                      rng.uniform(0.1, 0.8)]
        start, end = informative_push(points, normals, pose, rng)
        pred = predict_push(state, outline, start, end)
        assert pred.touched
        h = 1e-7
        central, kink = np.empty((7, 7)), False
        for j in range(7):
            dx = np.zeros(7)
            dx[j] = h
            f = [predict_push(state + s * dx, outline, start, end, jacobian=False).state
                 for s in (1, -1)]
            fwd, bwd = (f[0] - pred.state) / h, (pred.state - f[1]) / h
            # A contact feature or mode switch inside +-h: one-sided differences disagree.
            kink |= not np.allclose(fwd, bwd, rtol=1e-3, atol=1e-4)
            central[:, j] = (f[0] - f[1]) / (2 * h)
        if kink:
            continue
        smooth += 1
        np.testing.assert_allclose(pred.jacobian, central, rtol=1e-5, atol=1e-6)
    assert smooth >= 0.85 * n_cases


def test_push_jacobian_at_a_vertex_contact_matches_finite_differences() -> None:
    # The pusher moves toward a corner of a square: the contact is the vertex (normal from the
    # vertex to the pusher centre), not a face.
    outline = ContactOutline.from_points(square(0.03))
    state = np.array([0.01, -0.02, 0.2, 0.004, -0.003, 0.025, 0.4])
    corner = object_to_world(state[:3], [0.03, 0.03])
    direction = object_to_world([0, 0, state[2]], [-1.0, -0.8]) / math.hypot(1.0, 0.8)
    start = corner - 0.012 * direction
    end = start + 0.03 * direction
    pred = predict_push(state, outline, start, end, substep=0.1)
    assert pred.touched
    h = 1e-7
    central = np.empty((7, 7))
    for j in range(7):
        dx = np.zeros(7)
        dx[j] = h
        central[:, j] = (predict_push(state + dx, outline, start, end, substep=0.1,
                                      jacobian=False).state
                         - predict_push(state - dx, outline, start, end, substep=0.1,
                                        jacobian=False).state) / (2 * h)
    np.testing.assert_allclose(pred.jacobian, central, rtol=1e-5, atol=1e-6)
    assert not np.allclose(pred.jacobian[:3, :3], np.eye(3))


def test_fine_substeps_agree_with_the_rollout() -> None:
    points, normals = library_outline("butter")
    outline = ContactOutline.from_points(points, normals)
    rng = np.random.default_rng(3)
    diffs = []
    for _ in range(40):
        pose = np.array([0.0, 0.0, rng.uniform(-3, 3)])
        state = np.r_[pose, rng.normal(size=2) * 0.01, 0.04, rng.uniform(0.15, 0.5)]
        start, end = informative_push(points, normals, pose, rng)
        ours = predict_push(state, outline, start, end, substep=5e-4, jacobian=False).state
        ref = rollout_push(outline.vertices, pose, state[3:5], state[5], state[6], start,
                           end - start, substep=5e-4).poses[0, -1]
        diffs.append(np.abs(ours[:3] - ref))
    diffs = np.array(diffs)
    # Same model and contact test; they differ only in where a closed gap puts the contact
    # (ours: at the touch; the rollout: at the substep start), i.e. by O(substep).
    assert np.median(diffs) < 1e-5
    assert np.percentile(diffs, 95) < 1e-3


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"state": np.zeros(6)}, "state"),
    ({"state": np.r_[np.zeros(6), np.nan]}, "state"),
    ({"pusher_start": [0.0, np.inf]}, "pusher_start"),
    ({"pusher_end": [0.0, 0.0, 0.0]}, "pusher_end"),
    ({"substep": 0.0}, "substep"),
    ({"pusher_radius": -1e-3}, "pusher_radius"),
    ({"outline": np.zeros((4, 2))}, "outline"),
])
def test_predict_push_rejects_bad_inputs(kwargs: dict, match: str) -> None:
    args = {"state": np.array([0, 0, 0, 0, 0, 0.03, 0.3]),
            "outline": ContactOutline.from_points(square(0.03)),
            "pusher_start": [-0.05, 0.0], "pusher_end": [0.0, 0.0]}
    args.update(kwargs)
    extra = {k: args.pop(k) for k in ("substep", "pusher_radius") if k in args}
    with pytest.raises(ValueError, match=match):
        predict_push(args["state"], args["outline"], args["pusher_start"], args["pusher_end"],
                     **extra)


def test_max_substeps_bounds_the_loop_and_leaves_shorter_pushes_bit_identical() -> None:
    outline = ContactOutline.from_points(square(0.03, 4))
    state = np.array([0.0, 0.0, 0.0, 0.004, -0.006, 0.03, 0.3])
    start, end = np.array([-0.04, 0.005]), np.array([0.01, 0.005])  # 5 cm: 50 substeps
    free = predict_push(state, outline, start, end, substep=1e-3)
    for bound in (50, 51, 1000):  # not binding: the same bits
        capped = predict_push(state, outline, start, end, substep=1e-3, max_substeps=bound)
        assert capped.n_substeps == 50
        np.testing.assert_array_equal(capped.state, free.state)
        np.testing.assert_array_equal(capped.jacobian, free.jacobian)
    capped = predict_push(state, outline, start, end, substep=1e-3, max_substeps=10)
    assert capped.n_substeps == 10  # ten equal 5 mm substeps
    coarse = predict_push(state, outline, start, end, substep=5e-3)
    np.testing.assert_allclose(capped.state, coarse.state, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="max_substeps"):
        predict_push(state, outline, start, end, max_substeps=0)
    # The filter takes the bound from its config; the default never binds on a 1 m push.
    assert EKFConfig().max_substeps * EKFConfig().substep >= 1.0
    ekf = square_ekf(max_substeps=3)
    ekf.update_pose([0.0, 0.0, 0.0])
    assert ekf.predict_push([-0.5, 0.0], [0.5, 0.0]).n_substeps == 3
    for bad in (0, 10**6 + 1, 1.5, True, math.nan):
        with pytest.raises(ValueError, match="max_substeps"):
            EKFConfig(max_substeps=bad)


# --------------------------------------------------------------------------------------------
# The filter
# --------------------------------------------------------------------------------------------
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


def test_most_informative_push_prefers_a_push_that_touches() -> None:
    points, normals = library_outline("butter")
    ekf = PushEKF(points, normals)
    ekf.update_pose([0.0, 0.0, 0.0])
    rng = np.random.default_rng(4)
    touching = active.informative_push(points, normals, ekf.state[:3], rng)
    far = tuple(np.asarray(q) + [0.3, 0.0] for q in touching)  # the same push, 30 cm away
    assert active.most_informative_push(ekf, [far, touching]) == 1
    assert active.most_informative_push(ekf, [touching, far]) == 0
    with pytest.raises(ValueError, match="empty"):
        active.most_informative_push(ekf, [])


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


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"substep": 0.0}, "substep"),
    ({"pusher_radius": -0.001}, "pusher_radius"),
    ({"m_range": (0.5, 0.1)}, "m_range"),
    ({"m_init": 2.0}, "m_init"),
    ({"gate_probability": 0.0}, "gate_probability"),
    ({"gate_probability": 1.5}, "gate_probability"),
    ({"symmetry_order": -1}, "symmetry_order"),
    ({"symmetry_order": 1.5}, "symmetry_order"),
    ({"com_noise": float("nan")}, "com_noise"),
    ({"l_min_fraction": 1.0}, "l_min_fraction"),
])
def test_bad_config_raises_naming_the_field(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        EKFConfig(**kwargs)


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
