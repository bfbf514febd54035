"""The object's footprint in one frame: object points, the top-down view, its centroid.

ROS-free (numpy, OpenCV); the first steps of the mask-to-state pipeline
(:mod:`push_perception.tracker`), in the frames of docs/ARCHITECTURE.md.

1. **Object points.** Every mask pixel with a valid depth is deprojected with K and the
   extrinsics ``T_world_camera`` into ``world`` (:func:`object_points`). Points lower than
   ``min_height`` (or 40 % of the object's top height, whichever is larger) are dropped:
   they are table pixels at the mask boundary. What is left is the top face and the visible
   side walls; the walls are vertical, so their points project onto the outline.
2. **Top-down view.** The points' (x, y) are rasterised into an orthographic, world-aligned
   grid (``resolution``, 1 mm by default), closed morphologically (a disc of
   ``closing_radius`` cells fills the gaps between the image pixels' footprints, about
   1.3-2 mm apart on the table) and hole-filled; the largest component is the *footprint*
   (:func:`top_down_view`).
3. **Position.** The area centroid of the footprint: the origin of the ``object`` frame (the
   contract's "centre of the top-down mask"). This is not the mean of the mask's points: the
   camera sees one side wall and samples the near part of the top face more densely, both of
   which would bias a plain mean toward the camera.

Bounded work: whatever the input, the top-down raster is at most ``MAX_RASTER_SIDE`` (2048)
cells per side, checked before it is allocated (a larger extent, e.g. from absurd intrinsics,
extrinsics or depth, is a :class:`~push_perception.perception_config.PerceptionError` of kind
``"too_large"``); object points farther than ``MAX_COORDINATE`` (1 km) from the origin are
``"too_large"`` too (float64 no longer resolves a cell there) and a footprint of fewer than
``MIN_FOOTPRINT_CELLS`` cells is ``"few_pixels"``; the signed distance field is read in remap
calls of bounded size. The caps lie far outside what a table-top scene gives.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_perception.perception_config import PerceptionConfig, PerceptionError

__all__ = ["MAX_COORDINATE", "MAX_RASTER_SIDE", "MIN_FOOTPRINT_CELLS", "MIN_FOOTPRINT_SHARE",
           "TopDownView", "above_table", "object_points", "outline_view", "top_down_view"]

#: Smallest share of the object points the footprint (largest component) must hold; less
#: means the top-down view broke apart and its centroid would not be the object's.
MIN_FOOTPRINT_SHARE = 0.9
#: Range of the closing radius in metres (``closing_radius * resolution``), PerceptionConfig.
CLOSING_RANGE = (0.001, 0.01)
#: Largest |x|, |y| of an object point in ``world``, m (the table scene spans about a metre).
MAX_COORDINATE = 1000.0
#: Smallest footprint, cells (a library object covers thousands at 1 mm).
MIN_FOOTPRINT_CELLS = 9
#: Largest side of the top-down raster, cells (2.048 m at the default 1 mm resolution).
MAX_RASTER_SIDE = 2048
#: Points per row and per call of the remap in :meth:`TopDownView.sample_sdf` (OpenCV's maps
#: must have fewer than 32767 rows and columns).
_REMAP_WIDTH = 1024
_REMAP_CHUNK = _REMAP_WIDTH * 16384


def object_points(mask: NDArray[np.bool_], depth: NDArray[np.floating],
                  camera_matrix: NDArray[np.floating], t_world_camera: NDArray[np.floating]
                  ) -> tuple[NDArray[np.float64], int]:
    """World points of the mask pixels that have a depth.

    Parameters
    ----------
    mask : (H, W) bool
    depth : (H, W) float
        z-depth along the optical axis, metres; NaN, inf and values <= 0 mean no return.
    camera_matrix : (3, 3)
        K, pixels (OpenCV convention: pixel centres at integer coordinates).
    t_world_camera : (4, 4)
        world <- camera_color_optical_frame.

    Returns
    -------
    points : (N, 3) float64
        ``p_world = R (z (u - cx) / fx, z (v - cy) / fy, z) + t`` for each valid pixel.
    n_mask : int
        Number of mask pixels (with or without depth).
    """
    v, u = np.nonzero(mask)
    z = depth[v, u].astype(np.float64)
    ok = np.isfinite(z) & (z > 0)
    u, v, z = u[ok], v[ok], z[ok]
    k = camera_matrix
    cam = np.stack([(u - k[0, 2]) / k[0, 0] * z, (v - k[1, 2]) / k[1, 1] * z, z], axis=1)
    t = np.asarray(t_world_camera, dtype=np.float64)
    return cam @ t[:3, :3].T + t[:3, 3], int(len(ok))


@dataclass(frozen=True)
class TopDownView:
    """Orthographic, world-aligned top-down view of the object (the footprint).

    Cell ``[row, col]`` covers ``x in origin_x + [col, col + 1) * resolution`` and
    ``y in origin_y + [row, row + 1) * resolution`` (rows along +y, columns along +x).

    Attributes
    ----------
    image : (R, C) uint8
        1 on the footprint, 0 elsewhere.
    origin : (2,) float
        World (x, y) of the corner of cell (0, 0), metres.
    resolution : float
        Cell size, metres.
    centroid : (2,) float
        Area centroid of the footprint in ``world``, metres.
    area : float
        Footprint area, m^2.
    radius_of_gyration : float
        sqrt of the footprint's polar second moment about the centroid over its area, m.
    boundary : (P, 2) float
        Boundary cell centres in ``world`` (closed, counter-clockwise), metres.
    sdf : (R, C) float32
        Signed distance to the footprint's boundary, metres, negative inside (zero half-way
        between inside and outside cells).
    """

    image: NDArray[np.uint8]
    origin: NDArray[np.float64]
    resolution: float
    centroid: NDArray[np.float64]
    area: float
    radius_of_gyration: float
    boundary: NDArray[np.float64]
    sdf: NDArray[np.float32] = field(repr=False)

    def sample_sdf(self, points: NDArray[np.float64], outside: float) -> NDArray[np.float64]:
        """Bilinear SDF at world points (..., 2), metres; ``outside`` beyond the grid."""
        res = self.resolution
        shape = points.shape[:-1]
        flat = points.reshape(-1, 2)
        map_x = ((flat[:, 0] - self.origin[0]) / res - 0.5).astype(np.float32)
        map_y = ((flat[:, 1] - self.origin[1]) / res - 0.5).astype(np.float32)
        out = np.empty(len(flat), dtype=np.float32)
        # cv2.remap takes maps of fewer than 32767 rows and columns: read the points as rows of
        # _REMAP_WIDTH, at most _REMAP_CHUNK points per call.
        for start in range(0, len(flat), _REMAP_CHUNK):
            mx, my = map_x[start:start + _REMAP_CHUNK], map_y[start:start + _REMAP_CHUNK]
            n = len(mx)
            width = min(n, _REMAP_WIDTH)
            rows = -(-n // width)
            pad = rows * width - n
            mx, my = (np.pad(a, (0, pad)).reshape(rows, width) for a in (mx, my))
            got = cv2.remap(self.sdf, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                            borderValue=float(outside))
            out[start:start + n] = got.reshape(-1)[:n]
        return out.reshape(shape).astype(np.float64)


def above_table(points: NDArray[np.float64], cfg: PerceptionConfig
                ) -> tuple[NDArray[np.float64], float]:
    """The object points above the table, and the object's top height.

    Parameters
    ----------
    points : (N, 3) float
        Object points in ``world`` (metres).
    cfg : PerceptionConfig

    Returns
    -------
    kept : (M, 3) float
        The points higher than ``min_height`` and than 40 % of the top height (lower ones
        are table pixels at the mask boundary), M >= 3.
    top : float
        The 95th percentile of the points' heights, m.

    Raises
    ------
    PerceptionError
        ``"few_pixels"`` (fewer than 3 points kept), ``"too_large"`` (a point farther than
        ``MAX_COORDINATE`` from the origin).
    """
    z = points[:, 2]
    top = float(np.quantile(z, 0.95)) if len(z) else 0.0
    kept = points[z > max(cfg.min_height, 0.4 * top)]
    if len(kept) < 3:
        raise PerceptionError("few_pixels", f"only {len(kept)} mask point(s) above the table "
                              f"(>{1e3 * cfg.min_height:.1f} mm)")
    far = float(np.max(np.abs(kept[:, :2])))
    if not far <= MAX_COORDINATE:  # beyond it float64 cannot resolve millimetre cells
        raise PerceptionError("too_large", f"object points {far:.3g} m from the world origin "
                              f"(at most {MAX_COORDINATE:g} m; bad depth or extrinsics?)")
    return kept, top


def top_down_view(points: NDArray[np.float64], cfg: PerceptionConfig,
                  pad: float = 0.01) -> TopDownView:
    """Rasterise object points into the top-down footprint (see the module docstring).

    Parameters
    ----------
    points : (N, 3) float
        Object points in ``world`` (metres), N >= 3.
    cfg : PerceptionConfig
    pad : float
        Empty border around the footprint, metres (at least the chamfer truncation, so the
        SDF is valid wherever the rotation search reads it).

    Raises
    ------
    PerceptionError
        kind ``"few_pixels"`` when no point is above the table, ``"fragmented"`` when the
        largest component holds less than ``MIN_FOOTPRINT_SHARE`` of the points.
    """
    xy = above_table(points, cfg)[0][:, :2]
    res = cfg.resolution
    pad = max(pad, cfg.chamfer_truncation + 2 * res)
    lo = np.floor((xy.min(axis=0) - pad) / res) * res
    extent = np.ceil((xy.max(axis=0) + pad - lo) / res) + 1  # float: checked before the cast
    if not np.all(extent <= MAX_RASTER_SIDE):
        span = xy.max(axis=0) - xy.min(axis=0)
        raise PerceptionError("too_large", f"the object points span {span[0]:.3g} x "
                              f"{span[1]:.3g} m: a top-down view of more than "
                              f"{MAX_RASTER_SIDE} cells per side at {1e3 * res:g} mm (bad "
                              "depth, intrinsics or extrinsics?)")
    cols, rows = extent.astype(int)
    img = np.zeros((rows, cols), dtype=np.uint8)
    ij = ((xy - lo) / res).astype(np.intp)
    img[ij[:, 1], ij[:, 0]] = 1
    r = cfg.closing_radius
    if r > 0:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        img = cv2.morphologyEx(img, cv2.MORPH_CLOSE, kernel)
    # The largest outer contour, filled: drops stray cells and fills holes in one step.
    contours, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    outer = max(contours, key=cv2.contourArea)
    img = np.zeros_like(img)
    cv2.drawContours(img, [outer], -1, 1, thickness=cv2.FILLED)
    kept = float(np.mean(img[ij[:, 1], ij[:, 0]]))
    if kept < MIN_FOOTPRINT_SHARE:  # e.g. a sliver narrower than the raster: no pose
        raise PerceptionError("fragmented", f"the largest footprint component holds only "
                              f"{100 * kept:.0f} % of the object points (need "
                              f"{100 * MIN_FOOTPRINT_SHARE:.0f} %): the top-down view falls "
                              "apart (an object narrower than a few millimetres?)")
    mom = cv2.moments(img, binaryImage=True)
    cells = mom["m00"]
    if cells < MIN_FOOTPRINT_CELLS or len(outer) < 3:
        raise PerceptionError("few_pixels", f"the footprint covers only {cells:.0f} cells of "
                              f"{1e3 * res:g} mm (need {MIN_FOOTPRINT_CELLS})")
    centroid = lo + (np.array([mom["m10"], mom["m01"]]) / cells + 0.5) * res
    area = cells * res * res
    # Polar second moment of the cells about the centroid (+ each cell's own, res^2 / 6).
    r_gyr = float(np.sqrt((mom["mu20"] + mom["mu02"]) / cells + 1.0 / 6.0) * res)
    boundary = lo + (outer[:, 0, :].astype(np.float64) + 0.5) * res  # (P, 2) = (col, row)
    if _signed_area(boundary) < 0:
        boundary = boundary[::-1]
    inside = cv2.distanceTransform(img, cv2.DIST_L2, cv2.DIST_MASK_5)
    outside = cv2.distanceTransform(1 - img, cv2.DIST_L2, cv2.DIST_MASK_5)
    sdf = np.where(img > 0, -(inside - 0.5), outside - 0.5).astype(np.float32) * np.float32(res)
    return TopDownView(image=img, origin=lo, resolution=res, centroid=centroid, area=area,
                       radius_of_gyration=r_gyr, boundary=boundary, sdf=sdf)


def outline_view(points: ArrayLike, cfg: PerceptionConfig) -> TopDownView:
    """The top-down view of the footprint enclosed by an outline (the anchor of
    :meth:`EpisodeTracker.anchor`).

    Parameters
    ----------
    points : (K, 2) float
        Closed outline (metres), any frame; K >= 3.
    cfg : PerceptionConfig

    Returns
    -------
    TopDownView
        :func:`top_down_view` of the centres of the ``cfg.resolution`` cells inside the
        polygon (given a height of 1 cm, so none is taken for the table).
    """
    pts = np.asarray(points, dtype=np.float64)
    res = cfg.resolution
    lo = pts.min(axis=0) - 2 * res
    side = np.ceil((pts.max(axis=0) + 2 * res - lo) / res).astype(int) + 1
    if np.any(side > MAX_RASTER_SIDE):
        raise PerceptionError("too_large", "anchor outline larger than the top-down raster")
    img = np.zeros((side[1], side[0]), dtype=np.uint8)
    poly = np.round((pts - lo) / res * 16.0 - 8.0).astype(np.int32)  # cell centres, 4 bits
    cv2.fillPoly(img, [poly.reshape(-1, 1, 2)], 1, lineType=cv2.LINE_8, shift=4)
    rows, cols = np.nonzero(img)
    xy = lo + (np.stack([cols, rows], axis=1) + 0.5) * res
    cloud = np.column_stack([xy, np.full(len(xy), 0.01)])
    return top_down_view(cloud, cfg)


def _signed_area(poly: NDArray[np.float64]) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
