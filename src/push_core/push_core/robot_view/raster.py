"""A vectorised CPU triangle rasteriser with a z-buffer: mask and depth of triangles in a camera.

ROS-free, numpy only (no OpenGL, no simulator). Camera conventions (those of the pipeline's
RGB-D frames):

- triangles are given in the camera's REP 103 optical frame (x right, y down, z forward along
  the optical axis), metres;
- pixels follow OpenCV: ``u`` right (column), ``v`` down (row), integer coordinates at pixel
  centres, ``(u, v, 1) ~ K (x, y, z)``;
- depth is the optical z of the nearest surface (not the ray length).

A pixel belongs to a triangle when its centre lies inside (or on the edge of) the triangle's
projection; its depth is interpolated perspective-correctly (``1 / z`` is affine in the image).
Triangles are clipped against the near plane ``z = near`` (a triangle reaching behind the camera
is cut, not dropped), and a triangle flagged ``cull`` is skipped when it faces away from the
camera (its vertices run clockwise seen from the camera, i.e. its right-handed normal points
away): for a closed, consistently outward-wound mesh the front faces hide the back ones, so the
result is the same at half the work.

Work per call is bounded: the candidate pixels (the image-clipped bounding boxes of the
projected triangles) are processed in bands of at most ``CHUNK_PIXELS``, and a scene whose
candidates exceed ``max_work`` times the image's pixels (a surface filling the view many times
over: the robot on the lens) raises ``ValueError`` instead of running for seconds.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["CHUNK_PIXELS", "MAX_IMAGE_SIDE", "MAX_WORK", "check_camera", "check_size",
           "fill_polygon", "prism_silhouette", "rasterize"]

#: Candidate pixels evaluated at once (about 15 temporaries of 8 bytes each: ~250 MB at most).
CHUNK_PIXELS = 1 << 21
#: Largest image side, pixels.
MAX_IMAGE_SIDE = 8192
#: Default bound of the candidate pixels of one call, in multiples of the image's pixels.
MAX_WORK = 64.0
#: Barycentric tolerance: a pixel centre on a shared edge belongs to both triangles.
_EDGE_EPS = 1e-9


def check_camera(camera_matrix: ArrayLike, width: int, height: int) -> NDArray[np.float64]:
    """Validate a pinhole K and an image size; returns K as float64 (3, 3).

    Raises
    ------
    ValueError
        K not finite, not (3, 3), ``fx`` or ``fy`` not positive, last row not (0, 0, 1), or a
        side not an integer in [1, ``MAX_IMAGE_SIDE``].
    """
    k = np.asarray(camera_matrix, dtype=np.float64)
    if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0 \
            or k[1, 0] != 0 or not np.array_equal(k[2], (0.0, 0.0, 1.0)):
        raise ValueError(f"camera matrix must be a finite (3, 3) pinhole K (fx, fy > 0, last "
                         f"row 0 0 1), got {k.tolist() if k.size <= 9 else k.shape}")
    check_size(width, height)
    return k


def check_size(width: int, height: int) -> None:
    """Raise ``ValueError`` unless both sides are integers in [1, ``MAX_IMAGE_SIDE``] px."""
    for name, side in (("width", width), ("height", height)):
        if isinstance(side, bool) or int(side) != side or not 1 <= side <= MAX_IMAGE_SIDE:
            raise ValueError(f"{name} must be an integer in [1, {MAX_IMAGE_SIDE}], got {side!r}")


def rasterize(triangles: ArrayLike, camera_matrix: ArrayLike, width: int, height: int,
              near: float = 0.01, cull: ArrayLike | None = None,
              max_work: float = MAX_WORK) -> tuple[NDArray[np.bool_], NDArray[np.float32]]:
    """Mask and depth of triangles seen by a pinhole camera (module docstring).

    Parameters
    ----------
    triangles : (T, 3, 3) array_like
        Vertices in the camera's optical frame, metres; ``triangles[t, i]`` is vertex ``i``.
    camera_matrix : (3, 3) array_like
        K, pixels (skew allowed).
    width, height : int
        Image size, pixels.
    near : float
        Near clipping plane, metres (> 0).
    cull : (T,) bool array_like, optional
        Triangles that may be skipped when they face away from the camera (default: none).
    max_work : float
        Bound of the candidate pixels, in multiples of ``width * height``.

    Returns
    -------
    mask : (height, width) bool
        Pixels covered by a triangle.
    depth : (height, width) float32
        Optical z of the nearest triangle, metres; NaN where ``mask`` is False.

    Raises
    ------
    ValueError
        Bad shapes, non-finite vertices, a bad K or size, ``near`` not positive, or more
        candidate pixels than ``max_work`` allows.
    """
    k = check_camera(camera_matrix, width, height)
    tri = np.asarray(triangles, dtype=np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3):
        raise ValueError(f"triangles must be (T, 3, 3), got shape {tri.shape}")
    if not np.all(np.isfinite(tri)):
        raise ValueError("triangles: non-finite vertex")
    if not (np.isfinite(near) and near > 0):
        raise ValueError(f"near must be > 0 m, got {near!r}")
    flags = np.zeros(len(tri), dtype=bool) if cull is None else np.asarray(cull, dtype=bool)
    if flags.shape != (len(tri),):
        raise ValueError(f"cull must be ({len(tri)},) bools, got shape {flags.shape}")
    tri, flags = _clip_near(tri, flags, near)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    facing = np.einsum("ij,ij->i", normal, tri[:, 0]) < 0.0  # normal toward the camera
    keep = facing | ~flags
    tri = tri[keep]
    inv_w = np.zeros((height, width), dtype=np.float64)  # 1 / z of the nearest surface
    if len(tri):
        _draw(tri, k, width, height, max_work, inv_w)
    hit = inv_w > 0.0
    depth = np.full((height, width), np.nan, dtype=np.float32)
    depth[hit] = (1.0 / inv_w[hit]).astype(np.float32)
    return hit, depth


def _clip_near(tri: NDArray[np.float64], flags: NDArray[np.bool_], near: float
               ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Triangles clipped to ``z >= near``, vertex order (hence facing) kept."""
    inside = tri[:, :, 2] >= near
    count = inside.sum(axis=1)
    whole = tri[count == 3]
    parts, part_flags = [whole], [flags[count == 3]]
    for n_in in (1, 2):
        sel = count == n_in
        if not np.any(sel):
            continue
        t, ins = tri[sel], inside[sel]
        # Rotate each triangle (cyclically: the orientation stays) so vertex 0 is the odd one:
        # the one inside when one is inside, the one outside when two are.
        odd = np.argmax(ins if n_in == 1 else ~ins, axis=1)
        order = (odd[:, None] + np.arange(3)) % 3
        t = np.take_along_axis(t, order[:, :, None], axis=1)
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        ab = a + (b - a) * ((near - a[:, 2]) / (b[:, 2] - a[:, 2]))[:, None]
        ac = a + (c - a) * ((near - a[:, 2]) / (c[:, 2] - a[:, 2]))[:, None]
        if n_in == 1:  # a inside: the small triangle a, ab, ac
            parts.append(np.stack([a, ab, ac], axis=1))
            part_flags.append(flags[sel])
        else:  # a outside: the quad ab, b, c, ac as two triangles
            parts += [np.stack([ab, b, c], axis=1), np.stack([ab, c, ac], axis=1)]
            part_flags += [flags[sel], flags[sel]]
    return np.concatenate(parts), np.concatenate(part_flags)


def _draw(tri: NDArray[np.float64], k: NDArray[np.float64], width: int, height: int,
          max_work: float, inv_w: NDArray[np.float64]) -> None:
    """Z-buffer the clipped triangles into ``inv_w`` (the largest 1 / z per pixel)."""
    z = tri[:, :, 2]
    x, y = tri[:, :, 0] / z, tri[:, :, 1] / z
    u = k[0, 0] * x + k[0, 1] * y + k[0, 2]
    v = k[1, 1] * y + k[1, 2]
    w = 1.0 / z
    u0, v0 = u[:, 0], v[:, 0]
    du1, dv1, du2, dv2 = u[:, 1] - u0, v[:, 1] - v0, u[:, 2] - u0, v[:, 2] - v0
    det = du1 * dv2 - du2 * dv1
    lo_u = np.clip(np.ceil(u.min(axis=1)), 0, width)
    hi_u = np.clip(np.floor(u.max(axis=1)), -1, width - 1)
    lo_v = np.clip(np.ceil(v.min(axis=1)), 0, height)
    hi_v = np.clip(np.floor(v.max(axis=1)), -1, height - 1)
    bw = (hi_u - lo_u + 1).astype(np.int64)
    bh = (hi_v - lo_v + 1).astype(np.int64)
    ok = (bw > 0) & (bh > 0) & (np.abs(det) > 1e-12)
    if not np.any(ok):
        return
    idx = np.nonzero(ok)[0]
    total = float(np.sum(bw[idx] * bh[idx]))
    if total > max_work * width * height:
        raise ValueError(f"the triangles' bounding boxes cover {total / (width * height):.0f} "
                         f"images' worth of pixels (more than {max_work:g}): a surface right "
                         "in front of the camera?")
    # Barycentric coordinates b1, b2 and 1 / z as affine functions of (u - u0, v - v0).
    inv = 1.0 / det[idx]
    a1, c1 = dv2[idx] * inv, -du2[idx] * inv
    a2, c2 = -dv1[idx] * inv, du1[idx] * inv
    dw1, dw2 = w[idx, 1] - w[idx, 0], w[idx, 2] - w[idx, 0]
    coef = np.stack([a1, c1, a2, c2, a1 * dw1 + a2 * dw2, c1 * dw1 + c2 * dw2, u0[idx],
                     v0[idx], w[idx, 0]], axis=1)
    # Bands of rows of each bounding box, none larger than CHUNK_PIXELS; chunks of bands.
    rows = np.maximum(CHUNK_PIXELS // bw[idx], 1)
    nbands = -(-bh[idx] // rows)
    band_tri = np.repeat(np.arange(len(idx)), nbands)
    band_no = np.arange(len(band_tri)) - np.repeat(np.cumsum(nbands) - nbands, nbands)
    band_v0 = lo_v[idx][band_tri] + band_no * rows[band_tri]
    band_h = np.minimum(rows[band_tri], hi_v[idx][band_tri] - band_v0 + 1).astype(np.int64)
    size = bw[idx][band_tri] * band_h
    ends = np.cumsum(size)
    start = 0
    flat = inv_w.reshape(-1)
    while start < len(band_tri):
        stop = int(np.searchsorted(ends, ends[start] - size[start] + CHUNK_PIXELS,
                                   side="right"))
        stop = max(stop, start + 1)
        _draw_bands(band_tri[start:stop], band_v0[start:stop], band_h[start:stop], coef,
                    width, flat)
        start = stop


def _draw_bands(band_tri: NDArray[np.int64], band_v0: NDArray[np.float64],
                band_h: NDArray[np.int64], coef: NDArray[np.float64], width: int,
                flat: NDArray[np.float64]) -> None:
    """Scan-convert some bands of rows of their triangles; keep the nearest in ``flat``.

    Per row, each barycentric coordinate ``alpha (u - u0) + beta >= 0`` bounds ``u`` from one
    side, so the pixels inside form one span; only those are evaluated.
    """
    span_band = np.repeat(np.arange(len(band_tri)), band_h)
    row_no = np.arange(len(span_band)) - np.repeat(np.cumsum(band_h) - band_h, band_h)
    c = coef[band_tri[span_band]]
    v = band_v0[span_band] + row_no
    dv = v - c[:, 7]
    lo = np.full(len(v), -np.inf)
    hi = np.full(len(v), np.inf)
    for alpha, beta in ((c[:, 0], c[:, 1] * dv), (c[:, 2], c[:, 3] * dv),
                        (-(c[:, 0] + c[:, 2]), 1.0 - (c[:, 1] + c[:, 3]) * dv)):
        with np.errstate(divide="ignore", invalid="ignore"):
            edge = -beta / alpha
        lo = np.where(alpha > 0, np.maximum(lo, edge), lo)
        hi = np.where(alpha < 0, np.minimum(hi, edge), hi)
        hi = np.where((alpha == 0) & (beta < -_EDGE_EPS), -np.inf, hi)
    u_lo = np.maximum(np.ceil(c[:, 6] + lo - _EDGE_EPS), 0.0)
    u_hi = np.minimum(np.floor(c[:, 6] + hi + _EDGE_EPS), width - 1.0)
    n = np.maximum(u_hi - u_lo + 1.0, 0.0).astype(np.int64)
    keep = n > 0
    if not np.any(keep):
        return
    n, u_lo, v, dv, c = n[keep], u_lo[keep], v[keep], dv[keep], c[keep]
    # 1 / z at each span's first pixel and its step along the row.
    w_first = c[:, 8] + c[:, 4] * (u_lo - c[:, 6]) + c[:, 5] * dv
    span = np.repeat(np.arange(len(n)), n)
    offset = np.arange(len(span)) - np.repeat(np.cumsum(n) - n, n)
    w = w_first[span] + c[span, 4] * offset
    pixel = (v * width + u_lo).astype(np.int64)[span] + offset
    np.maximum.at(flat, pixel, w)


def fill_polygon(uv: ArrayLike, width: int, height: int) -> NDArray[np.bool_]:
    """The pixels whose centres lie inside a closed polygon in the image (even-odd rule).

    Parameters
    ----------
    uv : (K, 2) array_like
        Vertices in pixels (OpenCV: ``u`` right, ``v`` down, integer coordinates at pixel
        centres), any orientation, K >= 3; the polygon may be non-convex.
    width, height : int
        Image size, pixels.

    Returns
    -------
    (height, width) bool

    Raises
    ------
    ValueError
        Bad shape, a non-finite vertex, or a bad size.
    """
    check_size(width, height)
    p = np.asarray(uv, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
        raise ValueError(f"uv must be (K, 2) with K >= 3, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("uv: non-finite vertex")
    out = np.zeros((height, width), dtype=bool)
    a, b = p, np.roll(p, -1, axis=0)
    lo, hi = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
    # Rows whose centre v satisfies lo <= v < hi cross the edge (half-open: a vertex counts once).
    first = np.clip(np.ceil(lo), 0, height).astype(np.int64)
    last = np.clip(np.ceil(hi), 0, height).astype(np.int64)  # exclusive
    n = np.maximum(last - first, 0)
    if n.sum() == 0:
        return out
    edge = np.repeat(np.arange(len(p)), n)
    row = np.arange(len(edge)) - np.repeat(np.cumsum(n) - n, n) + first[edge]
    ea, eb = a[edge], b[edge]
    u = ea[:, 0] + (row - ea[:, 1]) * (eb[:, 0] - ea[:, 0]) / (eb[:, 1] - ea[:, 1])
    order = np.lexsort((u, row))
    row, u = row[order], u[order]
    # Consecutive crossings of a row pair up (even-odd): fill from each odd one to the next.
    starts, ends = u[0::2], u[1::2]
    span_row = row[0::2]
    u0 = np.maximum(np.ceil(starts), 0)
    u1 = np.minimum(np.floor(ends), width - 1)
    length = np.maximum(u1 - u0 + 1, 0).astype(np.int64)
    span = np.repeat(np.arange(len(length)), length)
    col = (np.arange(len(span)) - np.repeat(np.cumsum(length) - length, length)
           + u0[span].astype(np.int64))
    out[span_row[span], col] = True
    return out


def prism_silhouette(outline: ArrayLike, top: float, camera_matrix: ArrayLike,
                     t_camera_world: ArrayLike, width: int, height: int,
                     near: float = 0.01) -> NDArray[np.bool_]:
    """The image silhouette of a flat object: the prism of its outline from the table (z = 0)
    up to ``top``, seen by a pinhole camera.

    Parameters
    ----------
    outline : (K, 2) array_like
        The object's closed outline in ``world`` at its pose, m (K >= 3; any orientation,
        non-convex allowed).
    top : float
        Height of its top face above the table, m.
    camera_matrix : (3, 3) array_like
        K, pixels.
    t_camera_world : (4, 4) array_like
        ``camera optical frame <- world`` (the inverse of ``T_world_camera``).
    width, height : int
        Image size, pixels.
    near : float
        Near clipping plane, m: the side walls are clipped at it; a top or bottom face that
        reaches behind it is drawn through its side walls only.

    Returns
    -------
    (height, width) bool
        Pixel centres inside the silhouette (the side walls by :func:`rasterize`, the top and
        bottom faces by :func:`fill_polygon`).
    """
    k = check_camera(camera_matrix, width, height)
    t = np.asarray(t_camera_world, dtype=np.float64)
    xy = np.asarray(outline, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 3 or not np.all(np.isfinite(xy)):
        raise ValueError(f"outline must be finite (K, 2) with K >= 3, got shape {xy.shape}")
    n = len(xy)
    faces = [np.column_stack([xy, np.full(n, float(top))]), np.column_stack([xy, np.zeros(n)])]
    cam = [f @ t[:3, :3].T + t[:3, 3] for f in faces]
    a, b = cam[0], cam[1]
    a1, b1 = np.roll(a, -1, axis=0), np.roll(b, -1, axis=0)
    walls = np.concatenate([np.stack([a, a1, b1], axis=1), np.stack([a, b1, b], axis=1)])
    out = np.zeros((height, width), dtype=bool)
    u0, v0, u1, v1 = 0, 0, width, height
    every = np.concatenate(cam)
    if np.all(every[:, 2] >= near):  # all in front: draw in the bounding box only
        uv = (every[:, :2] / every[:, 2:3]) @ k[:2, :2].T + k[:2, 2]
        u0, v0 = (max(int(np.floor(c)), 0) for c in uv.min(axis=0))
        u1, v1 = min(int(np.ceil(uv[:, 0].max())) + 1, width), \
            min(int(np.ceil(uv[:, 1].max())) + 1, height)
        if u1 <= u0 or v1 <= v0:
            return out
    crop = k.copy()
    crop[0, 2] -= u0
    crop[1, 2] -= v0
    box = rasterize(walls, crop, u1 - u0, v1 - v0, near=near)[0]
    for face in cam:
        if np.all(face[:, 2] >= near):
            uv = (face[:, :2] / face[:, 2:3]) @ crop[:2, :2].T + crop[:2, 2]
            box |= fill_polygon(uv, u1 - u0, v1 - v0)
    out[v0:v1, u0:u1] = box
    return out
