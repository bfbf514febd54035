"""Unit tests of push_core.model: the analytical pushing model (Lynch et al. 1992)."""

import numpy as np
import pytest
import torch

from push_core.model import (
    ALPHA_MIN,
    L_MAX,
    L_MIN,
    apply_twist,
    predict_motion,
    push_twist,
    representative_pushes,
)

# Hand-worked example used by several tests (all lengths in metres):
#   COM c = (0.01, -0.01), contact r = (-0.04, 0.01)  =>  r' = r - c = (-0.05, 0.02)
#   normal into the object n = (1, 0), l = 0.05 (l^2 = 0.0025), m = 0.5.
#   alpha = atan(0.5): cos = 2/sqrt5, sin = 1/sqrt5.
#   f_r = R(+alpha) n = (2, 1)/sqrt5, tau_r = r'x f_ry - r'y f_rx = (-0.05 - 0.04)/sqrt5
#       = -0.09/sqrt5; v_pr = l^2 f_r + tau_r (-r'y, r'x)
#       = [(0.005, 0.0025) - 0.09 (-0.02, -0.05)]/sqrt5 = (0.0068, 0.0070)/sqrt5 ~ (34, 35).
#   f_l = R(-alpha) n = (2, -1)/sqrt5, tau_l = (0.05 - 0.04)/sqrt5 = 0.01/sqrt5;
#       v_pl = [(0.005, -0.0025) + 0.01 (-0.02, -0.05)]/sqrt5 = (0.0048, -0.0030)/sqrt5 ~ (8, -5).
#   D = l^2 + r'x^2 + r'y^2 = 0.0025 + 0.0025 + 0.0004 = 0.0054.
COM = np.array([0.01, -0.01])
CONTACT = np.array([-0.04, 0.01])
R_PRIME = CONTACT - COM
N_IN = np.array([1.0, 0.0])
L, M = 0.05, 0.5
V_PR = np.array([34.0, 35.0])
V_PL = np.array([8.0, -5.0])


def contact_velocity(twist: np.ndarray, r_prime: np.ndarray) -> np.ndarray:
    """Rigid-body displacement of the contact point: v_o + omega k x r'."""
    omega = twist[..., 2:3]
    return twist[..., :2] + omega * np.stack([-r_prime[..., 1], r_prime[..., 0]], -1)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def rotate(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], -1)


def random_problems(seed: int, n: int = 500) -> dict:
    """Random pushes on random contacts; normals into the object, l and m inside the clamps."""
    rng = np.random.default_rng(seed)
    phi = rng.uniform(-np.pi, np.pi, n)
    return {
        "push": rng.normal(scale=0.01, size=(n, 2)),
        "contact": rng.uniform(-0.08, 0.08, size=(n, 2)),
        "normal_in": np.stack([np.cos(phi), np.sin(phi)], -1) * rng.uniform(0.5, 2.0, (n, 1)),
        "com": rng.uniform(-0.02, 0.02, size=(n, 2)),
        "l": rng.uniform(0.01, 0.1, n),
        "m": rng.uniform(0.05, 2.0, n),
    }


# ---------------------------------------------------------------- hand-derived values


def test_push_through_com_along_normal_translates():
    # r' parallel to n: tau_b = r' x R(+-alpha) n = +-|r'| sin(alpha) (r' antiparallel to n)
    # and v_p(n) = l^2 n, so the cone is symmetric about n and v_u = s n sticks. Stage 2 with
    # r' = -rho n and v_p = s n: v_o = s n (the r'r'^T terms reproduce n), omega = r' x v_o/l^2 = 0.
    rng = np.random.default_rng(10)
    phi = rng.uniform(-np.pi, np.pi, 50)
    n = np.stack([np.cos(phi), np.sin(phi)], -1)
    com = rng.uniform(-0.02, 0.02, (50, 2))
    contact = com - rng.uniform(0.01, 0.1, (50, 1)) * n
    step = rng.uniform(1e-4, 0.05, (50, 1))
    twist = push_twist(step * n, contact, n, com, 0.04, rng.uniform(0.0, 2.0, 50))
    np.testing.assert_allclose(twist[:, :2], step * n, rtol=0, atol=1e-15)
    np.testing.assert_allclose(twist[:, 2], 0.0, atol=1e-13)


def test_off_centre_sticking_push_hand_value():
    # u = (0.01, 0) has slope 0 between the boundary slopes -5/8 and 35/34: sticking, v_p = u.
    # v_ox = (l^2 + r'x^2) v_px / D = 0.005 * 0.01 / 0.0054 = 1/108
    # v_oy = r'x r'y v_px / D = -0.001 * 0.01 / 0.0054 = -1/540
    # omega = (r'x v_oy - r'y v_ox) / l^2 = (0.05/540 - 0.02/108) / 0.0025 = -1/27 rad
    twist = push_twist([0.01, 0.0], CONTACT, N_IN, COM, L, M)
    np.testing.assert_allclose(twist, [1 / 108, -1 / 540, -1 / 27], rtol=1e-12)
    np.testing.assert_allclose(contact_velocity(twist, R_PRIME), [0.01, 0.0], atol=1e-15)


def test_off_centre_sliding_push_hand_value():
    # u = (0.01, 0.05) has slope 5 > 35/34: slides on the f_r boundary,
    # v_p = (u . n) / (v_pr . n) v_pr = 0.01 (1, 35/34).
    # omega = (r'x v_py - r'y v_px) / D (stage 2 simplified)
    #       = -0.01 (0.05 * 35/34 + 0.02) / 0.0054 = -0.0243 / 0.1836 = -0.132352941...
    twist = push_twist([0.01, 0.05], CONTACT, N_IN, COM, L, M)
    np.testing.assert_allclose(contact_velocity(twist, R_PRIME), [0.01, 0.01 * 35 / 34],
                               rtol=1e-12)
    np.testing.assert_allclose(twist[2], -0.0243 / 0.1836, rtol=1e-12)


def test_motion_cone_boundary_sticking_sliding_and_continuity():
    eps = 1e-7
    r_hat, l_hat = V_PR / np.linalg.norm(V_PR), V_PL / np.linalg.norm(V_PL)
    for boundary, outward in ((r_hat, +1.0), (l_hat, -1.0)):
        u_in = 0.01 * rotate(boundary, -outward * eps)  # towards n: inside the cone
        u_out = 0.01 * rotate(boundary, outward * eps)  # away from n: outside
        t_in = push_twist(u_in, CONTACT, N_IN, COM, L, M)
        t_out = push_twist(u_out, CONTACT, N_IN, COM, L, M)
        # Sticking: the contact point moves with the pusher.
        np.testing.assert_allclose(contact_velocity(t_in, R_PRIME), u_in, rtol=1e-12, atol=0)
        # Sliding: it moves along the boundary with the pusher's normal component.
        v_out = contact_velocity(t_out, R_PRIME)
        assert abs(cross(v_out, boundary)) < 1e-17
        np.testing.assert_allclose(v_out @ N_IN, u_out @ N_IN, rtol=1e-12)
        assert np.linalg.norm(v_out - u_out) > 1e-10  # not the sticking answer
        # Continuity: an O(eps) change of the push changes the twist by O(eps).
        assert np.max(np.abs(t_in - t_out)) < 10 * eps * 0.01 / L


def test_vanishing_friction_gives_a_normal_force_only():
    # With m -> 0 the force is f = k n: v_o = l^2 k n (parallel to n), omega = k tau with
    # tau = r' x n = r'x ny - r'y nx = -0.02, and v_p . n = u . n gives
    # k (l^2 + tau^2) = 0.01, i.e. twist = 0.01 (l^2, 0, tau) / (l^2 + tau^2)
    #   = 0.01 (0.0025, 0, -0.02) / 0.0029.
    # atan(m) is clamped to 0.1 deg: the force may tilt by delta <= 0.1 deg (tan = 1.75e-3), which
    # changes tau by <= |r'| sin(delta) = 0.054 * 1.75e-3 ~ 0.5 % of |tau|, hence rtol 1 %.
    expected = 0.01 * np.array([0.0025, 0.0, -0.02]) / 0.0029
    for u in ([0.01, 0.0], [0.01, 0.03], [0.01, -0.03]):
        twist = push_twist(u, CONTACT, N_IN, COM, L, 0.0)
        np.testing.assert_allclose(twist, expected, rtol=0, atol=0.01 * np.abs(expected).max())
        np.testing.assert_allclose(twist[[0, 2]], expected[[0, 2]], rtol=0.01)
        # The COM moves along the force: within 0.1 deg of the normal.
        assert abs(twist[1]) <= np.tan(ALPHA_MIN) * twist[0] * (1 + 1e-9)


def test_clamping_of_l_and_friction():
    big_l = push_twist([0.01, 0.0], CONTACT, N_IN, COM, 10.0, M)
    np.testing.assert_array_equal(big_l, push_twist([0.01, 0.0], CONTACT, N_IN, COM, L_MAX, M))
    small_l = push_twist([0.01, 0.0], CONTACT, N_IN, COM, 0.0, M)
    np.testing.assert_array_equal(small_l, push_twist([0.01, 0.0], CONTACT, N_IN, COM, L_MIN, M))
    assert np.all(np.isfinite(small_l))
    negative_m = push_twist([0.01, 0.03], CONTACT, N_IN, COM, L, -1.0)
    np.testing.assert_array_equal(negative_m, push_twist([0.01, 0.03], CONTACT, N_IN, COM, L, 0.0))


def test_zero_outputs_are_exact():
    p = random_problems(11, 200)
    zero_normal = push_twist(p["push"], p["contact"], 0.0 * p["normal_in"], p["com"], p["l"],
                             p["m"])
    assert np.all(zero_normal == 0.0)
    no_contact = push_twist(**p, contact_indicator=0.0)
    assert np.all(no_contact == 0.0)
    n = p["normal_in"]
    away = -np.abs(np.sum(p["push"] * n, -1, keepdims=True)) * n / np.sum(n * n, -1, keepdims=True)
    tangent = np.stack([-n[:, 1], n[:, 0]], -1)
    twist = push_twist(away + tangent * 0.01, p["contact"], n, p["com"], p["l"], p["m"])
    assert np.all(twist == 0.0)
    # Exactly tangential pushes (u . n = 0 in floating point) do not push either.
    grazing = push_twist([[0.0, 0.01], [0.0, -0.01], [0.01, 0.0]], CONTACT,
                         [[2.0, 0.0], [1.0, 0.0], [0.0, -1.0]], COM, L, M)
    assert np.all(grazing == 0.0)


def test_contact_indicator_scales_linearly():
    p = random_problems(12, 100)
    np.testing.assert_allclose(push_twist(**p, contact_indicator=0.25), 0.25 * push_twist(**p),
                               rtol=1e-14, atol=1e-18)


def test_normal_is_normalised():
    p = random_problems(13, 100)
    scaled = dict(p, normal_in=p["normal_in"] * 1e3)
    np.testing.assert_allclose(push_twist(**scaled), push_twist(**p), rtol=1e-12, atol=1e-17)


# ---------------------------------------------------------------- symmetries and invariants


def test_mirror_symmetry_across_x_axis():
    p = random_problems(14)
    flip = np.array([1.0, -1.0])
    mirrored = {k: (v * flip if np.ndim(v) == 2 else v) for k, v in p.items()}
    np.testing.assert_allclose(push_twist(**mirrored), push_twist(**p) * [1.0, -1.0, -1.0],
                               rtol=1e-12, atol=1e-17)


@pytest.mark.parametrize("angle", [0.3, -2.0, np.pi / 2, 3.0])
def test_rotating_the_problem_rotates_the_answer(angle):
    p = random_problems(15)
    rotated = {k: (rotate(v, angle) if np.ndim(v) == 2 else v) for k, v in p.items()}
    twist, twist_rot = push_twist(**p), push_twist(**rotated)
    np.testing.assert_allclose(twist_rot[:, :2], rotate(twist[:, :2], angle), rtol=0, atol=1e-15)
    np.testing.assert_allclose(twist_rot[:, 2], twist[:, 2], rtol=0, atol=1e-13)


def test_random_problems_obey_the_modes():
    # Every output either sticks (contact point moves with the pusher) or slides with the
    # pusher's normal component, and the COM moves along the contact force: r' x v_o = l^2 omega.
    p = random_problems(16, 2000)
    twist = push_twist(**p)
    n = p["normal_in"] / np.linalg.norm(p["normal_in"], axis=-1, keepdims=True)
    r_prime = p["contact"] - p["com"]
    u_n = np.sum(p["push"] * n, -1)
    v = contact_velocity(twist, r_prime)
    pushing = u_n > 0
    assert 0.2 < pushing.mean() < 0.8
    np.testing.assert_allclose(np.sum(v * n, -1)[pushing], u_n[pushing], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(cross(r_prime, twist[:, :2]), p["l"] ** 2 * twist[:, 2],
                               rtol=1e-9, atol=1e-15)
    sticks = np.all(np.isclose(v, p["push"], rtol=1e-9, atol=1e-15), axis=-1)
    assert 0.1 < sticks[pushing].mean() < 0.9  # both modes are exercised
    # Coulomb friction: the contact force f is parallel to v_o (ellipsoidal limit surface).
    # Sticking: f inside the friction cone, |f . t| <= m f . n. Sliding: f on the cone edge,
    # |f . t| = m f . n, pulled by the pusher, i.e. f . t has the sign of the slip (u - v) . t.
    tangent = np.stack([-n[:, 1], n[:, 0]], -1)
    f_n, f_t = np.sum(twist[:, :2] * n, -1), np.sum(twist[:, :2] * tangent, -1)
    stick, slide = pushing & sticks, pushing & ~sticks
    assert np.all(f_n[pushing] > 0)
    assert np.all(np.abs(f_t[stick]) <= p["m"][stick] * f_n[stick] * (1 + 1e-9))
    np.testing.assert_allclose(np.abs(f_t[slide]), p["m"][slide] * f_n[slide], rtol=1e-9)
    slip = np.sum((p["push"] - v) * tangent, -1)
    np.testing.assert_array_equal(np.sign(f_t[slide]), np.sign(slip[slide]))


def test_broadcasting_over_leading_dimensions():
    rng = np.random.default_rng(17)
    pushes = rng.normal(scale=0.01, size=(1, 7, 2))
    contact = rng.uniform(-0.05, 0.05, size=(5, 1, 2))
    m = rng.uniform(0.1, 1, (5, 1))
    out = push_twist(pushes, contact, [1.0, 0.0], [0.0, 0.0], 0.04, m)
    assert out.shape == (5, 7, 3)
    single = push_twist(pushes[0, 3], contact[2, 0], [1.0, 0.0], [0.0, 0.0], 0.04, m[2, 0])
    assert single.shape == (3,)
    np.testing.assert_array_equal(single, out[2, 3])


def test_shape_errors_name_the_argument():
    with pytest.raises(ValueError, match=r"normal_in must have shape \(\.\.\., 2\)"):
        push_twist([0.01, 0.0], CONTACT, [1.0, 0.0, 0.0], COM, L, M)
    with pytest.raises(ValueError, match=r"twist_obj must have shape \(\.\.\., 3\)"):
        apply_twist([0.0, 0.0, 0.0], [0.0, 0.0], COM)
    with pytest.raises(ValueError, match=r"pushes must have shape \(M, 2\) or \(N, M, 2\)"):
        predict_motion(np.zeros((4, 2)), np.ones((4, 2)), np.zeros((3, 5, 2)), COM, L, M)
    with pytest.raises(ValueError, match=r"points and normals_out must both have shape \(N, 2\)"):
        predict_motion(np.zeros((4, 2)), np.ones((3, 2)), np.zeros((5, 2)), COM, L, M)


# ---------------------------------------------------------------- numpy versus torch


def test_numpy_and_torch_agree():
    p = random_problems(18, 1000)
    p["normal_in"][:10] = 0.0  # zero normals
    indicator = np.random.default_rng(18).uniform(0, 1, 1000)
    expected = push_twist(**p, contact_indicator=indicator)
    out = push_twist(**{k: torch.tensor(v) for k, v in p.items()},
                     contact_indicator=torch.tensor(indicator))
    assert isinstance(out, torch.Tensor) and out.dtype == torch.float64
    np.testing.assert_allclose(out.numpy(), expected, rtol=1e-12, atol=1e-18)
    # Mixed inputs: one tensor makes the whole computation torch.
    mixed = push_twist(torch.tensor(p["push"]), p["contact"], p["normal_in"], p["com"], p["l"],
                       p["m"])
    assert isinstance(mixed, torch.Tensor)
    np.testing.assert_allclose(mixed.numpy(), push_twist(**p), rtol=1e-12, atol=1e-18)


def test_torch_gradients_match_finite_differences():
    # Problems well inside one contact mode, so the central differences do not cross a kink.
    p = random_problems(19, 40)
    u = p["push"]
    n = p["normal_in"]
    p["push"] = np.where(np.sum(u * n, -1, keepdims=True) > 0, u, -u)  # all pushing
    inputs = tuple(torch.tensor(p[k], requires_grad=True)
                   for k in ("push", "contact", "normal_in", "com", "l", "m"))
    assert torch.autograd.gradcheck(push_twist, inputs, eps=1e-7, atol=1e-7, rtol=1e-5)


def test_torch_gradients_are_finite_for_degenerate_inputs():
    p = random_problems(20, 300)
    p["normal_in"][:50] = 0.0  # zero normals (the sqrt and the division are guarded)
    p["push"][50:100] = 0.0  # zero pushes: u . n = 0
    p["l"][100:150] = 0.0  # l clamped
    inputs = {k: torch.tensor(v, requires_grad=True) for k, v in p.items()}
    push_twist(**inputs).sum().backward()
    for name, t in inputs.items():
        assert torch.all(torch.isfinite(t.grad)), name
    assert torch.all(inputs["push"].grad[:50] == 0.0)


def test_jacfwd_through_predict_motion_matches_finite_differences():
    # The EKF use: derivative of the one-step motion with respect to (c, l, m).
    points = np.array([[-0.05, 0.02], [0.01, -0.05], [0.05, 0.03]])
    normals = np.array([[-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]])
    pushes = representative_pushes(normals)[:, :5]
    theta0 = np.array([0.004, -0.006, 0.045, 0.4])  # c_x, c_y, l, m

    def f(theta):
        return predict_motion(points, normals, pushes, theta[:2], theta[2], theta[3])

    jac = torch.func.jacfwd(f)(torch.tensor(theta0))
    assert jac.shape == (3, 5, 3, 4)
    h = 1e-7
    fd = np.stack([(f(theta0 + h * e) - f(theta0 - h * e)) / (2 * h) for e in np.eye(4)], -1)
    assert np.linalg.norm(fd) > 1e-3  # the derivative is not trivially zero
    np.testing.assert_allclose(jac.numpy(), fd, rtol=1e-5, atol=1e-8)


# ---------------------------------------------------------------- apply_twist, affordances


def test_apply_twist_hand_values():
    # Translation along the object x axis, which is the world y axis at theta = pi/2.
    np.testing.assert_allclose(apply_twist([1.0, 2.0, np.pi / 2], [0.01, 0.0, 0.0], [0.1, 0.0]),
                               [1.0, 2.01, np.pi / 2], atol=1e-15)
    # Quarter turn about the COM (0.1, 0) from the identity pose: the COM stays at (0.1, 0),
    # the origin ends at COM - R(pi/2) c = (0.1, 0) - (0, 0.1) = (0.1, -0.1).
    np.testing.assert_allclose(apply_twist([0.0, 0.0, 0.0], [0.0, 0.0, np.pi / 2], [0.1, 0.0]),
                               [0.1, -0.1, np.pi / 2], atol=1e-15)


def test_apply_twist_moves_the_com_by_the_rotated_twist():
    rng = np.random.default_rng(22)
    pose = rng.uniform(-1, 1, (50, 3)) * [1, 1, 4]
    twist = rng.normal(scale=0.05, size=(50, 3))
    com = rng.uniform(-0.03, 0.03, (50, 2))

    def com_world(q):
        return q[:, :2] + rotate(com, q[:, 2])

    new = apply_twist(pose, twist, com)
    np.testing.assert_allclose(new[:, 2], pose[:, 2] + twist[:, 2], atol=1e-15)  # not wrapped
    np.testing.assert_allclose(com_world(new) - com_world(pose), rotate(twist[:, :2], pose[:, 2]),
                               atol=1e-15)
    torch_new = apply_twist(torch.tensor(pose), torch.tensor(twist), torch.tensor(com))
    np.testing.assert_allclose(torch_new.numpy(), new, rtol=0, atol=1e-15)


def test_representative_pushes_hand_values():
    # Bottom face: outward normal (0, -1), inward (0, 1). R(30 deg) (0, 1) = (-1/2, sqrt3/2).
    pushes = representative_pushes(np.array([[0.0, -2.0]]))  # normalised inside
    assert pushes.shape == (1, 10, 2)
    s3 = np.sqrt(3) / 2
    expected_dirs = [[0, 1], [-0.5, s3], [0.5, s3], [-s3, 0.5], [s3, 0.5]]
    np.testing.assert_allclose(pushes[0, :5], 0.01 * np.array(expected_dirs), atol=1e-17)
    np.testing.assert_allclose(pushes[0, 5:], 0.05 * np.array(expected_dirs), atol=1e-17)
    assert np.all(representative_pushes(np.zeros((2, 2))) == 0.0)


def test_predict_motion_of_the_origin():
    # One contact (the hand example) and the sticking push u = (0.01, 0): the COM twist is
    # (1/108, -1/540, -1/27); the origin moves by c + v_c - R(dtheta) c (object frame).
    motion = predict_motion(CONTACT[None], -N_IN[None], np.array([[0.01, 0.0]]), COM, L, M)
    assert motion.shape == (1, 1, 3)
    v_c, dtheta = np.array([1 / 108, -1 / 540]), -1 / 27
    np.testing.assert_allclose(motion[0, 0, :2], COM + v_c - rotate(COM, dtheta), rtol=1e-12)
    np.testing.assert_allclose(motion[0, 0, 2], dtheta, rtol=1e-12)


def test_predict_motion_shared_and_per_point_pushes_agree():
    rng = np.random.default_rng(23)
    phi = rng.uniform(-np.pi, np.pi, 30)
    normals = np.stack([np.cos(phi), np.sin(phi)], -1)
    points = 0.05 * normals
    pushes = rng.normal(scale=0.02, size=(10, 2))
    shared = predict_motion(points, normals, pushes, [0.005, 0.0], 0.04, 0.3)
    per_point = predict_motion(points, normals, np.broadcast_to(pushes, (30, 10, 2)),
                               [0.005, 0.0], 0.04, 0.3)
    assert shared.shape == (30, 10, 3)
    np.testing.assert_array_equal(shared, per_point)
    # Each entry is push_twist followed by apply_twist from the identity pose.
    twist = push_twist(pushes[3], points[7], -normals[7], [0.005, 0.0], 0.04, 0.3)
    np.testing.assert_allclose(shared[7, 3], apply_twist(np.zeros(3), twist, [0.005, 0.0]),
                               rtol=0, atol=1e-18)
    # Torch path agrees.
    torch_out = predict_motion(torch.tensor(points), torch.tensor(normals), torch.tensor(pushes),
                               torch.tensor([0.005, 0.0], dtype=torch.float64), 0.04, 0.3)
    np.testing.assert_allclose(torch_out.numpy(), shared, rtol=0, atol=1e-15)
