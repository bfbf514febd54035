"""The clear pose: where the arm ends a push so the camera sees the object (ROS-free).

After a push the arm does not park: it withdraws to a pose near the work whose image leaves the
object's silhouette free (docs/design/cycle.md). :class:`ClearView` is what
:func:`push_executor.motion.plan_push` asks (the :class:`push_executor.motion.View` protocol):
candidate tool tip positions, the preferred first, and how many pixels of the object's
silhouette the arm covers at a posture; the planner takes the first candidate that passes the
motion checks and covers none.

Inputs (all in ``world`` unless said otherwise; REP 103, metres):

- the camera (:class:`CameraView`): the pinhole matrix ``K`` (pixels) and the image size of
  ``camera/color/camera_info``, the pose ``T_world_camera`` (4 x 4) of
  ``camera/color/extrinsics`` (OpenCV pixels, optical frame z forward, x right, y down);
- the object: its outline in the object frame (``perception/outline``) at its last estimated
  pose (x, y, theta; ``estimator/object_pose``), and the push (contact and end point). Where the
  object lies after the push is not known yet, so the *region* it may occupy is the convex hull
  of the outline at the estimate, moved by the contact segment and turned by up to
  ``turn`` either way about its moved centre, grown by ``margin``
  (:func:`object_region`); its silhouette is the image of that region between the table and
  ``height`` (:func:`silhouette`);
- the robot's image at a posture: a callable ``robot_mask(q) -> (H, W) bool`` at the view's
  resolution (:func:`robot_mask_factory`: the URDF's collision geometry posed and rendered by
  :class:`push_core.robot_view.RobotGeometry`, as perception's self-filter does).

Candidates (:func:`clear_candidates`): the tip where the lift ends (the retreat point at the
approach height), then points around the region's centre at half ``distance`` and at
``distance`` beyond its radius, in eight directions starting from the lift's, at the lift's
height and ``rise`` above it, nearest to the lift's end first.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull, QhullError

from push_core.geometry import object_to_world, rot2
from push_core.robot_view import RobotGeometry

__all__ = ["CameraView", "ClearView", "clear_candidates", "fill_convex", "object_region",
           "robot_mask_factory", "silhouette"]

#: Directions of the candidates around the object, from the lift's own, rad.
DIRECTIONS = tuple(math.radians(a) for a in (0, 45, -45, 90, -90, 135, -135, 180))
#: Points on the circle a margin is approximated by (the region grows by their hull).
MARGIN_POINTS = 12
#: Corners of the object's prism nearer the camera's plane than this (m, optical depth), or
#: projected farther than this from the image origin (px), make its silhouette the whole image.
NEAR, FAR_PX = 1e-3, 1e6


@dataclass(frozen=True)
class CameraView:
    """A pinhole camera: ``K`` (3, 3) pixels, ``width`` x ``height``, ``T_world_camera`` (4, 4).

    Raises
    ------
    ValueError
        A non-finite or non-pinhole ``K``, a size below 1, a ``T_world_camera`` that is not a
        finite rigid transform.
    """

    camera_matrix: NDArray[np.float64]
    width: int
    height: int
    t_world_camera: NDArray[np.float64]

    def __post_init__(self) -> None:
        k = np.asarray(self.camera_matrix, dtype=float)
        t = np.asarray(self.t_world_camera, dtype=float)
        if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0 \
                or not np.allclose(k[2], (0.0, 0.0, 1.0)):
            raise ValueError(f"camera matrix: expected a finite pinhole K, got {k.tolist()}")
        if int(self.width) < 1 or int(self.height) < 1:
            raise ValueError(f"image size: expected >= 1 x 1, got {self.width} x {self.height}")
        if t.shape != (4, 4) or not np.all(np.isfinite(t)) \
                or not np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-6):
            raise ValueError("T_world_camera: expected a finite 4 x 4 rigid transform")
        object.__setattr__(self, "camera_matrix", k)
        object.__setattr__(self, "t_world_camera", t)

    def scaled(self, factor: float) -> CameraView:
        """The same camera at ``factor`` times the resolution (pixel centres kept)."""
        k = self.camera_matrix.copy()
        k[:2, :2] *= factor
        k[:2, 2] = (k[:2, 2] + 0.5) * factor - 0.5
        return CameraView(k, max(1, round(self.width * factor)),
                          max(1, round(self.height * factor)), self.t_world_camera)

    def project(self, points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Pixels (N, 2) (u, v) and optical depths (N,) of world points (N, 3)."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        t = self.t_world_camera
        cam = (p - t[:3, 3]) @ t[:3, :3]  # R^T (p - c), row-wise
        z = cam[:, 2]
        uv = (cam @ self.camera_matrix.T)[:, :2] / np.where(z > 1e-9, z, np.nan)[:, None]
        return uv, z


def _hull(points: ArrayLike) -> NDArray[np.float64]:
    """Counter-clockwise convex hull (H, 2) of points (N, 2) (qhull; fewer than 3 points or
    collinear ones: the points themselves)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    try:
        return pts[ConvexHull(pts).vertices]  # counter-clockwise in 2-D
    except (QhullError, ValueError):
        return pts


def object_region(outline: ArrayLike, pose: ArrayLike, contact: ArrayLike, end: ArrayLike,
                  margin: float, turn: float) -> NDArray[np.float64]:
    """Where the object may lie after the push: a convex polygon (M, 2) in ``world``, m.

    Parameters
    ----------
    outline : (K, 2) array_like
        Outline points in the object frame, m.
    pose : (3,) array_like
        The object's estimated pose (x, y, theta) in ``world``.
    contact, end : (2,) array_like
        The push's contact and end point, m: the object moves at most by ``end - contact``.
    margin : float
        Growth of the region, m (>= 0).
    turn : float
        Largest rotation of the object during the push either way, rad (>= 0).
    """
    footprint = np.asarray(object_to_world(pose, np.asarray(outline, dtype=float)))
    shift = np.asarray(end, dtype=float) - np.asarray(contact, dtype=float)
    centre = footprint.mean(axis=0) + shift
    moved = [footprint, footprint + shift]
    for angle in (-turn, turn):
        moved.append((footprint + shift - centre) @ rot2(angle).T + centre)
    hull = _hull(np.vstack(moved))
    if margin > 0:
        circle = margin * np.stack([np.cos(np.linspace(0, 2 * np.pi, MARGIN_POINTS,
                                                       endpoint=False)),
                                    np.sin(np.linspace(0, 2 * np.pi, MARGIN_POINTS,
                                                       endpoint=False))], axis=1)
        hull = _hull((hull[:, None, :] + circle[None, :, :]).reshape(-1, 2))
    return hull


def fill_convex(polygon: ArrayLike, width: int, height: int) -> NDArray[np.bool_]:
    """Pixels (``height`` x ``width``) whose centres lie in a convex polygon (N, 2) of pixel
    coordinates (u, v), either winding; an empty mask for fewer than 3 finite vertices."""
    poly = np.asarray(polygon, dtype=float).reshape(-1, 2)
    poly = poly[np.all(np.isfinite(poly), axis=1)]
    mask = np.zeros((height, width), dtype=bool)
    if len(poly) < 3:
        return mask
    hull = _hull(poly)  # counter-clockwise in (u, v)
    if len(hull) < 3:
        return mask
    # clipped before the cast: a vertex far outside the image (a point near the camera's
    # plane projects to 1e300 px) would overflow the integer and wrap
    size = [width - 1, height - 1]
    lo = np.floor(np.clip(hull.min(axis=0), 0, size)).astype(int)
    hi = np.ceil(np.clip(hull.max(axis=0), 0, size)).astype(int)
    u, v = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    inside = np.ones(u.shape, dtype=bool)
    for a, b in zip(hull, np.roll(hull, -1, axis=0), strict=True):
        inside &= (b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0]) >= -1e-9
    mask[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1] = inside
    return mask


def silhouette(camera: CameraView, region: ArrayLike, height: float) -> NDArray[np.bool_]:
    """The image (``camera.height`` x ``camera.width`` bool) of the prism over ``region``
    (M, 2; ``world``) from the table (z = 0) up to ``height`` (m): the convex hull of its
    projected corners; the whole image when a corner lies within :data:`NEAR` of the camera's
    plane or behind it, or projects beyond :data:`FAR_PX` (no pose is then clear of it: the
    arm parks)."""
    region = np.asarray(region, dtype=float).reshape(-1, 2)
    corners = np.vstack([np.column_stack([region, np.full(len(region), z)])
                         for z in (0.0, height)])
    uv, z = camera.project(corners)
    if np.any(z <= NEAR) or not np.all(np.abs(uv) <= FAR_PX):  # the camera inside or beside
        return np.ones((camera.height, camera.width), dtype=bool)  # the prism: all of it
    return fill_convex(uv, camera.width, camera.height)


def clear_candidates(top: ArrayLike, region: ArrayLike, distance: float, rise: float
                     ) -> list[NDArray[np.float64]]:
    """Tool tip positions (x, y, z) for the clear pose, the preferred first (module docstring).

    Parameters
    ----------
    top : (3,) array_like
        The tip at the end of the lift, ``world``, m: the candidates are at its height and
        ``rise`` above.
    region : (M, 2) array_like
        The object's region (:func:`object_region`).
    distance, rise : float
        m.
    """
    top = np.asarray(top, dtype=float)
    region = np.asarray(region, dtype=float).reshape(-1, 2)
    centre = region.mean(axis=0)
    radius = float(np.max(np.linalg.norm(region - centre, axis=1)))
    away = top[:2] - centre
    heading = math.atan2(away[1], away[0]) if np.linalg.norm(away) > 1e-9 else 0.0
    ring = []
    for z in (top[2], top[2] + rise):
        for r in (radius + distance / 2, radius + distance):
            for a in DIRECTIONS:
                xy = centre + r * np.array([math.cos(heading + a), math.sin(heading + a)])
                ring.append(np.array([xy[0], xy[1], z]))
    ring.sort(key=lambda p: float(np.linalg.norm(p - top)))
    return [top, *ring]


class ClearView:
    """The camera, the object's silhouette and the robot's image (module docstring).

    Parameters
    ----------
    camera : CameraView
        At the resolution of the check (the masks' size).
    region : (M, 2) array_like
        The object's region in ``world`` (:func:`object_region`).
    height : float
        Height of the object's prism, m.
    robot_mask : callable
        ``robot_mask(q)``: (``camera.height``, ``camera.width``) bool, the arm's pixels at
        chain posture ``q``.
    distance, rise : float
        Of the candidates (:func:`clear_candidates`), m.
    """

    def __init__(self, camera: CameraView, region: ArrayLike, height: float,
                 robot_mask: Callable[[NDArray[np.float64]], NDArray[np.bool_]],
                 distance: float, rise: float) -> None:
        self.camera = camera
        self.region = np.asarray(region, dtype=float)
        self.mask = silhouette(camera, self.region, height)
        self._robot_mask = robot_mask
        self._candidate_args = (distance, rise)
        #: Postures checked by :meth:`covered` (a diagnostic of the search).
        self.checked = 0

    def candidates(self, tip: NDArray[np.float64]) -> Sequence[NDArray[np.float64]]:
        """:func:`clear_candidates` around the region from the lift's end ``tip``."""
        return clear_candidates(tip, self.region, *self._candidate_args)

    def covered(self, q: NDArray[np.float64]) -> int:
        """Pixels of the object's silhouette the arm covers at posture ``q``."""
        self.checked += 1
        robot = np.asarray(self._robot_mask(q), dtype=bool)
        if robot.shape != self.mask.shape:
            raise ValueError(f"robot mask {robot.shape}, expected {self.mask.shape}")
        return int(np.count_nonzero(robot & self.mask))


def robot_mask_factory(urdf: str, base_pose: Sequence[float], joint_names: Sequence[str]
                       ) -> tuple[Callable[[CameraView], Callable[[NDArray[np.float64]],
                                                                   NDArray[np.bool_]]] | None,
                                  str]:
    """The arm's image at a camera from its URDF's collision geometry
    (:class:`push_core.robot_view.RobotGeometry`): ``(factory, "")`` with ``factory(camera)
    -> robot_mask(q)`` (chain postures in ``joint_names`` order), or ``(None, why not)``. A
    posture the model cannot render (a joint it needs that the chain lacks) gives a mask
    covering the whole image: that pose is never taken for clear."""
    try:
        robot = RobotGeometry.from_urdf(urdf, base_pose=tuple(base_pose))
    except ValueError as exc:
        return None, f"no robot image: {exc}"
    names = list(joint_names)

    def at(camera: CameraView) -> Callable[[NDArray[np.float64]], NDArray[np.bool_]]:
        def mask(q: NDArray[np.float64]) -> NDArray[np.bool_]:
            try:
                return robot.render(camera.camera_matrix, camera.t_world_camera, camera.width,
                                    camera.height, names, q).mask
            except ValueError:
                return np.ones((camera.height, camera.width), dtype=bool)
        return mask

    return at, ""
