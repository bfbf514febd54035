"""The push EKF's process model: one straight push, with its closed-form Jacobian.

ROS-free; SI units, state as in :mod:`push_core.estimator.config`. :func:`predict_push` is the
analytical pushing model (:mod:`push_core.model`) driven by the executed
straight push (pusher axis from ``pusher_start`` to ``pusher_end`` in ``world``), integrated in
substeps of at most ``substep`` (a push no longer than one substep is a single model step;
``max_substeps`` bounds the loop: a longer push is split into that many equal substeps).
Every substep finds the contact on the *decimated* outline polygon
(:class:`push_core.estimator.contact.ContactOutline`) the way
:func:`push_core.rollout.rollout_push` does (closest outline feature to the pusher centre at the
substep start, contact test ``approach > 0`` and ``gap - approach <= contact_tol``), with one
refinement: when the pusher closes a gap inside the substep, the contact point is taken where it
touches (not at the substep start) and only the rest of the substep pushes. ``c``, ``l`` and ``m``
do not change in the prediction; they are slowly varying parameters with a random walk per push
(the filter's process noise).

Jacobian: closed form. The substep model is written out in scalar arithmetic together with its
partial derivatives (the contact point and normal on the touched segment or vertex as functions
of the pose, the touch fraction, both contact modes of the motion cone, the twist about the COM
and its application to the pose) and chained over the substeps. It runs on Python floats,
written out per component, because numpy calls on 2-vectors cost more than the arithmetic
(timings: ``docs/results/bench_estimator.md``). Tests check it against central finite
differences and the model part against ``torch.func.jacfwd`` through
:func:`push_core.model.push_twist`; the values equal ``push_twist`` / ``apply_twist`` to
rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.estimator.config import STATE_SIZE, finite_vector
from push_core.estimator.contact import ContactOutline
from push_core.model import ALPHA_MAX, ALPHA_MIN, L_MAX, L_MIN
from push_core.rollout import CONTACT_TOL, PUSHER_RADIUS

__all__ = ["PushPrediction", "predict_push"]

#: Below this distance (m) of the pusher centre from a vertex, use the segment's normal.
_VERTEX_EPS = 1e-12
_EYE_7 = np.eye(STATE_SIZE)
_EYE_3x7_ROWS = np.eye(3, STATE_SIZE).tolist()


@dataclass(frozen=True)
class PushPrediction:
    """What :func:`predict_push` returns.

    Attributes
    ----------
    state : numpy.ndarray, shape (7,)
        Predicted state (only the pose changes).
    jacobian : numpy.ndarray, shape (7, 7) or None
        ``d state / d previous state``; None when not requested.
    touched : bool
        Whether the pusher touched the object in any substep.
    contact_length : float
        Pusher travel in contact, m.
    n_substeps : int
        Model steps the push was split into.
    """

    state: NDArray[np.float64]
    jacobian: NDArray[np.float64] | None
    touched: bool
    contact_length: float
    n_substeps: int


def _twist_with_jacobian(ux: float, uy: float, rx: float, ry: float, nx: float, ny: float,
                         cx: float, cy: float, l: float, m: float,  # noqa: E741
                         jacobian: bool) -> tuple[float, float, float, tuple | None]:
    """:func:`push_core.model.push_twist` for one push, with its Jacobian.

    The same arithmetic and branches as ``push_twist`` on Python floats (a tiny problem: numpy's
    per-call overhead would dominate). ``n`` must be a unit vector pointing into the object.
    Returns ``(v_ox, v_oy, omega, J)`` with ``J`` the (3, 10) matrix d twist / d (u_x, u_y,
    r_x, r_y, n_x, n_y, c_x, c_y, l, m) as three row tuples, None if not requested. The
    columns for ``n`` omit the derivative of the model's normalisation: they are exact for
    changes of ``n`` tangent to the unit circle, the only ones a unit normal can make.
    """
    dl = 1.0 if L_MIN <= l <= L_MAX else 0.0
    l = min(max(l, L_MIN), L_MAX)  # noqa: E741
    alpha = math.atan(m)
    dalpha = 1.0 / (1.0 + m * m) if ALPHA_MIN <= alpha <= ALPHA_MAX else 0.0
    alpha = min(max(alpha, ALPHA_MIN), ALPHA_MAX)
    u_n = ux * nx + uy * ny
    if u_n <= 0.0:  # the pusher leaves the surface
        return 0.0, 0.0, 0.0, (((0.0,) * 10,) * 3 if jacobian else None)
    px, py = rx - cx, ry - cy  # r' = r - c
    l2 = l * l
    ca, sa = math.cos(alpha), math.sin(alpha)

    def boundary(sigma: float) -> tuple[float, ...]:
        # f = R(sigma alpha) n, tau = r' x f, v_b = l^2 f + tau (k x r'), and v_b . n
        fx, fy = ca * nx - sigma * sa * ny, sigma * sa * nx + ca * ny
        tau = px * fy - py * fx
        vx, vy = l2 * fx - tau * py, l2 * fy + tau * px
        return fx, fy, tau, vx, vy, vx * nx + vy * ny

    sigma, b = 0.0, ()
    b_r = boundary(1.0)
    if b_r[5] > 0.0 and b_r[3] * uy - b_r[4] * ux > 0.0:
        sigma, b = 1.0, b_r
    else:
        b_l = boundary(-1.0)
        if b_l[5] > 0.0 and ux * b_l[4] - uy * b_l[3] > 0.0:
            sigma, b = -1.0, b_l
    if sigma:  # sliding along boundary b
        k = u_n / b[5]
        vpx, vpy = k * b[3], k * b[4]
    else:  # sticking
        vpx, vpy = ux, uy

    rxx, ryy, rxy = px * px, py * py, px * py
    d = l2 + rxx + ryy
    vox = ((l2 + rxx) * vpx + rxy * vpy) / d
    voy = ((l2 + ryy) * vpy + rxy * vpx) / d
    omega = (px * voy - py * vox) / l2
    if not jacobian:
        return vox, voy, omega, None

    # d v_p / d X with X = (u_x, u_y, p_x, p_y, n_x, n_y, l, alpha), p = r' = r - c.
    if sigma:
        fx, fy, tau, vx, vy, v_n = b
        # d v_b / d f = [[l^2 + p_y^2, -p_x p_y], [-p_x p_y, l^2 + p_x^2]];
        # d f / d n = R(sigma alpha); d f / d alpha = sigma (-f_y, f_x).
        m00, m01, m11 = l2 + ryy, -rxy, l2 + rxx
        r01, r10 = -sigma * sa, sigma * sa
        gx, gy = -sigma * fy, sigma * fx
        # d v_b / d X (zero for u), components p_x, p_y, n_x, n_y, l, alpha
        b0p, b0q, b0nx, b0ny, b0l, b0a = (-fy * py, fx * py - tau, m00 * ca + m01 * r10,
                                          m00 * r01 + m01 * ca, 2.0 * l * fx,
                                          m00 * gx + m01 * gy)
        b1p, b1q, b1nx, b1ny, b1l, b1a = (fy * px + tau, -fx * px, m01 * ca + m11 * r10,
                                          m01 * r01 + m11 * ca, 2.0 * l * fy,
                                          m01 * gx + m11 * gy)
        # k = (u . n) / (v_b . n): d k = (d(u . n) - k (n . d v_b + v_b . d n)) / (v_b . n)
        inv, mk = 1.0 / v_n, -k / v_n
        k_ux, k_uy = nx * inv, ny * inv
        k_px, k_py = mk * (nx * b0p + ny * b1p), mk * (nx * b0q + ny * b1q)
        k_nx = ux * inv + mk * (nx * b0nx + ny * b1nx + vx)
        k_ny = uy * inv + mk * (nx * b0ny + ny * b1ny + vy)
        k_l, k_a = mk * (nx * b0l + ny * b1l), mk * (nx * b0a + ny * b1a)
        # v_p = k v_b
        dvp0 = (vx * k_ux, vx * k_uy, k * b0p + vx * k_px, k * b0q + vx * k_py,
                k * b0nx + vx * k_nx, k * b0ny + vx * k_ny, k * b0l + vx * k_l,
                k * b0a + vx * k_a)
        dvp1 = (vy * k_ux, vy * k_uy, k * b1p + vy * k_px, k * b1q + vy * k_py,
                k * b1nx + vy * k_nx, k * b1ny + vy * k_ny, k * b1l + vy * k_l,
                k * b1a + vy * k_a)
    else:
        dvp0 = dvp1 = None  # sticking: v_p = u, d v_p / d X selects u

    # Stage 2: (v_o, omega) = f(v_p, p, l); partials w.r.t. v_p and directly w.r.t. p and l.
    a00, a01, a11 = (l2 + rxx) / d, rxy / d, (l2 + ryy) / d
    w0, w1 = (px * a01 - py * a00) / l2, (px * a11 - py * a01) / l2
    x_px = (2.0 * px * vpx + py * vpy - 2.0 * px * vox) / d
    x_py = (px * vpy - 2.0 * py * vox) / d
    y_px = (py * vpx - 2.0 * px * voy) / d
    y_py = (2.0 * py * vpy + px * vpx - 2.0 * py * voy) / d
    x_l = 2.0 * l * (vpx - vox) / d
    y_l = 2.0 * l * (vpy - voy) / d
    w_px = (voy + px * y_px - py * x_px) / l2
    w_py = (px * y_py - vox - py * x_py) / l2
    w_l = (px * y_l - py * x_l) / l2 - 2.0 * omega / l
    rows = []
    for c0, c1, d_px, d_py, d_l in ((a00, a01, x_px, x_py, x_l), (a01, a11, y_px, y_py, y_l),
                                    (w0, w1, w_px, w_py, w_l)):
        if dvp0 is None:
            t = (c0, c1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        else:
            t = [c0 * p + c1 * q for p, q in zip(dvp0, dvp1)]  # noqa: B905 (8 each)
        t2, t3 = t[2] + d_px, t[3] + d_py
        # columns u (2), r (2), n (2), c (2) = -r, l, m = alpha * d alpha / d m
        rows.append((t[0], t[1], t2, t3, t[4], t[5], -t2, -t3, (t[6] + d_l) * dl,
                     t[7] * dalpha))
    return vox, voy, omega, tuple(rows)


def _substep(pose: list[float], c: tuple[float, float], l: float, m: float,  # noqa: E741
             w: tuple[float, float], delta: tuple[float, float], outline: ContactOutline,
             pusher_radius: float, contact_tol: float,
             jacobian: bool) -> tuple[list[float], tuple | None, float]:
    """One model step: pusher centre ``w`` -> ``w + delta`` (world) against the outline.

    Returns the new pose ``[x, y, theta]``, ``G`` (3, 7) = d new pose / d (x, y, theta, c_x,
    c_y, l, m) at the substep start as three row lists (None if not requested or without
    contact) and the pusher
    travel in contact (m). Contact as in :func:`push_core.rollout.rollout_push`, with the
    contact point taken where the pusher touches when it closes a gap within the substep.
    """
    px, py, th = pose
    ct, st = math.cos(th), math.sin(th)
    wx, wy = w[0] - px, w[1] - py
    qx, qy = ct * wx + st * wy, -st * wx + ct * wy  # pusher centre, object frame
    dx, dy = ct * delta[0] + st * delta[1], -st * delta[0] + ct * delta[1]

    kind, i = outline.closest_feature(qx, qy)
    ax, ay, ex, ey, nox, noy = outline._segments[i]
    if kind == 1:  # vertex v: outward normal sign (q - v) / |q - v|, signed distance sign |q - v|
        vx, vy = ax, ay
        sx, sy = qx - vx, qy - vy
        dist = math.hypot(sx, sy)
        if dist < _VERTEX_EPS:
            kind = 0
        else:
            sign = 1.0 if outline._convex[i] else -1.0
            nox, noy = sign * sx / dist, sign * sy / dist
            sd = sign * dist
    if kind == 0:  # interior of a segment
        sd = nox * (qx - ax) + noy * (qy - ay)
    gap = sd - pusher_radius  # clearance at the substep start
    approach = -(dx * nox + dy * noy)  # motion into the surface over the substep
    if not (approach > 0.0 and gap - approach <= contact_tol):
        return [px, py, th], None, 0.0
    t0 = gap / approach if gap > 0.0 else 0.0  # fraction of the substep before the touch
    if t0 >= 1.0:
        return [px, py, th], None, 0.0
    frac = 1.0 - t0
    tx, ty = qx + t0 * dx, qy + t0 * dy  # pusher centre at the touch
    if kind == 0:
        along = ex * (tx - ax) + ey * (ty - ay)
        rx, ry = ax + along * ex, ay + along * ey
        nix, niy = -nox, -noy
    else:
        rx, ry = vx, vy
        hx, hy = tx - vx, ty - vy
        dist_t = math.hypot(hx, hy)
        hx, hy = hx / dist_t, hy / dist_t
        nix, niy = -sign * hx, -sign * hy
    cx, cy = c
    vox, voy, omega, jt = _twist_with_jacobian(frac * dx, frac * dy, rx, ry, nix, niy, cx, cy,
                                               l, m, jacobian)

    # apply_twist (push_core.model): the COM moves by R(theta) v_o, the object turns about it.
    ox, oy = cx + vox, cy + voy
    th1 = th + omega
    c1, s1 = math.cos(th1), math.sin(th1)
    rcx, rcy = c1 * cx - s1 * cy, s1 * cx + c1 * cy  # R(theta1) c
    new = [px + ct * ox - st * oy - rcx, py + st * ox + ct * oy - rcy, th1]
    length = frac * math.hypot(dx, dy)
    if not jacobian:
        return new, None, length

    # Partials w.r.t. the pose (x, y, theta) at the substep start, written out per component
    # (suffix 0, 1, 2 = x, y, theta): loops and tuples over three numbers cost more than the
    # arithmetic.
    # q = R^T (w - p): dq/dp = -R^T, dq/dtheta = (q_y, -q_x); d = R^T delta: dd/dtheta = (d_y, -d_x)
    qx0, qx1, qx2 = -ct, -st, qy  # d q_x
    qy0, qy1, qy2 = st, -ct, -qx  # d q_y
    if t0 > 0.0:
        # t0 = gap / approach; gap = sd - r_p with d sd = n_out . dq; approach = -(d . n_out):
        # d t0 = (n_out . dq + t0 (n_out . dd + d . dn_out)) / approach
        a0 = nox * qx0 + noy * qy0
        a1 = nox * qx1 + noy * qy1
        a2 = nox * qx2 + noy * qy2 + t0 * (nox * dy - noy * dx)
        if kind == 1:  # d n_out = sign (I - u u^T) dq / |q - v|, u = (q - v) / |q - v|
            ux_, uy_ = sx / dist, sy / dist
            f = t0 * sign / dist
            # t0 d . d n_out = bx . dq_x + by . dq_y
            bx = f * ((1.0 - ux_ * ux_) * dx - ux_ * uy_ * dy)
            by = f * ((1.0 - uy_ * uy_) * dy - ux_ * uy_ * dx)
            a0 += bx * qx0 + by * qy0
            a1 += bx * qx1 + by * qy1
            a2 += bx * qx2 + by * qy2
        t00, t01, t02 = a0 / approach, a1 / approach, a2 / approach  # d t0
    else:
        t00 = t01 = t02 = 0.0
    # touch point q_t = q + t0 d; pushed part u = (1 - t0) d
    tx0, tx1, tx2 = qx0 + dx * t00, qx1 + dx * t01, qx2 + t0 * dy + dx * t02
    ty0, ty1, ty2 = qy0 + dy * t00, qy1 + dy * t01, qy2 - t0 * dx + dy * t02
    ux0, ux1, ux2 = -dx * t00, -dx * t01, frac * dy - dx * t02
    uy0, uy1, uy2 = -dy * t00, -dy * t01, -frac * dx - dy * t02
    # d twist / d pose = J_u du + J_r dr + J_n dn (J: the model's Jacobian rows), written as
    # J_u du + ca za + cb zb per row
    if kind == 0:  # r = projection of q_t on the segment (dr = t t^T dq_t); n constant
        za0, za1, za2 = ex * tx0 + ey * ty0, ex * tx1 + ey * ty1, ex * tx2 + ey * ty2
        zb0 = zb1 = zb2 = 0.0
        coeffs = [(j[2] * ex + j[3] * ey, 0.0) for j in jt]
    else:  # r = v; n_in = -sign (q_t - v) / |q_t - v|: dn = f (I - h h^T) dq_t
        f = -sign / dist_t
        hxx, hxy, hyy = 1.0 - hx * hx, -hx * hy, 1.0 - hy * hy
        za0, za1, za2 = f * (hxx * tx0 + hxy * ty0), f * (hxx * tx1 + hxy * ty1), \
            f * (hxx * tx2 + hxy * ty2)
        zb0, zb1, zb2 = f * (hxy * tx0 + hyy * ty0), f * (hxy * tx1 + hyy * ty1), \
            f * (hxy * tx2 + hyy * ty2)
        coeffs = [(j[4], j[5]) for j in jt]
    rows = [[j[0] * ux0 + j[1] * uy0 + ca * za0 + cb * zb0,
             j[0] * ux1 + j[1] * uy1 + ca * za1 + cb * zb1,
             j[0] * ux2 + j[1] * uy2 + ca * za2 + cb * zb2, j[6], j[7], j[8], j[9]]
            for j, (ca, cb) in zip(jt, coeffs)]  # noqa: B905 (three rows each)
    # new pose = apply_twist(pose, twist, c): partials w.r.t. the twist (A) and directly
    d0, d1, d2 = rows
    s_c = s1 * cx + c1 * cy
    g0 = [ct * a - st * b + s_c * e for a, b, e in zip(d0, d1, d2)]  # noqa: B905 (7 each)
    g1 = [st * a + ct * b - rcx * e for a, b, e in zip(d0, d1, d2)]  # noqa: B905
    g2 = d2
    g0[0] += 1.0
    g0[2] += s_c - (st * ox + ct * oy)
    g0[3] += ct - c1
    g0[4] += s1 - st
    g1[1] += 1.0
    g1[2] += (ct * ox - st * oy) - rcx
    g1[3] += st - s1
    g1[4] += ct - c1
    g2[2] += 1.0
    return new, (g0, g1, g2), length


def predict_push(state: ArrayLike, outline: ContactOutline, pusher_start: ArrayLike,
                 pusher_end: ArrayLike, *, pusher_radius: float = PUSHER_RADIUS,
                 substep: float = 0.01, contact_tol: float = CONTACT_TOL,
                 jacobian: bool = True, max_substeps: int | None = None) -> PushPrediction:
    """The process model: the state after one straight push, with its Jacobian.

    Parameters
    ----------
    state : array_like, shape (7,)
        ``(x, y, theta, c_x, c_y, l, m)`` before the push (:mod:`push_core.estimator.config`).
    outline : ContactOutline
        The object's outline (object frame).
    pusher_start, pusher_end : array_like, shape (2,)
        Executed pusher axis positions at the start and end of the straight push, ``world``,
        metres.
    pusher_radius : float
        m.
    substep : float
        Longest model step, m.
    contact_tol : float
        Contact test tolerance, m.
    jacobian : bool
        Also compute ``d new state / d state``.
    max_substeps : int, optional
        Bound on the model steps of one push (bounded work per push): a push that needs more
        substeps of ``substep`` is integrated in ``max_substeps`` equal, longer substeps.
        None: unbounded.

    Returns
    -------
    PushPrediction

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, non-finite values, ``substep <= 0`` or a negative
        ``pusher_radius`` / ``contact_tol``.
    """
    x = finite_vector("state", state, STATE_SIZE)
    start = finite_vector("pusher_start", pusher_start, 2)
    end = finite_vector("pusher_end", pusher_end, 2)
    if not substep > 0.0:
        raise ValueError(f"substep must be > 0, got {substep!r}")
    if not pusher_radius >= 0.0:
        raise ValueError(f"pusher_radius must be >= 0, got {pusher_radius!r}")
    if not contact_tol >= 0.0:
        raise ValueError(f"contact_tol must be >= 0, got {contact_tol!r}")
    if max_substeps is not None and not (isinstance(max_substeps, int) and max_substeps >= 1):
        raise ValueError(f"max_substeps must be an integer >= 1 or None, got {max_substeps!r}")
    if not isinstance(outline, ContactOutline):
        raise ValueError(f"outline must be a ContactOutline, got {type(outline).__name__}")
    return _predict_push(x, outline, start, end, pusher_radius, substep, contact_tol, jacobian,
                         max_substeps)


def _predict_push(x: NDArray[np.float64], outline: ContactOutline, start: NDArray[np.float64],
                  end: NDArray[np.float64], pusher_radius: float, substep: float,
                  contact_tol: float, jacobian: bool,
                  max_substeps: int | None = None) -> PushPrediction:
    """:func:`predict_push` without the input checks (the filter checks once)."""
    # Python floats throughout: numpy scalars would make every operation below slower.
    push = (float(end[0]) - float(start[0]), float(end[1]) - float(start[1]))
    total = math.hypot(push[0], push[1])
    n_sub = math.ceil(total / substep * (1.0 - 1e-12)) if total > 0.0 else 0
    pose = [float(x[0]), float(x[1]), float(x[2])]
    c = (float(x[3]), float(x[4]))
    l, m = float(x[5]), float(x[6])  # noqa: E741
    jp = _EYE_3x7_ROWS  # d pose / d initial state, three row lists
    touched, in_contact = False, 0.0
    sx, sy = float(start[0]), float(start[1])
    scale = substep / total if total > 0.0 else 0.0  # substep as a fraction of the push
    if max_substeps is not None and n_sub > max_substeps:  # bounded work: longer substeps
        n_sub = max_substeps
        scale = 1.0 / n_sub
    for k in range(n_sub):
        # Fixed-length substeps from the start, the last one shorter: the substep boundaries
        # do not depend on the state, so the prediction is continuous in it.
        a = k * scale
        b = (k + 1) * scale if k + 1 < n_sub else 1.0
        w = (sx + a * push[0], sy + a * push[1])
        delta = ((b - a) * push[0], (b - a) * push[1])
        pose, g, length = _substep(pose, c, l, m, w, delta, outline, pusher_radius,
                                   contact_tol, jacobian)
        if length > 0.0:
            touched = True
            in_contact += length
            if g is not None and jp is _EYE_3x7_ROWS:  # first contact: jp = G
                jp = g
            elif g is not None:  # chain rule: jp <- G[:, :3] jp + [0 | G[:, 3:]]
                j0, j1, j2 = jp
                jp = []
                for r in g:
                    r0, r1, r2 = r[0], r[1], r[2]
                    row = [r0 * a + r1 * b + r2 * e for a, b, e in zip(j0, j1, j2)]  # noqa: B905
                    row[3] += r[3]
                    row[4] += r[4]
                    row[5] += r[5]
                    row[6] += r[6]
                    jp.append(row)
    new_state = x.copy()
    new_state[0:3] = pose
    jac = None
    if jacobian:
        jac = _EYE_7.copy()
        jac[0:3] = jp
    return PushPrediction(state=new_state, jacobian=jac, touched=touched,
                          contact_length=in_contact, n_substeps=n_sub)
