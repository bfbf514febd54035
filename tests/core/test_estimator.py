"""push_core.estimator (the facade re-exporting the estimator's parts): outline geometry, the
process model and its Jacobian through the names the estimator's users import (the filter
itself: test_ekf.py; its settings: test_estimator_config.py; the active push choice:
test_active.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator import (
    ContactOutline,
    EKFConfig,
    PushEKF,
    active,
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
    import push_core.estimator.contact as estimator

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
    # The pushing model (docs/design/pushing-model.md) with r' = (-0.03, 0.01),
    # l^2 = 9e-4, D = l^2 + r'^2 = 1.9e-3:
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
    ekf = PushEKF(square(0.03, 10), config=EKFConfig(max_substeps=3))
    ekf.update_pose([0.0, 0.0, 0.0])
    assert ekf.predict_push([-0.5, 0.0], [0.5, 0.0]).n_substeps == 3
    for bad in (0, 10**6 + 1, 1.5, True, math.nan):
        with pytest.raises(ValueError, match="max_substeps"):
            EKFConfig(max_substeps=bad)
