"""Rigid 2-D geometry for planar pushing: rotations, poses, closest points on outlines.

Conventions (see ``docs/ARCHITECTURE.md#units-frames-conventions``): SI units (metres,
radians), right-handed, z up.
A planar pose is an array ``(..., 3)`` = ``(x, y, theta)``: the position of the object frame
origin in the world frame and the rotation of the object frame about z. Points are arrays
``(..., 2)``. Leading dimensions broadcast in the numpy way.

Quaternions are (x, y, z, w), the order of ROS and pybullet; the one quaternion rule of the
pipeline (:data:`QUATERNION_TOLERANCE`: finite, unit norm within 1e-3, and for a planar pose
``|q_x|, |q_y| <= 1e-3``) is :func:`check_quaternion` / :func:`yaw_from_quaternion`, used by
every message reader (``push_ros``).

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
#: :func:`closest_point_on_polyline` works on at most this many query x segment pairs at a
#: time (about 20 temporaries of 8 bytes each: ~40 MB), whatever the number of queries.
CLOSEST_POINT_BUDGET = 1 << 18


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


def check_vector(value: ArrayLike, size: int, name: str) -> NDArray[np.float64]:
    """Check one finite vector of ``size`` numbers (a pose, a goal, a state).

    Parameters
    ----------
    value : array_like, shape (size,)
        The argument to check.
    size : int
        Required length.
    name : str
        Argument name the error message starts with.

    Returns
    -------
    numpy.ndarray, shape (size,), float64
        A new array.

    Raises
    ------
    ValueError
        If ``value`` is not numbers, not of shape ``(size,)``, or not finite.
    """
    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {size} numbers, got {value!r}") from None
    if v.shape != (size,):
        raise ValueError(f"{name}: expected shape ({size},), got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: must be finite, got {v.tolist()}")
    return v


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

    Vectorised over all queries x all segments; the queries are processed in chunks of at
    most ``CLOSEST_POINT_BUDGET / P`` (each row is independent, so the result is the same
    bits), which bounds the memory of one call to O(``CLOSEST_POINT_BUDGET``) whatever Q.

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
    flat = q.reshape(-1, 2)
    rows = max(1, CLOSEST_POINT_BUDGET // len(v))
    if len(flat) <= rows:
        closest, normal, sd, seg = _closest_point_flat(v, flat)
    else:  # bounded memory: the queries are independent, so chunks give the same bits
        parts = [_closest_point_flat(v, flat[i:i + rows]) for i in range(0, len(flat), rows)]
        closest, normal, sd, seg = (np.concatenate(a) for a in zip(*parts, strict=True))
    return (closest.reshape(*lead, 2), normal.reshape(*lead, 2), sd.reshape(lead),
            seg.reshape(lead))


def _closest_point_flat(
    v: NDArray[np.float64], q: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """:func:`closest_point_on_polyline` of checked vertices (P, 2) and queries (K, 2)."""
    qx = q[:, 0].reshape(-1, 1)  # (K, 1)
    qy = q[:, 1].reshape(-1, 1)
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

    return np.stack([cx, cy], -1), np.stack([nx, ny], -1), sign * dist, seg


# --------------------------------------------------------------------------------------------
# Quaternions (x, y, z, w): the order of geometry_msgs/Quaternion and of pybullet.
# --------------------------------------------------------------------------------------------
#: The one quaternion rule of the pipeline: a quaternion is accepted when it is finite and its
#: norm is within this of 1 (it is then normalised); a *planar* orientation (a yaw, every
#: reader of a planar pose) also needs ``|q_x|, |q_y|`` at most this (a rotation about z).
QUATERNION_TOLERANCE = 1e-3


class NonFiniteError(ValueError):
    """A value holds NaN or infinity (a ``ValueError``, so callers may lump it in)."""


def check_quaternion(q: ArrayLike) -> NDArray[np.float64]:
    """Validate a quaternion (x, y, z, w) and return it normalised, shape (4,).

    Raises
    ------
    NonFiniteError
        A NaN or infinite component.
    ValueError
        Not 4 values, (near) zero norm, or a norm further than :data:`QUATERNION_TOLERANCE`
        from 1.
    """
    v = np.asarray(q, dtype=float)
    if v.shape != (4,):
        raise ValueError(f"quaternion must be 4 numbers (x, y, z, w), got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise NonFiniteError(f"quaternion (x, y, z, w) = {v.tolist()} is not finite")
    norm = float(np.linalg.norm(v))
    if norm < 1e-9:
        raise ValueError("quaternion has zero norm")
    if abs(norm - 1.0) > QUATERNION_TOLERANCE:
        raise ValueError(f"quaternion (x, y, z, w) = {v.tolist()} is not unit length "
                         f"(norm {norm:.6g}, tolerance {QUATERNION_TOLERANCE})")
    return v / norm


def quaternion_from_yaw(theta: float) -> NDArray[np.float64]:
    """Quaternion (x, y, z, w) = (0, 0, sin(theta / 2), cos(theta / 2)) of a yaw, radians."""
    half = 0.5 * float(theta)
    return np.array([0.0, 0.0, np.sin(half), np.cos(half)])


def yaw_from_quaternion(q: ArrayLike) -> float:
    """Yaw (radians in (-pi, pi]) of a planar orientation quaternion (x, y, z, w).

    The planarity rule (:data:`QUATERNION_TOLERANCE`): unit norm and ``|q_x|, |q_y|`` at most
    the tolerance, i.e. a rotation about z; the yaw is the z angle of the ZYX decomposition.

    Raises
    ------
    NonFiniteError
        A NaN or infinite component.
    ValueError
        See :func:`check_quaternion`; or a rotation that is not about z.
    """
    x, y, z, w = check_quaternion(q)
    if max(abs(x), abs(y)) > QUATERNION_TOLERANCE:
        raise ValueError(f"quaternion (x, y, z, w) = {[x, y, z, w]} is not a rotation about z "
                         f"(a planar pose has |q_x|, |q_y| <= {QUATERNION_TOLERANCE})")
    return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def matrix_from_quaternion(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix (3, 3) of a quaternion (x, y, z, w) (see :func:`check_quaternion`)."""
    x, y, z, w = check_quaternion(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def quaternion_from_matrix(rotation: ArrayLike) -> NDArray[np.float64]:
    """Quaternion (x, y, z, w) with ``w >= 0`` of a proper rotation matrix (3, 3).

    Raises
    ------
    ValueError
        If the matrix is not finite, not orthonormal or has determinant <= 0 (to 1e-6).
    """
    r = np.asarray(rotation, dtype=float)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"rotation must be a finite (3, 3) array, got shape {r.shape}")
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) <= 0:
        raise ValueError("rotation must be orthonormal with determinant +1")
    # Shepperd's method: pivot on the largest of w, x, y, z for numerical stability.
    trace = np.trace(r)
    i = int(np.argmax([trace, r[0, 0], r[1, 1], r[2, 2]]))
    if i == 0:
        s = 2.0 * np.sqrt(1.0 + trace)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4]
    elif i == 1:
        s = 2.0 * np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s]
    elif i == 2:
        s = 2.0 * np.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4, (r[1, 0] - r[0, 1]) / s]
    quat = np.asarray(q, dtype=float)
    quat /= np.linalg.norm(quat)
    return -quat if quat[3] < 0 else quat
