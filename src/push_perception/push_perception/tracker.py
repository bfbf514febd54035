"""From an object mask and depth to the object's state over an episode: pose, relative
orientation, outline, covariance.

ROS-free (numpy, OpenCV, scipy); the node (``segmentation_node``) and the evaluation wrap it.
The pipeline's pose steps (docs/design/perception.md); the frames are those of
docs/ARCHITECTURE.md.

Pipeline for one frame (:meth:`EpisodeTracker.update`)
------------------------------------------------------
1. The frame's arrays are checked
   (:func:`push_perception.perception_config.check_frame_arrays`).
2. Object points, the top-down footprint and its centroid, the position
   (:mod:`push_perception.footprint`).
3. The outline with outward normals (:mod:`push_perception.outline`); on the first frame of an
   episode it is the shape encoding, in the ``object`` frame.
4. The orientation relative to the first frame (:mod:`push_perception.orientation`).
   A continuously symmetric outline (a disc; :func:`push_core.symmetry.has_continuous_symmetry`
   of the first frame's outline) has no orientation to find: the search is skipped, the
   orientation stays at the episode frame's 0 and is reported as not observed (variance
   ``push_core.symmetry.UNOBSERVED_VARIANCE``).
5. With the robot's pixels given (``robot``) and the robot touching the object, the pose comes
   from the visible part instead (:mod:`push_perception.occlusion`): the episode's reference
   footprint fitted to what is seen, the robot's edge left out; the share of the object's
   predicted silhouette the robot hides is reported (``Measurement.occluded_share``) and
   above ``max_occluded`` the frame gives no pose (``"occluded"``). The frame that fixes the
   episode's outline must show the object clear of the robot.

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

Whatever the input, one frame costs bounded time and memory: each step bounds its own work
(its module docstring says how).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import wrap_angle
from push_core.symmetry import UNOBSERVED_VARIANCE, has_continuous_symmetry
from push_perception.footprint import (
    TopDownView,
    above_table,
    object_points,
    outline_view,
    top_down_view,
)
from push_perception.occlusion import (
    fit_visible,
    grow,
    hidden_share,
    silhouette,
    visible_match,
    visible_view,
)
from push_perception.orientation import coarse_minima, rotation_search
from push_perception.outline import smooth_outline
from push_perception.perception_config import (
    PerceptionConfig,
    PerceptionError,
    check_frame_arrays,
)
from push_perception.robot_filter import segment

__all__ = ["ANCHOR_MAX_COST", "NOMINAL_PIXELS", "EpisodeTracker", "Measurement",
           "pose_covariance"]

#: Mask size (pixels with depth) at which the base standard deviations apply: a ~100 cm^2
#: object near the workspace centre in a 640 x 480 frame.
NOMINAL_PIXELS = 5000
#: Largest chamfer cost (m) of an anchor outline against the first frame after a restart
#: (:meth:`EpisodeTracker.anchor`): above it the anchor is another object and is dropped.
ANCHOR_MAX_COST = 0.003
#: Smallest IoU of the predicted visible part of the object with its mask for a pose from the
#: visible part (:func:`push_perception.occlusion.visible_match`); below it the fit is refused.
MIN_VISIBLE_MATCH = 0.85


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
    occluded_share : float
        Share of the object's predicted image silhouette hidden by the robot, [0, 1] (0
        without the robot's pixels).
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
    occluded_share: float = 0.0


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
        #: The reference's top height (m) and largest radius about its centroid (m), and the
        #: last measured position (m): the fit's start when the robot hides part of the object.
        self._height = self._reach = 0.0
        self._last_xy = np.zeros(2)
        self._symmetries = np.zeros(1)
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

    def measure_frame(self, segmenter: Any, frame: Any, robot: ArrayLike | None = None,
                      robot_cover: ArrayLike | None = None) -> Measurement:
        """Segment a rendered frame and :meth:`update` with its mask (the in-process path).

        ``frame`` has ``rgb``, ``depth``, ``camera_matrix`` and ``T_world_camera`` (for example
        ``sim_bridge.world.Frame``); ``segmenter`` is a ``push_perception.model.Segmenter``;
        ``robot`` and ``robot_cover`` the robot's pixels, if any, as :meth:`update` takes them
        (the frame is segmented with :func:`push_perception.robot_filter.segment`). Raises
        :class:`PerceptionError` like :meth:`update`.
        """
        rob = None if robot is None else np.asarray(robot, dtype=bool)
        seg = segment(segmenter, frame.rgb, frame.depth, frame.camera_matrix,
                      frame.T_world_camera, rob)
        return self.update(seg.mask, frame.depth, frame.camera_matrix, frame.T_world_camera,
                           rob, robot_cover)

    def update(self, mask: ArrayLike, depth: ArrayLike, camera_matrix: ArrayLike,
               t_world_camera: ArrayLike, robot: ArrayLike | None = None,
               robot_cover: ArrayLike | None = None) -> Measurement:
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
        robot : (H, W) bool, optional
            The robot's pixels (where its model is in front of what the camera measured):
            never object pixels; where they touch the object the pose comes from its visible
            part (module docstring, step 5). None: no robot in view.
        robot_cover : (H, W) bool, optional
            The robot's pixels without the safety margin ``robot`` may have been grown by:
            the occluded share is counted on them (default ``robot``).

        Raises
        ------
        PerceptionError
            With ``kind`` ``"bad_input"``, ``"empty_mask"``, ``"out_of_view"``,
            ``"few_pixels"``, ``"no_depth"``, ``"fragmented"`` or ``"occluded"``; the
            tracker's state is unchanged.
        """
        m, d, k, t = check_frame_arrays(mask, depth, camera_matrix, t_world_camera)
        rob = cover = None
        if robot is not None:
            rob = np.asarray(robot, dtype=bool)
            cover = rob if robot_cover is None else np.asarray(robot_cover, dtype=bool)
            if rob.shape != m.shape or cover.shape != m.shape:
                raise PerceptionError("bad_input", f"robot masks {rob.shape}, {cover.shape} and "
                                      f"mask {m.shape} differ in size")
            m = m & ~rob
        try:
            return self._update(m, d, k, t, rob, cover)
        except PerceptionError as exc:
            # Little or nothing seen where the robot hides the object's last pose: occluded.
            if rob is None or self._ref is None or exc.kind not in (
                    "empty_mask", "few_pixels", "no_depth", "fragmented"):
                raise
            share = self._hidden_share(np.array([*self._last_xy, self._previous]), cover, k, t)
            if share <= self.cfg.max_occluded:
                raise
            raise PerceptionError("occluded", f"the robot hides {100 * share:.0f} % of the "
                                  f"object at its last pose (more than "
                                  f"{100 * self.cfg.max_occluded:.0f} %); {exc}",
                                  share) from None

    def _update(self, m: NDArray[np.bool_], d: NDArray[np.float32], k: NDArray[np.float64],
                t: NDArray[np.float64], rob: NDArray[np.bool_] | None,
                cover: NDArray[np.bool_] | None) -> Measurement:
        cfg = self.cfg
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
        near = None if rob is None else grow(rob, cfg.occlusion_margin_px)
        if near is not None and np.any(near & m):
            if self._ref is None:
                raise PerceptionError("occluded", "the robot touches the object in the frame "
                                      "that would fix the episode's outline; waiting for a "
                                      "clear frame")
            return self._visible_part(m, points, near, rob, cover, k, t, n_mask, n_valid,
                                      fraction)
        view = top_down_view(points, cfg)
        pts, normals = smooth_outline(view.boundary, cfg.outline_spacing,
                                      cfg.outline_smoothing,
                                      0.5 * cfg.resolution + cfg.outline_offset)
        if self._ref is None and self._anchor is not None:
            anchored = self._anchored_reference(view, pts, n_mask, n_valid, fraction)
            if anchored is not None:
                self._set_shape(points, view, pts)
                return anchored
        if self._ref is None:
            self._ref, self._ref_points = view, pts
            self._outline = (pts - view.centroid, normals)
            self._previous = 0.0
            self._symmetric = has_continuous_symmetry(self._outline[0])
            self._set_shape(points, view, pts)
            cov = pose_covariance(n_valid, fraction, 0.0, 0.0, view.area,
                                  view.radius_of_gyration, cfg)
            return self._measurement(np.array([*view.centroid, 0.0]), cov, n_mask, n_valid,
                                     view.area, 0.0, 1, True)
        ref = self._ref
        mismatch = abs(view.area / ref.area - 1.0)
        self._last_xy = view.centroid.copy()
        if self._symmetric:  # no orientation to search for (a disc): position only
            cov = pose_covariance(n_valid, fraction, mismatch, 0.0, ref.area,
                                  ref.radius_of_gyration, cfg)
            return self._measurement(np.array([*view.centroid, self._offset + self._previous]),
                                     cov, n_mask, n_valid, view.area, 0.0, 0, False)
        rot = rotation_search(ref, self._ref_points, view, pts, self._previous, cfg)
        self._previous = rot.theta
        cov = pose_covariance(n_valid, fraction, mismatch, rot.cost, ref.area,
                              ref.radius_of_gyration, cfg)
        share = 0.0 if cover is None else self._hidden_share(
            np.array([*view.centroid, rot.theta]), cover, k, t)
        return self._measurement(np.array([*view.centroid, self._offset + rot.theta]), cov,
                                 n_mask, n_valid, view.area, rot.cost, len(rot.candidates),
                                 False, share)

    def _set_shape(self, points: NDArray[np.float64], view: TopDownView,
                   pts: NDArray[np.float64]) -> None:
        """Keep the reference's top height, reach and symmetry angles (the rotations that map
        its footprint onto itself), and its position as the last one."""
        self._height = above_table(points, self.cfg)[1]
        self._reach = float(np.max(np.linalg.norm(pts - view.centroid, axis=1)))
        self._last_xy = view.centroid.copy()
        self._symmetries = np.zeros(1) if self._symmetric else rotation_search(
            view, pts, view, pts, 0.0, self.cfg).candidates

    def _outline_at(self, pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """The reference outline in ``world`` at ``pose`` (where the reference centroid goes,
        m; rotation since the reference, rad)."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        q = self._ref_points - self._ref.centroid
        return q @ np.array([[c, s], [-s, c]]) + pose[:2]

    def _hidden_share(self, pose: NDArray[np.float64], rob: NDArray[np.bool_],
                      k: NDArray[np.float64], t: NDArray[np.float64]) -> float:
        """The share of the object's predicted silhouette the robot hides at ``pose``."""
        return hidden_share(self._outline_at(pose), self._height, rob, k, t)[0]

    def _visible_part(self, m: NDArray[np.bool_], points: NDArray[np.float64],
                      near: NDArray[np.bool_], rob: NDArray[np.bool_], cover: NDArray[np.bool_],
                      k: NDArray[np.float64], t: NDArray[np.float64], n_mask: int,
                      n_valid: int, fraction: float) -> Measurement:
        """The pose from the visible part of the object (module docstring, step 5)."""
        cfg, ref = self.cfg, self._ref
        kept, _ = above_table(points, cfg)
        vis = visible_view(kept, self._reach, self._height, near, k, t, cfg)
        # Starts: the previous pose, and the whole-view estimate (of its symmetric
        # equivalents the one closest to the previous angle).
        theta = self._previous
        if not self._symmetric:  # the coarse minimum closest to it; the fit refines it
            angles = coarse_minima(ref, self._ref_points, vis.view, vis.view.boundary[::2],
                                   cfg)[0]
            deltas = wrap_angle(angles - self._previous)
            theta = self._previous + float(deltas[np.argmin(np.abs(deltas))])
        starts = [[*self._last_xy, self._previous], [*vis.view.centroid, theta]]
        pose, cost = fit_visible(ref, self._ref_points, vis, starts, self._previous,
                                 not self._symmetric, cfg)
        # A symmetric outline: its equivalent closest to the previous angle, refined, competes
        # (the fit keeps the angle continuous as the whole-view search does).
        turns = pose[2] + self._symmetries
        alt = float(turns[np.argmin(np.abs(wrap_angle(turns - self._previous)))])
        if abs(alt - pose[2]) > math.radians(1.0):
            alt = self._previous + float(wrap_angle(alt - self._previous))
            pose, cost = fit_visible(ref, self._ref_points, vis, [pose, [*pose[:2], alt]],
                                     self._previous, True, cfg)
        sil = silhouette(self._outline_at(pose), self._height, k, t, m.shape)
        share = np.count_nonzero(sil & cover) / max(np.count_nonzero(sil), 1)
        if share > cfg.max_occluded:
            raise PerceptionError("occluded", f"the robot hides {100 * share:.0f} % of the "
                                  f"object (more than {100 * cfg.max_occluded:.0f} %)", share)
        match = visible_match(sil, rob, m)
        self.last_visible_match = match
        if match < MIN_VISIBLE_MATCH:
            raise PerceptionError("occluded", f"the visible part of the object matches the "
                                  f"episode's outline poorly (IoU {match:.2f} < "
                                  f"{MIN_VISIBLE_MATCH}): no reliable pose with the robot "
                                  f"hiding {100 * share:.0f} % of it", share)
        self._previous, self._last_xy = float(pose[2]), pose[:2].copy()
        mismatch = abs(vis.view.area / (ref.area * max(1.0 - share, 1e-3)) - 1.0)
        cov = pose_covariance(n_valid, fraction, mismatch, cost, ref.area,
                              ref.radius_of_gyration, cfg)
        return self._measurement(np.array([*pose[:2], self._offset + pose[2]]), cov, n_mask,
                                 n_valid, vis.view.area, cost, 1, False, share)

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
                     is_reference: bool, occluded_share: float = 0.0) -> Measurement:
        """The frame's Measurement; a continuously symmetric outline reports its orientation
        as not observed (variance ``UNOBSERVED_VARIANCE``)."""
        if self._symmetric:
            cov = cov.copy()
            cov[2, 2] = UNOBSERVED_VARIANCE
        return Measurement(pose, cov, n_mask, n_valid, area, cost, candidates, is_reference,
                           orientation_observed=not self._symmetric,
                           occluded_share=float(occluded_share))
