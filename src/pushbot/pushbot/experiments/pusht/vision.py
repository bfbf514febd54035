"""The T's pose from Push-T's 96 x 96 image: colour unmixing + sub-pixel shape fit.

The same observation as Diffusion Policy: the env's ``pixels`` (96 x 96 RGB, the 512 x 512
pygame render shrunk by ``cv2.resize`` with bilinear interpolation) and the agent position it
provides. Method (the project's perception ideas: segmentation, then a shape fit against the
known outline at sub-pixel precision):

1. **Segmentation by colour unmixing.** Every pixel is a mix of the block's colour
   (LightSlateGray), the background (white) and the goal (LightGreen); least squares with the
   mix summing to one gives the block fraction ``f`` of each pixel (linear, all pixels at once).
   Pixels near the agent disc (drawn over the block) and the walls are left out.
2. **Rendering model.** ``cv2.resize`` (bilinear, no area averaging) samples the 512 x 512
   render at ``s = (u + 0.5) * 512 / 96 - 0.5`` for output pixel ``u``; the render fills the
   pixels whose centres (env coordinates ``(i, j)``) lie inside the T. So the predicted block
   fraction of an output pixel is the bilinear blend of the four render pixels around ``s``,
   each "inside" through a linear ramp of the signed distance (``clip(0.5 - (d - dilation) /
   width, 0, 1)``: a sub-pixel, piecewise-differentiable coverage).
3. **Fit.** ``scipy.optimize.least_squares`` over the body pose ``(x, y, angle)`` (env units,
   radians) of the difference between observed and predicted fractions, coarse-to-fine (ramp
   widths 6 then 1 render pixels), started from the caller's prediction (the planner's or the
   estimator's pose after the push); when the fit is poor (mean absolute residual above
   ``RESTART_RESIDUAL``) it restarts from the best of 72 orientations (every 5 degrees) about
   the mask's centroid.

Frames: env units (render pixels), the env's body frame of the T (see
:mod:`pushbot.experiments.pusht`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import map_coordinates
from scipy.optimize import least_squares

#: Colours of the render (pygame named colours), RGB. gym-pusht draws each box of the T filled
#: with 1.2 x its colour and its edges as 2-unit-radius fat lines in the colour
#: itself, so the block is the union of the boxes dilated by 2 units, in two colours.
BLOCK_RGB = (119, 136, 153)  # LightSlateGray: the edges
BLOCK_FILL_RGB = (143, 163, 184)  # 1.2 x LightSlateGray (rounded): the inside
GOAL_RGB = (144, 238, 144)  # LightGreen
BACKGROUND_RGB = (255, 255, 255)
#: The drawn block reaches this far beyond the outline (the fat edges' radius), env units.
EDGE_RADIUS = 2.0
#: Side of the render the observation is shrunk from, env units.
RENDER_SIZE = 512
#: Mean absolute fraction residual over the fitted window above which the fit restarts.
RESTART_RESIDUAL = 0.15
#: Render pixels around the agent disc left out of the fit (beyond its radius).
AGENT_MARGIN = 3.0
#: Orientations tried on a restart.
RESTART_ANGLES = 72


def colour_fractions(image: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Block and goal fractions (H, W) in [0, 1] of every pixel of an RGB image (H, W, 3)
    uint8: unmixing of the four colours (block edge, block fill, background, goal; fractions
    summing to one: three unknowns from three channels), the two block fractions added."""
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image: expected (H, W, 3), got shape {img.shape}")
    w = np.array(BACKGROUND_RGB, dtype=np.float64)
    basis = np.stack([np.array(c, float) - w for c in (BLOCK_RGB, BLOCK_FILL_RGB, GOAL_RGB)], 1)
    coef = (img.reshape(-1, 3) - w) @ np.linalg.inv(basis).T  # (N, 3)
    block = np.clip(coef[:, 0] + coef[:, 1], 0.0, 1.0).reshape(img.shape[:2])
    return block, np.clip(coef[:, 2], 0.0, 1.0).reshape(img.shape[:2])


def block_fraction(image: ArrayLike) -> NDArray[np.float64]:
    """Block fraction (H, W) in [0, 1] of every pixel of an RGB image (H, W, 3) uint8
    (:func:`colour_fractions`)."""
    return colour_fractions(image)[0]

def signed_distance(outline: NDArray[np.float64], local: NDArray[np.float64]
                    ) -> NDArray[np.float64]:
    """Signed distance (Q,) of points (Q, 2) from a closed polygon outline (P, 2), negative
    inside (same frame and unit for both)."""
    a = outline
    ab = np.roll(outline, -1, axis=0) - a
    ab2 = np.sum(ab ** 2, axis=1)
    rel = local[:, None, :] - a[None]
    t = np.clip(np.sum(rel * ab[None], axis=-1) / ab2[None], 0.0, 1.0)
    d = rel - t[..., None] * ab[None]
    dist = np.sqrt(np.min(np.sum(d * d, axis=-1), axis=1))
    y = local[:, 1:2]
    a, b = a[None], (a + ab)[None]
    crosses = (a[..., 1] > y) != (b[..., 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = a[..., 0] + (y - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
    inside = (np.count_nonzero(crosses & (local[:, 0:1] < xi), axis=1) % 2) == 1
    return np.where(inside, -dist, dist)


def render_fraction(outline: NDArray[np.float64] | Callable[[NDArray[np.float64]],
                                                             NDArray[np.float64]],
                    pose: ArrayLike, sx: NDArray[np.float64], sy: NDArray[np.float64],
                    width: float, dilation: float) -> NDArray[np.float64]:
    """The rendering model (module docstring, step 2): the predicted fraction (Q,) of the
    region ``outline`` (P, 2; its own frame, env units; or its signed distance function of
    points (Q, 2) in that frame) placed at ``pose`` (env units, rad) grown by ``dilation``, at
    output pixels sampling the render at ``(sx, sy)`` (Q,) (env units), with a signed-distance
    ramp of ``width`` render pixels."""
    p = np.asarray(pose, dtype=np.float64)
    x0, y0 = np.floor(sx), np.floor(sy)
    fx, fy = sx - x0, sy - y0
    corners = np.stack([np.stack([x0 + dx, y0 + dy], -1) for dy in (0, 1) for dx in (0, 1)],
                       1)  # (Q, 4, 2)
    weights = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], 1)
    c, s = math.cos(p[2]), math.sin(p[2])
    rel = corners.reshape(-1, 2) - p[:2]
    local = np.stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]], -1)
    sd = (outline(local) if callable(outline) else signed_distance(outline, local)).reshape(-1, 4)
    inside = np.clip(0.5 - (sd - dilation) / width, 0.0, 1.0)
    return np.sum(weights * inside, axis=1)


def sdf_grid(outline: NDArray[np.float64], cell: float, margin: float = 60.0
             ) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The signed distance (negative inside) of a polygon (P, 2), as a function of points
    (Q, 2): exact on a grid of ``cell`` spacing over the polygon's bounds grown by ``margin``
    (computed once, :func:`signed_distance`), bilinear between grid points, the border value
    beyond (at least ``margin``: far outside for any rendering ramp)."""
    lo = outline.min(axis=0) - margin
    n = np.ceil((outline.max(axis=0) + margin - lo) / cell).astype(int) + 1
    gx, gy = np.meshgrid(lo[0] + cell * np.arange(n[0]), lo[1] + cell * np.arange(n[1]))
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    grid = np.concatenate([signed_distance(outline, pts[i:i + 20000])
                           for i in range(0, len(pts), 20000)]).reshape(gx.shape)

    def distance(q: NDArray[np.float64]) -> NDArray[np.float64]:
        ij = (np.asarray(q, dtype=np.float64) - lo) / cell
        return map_coordinates(grid, [ij[:, 1], ij[:, 0]], order=1, mode="nearest")

    return distance


class TeeFitter:
    """Fits the T's body pose to Push-T images (module docstring).

    Parameters
    ----------
    outline : array_like, shape (P, 2)
        The T's outline in its body frame, env units, counter-clockwise.
    agent_radius : float
        Radius of the agent disc, env units.
    image_size : int
        Side of the observation, pixels.
    dilation : float
        Offset of the drawn region beyond the outline, render pixels: the fat edges' radius.
    sdf_cell : float, optional
        None (default): the exact signed distance of the outline, per evaluation. A cell size
        (env units): the signed distance read bilinearly from a grid computed once
        (:func:`sdf_grid`; about 0.1 unit off, a few times faster), for outlines fitted
        afresh in every episode (``--object-model estimated``).
    """

    def __init__(self, outline: ArrayLike, agent_radius: float = 15.0, image_size: int = 96,
                 dilation: float = EDGE_RADIUS, sdf_cell: float | None = None) -> None:
        self.outline = np.asarray(outline, dtype=np.float64)
        self._distance = sdf_grid(self.outline, sdf_cell) if sdf_cell is not None else \
            (lambda q: signed_distance(self.outline, q))
        self.agent_radius = float(agent_radius)
        self.size = int(image_size)
        self.dilation = float(dilation)
        self.scale = RENDER_SIZE / self.size
        c = (np.arange(self.size) + 0.5) * self.scale - 0.5  # sample coordinate per pixel
        self._sample = c
        self.radius = float(np.max(np.linalg.norm(self.outline, axis=1)))

    @property
    def sample(self) -> NDArray[np.float64]:
        """Render coordinate (env units) each output pixel row or column samples (size,)."""
        return self._sample

    # ---- model -------------------------------------------------------------------------------
    def predict(self, pose: ArrayLike, rows: NDArray[np.intp], cols: NDArray[np.intp],
                width: float = 1.0) -> NDArray[np.float64]:
        """Predicted block fraction of pixels (rows, cols) for a body pose (env units)."""
        return render_fraction(self._distance, pose, self._sample[cols], self._sample[rows],
                               width, self.dilation)

    # ---- fit ---------------------------------------------------------------------------------
    def _mask(self, agent: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Pixels usable for the fit: away from the agent disc and the walls."""
        c = self._sample
        gx, gy = np.meshgrid(c, c)
        near_agent = np.hypot(gx - agent[0], gy - agent[1]) <= self.agent_radius + AGENT_MARGIN
        walls = (gx < 10.0) | (gx > 501.0) | (gy < 10.0) | (gy > 501.0)
        return ~(near_agent | walls)

    def _window(self, pose: NDArray[np.float64], usable: NDArray[np.bool_], pad: float
                ) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """Usable pixels whose sample point lies within ``pad`` (env units) of the outline at
        ``pose``: elsewhere the prediction is constant while the pose moves less than
        ``pad``, so they do not change the fit."""
        r = self.radius + pad
        lo = np.searchsorted(self._sample, pose[:2] - r)
        hi = np.searchsorted(self._sample, pose[:2] + r)
        rows, cols = np.mgrid[lo[1]:hi[1], lo[0]:hi[0]]
        rows, cols = rows.ravel(), cols.ravel()
        keep = usable[rows, cols]
        rows, cols = rows[keep], cols[keep]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        rel = np.stack([self._sample[cols] - pose[0], self._sample[rows] - pose[1]], -1)
        local = np.stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]], -1)
        band = np.abs(self._distance(local)) <= pad
        return rows[band], cols[band]

    def _stage(self, frac: NDArray[np.float64], usable: NDArray[np.bool_],
               pose: NDArray[np.float64], width: float, pad: float, max_nfev: int
               ) -> tuple[NDArray[np.float64], float]:
        """One least-squares stage at ramp ``width``; the pose and its mean absolute residual
        (at that width)."""
        rows, cols = self._window(pose, usable, pad)
        obs = frac[rows, cols]

        def residual(p: NDArray[np.float64]) -> NDArray[np.float64]:
            return self.predict(p, rows, cols, width) - obs

        res = least_squares(residual, pose, x_scale=np.array([1.0, 1.0, 0.02]),
                            diff_step=np.array([1e-3, 1e-3, 1e-3]), max_nfev=max_nfev)
        return res.x, float(np.mean(np.abs(res.fun))) if len(obs) else math.inf

    def _refine(self, frac: NDArray[np.float64], usable: NDArray[np.bool_],
                pose: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
        pose, _ = self._stage(frac, usable, pose, 6.0, 30.0, 30)
        pose, _ = self._stage(frac, usable, pose, 1.0, 8.0, 30)
        return self._stage(frac, usable, pose, 1.0, 4.0, 20)

    def fit(self, image: ArrayLike, agent: ArrayLike, guess: ArrayLike | None = None
            ) -> NDArray[np.float64]:
        """Body pose ``(x, y, angle)`` (env units, rad) of the T in ``image`` (96, 96, 3).

        ``agent``: the agent position (env units, as the env provides it); ``guess``: a
        predicted pose to start from (None: search from the mask's centroid).
        """
        pose, _ = self.fit_with_error(image, agent, guess)
        return pose

    def fit_with_error(self, image: ArrayLike, agent: ArrayLike,
                       guess: ArrayLike | None = None) -> tuple[NDArray[np.float64], float]:
        """:meth:`fit` and its mean absolute fraction residual."""
        return self.fit_fraction(block_fraction(image), self.usable(agent), guess)

    def usable(self, agent: ArrayLike) -> NDArray[np.bool_]:
        """Pixels (96, 96) usable for a fit: away from the agent disc at ``agent`` (env
        units) and the walls."""
        return self._mask(np.asarray(agent, dtype=np.float64))

    def fit_fraction(self, frac: NDArray[np.float64], usable: NDArray[np.bool_],
                     guess: ArrayLike | None = None) -> tuple[NDArray[np.float64], float]:
        """The pose (env units, rad) of the region whose fraction image (96, 96) is ``frac``,
        fitted over the ``usable`` pixels, and its mean absolute fraction residual."""
        best, err = None, math.inf
        if guess is not None:
            best, err = self._refine(frac, usable, np.asarray(guess, dtype=np.float64).copy())
        if err > RESTART_RESIDUAL:
            w = np.where(usable, frac, 0.0)
            total = float(w.sum())
            if total <= 0.0:
                raise ValueError("image: no block pixels found")
            gy, gx = np.meshgrid(self._sample, self._sample, indexing="ij")
            centroid = np.array([np.sum(w * gx), np.sum(w * gy)]) / total
            area_centroid = _area_centroid(self.outline)
            near = usable & (np.hypot(gx - centroid[0], gy - centroid[1]) <= self.radius + 10.0)
            rows, cols = np.nonzero(near)
            obs = frac[rows, cols]
            best_start, best_cost = None, math.inf
            for k in range(RESTART_ANGLES):  # every orientation about the mask's centroid ...
                a = 2.0 * math.pi * k / RESTART_ANGLES
                c, s = math.cos(a), math.sin(a)
                origin = centroid - np.array([c * area_centroid[0] - s * area_centroid[1],
                                              s * area_centroid[0] + c * area_centroid[1]])
                cand = np.array([origin[0], origin[1], a])
                cost = float(np.sum((self.predict(cand, rows, cols, 6.0) - obs) ** 2))
                if cost < best_cost:
                    best_start, best_cost = cand, cost
            start = best_start  # ... the best one refined
            cand, e = self._refine(frac, usable, start)
            if e < err:
                best, err = cand, e
        assert best is not None
        return best, err

def _area_centroid(v: NDArray[np.float64]) -> NDArray[np.float64]:
    w = np.roll(v, -1, axis=0)
    cr = v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0]
    area = 0.5 * np.sum(cr)
    return np.sum((v + w) * cr[:, None], axis=0) / (6.0 * area)


# ------------------------------------------------------------------------------ outline
#: Douglas-Peucker tolerance of the coarse outline, output pixels.
COARSE_TOLERANCE = 1.0
#: Cells per pixel side of the coarse footprint (its closing then fills concave corners by
#: about half a pixel only).
SUBCELLS = 4
#: After the fit, a vertex whose outline turns by less than this (degrees) or that lies closer
#: than ``MIN_EDGE`` (env units) to its neighbour is dropped and the polygon fitted again.
MIN_TURN_DEG = 12.0
MIN_EDGE = 3.0
#: Farthest a vertex may move from the coarse outline in the fit, env units (1.5 pixels).
MAX_VERTEX_MOVE = 8.0


def coarse_outline(frac: NDArray[np.float64], usable: NDArray[np.bool_], size: int = 96
                   ) -> NDArray[np.float64]:
    """A first polygon (P, 2) (env units, counter-clockwise in the env's axes) of the region
    whose fraction image is ``frac``: the perception core's mask -> footprint step
    (:func:`push_perception.footprint.top_down_view` on the pixel centres with fraction above 0.5,
    one cell per pixel), its boundary simplified by Douglas-Peucker (``cv2.approxPolyDP``,
    :data:`COARSE_TOLERANCE` pixels) and moved half a pixel outward to the pixels' edges."""
    import cv2

    from push_perception.footprint import top_down_view
    from push_perception.perception_config import PerceptionConfig

    rows, cols = np.nonzero((frac > 0.5) & usable)
    if len(rows) < 9:
        raise ValueError(f"image: only {len(rows)} block pixels found (need 9)")
    cell = 1e-3  # the perception core works in metres: a pixel is SUB x SUB cells of 1 mm
    su, sv = np.meshgrid((np.arange(SUBCELLS) + 0.5) / SUBCELLS,
                         (np.arange(SUBCELLS) + 0.5) / SUBCELLS)
    u = (cols[:, None] + su.ravel()[None]).ravel()  # pixel units: pixel k spans [k, k + 1)
    v = (rows[:, None] + sv.ravel()[None]).ravel()
    points = np.column_stack([u * SUBCELLS * cell, v * SUBCELLS * cell, np.full(len(u), 0.01)])
    view = top_down_view(points, PerceptionConfig(resolution=cell, closing_radius=2,
                                                  min_height=0.0))
    boundary = view.boundary / (SUBCELLS * cell)  # pixel units, counter-clockwise
    poly = cv2.approxPolyDP(boundary.astype(np.float32).reshape(-1, 1, 2), COARSE_TOLERANCE,
                            True)[:, 0, :].astype(np.float64)
    scale = RENDER_SIZE / size
    return poly * scale - 0.5  # pixel k's centre k + 0.5 samples (k + 0.5) * scale - 0.5


def _prune(poly: NDArray[np.float64]) -> NDArray[np.float64]:
    """Drop vertices of a closed polygon that barely turn or sit on their neighbour."""
    while len(poly) > 3:
        prev, nxt = np.roll(poly, 1, axis=0), np.roll(poly, -1, axis=0)
        u, v = poly - prev, nxt - poly
        turn = np.abs(np.arctan2(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0], np.sum(u * v, axis=1)))
        short = np.linalg.norm(u, axis=1) < MIN_EDGE
        bad = np.flatnonzero((turn < math.radians(MIN_TURN_DEG)) | short)
        if len(bad) == 0:
            break
        poly = np.delete(poly, bad[np.argmin(turn[bad])], axis=0)
    return poly


def fit_outline(image: ArrayLike, agent: ArrayLike, agent_radius: float = 15.0,
                size: int = 96) -> tuple[NDArray[np.float64], float]:
    """The block's outline from one image: a polygon (P, 2) in the env's frame (env units,
    counter-clockwise in the env's axes) and its mean absolute fraction residual.

    Sub-pixel refinement: :func:`coarse_outline` gives the start; every vertex is then moved
    by least squares so that the rendering model (:func:`render_fraction`, the block drawn
    :data:`EDGE_RADIUS` beyond its outline) reproduces the observed block fractions of the
    pixels near the outline (ramp widths 6 then 1 render pixels, as the pose fit); vertices
    that turn by less than :data:`MIN_TURN_DEG` are dropped (:func:`_prune`) and the polygon
    fitted again (fine stage). Pixels near the agent disc and the walls are left out.
    """
    fitter = TeeFitter(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), agent_radius, size)
    frac = block_fraction(image)
    usable = fitter.usable(agent)
    poly = coarse_outline(frac, usable, size)
    sample = fitter.sample
    err = math.inf
    stages = ((6.0, 12.0, 20), (1.0, 5.0, 20))
    for _ in range(2):
        start = poly.copy()
        for width, pad, nfev in stages:
            rows, cols = _band(poly, sample, usable, pad)
            obs = frac[rows, cols]
            sx, sy, n = sample[cols], sample[rows], len(poly)

            def residual(v: NDArray[np.float64], w: float = width, n: int = n,
                         sx: NDArray[np.float64] = sx, sy: NDArray[np.float64] = sy,
                         obs: NDArray[np.float64] = obs) -> NDArray[np.float64]:
                return render_fraction(v.reshape(n, 2), (0.0, 0.0, 0.0), sx, sy, w,
                                       EDGE_RADIUS) - obs

            res = least_squares(residual, poly.ravel(), diff_step=1e-3, max_nfev=nfev,
                                jac_sparsity=_sparsity(poly, sx, sy, pad + 2.0 * width),
                                bounds=((start - MAX_VERTEX_MOVE).ravel(),
                                        (start + MAX_VERTEX_MOVE).ravel()))
            poly, err = res.x.reshape(n, 2), float(np.mean(np.abs(res.fun)))
        pruned = _prune(poly)
        if len(pruned) == len(poly):
            break
        poly, stages = pruned, stages[1:]  # near the outline already: the fine stage again
    return poly, err


def _sparsity(poly: NDArray[np.float64], sx: NDArray[np.float64], sy: NDArray[np.float64],
              reach: float) -> NDArray[np.bool_]:
    """Which residual (pixel sampling ``(sx, sy)``) a vertex coordinate can change: those
    within ``reach`` (env units, beyond the drawn edge) of one of the vertex's two edges."""
    q = np.column_stack([sx, sy])[:, None, :]
    a, b = poly[None], np.roll(poly, -1, axis=0)[None]
    ab = b - a
    t = np.clip(np.sum((q - a) * ab, axis=-1) / np.sum(ab * ab, axis=-1), 0.0, 1.0)
    near = np.linalg.norm(q - a - t[..., None] * ab, axis=-1) <= reach + EDGE_RADIUS + 2.0
    touches = near | np.roll(near, 1, axis=1)  # vertex j ends edges j - 1 and j
    return np.repeat(touches, 2, axis=1)


def _band(poly: NDArray[np.float64], sample: NDArray[np.float64], usable: NDArray[np.bool_],
          pad: float) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Usable pixels whose sample point lies within ``pad`` (env units) of ``poly``."""
    gy, gx = np.meshgrid(sample, sample, indexing="ij")
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    near = np.abs(signed_distance(poly, pts)) <= pad + EDGE_RADIUS
    rows, cols = np.nonzero(near.reshape(gx.shape) & usable)
    return rows, cols
