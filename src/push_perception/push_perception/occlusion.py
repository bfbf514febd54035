"""The object's pose from its visible part when the robot hides some of it, and the hidden share.

ROS-free (numpy, OpenCV). :class:`~push_perception.tracker.EpisodeTracker` calls this when a
frame comes with the robot's pixels (``robot``: (H, W) bool, the pixels where the robot's model
is in front of the surface the camera measured; ``push_core.robot_view`` renders them) and the
robot touches the object's mask. Frames as in docs/ARCHITECTURE.md; the design is in
docs/design/arm-in-view.md.

1. **Hidden cells** (:func:`hidden_cells`). A top-down cell is hidden when its centre, lifted to
   the object's top height, projects into the robot's pixels grown by ``margin_px``: the object
   could be there unseen.
2. **Visible footprint** (:func:`visible_view`). The visible object points rasterised as in
   :func:`push_perception.footprint.top_down_view`, but every component is kept (the rod across
   the object cuts its top face in two) and the boundary cells next to a hidden cell are marked
   *cut*: there the boundary is the robot's edge, not the object's.
3. **Fit** (:func:`fit_visible`). The episode's first clear footprint (the reference), moved by
   a pose ``(x, y, theta)`` (``x, y`` where its centroid goes, ``theta`` its rotation), should
   match the visible footprint where both are seen: the cost is the mean truncated distance of
   the uncut visible boundary to the moved reference boundary, plus that of the moved
   reference boundary points that are not hidden to the visible boundary, halved (the chamfer
   cost of :func:`push_perception.orientation.chamfer_cost`, restricted to what is seen). A
   vectorised pattern search minimises it from two starts: the previous frame's pose and the
   whole-view estimate (the visible centroid, the rotation search's angle closest to the
   previous one); of the minima within ``symmetry_tolerance`` of the best, the one closest to
   the previous angle wins.
4. **Hidden share** (:func:`hidden_share`). The moved reference outline is drawn as a prism
   (top at the object's height, bottom on the table) into the image; the share of its pixels
   that are the robot's is the occluded share of the object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.robot_view import prism_silhouette
from push_perception.footprint import TopDownView
from push_perception.perception_config import PerceptionConfig, PerceptionError

__all__ = ["MIN_FIT_POINTS", "VisibleView", "fit_visible", "grow", "hidden_cells",
           "hidden_share", "project", "silhouette", "touches", "visible_match", "visible_view"]

#: Fewest uncut boundary points a fit needs (a few centimetres of the outline at 1 mm cells).
MIN_FIT_POINTS = 20
#: Smallest component of the visible footprint kept, cells (specks of depth noise).
MIN_COMPONENT_CELLS = 20
#: Pattern search: first steps (m, m, rad), the steps it stops below, most iterations.
_FIRST_STEP = np.array([0.004, 0.004, math.radians(4.0)])
_LAST_STEP = np.array([2e-5, 2e-5, math.radians(0.01)])
_MAX_ITERATIONS = 200
_STENCIL = np.stack(np.meshgrid(*([np.array([-1.0, 0.0, 1.0])] * 3), indexing="ij"),
                    axis=-1).reshape(-1, 3)


def project(points: ArrayLike, camera_matrix: NDArray[np.float64],
            t_world_camera: NDArray[np.float64]) -> tuple[NDArray[np.float64],
                                                          NDArray[np.float64]]:
    """Pixels ``(N, 2)`` (u, v; OpenCV, centres at integers) and optical depths ``(N,)`` (m)
    of world points ``(N, 3)``."""
    p = np.asarray(points, dtype=np.float64)
    t = np.linalg.inv(t_world_camera)
    cam = p @ t[:3, :3].T + t[:3, 3]
    z = cam[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (cam[:, :2] / z[:, None]) @ camera_matrix[:2, :2].T + camera_matrix[:2, 2]
    return uv, z


def _lookup(image: NDArray[np.bool_], uv: NDArray[np.float64], z: NDArray[np.float64]
            ) -> NDArray[np.bool_]:
    """``image`` at the nearest pixel of each ``uv``; False outside it or behind the camera."""
    h, w = image.shape
    u = np.round(uv[:, 0])
    v = np.round(uv[:, 1])
    inside = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    out = np.zeros(len(uv), dtype=bool)
    out[inside] = image[v[inside].astype(np.intp), u[inside].astype(np.intp)]
    return out


def grow(mask: NDArray[np.bool_], radius: int) -> NDArray[np.bool_]:
    """``mask`` dilated by a disc of ``radius`` pixels (``radius`` 0: unchanged)."""
    if radius <= 0:
        return mask
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)


def touches(mask: NDArray[np.bool_], robot: NDArray[np.bool_], margin_px: int) -> bool:
    """Whether an object pixel lies within ``margin_px`` of a robot pixel."""
    return bool(np.any(grow(robot, margin_px) & mask))


def hidden_cells(origin: NDArray[np.float64], shape: tuple[int, int], resolution: float,
                 height: float, near_robot: NDArray[np.bool_],
                 camera_matrix: NDArray[np.float64], t_world_camera: NDArray[np.float64]
                 ) -> NDArray[np.bool_]:
    """Cells of a top-down grid whose centre at ``height`` (m) projects into ``near_robot``.

    The grid is that of :class:`push_perception.footprint.TopDownView`: ``origin`` (2,) the
    corner of cell (0, 0), ``shape`` (rows, cols), rows along +y.
    """
    rows, cols = shape
    xs = origin[0] + (np.arange(cols) + 0.5) * resolution
    ys = origin[1] + (np.arange(rows) + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)
    pts = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, height)])
    uv, z = project(pts, camera_matrix, t_world_camera)
    return _lookup(near_robot, uv, z).reshape(rows, cols)


@dataclass(frozen=True)
class VisibleView:
    """The visible part of the object from above (module docstring, step 2).

    Attributes
    ----------
    view : TopDownView
        Every component of the visible footprint (filled), its centroid, area and signed
        distance field; ``view.boundary`` is every component's boundary, concatenated.
    cut : (P,) bool
        Boundary cells next to a hidden cell.
    hidden : (R, C) bool
        The hidden cells of the grid.
    """

    view: TopDownView
    cut: NDArray[np.bool_]
    hidden: NDArray[np.bool_]

    def hidden_at(self, points: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Whether world points ``(..., 2)`` fall on hidden cells (outside the grid: not
        hidden; the grid reaches beyond wherever the object can be)."""
        v = self.view
        ij = np.floor((points - v.origin) / v.resolution).astype(np.int64)
        rows, cols = self.hidden.shape
        inside = (ij[..., 0] >= 0) & (ij[..., 0] < cols) & (ij[..., 1] >= 0) & (ij[..., 1] < rows)
        out = np.zeros(points.shape[:-1], dtype=bool)
        out[inside] = self.hidden[ij[..., 1][inside], ij[..., 0][inside]]
        return out


def visible_view(points: NDArray[np.float64], reach: float, height: float,
                 near_robot: NDArray[np.bool_], camera_matrix: NDArray[np.float64],
                 t_world_camera: NDArray[np.float64], cfg: PerceptionConfig) -> VisibleView:
    """The visible footprint of object points ``(N, 3)`` (module docstring, step 2).

    Parameters
    ----------
    points : (N, 3) float
        Visible object points in ``world``, m (the table pixels already dropped).
    reach : float
        The grid extends this far beyond the points, m (the object's largest radius: wherever
        its hidden part may lie).
    height : float
        The object's top height above the table, m.
    near_robot : (H, W) bool
        The robot's pixels grown by the margin.
    camera_matrix, t_world_camera
        K and ``world <- optical``.
    cfg : PerceptionConfig

    Raises
    ------
    PerceptionError
        ``"too_large"`` (grid over ``MAX_RASTER_SIDE``, from
        :func:`push_perception.footprint.top_down_view`'s rule), ``"occluded"`` (too little
        of the object is visible).
    """
    from push_perception.footprint import MAX_RASTER_SIDE

    res = cfg.resolution
    xy = points[:, :2]
    pad = reach + cfg.chamfer_truncation + 2 * res
    lo = np.floor((xy.min(axis=0) - pad) / res) * res
    extent = np.ceil((xy.max(axis=0) + pad - lo) / res) + 1
    if not np.all(extent <= MAX_RASTER_SIDE):
        raise PerceptionError("too_large", "the visible object points span a top-down view "
                              f"of more than {MAX_RASTER_SIDE} cells per side")
    cols, rows = extent.astype(int)
    img = np.zeros((rows, cols), dtype=np.uint8)
    ij = ((xy - lo) / res).astype(np.intp)
    img[ij[:, 1], ij[:, 0]] = 1
    r = cfg.closing_radius
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    img = cv2.morphologyEx(img, cv2.MORPH_CLOSE, kernel)
    contours, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contours = [c for c in contours if cv2.contourArea(c) >= MIN_COMPONENT_CELLS]
    if not contours:
        raise PerceptionError("occluded", "too little of the object is visible beside the "
                              "robot (no footprint left)")
    img = np.zeros_like(img)
    cv2.drawContours(img, contours, -1, 1, thickness=cv2.FILLED)
    hidden = hidden_cells(lo, (rows, cols), res, height, near_robot, camera_matrix,
                          t_world_camera) & (img == 0)
    cells = np.concatenate([c[:, 0, :] for c in contours])  # (P, 2) = (col, row)
    # A boundary cell is cut when a hidden cell is among its 8 neighbours (or itself).
    near_hidden = cv2.dilate(hidden.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    cut = near_hidden[cells[:, 1], cells[:, 0]]
    mom = cv2.moments(img, binaryImage=True)
    n = mom["m00"]
    centroid = lo + (np.array([mom["m10"], mom["m01"]]) / n + 0.5) * res
    inside = cv2.distanceTransform(img, cv2.DIST_L2, cv2.DIST_MASK_5)
    outside = cv2.distanceTransform(1 - img, cv2.DIST_L2, cv2.DIST_MASK_5)
    sdf = np.where(img > 0, -(inside - 0.5), outside - 0.5).astype(np.float32) * np.float32(res)
    r_gyr = float(np.sqrt((mom["mu20"] + mom["mu02"]) / n + 1.0 / 6.0) * res)
    view = TopDownView(image=img, origin=lo, resolution=res, centroid=centroid,
                       area=n * res * res, radius_of_gyration=r_gyr,
                       boundary=lo + (cells.astype(np.float64) + 0.5) * res, sdf=sdf)
    return VisibleView(view=view, cut=cut, hidden=hidden)


def _costs(poses: NDArray[np.float64], ref: TopDownView, ref_points: NDArray[np.float64],
           vis: VisibleView, seen: NDArray[np.float64], trunc: float) -> NDArray[np.float64]:
    """The restricted chamfer cost (module docstring, step 3) of poses ``(M, 3)``."""
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    # Seen (uncut) visible boundary points carried back onto the reference: R(-theta)(p - t).
    d = seen[None, :, :] - poses[:, None, :2]
    back = np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)
    a = np.minimum(np.abs(ref.sample_sdf(back + ref.centroid, trunc)), trunc).mean(axis=1)
    # Reference boundary points carried forward: R(theta)(r - c_ref) + t, where not hidden.
    q = ref_points - ref.centroid
    fwd = np.stack([c * q[:, 0] - s * q[:, 1], s * q[:, 0] + c * q[:, 1]], axis=-1) \
        + poses[:, None, :2]
    dist = np.minimum(np.abs(vis.view.sample_sdf(fwd, trunc)), trunc)
    shown = ~vis.hidden_at(fwd)
    b = np.where(shown.any(axis=1), (dist * shown).sum(axis=1) / np.maximum(shown.sum(axis=1),
                                                                            1), trunc)
    return 0.5 * (a + b)


def fit_visible(ref: TopDownView, ref_points: NDArray[np.float64], vis: VisibleView,
                starts: ArrayLike, previous: float, rotate: bool, cfg: PerceptionConfig
                ) -> tuple[NDArray[np.float64], float]:
    """The pose of the reference footprint that best matches the visible one (module
    docstring, step 3).

    Parameters
    ----------
    ref : TopDownView
        The episode's reference (first clear) footprint.
    ref_points : (K, 2) float
        Its outline points in ``world`` (at the reference), m.
    vis : VisibleView
    starts : (S, 3) array_like
        Starting poses ``(x, y, theta)``: where the reference centroid goes (m) and the
        rotation since the reference (rad).
    previous : float
        The previous frame's rotation, rad (picks among symmetric equivalents).
    rotate : bool
        False: the rotation stays at each start's (a continuously symmetric outline).
    cfg : PerceptionConfig

    Returns
    -------
    pose : (3,) float
    cost : float
        Its restricted chamfer cost, m.

    Raises
    ------
    PerceptionError
        ``"occluded"``: fewer than ``MIN_FIT_POINTS`` uncut boundary points.
    """
    seen = vis.view.boundary[~vis.cut]
    if len(seen) < MIN_FIT_POINTS:
        raise PerceptionError("occluded", f"only {len(seen)} boundary cells of the object are "
                              f"its own (the rest is the robot's edge; need {MIN_FIT_POINTS})")
    seen = seen[::2] if len(seen) > 400 else seen
    trunc = cfg.chamfer_truncation
    pose = np.array(starts, dtype=np.float64).reshape(-1, 3)
    step = np.tile(_FIRST_STEP, (len(pose), 1))
    if not rotate:
        step[:, 2] = 0.0
    cost = _costs(pose, ref, ref_points, vis, seen, trunc)
    for _ in range(_MAX_ITERATIONS):  # each start moves one step, or its steps halve
        active = np.any(step > _LAST_STEP, axis=1)
        if not np.any(active):
            break
        cand = pose[active, None, :] + _STENCIL[None] * step[active, None, :]
        got = _costs(cand.reshape(-1, 3), ref, ref_points, vis, seen, trunc).reshape(
            len(cand), -1)
        best = np.argmin(got, axis=1)
        rows = np.nonzero(active)[0]
        moved = got[np.arange(len(rows)), best] < cost[rows] - 1e-12
        pose[rows[moved]] = cand[moved, best[moved]]
        cost[rows[moved]] = got[moved, best[moved]]
        step[rows[~moved]] *= 0.5
    best = cost.min()
    close = np.nonzero(cost <= best + cfg.symmetry_tolerance)[0]
    pick = close[np.argmin(np.abs(pose[close, 2] - previous))]
    return pose[pick], float(cost[pick])


def silhouette(outline: NDArray[np.float64], height: float, camera_matrix: NDArray[np.float64],
               t_world_camera: NDArray[np.float64], shape: tuple[int, int]
               ) -> NDArray[np.bool_]:
    """The object's image silhouette, (H, W) bool: the prism of ``outline`` (K, 2) in
    ``world`` (m, closed) from the table up to ``height`` (m), seen by the camera
    (:func:`push_core.robot_view.prism_silhouette`)."""
    h, w = shape
    return prism_silhouette(outline, height, camera_matrix, np.linalg.inv(t_world_camera), w, h)


def hidden_share(outline: NDArray[np.float64], height: float, robot: NDArray[np.bool_],
                 camera_matrix: NDArray[np.float64], t_world_camera: NDArray[np.float64]
                 ) -> tuple[float, int]:
    """The share of the object's predicted image silhouette that is the robot's.

    Parameters
    ----------
    outline : (K, 2) float
        The object's outline in ``world`` at its pose, m (closed, K >= 3).
    height : float
        The object's top height, m (the silhouette is the prism from the table to it).
    robot : (H, W) bool
    camera_matrix, t_world_camera
        K and ``world <- optical``.

    Returns
    -------
    share : float
        In [0, 1] (0 when the silhouette is out of the image).
    pixels : int
        Pixels of the silhouette in the image.
    """
    sil = silhouette(outline, height, camera_matrix, t_world_camera, robot.shape)
    n = int(np.count_nonzero(sil))
    return (np.count_nonzero(sil & robot) / n if n else 0.0), n


def visible_match(sil: NDArray[np.bool_], robot: NDArray[np.bool_], mask: NDArray[np.bool_]
                  ) -> float:
    """IoU of the predicted visible part (silhouette ``sil`` off the robot's pixels) with the
    object mask ``mask``: near 1 for the right pose, low for a fit that went astray."""
    seen = sil & ~robot
    union = np.count_nonzero(seen | mask)
    return np.count_nonzero(seen & mask) / union if union else 0.0
