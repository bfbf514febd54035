"""The mask-to-state configuration, the error of a frame without a pose, the frame array checks.

ROS-free. :class:`PerceptionConfig` holds every parameter of the pipeline that turns a mask and
a depth image into the object's state (:mod:`push_perception.tracker`), each refused outside the
range in which the pose was measured to stay accurate; :class:`PerceptionError` is what a frame
without a pose raises, the class of the problem in ``kind``; :func:`check_frame_arrays`
validates one frame's mask, depth, K and extrinsics before any step reads them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["CLOSING_RANGE", "PerceptionConfig", "PerceptionError", "check_frame_arrays"]

#: Range of the closing radius in metres (``closing_radius * resolution``), PerceptionConfig.
CLOSING_RANGE = (0.001, 0.01)


class PerceptionError(ValueError):
    """A frame from which no pose can be measured; ``kind`` names the class of problem.

    Kinds: ``"empty_mask"``, ``"few_pixels"``, ``"no_depth"``, ``"out_of_view"``,
    ``"fragmented"`` (the top-down view falls apart into pieces), ``"too_large"`` (the object
    points span more than ``MAX_RASTER_SIDE`` cells), ``"occluded"`` (the robot hides too much
    of the object, or touches it in the frame that would fix the episode's outline),
    ``"bad_input"`` (malformed arrays).
    """

    def __init__(self, kind: str, message: str, occluded_share: float = math.nan) -> None:
        super().__init__(message)
        self.kind = kind
        #: The share of the object the robot hid, when known (kind ``"occluded"``).
        self.occluded_share = float(occluded_share)


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
    max_occluded : float
        With the robot's pixels given: a frame in which the robot hides a larger share of the
        object's predicted silhouette gives no pose (``"occluded"``), [0, 0.9].
    occlusion_margin_px : int
        Object boundary within this many pixels of the robot's pixels is the robot's edge,
        not the object's outline (left out of the fit); the episode's first frame must keep
        the object this far from the robot, [0, 20].
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
    max_occluded: float = 0.3
    occlusion_margin_px: int = 3

    def __post_init__(self) -> None:
        checks = (
            ("resolution", 5e-4, 3e-3), ("min_height", 0.0, 0.01),
            ("outline_spacing", 5e-4, 0.01), ("outline_smoothing", 0.0, 0.01),
            ("outline_offset", -0.005, 0.005), ("coarse_step_deg", 0.1, 10.0),
            ("angle_tolerance_deg", 1e-4, 1.0), ("symmetry_tolerance", 0.0, 0.01),
            ("chamfer_truncation", 1e-4, 0.05), ("min_valid_fraction", 0.0, 1.0),
            ("sigma_position", 1e-6, 1.0), ("sigma_theta", 1e-6, math.pi),
            ("match_cost_floor", 0.0, 0.01), ("max_occluded", 0.0, 0.9),
        )
        for name, low, high in checks:
            value = getattr(self, name)
            if isinstance(value, bool) or not (np.isfinite(value) and low <= value <= high):
                raise ValueError(f"{name}: must be in [{low}, {high}], got {value!r}")
            object.__setattr__(self, name, float(value))
        for name, low, high in (("closing_radius", 2, 10), ("min_pixels", 3, 10**7),
                                ("max_border_pixels", 0, 10**7),
                                ("occlusion_margin_px", 0, 20)):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or not low <= value <= high:
                raise ValueError(f"{name}: must be an integer in [{low}, {high}], got {value!r}")
            object.__setattr__(self, name, int(value))
        closing = self.closing_radius * self.resolution
        if not CLOSING_RANGE[0] - 1e-12 <= closing <= CLOSING_RANGE[1] + 1e-12:
            raise ValueError(f"closing_radius: closing_radius * resolution must be in "
                             f"[{1e3 * CLOSING_RANGE[0]:g}, {1e3 * CLOSING_RANGE[1]:g}] mm, got "
                             f"{self.closing_radius} * {1e3 * self.resolution:g} mm")


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

