"""The outline as the push EKF sees it: contact queries and the polygon's area properties.

ROS-free; object frame, metres. :class:`ContactOutline` is the perceived outline prepared for
the process model (:mod:`push_core.estimator.process_model`): validated, decimated to a
counter-clockwise polygon (Douglas-Peucker), with per-segment tangents and outward normals,
the closest-feature search of the contact test (a Python loop over outlines of at most
``_SMALL_POLYGON`` segments, vectorised over larger ones: numpy calls on 2-vectors cost more
than the arithmetic), the clip of a COM estimate to the outline's convex hull (a rigid object's
COM lies inside it) and the quantities of the filter's prior: the area's second moment matrix
(:func:`area_second_moment`, the covariance of "COM anywhere in the object, uniformly") and the
exact uniform-pressure limit-surface parameter (:func:`limit_surface_of_polygon`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull

from push_core.geometry import check_points, closest_point_on_polyline
from push_core.shapes import Polygon
from push_core.symmetry import symmetry_order_of_polygon

__all__ = ["ContactOutline", "area_second_moment", "limit_surface_of_polygon"]

#: Outlines with at most this many segments are searched in a Python loop, larger ones in numpy.
_SMALL_POLYGON = 16


def limit_surface_of_polygon(vertices: ArrayLike, com: ArrayLike = (0.0, 0.0)) -> float:
    """Limit-surface parameter ``l`` of a polygon under uniform pressure, exactly.

    ``l`` = mean distance of the area from the centre of mass (maximum friction torque over
    maximum friction force for uniform pressure; ``2R/3`` for a disc of radius R), the quantity
    :meth:`push_core.objects.ObjectSpec.limit_surface_guess` estimates by sampling.

    Parameters
    ----------
    vertices : array_like, shape (P, 2)
        Closed counter-clockwise polygon, metres (may be non-convex).
    com : array_like, shape (2,)
        Centre of mass in the same frame, metres.

    Returns
    -------
    float
        ``l`` in metres.

    Notes
    -----
    Sum over the edges of the signed triangles (com, a, b): in polar coordinates about the COM,
    ``int |p| dA = int rho(phi)^3 / 3 dphi`` with ``rho = h / cos(psi)``, which integrates to
    ``F(t) = (h |p| t + h^3 asinh(t / h)) / 6`` along the edge (``h`` distance of the edge's line
    from the COM, ``t`` coordinate along the edge from the foot of the perpendicular).
    """
    v = Polygon(vertices, field="vertices").vertices - np.asarray(
        check_points(com, "com"), dtype=np.float64)
    a, b = v, np.roll(v, -1, axis=0)
    edge = b - a
    length = np.hypot(edge[:, 0], edge[:, 1])
    e = edge / length[:, None]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    h = np.abs(cross) / length
    keep = h > 1e-15  # edges whose line passes through the COM add nothing
    t_a = np.sum(a * e, axis=1)
    t_b = np.sum(b * e, axis=1)
    hk = np.where(keep, h, 1.0)

    def primitive(t: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
        r = np.hypot(p[:, 0], p[:, 1])
        return (hk * r * t + hk**3 * np.arcsinh(t / hk)) / 6.0

    integral = np.sign(cross) * (primitive(t_b, b) - primitive(t_a, a))
    area = 0.5 * float(np.sum(cross))
    return float(np.sum(np.where(keep, integral, 0.0)) / area)


def area_second_moment(vertices: ArrayLike) -> NDArray[np.float64]:
    """Second moment matrix of a polygon's area about the frame origin, per unit area.

    Parameters
    ----------
    vertices : array_like, shape (P, 2)
        Closed counter-clockwise polygon, metres.

    Returns
    -------
    numpy.ndarray, shape (2, 2)
        ``[[E x^2, E xy], [E xy, E y^2]]`` for a point uniformly distributed over the area, m^2
        (its covariance when the origin is the area centroid).
    """
    v = Polygon(vertices, field="vertices").vertices
    a, b = v, np.roll(v, -1, axis=0)
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]  # twice the signed area of (0, a, b)
    sxx = np.sum(cross * (a[:, 0] ** 2 + a[:, 0] * b[:, 0] + b[:, 0] ** 2)) / 12.0
    syy = np.sum(cross * (a[:, 1] ** 2 + a[:, 1] * b[:, 1] + b[:, 1] ** 2)) / 12.0
    sxy = np.sum(cross * (2 * a[:, 0] * a[:, 1] + a[:, 0] * b[:, 1] + b[:, 0] * a[:, 1]
                          + 2 * b[:, 0] * b[:, 1])) / 24.0
    area = 0.5 * np.sum(cross)
    return np.array([[sxx, sxy], [sxy, syy]]) / area


@dataclass(frozen=True)
class ContactOutline:
    """The perceived outline prepared for contact queries: a decimated CCW polygon.

    Build it with :meth:`from_points`. Object frame, metres.

    Attributes
    ----------
    vertices : numpy.ndarray, shape (P, 2)
        Decimated polygon, counter-clockwise.
    tangents : numpy.ndarray, shape (P, 2)
        Unit direction of segment i (vertex i -> i + 1).
    lengths : numpy.ndarray, shape (P,)
        Segment lengths.
    normals : numpy.ndarray, shape (P, 2)
        Outward unit normal of segment i.
    convex : numpy.ndarray of bool, shape (P,)
        Whether vertex i is convex.
    area : float
        Area of the full (undecimated) outline, m^2.
    area_moment : numpy.ndarray, shape (2, 2)
        Second moment matrix of the area about the origin divided by the area, m^2: the
        covariance of a point uniformly distributed over the object.
    limit_surface : float
        ``l_0``: uniform-pressure ``l`` about the origin (:func:`limit_surface_of_polygon`).
    radius : float
        Largest distance of the outline from the origin, m.
    symmetry_order : int
        Rotational symmetry order used for the orientation (1 = none).
    """

    vertices: NDArray[np.float64]
    tangents: NDArray[np.float64]
    lengths: NDArray[np.float64]
    normals: NDArray[np.float64]
    convex: NDArray[np.bool_]
    area: float
    area_moment: NDArray[np.float64]
    limit_surface: float
    radius: float
    symmetry_order: int
    #: Python-float copies of the arrays for the scalar model (numpy indexing costs more than
    #: the arithmetic there): per segment (a_x, a_y, t_x, t_y, n_x, n_y), convex flags.
    _segments: tuple[tuple[float, ...], ...] = field(default=(), repr=False, compare=False)
    _convex: tuple[bool, ...] = field(default=(), repr=False, compare=False)
    _lengths: tuple[float, ...] = field(default=(), repr=False, compare=False)
    #: Contiguous columns (a_x, a_y, t_x, t_y) for the vectorised closest-feature search.
    _columns: tuple[NDArray[np.float64], ...] = field(default=(), repr=False, compare=False)
    #: Convex hull edges (a_x, a_y, t_x, t_y, length, n_x, n_y), counter-clockwise.
    _hull: tuple[tuple[float, ...], ...] = field(default=(), repr=False, compare=False)

    def __post_init__(self) -> None:
        segments = tuple(tuple(row) for row in np.hstack(
            [self.vertices, self.tangents, self.normals]).tolist())
        object.__setattr__(self, "_segments", segments)
        object.__setattr__(self, "_convex", tuple(bool(c) for c in self.convex))
        object.__setattr__(self, "_lengths", tuple(self.lengths.tolist()))
        object.__setattr__(self, "_columns", tuple(np.ascontiguousarray(a) for a in (
            self.vertices[:, 0], self.vertices[:, 1], self.tangents[:, 0], self.tangents[:, 1])))
        hull = self.vertices[ConvexHull(self.vertices).vertices]  # counter-clockwise in 2-D
        edge = np.roll(hull, -1, axis=0) - hull
        length = np.hypot(edge[:, 0], edge[:, 1])
        t = edge / length[:, None]
        object.__setattr__(self, "_hull", tuple(tuple(row) for row in np.column_stack(
            [hull, t, length, t[:, 1], -t[:, 0]]).tolist()))

    def clip_to_hull(self, x: float, y: float) -> tuple[float, float]:
        """The point of the outline's convex hull closest to ``(x, y)`` (object frame, m).

        A rigid object's centre of mass lies inside the convex hull of its outline; the filter
        projects its COM estimate onto it. Points inside are returned unchanged.
        """
        if all(nx * (x - ax) + ny * (y - ay) <= 0.0 for ax, ay, _, _, _, nx, ny in self._hull):
            return x, y
        best, out = math.inf, (x, y)
        for ax, ay, ex, ey, length, _, _ in self._hull:
            s = min(max((x - ax) * ex + (y - ay) * ey, 0.0), length)
            px, py = ax + s * ex, ay + s * ey
            d2 = (x - px) ** 2 + (y - py) ** 2
            if d2 < best:
                best, out = d2, (px, py)
        return out

    @classmethod
    def from_points(cls, points: ArrayLike, normals: ArrayLike | None = None, *,
                    tolerance: float = 5e-4, symmetry_order: int = 1,
                    symmetry_tolerance: float = 1e-3) -> ContactOutline:
        """Validate a perceived outline and decimate it.

        Parameters
        ----------
        points : array_like, shape (N, 2)
            Outline points in the object frame (origin at the area centroid), metres, ordered
            counter-clockwise along the outline (a closed polyline), ``N >= 3``.
        normals : array_like, shape (N, 2), optional
            Outward unit normals at ``points``; only checked (unit length, pointing outward).
            Contact normals come from the decimated polygon's segments.
        tolerance : float
            Douglas-Peucker tolerance, m.
        symmetry_order : int
            1 = none, k > 1 = k-fold, 0 = detect (:func:`symmetry_order_of_polygon`).
        symmetry_tolerance : float
            Tolerance of the detection, m.

        Raises
        ------
        ValueError
            Naming ``points`` or ``normals``: wrong shape, non-finite values, fewer than 3
            points, clockwise or self-intersecting outline, normals that are not unit or point
            inward.
        """
        pts = np.asarray(check_points(points, "points"), dtype=np.float64)
        if pts.ndim != 2 or len(pts) < 3:
            raise ValueError(f"points must have shape (N, 2) with N >= 3, got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ValueError("points must be finite")
        polygon = Polygon(pts, field="points")  # raises on clockwise / self-intersecting
        if normals is not None:
            _check_outline_normals(pts, normals)
        if not tolerance > 0.0:
            raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
        order = int(symmetry_order)
        if order == 0:
            order = symmetry_order_of_polygon(polygon.vertices, symmetry_tolerance)
        elif order < 0:
            raise ValueError(f"symmetry_order must be >= 0, got {symmetry_order!r}")
        v = polygon.simplified(tolerance).vertices
        edge = np.roll(v, -1, axis=0) - v
        lengths = np.hypot(edge[:, 0], edge[:, 1])
        tangents = edge / lengths[:, None]
        prev = np.roll(tangents, 1, axis=0)
        convex = prev[:, 0] * tangents[:, 1] - prev[:, 1] * tangents[:, 0] > 0.0
        arrays = {
            "vertices": v, "tangents": tangents, "lengths": lengths,
            "normals": np.stack([tangents[:, 1], -tangents[:, 0]], axis=1), "convex": convex,
        }
        arrays["area_moment"] = area_second_moment(polygon.vertices)
        for a in arrays.values():
            a.setflags(write=False)
        return cls(**arrays, area=float(polygon.area),
                   limit_surface=limit_surface_of_polygon(polygon.vertices),
                   radius=float(np.max(np.hypot(pts[:, 0], pts[:, 1]))),
                   symmetry_order=order)

    def closest_feature(self, qx: float, qy: float) -> tuple[int, int]:
        """Closest feature of the polygon to the point ``(qx, qy)`` (object frame).

        Returns
        -------
        kind, index : int, int
            ``(0, i)``: the interior of segment i; ``(1, i)``: vertex i.
        """
        if len(self._segments) <= _SMALL_POLYGON:  # a Python loop beats numpy's overhead
            best, i, si = math.inf, 0, 0.0
            for j, (ax, ay, ex, ey, _, _) in enumerate(self._segments):
                rx, ry = qx - ax, qy - ay
                s = min(max(rx * ex + ry * ey, 0.0), self._lengths[j])
                dx, dy = rx - s * ex, ry - s * ey
                d2 = dx * dx + dy * dy
                if d2 < best:  # the first of equal minima, as numpy's argmin
                    best, i, si = d2, j, s
        else:
            ax, ay, ex, ey = self._columns
            rx, ry = qx - ax, qy - ay
            s = np.minimum(np.maximum(rx * ex + ry * ey, 0.0), self.lengths)
            dx, dy = rx - s * ex, ry - s * ey
            i = int(np.argmin(dx * dx + dy * dy))
            si = float(s[i])
        if si <= 0.0:
            return 1, i
        if si >= self._lengths[i]:
            return 1, (i + 1) % len(self._lengths)
        return 0, i


def _check_outline_normals(points: NDArray[np.float64], normals: ArrayLike) -> None:
    n = np.asarray(check_points(normals, "normals"), dtype=np.float64)
    if n.shape != points.shape:
        raise ValueError(f"normals must have the shape of points {points.shape}, got {n.shape}")
    if not np.all(np.isfinite(n)):
        raise ValueError("normals must be finite")
    norm = np.hypot(n[:, 0], n[:, 1])
    if np.any(np.abs(norm - 1.0) > 1e-3):
        raise ValueError(f"normals must be unit vectors, got norms in [{norm.min():.4g}, "
                         f"{norm.max():.4g}]")
    _, seg_normals, _, _ = closest_point_on_polyline(points, points)
    outward = np.mean(np.sum(n * seg_normals, axis=1) > 0.0)
    if outward < 0.9:
        raise ValueError(f"normals must point outward (counter-clockwise outline), but only "
                         f"{100 * outward:.0f} % do")
