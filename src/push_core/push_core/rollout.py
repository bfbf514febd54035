"""Multi-step rollout of a straight-line push with a cylindrical pusher.

The model and its conventions: docs/design/pushing-model.md.

The pusher, a disc of radius ``pusher_radius`` centred on its axis, moves along a straight
line in the world frame in substeps. At every substep the contact point and normal are found
again on the *moved* outline and the analytical model (:mod:`push_core.model`) moves the object.
Numpy only; vectorised over the batch (a Python loop runs over substeps only).

Contact test of one substep (pusher centre ``p`` -> ``p + d``; object pose at the substep start):

1. ``q = p`` in the (moved) object frame; closest outline point ``r``, outward normal ``n`` and
   signed distance ``sd`` of ``q`` (:func:`push_core.geometry.closest_point_on_polyline`);
   ``d_obj`` is ``d`` in the same frame.
2. ``gap = sd - pusher_radius`` is the clearance at the substep start (negative: overlap) and
   ``approach = -d_obj . n`` the motion into the surface over the substep.
3. In contact iff ``approach > 0`` and ``gap - approach <= contact_tol``: the pusher touches the
   surface, or reaches it within the substep, to within ``contact_tol`` (the surface linearised
   at ``r``). With ``gap <= contact_tol`` this is the plain test ``sd <= pusher_radius +
   contact_tol``.
4. In contact, the model is driven by the part of the substep after the touch,
   ``clip((approach - gap) / approach, 0, 1) * d_obj``, with contact point ``r`` and
   ``n_in = -n``. So a gap is closed exactly rather than to within one substep; an overlap that
   is already there (pusher placed inside the object) is not pushed out.

The pusher always advances by ``d``. The test uses the pusher centre at the substep start, which
stays outside the outline in steady contact (each contact substep ends with the pusher touching,
up to the model's first-order error), so the closest point is well defined even when the
substep is longer than the pusher radius. A substep that starts on a face and passes a corner
counts as in contact (it touched for part of the substep); the next one does not.

"Lost contact": the pusher was in contact at some substep and is not in contact at a later
substep of the same push (it slid off a corner, or the object rotated away from it).
``first_lost_step`` is the first such substep. Contact that resumes later does not clear it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import (
    check_points,
    check_polyline,
    check_poses,
    closest_point_on_polyline,
    world_to_object,
)
from push_core.model import apply_twist, push_twist

#: Radius of the source setup's steel pusher (m; Kloss et al. 2020).
PUSHER_RADIUS = 0.0048
#: Rollout substep (m): the model is applied every 5 mm of pusher travel.
SUBSTEP = 0.005
#: Contact tolerance on the pusher-outline distance (m).
CONTACT_TOL = 5e-4


@dataclass(frozen=True)
class RolloutResult:
    """Trajectory of a batch of pushes; B pushes, S = max over the batch of ``n_steps``.

    Attributes
    ----------
    poses : numpy.ndarray, shape (B, S + 1, 3)
        Object pose ``(x, y, theta)`` in the world frame before substep 0 and after every
        substep; ``theta`` is continuous (not wrapped).
    pusher : numpy.ndarray, shape (B, S + 1, 2)
        Pusher centre in the world frame at the same instants.
    contact : numpy.ndarray of bool, shape (B, S)
        Whether the pusher touched the object during each substep (see the module docstring;
        False after ``n_steps``).
    contact_points : numpy.ndarray, shape (B, S, 2)
        Closest outline point to the pusher centre at the start of each substep, in the object
        frame (the contact point where ``contact`` is True).
    normals : numpy.ndarray, shape (B, S, 2)
        Outward unit normal at ``contact_points``, object frame.
    lost_contact : numpy.ndarray of bool, shape (B,)
        Whether contact was made and later lost within the push.
    first_lost_step : numpy.ndarray of int, shape (B,)
        First substep without contact after a substep with contact; -1 if never.
    n_steps : numpy.ndarray of int, shape (B,)
        Substeps of each push, ``ceil(|push| / substep)``; the last one is shorter unless the
        length is a multiple of ``substep``. Entries beyond ``n_steps`` repeat the final state.
    """

    poses: NDArray[np.float64]
    pusher: NDArray[np.float64]
    contact: NDArray[np.bool_]
    contact_points: NDArray[np.float64]
    normals: NDArray[np.float64]
    lost_contact: NDArray[np.bool_]
    first_lost_step: NDArray[np.int64]
    n_steps: NDArray[np.int64]


def _batch(x: NDArray[np.float64], ndim: int, batch: int) -> NDArray[np.float64]:
    """Broadcast an unbatched (``ndim`` axes) or batched input to a leading batch axis."""
    if x.ndim == ndim:
        x = x[None]
    return np.broadcast_to(x, (batch, *x.shape[1:]))


def rollout_push(
    outline: ArrayLike,
    pose0: ArrayLike,
    com: ArrayLike,
    l: ArrayLike,  # noqa: E741 - the limit-surface symbol of Lynch et al.
    m: ArrayLike,
    pusher_start: ArrayLike,
    push: ArrayLike,
    substep: float = SUBSTEP,
    pusher_radius: float = PUSHER_RADIUS,
    contact_tol: float = CONTACT_TOL,
    two_faces: bool = False,
) -> RolloutResult:
    """Roll out straight-line pushes of a disc pusher against an outline, in substeps.

    Parameters
    ----------
    outline : array_like, shape (P, 2)
        Closed counter-clockwise polyline of the object outline, object frame (metres).
    pose0 : array_like, shape (B, 3) or (3,)
        Initial object pose ``(x, y, theta)`` in the world frame.
    com : array_like, shape (B, 2) or (2,)
        COM offset in the object frame (metres).
    l, m : float or array_like, shape (B,)
        Limit-surface parameter (metres) and pusher-object friction coefficient.
    pusher_start : array_like, shape (B, 2) or (2,)
        Pusher centre at the start of the push, world frame (metres).
    push : array_like, shape (B, 2) or (2,)
        Pusher displacement over the whole push, world frame (metres).
    substep : float
        Substep length in metres (> 0).
    pusher_radius : float
        Pusher radius in metres (>= 0).
    contact_tol : float
        Distance tolerance of the contact test in metres (>= 0).
    two_faces : bool
        Frictionless pushes (``m = 0``) only: when the pusher also touches a second face (an
        inner corner of a non-convex outline, :func:`wedge_twist`), both contacts push at once.
        Default False: one contact, the nearest face (pushes with ``m > 0`` always use one).

    Returns
    -------
    RolloutResult
        Batch size B from broadcasting the inputs (B = 1 if none is batched).

    Raises
    ------
    ValueError
        On a bad outline, inputs of the wrong shape, batch sizes that do not broadcast, or a
        non-positive ``substep`` / negative ``pusher_radius`` or ``contact_tol``.
    """
    if not substep > 0.0:
        raise ValueError(f"substep must be > 0, got {substep}")
    if not pusher_radius >= 0.0:
        raise ValueError(f"pusher_radius must be >= 0, got {pusher_radius}")
    if not contact_tol >= 0.0:
        raise ValueError(f"contact_tol must be >= 0, got {contact_tol}")
    outline = check_polyline(outline, "outline")
    arrays = {
        "pose0": (np.asarray(check_poses(pose0, "pose0"), dtype=np.float64), 1),
        "com": (np.asarray(check_points(com, "com"), dtype=np.float64), 1),
        "l": (np.asarray(l, dtype=np.float64), 0),
        "m": (np.asarray(m, dtype=np.float64), 0),
        "pusher_start": (np.asarray(check_points(pusher_start, "pusher_start"), np.float64), 1),
        "push": (np.asarray(check_points(push, "push"), dtype=np.float64), 1),
    }
    sizes = {}
    for name, (x, ndim) in arrays.items():
        if x.ndim not in (ndim, ndim + 1):
            raise ValueError(f"{name} must be unbatched or have one batch axis, got {x.shape}")
        if x.ndim == ndim + 1:
            sizes[name] = x.shape[0]
    try:
        (batch,) = np.broadcast_shapes(*((s,) for s in sizes.values())) if sizes else (1,)
    except ValueError:
        raise ValueError(f"batch sizes do not broadcast: {sizes}") from None
    pose, com, l, m, start, push = (  # noqa: E741
        _batch(x, nd, batch) for x, nd in arrays.values()
    )

    length = np.hypot(push[:, 0], push[:, 1])  # (B,)
    direction = push / np.where(length > 0.0, length, 1.0)[:, None]
    # ceil, robust to 0.05 / 0.005 = 10.000000000000002
    n_steps = np.ceil(length / substep * (1.0 - 1e-12)).astype(np.int64)
    n_sub = int(n_steps.max(initial=0))

    poses = np.empty((batch, n_sub + 1, 3))
    pusher = np.empty((batch, n_sub + 1, 2))
    contact = np.zeros((batch, n_sub), dtype=bool)
    points = np.empty((batch, n_sub, 2))
    normals = np.empty((batch, n_sub, 2))
    poses[:, 0], pusher[:, 0] = pose, start
    for k in range(n_sub):
        travelled = np.minimum((k + 1) * substep, length)[:, None]
        p_end = np.where((k + 1 >= n_steps)[:, None], start + push, start + direction * travelled)
        q_start = world_to_object(pose, pusher[:, k])
        d_obj = world_to_object(pose, p_end) - q_start
        closest, n_out, sd, _ = closest_point_on_polyline(outline, q_start)
        approach = -np.sum(d_obj * n_out, axis=-1)
        gap = sd - pusher_radius
        touching = (k < n_steps) & (approach > 0.0) & (gap - approach <= contact_tol)
        frac = np.clip((approach - gap) / np.where(touching, approach, 1.0), 0.0, 1.0)
        twist = push_twist(frac[:, None] * d_obj, closest, -n_out, com, l, m, touching)
        if two_faces:
            twist = _two_face_twist(outline, q_start, frac[:, None] * d_obj, closest, n_out,
                                    com, l, m, touching, pusher_radius + contact_tol, twist)
        pose = np.where(touching[:, None], apply_twist(pose, twist, com), pose)
        poses[:, k + 1], pusher[:, k + 1] = pose, p_end
        contact[:, k], points[:, k], normals[:, k] = touching, closest, n_out

    ever = np.logical_or.accumulate(contact, axis=1)
    before = np.concatenate([np.zeros((batch, 1), dtype=bool), ever[:, :-1]], axis=1)
    active = np.arange(n_sub)[None, :] < n_steps[:, None]
    lost = before & ~contact & active
    lost_contact = lost.any(axis=1)
    first = np.argmax(lost, axis=1) if n_sub > 0 else np.zeros(batch, dtype=np.int64)
    first_lost = np.where(lost_contact, first, -1).astype(np.int64)
    return RolloutResult(
        poses=poses,
        pusher=pusher,
        contact=contact,
        contact_points=points,
        normals=normals,
        lost_contact=lost_contact,
        first_lost_step=first_lost,
        n_steps=n_steps,
    )


def wedge_twist(push: ArrayLike, contacts: ArrayLike, normals_in: ArrayLike, com: ArrayLike,
                l: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:  # noqa: E741
    """Twist of a frictionless push with two simultaneous contacts (a pusher in an inner corner).

    Ellipsoidal limit surface, frictionless contacts: the contact wrenches
    ``w_i = (n_i, (r_i - c) x n_i)`` with multipliers ``lam_i >= 0`` move the object by
    ``V = A (lam_1 w_1 + lam_2 w_2)``, ``A = diag(1, 1, 1 / l^2)``, and each active contact
    follows the pusher along its normal: ``w_i . V = u . n_i``. Solved as a 2 x 2 system;
    ``ok`` is False where a multiplier would be negative (the pusher leaves that face: use one
    contact) or the system is singular (parallel faces).

    Parameters
    ----------
    push : array_like, shape (B, 2)
        Pusher displacement, object frame (metres).
    contacts, normals_in : array_like, shape (B, 2, 2)
        The two contact points and inward unit normals, object frame.
    com : array_like, shape (B, 2)
    l : array_like, shape (B,)

    Returns
    -------
    twist : numpy.ndarray, shape (B, 3)
        COM displacement (metres) and rotation (radians), object frame.
    ok : numpy.ndarray of bool, shape (B,)
    """
    u = np.asarray(push, dtype=np.float64)
    r = np.asarray(contacts, dtype=np.float64) - np.asarray(com, dtype=np.float64)[:, None, :]
    n = np.asarray(normals_in, dtype=np.float64)
    torque = r[..., 0] * n[..., 1] - r[..., 1] * n[..., 0]  # (B, 2)
    w = np.concatenate([n, torque[..., None]], axis=-1)  # (B, 2, 3)
    a = np.array([1.0, 1.0, 0.0])[None, :] + np.array([0.0, 0.0, 1.0])[None, :] / np.square(
        np.asarray(l, dtype=np.float64))[:, None]  # (B, 3) diagonal of A
    g = np.einsum("bik,bk,bjk->bij", w, a, w)
    rhs = np.einsum("bk,bik->bi", u, n)
    det = g[:, 0, 0] * g[:, 1, 1] - g[:, 0, 1] * g[:, 1, 0]
    safe = np.abs(det) > 1e-12 * np.maximum(g[:, 0, 0] * g[:, 1, 1], 1e-300)
    det = np.where(safe, det, 1.0)
    lam = np.stack([g[:, 1, 1] * rhs[:, 0] - g[:, 0, 1] * rhs[:, 1],
                    g[:, 0, 0] * rhs[:, 1] - g[:, 1, 0] * rhs[:, 0]], -1) / det[:, None]
    ok = safe & np.all(lam > 0.0, axis=1)
    twist = a * np.einsum("bi,bik->bk", lam, w)
    return np.where(ok[:, None], twist, 0.0), ok


def _two_face_twist(outline: NDArray[np.float64], q: NDArray[np.float64],
                    push: NDArray[np.float64], closest: NDArray[np.float64],
                    n_out: NDArray[np.float64], com: NDArray[np.float64], l: NDArray[np.float64],  # noqa: E741
                    m: NDArray[np.float64], touching: NDArray[np.bool_], reach: float,
                    single: NDArray[np.float64]) -> NDArray[np.float64]:
    """``single`` replaced by :func:`wedge_twist` where a frictionless pusher in contact also
    touches another face (within ``reach`` of the pusher centre ``q``, its nearest point inside
    the face, more than 1 mm from ``closest``, with a normal at least 8 degrees from
    ``n_out``)."""
    a = outline
    ab = np.roll(outline, -1, axis=0) - a
    t = np.clip(np.einsum("bpk,pk->bp", q[:, None, :] - a[None], ab) / np.sum(ab * ab, 1), 0, 1)
    foot = a[None] + t[..., None] * ab[None]  # (B, P, 2)
    dist = np.linalg.norm(q[:, None, :] - foot, axis=-1)
    normal = np.stack([ab[:, 1], -ab[:, 0]], -1) / np.linalg.norm(ab, axis=1)[:, None]
    # a face the pusher touches squarely (its foot inside the segment, not at an end point: at
    # a convex corner the other face's nearest point is the shared vertex, not a contact)
    other = (np.linalg.norm(foot - closest[:, None, :], axis=-1) > 1e-3) & (
        np.einsum("pk,bk->bp", normal, n_out) < math.cos(math.radians(8.0))) & (
        t > 1e-6) & (t < 1.0 - 1e-6)
    dist = np.where(other, dist, np.inf)
    j = np.argmin(dist, axis=1)
    rows = np.arange(len(q))
    second = touching & (np.asarray(m) <= 0.0) & (dist[rows, j] <= reach) & (
        -np.sum(push * normal[j], axis=-1) > 0.0)
    if not second.any():
        return single
    contacts = np.stack([closest, foot[rows, j]], 1)
    normals_in = -np.stack([n_out, normal[j]], 1)
    twist, ok = wedge_twist(push, contacts, normals_in, com, l)
    return np.where((second & ok)[:, None], twist, single)
