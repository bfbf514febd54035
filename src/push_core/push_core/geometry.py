"""Rigid 2-D geometry for planar pushing: rotations, poses, closest points on outlines.

Conventions (see ``docs/ARCHITECTURE.md``): SI units (metres, radians), right-handed, z up.
A planar pose is an array ``(..., 3)`` = ``(x, y, theta)``: the position of the object frame
origin in the world frame and the rotation of the object frame about z. Points are arrays
``(..., 2)``. Leading dimensions broadcast in the numpy way.

``rot2``, ``wrap_angle``, ``object_to_world`` and ``world_to_object`` are generic over numpy and
torch: given a ``torch.Tensor`` they compute in torch (differentiable), otherwise in numpy
float64 (see :func:`array_namespace`). ``closest_point_on_polyline`` and the ``check_*``
validators are numpy only.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: An array of either backend: ``numpy.ndarray`` (float64) or ``torch.Tensor``.
Array = Any

#: Below this distance (m) a query is "on" the outline and gets the segment's normal.
ON_OUTLINE_TOL = 1e-9


def array_namespace(*arrays: Any) -> tuple[ModuleType, Callable[[Any], Array]]:
    """Pick the array backend of the inputs: torch if any input is a tensor, else numpy.

    The returned module is used through names that numpy (>= 2) and torch share with the same
    positional signatures: ``where, atan, clip, sqrt, cos, sin, ceil, stack(seq, axis)``.

    Parameters
    ----------
    *arrays
        Inputs of a function: ``numpy.ndarray``, ``torch.Tensor``, Python scalars or sequences.

    Returns
    -------
    xp : module
        ``numpy`` or ``torch``.
    asarray : callable
        Converts one input to an array of that backend: float64 for numpy; for torch the
        promoted dtype of the floating-point tensors among ``arrays`` (float64 if there are
        none) on the device of the first tensor.
    """
    torch = sys.modules.get("torch")  # a tensor can only exist if torch has been imported
    if torch is not None:
        tensors = [a for a in arrays if isinstance(a, torch.Tensor)]
        if tensors:
            dtype = torch.float64 if not any(t.is_floating_point() for t in tensors) else None
            for t in tensors:
                if t.is_floating_point():
                    dtype = t.dtype if dtype is None else torch.promote_types(dtype, t.dtype)
            device = tensors[0].device

            def as_tensor(a: Any) -> Array:
                return torch.as_tensor(a, dtype=dtype, device=device)

            return torch, as_tensor

    def as_float64(a: Any) -> Array:
        return np.asarray(a, dtype=np.float64)

    return np, as_float64


def _shape_of(x: Any) -> tuple[int, ...]:
    return tuple(x.shape) if hasattr(x, "shape") else np.shape(x)


def check_vectors(x: ArrayLike, size: int, name: str) -> Array:
    """Check that ``x`` has shape ``(..., size)``.

    Parameters
    ----------
    x : array_like or torch.Tensor
        The argument to check.
    size : int
        Required length of the last axis.
    name : str
        Argument name used in the error message.

    Returns
    -------
    array
        ``x`` unchanged if it is a ``numpy.ndarray`` or ``torch.Tensor``, otherwise
        ``numpy.asarray(x, dtype=float64)``.

    Raises
    ------
    ValueError
        If the last axis does not have length ``size``.
    """
    if not hasattr(x, "shape"):
        x = np.asarray(x, dtype=np.float64)
    shape = _shape_of(x)
    if len(shape) == 0 or shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), got shape {shape}")
    return x


def check_points(points: ArrayLike, name: str = "points") -> Array:
    """Check that ``points`` has shape ``(..., 2)``; see :func:`check_vectors`."""
    return check_vectors(points, 2, name)


def check_poses(poses: ArrayLike, name: str = "pose") -> Array:
    """Check that ``poses`` has shape ``(..., 3)``, ``(x, y, theta)``; see :func:`check_vectors`."""
    return check_vectors(poses, 3, name)


def check_polyline(vertices: ArrayLike, name: str = "vertices") -> NDArray[np.float64]:
    """Check a closed counter-clockwise polyline (polygon outline).

    Parameters
    ----------
    vertices : array_like, shape (P, 2)
        Vertices in metres, ``P >= 3``, counter-clockwise; the closing segment from the last to
        the first vertex is implied. The polygon may be non-convex.
    name : str
        Argument name used in the error message.

    Returns
    -------
    numpy.ndarray, shape (P, 2), float64

    Raises
    ------
    ValueError
        If the shape is not ``(P, 2)`` with ``P >= 3``, a value is not finite, or the signed
        area is not positive (clockwise or degenerate).
    """
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3:
        raise ValueError(f"{name} must have shape (P, 2) with P >= 3, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be finite, got non-finite values in shape {v.shape}")
    x, y = v[:, 0], v[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if not area > 0.0:
        raise ValueError(
            f"{name} must be counter-clockwise with positive area, got signed area "
            f"{area:.3g} m^2 for shape {v.shape}"
        )
    return v


def rot2(theta: ArrayLike) -> Array:
    """Planar rotation matrices.

    Parameters
    ----------
    theta : array_like or torch.Tensor, shape (...)
        Angles in radians, counter-clockwise about z.

    Returns
    -------
    array, shape (..., 2, 2)
        ``[[cos, -sin], [sin, cos]]``; ``rot2(theta) @ p`` rotates the column vector ``p``.
    """
    xp, asarray = array_namespace(theta)
    theta = asarray(theta)
    c, s = xp.cos(theta), xp.sin(theta)
    return xp.stack([xp.stack([c, -s], -1), xp.stack([s, c], -1)], -2)


def wrap_angle(theta: ArrayLike) -> Array:
    """Wrap angles to the interval (-pi, pi].

    Parameters
    ----------
    theta : array_like or torch.Tensor, shape (...)
        Angles in radians.

    Returns
    -------
    array, shape (...)
        ``theta - 2 pi k`` with the integer ``k`` that puts the result in (-pi, pi].
    """
    xp, asarray = array_namespace(theta)
    theta = asarray(theta)
    return theta - 2.0 * np.pi * xp.ceil((theta - np.pi) / (2.0 * np.pi))


def _transform(pose: ArrayLike, points: ArrayLike, inverse: bool) -> Array:
    """``(x, y) + R(theta) p``, or ``R(theta)^T (p - (x, y))`` if ``inverse``."""
    xp, asarray = array_namespace(pose, points)
    pose = check_poses(asarray(pose), "pose")
    points = check_points(asarray(points), "points")
    c, s = xp.cos(pose[..., 2]), xp.sin(pose[..., 2])
    px, py = points[..., 0], points[..., 1]
    if inverse:
        px, py, s = px - pose[..., 0], py - pose[..., 1], -s
    qx, qy = c * px - s * py, s * px + c * py
    if not inverse:
        qx, qy = qx + pose[..., 0], qy + pose[..., 1]
    return xp.stack([qx, qy], -1)


def object_to_world(pose: ArrayLike, points: ArrayLike) -> Array:
    """Transform points from the object frame to the world frame.

    Parameters
    ----------
    pose : array_like or torch.Tensor, shape (..., 3)
        Object pose ``(x, y, theta)`` in the world frame (metres, radians).
    points : array_like or torch.Tensor, shape (..., 2)
        Points in the object frame (metres). Leading dimensions broadcast with ``pose``: to
        transform N points by one pose pass ``pose`` (3,) and ``points`` (N, 2).

    Returns
    -------
    array, shape (..., 2)
        ``p_world = (x, y) + R(theta) p_object``.
    """
    return _transform(pose, points, inverse=False)


def world_to_object(pose: ArrayLike, points: ArrayLike) -> Array:
    """Transform points from the world frame to the object frame.

    Parameters
    ----------
    pose : array_like or torch.Tensor, shape (..., 3)
        Object pose ``(x, y, theta)`` in the world frame (metres, radians).
    points : array_like or torch.Tensor, shape (..., 2)
        Points in the world frame (metres); leading dimensions broadcast with ``pose``.

    Returns
    -------
    array, shape (..., 2)
        ``p_object = R(theta)^T (p_world - (x, y))``; inverse of :func:`object_to_world`.
    """
    return _transform(pose, points, inverse=True)


def closest_point_on_polyline(
    vertices: ArrayLike, queries: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """Exact closest point on a closed counter-clockwise polyline, with signed distance.

    Vectorised over all queries x all segments (memory O(Q P)).

    Parameters
    ----------
    vertices : array_like, shape (P, 2)
        Closed counter-clockwise polyline (polygon outline) in metres, any frame; segment ``i``
        runs from vertex ``i`` to vertex ``i + 1`` (the last one back to vertex 0). May be
        non-convex; see :func:`check_polyline`.
    queries : array_like, shape (..., 2)
        Query points in the same frame (metres).

    Returns
    -------
    closest : numpy.ndarray, shape (..., 2)
        Closest point on the polyline to each query (same frame).
    outward_normal : numpy.ndarray, shape (..., 2)
        Unit outward normal at the closest point. For a query outside: the unit vector from the
        closest point toward the query (at a vertex this is the contact normal of a disc touching
        the vertex); inside: the unit vector from the query toward the closest point. When
        ``|signed_distance| <= ON_OUTLINE_TOL`` it is the outward normal of the closest segment,
        ``(dy, -dx) / length`` (at a vertex, the first of the two segments in index order).
    signed_distance : numpy.ndarray, shape (...)
        Euclidean distance to the polyline in metres, negative inside the polygon. Inside is
        decided by the crossing parity of a ray in +x, so non-convex outlines work.
    segment_index : numpy.ndarray of intp, shape (...)
        Index of the segment holding the closest point.

    Raises
    ------
    ValueError
        If ``vertices`` fails :func:`check_polyline` or ``queries`` is not ``(..., 2)``.
    """
    v = check_polyline(vertices, "vertices")
    q = np.asarray(check_points(queries, "queries"), dtype=np.float64)
    lead = q.shape[:-1]
    qx = q[..., 0].reshape(-1, 1)  # (K, 1)
    qy = q[..., 1].reshape(-1, 1)
    ax, ay = v[:, 0], v[:, 1]  # (P,)
    bx, by = np.roll(ax, -1), np.roll(ay, -1)
    dx, dy = bx - ax, by - ay
    seg_len2 = dx * dx + dy * dy
    inv_len2 = np.where(seg_len2 > 0.0, 1.0 / np.where(seg_len2 > 0.0, seg_len2, 1.0), 0.0)

    # Closest point on every segment: a + t d with t clipped to [0, 1].
    t = np.clip(((qx - ax) * dx + (qy - ay) * dy) * inv_len2, 0.0, 1.0)  # (K, P)
    px, py = ax + t * dx, ay + t * dy
    dist2 = (qx - px) ** 2 + (qy - py) ** 2
    dist2 = np.where(seg_len2 > 0.0, dist2, np.inf)  # repeated vertices: never the answer
    seg = np.argmin(dist2, axis=1)  # (K,)
    rows = np.arange(seg.size)
    cx, cy = px[rows, seg], py[rows, seg]
    dist = np.sqrt(dist2[rows, seg])

    # Crossing parity of the ray from the query in +x; (ay > qy) != (by > qy) excludes
    # horizontal segments, so the division is safe where it is used.
    straddles = (ay > qy) != (by > qy)
    dy_safe = np.where(straddles, dy, 1.0)
    x_cross = ax + (qy - ay) * dx / dy_safe
    inside = (np.count_nonzero(straddles & (qx < x_cross), axis=1) % 2) == 1

    qx, qy = qx[:, 0], qy[:, 0]
    sign = np.where(inside, -1.0, 1.0)
    on_outline = dist <= ON_OUTLINE_TOL
    inv_dist = sign / np.where(on_outline, 1.0, dist)
    seg_inv_len = np.sqrt(inv_len2[seg])
    nx = np.where(on_outline, dy[seg] * seg_inv_len, (qx - cx) * inv_dist)
    ny = np.where(on_outline, -dx[seg] * seg_inv_len, (qy - cy) * inv_dist)

    closest = np.stack([cx, cy], -1).reshape(*lead, 2)
    normal = np.stack([nx, ny], -1).reshape(*lead, 2)
    return closest, normal, (sign * dist).reshape(lead), seg.reshape(lead)
