"""From an object mask and depth to the object's state: pose, relative orientation, outline.

ROS-free (numpy, OpenCV, scipy); the node (``segmentation_node``) and the evaluation wrap it.
The pipeline's segmentation and pose steps (docs/design/perception.md); the frames
are those of ``docs/ARCHITECTURE.md#units-frames-conventions``.

Pipeline for one frame (:class:`EpisodeTracker.update`)
-------------------------------------------------------
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
4. **Outline.** The footprint's boundary (``cv2.findContours``, cell centres) is resampled,
   smoothed along its length with a Gaussian (``outline_smoothing``, metres), moved outward by
   half a cell (the cell centres lie half a cell inside the boundary) and resampled at
   ``outline_spacing`` (2 mm); normals are the outward unit normals of the smoothed curve,
   points counter-clockwise (:func:`smooth_outline`). On the first frame of an episode this is
   the shape encoding, in the object frame (origin at the centroid, axes = world axes at the
   first frame).
5. **Orientation** relative to the first frame (:func:`rotation_search`): the rotation about
   the centroid that best aligns the current outline with the first frame's, by a symmetric,
   truncated chamfer cost (mean distance of each outline's points to the other footprint's
   boundary, read bilinearly from signed distance fields), searched on a coarse grid over the
   full circle and refined around every candidate minimum by successive parabolic fits.
   Symmetric objects have several (near-)equal minima: every refined minimum whose cost is
   within ``symmetry_tolerance`` of the best is a candidate, and the one closest to the
   previous frame's angle is reported (the angle is continuous, not wrapped).
   A continuously symmetric outline (a disc; :func:`push_core.symmetry.has_continuous_symmetry`
   of the first frame's outline) has no orientation to find: the search is skipped, the
   orientation stays at the episode frame's 0 and is reported as not observed (variance
   ``push_core.symmetry.UNOBSERVED_VARIANCE``).

Covariance model (:func:`pose_covariance`)
------------------------------------------
Standard deviations of (x, y) and theta grow with fewer valid pixels, with missing depth and
with disagreement between the current footprint and the first one::

    k       = sqrt(NOMINAL_PIXELS / n_valid) / valid_fraction
    sigma_p = sigma_position * k + area_mismatch * sqrt(A_0) / 2
    sigma_t = sigma_theta * k + max(match_cost - match_cost_floor, 0) / r_0 + area_mismatch

``n_valid`` mask pixels with depth of ``n_mask``, ``valid_fraction = n_valid / n_mask``;
``area_mismatch = |A_t / A_0 - 1|`` (an occluded or mis-segmented part moves the centroid by up
to about half the object's size times the missing fraction); ``match_cost`` the chamfer
residual of the rotation search (metres), of which ``match_cost_floor`` is what a correct match
leaves (the raster and depth noise: 0.3 mm on clean frames, 0.6 mm with depth noise), and
``r_0`` the footprint's radius of gyration (an outline misfit of d metres at radius r is an
angle of about d / r). The base values
``sigma_position`` and ``sigma_theta`` are the measured median errors on the held-out objects
(docs/results/eval_perception.md). x and y are uncorrelated and share one variance.

Bounded work per frame
----------------------
Whatever the input, one frame costs bounded time and memory (the caps lie far outside what a
table-top scene gives, so they never act on one): the top-down raster is at most
``MAX_RASTER_SIDE`` (2048) cells per side, checked before it is allocated (a larger extent,
e.g. from absurd intrinsics, extrinsics or depth, is a :class:`PerceptionError` of kind
``"too_large"``); an outline has at most ``MAX_OUTLINE_POINTS`` (1000) points (a longer
boundary is resampled with the spacing widened to fit: 2 m of perimeter at the default 2 mm);
object points farther than ``MAX_COORDINATE`` (1 km) from the origin are ``"too_large"`` too
(float64 no longer resolves a cell there) and a footprint of fewer than
``MIN_FOOTPRINT_CELLS`` cells is ``"few_pixels"``;
the dense curve it is smoothed on has at most ``MAX_DENSE_POINTS``; the rotation search
refines at most ``MAX_REFINED_MINIMA`` (64) coarse minima (the lowest; a 3 degree grid has at
most 60) and reads the signed distance fields in remap calls of bounded size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import gaussian_filter1d

from push_core.symmetry import UNOBSERVED_VARIANCE, has_continuous_symmetry

__all__ = [
    "CLOSING_RANGE",
    "MAX_OUTLINE_POINTS",
    "MAX_RASTER_SIDE",
    "ANCHOR_MAX_COST",
    "MAX_REFINED_MINIMA",
    "NOMINAL_PIXELS",
    "EpisodeTracker",
    "Measurement",
    "PerceptionConfig",
    "PerceptionError",
    "TopDownView",
    "check_frame_arrays",
    "object_points",
    "outline_view",
    "pose_covariance",
    "rotation_search",
    "smooth_outline",
    "top_down_view",
]

#: Mask size (pixels with depth) at which the base standard deviations apply: a ~100 cm^2
#: object near the workspace centre in a 640 x 480 frame.
NOMINAL_PIXELS = 5000
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
#: Most outline points of one frame; a longer boundary is resampled with a wider spacing.
MAX_OUTLINE_POINTS = 1000
#: Most samples of the dense curve an outline is smoothed on.
MAX_DENSE_POINTS = 65536
#: Most coarse minima of the rotation search that are refined (the lowest ones).
MAX_REFINED_MINIMA = 64
#: Largest chamfer cost (m) of an anchor outline against the first frame after a restart
#: (:meth:`EpisodeTracker.anchor`): above it the anchor is another object and is dropped.
ANCHOR_MAX_COST = 0.003
#: Points per row and per call of the remap in :meth:`TopDownView.sample_sdf` (OpenCV's maps
#: must have fewer than 32767 rows and columns).
_REMAP_WIDTH = 1024
_REMAP_CHUNK = _REMAP_WIDTH * 16384


class PerceptionError(ValueError):
    """A frame from which no pose can be measured; ``kind`` names the class of problem.

    Kinds: ``"empty_mask"``, ``"few_pixels"``, ``"no_depth"``, ``"out_of_view"``,
    ``"fragmented"`` (the top-down view falls apart into pieces), ``"too_large"`` (the object
    points span more than ``MAX_RASTER_SIDE`` cells), ``"bad_input"`` (malformed arrays).
    """

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


@dataclass(frozen=True)
class PerceptionConfig:
    """Parameters of the mask-to-state pipeline (SI units).

    Attributes
    ----------
    resolution : float
        Cell size of the top-down view, m, [0.5, 3] mm (finer leaves the gaps between the
        camera pixels' footprints open: the view falls apart; 5 mm costs 2 deg of yaw).
    min_height : float
        Points lower than this above the table are not the object, m, [0, 10] mm (it must stay
        below the object's thickness, 13 mm for the library objects).
    closing_radius : int
        Radius of the morphological closing of the top-down view, cells, [2, 10], and
        ``closing_radius * resolution`` in [1, 10] mm: a smaller closing leaves the view
        fragmented (no pose), a larger one fills concavities (15 mm: 4.6 mm and 5 deg off).
    outline_spacing : float
        Distance between outline points, m, [0.5, 10] mm (at most ``MAX_OUTLINE_POINTS``
        points: a longer outline is resampled more coarsely).
    outline_smoothing : float
        Standard deviation of the Gaussian smoothing along the outline, m.
    outline_offset : float
        Extra outward offset of the outline (a calibration), m.
    coarse_step_deg : float
        Grid step of the coarse rotation search, degrees.
    angle_tolerance_deg : float
        Step below which the parabolic refinement of the rotation stops, degrees.
    symmetry_tolerance : float
        Candidate minima whose chamfer cost is within this of the best are treated as
        symmetric equivalents (the one closest to the previous angle wins), m.
    chamfer_truncation : float
        Distances are truncated at this value in the chamfer cost (robustness), m.
    min_pixels : int
        Fewer mask pixels with depth than this: no pose.
    min_valid_fraction : float
        Smaller fraction of mask pixels with depth than this: no pose.
    max_border_pixels : int
        More mask pixels than this on the image border: the object is (partly) out of view,
        no pose.
    sigma_position : float
        Base standard deviation of x and y at ``NOMINAL_PIXELS`` with full depth, m.
    sigma_theta : float
        Base standard deviation of the relative orientation, rad.
    match_cost_floor : float
        Chamfer residual of a correct rotation match (raster and depth noise), m; only the
        excess over it widens the orientation's standard deviation.
    """

    resolution: float = 0.001
    min_height: float = 0.003
    closing_radius: int = 2
    outline_spacing: float = 0.002
    outline_smoothing: float = 0.003
    outline_offset: float = 0.0
    coarse_step_deg: float = 3.0
    angle_tolerance_deg: float = 0.02
    symmetry_tolerance: float = 0.0008
    chamfer_truncation: float = 0.005
    min_pixels: int = 100
    min_valid_fraction: float = 0.3
    max_border_pixels: int = 3
    sigma_position: float = 0.0005
    sigma_theta: float = 0.003
    match_cost_floor: float = 0.0007

    def __post_init__(self) -> None:
        checks = (
            ("resolution", 5e-4, 3e-3), ("min_height", 0.0, 0.01),
            ("outline_spacing", 5e-4, 0.01), ("outline_smoothing", 0.0, 0.01),
            ("outline_offset", -0.005, 0.005), ("coarse_step_deg", 0.1, 10.0),
            ("angle_tolerance_deg", 1e-4, 1.0), ("symmetry_tolerance", 0.0, 0.01),
            ("chamfer_truncation", 1e-4, 0.05), ("min_valid_fraction", 0.0, 1.0),
            ("sigma_position", 1e-6, 1.0), ("sigma_theta", 1e-6, math.pi),
            ("match_cost_floor", 0.0, 0.01),
        )
        for name, low, high in checks:
            value = getattr(self, name)
            if isinstance(value, bool) or not (np.isfinite(value) and low <= value <= high):
                raise ValueError(f"{name}: must be in [{low}, {high}], got {value!r}")
            object.__setattr__(self, name, float(value))
        for name, low, high in (("closing_radius", 2, 10), ("min_pixels", 3, 10**7),
                                ("max_border_pixels", 0, 10**7)):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or not low <= value <= high:
                raise ValueError(f"{name}: must be an integer in [{low}, {high}], got {value!r}")
            object.__setattr__(self, name, int(value))
        closing = self.closing_radius * self.resolution
        if not CLOSING_RANGE[0] - 1e-12 <= closing <= CLOSING_RANGE[1] + 1e-12:
            raise ValueError(f"closing_radius: closing_radius * resolution must be in "
                             f"[{1e3 * CLOSING_RANGE[0]:g}, {1e3 * CLOSING_RANGE[1]:g}] mm, got "
                             f"{self.closing_radius} * {1e3 * self.resolution:g} mm")


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------
def check_frame_arrays(mask: ArrayLike, depth: ArrayLike, camera_matrix: ArrayLike,
                t_world_camera: ArrayLike) -> tuple[NDArray[np.bool_], NDArray[np.float32],
                                                    NDArray[np.float64], NDArray[np.float64]]:
    """Validate one frame's arrays; returns them as (bool, float32, float64, float64).

    Raises
    ------
    PerceptionError
        kind ``"bad_input"``, naming the offending array: mask and depth not 2-D or of
        different sizes, K not a finite pinhole matrix, T not a finite rigid transform.
    """
    m = np.asarray(mask)
    d = np.asarray(depth)
    if m.ndim != 2 or d.ndim != 2:
        raise PerceptionError("bad_input", f"mask and depth must be 2-D, got shapes {m.shape} "
                              f"and {d.shape}")
    if m.shape != d.shape:
        raise PerceptionError("bad_input", f"mask {m.shape} and depth {d.shape} differ in size")
    k = np.asarray(camera_matrix, dtype=np.float64)
    if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0 \
            or not np.allclose(k[2], (0.0, 0.0, 1.0)):
        raise PerceptionError("bad_input", f"camera matrix must be a finite (3, 3) pinhole K "
                              f"with fx, fy > 0, got {k.tolist()}")
    t = np.asarray(t_world_camera, dtype=np.float64)
    if t.shape != (4, 4) or not np.all(np.isfinite(t)) \
            or not np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-6) \
            or not np.allclose(t[3], (0.0, 0.0, 0.0, 1.0)):
        raise PerceptionError("bad_input", "T_world_camera must be a finite (4, 4) rigid "
                              "transform")
    return m.astype(bool, copy=False), d.astype(np.float32, copy=False), k, t


# --------------------------------------------------------------------------------------------
# Geometry of one frame
# --------------------------------------------------------------------------------------------
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
    z = points[:, 2]
    top = float(np.quantile(z, 0.95)) if len(z) else 0.0
    keep = z > max(cfg.min_height, 0.4 * top)
    xy = points[keep, :2]
    if len(xy) < 3:
        raise PerceptionError("few_pixels", f"only {len(xy)} mask point(s) above the table "
                              f"(>{1e3 * cfg.min_height:.1f} mm)")
    far = float(np.max(np.abs(xy)))
    if not far <= MAX_COORDINATE:  # beyond it float64 cannot resolve millimetre cells
        raise PerceptionError("too_large", f"object points {far:.3g} m from the world origin "
                              f"(at most {MAX_COORDINATE:g} m; bad depth or extrinsics?)")
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


def smooth_outline(boundary: NDArray[np.float64], spacing: float, smoothing: float,
                   offset: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Smooth, offset and resample a closed counter-clockwise boundary.

    Parameters
    ----------
    boundary : (P, 2) float
        Closed polyline (first point not repeated), counter-clockwise, metres.
    spacing : float
        Arc-length spacing of the output points, metres.
    smoothing : float
        Standard deviation of the Gaussian applied along the curve, metres (0: none).
    offset : float
        Distance the curve is moved along its outward normal, metres.

    Returns
    -------
    points, normals : (K, 2) float64
        Points counter-clockwise at the centres of ``round(length / spacing)`` equal arcs
        (like ``push_core.shapes.Polygon.outline``) and their outward unit normals; at most
        ``MAX_OUTLINE_POINTS`` (the spacing widened to fit).
    """
    pts = np.asarray(boundary, dtype=np.float64)
    closed = np.vstack([pts, pts[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    length = float(s[-1])
    step = min(spacing / 4.0, max(smoothing / 2.0, 1e-5)) if smoothing > 0 else spacing / 4.0
    n_dense = max(16, min(int(math.ceil(length / step)), MAX_DENSE_POINTS))
    sd = np.arange(n_dense) * (length / n_dense)
    x = np.interp(sd, s, closed[:, 0])
    y = np.interp(sd, s, closed[:, 1])
    if smoothing > 0:
        sigma = smoothing / (length / n_dense)
        x = gaussian_filter1d(x, sigma, mode="wrap")
        y = gaussian_filter1d(y, sigma, mode="wrap")
    tx = np.roll(x, -1) - np.roll(x, 1)
    ty = np.roll(y, -1) - np.roll(y, 1)
    norm = np.hypot(tx, ty)
    norm[norm == 0] = 1.0
    nx, ny = ty / norm, -tx / norm  # outward for a counter-clockwise curve
    x, y = x + offset * nx, y + offset * ny
    # Resample by arc length of the smoothed, offset curve.
    closed = np.stack([np.append(x, x[0]), np.append(y, y[0])], axis=1)
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n_out = max(3, min(int(round(s[-1] / spacing)), MAX_OUTLINE_POINTS))
    so = (np.arange(n_out) + 0.5) * (s[-1] / n_out)
    px = np.interp(so, s, closed[:, 0])
    py = np.interp(so, s, closed[:, 1])
    nxo = np.interp(so, s, np.append(nx, nx[0]))
    nyo = np.interp(so, s, np.append(ny, ny[0]))
    nn = np.hypot(nxo, nyo)
    nn[nn == 0] = 1.0
    return np.stack([px, py], axis=1), np.stack([nxo / nn, nyo / nn], axis=1)


# --------------------------------------------------------------------------------------------
# Rotation search
# --------------------------------------------------------------------------------------------
def _rot(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return np.cos(theta), np.sin(theta)


def chamfer_cost(theta: ArrayLike, ref: TopDownView, ref_points: NDArray[np.float64],
                 cur: TopDownView, cur_points: NDArray[np.float64],
                 truncation: float) -> NDArray[np.float64]:
    """Symmetric truncated chamfer cost of the hypothesis "the object turned by ``theta``
    (about its centroid) from the reference view to the current one", metres, for every
    angle in ``theta`` (T,).

    ``ref_points`` / ``cur_points`` (N, 2) are outline points of each view in ``world``. The
    cost is the mean of ``min(|sdf_ref(R(-theta)(p - c_cur) + c_ref)|, truncation)`` over the
    current points plus the same with the roles swapped (rotation by ``+theta``), halved.
    """
    th = np.atleast_1d(np.asarray(theta, dtype=np.float64))
    c, s = _rot(th)
    pc = cur_points - cur.centroid  # (N, 2)
    qr = ref_points - ref.centroid
    # Current points rotated back by -theta onto the reference; reference points by +theta.
    fwd = np.stack([c[:, None] * pc[:, 0] + s[:, None] * pc[:, 1],
                    -s[:, None] * pc[:, 0] + c[:, None] * pc[:, 1]], axis=-1) + ref.centroid
    bwd = np.stack([c[:, None] * qr[:, 0] - s[:, None] * qr[:, 1],
                    s[:, None] * qr[:, 0] + c[:, None] * qr[:, 1]], axis=-1) + cur.centroid
    d1 = np.minimum(np.abs(ref.sample_sdf(fwd, truncation)), truncation).mean(axis=1)
    d2 = np.minimum(np.abs(cur.sample_sdf(bwd, truncation)), truncation).mean(axis=1)
    return 0.5 * (d1 + d2)


@dataclass(frozen=True)
class RotationResult:
    """Outcome of :func:`rotation_search`.

    Attributes
    ----------
    theta : float
        Chosen rotation (current relative to reference), radians, continuous: within pi of
        the previous angle.
    cost : float
        Chamfer cost at ``theta``, metres.
    candidates : (K,) float
        All refined minima within the symmetry tolerance of the best, radians in (-pi, pi].
    """

    theta: float
    cost: float
    candidates: NDArray[np.float64]


def rotation_search(ref: TopDownView, ref_points: NDArray[np.float64], cur: TopDownView,
                    cur_points: NDArray[np.float64], previous: float,
                    cfg: PerceptionConfig) -> RotationResult:
    """Rotation of the current view relative to the reference (see the module docstring).

    Parameters
    ----------
    ref, cur : TopDownView
        Reference (first frame) and current views.
    ref_points, cur_points : (N, 2) float
        Outline points of each view in ``world``, metres.
    previous : float
        Angle reported for the previous frame, radians (0 for the second frame).
    cfg : PerceptionConfig

    Returns
    -------
    RotationResult
    """
    trunc = cfg.chamfer_truncation
    step = math.radians(cfg.coarse_step_deg)
    n = int(math.ceil(2 * math.pi / step))
    grid = -math.pi + np.arange(n) * (2 * math.pi / n)
    # Coarse search on every third point (6 mm apart at the default spacing: plenty).
    coarse = chamfer_cost(grid, ref, ref_points[::3], cur, cur_points[::3], trunc)
    left, right = np.roll(coarse, 1), np.roll(coarse, -1)
    minima = np.nonzero((coarse <= left) & (coarse <= right))[0]
    # Refine the promising minima (within a generous margin of the coarse best) together.
    best_coarse = coarse[minima].min()
    margin = cfg.symmetry_tolerance + 0.5 * best_coarse
    promising = minima[coarse[minima] <= best_coarse + margin]
    if len(promising) > MAX_REFINED_MINIMA:  # bounded work (only with a very fine grid)
        promising = promising[np.argsort(coarse[promising], kind="stable")[:MAX_REFINED_MINIMA]]
    thetas = grid[promising]
    thetas, costs = _refine(thetas, 2 * math.pi / n, math.radians(cfg.angle_tolerance_deg),
                            ref, ref_points, cur, cur_points, trunc)
    best = costs.min()
    close = costs <= best + cfg.symmetry_tolerance
    cand = _wrap(thetas[close])
    # The candidate closest to the previous angle, reported continuously around it.
    deltas = _wrap(cand - previous)
    k = int(np.argmin(np.abs(deltas)))
    return RotationResult(theta=float(previous + deltas[k]), cost=float(costs[close][k]),
                          candidates=cand)


def _refine(thetas: NDArray[np.float64], step: float, tol: float, ref: TopDownView,
            ref_points: NDArray[np.float64], cur: TopDownView, cur_points: NDArray[np.float64],
            trunc: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Refine several local minima at once (one vectorised cost call per iteration).

    Each iteration evaluates every angle at ``theta + h (-1, -1/2, 0, 1/2, 1)``; if the lowest
    value is at an end the angle moves there (same ``h``), otherwise it moves to the vertex of
    the parabola through the lowest value and its two neighbours and ``h`` shrinks by 2.5,
    until ``h < tol``. The chamfer cost is not quadratic far from its minimum (it is closer
    to a V with a noise floor), hence the small steps. Returns the angles and their costs.
    """
    h = step
    offsets = np.linspace(-1.0, 1.0, 5)
    for _ in range(100):  # bounded: each end move covers h, each other iteration shrinks h
        if h < tol:
            break
        c = chamfer_cost((thetas[:, None] + h * offsets).ravel(), ref, ref_points, cur,
                         cur_points, trunc).reshape(-1, 5)
        j = np.argmin(c, axis=1)
        at_end = (j == 0) | (j == 4)
        jj = np.clip(j, 1, 3)
        rows = np.arange(len(j))
        c0, c1, c2 = c[rows, jj - 1], c[rows, jj], c[rows, jj + 1]
        denom = c0 - 2.0 * c1 + c2
        vertex = np.where(denom > 0, 0.5 * (c0 - c2) / np.where(denom > 0, denom, 1.0), 0.0)
        inner = offsets[jj] + 0.5 * np.clip(vertex, -1.0, 1.0)
        thetas = thetas + h * np.where(at_end, offsets[j], inner)
        if not np.any(at_end):
            h /= 2.5
    return thetas, chamfer_cost(thetas, ref, ref_points, cur, cur_points, trunc)


def _wrap(theta: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped to (-pi, pi]."""
    t = np.asarray(theta, dtype=np.float64)
    return np.pi - np.mod(np.pi - t, 2 * np.pi)


# --------------------------------------------------------------------------------------------
# Covariance
# --------------------------------------------------------------------------------------------
def pose_covariance(n_valid: int, valid_fraction: float, area_mismatch: float,
                    match_cost: float, reference_area: float, radius_of_gyration: float,
                    cfg: PerceptionConfig) -> NDArray[np.float64]:
    """Covariance (3, 3) of the measured (x, y, theta), m^2 and rad^2 (module docstring).

    Parameters
    ----------
    n_valid : int
        Mask pixels with a valid depth (>= 1).
    valid_fraction : float
        ``n_valid`` over the number of mask pixels, (0, 1].
    area_mismatch : float
        ``|A_t / A_0 - 1|`` of the footprint areas (0 on the first frame).
    match_cost : float
        Chamfer residual of the rotation search, metres (0 on the first frame).
    reference_area : float
        First frame's footprint area, m^2.
    radius_of_gyration : float
        First frame's footprint radius of gyration, m.
    cfg : PerceptionConfig
    """
    k = math.sqrt(NOMINAL_PIXELS / max(n_valid, 1)) / max(valid_fraction, 1e-3)
    sigma_p = cfg.sigma_position * k + area_mismatch * math.sqrt(reference_area) / 2.0
    excess = max(match_cost - cfg.match_cost_floor, 0.0)
    sigma_t = cfg.sigma_theta * k + excess / max(radius_of_gyration, 1e-3) + area_mismatch
    return np.diag([sigma_p**2, sigma_p**2, sigma_t**2])


# --------------------------------------------------------------------------------------------
# Episode tracking
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Measurement:
    """What one frame says about the object.

    Attributes
    ----------
    pose : (3,) float
        ``(x, y, theta)``: area centroid of the footprint in ``world`` (m) and the orientation
        relative to the episode's first frame (rad, continuous across frames; 0 on the first).
    covariance : (3, 3) float
        Of ``pose``, m^2 / rad^2.
    n_mask, n_valid : int
        Mask pixels, and those with a valid depth.
    area : float
        Footprint area, m^2.
    match_cost : float
        Chamfer residual of the rotation search, m (0 on the first frame).
    candidates : int
        Number of symmetric orientation candidates (1 for an asymmetric match, 0 when the
        orientation is not observed).
    is_reference : bool
        True on the first frame of an episode (the outline was computed from it).
    orientation_observed : bool
        False for a continuously symmetric outline (:mod:`push_core.symmetry`): ``pose[2]`` is
        the episode frame's 0 and ``covariance[2, 2]`` is ``UNOBSERVED_VARIANCE``.
    anchored : bool
        True on the first frame after :meth:`EpisodeTracker.anchor` that matched the anchor:
        the outline is the anchor's, the yaw the frame's in the episode frame.
    """

    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]
    n_mask: int
    n_valid: int
    area: float
    match_cost: float
    candidates: int
    is_reference: bool
    orientation_observed: bool = True
    anchored: bool = False


class EpisodeTracker:
    """Pose, relative orientation and outline over one episode (not thread-safe).

    The first successful :meth:`update` after construction or :meth:`reset` fixes the
    reference: the ``object`` frame (origin at that frame's footprint centroid, axes = world
    axes) and the outline in it (:attr:`outline`).
    """

    def __init__(self, cfg: PerceptionConfig | None = None) -> None:
        self.cfg = PerceptionConfig() if cfg is None else cfg
        self.reset()

    def reset(self) -> None:
        """Start a new episode: the next good frame becomes the reference."""
        self._ref: TopDownView | None = None
        self._ref_points: NDArray[np.float64] | None = None
        self._outline: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._previous = 0.0
        self._symmetric = False
        #: Yaw of the reference frame in the episode frame (non-zero only when anchored).
        self._offset = 0.0
        self._anchor: tuple[NDArray[np.float64], NDArray[np.float64], float] | None = None

    def anchor(self, points: ArrayLike, normals: ArrayLike, yaw: float) -> None:
        """Continue an episode begun elsewhere (a restarted perception node): the next good
        frame is matched against this episode outline instead of becoming yaw 0.

        Parameters
        ----------
        points, normals : (K, 2) float
            The episode's outline in its ``object`` frame (metres, counter-clockwise, outward
            unit normals): what the episode's first frame gave.
        yaw : float
            A recent estimate of the object's yaw in the episode frame, radians: it picks the
            symmetric equivalent of the match (it need only be within half the symmetry angle)
            and is the yaw reported for a continuously symmetric outline.

        The next good frame's footprint is matched by :func:`rotation_search` against a
        footprint rasterised from ``points`` (:func:`outline_view`); its yaw in the episode
        frame becomes the offset of every later frame, and :attr:`outline` is ``points``. A
        match costing more than ``ANCHOR_MAX_COST`` (another object) drops the anchor: that
        frame becomes a new reference, as after :meth:`reset`.
        """
        pts = np.asarray(points, dtype=np.float64)
        nrm = np.asarray(normals, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape != nrm.shape or len(pts) < 3:
            raise ValueError(f"anchor outline must be (K, 2) points and normals with K >= 3, "
                             f"got {pts.shape} and {nrm.shape}")
        if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(nrm)) and math.isfinite(yaw)):
            raise ValueError("anchor outline and yaw must be finite")
        self.reset()
        self._anchor = (pts.copy(), nrm.copy(), float(yaw))

    @property
    def anchored(self) -> bool:
        """Whether the next good frame will be matched against an anchor (:meth:`anchor`)."""
        return self._anchor is not None and self._ref is None

    @property
    def outline(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """(points, normals) (K, 2) of the episode's outline in the ``object`` frame (metres,
        counter-clockwise, outward unit normals), or None before the first good frame."""
        return self._outline

    @property
    def orientation_observable(self) -> bool:
        """False when the episode's outline is continuously symmetric (a disc): its
        orientation cannot be seen (:func:`push_core.symmetry.has_continuous_symmetry`)."""
        return not self._symmetric

    @property
    def reference(self) -> TopDownView | None:
        """The first frame's top-down view (None before the first good frame)."""
        return self._ref

    def measure_frame(self, segmenter: Any, frame: Any) -> Measurement:
        """Segment a rendered frame and :meth:`update` with its mask (the in-process path).

        ``frame`` has ``rgb``, ``depth``, ``camera_matrix`` and ``T_world_camera`` (for example
        ``sim_bridge.world.Frame``); ``segmenter`` is a ``push_perception.model.Segmenter``.
        Raises :class:`PerceptionError` like :meth:`update`.
        """
        seg = segmenter(frame.rgb, frame.depth, frame.camera_matrix, frame.T_world_camera)
        return self.update(seg.mask, frame.depth, frame.camera_matrix, frame.T_world_camera)

    def update(self, mask: ArrayLike, depth: ArrayLike, camera_matrix: ArrayLike,
               t_world_camera: ArrayLike) -> Measurement:
        """Measure the object in one frame.

        Parameters
        ----------
        mask : (H, W) bool
            Object pixels.
        depth : (H, W) float
            z-depth aligned to the mask, metres; NaN/0 = no return.
        camera_matrix : (3, 3)
            K, pixels.
        t_world_camera : (4, 4)
            world <- camera_color_optical_frame.

        Raises
        ------
        PerceptionError
            With ``kind`` ``"bad_input"``, ``"empty_mask"``, ``"out_of_view"``,
            ``"few_pixels"``, ``"no_depth"`` or ``"fragmented"``; the tracker's state is
            unchanged.
        """
        cfg = self.cfg
        m, d, k, t = check_frame_arrays(mask, depth, camera_matrix, t_world_camera)
        n_mask = int(np.count_nonzero(m))
        if n_mask == 0:
            raise PerceptionError("empty_mask", "the object mask is empty (object not found)")
        border = int(np.count_nonzero(m[0]) + np.count_nonzero(m[-1])
                     + np.count_nonzero(m[1:-1, 0]) + np.count_nonzero(m[1:-1, -1]))
        if border > cfg.max_border_pixels:
            raise PerceptionError("out_of_view", f"the object touches the image border "
                                  f"({border} mask pixels on it): partly out of view")
        if n_mask < cfg.min_pixels:
            raise PerceptionError("few_pixels", f"only {n_mask} mask pixels (< min_pixels = "
                                  f"{cfg.min_pixels})")
        points, _ = object_points(m, d, k, t)
        n_valid = len(points)
        fraction = n_valid / n_mask
        if n_valid < cfg.min_pixels or fraction < cfg.min_valid_fraction:
            raise PerceptionError("no_depth", f"only {n_valid} of {n_mask} mask pixels have a "
                                  f"valid depth ({100 * fraction:.0f} %; need >= "
                                  f"{cfg.min_pixels} and {100 * cfg.min_valid_fraction:.0f} %)")
        view = top_down_view(points, cfg)
        pts, normals = smooth_outline(view.boundary, cfg.outline_spacing,
                                      cfg.outline_smoothing,
                                      0.5 * cfg.resolution + cfg.outline_offset)
        if self._ref is None and self._anchor is not None:
            anchored = self._anchored_reference(view, pts, n_mask, n_valid, fraction)
            if anchored is not None:
                return anchored
        if self._ref is None:
            self._ref, self._ref_points = view, pts
            self._outline = (pts - view.centroid, normals)
            self._previous = 0.0
            self._symmetric = has_continuous_symmetry(self._outline[0])
            cov = pose_covariance(n_valid, fraction, 0.0, 0.0, view.area,
                                  view.radius_of_gyration, cfg)
            return self._measurement(np.array([*view.centroid, 0.0]), cov, n_mask, n_valid,
                                     view.area, 0.0, 1, True)
        ref = self._ref
        mismatch = abs(view.area / ref.area - 1.0)
        if self._symmetric:  # no orientation to search for (a disc): position only
            cov = pose_covariance(n_valid, fraction, mismatch, 0.0, ref.area,
                                  ref.radius_of_gyration, cfg)
            return self._measurement(np.array([*view.centroid, self._offset + self._previous]),
                                     cov, n_mask, n_valid, view.area, 0.0, 0, False)
        rot = rotation_search(ref, self._ref_points, view, pts, self._previous, cfg)
        self._previous = rot.theta
        cov = pose_covariance(n_valid, fraction, mismatch, rot.cost, ref.area,
                              ref.radius_of_gyration, cfg)
        return self._measurement(np.array([*view.centroid, self._offset + rot.theta]), cov,
                                 n_mask, n_valid, view.area, rot.cost, len(rot.candidates),
                                 False)

    def _anchored_reference(self, view: TopDownView, pts: NDArray[np.float64], n_mask: int,
                            n_valid: int, fraction: float) -> Measurement | None:
        """Make ``view`` the reference of an anchored episode (:meth:`anchor`); None (and the
        anchor dropped) when the anchor outline does not match it."""
        cfg = self.cfg
        points, normals, yaw = self._anchor
        self._anchor = None
        symmetric = has_continuous_symmetry(points)
        cost = 0.0
        if symmetric:
            theta = yaw
        else:
            ref = outline_view(points, cfg)
            rot = rotation_search(ref, points, view, pts, yaw, cfg)
            if rot.cost > ANCHOR_MAX_COST:
                return None
            theta, cost = rot.theta, rot.cost
        self._ref, self._ref_points = view, pts
        self._outline = (points, normals)
        self._symmetric = symmetric
        self._offset, self._previous = float(theta), 0.0
        cov = pose_covariance(n_valid, fraction, 0.0, cost, view.area, view.radius_of_gyration,
                              cfg)
        meas = self._measurement(np.array([*view.centroid, theta]), cov, n_mask, n_valid,
                                 view.area, cost, 1, True)
        return replace(meas, anchored=True)

    def _measurement(self, pose: NDArray[np.float64], cov: NDArray[np.float64], n_mask: int,
                     n_valid: int, area: float, cost: float, candidates: int,
                     is_reference: bool) -> Measurement:
        """The frame's Measurement; a continuously symmetric outline reports its orientation
        as not observed (variance ``UNOBSERVED_VARIANCE``)."""
        if self._symmetric:
            cov = cov.copy()
            cov[2, 2] = UNOBSERVED_VARIANCE
        return Measurement(pose, cov, n_mask, n_valid, area, cost, candidates, is_reference,
                           orientation_observed=not self._symmetric)
