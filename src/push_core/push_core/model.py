"""Analytical quasi-static pushing model (Lynch et al. 1992, ellipsoidal limit surface).

Implements the model (docs/design/pushing-model.md) once, generic over numpy and torch:
every function computes in torch (differentiable, e.g. for ``torch.func.jacfwd``) when any input is
a ``torch.Tensor`` and in numpy float64 otherwise (:func:`push_core.geometry.array_namespace`). All
inputs broadcast over leading dimensions.

Conventions (``docs/design/pushing-model.md``): the contact point ``r``, the centre of mass
``c`` and the normal ``n`` are given in one common frame (usually the object frame) and ``n`` points
**into** the object. ``l`` (metres) is the limit-surface parameter (maximum friction torque over
maximum friction force), ``m`` the pusher-object Coulomb friction coefficient. The model is
homogeneous of degree one in the push, so a pusher displacement (metres) yields the displacement
twist of the object (metres, radians).

Contact modes. With ``alpha = atan(m)``, the friction-cone edges ``f_r = R(+alpha) n`` and
``f_l = R(-alpha) n`` map to the boundary contact velocities ``v_pb = l^2 f_b + tau_b (k x r')``,
``r' = r - c``. That map is symmetric positive definite, so the motion cone is a proper convex
cone with ``v_pr`` counter-clockwise of ``v_pl``. The push ``v_u`` (with ``v_u . n > 0``) sticks
when it lies inside the cone; otherwise the contact slides along the boundary on the side where
``v_u`` leaves the cone, ``v_p = (v_u . n) / (v_pb . n) v_pb``. For ordinary parameters this is
exactly the usual "boundary closer to v_u" rule (Lynch et al. 1992); the side test (cross products,
valid only against a boundary with ``v_pb . n > 0``) also stays correct for very high friction,
where one boundary can point away from the surface and the "closer" rule would divide by a negative
``v_pb . n``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from push_core.geometry import Array, array_namespace, check_points, check_poses, check_vectors

#: Clamp range of the limit-surface parameter ``l`` (metres).
L_MIN = 1e-3
L_MAX = 1.0
#: Clamp range of the friction-cone half angle ``alpha_m = atan(m)`` (radians).
ALPHA_MIN = float(np.deg2rad(0.1))
ALPHA_MAX = float(np.deg2rad(89.9))
#: A normal with squared norm at or below this is treated as zero (no contact).
NORMAL_EPS2 = 1e-24

#: Representative push set of the affordances: directions relative to the inward normal (deg)
#: and lengths (m), 10 pushes (Kloss et al. 2020; docs/design/planner.md).
REPRESENTATIVE_ANGLES_DEG = (0.0, 30.0, -30.0, 60.0, -60.0)
REPRESENTATIVE_LENGTHS = (0.01, 0.05)


def push_twist(
    push: ArrayLike,
    contact: ArrayLike,
    normal_in: ArrayLike,
    com: ArrayLike,
    l: ArrayLike,  # noqa: E741 - the limit-surface symbol of Lynch et al.
    m: ArrayLike,
    contact_indicator: ArrayLike = 1.0,
) -> Array:
    """Object twist about the COM caused by a push at one contact (module docstring).

    Parameters
    ----------
    push : array_like or torch.Tensor, shape (..., 2)
        Pusher displacement ``v_u`` in metres (or a velocity in m/s: the model is homogeneous of
        degree one).
    contact : array_like or torch.Tensor, shape (..., 2)
        Contact point ``r`` in metres.
    normal_in : array_like or torch.Tensor, shape (..., 2)
        Surface normal at ``r`` pointing into the object; normalised here. A zero vector
        (squared norm <= ``NORMAL_EPS2``) means "no contact".
    com : array_like or torch.Tensor, shape (..., 2)
        Centre of mass ``c`` in metres.
    l : array_like or torch.Tensor, shape (...)
        Limit-surface parameter in metres, clamped to ``[L_MIN, L_MAX]``.
    m : array_like or torch.Tensor, shape (...)
        Pusher-object friction coefficient; ``atan(m)`` is clamped to ``[ALPHA_MIN, ALPHA_MAX]``.
    contact_indicator : array_like or torch.Tensor, shape (...), optional
        ``s`` in [0, 1] multiplying the contact velocity ``v_p`` (0: the pusher does not touch).

    Returns
    -------
    array, shape (..., 3)
        ``(dx_com, dy_com, dtheta)``: displacement of the COM (metres) and rotation (radians) in
        the frame of the inputs. Exactly zero when ``||n|| = 0``, ``s = 0`` or
        ``push . n <= 0`` (the pusher does not move into the surface).

    Notes
    -----
    Stage 2 (sticking contact with velocity ``v_p``, ``D = l^2 + r'_x^2 + r'_y^2``)::

        v_ox  = ((l^2 + r'_x^2) v_px + r'_x r'_y v_py) / D
        v_oy  = ((l^2 + r'_y^2) v_py + r'_x r'_y v_px) / D
        omega = (r'_x v_oy - r'_y v_ox) / l^2

    The COM motion is parallel to the contact force (ellipsoidal limit surface). Clamping
    ``l`` and ``alpha`` zeroes the gradients with respect to them outside their ranges.
    """
    xp, asarray = array_namespace(push, contact, normal_in, com, l, m, contact_indicator)
    push = check_points(asarray(push), "push")
    contact = check_points(asarray(contact), "contact")
    normal_in = check_points(asarray(normal_in), "normal_in")
    com = check_points(asarray(com), "com")
    l = xp.clip(asarray(l), L_MIN, L_MAX)  # noqa: E741
    alpha = xp.clip(xp.atan(asarray(m)), ALPHA_MIN, ALPHA_MAX)
    s = asarray(contact_indicator)

    ux, uy = push[..., 0], push[..., 1]
    rx, ry = contact[..., 0] - com[..., 0], contact[..., 1] - com[..., 1]  # r' = r - c
    nx, ny = normal_in[..., 0], normal_in[..., 1]
    nn = nx * nx + ny * ny
    has_normal = nn > NORMAL_EPS2
    inv_norm = 1.0 / xp.sqrt(xp.where(has_normal, nn, 1.0))
    nx, ny = nx * inv_norm, ny * inv_norm
    l2 = l * l

    # Stage 1: friction-cone edges, f_r = R(+alpha) n and f_l = R(-alpha) n, and the boundary
    # contact velocities v_pb = l^2 f_b + tau_b (k x r') with k x r' = (-r'_y, r'_x).
    ca, sa = xp.cos(alpha), xp.sin(alpha)
    frx, fry = ca * nx - sa * ny, sa * nx + ca * ny
    flx, fly = ca * nx + sa * ny, -sa * nx + ca * ny
    tau_r = rx * fry - ry * frx
    tau_l = rx * fly - ry * flx
    vrx, vry = l2 * frx - tau_r * ry, l2 * fry + tau_r * rx
    vlx, vly = l2 * flx - tau_l * ry, l2 * fly + tau_l * rx

    u_n = ux * nx + uy * ny
    vr_n = vrx * nx + vry * ny
    vl_n = vlx * nx + vly * ny
    # v_u beyond the counter-clockwise boundary v_pr, or beyond the clockwise boundary v_pl.
    slide_r = (vr_n > 0.0) & (vrx * uy - vry * ux > 0.0)
    slide_l = (vl_n > 0.0) & (ux * vly - uy * vlx > 0.0) & ~slide_r
    k_r = u_n / xp.where(slide_r, vr_n, 1.0)
    k_l = u_n / xp.where(slide_l, vl_n, 1.0)
    vpx = xp.where(slide_r, k_r * vrx, xp.where(slide_l, k_l * vlx, ux))
    vpy = xp.where(slide_r, k_r * vry, xp.where(slide_l, k_l * vly, uy))

    active = has_normal & (u_n > 0.0)
    vpx = xp.where(active, s * vpx, 0.0)
    vpy = xp.where(active, s * vpy, 0.0)

    # Stage 2: twist about the COM for a sticking contact moving with v_p.
    rxx, ryy, rxy = rx * rx, ry * ry, rx * ry
    d = l2 + rxx + ryy
    vox = ((l2 + rxx) * vpx + rxy * vpy) / d
    voy = ((l2 + ryy) * vpy + rxy * vpx) / d
    omega = (rx * voy - ry * vox) / l2
    return xp.stack([vox, voy, omega], -1)


def apply_twist(pose: ArrayLike, twist_obj: ArrayLike, com: ArrayLike) -> Array:
    """Apply a finite object-frame twist about the COM to a world pose.

    Parameters
    ----------
    pose : array_like or torch.Tensor, shape (..., 3)
        Object pose ``(x, y, theta)`` in the world frame (metres, radians).
    twist_obj : array_like or torch.Tensor, shape (..., 3)
        ``(dx_com, dy_com, dtheta)``: COM displacement in the object frame (metres) and rotation
        (radians), e.g. the output of :func:`push_twist` for inputs in the object frame.
    com : array_like or torch.Tensor, shape (..., 2)
        COM offset ``c`` in the object frame (metres).

    Returns
    -------
    array, shape (..., 3)
        New pose: the COM moves by ``R(theta) (dx_com, dy_com)`` in the world, the object rotates
        about it by ``dtheta``, and the origin follows, ``p_new = com_world_new -
        R(theta + dtheta) c``. ``theta`` is not wrapped (trajectories stay continuous); use
        :func:`push_core.geometry.wrap_angle` where a wrapped angle is needed.
    """
    xp, asarray = array_namespace(pose, twist_obj, com)
    pose = check_poses(asarray(pose), "pose")
    twist_obj = check_vectors(asarray(twist_obj), 3, "twist_obj")
    com = check_points(asarray(com), "com")
    theta = pose[..., 2]
    cx, cy = com[..., 0], com[..., 1]
    c0, s0 = xp.cos(theta), xp.sin(theta)
    # COM in the world after the translation: p + R(theta) (c + v_c).
    px, py = cx + twist_obj[..., 0], cy + twist_obj[..., 1]
    gx = pose[..., 0] + c0 * px - s0 * py
    gy = pose[..., 1] + s0 * px + c0 * py
    theta1 = theta + twist_obj[..., 2]
    c1, s1 = xp.cos(theta1), xp.sin(theta1)
    return xp.stack([gx - (c1 * cx - s1 * cy), gy - (s1 * cx + c1 * cy), theta1], -1)


def predict_motion(
    points: ArrayLike,
    normals_out: ArrayLike,
    pushes: ArrayLike,
    com: ArrayLike,
    l: ArrayLike,  # noqa: E741
    m: ArrayLike,
) -> Array:
    """One-step object motion for every contact point x push (the affordances).

    Parameters
    ----------
    points : array_like or torch.Tensor, shape (N, 2)
        Candidate contact points on the outline, object frame (metres).
    normals_out : array_like or torch.Tensor, shape (N, 2)
        Outward unit surface normals at ``points``, object frame.
    pushes : array_like or torch.Tensor, shape (M, 2) or (N, M, 2)
        Pusher displacements in the object frame (metres): the same M pushes for every point, or
        M pushes per point (e.g. :func:`representative_pushes`).
    com : array_like or torch.Tensor, shape (2,)
        COM offset in the object frame (metres).
    l, m : float or array_like or torch.Tensor
        Limit-surface parameter (metres) and pusher-object friction coefficient; see
        :func:`push_twist`.

    Returns
    -------
    array, shape (N, M, 3)
        ``(dx, dy, dtheta)``: displacement of the object frame **origin** expressed in the object
        frame before the push (metres), and rotation (radians). Pushes that leave the surface
        give zeros. The contact is assumed to hold for the whole push (no rollout).
    """
    xp, asarray = array_namespace(points, normals_out, pushes, com, l, m)
    points = check_points(asarray(points), "points")
    normals_out = check_points(asarray(normals_out), "normals_out")
    pushes = check_points(asarray(pushes), "pushes")
    if points.ndim != 2 or normals_out.shape != points.shape:
        raise ValueError(
            f"points and normals_out must both have shape (N, 2), got shapes "
            f"{tuple(points.shape)} and {tuple(normals_out.shape)}"
        )
    if pushes.ndim == 2:
        pushes = pushes[None, :, :]
    elif pushes.ndim != 3 or pushes.shape[0] != points.shape[0]:
        raise ValueError(
            f"pushes must have shape (M, 2) or (N, M, 2) with N = {points.shape[0]}, got shape "
            f"{tuple(pushes.shape)}"
        )
    com = asarray(com)
    if tuple(com.shape) != (2,):
        raise ValueError(f"com must have shape (2,), got shape {tuple(com.shape)}")
    twist = push_twist(pushes, points[:, None, :], -normals_out[:, None, :], com, l, m)
    return apply_twist(xp.zeros_like(twist), twist, com)


def representative_pushes(
    normals_out: ArrayLike,
    angles_deg: Sequence[float] = REPRESENTATIVE_ANGLES_DEG,
    lengths: Sequence[float] = REPRESENTATIVE_LENGTHS,
) -> Array:
    """The representative push set (:data:`REPRESENTATIVE_ANGLES_DEG` x
    :data:`REPRESENTATIVE_LENGTHS`) at every contact point.

    Parameters
    ----------
    normals_out : array_like or torch.Tensor, shape (N, 2)
        Outward surface normals at the contact points, object frame; normalised here (a zero
        normal gives zero pushes).
    angles_deg : sequence of float, length A
        Push directions in degrees relative to the inward normal, counter-clockwise positive.
    lengths : sequence of float, length K
        Push lengths in metres.

    Returns
    -------
    array, shape (N, K * A, 2)
        Push displacements in the object frame (metres), ordered length-major: push
        ``k * A + a`` has length ``lengths[k]`` and direction ``R(angles_deg[a]) n_in``. With the
        defaults: (N, 10, 2), the first five 1 cm long, the last five 5 cm.
    """
    xp, asarray = array_namespace(normals_out)
    normals_out = check_points(asarray(normals_out), "normals_out")
    if normals_out.ndim != 2:
        raise ValueError(
            f"normals_out must have shape (N, 2), got shape {tuple(normals_out.shape)}"
        )
    ang = np.deg2rad(np.asarray(angles_deg, dtype=np.float64))
    length = np.asarray(lengths, dtype=np.float64)
    # (K * A,) factors: direction R(a) n_in scaled by the length.
    cos_k = asarray((length[:, None] * np.cos(ang)[None, :]).reshape(-1))
    sin_k = asarray((length[:, None] * np.sin(ang)[None, :]).reshape(-1))
    nx, ny = -normals_out[:, 0:1], -normals_out[:, 1:2]
    nn = nx * nx + ny * ny
    has_normal = nn > NORMAL_EPS2
    inv_norm = xp.where(has_normal, 1.0 / xp.sqrt(xp.where(has_normal, nn, 1.0)), 0.0)
    nx, ny = nx * inv_norm, ny * inv_norm
    return xp.stack([cos_k * nx - sin_k * ny, sin_k * nx + cos_k * ny], -1)
