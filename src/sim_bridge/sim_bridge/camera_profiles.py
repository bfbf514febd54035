"""Camera profiles: the simulated camera published as common RGB-D drivers publish.

The world renders an ideal pinhole frame (colour and aligned z-depth, :mod:`sim_bridge.camera`)
at the profile's resolution and intrinsics; :func:`driver_frame` then makes it what the driver
sends: lens distortion (the ideal image remapped through the lens model of
:mod:`push_core.camera_model`), the depth camera's noise, its own optical frame when the driver
does not align depth to colour, and the driver's encodings. Topic names are this project's
(``camera/color/image_raw``, ``camera/aligned_depth_to_color/image_raw`` or
``camera/depth/image_raw`` + ``camera/depth/camera_info``); a real driver's names are mapped
onto them by remapping (docs/design/cameras.md).

The figures of each profile are the public data-sheet values of the camera's default ROS
stream (resolution, field of view, baseline); the distortion coefficients are of the size such
lenses report, not of one unit.

- ``default``: this project's camera (640 x 480, 615 px, rgb8, 32FC1 m, ideal, aligned;
  ``depth_noise`` switches the D415-like noise of :func:`sim_bridge.camera.add_depth_noise`).
- ``d415``: Intel RealSense D415, colour 1280 x 720 (69 x 42 deg), rgb8, aligned 16UC1 mm,
  ``plumb_bob``; active stereo, 55 mm baseline, 0.08 px subpixel noise, edge dropouts.
- ``d435``: Intel RealSense D435, colour 848 x 480, rgb8, aligned 16UC1 mm, ``plumb_bob``;
  active stereo with the wide depth imager (87 deg: 447 px at 848 wide), 50 mm baseline.
- ``orbbec``: an Orbbec Astra-class structured-light camera, colour 640 x 480 (570 px),
  ``rational_polynomial``, rgb8; depth 640 x 480 in its own optical frame 25 mm beside the
  colour camera with its own camera_info (not aligned), 16UC1 mm, disparity quantised to 1/8 px
  (75 mm baseline) and the projector's shadow: holes at depth edges.
- ``zed``: a Stereolabs ZED 2i at HD720, 1280 x 720 (525 px: 101 deg wide), bgra8, depth
  32FC1 m on the rectified left image (aligned, zero distortion: the wrapper publishes
  rectified images), passive stereo, 120 mm baseline, 0.15 px subpixel noise, no quantisation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from push_core.camera_model import distortion_maps, register_depth
from sim_bridge.camera import CameraConfig, depth_edges

__all__ = ["PROFILES", "CameraProfile", "DriverFrame", "driver_frame", "profile"]


@dataclass(frozen=True)
class DepthNoise:
    """Depth noise of a stereo or structured-light camera.

    Attributes
    ----------
    kind : str
        ``stereo`` (Gaussian disparity noise) or ``structured_light`` (disparity quantised).
    focal_px, baseline : float
        Depth imager focal length, px, and baseline, m: disparity ``d = f B / z``.
    subpixel : float
        Stereo: RMS disparity noise, px; structured light: the disparity step, px.
    unit : float
        Depth quantisation of the driver, m (0: none, a float stream).
    edge_drop : float
        Probability that a pixel on a depth step larger than 5 mm has no depth.
    drop : float
        Probability that any pixel has no depth.
    """

    kind: str
    focal_px: float
    baseline: float
    subpixel: float
    unit: float = 0.001
    edge_drop: float = 0.5
    drop: float = 0.005

    def apply(self, depth: NDArray[np.float32], rng: np.random.Generator) -> NDArray[np.float32]:
        """Noisy copy of ``depth`` (metres, NaN = none)."""
        z = depth.astype(np.float64)
        fb = self.focal_px * self.baseline
        with np.errstate(invalid="ignore", divide="ignore"):
            disparity = fb / z
            if self.kind == "stereo":
                disparity = disparity + self.subpixel * rng.standard_normal(z.shape)
            else:
                disparity = np.round(disparity / self.subpixel) * self.subpixel
            noisy = fb / disparity
        if self.unit > 0:
            noisy = np.round(noisy / self.unit) * self.unit
        drop = rng.random(z.shape) < self.drop
        drop |= depth_edges(z) & (rng.random(z.shape) < self.edge_drop)
        noisy[drop | ~np.isfinite(noisy)] = np.nan
        return noisy.astype(np.float32)


@dataclass(frozen=True)
class CameraProfile:
    """How one driver publishes (module docstring).

    Attributes
    ----------
    name : str
    width, height : int
        Colour image size, px.
    focal_px : float
        Colour focal length (fx = fy), px; the principal point is the image centre.
    color_encoding, depth_encoding : str
        ``rgb8`` / ``bgr8`` / ``rgba8`` / ``bgra8``; ``16UC1`` (mm) or ``32FC1`` (m).
    distortion_model : str
        ``plumb_bob`` or ``rational_polynomial``.
    distortion : tuple of float
        The colour lens' coefficients (5 or 8, OpenCV's order).
    noise : DepthNoise or None
        None: the ``depth_noise`` switch of the world decides (the default profile only).
    depth_aligned : bool
        Depth published aligned to colour; False: in its own frame with its own camera_info.
    depth_focal_px : float
        Own depth stream: focal length, px (same size as colour).
    depth_offset : tuple of float
        Own depth stream: position of the depth optical frame in the colour optical frame, m
        (same orientation).
    """

    name: str
    width: int = 640
    height: int = 480
    focal_px: float = 615.0
    color_encoding: str = "rgb8"
    depth_encoding: str = "32FC1"
    distortion_model: str = "plumb_bob"
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    noise: DepthNoise | None = None
    depth_aligned: bool = True
    depth_focal_px: float = 0.0
    depth_offset: tuple[float, float, float] = field(default=(0.0, 0.0, 0.0))

    def camera_config(self) -> CameraConfig:
        """The rendered (ideal) camera of this profile."""
        return CameraConfig(width=self.width, height=self.height, fx=self.focal_px,
                            fy=self.focal_px)

    def depth_matrix(self) -> NDArray[np.float64]:
        """K of the own depth stream, px."""
        f = self.depth_focal_px or self.focal_px
        return np.array([[f, 0.0, (self.width - 1) / 2], [0.0, f, (self.height - 1) / 2],
                         [0.0, 0.0, 1.0]])

    def t_color_depth(self) -> NDArray[np.float64]:
        """Pose of the depth optical frame in the colour optical frame (4, 4), m."""
        t = np.eye(4)
        t[:3, 3] = self.depth_offset
        return t


PROFILES: dict[str, CameraProfile] = {
    "default": CameraProfile("default"),
    "d415": CameraProfile(
        "d415", 1280, 720, 922.0, "rgb8", "16UC1", "plumb_bob",
        (0.02, -0.05, 0.0005, -0.0003, 0.01),
        DepthNoise("stereo", 922.0, 0.055, 0.08)),
    "d435": CameraProfile(
        "d435", 848, 480, 615.0, "rgb8", "16UC1", "plumb_bob",
        (0.03, -0.06, 0.0004, 0.0002, 0.02),
        DepthNoise("stereo", 447.0, 0.050, 0.08)),
    "orbbec": CameraProfile(
        "orbbec", 640, 480, 570.0, "rgb8", "16UC1", "rational_polynomial",
        (0.08, -0.12, 0.0006, -0.0004, 0.03, 0.01, -0.02, 0.01),
        DepthNoise("structured_light", 575.0, 0.075, 0.125, edge_drop=0.8),
        depth_aligned=False, depth_focal_px=575.0, depth_offset=(-0.025, 0.0, 0.0)),
    "zed": CameraProfile(
        "zed", 1280, 720, 525.0, "bgra8", "32FC1", "plumb_bob", (0.0, 0.0, 0.0, 0.0, 0.0),
        DepthNoise("stereo", 525.0, 0.120, 0.15, unit=0.0)),
}


def profile(name: str) -> CameraProfile:
    """The profile called ``name``; ``ValueError`` names the known ones."""
    if name not in PROFILES:
        raise ValueError(f"camera.profile must be one of {sorted(PROFILES)}, got {name!r}")
    return PROFILES[name]


@dataclass(frozen=True)
class DriverFrame:
    """One frame as the driver sends it (arrays; the node encodes them).

    Attributes
    ----------
    rgb : (H, W, 3) uint8
        Colour through the lens (distorted), R, G, B.
    depth : (H_d, W_d) float32
        Depth, metres, NaN = none: aligned to the distorted colour image, or in the depth
        camera's own pixels (``depth_k`` not None).
    depth_k : (3, 3) or None
        The own depth stream's K.
    """

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    depth_k: NDArray[np.float64] | None = None


class _Maps:
    """The distortion remap tables of one profile (computed once)."""

    def __init__(self) -> None:
        self._cache: dict[tuple[str, bytes], tuple[NDArray, NDArray]] = {}

    def get(self, prof: CameraProfile, k: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        key = (prof.name, np.asarray(k, np.float64).tobytes())
        if key not in self._cache:
            self._cache[key] = distortion_maps(k, prof.distortion, (prof.width, prof.height))
        return self._cache[key]


_MAPS = _Maps()


def driver_frame(prof: CameraProfile, rgb: NDArray[np.uint8], clean_depth: NDArray[np.float32],
                 k: NDArray[np.float64], rng: np.random.Generator) -> DriverFrame:
    """The frame ``prof``'s driver would send of the ideal rendering (``rgb``,
    ``clean_depth`` aligned to it, intrinsics ``k``), with fresh depth noise from ``rng``.

    Distortion is applied to colour (bilinear) and to aligned depth (nearest); an own depth
    stream is the clean depth re-projected into the depth camera (what it sees of the surfaces
    the colour camera sees), then made noisy.
    """
    if any(prof.distortion):
        map_u, map_v = _MAPS.get(prof, k)
        rgb = cv2.remap(rgb, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    if not prof.depth_aligned:
        dk = prof.depth_matrix()
        own = register_depth(clean_depth, k, dk, np.linalg.inv(prof.t_color_depth()),
                             (prof.width, prof.height))
        noisy = own if prof.noise is None else prof.noise.apply(own, rng)
        return DriverFrame(rgb, noisy, dk)
    depth = clean_depth if prof.noise is None else prof.noise.apply(clean_depth, rng)
    if any(prof.distortion):
        map_u, map_v = _MAPS.get(prof, k)
        depth = cv2.remap(depth, map_u, map_v, cv2.INTER_NEAREST,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
    return DriverFrame(rgb, depth)
