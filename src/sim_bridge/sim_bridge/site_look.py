"""The *site look*: an appearance the segmentation network was never trained on.

ROS-free. ``WorldConfig.look = "site"`` (``sim_bridge_node`` parameter ``appearance.look``)
draws it from the world's appearance stream instead of
:func:`sim_bridge.rendering.random_appearance`,
to measure the network on a look it has not seen and to adapt it to one
(docs/design/site-adaptation.md). Differences from the training appearance:

- **Textured table**: a procedural texture over the whole 1.5 m table (1024 x 1024 texels, about
  1.5 mm each), one of ``wood`` (growth rings warped by low-frequency noise, fine grain),
  ``checker`` (two colours, squares 1.5-5 cm) or ``noise`` (multi-octave value noise between
  two colours). The training frames only had uniformly coloured tables.
- **Metallic object**: greys, golds and coppers of low saturation with a strong specular
  highlight (``Appearance.object_specular`` 0.8-1.0 against 0.4).
- **Coloured light**: one channel at 1, the other two in [0.45, 0.8] (training: every channel
  in [0.8, 1]).
- **Strong shadows**: shadows always on, the light 20-45 deg above the table (long shadows),
  ambient 0.15-0.3 and diffuse 0.6-0.9.

Colour noise (sigma 2 grey levels) is that of the training look. The texture is drawn from its
own seed (:attr:`Appearance.texture_seed`), so a scene is reproduced exactly by its world seed.
"""

from __future__ import annotations

import colorsys
import os
import tempfile

import cv2
import numpy as np
from numpy.typing import NDArray
from pybullet_utils.bullet_client import BulletClient

from sim_bridge.rendering import Appearance

__all__ = ["LOOKS", "TEXTURE_KINDS", "TEXTURE_SIZE", "load_texture", "site_appearance",
           "table_texture"]

#: The values of ``WorldConfig.look``.
LOOKS = ("default", "site")
#: Procedural table textures of the site look.
TEXTURE_KINDS = ("wood", "checker", "noise")
#: Texels per side of a table texture (it spans the whole 1.5 m table face).
TEXTURE_SIZE = 1024
#: Side of the table face the texture spans, m (``sim_bridge.scene.TABLE_SIDE``).
_TABLE_SIDE = 1.5


def site_appearance(rng: np.random.Generator) -> Appearance:
    """Draw one site look (ranges in the module docstring) from ``rng``."""
    kind = TEXTURE_KINDS[int(rng.integers(len(TEXTURE_KINDS)))]
    metal = colorsys.hsv_to_rgb(rng.uniform(0.05, 0.15) if rng.random() < 0.5 else 0.0,
                                rng.uniform(0.0, 0.45), rng.uniform(0.45, 0.9))
    light = rng.uniform(0.45, 0.8, 3)
    light[int(rng.integers(3))] = 1.0
    az, el = rng.uniform(0.0, 2 * np.pi), np.radians(rng.uniform(20.0, 45.0))
    direction = (np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el))
    return Appearance(
        table_rgb=(1.0, 1.0, 1.0), object_rgb=tuple(float(v) for v in metal),
        light_direction=tuple(float(v) for v in direction),
        light_color=tuple(float(v) for v in light),
        ambient=float(rng.uniform(0.15, 0.3)), diffuse=float(rng.uniform(0.6, 0.9)),
        specular=float(rng.uniform(0.6, 1.0)), shadow=True, rgb_noise=2.0,
        table_texture=kind, texture_seed=int(rng.integers(2**31 - 1)),
        object_specular=float(rng.uniform(0.8, 1.0)),
        object_textured=bool(rng.random() < 0.5),
        texture_shift=(float(rng.uniform(0.0, 0.5)), float(rng.uniform(0.0, 0.5))))


def _value_noise(rng: np.random.Generator, size: int, cells: int) -> NDArray[np.float32]:
    """Smooth noise (size, size) in [0, 1]: a ``cells`` x ``cells`` random grid, bicubic."""
    grid = rng.random((cells + 1, cells + 1)).astype(np.float32)
    return np.clip(cv2.resize(grid, (size, size), interpolation=cv2.INTER_CUBIC), 0.0, 1.0)


def _colour(rng: np.random.Generator, hue: tuple[float, float], sat: tuple[float, float],
            val: tuple[float, float]) -> NDArray[np.float32]:
    return np.array(colorsys.hsv_to_rgb(rng.uniform(*hue), rng.uniform(*sat), rng.uniform(*val)),
                    dtype=np.float32)


def table_texture(kind: str, seed: int, size: int = TEXTURE_SIZE) -> NDArray[np.uint8]:
    """The procedural table texture ``kind`` of seed ``seed``: (size, size, 3) uint8 RGB.

    Raises
    ------
    ValueError
        ``kind`` not one of :data:`TEXTURE_KINDS`.
    """
    if kind not in TEXTURE_KINDS:
        raise ValueError(f"table texture must be one of {TEXTURE_KINDS}, got {kind!r}")
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32) / size  # texture coordinates
    if kind == "wood":
        dark = _colour(rng, (0.05, 0.1), (0.5, 0.8), (0.25, 0.45))
        light = _colour(rng, (0.07, 0.12), (0.35, 0.6), (0.6, 0.9))
        warp = _value_noise(rng, size, 6) - 0.5
        rings = rng.uniform(25.0, 60.0)  # rings across the table
        phase = rings * (xx + 0.08 * warp + 0.02 * np.sin(2 * np.pi * 3 * yy))
        t = 0.5 + 0.5 * np.sin(2 * np.pi * phase)
        grain = _value_noise(rng, size, size // 4)
        t = np.clip(0.75 * t ** 2 + 0.25 * grain, 0.0, 1.0)
    elif kind == "checker":
        dark = _colour(rng, (0.0, 1.0), (0.0, 0.8), (0.1, 0.5))
        light = _colour(rng, (0.0, 1.0), (0.0, 0.6), (0.6, 1.0))
        squares = _TABLE_SIDE / rng.uniform(0.015, 0.05)
        t = ((np.floor(xx * squares) + np.floor(yy * squares)) % 2).astype(np.float32)
    else:
        dark = _colour(rng, (0.0, 1.0), (0.1, 0.7), (0.15, 0.5))
        light = _colour(rng, (0.0, 1.0), (0.1, 0.7), (0.55, 0.95))
        t = sum(w * _value_noise(rng, size, c) for w, c in ((0.5, 12), (0.3, 48), (0.2, 192)))
    image = dark[None, None] * (1.0 - t[..., None]) + light[None, None] * t[..., None]
    return np.clip(np.round(255.0 * image), 0, 255).astype(np.uint8)


def load_texture(client: BulletClient, look: Appearance) -> int:
    """Load ``look``'s table texture into ``client``; returns the pybullet texture id.

    Raises
    ------
    ValueError
        ``look`` has no table texture.
    """
    image = table_texture(look.table_texture, look.texture_seed)
    fd, path = tempfile.mkstemp(prefix="pushbot_texture_", suffix=".png")
    os.close(fd)
    try:
        cv2.imwrite(path, image[:, :, ::-1])
        return int(client.loadTexture(path))
    finally:
        os.unlink(path)
