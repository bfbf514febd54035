"""Simulated RGB-D camera modelled on the Intel RealSense D415 colour stream.

Pure numpy helpers used by :mod:`sim_bridge.world`; no pybullet state lives here.

Frames and conventions
----------------------
- ``world``: table frame, z up, origin on the table at the workspace centre
  (docs/ARCHITECTURE.md#units-frames-conventions).
- ``camera_color_optical_frame``: REP 103 optical frame, z forward along the optical axis,
  x right in the image, y down in the image. ``T_world_camera`` (4, 4) maps points from this
  frame to ``world``: ``p_world = T[:3, :3] @ p_cam + T[:3, 3]``.
- Pixels follow the OpenCV convention: ``u`` right (column), ``v`` down (row), integer
  coordinates at pixel centres, ``u = fx x / z + cx``, ``v = fy y / z + cy``.
- Depth is the z coordinate in the optical frame (metres), not the ray length.

Default viewpoint: the camera stands on the far side of the table, facing the robot (+x side,
looking toward -x), 0.8 m from a point 3 cm in front of the workspace centre, its optical axis
55 degrees below the horizontal. At the D415's 615 px focal length (69 x 42 degree field of
view at 640 x 480) this is the closest oblique viewpoint that keeps the whole default
workspace (x in [-0.25, 0.25] m, y in [-0.3, 0.3] m) in the image with a margin of more than
25 px on every side; a pixel covers about 1.3 mm on the table at the workspace centre.

Depth noise (optional, RealSense-like; Ahn et al. 2019 and the Intel D400 datasheet): the
stereo depth error grows with the square of the depth,
``sigma_z = z^2 * sigma_d / (f * B)`` with subpixel disparity noise ``sigma_d = 0.08 px``,
the depth imager focal length ``f = 615 px`` and baseline ``B = 55 mm`` (0.85 mm at 0.6 m,
1.5 mm at 0.8 m); depth is then quantised to the driver's 1 mm depth unit; 0.5 % of the
pixels are dropped at random and pixels on a depth discontinuity larger than 5 mm are
dropped with probability 0.5 (the stereo "shadow" at object edges). Dropped pixels are NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "D415_BASELINE",
    "D415_FOCAL_PX",
    "CameraConfig",
    "add_depth_noise",
    "deproject",
    "depth_edges",
    "depth_from_zbuffer",
    "intrinsics",
    "jittered",
    "look_at_pose",
    "opengl_projection",
    "opengl_view",
    "project",
]

#: Focal length of the D415 colour stream at 640 x 480, pixels.
D415_FOCAL_PX = 615.0
#: Stereo baseline of the D415, metres.
D415_BASELINE = 0.055
#: Subpixel disparity noise of the D415 stereo matcher, pixels (RMS).
D415_SUBPIXEL = 0.08
#: Depth unit of the RealSense driver's z16 stream, metres.
DEPTH_UNIT = 0.001


@dataclass(frozen=True)
class CameraConfig:
    """Intrinsics and viewpoint of the simulated colour camera (depth is aligned to it).

    Attributes
    ----------
    width, height : int
        Image size in pixels (default 640 x 480, the D415 colour stream).
    fx, fy : float or None
        Focal lengths in pixels; ``None`` scales the D415's 615 px with the image size
        (``615 * width / 640`` and ``615 * height / 480``).
    cx, cy : float or None
        Principal point in pixels; ``None`` puts it at the image centre
        (``(width - 1) / 2``, ``(height - 1) / 2``).
    look_at : (3,) tuple of float
        World point (metres) on the optical axis.
    distance : float
        Distance of the optical centre from ``look_at``, metres.
    elevation_deg : float
        Angle of the optical axis below the horizontal, degrees (90 looks straight down).
    azimuth_deg : float
        Direction from ``look_at`` to the camera, degrees counter-clockwise from world +x
        (0: the camera is on the far side of the table, facing the robot).
    near, far : float
        Clipping planes of the renderer, metres; nothing outside is rendered.
    jitter_position : float
        Standard deviation per axis of the camera position jitter, metres; applied only when
        ``WorldConfig.randomize_camera`` is set.
    jitter_angle_deg : float
        Standard deviation per axis of the camera orientation jitter, degrees (same switch).
    """

    width: int = 640
    height: int = 480
    fx: float | None = None
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None
    look_at: tuple[float, float, float] = (0.03, 0.0, 0.0)
    distance: float = 0.8
    elevation_deg: float = 55.0
    azimuth_deg: float = 0.0
    near: float = 0.05
    far: float = 4.0
    jitter_position: float = 0.005
    jitter_angle_deg: float = 1.0

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or not 8 <= value <= 4096:
                raise ValueError(f"camera.{name}: expected an integer in [8, 4096], got {value!r}")
            object.__setattr__(self, name, int(value))
        for name in ("fx", "fy"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ValueError(f"camera.{name}: must be > 0 pixels or None, got {value!r}")
        for name in ("cx", "cy"):
            value = getattr(self, name)
            if value is not None and not np.isfinite(value):
                raise ValueError(f"camera.{name}: must be finite or None, got {value!r}")
        look = np.asarray(self.look_at, dtype=float)
        if look.shape != (3,) or not np.all(np.isfinite(look)):
            raise ValueError(f"camera.look_at: expected three finite numbers, got {self.look_at!r}")
        object.__setattr__(self, "look_at", tuple(float(v) for v in look))
        if not (np.isfinite(self.distance) and self.distance > 0):
            raise ValueError(f"camera.distance: must be > 0 m, got {self.distance!r}")
        if not (np.isfinite(self.elevation_deg) and 0 < self.elevation_deg <= 90):
            raise ValueError(
                f"camera.elevation_deg: must be in (0, 90] degrees, got {self.elevation_deg!r}"
            )
        if not np.isfinite(self.azimuth_deg):
            raise ValueError(f"camera.azimuth_deg: must be finite, got {self.azimuth_deg!r}")
        if not (0 < self.near < self.far and np.isfinite(self.far)):
            raise ValueError(
                f"camera.near/far: need 0 < near < far < inf, got near={self.near!r}, "
                f"far={self.far!r}"
            )
        for name in ("jitter_position", "jitter_angle_deg"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"camera.{name}: must be >= 0, got {value!r}")


def intrinsics(cfg: CameraConfig) -> NDArray[np.float64]:
    """Camera matrix K (3, 3) in pixels for ``cfg`` (see :class:`CameraConfig` defaults)."""
    fx = D415_FOCAL_PX * cfg.width / 640.0 if cfg.fx is None else float(cfg.fx)
    fy = D415_FOCAL_PX * cfg.height / 480.0 if cfg.fy is None else float(cfg.fy)
    cx = (cfg.width - 1) / 2.0 if cfg.cx is None else float(cfg.cx)
    cy = (cfg.height - 1) / 2.0 if cfg.cy is None else float(cfg.cy)
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def look_at_pose(cfg: CameraConfig) -> NDArray[np.float64]:
    """``T_world_camera`` (4, 4) of the optical frame for the viewpoint in ``cfg``.

    The optical z axis points from the camera to ``look_at``; the image x axis is horizontal
    (no roll), so the image y axis points down the slope of the view.
    """
    el, az = np.radians(cfg.elevation_deg), np.radians(cfg.azimuth_deg)
    back = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    position = np.asarray(cfg.look_at) + cfg.distance * back
    z = -back
    # Image x = optical z x world up (horizontal, to the right); at 90 degrees (straight
    # down) that is undefined, so fall back to the azimuth direction.
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-9:
        x = np.array([np.sin(az), -np.cos(az), 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    t = np.eye(4)
    t[:3, :3] = np.stack([x, y, z], axis=1)
    t[:3, 3] = position
    return t


def jittered(t_world_camera: NDArray[np.float64], cfg: CameraConfig,
             rng: np.random.Generator) -> NDArray[np.float64]:
    """``t_world_camera`` moved by a random translation and small rotation (``cfg.jitter_*``).

    The rotation is ``exp([w]x)`` with ``w ~ N(0, jitter_angle^2 I)`` applied in the optical
    frame; the translation ``N(0, jitter_position^2 I)`` in world.
    """
    w = np.radians(cfg.jitter_angle_deg) * rng.standard_normal(3)
    dp = cfg.jitter_position * rng.standard_normal(3)
    angle = float(np.linalg.norm(w))
    k = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if angle > 1e-12:
        k /= angle
        rot = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)
    else:
        rot = np.eye(3)
    out = t_world_camera.copy()
    out[:3, :3] = t_world_camera[:3, :3] @ rot
    out[:3, 3] += dp
    return out


def opengl_view(t_world_camera: NDArray[np.float64]) -> list[float]:
    """pybullet view matrix (16 floats, column-major) for an optical-frame pose.

    OpenGL's eye frame has y up and looks along -z: ``T_world_eye = T_world_optical @
    diag(1, -1, -1, 1)``; the view matrix is its inverse.
    """
    t_world_eye = t_world_camera @ np.diag([1.0, -1.0, -1.0, 1.0])
    view = np.linalg.inv(t_world_eye)
    return view.T.reshape(-1).tolist()


def opengl_projection(k: NDArray[np.float64], width: int, height: int, near: float,
                      far: float) -> list[float]:
    """pybullet projection matrix (16 floats, column-major) that reproduces the pinhole K.

    A point at optical-frame ``(x, y, z)`` lands at the OpenCV pixel
    ``(fx x / z + cx, fy y / z + cy)`` (integer coordinates at pixel centres). pybullet's
    TinyRenderer samples image pixel ``(u, v)`` (row ``v`` from the top) at the integer window
    coordinates ``(u, height - 1 - v)``, without OpenGL's half-pixel offset; this was
    measured by rendering a known scene (``tests/sim/test_world.py`` checks it to 2 mm).
    Depth is mapped to the z-buffer in [0, 1] as in OpenGL with the given clip planes.
    """
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    p = np.zeros((4, 4))
    p[0, 0] = 2.0 * fx / width
    p[0, 2] = 1.0 - 2.0 * cx / width
    p[1, 1] = 2.0 * fy / height
    p[1, 2] = 2.0 * (cy + 1.0) / height - 1.0
    p[2, 2] = -(far + near) / (far - near)
    p[2, 3] = -2.0 * far * near / (far - near)
    p[3, 2] = -1.0
    return p.T.reshape(-1).tolist()


def depth_from_zbuffer(zbuffer: ArrayLike, near: float, far: float) -> NDArray[np.float32]:
    """Metric z-depth (float32, metres) from an OpenGL z-buffer in [0, 1].

    ``z = far near / (far - (far - near) zbuffer)``; the far plane (``zbuffer >= 1``, no
    geometry) becomes NaN.
    """
    zb = np.asarray(zbuffer, dtype=np.float64)
    depth = far * near / (far - (far - near) * zb)
    depth[zb >= 1.0] = np.nan
    return depth.astype(np.float32)


def depth_edges(z: NDArray[np.floating], step: float = 0.005) -> NDArray[np.bool_]:
    """Pixels on a depth discontinuity (H, W) bool: a right or lower neighbour (or the pixel
    it is the neighbour of) differs by more than ``step`` m (NaN never counts)."""
    edge = np.zeros(z.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        jump_u = np.abs(np.diff(z, axis=1)) > step
        jump_v = np.abs(np.diff(z, axis=0)) > step
    edge[:, :-1] |= jump_u
    edge[:, 1:] |= jump_u
    edge[:-1, :] |= jump_v
    edge[1:, :] |= jump_v
    return edge


def add_depth_noise(depth: NDArray[np.float32], rng: np.random.Generator,
                    focal_px: float = D415_FOCAL_PX) -> NDArray[np.float32]:
    """RealSense-like depth noise (see the module docstring); returns a new float32 array.

    Parameters
    ----------
    depth : (H, W) float32
        Noise-free z-depth in metres, NaN where there is no return.
    rng : numpy.random.Generator
        Source of the noise (the world's seeded noise stream).
    focal_px : float
        Focal length of the depth imager in pixels.
    """
    z = depth.astype(np.float64)
    sigma = z**2 * D415_SUBPIXEL / (focal_px * D415_BASELINE)
    noisy = z + sigma * rng.standard_normal(z.shape)
    noisy = np.round(noisy / DEPTH_UNIT) * DEPTH_UNIT
    drop = rng.random(z.shape) < 0.005
    drop |= depth_edges(z) & (rng.random(z.shape) < 0.5)
    noisy[drop] = np.nan
    return noisy.astype(np.float32)


def deproject(depth: ArrayLike, k: ArrayLike, t_world_camera: ArrayLike,
              pixels: ArrayLike | None = None) -> NDArray[np.float64]:
    """World points of depth pixels.

    Parameters
    ----------
    depth : (H, W) array
        z-depth in metres (NaN stays NaN).
    k : (3, 3) array
        Camera matrix.
    t_world_camera : (4, 4) array
        world <- optical frame.
    pixels : (N, 2) int array of (v, u) = (row, column), optional
        Pixels to deproject; default all, returning (H, W, 3).

    Returns
    -------
    (N, 3) or (H, W, 3) float64 array of world points, metres.
    """
    depth = np.asarray(depth, dtype=np.float64)
    k = np.asarray(k, dtype=np.float64)
    t = np.asarray(t_world_camera, dtype=np.float64)
    if pixels is None:
        v, u = np.indices(depth.shape)
        z = depth
    else:
        px = np.asarray(pixels)
        v, u = px[:, 0], px[:, 1]
        z = depth[v, u]
    x = (u - k[0, 2]) / k[0, 0] * z
    y = (v - k[1, 2]) / k[1, 1] * z
    cam = np.stack([x, y, z], axis=-1)
    return cam @ t[:3, :3].T + t[:3, 3]


def project(points: ArrayLike, k: ArrayLike, t_world_camera: ArrayLike) -> NDArray[np.float64]:
    """OpenCV pixel coordinates (..., 2) = (u, v) of world points (..., 3); also returns
    nothing about visibility (points behind the camera give meaningless pixels)."""
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(t_world_camera, dtype=np.float64)
    k = np.asarray(k, dtype=np.float64)
    cam = (p - t[:3, 3]) @ t[:3, :3]
    return np.stack([k[0, 0] * cam[..., 0] / cam[..., 2] + k[0, 2],
                     k[1, 1] * cam[..., 1] / cam[..., 2] + k[1, 2]], axis=-1)
