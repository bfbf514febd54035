"""A driver's RGB-D frame -> the ideal, aligned pinhole frame the perception measures with.

ROS-free (numpy, OpenCV): the node decodes the messages with :mod:`push_ros.images` and hands
the arrays and camera models here. Rules (docs/design/cameras.md):

- **Distortion.** A colour image with non-zero distortion is remapped onto the ideal pinhole
  image with the same K (bilinear); depth aligned to colour lives in the colour camera's
  distorted pixels, so it is remapped with the colour model (nearest: depth is never blended
  across an edge). Pixels that fall outside the source become black colour and NaN depth.
  Zero distortion costs nothing.
- **Registration.** Depth with its own camera_info (a depth camera beside the colour one) is
  undistorted with its own model, then re-projected into the colour camera
  (:func:`push_core.camera_model.register_depth`) with the depth-to-colour pose.
- The remap tables are cached per (K, d, size): each frame costs one remap per image.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from push_core.camera_model import register_depth, undistortion_maps

__all__ = ["CameraModel", "FrameRectifier"]


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics of one stream as its camera_info gives them.

    Attributes
    ----------
    k : (3, 3) float
        Camera matrix, px.
    d : (5,) or (8,) float
        Distortion coefficients, OpenCV's order (zero: an ideal pinhole).
    size : (width, height)
        Image size, px.
    """

    k: NDArray[np.float64]
    d: NDArray[np.float64]
    size: tuple[int, int]

    @property
    def ideal(self) -> bool:
        """No distortion: the image is already the pinhole image of ``k``."""
        return not np.any(self.d)

    def key(self) -> tuple[bytes, bytes, tuple[int, int]]:
        """Identity of the model for the remap cache."""
        return (np.asarray(self.k, np.float64).tobytes(), np.asarray(self.d, np.float64).tobytes(),
                tuple(self.size))


class FrameRectifier:
    """Undistorts and registers frames (module docstring); not thread-safe (caches maps).

    Parameters
    ----------
    t_color_depth : (4, 4) array, optional
        Pose of the depth optical frame in the colour optical frame, m (for depth with its own
        camera_info; identity by default).
    """

    def __init__(self, t_color_depth: NDArray[np.float64] | None = None) -> None:
        self.t_color_depth = np.eye(4) if t_color_depth is None else np.asarray(
            t_color_depth, dtype=np.float64)
        self._maps: dict[tuple[bytes, bytes, tuple[int, int]], tuple[NDArray, NDArray]] = {}

    def _remap(self, image: NDArray, model: CameraModel, nearest: bool) -> NDArray:
        key = model.key()
        maps = self._maps.get(key)
        if maps is None:
            if len(self._maps) >= 4:  # a camera has two streams; a model change drops the rest
                self._maps.clear()
            maps = self._maps[key] = undistortion_maps(model.k, model.d, model.size)
        if nearest:
            return cv2.remap(image, maps[0], maps[1], cv2.INTER_NEAREST,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
        return cv2.remap(image, maps[0], maps[1], cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    def color(self, rgb: NDArray[np.uint8], model: CameraModel) -> NDArray[np.uint8]:
        """The ideal pinhole colour image (H, W, 3) of ``rgb`` taken through ``model``."""
        return rgb if model.ideal else self._remap(rgb, model, nearest=False)

    def depth(self, depth: NDArray[np.float32], color: CameraModel,
              own: CameraModel | None = None) -> NDArray[np.float32]:
        """Depth (metres, NaN = none) in the colour camera's ideal pixels.

        Parameters
        ----------
        depth : (H, W) float32
            Depth as published: aligned to the (distorted) colour image when ``own`` is None,
            else in the depth camera's own pixels.
        color : CameraModel
            The colour stream's model.
        own : CameraModel, optional
            The depth stream's model (depth with its own camera_info): undistorted with it and
            registered into the colour camera.
        """
        depth = np.asarray(depth, dtype=np.float32)
        if own is None:
            return depth if color.ideal else self._remap(depth, color, nearest=True)
        ideal = depth if own.ideal else self._remap(depth, own, nearest=True)
        return register_depth(ideal, own.k, color.k, self.t_color_depth, color.size)
