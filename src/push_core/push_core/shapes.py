"""Planar object shapes: validated polygons and ellipses, outlines, decompositions.

All coordinates are metres in the shape's own 2-D frame (the object frame once the object
library has centred the shape on its area centroid). Polygons are simple and counter-clockwise.
Outlines are ordered counter-clockwise and carry outward unit normals.

Every validation error is a ``ValueError`` whose message starts with the name of the offending
field (``field`` argument, for example ``"shape.vertices"``), so that an object specification
file can report which entry is wrong.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Ellipse", "Polygon", "Shape", "polygon_signed_area"]

_EPS = 1e-12


def polygon_signed_area(vertices: np.ndarray) -> float:
    """Signed area of a closed polygon (shoelace formula).

    Parameters
    ----------
    vertices : (P, 2) array
        Polygon vertices; the closing edge from the last to the first vertex is implied.

    Returns
    -------
    float
        Area in m^2, positive for counter-clockwise vertex order.
    """
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _self_intersections(vertices: np.ndarray) -> list[tuple[int, int]]:
    """Pairs (i, j) of non-adjacent edges that intersect or touch.

    Edge i runs from vertex i to vertex i+1 (closed). Vectorised over all pairs.
    """
    p = vertices
    q = np.roll(vertices, -1, axis=0)
    n = len(p)
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # the closing edge is adjacent to edge 0
    scale = max(float(np.ptp(vertices)), _EPS)
    # Edges whose bounding boxes (grown by the touching margin) are apart can neither cross
    # nor touch: only the other pairs go through the exact tests below (the same answer).
    lo, hi = np.minimum(p, q) - 1e-9 * scale, np.maximum(p, q) + 1e-9 * scale
    keep &= np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=-1)
    i, j = i[keep], j[keep]
    a, b, c, d = p[i], q[i], p[j], q[j]
    tol = 1e-9 * scale * scale
    d1 = _cross(b - a, c - a)
    d2 = _cross(b - a, d - a)
    d3 = _cross(d - c, a - c)
    d4 = _cross(d - c, b - c)
    proper = (((d1 > tol) & (d2 < -tol)) | ((d1 < -tol) & (d2 > tol))) & (
        ((d3 > tol) & (d4 < -tol)) | ((d3 < -tol) & (d4 > tol))
    )

    def on_segment(s0, s1, pt, orient):
        lo = np.minimum(s0, s1) - 1e-9 * scale
        hi = np.maximum(s0, s1) + 1e-9 * scale
        inside = np.all((pt >= lo) & (pt <= hi), axis=-1)
        return (np.abs(orient) <= tol) & inside

    touching = (
        on_segment(a, b, c, d1)
        | on_segment(a, b, d, d2)
        | on_segment(c, d, a, d3)
        | on_segment(c, d, b, d4)
    )
    bad = proper | touching
    return list(zip(i[bad].tolist(), j[bad].tolist(), strict=True))


def _triangulate(vertices: np.ndarray) -> list[tuple[int, int, int]]:
    """Ear-clipping triangulation of a simple counter-clockwise polygon (vertex indices)."""
    idx = list(range(len(vertices)))
    tris: list[tuple[int, int, int]] = []
    guard = 0
    while len(idx) > 3:
        guard += 1
        if guard > 10 * len(vertices) ** 2:
            raise ValueError("polygon could not be triangulated (degenerate geometry)")
        m = len(idx)
        pts = vertices[idx]
        prev = np.roll(pts, 1, axis=0)
        nxt = np.roll(pts, -1, axis=0)
        convex = _cross(pts - prev, nxt - pts) > _EPS
        clipped = False
        for k in np.flatnonzero(convex):
            a, b, c = prev[k], pts[k], nxt[k]
            others = np.delete(pts, [(k - 1) % m, k, (k + 1) % m], axis=0)
            if len(others):
                # Reject the ear when any other vertex lies inside or on the triangle.
                w1 = _cross(b - a, others - a)
                w2 = _cross(c - b, others - b)
                w3 = _cross(a - c, others - c)
                if np.any((w1 >= -_EPS) & (w2 >= -_EPS) & (w3 >= -_EPS)):
                    continue
            tris.append((idx[(k - 1) % m], idx[k], idx[(k + 1) % m]))
            del idx[k]
            clipped = True
            break
        if not clipped:
            raise ValueError("polygon could not be triangulated (not simple?)")
    tris.append((idx[0], idx[1], idx[2]))
    return tris


def _douglas_peucker(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices of an open polyline kept by Douglas-Peucker simplification."""
    keep = np.zeros(len(points), dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, len(points) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        a, b = points[i], points[j]
        seg = b - a
        length = np.linalg.norm(seg)
        rel = points[i + 1 : j] - a
        if length < _EPS:
            dist = np.linalg.norm(rel, axis=1)
        else:
            dist = np.abs(_cross(seg, rel)) / length
        k = int(np.argmax(dist))
        if dist[k] > tolerance:
            keep[i + 1 + k] = True
            stack += [(i, i + 1 + k), (i + 1 + k, j)]
    return np.flatnonzero(keep)


def _is_convex_ccw(vertices: np.ndarray) -> bool:
    prev = np.roll(vertices, 1, axis=0)
    nxt = np.roll(vertices, -1, axis=0)
    return bool(np.all(_cross(vertices - prev, nxt - vertices) >= -1e-15))


def _merge_convex(tris: list[tuple[int, int, int]], vertices: np.ndarray) -> list[list[int]]:
    """Hertel-Mehlhorn: greedily remove diagonals while the merged pieces stay convex."""
    pieces = [list(t) for t in tris]
    merged = True
    while merged:
        merged = False
        for a in range(len(pieces)):
            for b in range(a + 1, len(pieces)):
                pa, pb = pieces[a], pieces[b]
                shared = _shared_edge(pa, pb)
                if shared is None:
                    continue
                union = _join(pa, pb, shared)
                if _is_convex_ccw(vertices[union]):
                    pieces[a] = union
                    del pieces[b]
                    merged = True
                    break
            if merged:
                break
    return pieces


def _shared_edge(pa: list[int], pb: list[int]) -> tuple[int, int] | None:
    """The edge (u, v) that runs u->v in pa and v->u in pb, if any."""
    edges_b = {(pb[k], pb[(k + 1) % len(pb)]) for k in range(len(pb))}
    for k in range(len(pa)):
        u, v = pa[k], pa[(k + 1) % len(pa)]
        if (v, u) in edges_b:
            return u, v
    return None


def _join(pa: list[int], pb: list[int], edge: tuple[int, int]) -> list[int]:
    u, v = edge
    ka = pa.index(u)
    a_rot = pa[ka + 1 :] + pa[: ka + 1]  # starts at v, ends at u
    kb = pb.index(u)
    b_rot = pb[kb:] + pb[:kb]  # starts at u, continues to v last
    # b_rot = [u, ..., v]; walk a from v to u, then b's vertices strictly between u and v.
    return a_rot + b_rot[1:-1]


@dataclass(frozen=True)
class Polygon:
    """A simple, counter-clockwise polygon.

    Parameters
    ----------
    vertices : (P, 2) array_like
        Vertices in metres, counter-clockwise, without repeating the first vertex.
    field : str
        Name used in validation errors (for example ``"shape.vertices"``).
    """

    vertices: np.ndarray
    field: str = field(default="vertices", compare=False, repr=False)

    def __post_init__(self) -> None:
        name = self.field
        try:
            v = np.array(self.vertices, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name}: expected a list of [x, y] pairs ({exc})") from None
        if v.ndim != 2 or v.shape[1] != 2:
            raise ValueError(f"{name}: expected shape (P, 2), got {v.shape}")
        if len(v) >= 2 and np.allclose(v[0], v[-1]):
            v = v[:-1]  # tolerate an explicitly closed ring
        if len(v) < 3:
            raise ValueError(f"{name}: a polygon needs at least 3 vertices, got {len(v)}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name}: vertices must be finite numbers")
        edge_len = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
        if np.any(edge_len <= 1e-9):
            k = int(np.argmin(edge_len))
            raise ValueError(f"{name}: vertices {k} and {(k + 1) % len(v)} coincide")
        hits = _self_intersections(v)
        if hits:
            i, j = hits[0]
            raise ValueError(
                f"{name}: polygon is self-intersecting (edge {i} crosses edge {j}; "
                f"{len(hits)} crossing pair(s))"
            )
        area = polygon_signed_area(v)
        if abs(area) <= 1e-12:
            raise ValueError(f"{name}: polygon has zero area")
        if area < 0:
            raise ValueError(
                f"{name}: polygon is clockwise (signed area {area:.3g} m^2); "
                "list the vertices counter-clockwise"
            )
        v.setflags(write=False)
        object.__setattr__(self, "vertices", v)

    @property
    def area(self) -> float:
        """Area in m^2."""
        return polygon_signed_area(self.vertices)

    @property
    def centroid(self) -> np.ndarray:
        """Centre of area, (2,) metres."""
        v = self.vertices
        w = np.roll(v, -1, axis=0)
        cr = _cross(v, w)
        return np.sum((v + w) * cr[:, None], axis=0) / (6.0 * self.area)

    def polar_moment(self, about: np.ndarray | None = None) -> float:
        """Polar second moment of area about a point (default: the centroid), m^4."""
        about = self.centroid if about is None else np.asarray(about, dtype=float)
        v = self.vertices - about
        w = np.roll(v, -1, axis=0)
        cr = _cross(v, w)
        ixx = np.sum(cr * (v[:, 1] ** 2 + v[:, 1] * w[:, 1] + w[:, 1] ** 2)) / 12.0
        iyy = np.sum(cr * (v[:, 0] ** 2 + v[:, 0] * w[:, 0] + w[:, 0] ** 2)) / 12.0
        return float(ixx + iyy)

    @property
    def radius(self) -> float:
        """Largest distance of a vertex from the frame origin, metres."""
        return float(np.max(np.linalg.norm(self.vertices, axis=1)))

    @property
    def is_convex(self) -> bool:
        return _is_convex_ccw(self.vertices)

    def translated(self, offset: np.ndarray) -> Polygon:
        """The same polygon with every vertex moved by ``offset`` (2,)."""
        return Polygon(self.vertices + np.asarray(offset, dtype=float), field=self.field)

    def polyline(self) -> np.ndarray:
        """Closed counter-clockwise polyline (P, 2) for contact queries: the vertices."""
        return self.vertices

    def outline(self, spacing: float = 0.002) -> tuple[np.ndarray, np.ndarray]:
        """Points along the boundary with outward unit normals, ordered counter-clockwise.

        Points are equally spaced by arc length along the whole boundary (at the centres of
        ``round(perimeter / spacing)`` equal intervals), so dense measured outlines are
        resampled too; each point takes the outward normal of the edge it lies on.

        Returns
        -------
        points, normals : (K, 2) arrays
        """
        if spacing <= 0:
            raise ValueError(f"spacing: must be > 0, got {spacing}")
        a = self.vertices
        d = np.roll(a, -1, axis=0) - a
        length = np.linalg.norm(d, axis=1)
        ends = np.cumsum(length)
        n = max(3, int(round(ends[-1] / spacing)))
        s = (np.arange(n) + 0.5) * ends[-1] / n
        edge = np.minimum(np.searchsorted(ends, s, side="right"), len(a) - 1)
        t = (s - (ends[edge] - length[edge])) / length[edge]
        points = a[edge] + t[:, None] * d[edge]
        normals = np.stack([d[edge, 1], -d[edge, 0]], axis=1) / length[edge, None]
        return points, normals

    def simplified(self, tolerance: float) -> Polygon:
        """Douglas-Peucker simplification: no removed vertex lies further than ``tolerance``
        (metres) from the simplified outline. Falls back to halving the tolerance if the
        result would not be a valid simple polygon."""
        v = self.vertices
        # Split the ring at the vertex furthest from vertex 0 so both halves are open chains.
        far = int(np.argmax(np.linalg.norm(v - v[0], axis=1)))
        ring = np.concatenate([v, v[:1]])
        first = _douglas_peucker(ring[: far + 1], tolerance)
        second = far + _douglas_peucker(ring[far:], tolerance)
        idx = np.unique(np.concatenate([first, second[:-1]]))
        if len(idx) == len(v):
            return self
        try:
            return Polygon(v[idx], field=self.field)
        except ValueError:
            if tolerance < 1e-6:
                return self
            return self.simplified(tolerance / 2)

    def convex_pieces(self, tolerance: float = 3e-4) -> list[np.ndarray]:
        """Decomposition into convex counter-clockwise polygons, for collision shapes.

        The outline is first simplified (Douglas-Peucker, ``tolerance`` metres; a measured,
        noisy outline such as butter's has hundreds of tiny reflex corners), then triangulated
        by ear clipping, then diagonals are removed while both sides stay convex
        (Hertel-Mehlhorn, at most four times the optimal number of pieces). A convex polygon
        returns itself.
        """
        if self.is_convex:
            return [self.vertices.copy()]
        simple = self.simplified(tolerance) if tolerance > 0 else self
        if simple.is_convex:
            return [simple.vertices.copy()]
        tris = _triangulate(simple.vertices)
        return [simple.vertices[p] for p in _merge_convex(tris, simple.vertices)]

    def triangles(self) -> np.ndarray:
        """Triangulation as vertex indices, (T, 3) int, each counter-clockwise."""
        return np.array(_triangulate(self.vertices), dtype=int)


@dataclass(frozen=True)
class Ellipse:
    """An ellipse centred on the frame origin with semi-axes ``a`` (along x), ``b`` (along y).

    Parameters
    ----------
    a, b : float
        Semi-axes in metres, > 0.
    field : str
        Name used in validation errors.
    """

    a: float
    b: float
    field: str = field(default="semi_axes", compare=False, repr=False)

    def __post_init__(self) -> None:
        for value in (self.a, self.b):
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{self.field}: semi-axes must be finite and > 0, got "
                                 f"({self.a}, {self.b})")
        object.__setattr__(self, "a", float(self.a))
        object.__setattr__(self, "b", float(self.b))

    @property
    def area(self) -> float:
        return float(np.pi * self.a * self.b)

    @property
    def centroid(self) -> np.ndarray:
        return np.zeros(2)

    def polar_moment(self, about: np.ndarray | None = None) -> float:
        """Polar second moment of area about a point (default: the centre), m^4."""
        j = np.pi * self.a * self.b * (self.a**2 + self.b**2) / 4.0
        if about is not None:
            j += self.area * float(np.sum(np.asarray(about, dtype=float) ** 2))
        return float(j)

    @property
    def radius(self) -> float:
        return max(self.a, self.b)

    @property
    def is_convex(self) -> bool:
        return True

    @property
    def perimeter(self) -> float:
        """Perimeter (Ramanujan's second approximation, relative error < 1e-9 here)."""
        a, b = self.a, self.b
        h = ((a - b) / (a + b)) ** 2
        return float(np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h))))

    def _points_at_arclength(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        t = np.linspace(0.0, 2 * np.pi, 4096 + 1)
        speed = np.hypot(self.a * np.sin(t), self.b * np.cos(t))
        s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])
        targets = (np.arange(n) + 0.5) * s[-1] / n
        tt = np.interp(targets, s, t)
        points = np.stack([self.a * np.cos(tt), self.b * np.sin(tt)], axis=1)
        normals = np.stack([points[:, 0] / self.a**2, points[:, 1] / self.b**2], axis=1)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        return points, normals

    def polyline(self, max_spacing: float = 0.001) -> np.ndarray:
        """Closed counter-clockwise polygon through the ellipse (vertices at most
        ``max_spacing`` apart, at least 64)."""
        n = max(64, int(np.ceil(self.perimeter / max_spacing)))
        return self._points_at_arclength(n)[0]

    def outline(self, spacing: float = 0.002) -> tuple[np.ndarray, np.ndarray]:
        """Points equally spaced by arc length with outward unit normals, counter-clockwise."""
        if spacing <= 0:
            raise ValueError(f"spacing: must be > 0, got {spacing}")
        return self._points_at_arclength(max(8, int(round(self.perimeter / spacing))))

    def as_polygon(self, max_spacing: float = 0.001) -> Polygon:
        return Polygon(self.polyline(max_spacing), field=self.field)

    def convex_pieces(self) -> list[np.ndarray]:
        return [self.polyline()]


Shape = Polygon | Ellipse
