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

import numpy as np
from numpy.typing import ArrayLike, NDArray
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


def block_fraction(image: ArrayLike) -> NDArray[np.float64]:
    """Block fraction (H, W) in [0, 1] of every pixel of an RGB image (H, W, 3) uint8:
    unmixing of the four colours (block edge, block fill, background, goal; fractions summing
    to one: three unknowns from three channels), the two block fractions added."""
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image: expected (H, W, 3), got shape {img.shape}")
    w = np.array(BACKGROUND_RGB, dtype=np.float64)
    basis = np.stack([np.array(c, float) - w for c in (BLOCK_RGB, BLOCK_FILL_RGB, GOAL_RGB)], 1)
    coef = (img.reshape(-1, 3) - w) @ np.linalg.inv(basis).T  # (N, 3)
    return np.clip(coef[:, 0] + coef[:, 1], 0.0, 1.0).reshape(img.shape[:2])


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
    """

    def __init__(self, outline: ArrayLike, agent_radius: float = 15.0, image_size: int = 96,
                 dilation: float = EDGE_RADIUS) -> None:
        self.outline = np.asarray(outline, dtype=np.float64)
        self.agent_radius = float(agent_radius)
        self.size = int(image_size)
        self.dilation = float(dilation)
        self.scale = RENDER_SIZE / self.size
        c = (np.arange(self.size) + 0.5) * self.scale - 0.5  # sample coordinate per pixel
        self._sample = c
        a, b = self.outline, np.roll(self.outline, -1, axis=0)
        self._a, self._ab = a, b - a
        self._ab2 = np.sum(self._ab ** 2, axis=1)
        self.radius = float(np.max(np.linalg.norm(self.outline, axis=1)))

    # ---- model -------------------------------------------------------------------------------
    def _signed_distance(self, local: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signed distance (Q,) of body-frame points (Q, 2) from the outline, negative inside."""
        rel = local[:, None, :] - self._a[None]
        t = np.clip(np.sum(rel * self._ab[None], axis=-1) / self._ab2[None], 0.0, 1.0)
        d = rel - t[..., None] * self._ab[None]
        dist = np.sqrt(np.min(np.sum(d * d, axis=-1), axis=1))
        y = local[:, 1:2]
        a, b = self._a[None], (self._a + self._ab)[None]
        crosses = (a[..., 1] > y) != (b[..., 1] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xi = a[..., 0] + (y - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
        inside = (np.count_nonzero(crosses & (local[:, 0:1] < xi), axis=1) % 2) == 1
        return np.where(inside, -dist, dist)

    def predict(self, pose: ArrayLike, rows: NDArray[np.intp], cols: NDArray[np.intp],
                width: float = 1.0) -> NDArray[np.float64]:
        """Predicted block fraction of pixels (rows, cols) for a body pose (env units)."""
        p = np.asarray(pose, dtype=np.float64)
        sx, sy = self._sample[cols], self._sample[rows]
        x0, y0 = np.floor(sx), np.floor(sy)
        fx, fy = sx - x0, sy - y0
        corners = np.stack([np.stack([x0 + dx, y0 + dy], -1) for dy in (0, 1) for dx in (0, 1)],
                           1)  # (Q, 4, 2)
        weights = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], 1)
        c, s = math.cos(p[2]), math.sin(p[2])
        rel = corners.reshape(-1, 2) - p[:2]
        local = np.stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]], -1)
        sd = self._signed_distance(local).reshape(-1, 4)
        inside = np.clip(0.5 - (sd - self.dilation) / width, 0.0, 1.0)
        return np.sum(weights * inside, axis=1)

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
        band = np.abs(self._signed_distance(local)) <= pad
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
        frac = block_fraction(image)
        usable = self._mask(np.asarray(agent, dtype=np.float64))
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
            gy, gx = np.meshgrid(self._sample, self._sample, indexing="ij")
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
