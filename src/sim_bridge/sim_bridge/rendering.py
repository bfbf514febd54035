"""Rendering of the pybullet world: appearance, camera view and RGB-D frames.

ROS-free; :class:`sim_bridge.world.PushWorld` is the entry point (this module holds its camera
half). Images are in ``camera_color_optical_frame`` (REP 103: z forward, x right, y down; see
:mod:`sim_bridge.camera`); depth is z-depth along the optical axis in metres.

Appearance (``WorldConfig.randomize_appearance``, drawn by :func:`random_appearance`): table
and object colour (HSV; the object's brightness differs from the table's by at least 0.1),
light direction (azimuth uniform, elevation 30-90 deg), light colour (each channel in
[0.8, 1]), ambient/diffuse/specular coefficients, shadows on or off, and Gaussian colour noise
(sigma 2 grey levels) per frame. ``depth_noise``: RealSense-like depth noise and dropouts
(:func:`sim_bridge.camera.add_depth_noise`), fresh per frame. Speed per frame:
docs/results/bench_sim.md.

Monitor (:class:`MonitorConfig`): a visualisation stream rendered *during* a push (the pusher
in view) from the same camera pose, usually smaller (:func:`monitor_view` scales the
intrinsics), without depth noise or colour noise: it never draws from the world's
sensor-noise stream, so the camera frames and the physics are exactly those without it.
"""

from __future__ import annotations

import colorsys
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from pybullet_utils.bullet_client import BulletClient

from sim_bridge.camera import (
    CameraConfig,
    add_depth_noise,
    depth_from_zbuffer,
    intrinsics,
    opengl_projection,
    opengl_view,
)

__all__ = ["Appearance", "CameraView", "Frame", "MonitorConfig", "camera_view", "monitor_view",
           "random_appearance", "render", "sensor_noise", "still_frame"]

DEFAULT_TABLE_RGB = (0.78, 0.74, 0.66)
DEFAULT_OBJECT_RGB = (0.50, 0.52, 0.56)


@dataclass(frozen=True)
class Frame:
    """One RGB-D camera frame; all images in ``camera_color_optical_frame``.

    Attributes
    ----------
    rgb : (H, W, 3) uint8
    depth : (H, W) float32
        z-depth along the optical axis in metres; NaN where there is no return.
    mask : (H, W) bool
        Pixels that show the object.
    stamp : float
        ``sim_time`` of the frame, s.
    camera_matrix : (3, 3) ndarray
        K (addition).
    T_world_camera : (4, 4) ndarray
        world <- optical frame at the time of the frame (addition).
    object_pose : (3,) ndarray
        Ground-truth object pose at the time of the frame (addition).
    clean_rgb, clean_depth : ndarray or None
        The images before sensor noise (None where the frame was not rendered by
        :func:`render`): :func:`still_frame` draws fresh noise on them.
    """

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    mask: NDArray[np.bool_]
    stamp: float
    camera_matrix: NDArray[np.float64] = field(default_factory=lambda: np.eye(3))
    T_world_camera: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))  # noqa: N815
    object_pose: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    clean_rgb: NDArray[np.uint8] | None = None
    clean_depth: NDArray[np.float32] | None = None


@dataclass(frozen=True)
class Appearance:
    """Colours (RGB in [0, 1]) and lighting of a scene."""

    table_rgb: tuple[float, float, float] = DEFAULT_TABLE_RGB
    object_rgb: tuple[float, float, float] = DEFAULT_OBJECT_RGB
    light_direction: tuple[float, float, float] = (0.5, 0.3, 1.0)
    light_color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    ambient: float = 0.5
    diffuse: float = 0.55
    specular: float = 0.1
    shadow: bool = False
    rgb_noise: float = 0.0  # grey levels (sigma)
    table_texture: str = ""  # "" (plain table_rgb) or a kind of sim_bridge.site_look
    texture_seed: int = 0  # seed of the procedural table texture
    object_specular: float = 0.4  # the object material's specular colour (grey level)
    object_textured: bool = False  # the object wears the table's texture (camouflage)
    texture_shift: tuple[float, float] = (0.0, 0.0)  # of the object's texture coordinates


@dataclass(frozen=True)
class CameraView:
    """The camera of a scene: K (3, 3) in pixels, ``world <- optical`` (4, 4), and the OpenGL
    view and projection matrices pybullet renders with."""

    camera_matrix: NDArray[np.float64]
    T_world_camera: NDArray[np.float64]  # noqa: N815 - the contract's name
    view: list[float]
    projection: list[float]


def camera_view(camera: CameraConfig, t_world_camera: NDArray[np.float64]) -> CameraView:
    """The :class:`CameraView` of ``camera`` placed at ``t_world_camera``."""
    k = intrinsics(camera)
    return CameraView(camera_matrix=k, T_world_camera=t_world_camera,
                      view=opengl_view(t_world_camera),
                      projection=opengl_projection(k, camera.width, camera.height,
                                                   camera.near, camera.far))


@dataclass(frozen=True)
class MonitorConfig:
    """The monitor stream of :meth:`sim_bridge.world.PushWorld.execute_push` (module docstring).

    Attributes
    ----------
    rate : float
        Frames per second of *simulated* time, in (0, 240]; the period is rounded to a whole
        number of physics steps, ``max(1, round(1 / (rate * time_step)))`` (10 Hz at the
        default 1/240 s step: every 24 steps, exactly 10 Hz).
    width, height : int
        Image size, pixels, in [8, 4096] (default 320 x 240: TinyRenderer time grows with the
        pixel count).
    """

    rate: float = 10.0
    width: int = 320
    height: int = 240

    def __post_init__(self) -> None:
        if isinstance(self.rate, bool) or not (np.isfinite(self.rate) and 0 < self.rate <= 240):
            raise ValueError(f"monitor.rate: must be in (0, 240] Hz of sim time, got "
                             f"{self.rate!r}")
        object.__setattr__(self, "rate", float(self.rate))
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or not 8 <= value <= 4096:
                raise ValueError(f"monitor.{name}: expected an integer in [8, 4096], got "
                                 f"{value!r}")
            object.__setattr__(self, name, int(value))

    def every(self, time_step: float) -> int:
        """Physics steps between two monitor frames (>= 1)."""
        return max(1, round(1.0 / (self.rate * time_step)))


def monitor_view(camera: CameraConfig, view: CameraView, monitor: MonitorConfig
                 ) -> tuple[CameraConfig, CameraView]:
    """The camera of ``view`` (same pose) at the monitor's image size.

    Intrinsics scale with the size per axis, pixel centres kept (OpenCV convention):
    ``f' = s f``, ``c' = s (c + 1/2) - 1/2`` with ``s = width' / width`` (``height`` for y).
    """
    k = view.camera_matrix
    sx, sy = monitor.width / camera.width, monitor.height / camera.height
    small = replace(camera, width=monitor.width, height=monitor.height, fx=sx * k[0, 0],
                    fy=sy * k[1, 1], cx=sx * (k[0, 2] + 0.5) - 0.5, cy=sy * (k[1, 2] + 0.5) - 0.5)
    return small, camera_view(small, view.T_world_camera)


def random_appearance(rng: np.random.Generator) -> Appearance:
    """Random colours, lighting and colour noise (ranges in the module docstring)."""
    table = colorsys.hsv_to_rgb(rng.random(), rng.uniform(0.0, 0.5), rng.uniform(0.3, 0.95))
    while True:
        obj = colorsys.hsv_to_rgb(rng.random(), rng.uniform(0.0, 0.6), rng.uniform(0.2, 0.9))
        if abs(max(obj) - max(table)) >= 0.1:
            break
    az, el = rng.uniform(0.0, 2 * np.pi), np.radians(rng.uniform(30.0, 90.0))
    direction = (np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el))
    return Appearance(
        table_rgb=tuple(float(v) for v in table), object_rgb=tuple(float(v) for v in obj),
        light_direction=tuple(float(v) for v in direction),
        light_color=tuple(float(v) for v in rng.uniform(0.8, 1.0, 3)),
        ambient=float(rng.uniform(0.3, 0.7)), diffuse=float(rng.uniform(0.3, 0.7)),
        specular=float(rng.uniform(0.0, 0.5)), shadow=bool(rng.random() < 0.5),
        rgb_noise=2.0)


def render(client: BulletClient, camera: CameraConfig, view: CameraView, look: Appearance,
           object_id: int, depth_noise: bool, rng_noise: np.random.Generator, stamp: float,
           object_pose: Callable[[], NDArray[np.float64]]) -> Frame:
    """Render one RGB-D frame with pybullet's TinyRenderer (CPU).

    Parameters
    ----------
    client : BulletClient
    camera : CameraConfig
        Image size and clipping planes.
    view : CameraView
    look : Appearance
    object_id : int
        pybullet body of the object (its pixels form the mask).
    depth_noise : bool
        Add RealSense-like depth noise and dropouts.
    rng_noise : numpy.random.Generator
        The world's sensor-noise stream (depth noise first, then colour noise).
    stamp : float
        ``sim_time`` of the frame, s.
    object_pose : callable
        Returns the ground-truth ``(x, y, theta)`` stored with the frame.

    Returns
    -------
    Frame
        rgb (H, W, 3) uint8; depth (H, W) float32 z-depth in metres with NaN where no
        surface is hit (and where ``depth_noise`` drops pixels); mask (H, W) bool of the
        object's pixels.
    """
    w, h = camera.width, camera.height
    _, _, rgba, zbuf, seg = client.getCameraImage(
        w, h, viewMatrix=view.view, projectionMatrix=view.projection,
        renderer=p.ER_TINY_RENDERER, lightDirection=list(look.light_direction),
        lightColor=list(look.light_color), lightDistance=2.0, shadow=int(look.shadow),
        lightAmbientCoeff=look.ambient, lightDiffuseCoeff=look.diffuse,
        lightSpecularCoeff=look.specular)
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3]
    seg = np.asarray(seg).reshape(h, w)
    depth = depth_from_zbuffer(np.asarray(zbuf).reshape(h, w), camera.near, camera.far)
    depth[seg < 0] = np.nan
    clean_rgb = np.ascontiguousarray(rgb)
    noisy_rgb, noisy_depth = sensor_noise(clean_rgb, depth, depth_noise, look.rgb_noise, rng_noise)
    return Frame(rgb=noisy_rgb, depth=noisy_depth, mask=seg == object_id, stamp=stamp,
                 camera_matrix=view.camera_matrix.copy(),
                 T_world_camera=view.T_world_camera.copy(), object_pose=object_pose(),
                 clean_rgb=clean_rgb, clean_depth=depth)


def sensor_noise(rgb: NDArray[np.uint8], depth: NDArray[np.float32], depth_noise: bool,
                 rgb_noise: float, rng: np.random.Generator
                 ) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
    """The camera's per-frame noise on clean images (new arrays; the inputs are unchanged).

    Parameters
    ----------
    rgb : (H, W, 3) uint8
    depth : (H, W) float32
        z-depth, m (NaN: no return).
    depth_noise : bool
        RealSense-like depth noise and dropouts (:func:`sim_bridge.camera.add_depth_noise`).
    rgb_noise : float
        Sigma of the Gaussian colour noise, grey levels (0: none).
    rng : numpy.random.Generator
        Drawn from in this order: depth noise, then colour noise.

    Returns
    -------
    rgb, depth : ndarray
    """
    depth = add_depth_noise(depth, rng) if depth_noise else depth.copy()
    if rgb_noise > 0:
        noisy = rgb + rgb_noise * rng.standard_normal(rgb.shape)
        rgb = np.clip(np.round(noisy), 0, 255).astype(np.uint8)
    else:
        rgb = rgb.copy()
    return rgb, depth


def still_frame(frame: Frame, depth_noise: bool, rgb_noise: float,
                rng: np.random.Generator) -> Frame:
    """Another frame of an unchanged scene: ``frame``'s clean images with fresh sensor noise
    (what a camera streaming at a resting scene delivers), same ``stamp`` field.

    Raises
    ------
    ValueError
        ``frame`` has no clean images (it was not made by :func:`render`).
    """
    if frame.clean_rgb is None or frame.clean_depth is None:
        raise ValueError("still_frame needs a frame with its clean images (made by render)")
    rgb, depth = sensor_noise(frame.clean_rgb, frame.clean_depth, depth_noise, rgb_noise, rng)
    return replace(frame, rgb=rgb, depth=depth)
