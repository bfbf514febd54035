"""Segmentation from depth alone (no training) and the CNN's fallback to it.

ROS-free (numpy, OpenCV). :class:`DepthSegmenter` is called like
:class:`push_perception.model.Segmenter` and returns the same
:class:`~push_perception.model.Segmentation`, so the node, the evaluation and the tracker do
not care which one made the mask (docs/design/cameras.md#segmentation-from-depth).

Steps, per frame:

1. **Table plane.** The pixels are deprojected to ``world`` with K and the extrinsics; those of
   the workspace (``workspace`` plus ``margin``) within ``plane_band`` of z = 0 are fitted with a
   plane (least squares, twice: the second fit keeps the points within 3 sigma of the first).
   The plane absorbs a table that is not quite at z = 0 or an extrinsic that is slightly off.
2. **Above the plane.** A pixel's height is its distance above that plane (3 x 3 median of the
   valid heights: one noisy pixel does not make an object); the object's candidates are the
   pixels between ``min_height`` and ``max_height`` above it inside the workspace.
3. **Nothing tall.** Points higher than ``max_height`` (a pusher, a finger, an arm link the
   self-filter missed) mark their footprint on the table (a top-down grid of ``cell`` m, grown
   by ``tall_margin``); candidates standing on that footprint are the tall thing's sides, not
   the object.
4. **The object.** The robot's pixels (the self-filter) are never object pixels and join the
   pieces on either side of them; the largest connected piece, with its holes (no-depth
   pixels inside the object) filled, is the mask.

:class:`FallbackSegmenter` runs the CNN and uses this segmentation instead when the CNN finds
nothing or its confidence (the mean object probability of its mask) is below a bound.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from push_perception.model import Segmentation

__all__ = ["DepthSegmentationConfig", "DepthSegmenter", "FallbackSegmenter"]


@dataclass(frozen=True)
class DepthSegmentationConfig:
    """Parameters of :class:`DepthSegmenter` (SI units).

    Attributes
    ----------
    workspace : (x_min, x_max, y_min, y_max)
        Table region where the object may be, ``world`` m.
    margin : float
        Added around ``workspace`` (an object partly outside it is still whole), m.
    min_height, max_height : float
        Candidate heights above the table plane, m (the library's plates are 5-25 mm thick;
        the pusher stands 60 mm tall).
    plane_band : float
        Points within this of z = 0 enter the plane fit, m.
    cell, tall_margin : float
        Grid cell of the tall things' footprint and its growth, m.
    min_pixels : int
        Smaller largest pieces are no object (empty mask).
    """

    workspace: tuple[float, float, float, float] = (-0.25, 0.25, -0.3, 0.3)
    margin: float = 0.05
    min_height: float = 0.003
    max_height: float = 0.04
    plane_band: float = 0.006
    cell: float = 0.002
    tall_margin: float = 0.003
    min_pixels: int = 50

    def __post_init__(self) -> None:
        x0, x1, y0, y1 = (float(v) for v in self.workspace)
        if not (x0 < x1 and y0 < y1) or not np.all(np.isfinite(self.workspace)):
            raise ValueError(f"workspace: need x_min < x_max, y_min < y_max, got "
                             f"{self.workspace!r}")
        if not 0.0 < self.min_height < self.max_height <= 0.5:
            raise ValueError(f"heights: need 0 < min_height < max_height <= 0.5 m, got "
                             f"{self.min_height!r}, {self.max_height!r}")
        for name in ("margin", "plane_band", "cell", "tall_margin"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0) or (name == "cell" and value <= 0):
                raise ValueError(f"{name}: must be a finite number >= 0 m (cell > 0), got "
                                 f"{value!r}")
        if int(self.min_pixels) < 1:
            raise ValueError(f"min_pixels: must be >= 1, got {self.min_pixels!r}")


def _fit_plane(points: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """``(a, b, c)`` of ``z = a x + b y + c`` fitted to (N, 3) points, or None (< 3 points)."""
    if len(points) < 3:
        return None
    a = np.column_stack([points[:, 0], points[:, 1], np.ones(len(points))])
    coef, *_ = np.linalg.lstsq(a, points[:, 2], rcond=None)
    return coef


class DepthSegmenter:
    """The object's mask from depth alone (module docstring). Not thread-safe (caches rays).

    Parameters
    ----------
    config : DepthSegmentationConfig, optional

    Attributes
    ----------
    last_plane_rms : float
        RMS vertical distance of the last frame's plane inliers from the fitted table plane, m (NaN
        when no plane was fitted): how flat and how well calibrated the table looked.
    """

    def __init__(self, config: DepthSegmentationConfig | None = None) -> None:
        self.config = DepthSegmentationConfig() if config is None else config
        self.last_plane_rms = float("nan")
        self._key: tuple[bytes, bytes, tuple[int, int]] | None = None
        self._rays: NDArray[np.float64] | None = None  # (H, W, 3) world ray per unit depth

    def _world_rays(self, shape: tuple[int, int], k: NDArray[np.float64],
                    t: NDArray[np.float64]) -> NDArray[np.float64]:
        key = (k.tobytes(), t.tobytes(), shape)
        if key != self._key:
            h, w = shape
            u = (np.arange(w) - k[0, 2]) / k[0, 0]
            v = (np.arange(h) - k[1, 2]) / k[1, 1]
            cam = np.stack(np.broadcast_arrays(u[None, :], v[:, None], np.ones((h, 1))), -1)
            self._rays, self._key = cam @ t[:3, :3].T, key
        return self._rays

    def __call__(self, rgb: NDArray[np.uint8], depth: NDArray[np.floating],
                 camera_matrix: NDArray[np.floating], t_world_camera: NDArray[np.floating],
                 robot: NDArray[np.bool_] | None = None) -> Segmentation:
        """Segment the object in one frame (the arguments of
        :meth:`push_perception.model.Segmenter.__call__`; ``rgb`` is not used)."""
        cfg = self.config
        k = np.asarray(camera_matrix, dtype=np.float64)
        t = np.asarray(t_world_camera, dtype=np.float64)
        z = np.asarray(depth, dtype=np.float64)
        h, w = z.shape
        empty = Segmentation(np.zeros((h, w), dtype=bool), None, 0)
        points = self._world_rays((h, w), k, t) * z[..., None] + t[:3, 3]
        valid = np.isfinite(z) & (z > 0)
        x0, x1, y0, y1 = cfg.workspace
        m = cfg.margin
        with np.errstate(invalid="ignore"):
            inside = valid & (points[..., 0] >= x0 - m) & (points[..., 0] <= x1 + m) \
                & (points[..., 1] >= y0 - m) & (points[..., 1] <= y1 + m)
            if robot is not None:
                inside &= ~robot
            table = inside & (np.abs(points[..., 2]) < cfg.plane_band)
        sample = points[table][::7]
        plane = _fit_plane(sample)
        self.last_plane_rms = float("nan")
        if plane is None:
            return empty
        residual = sample[:, 2] - sample[:, :2] @ plane[:2] - plane[2]
        keep = np.abs(residual) < max(3.0 * float(np.std(residual)), 1e-4)
        plane = _fit_plane(sample[keep]) if np.count_nonzero(keep) >= 3 else plane
        inliers = sample[keep] if np.count_nonzero(keep) >= 3 else sample
        self.last_plane_rms = float(np.sqrt(np.mean(
            (inliers[:, 2] - inliers[:, :2] @ plane[:2] - plane[2]) ** 2)))
        normal = np.array([-plane[0], -plane[1], 1.0])
        height = (points[..., 2] - points[..., :2] @ plane[:2] - plane[2]) / np.linalg.norm(normal)
        height = np.where(valid, height, np.nan).astype(np.float32)
        smooth = cv2.medianBlur(np.nan_to_num(height, nan=0.0), 3)
        smooth[~valid] = np.nan
        with np.errstate(invalid="ignore"):
            candidate = inside & (smooth > cfg.min_height) & (smooth < cfg.max_height)
            tall = inside & (smooth >= cfg.max_height)
        if np.any(tall):
            candidate &= ~self._on_tall_footprint(points, tall, candidate)
        joined = candidate if robot is None else candidate | robot
        n, labels = cv2.connectedComponents(joined.astype(np.uint8), connectivity=4)
        if n <= 1:
            return empty
        counts = np.bincount(labels[candidate], minlength=n)
        counts[0] = 0
        best = int(np.argmax(counts))
        if counts[best] < cfg.min_pixels:
            return empty
        piece = (labels == best).astype(np.uint8)
        mask = _fill_holes(piece)
        if robot is not None:
            mask &= ~robot
        vs, us = np.nonzero(mask)
        box = (int(us.min()), int(vs.min()), int(us.max()) + 1, int(vs.max()) + 1)
        return Segmentation(mask, box, int(counts[best]))

    def _on_tall_footprint(self, points: NDArray[np.float64], tall: NDArray[np.bool_],
                           candidate: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Candidates whose (x, y) lies on the grown footprint of the tall points."""
        cfg = self.config
        x0, _, y0, _ = cfg.workspace
        origin = np.array([x0 - cfg.margin, y0 - cfg.margin])
        nx = int(np.ceil((cfg.workspace[1] - cfg.workspace[0] + 2 * cfg.margin) / cfg.cell)) + 1
        ny = int(np.ceil((cfg.workspace[3] - cfg.workspace[2] + 2 * cfg.margin) / cfg.cell)) + 1
        cells = np.floor((points[tall][:, :2] - origin) / cfg.cell).astype(np.int64)
        grid = np.zeros((ny, nx), dtype=np.uint8)
        ok = (cells[:, 0] >= 0) & (cells[:, 0] < nx) & (cells[:, 1] >= 0) & (cells[:, 1] < ny)
        grid[cells[ok, 1], cells[ok, 0]] = 1
        r = int(np.ceil(cfg.tall_margin / cfg.cell))
        if r > 0:
            grid = cv2.dilate(grid, cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                              (2 * r + 1, 2 * r + 1)))
        out = np.zeros(candidate.shape, dtype=bool)
        cand = np.floor((points[candidate][:, :2] - origin) / cfg.cell).astype(np.int64)
        cx = np.clip(cand[:, 0], 0, nx - 1)
        cy = np.clip(cand[:, 1], 0, ny - 1)
        out[candidate] = grid[cy, cx] > 0
        return out


def _fill_holes(piece: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """``piece`` with the holes inside its outer contour filled."""
    contours, _ = cv2.findContours(piece, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros_like(piece)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    return filled.astype(bool) | piece.astype(bool)


class FallbackSegmenter:
    """The CNN, or the depth segmentation where the CNN is not sure (module docstring).

    Parameters
    ----------
    cnn : push_perception.model.Segmenter
    depth : DepthSegmenter
    min_confidence : float
        The CNN's mask is used when its confidence is at least this, [0, 1]; 0: never fall
        back unless the CNN finds nothing.

    Attributes
    ----------
    fallbacks : int
        Frames segmented by depth because the CNN was not sure (or found nothing).
    last_source : str
        ``"cnn"`` or ``"depth"``: who made the last mask.
    """

    def __init__(self, cnn: Any, depth: DepthSegmenter, min_confidence: float) -> None:
        if not 0.0 <= float(min_confidence) <= 1.0:
            raise ValueError(f"min_confidence: must be in [0, 1], got {min_confidence!r}")
        self.cnn, self.depth = cnn, depth
        self.min_confidence = float(min_confidence)
        self.fallbacks = 0
        self.last_source = "cnn"

    def __call__(self, rgb: NDArray[np.uint8], depth: NDArray[np.floating],
                 camera_matrix: NDArray[np.floating], t_world_camera: NDArray[np.floating],
                 robot: NDArray[np.bool_] | None = None) -> Segmentation:
        seg = self.cnn(rgb, depth, camera_matrix, t_world_camera, robot=robot)
        if seg.box is not None and seg.confidence >= self.min_confidence:
            self.last_source = "cnn"
            return seg
        self.fallbacks += 1
        self.last_source = "depth"
        return self.depth(rgb, depth, camera_matrix, t_world_camera, robot=robot)
