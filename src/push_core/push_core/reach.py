"""What one push can do: the model's reach, and the physical minimum it implies.

:func:`push_core.episode.min_pushes` bounds the pushes of a goal by geometry alone: the distance
over the longest push, and one push for a rotation. One push cannot turn an object by any amount
*in place*, though. In the analytical model (docs/design/pushing-model.md) the
object's angular velocity is ``omega = (r' x v_o) / l^2`` with ``r'`` the contact relative to the
COM, so its COM moves at least ``l^2 / rho`` per radian turned (``rho`` the farthest outline
point from the COM, :func:`turn_radius`): a push that turns a flat object by 0.5 rad drags its
COM along with it, and for most objects farther than a 7.5 mm goal region allows.

:func:`one_push_reaches` decides it for a given object and goal by search: every single push of
the model (outline points every ``REACH_SPACING``, directions within ``REACH_ANGLE`` of the
inward normal every ``REACH_ANGLE_STEP``, friction ``m`` in ``REACH_FRICTIONS``; rolled out in
``REACH_SUBSTEP`` substeps and checked after every substep, so every length up to the longest
push counts) is rolled out and its end pose compared with the goal region.
:func:`model_min_pushes` is the physical minimum used by the benchmarks' ``pushes / min``
column: the geometric bound, raised from 1 to 2 when no single push of the model reaches the
goal.

The model is the optimistic case for a simulator whose supports resist turning more than a
uniform pressure does (docs/results/eval_push_support.md): with the uniform-pressure ``l``
of the outline, a larger true ``l`` only moves the COM farther per turn. Friction is unknown, so
any of ``REACH_FRICTIONS`` counts.

Units: metres and radians; offsets in the object's *initial* frame (``x``, ``y`` along the
object's axes at the start, ``theta`` the turn).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.episode import check_goal_offset, min_pushes
from push_core.geometry import check_polyline, wrap_angle
from push_core.rollout import PUSHER_RADIUS, rollout_push
from push_core.shapes import Polygon

__all__ = [
    "REACH_ANGLE",
    "REACH_ANGLE_STEP",
    "REACH_FRICTIONS",
    "REACH_SIMPLIFY",
    "REACH_SPACING",
    "REACH_SUBSTEP",
    "model_min_pushes",
    "one_push_reaches",
    "turn_radius",
]

#: Spacing of the outline points the search pushes at, m.
REACH_SPACING = 0.002
#: Push directions within this angle of the inward normal (rad; the planner's base directions
#: span +-60 deg) ...
REACH_ANGLE = math.radians(75.0)
#: ... every this many radians.
REACH_ANGLE_STEP = math.radians(2.5)
#: Pusher-object friction coefficients tried (the search keeps the best).
REACH_FRICTIONS = (0.1, 0.3, 0.6, 1.0)
#: Substep of the search's rollouts, m: every multiple of it up to the longest push is a length.
REACH_SUBSTEP = 0.001
#: Douglas-Peucker tolerance of the outline pushed against, m (the planner's,
#: ``PlannerConfig.simplify_tolerance``).
REACH_SIMPLIFY = 5e-4
#: Gap between the pusher and the surface at the start of a searched push, m (the push runs
#: that much farther, so its length past the contact is the longest push).
_START_GAP = 5e-4
#: Pushes rolled out per batch (bounds the memory of the search).
_CHUNK = 4096


def turn_radius(polyline: ArrayLike, com: ArrayLike, l: float) -> float:  # noqa: E741
    """``l^2 / rho``: the least distance of a push's instantaneous centre of rotation from the
    COM, m (module docstring); ``rho`` is the largest distance of an outline vertex from the
    COM. A push that turns the object by ``phi`` moves its COM along a path of at least
    ``turn_radius * |phi|``.

    Parameters
    ----------
    polyline : array_like, shape (P, 2)
        Counter-clockwise outline (closing edge implied), object frame, m.
    com : array_like, shape (2,)
        COM in the object frame, m.
    l : float
        Limit-surface parameter, m (> 0).

    Raises
    ------
    ValueError
        Naming ``polyline``, ``com`` or ``l``.
    """
    poly = check_polyline(polyline, "polyline")
    c = np.asarray(com, dtype=np.float64)
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise ValueError(f"com: expected 2 finite numbers, got {com!r}")
    if not (isinstance(l, int | float | np.floating) and math.isfinite(l) and l > 0.0):
        raise ValueError(f"l: expected a finite number > 0 m, got {l!r}")
    rho = float(np.max(np.linalg.norm(poly - c, axis=1)))
    return float(l) ** 2 / rho


def _push_starts(poly: NDArray[np.float64], spacing: float,
                 pusher_radius: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pusher start points just outside each edge (every ``spacing``) and the edges' inward
    normals, object frame. ``poly`` is counter-clockwise, its closing edge implied."""
    starts, inward = [], []
    for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        edge = b - a
        length = float(np.linalg.norm(edge))
        if length < 1e-9:
            continue
        n_out = np.array([edge[1], -edge[0]]) / length
        k = max(1, int(math.ceil(length / spacing)))
        s = (np.arange(k) + 0.5) / k
        points = a + s[:, None] * edge
        starts.append(points + (pusher_radius + _START_GAP) * n_out)
        inward.append(np.broadcast_to(-n_out, points.shape))
    return np.concatenate(starts), np.concatenate(inward)


def one_push_reaches(polyline: ArrayLike, com: ArrayLike, l: float,  # noqa: E741
                     offset: ArrayLike, tolerances: tuple[float, float], max_push_length: float,
                     order: int = 1, pusher_radius: float = PUSHER_RADIUS) -> bool:
    """Whether some single push of the model ends inside the goal region (module docstring).

    Parameters
    ----------
    polyline : array_like, shape (P, 2)
        Counter-clockwise outline (closing edge implied), object frame, m; pushed against
        simplified by ``REACH_SIMPLIFY``.
    com : array_like, shape (2,)
        COM, object frame, m.
    l : float
        Limit-surface parameter, m (> 0).
    offset : array_like, shape (3,)
        Goal minus start in the object's initial frame: ``(dx, dy)`` m, ``theta`` rad.
    tolerances : (float, float)
        Goal region: position (m) and orientation (rad), > 0.
    max_push_length : float
        Longest push past the contact, m (> 0).
    order : int
        Rotational symmetry order of the outline (1: none); the orientation is compared modulo
        ``2 pi / order``.
    pusher_radius : float
        m (>= 0).

    Returns
    -------
    bool

    Raises
    ------
    ValueError
        Naming the bad argument.
    """
    poly = check_polyline(polyline, "polyline")
    turn_radius(poly, com, l)  # validates com and l
    o, tol_xy, tol_theta = check_goal_offset(offset, tolerances, max_push_length)
    # the contact polyline the planner uses (a measured outline has hundreds of tiny edges)
    poly = Polygon(poly).simplified(REACH_SIMPLIFY).vertices
    starts, inward = _push_starts(poly, REACH_SPACING, pusher_radius)
    angles = np.arange(-REACH_ANGLE, REACH_ANGLE + 1e-9, REACH_ANGLE_STEP)
    c, s = np.cos(angles), np.sin(angles)
    # every start x every direction: the inward normal turned by each angle
    dx = c[None, :] * inward[:, None, 0] - s[None, :] * inward[:, None, 1]
    dy = s[None, :] * inward[:, None, 0] + c[None, :] * inward[:, None, 1]
    pusher0 = np.repeat(starts, len(angles), axis=0)
    travel = (max_push_length + _START_GAP) * np.stack([dx.ravel(), dy.ravel()], axis=1)
    period = 2.0 * math.pi / max(int(order), 1)
    pose0 = np.zeros(3)
    for m in REACH_FRICTIONS:
        for i in range(0, len(pusher0), _CHUNK):
            result = rollout_push(poly, pose0, com, l, m, pusher0[i:i + _CHUNK],
                                  travel[i:i + _CHUNK], substep=REACH_SUBSTEP,
                                  pusher_radius=pusher_radius)
            poses = result.poses[:, 1:]  # after every substep
            dxy = np.hypot(poses[..., 0] - o[0], poses[..., 1] - o[1])
            dth = np.asarray(wrap_angle(o[2] - poses[..., 2]))
            dth = np.abs(dth - period * np.round(dth / period))
            if np.any((dxy <= tol_xy) & (dth <= tol_theta)):
                return True
    return False


def model_min_pushes(offset: ArrayLike, tolerances: tuple[float, float], max_push_length: float,
                     polyline: ArrayLike, com: ArrayLike, l: float,  # noqa: E741
                     order: int = 1, pusher_radius: float = PUSHER_RADIUS) -> int:
    """The physical minimum of pushes for a goal: :func:`push_core.episode.min_pushes`, raised
    from 1 to 2 when no single push of the model reaches the goal
    (:func:`one_push_reaches`; arguments as there, ``offset`` in the object's initial frame).

    Returns
    -------
    int
        >= 0.
    """
    n = min_pushes(offset, tolerances, max_push_length, order)
    if n == 1 and not one_push_reaches(polyline, com, l, offset, tolerances, max_push_length,
                                       order, pusher_radius):
        return 2
    return n
