"""The segmentation CNN: a coarse-to-fine encoder-decoder on RGB + height above the table.

ROS-free (numpy, OpenCV, torch). :class:`Segmenter` is what the node and the evaluation call:
``Segmenter.load()(rgb, depth, K, T_world_camera) -> Segmentation``.

Input
-----
Four channels per pixel: the colour image (``rgb / 255 - 0.5``) and the *height above the
table* of the surface seen at that pixel (depth deprojected with K and the extrinsics, world
z, divided by ``HEIGHT_SCALE`` = 2 cm and clipped to [-1, 4]; NaN depth reads as table
level). Height instead of raw depth makes the input independent of the camera's viewpoint
(the object is a 5-25 mm thick plate on z = 0, the pusher a 60 mm cylinder) and costs one
multiply-add per pixel (:class:`HeightMap` caches the per-pixel ray factor).

Two stages
----------
1. :class:`CoarseNet` sees the whole frame downscaled by ``s = round(W / 160)`` (640 x 480 ->
   160 x 120, ``cv2.INTER_AREA``) and predicts object logits at 1/2 of that (80 x 60): a
   stride-2 stem, two more stride-2 levels (16, 32, 64 channels) and an additive (FPN-style)
   decoder. Its largest connected component above 0.5 locates the object.
2. :class:`FineNet` runs at full resolution on a crop around that component (bounding box +
   ``CROP_MARGIN`` px). Its input is the crop's four channels plus the coarse logits
   bilinearly resampled to full resolution (``grid_sample``, align_corners=False: pixel
   centres map to the same normalised image coordinates in both stages); it predicts a
   correction added to those logits (8, 16, 32 channels, two stride-2 levels). The full-res
   stage is what puts the mask boundary within a fraction of a pixel (IoU >= 0.95 needs a
   mean boundary error below ~0.5 px on a 4000-pixel object).

The result is the largest connected component of the fine mask. Batch norm is folded into
the convolutions for inference (:meth:`SegmentationNet.fused`). Sizes and timings: the model
card next to the weights (``models/segmentation.md``) and docs/results/bench_perception.md.
"""

from __future__ import annotations

import copy
import pickle
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from numpy.typing import NDArray
from torch import nn

__all__ = [
    "COARSE_WIDTH",
    "CROP_MARGIN",
    "DEFAULT_WEIGHTS",
    "HEIGHT_SCALE",
    "CoarseNet",
    "FineNet",
    "HeightMap",
    "Segmentation",
    "SegmentationNet",
    "Segmenter",
    "coarse_factor",
    "crop_grid",
    "load_net",
    "normalise_inputs",
]

#: Height above the table that maps to 1.0 in the network input, metres.
HEIGHT_SCALE = 0.02
#: Target width of the coarse stage's input, px (the factor is rounded to an integer).
COARSE_WIDTH = 160
#: Pixels added around the coarse bounding box before the fine stage, full resolution.
CROP_MARGIN = 12
#: File name of the bundled weights in ``push_perception/models``.
DEFAULT_WEIGHTS = "segmentation.pt"


# --------------------------------------------------------------------------------------------
# Input preparation
# --------------------------------------------------------------------------------------------
class HeightMap:
    """Height above the table (world z, metres) of every pixel from a z-depth image.

    For a pixel ``(u, v)`` with depth ``z`` the optical-frame point is
    ``z ((u - cx) / fx, (v - cy) / fy, 1)``, so its world z is ``z * a(u, v) + t_z`` with
    ``a = R[2] . ((u - cx) / fx, (v - cy) / fy, 1)`` (``R``, ``t`` of ``T_world_camera``).
    ``a`` is cached per (K, T, image size), so each frame costs one multiply-add per pixel.
    """

    def __init__(self) -> None:
        self._key: tuple[bytes, bytes, tuple[int, int]] | None = None
        self._a: NDArray[np.float32] | None = None
        self._tz = 0.0

    def __call__(self, depth: NDArray[np.floating], camera_matrix: NDArray[np.floating],
                 t_world_camera: NDArray[np.floating]) -> NDArray[np.float32]:
        """Height map (H, W) float32, metres; NaN where the depth is NaN (no return)."""
        k = np.asarray(camera_matrix, dtype=np.float64)
        t = np.asarray(t_world_camera, dtype=np.float64)
        key = (k.tobytes(), t.tobytes(), depth.shape)
        if key != self._key:
            h, w = depth.shape
            r = t[2, :3]
            u = (np.arange(w) - k[0, 2]) / k[0, 0]
            v = (np.arange(h) - k[1, 2]) / k[1, 1]
            self._a = (r[0] * u[None, :] + r[1] * v[:, None] + r[2]).astype(np.float32)
            self._tz = float(t[2, 3])
            self._key = key
        return np.asarray(depth, dtype=np.float32) * self._a + np.float32(self._tz)


def normalise_inputs(rgb: NDArray[np.uint8], height: NDArray[np.floating]) -> NDArray[np.float32]:
    """Network input (4, H, W) float32 from RGB (H, W, 3) uint8 and a height map (H, W) in m.

    NaN heights (no depth) become 0 (table level); heights are divided by ``HEIGHT_SCALE`` and
    clipped to [-1, 4].
    """
    x = np.empty((4, *height.shape), dtype=np.float32)
    x[:3] = np.moveaxis(rgb, -1, 0)
    x[:3] *= np.float32(1.0 / 255.0)
    x[:3] -= np.float32(0.5)
    np.multiply(height, np.float32(1.0 / HEIGHT_SCALE), out=x[3])
    x[3][np.isnan(x[3])] = 0.0
    np.clip(x[3], -1.0, 4.0, out=x[3])
    return x


def coarse_factor(width: int) -> int:
    """Integer downscaling factor of the coarse stage for an image ``width`` px wide."""
    return max(1, int(round(width / COARSE_WIDTH)))


def crop_grid(box: tuple[int, int, int, int], image_size: tuple[int, int],
              dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """``grid_sample`` grid (1, h, w, 2) of the pixel centres of a crop, normalised.

    Parameters
    ----------
    box : (u0, v0, u1, v1)
        Crop in full-resolution pixels, columns ``u0 <= u < u1``, rows ``v0 <= v < v1``.
    image_size : (width, height)
        Full image size, px.

    Notes
    -----
    With ``align_corners=False`` the normalised coordinate of pixel centre ``u`` is
    ``2 (u + 0.5) / W - 1`` at every resolution, so sampling the coarse logits with this grid
    lines them up with the full-resolution pixels.
    """
    u0, v0, u1, v1 = box
    w, h = image_size
    xs = (2.0 * (torch.arange(u0, u1, dtype=dtype) + 0.5) / w) - 1.0
    ys = (2.0 * (torch.arange(v0, v1, dtype=dtype) + 0.5) / h) - 1.0
    gy, gx = torch.meshgrid(ys, xs, indexing="ij")
    return torch.stack([gx, gy], dim=-1)[None]


# --------------------------------------------------------------------------------------------
# Networks
# --------------------------------------------------------------------------------------------
def _cbr(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, 1, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))


def _up_add(x: torch.Tensor, skip: torch.Tensor) -> torch.Tensor:
    return F.interpolate(x, size=skip.shape[-2:], mode="bilinear", align_corners=False) + skip


class _EncoderDecoder(nn.Module):
    """Three encoder levels (the first given, then two stride-2 levels) and an additive,
    FPN-style decoder back to the first level's resolution; returns one logit channel."""

    def __init__(self, enc1: nn.Module, channels: tuple[int, int, int]) -> None:
        super().__init__()
        a, b, c = channels
        self.enc1 = enc1
        self.enc2 = nn.Sequential(_cbr(a, b, 2), _cbr(b, b))
        self.enc3 = nn.Sequential(_cbr(b, c, 2), _cbr(c, c))
        self.lat3, self.lat2 = nn.Conv2d(c, b, 1), nn.Conv2d(b, a, 1)
        self.dec2, self.dec1 = _cbr(b, b), _cbr(a, a)
        self.head = nn.Conv2d(a, 1, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x1 = self.enc1(x)
        x2 = self.enc2(x1)
        x3 = self.enc3(x2)
        y = self.dec2(_up_add(self.lat3(x3), x2))
        y = self.dec1(_up_add(self.lat2(y), x1))
        return self.head(y)


class CoarseNet(_EncoderDecoder):
    """Whole-frame localisation: (B, 4, h, w) -> logits (B, 1, ceil(h/2), ceil(w/2))."""

    def __init__(self, channels: tuple[int, int, int] = (16, 32, 64)) -> None:
        a = channels[0]
        super().__init__(nn.Sequential(_cbr(4, a, 2), _cbr(a, a)), channels)


class FineNet(_EncoderDecoder):
    """Full-resolution refinement of a crop: (B, 5, h, w) -> logits (B, 1, h, w).

    Channel 4 of the input is the coarse logit at each pixel; the output is that logit plus a
    learned correction.
    """

    def __init__(self, channels: tuple[int, int, int] = (8, 16, 32)) -> None:
        super().__init__(_cbr(5, channels[0]), channels)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return super().forward(x) + x[:, 4:5]


class SegmentationNet(nn.Module):
    """Both stages in one module (one state dict, one file)."""

    def __init__(self) -> None:
        super().__init__()
        self.coarse = CoarseNet()
        self.fine = FineNet()

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # pragma: no cover - use the stages
        raise NotImplementedError("call .coarse and .fine; see Segmenter")

    def fused(self) -> SegmentationNet:
        """An inference copy with every BatchNorm folded into its convolution (eval mode)."""
        net = copy.deepcopy(self).eval()
        for module in net.modules():
            if isinstance(module, nn.Sequential) and len(module) == 3 \
                    and isinstance(module[0], nn.Conv2d) and isinstance(module[1], nn.BatchNorm2d):
                conv, bn = module[0], module[1]
                scale = bn.weight / torch.sqrt(bn.running_var + bn.eps)
                fused = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size,
                                  conv.stride, conv.padding, bias=True)
                with torch.no_grad():
                    fused.weight.copy_(conv.weight * scale[:, None, None, None])
                    fused.bias.copy_(bn.bias - bn.running_mean * scale)
                module[0], module[1] = fused, nn.Identity()
        return net


# --------------------------------------------------------------------------------------------
# Inference
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Segmentation:
    """Output of :class:`Segmenter` for one frame.

    Attributes
    ----------
    mask : (H, W) bool
        Object pixels (largest connected component), ``camera_color_optical_frame``.
    box : (u0, v0, u1, v1) or None
        Crop refined at full resolution (None: nothing found).
    coarse_pixels : int
        Size of the coarse component, in coarse cells (0: nothing found).
    confidence : float
        Mean object probability of the mask's pixels, [0, 1] (1 for a segmentation without
        probabilities, e.g. from depth; 0 when nothing was found).
    """

    mask: NDArray[np.bool_]
    box: tuple[int, int, int, int] | None
    coarse_pixels: int
    confidence: float = 1.0


class Segmenter:
    """Run the two-stage network on a frame. Not thread-safe (caches buffers).

    Parameters
    ----------
    net : SegmentationNet
        Trained network (it is copied, fused and put in eval mode).
    threshold : float
        Probability above which a pixel is the object, (0, 1).
    min_coarse_cells : int
        Smallest coarse component taken for an object (smaller ones are noise), >= 1.
    """

    def __init__(self, net: SegmentationNet, threshold: float = 0.5,
                 min_coarse_cells: int = 3) -> None:
        if not 0.0 < threshold < 1.0:
            raise ValueError(f"threshold: must be in (0, 1), got {threshold!r}")
        if int(min_coarse_cells) < 1:
            raise ValueError(f"min_coarse_cells: must be >= 1, got {min_coarse_cells!r}")
        self.net = net.fused()
        self.logit_threshold = float(np.log(threshold / (1.0 - threshold)))
        self.min_coarse_cells = int(min_coarse_cells)
        self._height = HeightMap()

    @classmethod
    def load(cls, path: str | Path | None = None, **kwargs: float) -> Segmenter:
        """Load weights (default: the bundled ``models/segmentation.pt``).

        Raises
        ------
        ValueError
            If the file does not exist or does not hold a SegmentationNet state dict.
        """
        if path is None or str(path) == "":
            ref = resources.files("push_perception").joinpath("models", DEFAULT_WEIGHTS)
            path = Path(str(ref))
        net = load_net(Path(path))
        return cls(net, **kwargs)

    def __call__(self, rgb: NDArray[np.uint8], depth: NDArray[np.floating],
                 camera_matrix: NDArray[np.floating],
                 t_world_camera: NDArray[np.floating],
                 robot: NDArray[np.bool_] | None = None) -> Segmentation:
        """Segment the object in one frame.

        Parameters
        ----------
        rgb : (H, W, 3) uint8
            Colour image (R, G, B).
        depth : (H, W) float
            z-depth aligned to colour, metres, NaN = no return.
        camera_matrix : (3, 3)
            K, pixels.
        t_world_camera : (4, 4)
            world <- camera_color_optical_frame.
        robot : (H, W) bool, optional
            The robot's pixels: never object pixels, and they join the object's pieces on
            either side of them (the rod across the object) into one component, at both
            stages. Their colour and depth should be neutral already
            (:func:`push_perception.robot_filter.clear_robot`).

        Returns
        -------
        Segmentation
        """
        h, w = depth.shape
        height = self._height(depth, camera_matrix, t_world_camera)
        s = coarse_factor(w)
        small_size = (max(1, round(w / s)), max(1, round(h / s)))
        small = normalise_inputs(cv2.resize(rgb, small_size, interpolation=cv2.INTER_AREA),
                                 cv2.resize(np.nan_to_num(height, nan=0.0), small_size,
                                            interpolation=cv2.INTER_AREA))
        empty = Segmentation(np.zeros((h, w), dtype=bool), None, 0, 0.0)
        with torch.inference_mode():
            coarse = self.net.coarse(torch.from_numpy(small)[None])
            cmask = (coarse[0, 0] > self.logit_threshold).numpy().astype(np.uint8)
            ch, cw = cmask.shape
            rmask = None if robot is None else cv2.resize(
                robot.astype(np.uint8), (cw, ch), interpolation=cv2.INTER_AREA) > 0
            best_mask = _largest_piece(cmask, rmask, connectivity=8)
            cells = int(np.count_nonzero(best_mask))
            if cells == 0 or cells < self.min_coarse_cells:
                return empty
            ys, xs = np.nonzero(best_mask)
            x, y, bw, bh = int(xs.min()), int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1
            u0 = max(0, int(np.floor(x * w / cw)) - CROP_MARGIN)
            v0 = max(0, int(np.floor(y * h / ch)) - CROP_MARGIN)
            u1 = min(w, int(np.ceil((x + bw) * w / cw)) + CROP_MARGIN)
            v1 = min(h, int(np.ceil((y + bh) * h / ch)) + CROP_MARGIN)
            box = (u0, v0, u1, v1)
            crop = np.empty((5, v1 - v0, u1 - u0), dtype=np.float32)
            crop[:4] = normalise_inputs(rgb[v0:v1, u0:u1], height[v0:v1, u0:u1])
            x_crop = torch.from_numpy(crop)[None]
            x_crop[:, 4:5] = F.grid_sample(coarse, crop_grid(box, (w, h)), mode="bilinear",
                                           padding_mode="border", align_corners=False)
            fine = self.net.fine(x_crop)[0, 0].numpy()
        fmask = (fine > self.logit_threshold).astype(np.uint8)
        mask = np.zeros((h, w), dtype=bool)
        piece = _largest_piece(fmask, None if robot is None else robot[v0:v1, u0:u1],
                               connectivity=4)
        mask[v0:v1, u0:u1] = piece
        confidence = float(np.mean(1.0 / (1.0 + np.exp(-fine[piece])))) if piece.any() else 0.0
        return Segmentation(mask, box, cells, confidence)


def load_net(path: Path) -> SegmentationNet:
    """The :class:`SegmentationNet` of a weights file (a ``state_dict`` or a checkpoint of
    ``pushbot train segmentation``), in eval mode.

    Raises
    ------
    ValueError
        If the file does not exist or does not hold a SegmentationNet state dict.
    """
    if not path.is_file():
        raise ValueError(f"segmentation weights {path} do not exist")
    net = SegmentationNet()
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
        net.load_state_dict(state["state_dict"] if "state_dict" in state else state)
    except (RuntimeError, KeyError, OSError, TypeError, pickle.UnpicklingError) as exc:
        raise ValueError(f"{path}: not a segmentation network checkpoint ({exc})") from None
    return net.eval()


def _largest_piece(mask: NDArray[np.uint8], robot: NDArray[np.bool_] | None,
                   connectivity: int) -> NDArray[np.bool_]:
    """The largest connected component of ``mask`` (empty when there is none); with
    ``robot``, components are those of ``mask | robot`` (ranked by their ``mask`` pixels) and
    the result is their ``mask`` pixels off the robot."""
    joined = mask if robot is None else (mask.astype(bool) | robot).astype(np.uint8)
    n, labels = cv2.connectedComponents(joined, connectivity=connectivity)
    if n <= 1:
        return np.zeros(mask.shape, dtype=bool)
    own = mask.astype(bool) if robot is None else mask.astype(bool) & ~robot
    counts = np.bincount(labels[own], minlength=n)
    counts[0] = 0
    return (labels == int(np.argmax(counts))) & own
