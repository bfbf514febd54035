"""Transit planning for a pusher that cannot lift: a collision-free way to the approach point.

A planar pusher (a disc of radius ``r``) that stays on the table must travel from where it is to
the approach point of the next push without touching the object or any obstacle. This module
finds the shortest such path among polygonal obstacles, inside a rectangular workspace, with a
visibility graph (Lozano-Perez and Wesley 1979):

- every obstacle (the object at its current pose, walls, other objects: simple polygons, any
  orientation) is kept at ``clearance`` (at least the pusher radius) from the pusher centre;
- the graph's nodes are the start, the goal and, at every convex vertex of every obstacle,
  ``CORNER_SAMPLES`` points at distance ``clearance / cos(half the angle between them)`` in the
  vertex's normal cone (the offset polygon's rounded corner, circumscribed so the chords between
  them keep the clearance); nodes outside the workspace or too close to an obstacle are dropped;
- an edge joins two nodes when the segment between them keeps ``clearance`` from every
  obstacle edge and does not cross an obstacle (vectorised segment-segment distances);
- Dijkstra (``scipy.sparse.csgraph``) from the start gives the shortest path to the goal and the
  travel length to any number of goals at once (:meth:`TransitPlanner.lengths`, the travel cost
  of push selection in :meth:`push_core.planner.Planner.plan`).

A start (or goal) closer than ``clearance`` to an obstacle, such as a pusher still touching the
object after a push, first retreats straight away from the nearest obstacle point to
``clearance`` (``retreat`` in the path); the retreat itself is the only motion allowed closer.

Frames and units: every point is in one common frame (``world``), metres (any unit works if all
inputs share it). Paths are arrays (K, 2) of waypoints from start to goal.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from push_core.geometry import check_polyline
from push_core.shapes import polygon_signed_area

__all__ = ["CORNER_SAMPLES", "TransitPlanner", "ccw_polygon", "point_polygon_distance",
           "segment_polygon_clear"]

#: Nodes per convex obstacle corner (spread over its normal cone, both edge normals included).
CORNER_SAMPLES = 3
#: Nodes sit this much beyond the circumscribed clearance (relative), so they test clear.
_NODE_SLACK = 1.02


def ccw_polygon(vertices: ArrayLike, name: str = "polygon") -> NDArray[np.float64]:
    """A simple polygon's vertices (P, 2), float64, counter-clockwise: clockwise input is
    reversed (the polygon is the same), anything else is checked by
    :func:`push_core.geometry.check_polyline` (``ValueError`` naming ``name``)."""
    try:
        v = np.array(vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected (P, 2) numbers, got {vertices!r}") from None
    if v.ndim == 2 and v.shape[1:] == (2,) and len(v) >= 3 and np.all(np.isfinite(v)) \
            and polygon_signed_area(v) < 0.0:
        v = v[::-1].copy()
    return check_polyline(v, name)


def _edges(polygons: Sequence[NDArray[np.float64]]) -> tuple[NDArray[np.float64],
                                                               NDArray[np.float64]]:
    a = np.concatenate([p for p in polygons]) if polygons else np.zeros((0, 2))
    b = np.concatenate([np.roll(p, -1, axis=0) for p in polygons]) if polygons else np.zeros((0, 2))
    return a, b


def _point_segment_distance(p: NDArray[np.float64], a: NDArray[np.float64],
                            b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance of points ``p`` (..., 2) from segments ``a -> b`` (..., 2), broadcast."""
    ab = b - a
    denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-300)
    t = np.clip(np.sum((p - a) * ab, axis=-1) / denom, 0.0, 1.0)
    d = p - (a + t[..., None] * ab)
    return np.hypot(d[..., 0], d[..., 1])


def _inside(points: NDArray[np.float64], polygon: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Even-odd point-in-polygon test, vectorised over points (Q, 2)."""
    x, y = points[:, 0:1], points[:, 1:2]
    a, b = polygon, np.roll(polygon, -1, axis=0)
    crosses = (a[None, :, 1] > y) != (b[None, :, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (
            b[None, :, 1] - a[None, :, 1])
    return (np.count_nonzero(crosses & (x < xi), axis=1) % 2) == 1


def point_polygon_distance(points: ArrayLike, polygon: ArrayLike) -> NDArray[np.float64]:
    """Signed distance of points from a simple polygon: negative inside.

    Parameters
    ----------
    points : array_like, shape (Q, 2)
    polygon : array_like, shape (P, 2)
        Vertices, either orientation.

    Returns
    -------
    numpy.ndarray, shape (Q,)
        Distance to the nearest edge (same unit as the inputs), negated for points inside.
    """
    q = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    poly = np.asarray(polygon, dtype=np.float64)
    a, b = poly, np.roll(poly, -1, axis=0)
    d = _point_segment_distance(q[:, None, :], a[None], b[None]).min(axis=1)
    return np.where(_inside(q, poly), -d, d)


def _segments_distance(p0: NDArray[np.float64], p1: NDArray[np.float64],
                       a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance between segments ``p0 -> p1`` (M, 2) and ``a -> b`` (E, 2): (M, E)."""
    P0, P1 = p0[:, None, :], p1[:, None, :]  # noqa: N806
    A, B = a[None], b[None]  # noqa: N806
    d = np.minimum.reduce([_point_segment_distance(P0, A, B), _point_segment_distance(P1, A, B),
                           _point_segment_distance(A, P0, P1), _point_segment_distance(B, P0, P1)])

    def cross(o, u, v):
        return (u[..., 0] - o[..., 0]) * (v[..., 1] - o[..., 1]) - (
            u[..., 1] - o[..., 1]) * (v[..., 0] - o[..., 0])

    d1, d2 = cross(P0, P1, A), cross(P0, P1, B)
    d3, d4 = cross(A, B, P0), cross(A, B, P1)
    crossing = (d1 * d2 < 0.0) & (d3 * d4 < 0.0)
    return np.where(crossing, 0.0, d)


def segment_polygon_clear(starts: ArrayLike, ends: ArrayLike, polygons: Sequence[ArrayLike],
                          clearance: float) -> NDArray[np.bool_]:
    """Whether each segment keeps ``clearance`` from every polygon (and is outside them all).

    Parameters
    ----------
    starts, ends : array_like, shape (M, 2)
        Segment end points.
    polygons : sequence of array_like, each (P_i, 2)
        Simple polygons, either orientation.
    clearance : float
        Smallest allowed distance, >= 0.

    Returns
    -------
    numpy.ndarray of bool, shape (M,)
    """
    p0 = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
    p1 = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
    clear = np.ones(len(p0), dtype=bool)
    if not polygons or len(p0) == 0:
        return clear
    polys = [np.asarray(p, dtype=np.float64) for p in polygons]
    a, b = _edges(polys)
    for i in range(0, len(p0), 4096):  # bounded memory: 4096 x E pairs at a time
        sl = slice(i, i + 4096)
        d = _segments_distance(p0[sl], p1[sl], a, b).min(axis=1)
        clear[sl] = (d >= clearance) & (d > 0.0)  # touching or crossing is never clear
    for poly in polys:  # a segment wholly inside a polygon touches no edge
        clear &= ~_inside(p0, poly)
    return clear


class TransitPlanner:
    """Shortest collision-free pusher paths among polygonal obstacles (module docstring).

    Parameters
    ----------
    obstacles : sequence of array_like, each (P_i, 2)
        Simple polygons the pusher centre must keep ``clearance`` from (world frame); either
        orientation. The object being pushed is one of them.
    clearance : float
        Smallest distance between the pusher centre and an obstacle (at least the pusher
        radius; add a margin for tracking error), > 0.
    workspace : ((xmin, xmax), (ymin, ymax)), optional
        Rectangle the pusher centre must stay in (any position, not necessarily centred).

    Raises
    ------
    ValueError
        Naming ``obstacles[i]``, ``clearance`` or ``workspace``.
    """

    def __init__(self, obstacles: Sequence[ArrayLike], clearance: float,
                 workspace: tuple[tuple[float, float], tuple[float, float]] | None = None
                 ) -> None:
        if not (isinstance(clearance, int | float) and math.isfinite(clearance)
                and clearance > 0.0):
            raise ValueError(f"clearance: expected a finite number > 0, got {clearance!r}")
        self.clearance = float(clearance)
        self.obstacles = [ccw_polygon(p, f"obstacles[{i}]") for i, p in enumerate(obstacles)]
        self.workspace = None
        if workspace is not None:
            ws = np.asarray(workspace, dtype=np.float64)
            if ws.shape != (2, 2) or not np.all(np.isfinite(ws)) or np.any(ws[:, 1] <= ws[:, 0]):
                raise ValueError(f"workspace: expected ((xmin, xmax), (ymin, ymax)) with "
                                 f"min < max, got {workspace!r}")
            self.workspace = ws
        self._edge_a, self._edge_b = _edges(self.obstacles)
        self.nodes = self._corner_nodes()
        self._graph = self._visibility(self.nodes)

    # ---- geometry ----------------------------------------------------------------------------
    def _corner_nodes(self) -> NDArray[np.float64]:
        nodes = []
        for poly in self.obstacles:
            prev, nxt = np.roll(poly, 1, axis=0), np.roll(poly, -1, axis=0)
            e_in, e_out = poly - prev, nxt - poly
            convex = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0] > 0.0
            n_in = np.stack([e_in[:, 1], -e_in[:, 0]], -1)
            n_out = np.stack([e_out[:, 1], -e_out[:, 0]], -1)
            n_in /= np.linalg.norm(n_in, axis=1, keepdims=True)
            n_out /= np.linalg.norm(n_out, axis=1, keepdims=True)
            a0 = np.arctan2(n_in[:, 1], n_in[:, 0])
            turn = np.arctan2(n_in[:, 0] * n_out[:, 1] - n_in[:, 1] * n_out[:, 0],
                              np.sum(n_in * n_out, axis=1))  # in (0, pi) at convex corners
            for i in np.flatnonzero(convex):
                gap = turn[i] / (CORNER_SAMPLES - 1)
                radius = _NODE_SLACK * self.clearance / math.cos(min(gap / 2.0, 1.2))
                angles = a0[i] + gap * np.arange(CORNER_SAMPLES)
                nodes.append(poly[i] + radius * np.stack([np.cos(angles), np.sin(angles)], -1))
        if not nodes:
            return np.zeros((0, 2))
        cand = np.concatenate(nodes)
        return cand[self._free(cand)]

    def _in_workspace(self, points: NDArray[np.float64]) -> NDArray[np.bool_]:
        if self.workspace is None:
            return np.ones(len(points), dtype=bool)
        (x0, x1), (y0, y1) = self.workspace
        return ((points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 1] >= y0)
                & (points[:, 1] <= y1))

    def _free(self, points: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Points inside the workspace at ``clearance`` or more from every obstacle."""
        ok = self._in_workspace(points)
        for poly in self.obstacles:
            ok &= point_polygon_distance(points, poly) >= self.clearance * (1.0 - 1e-9)
        return ok

    def _visibility(self, nodes: NDArray[np.float64]) -> NDArray[np.float64]:
        """Dense (n, n) matrix of edge lengths, 0 where two nodes do not see each other."""
        n = len(nodes)
        i, j = np.triu_indices(n, k=1)
        ok = segment_polygon_clear(nodes[i], nodes[j], self.obstacles, self.clearance * 0.999)
        w = np.zeros((n, n))
        d = np.linalg.norm(nodes[i] - nodes[j], axis=1)
        w[i[ok], j[ok]] = d[ok]
        w[j[ok], i[ok]] = d[ok]
        return w

    def retreat(self, point: ArrayLike) -> NDArray[np.float64]:
        """``point`` moved straight away from the nearest obstacle until it has ``clearance``
        (``point`` itself if it already has; inside an obstacle: out through the nearest edge).
        """
        p = np.asarray(point, dtype=np.float64).reshape(2)
        for _ in range(len(self.obstacles) + 1):
            if not self.obstacles:
                return p
            dist = np.array([point_polygon_distance(p[None], poly)[0] for poly in self.obstacles])
            k = int(np.argmin(dist))
            if dist[k] >= self.clearance * (1.0 - 1e-9):
                return p
            poly = self.obstacles[k]
            a, b = poly, np.roll(poly, -1, axis=0)
            ab = b - a
            t = np.clip(np.sum((p - a) * ab, axis=1) / np.sum(ab * ab, axis=1), 0.0, 1.0)
            foot = a + t[:, None] * ab
            e = int(np.argmin(np.linalg.norm(p - foot, axis=1)))
            away = p - foot[e]
            norm = float(np.linalg.norm(away))
            if norm < 1e-12 or dist[k] < 0.0:  # on or inside: leave along the edge normal
                away = np.array([ab[e, 1], -ab[e, 0]]) / np.linalg.norm(ab[e])
                norm = 1.0
                p = foot[e] + away * (_NODE_SLACK * self.clearance)
            else:
                p = foot[e] + away / norm * (_NODE_SLACK * self.clearance)
        return p

    # ---- queries -----------------------------------------------------------------------------
    def _search(self, start: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                           NDArray[np.float64],
                                                           NDArray[np.intp]]:
        """Dijkstra from ``start`` (already clear) over the corner nodes: distances, the
        nodes with the start appended last, predecessors."""
        nodes = np.vstack([self.nodes, start[None]])
        n = len(nodes)
        w = np.zeros((n, n))
        w[:-1, :-1] = self._graph
        if n > 1:
            ok = segment_polygon_clear(np.repeat(start[None], n - 1, 0), self.nodes,
                                       self.obstacles, self.clearance * 0.999)
            d = np.linalg.norm(self.nodes - start, axis=1)
            w[-1, :-1] = np.where(ok, d, 0.0)
            w[:-1, -1] = w[-1, :-1]
        dist, pred = dijkstra(csr_matrix(w), directed=False, indices=n - 1,
                              return_predecessors=True)
        return dist, nodes, pred

    def lengths(self, start: ArrayLike, goals: ArrayLike) -> NDArray[np.float64]:
        """Length of the shortest path from ``start`` to each goal (``inf`` if none).

        Parameters
        ----------
        start : array_like, shape (2,)
        goals : array_like, shape (B, 2)

        Returns
        -------
        numpy.ndarray, shape (B,)
            Including the retreats of the start and of each goal (see :meth:`retreat`).
        """
        s0 = np.asarray(start, dtype=np.float64).reshape(2)
        g0 = np.asarray(goals, dtype=np.float64).reshape(-1, 2)
        if len(g0) == 0:
            return np.zeros(0)
        s = self.retreat(s0)
        g = np.array([self.retreat(q) for q in g0])
        dist, nodes, _ = self._search(s)
        reach = np.isfinite(dist)
        idx = np.flatnonzero(reach)
        # goals x reachable nodes visibility
        gi = np.repeat(g, len(idx), axis=0)
        ni = np.tile(nodes[idx], (len(g), 1))
        ok = segment_polygon_clear(ni, gi, self.obstacles, self.clearance * 0.999)
        ok = ok.reshape(len(g), len(idx))
        via = dist[idx][None, :] + np.linalg.norm(g[:, None, :] - nodes[idx][None], axis=-1)
        best = np.where(ok, via, np.inf).min(axis=1)
        best = np.where(self._in_workspace(g) | (self.workspace is None), best, np.inf)
        return (best + np.linalg.norm(s - s0) + np.linalg.norm(g - g0, axis=1))

    def path(self, start: ArrayLike, goal: ArrayLike) -> NDArray[np.float64] | None:
        """Shortest path of waypoints (K, 2) from ``start`` to ``goal``, or None if there is
        none. Begins with ``start`` (and its retreat if it is too close to an obstacle) and
        ends with the goal's retreat point and ``goal``."""
        s0 = np.asarray(start, dtype=np.float64).reshape(2)
        g0 = np.asarray(goal, dtype=np.float64).reshape(2)
        s, g = self.retreat(s0), self.retreat(g0)
        dist, nodes, pred = self._search(s)
        idx = np.flatnonzero(np.isfinite(dist))
        ok = segment_polygon_clear(nodes[idx], np.repeat(g[None], len(idx), 0),
                                   self.obstacles, self.clearance * 0.999)
        if not ok.any() or not self._in_workspace(g[None])[0]:
            return None
        via = dist[idx] + np.linalg.norm(nodes[idx] - g, axis=1)
        k = int(idx[np.flatnonzero(ok)[np.argmin(via[ok])]])
        chain = [k]
        while pred[chain[-1]] >= 0:
            chain.append(int(pred[chain[-1]]))
        points = [s0, *(nodes[c] for c in reversed(chain)), g, g0]
        out = [points[0]]
        for q in points[1:]:
            if np.linalg.norm(q - out[-1]) > 1e-9:
                out.append(q)
        return np.array(out)
