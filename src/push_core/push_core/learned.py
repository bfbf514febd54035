"""Learned affordance model (``lrn``; docs/design/planner.md): a CNN from shape encoding,
COM and pushes to the object motion of every outline point x representative push.

Architecture (:class:`AffordanceNet`):

- **Shape encoding** (:func:`shape_encoding`, once per outline): a top-down image of the object,
  ``GRID`` x ``GRID`` = 64 x 64 pixels of ``RESOLUTION`` = 4 mm centred on the object frame
  origin (25.6 cm across), channels occupancy, outline, outward normal x and y (on the outline
  pixels); :func:`com_channels` adds two channels ``(x - c_x, y - c_y) / 0.1 m`` per pixel
  (the COM input). Rows run along +y, columns along +x of the object frame.
- **Local shape features**: a 3-layer CNN with max-pooling (3 x 3 convolutions with 16, 32, 32
  channels, ReLU, 2 x 2 max-pooling after each); the three feature maps are sampled bilinearly
  at each contact point, plus a global max over the last map (80 + 32 features per point).
- **Motion head**: a second 3-layer network without pooling (1 x 1 convolutions, i.e. the same
  small MLP applied to every point x push; 128, 128, 3 units) on the point features, the
  contact relative to the COM expressed in the contact frame and the push (direction relative to
  the inward normal as cos/sin, length / 5 cm). Its output is the COM displacement in the contact
  frame (along the inward normal and the tangent, in cm) and the rotation (in units of 5 deg),
  converted to the motion of the object frame origin in the object frame
  (:func:`push_core.model.apply_twist`), the convention of
  :func:`push_core.affordances.analytical_affordances`.

The contact-frame inputs and outputs make the head invariant to rotations of the object frame;
training rotates and mirrors the shape encoding accordingly. The model does not use ``l`` and ``m``
of the analytical model; it learns them from the data, including pushes that slide off corners.

Weights: ``torch.save`` of ``{"format_version", "config", "state_dict", "meta"}``; load with
:func:`load_affordance_model` (``weights_only=True``). CPU, one intra-op thread recommended.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from torch import nn
from torch.nn import functional as F  # noqa: N812

from push_core.model import REPRESENTATIVE_ANGLES_DEG, REPRESENTATIVE_LENGTHS, apply_twist

__all__ = [
    "FORMAT_VERSION",
    "GRID",
    "RESOLUTION",
    "AffordanceNet",
    "LearnedAffordances",
    "com_channels",
    "contact_frame_targets",
    "load_affordance_model",
    "push_features",
    "shape_encoding",
]

FORMAT_VERSION = 1
#: Pixels per side of the shape encoding and metres per pixel.
GRID = 64
RESOLUTION = 0.004
#: Scales of the network's inputs and outputs.
POSITION_SCALE = 0.1  # m, COM channels
LEVER_SCALE = 0.05  # m, contact relative to the COM
TRANSLATION_SCALE = 0.01  # m (outputs in cm)
ROTATION_SCALE = math.radians(5.0)  # rad
LENGTH_SCALE = 0.05  # m


# ------------------------------------------------------------------------------ encoding
def _pixel_centres(grid: int, resolution: float) -> NDArray[np.float64]:
    return (np.arange(grid) + 0.5 - grid / 2.0) * resolution


def shape_encoding(points: ArrayLike, normals_out: ArrayLike, grid: int = GRID,
                   resolution: float = RESOLUTION) -> NDArray[np.float32]:
    """The static channels of the shape encoding: occupancy, outline, normal x, normal y.

    Parameters
    ----------
    points, normals_out : array_like, shape (N, 2)
        Outline (counter-clockwise) and outward unit normals, object frame (metres).
    grid, resolution : int, float
        Image size (pixels) and pixel size (metres); the image is centred on the origin.

    Returns
    -------
    numpy.ndarray, float32, shape (4, grid, grid)
        Row ``i`` is ``y = (i + 0.5 - grid / 2) * resolution``, column ``j`` likewise ``x``.
        Occupancy: pixel centre inside the polygon of ``points``; outline: 1 where an outline
        point falls; normals: mean outward normal of those points, normalised (0 elsewhere).
        Points beyond the image are clamped to its border pixels.
    """
    from matplotlib.path import Path as MplPath

    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals_out, dtype=np.float64)
    c = _pixel_centres(grid, resolution)
    xx, yy = np.meshgrid(c, c)
    inside = MplPath(p).contains_points(np.stack([xx.ravel(), yy.ravel()], 1))
    out = np.zeros((4, grid, grid), dtype=np.float64)
    out[0] = inside.reshape(grid, grid)
    col = np.clip(np.floor(p[:, 0] / resolution + grid / 2.0).astype(int), 0, grid - 1)
    row = np.clip(np.floor(p[:, 1] / resolution + grid / 2.0).astype(int), 0, grid - 1)
    np.add.at(out[1], (row, col), 1.0)
    np.add.at(out[2], (row, col), n[:, 0])
    np.add.at(out[3], (row, col), n[:, 1])
    norm = np.hypot(out[2], out[3])
    has = out[1] > 0
    out[2:4, has] /= np.maximum(norm[has], 1e-12)
    out[1] = has
    return out.astype(np.float32)


def com_channels(com: torch.Tensor, grid: int = GRID,
                 resolution: float = RESOLUTION) -> torch.Tensor:
    """The COM channels ``(x - c_x, y - c_y) / POSITION_SCALE`` for a batch of COMs.

    Parameters
    ----------
    com : torch.Tensor, shape (B, 2)
        COM offsets in the object frame, metres.

    Returns
    -------
    torch.Tensor, shape (B, 2, grid, grid)
    """
    c = torch.as_tensor(_pixel_centres(grid, resolution), dtype=com.dtype, device=com.device)
    x = (c[None, None, :] - com[:, 0, None, None]) / POSITION_SCALE
    y = (c[None, :, None] - com[:, 1, None, None]) / POSITION_SCALE
    return torch.stack([x.expand(-1, grid, grid), y.expand(-1, grid, grid)], 1)


def push_features(dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """The 10 representative pushes as network inputs, shape (10, 3): cos, sin of the angle
    to the inward normal and length / 5 cm, length-major like
    :func:`push_core.model.representative_pushes`."""
    rows = [(math.cos(math.radians(a)), math.sin(math.radians(a)), length / LENGTH_SCALE)
            for length in REPRESENTATIVE_LENGTHS for a in REPRESENTATIVE_ANGLES_DEG]
    return torch.tensor(rows, dtype=dtype)


def _contact_frame(normals_out: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    e_n = -normals_out / torch.linalg.vector_norm(normals_out, dim=-1, keepdim=True)
    e_t = torch.stack([-e_n[..., 1], e_n[..., 0]], -1)
    return e_n, e_t


def contact_frame_targets(points: ArrayLike, normals_out: ArrayLike, com: ArrayLike,
                          motion: ArrayLike) -> NDArray[np.float64]:
    """Training targets: origin motion (object frame) -> scaled COM motion in the contact frame.

    Parameters
    ----------
    points, normals_out : array_like, shape (..., P, 2)
        Contact points and outward normals.
    com : array_like, shape (..., 2)
        COM offsets.
    motion : array_like, shape (..., P, M, 3)
        Origin displacement in the object frame before the push and rotation (labels).

    Returns
    -------
    numpy.ndarray, shape (..., P, M, 3)
        ``(v_c . e_n, v_c . e_t) / TRANSLATION_SCALE`` and ``dtheta / ROTATION_SCALE`` with the
        COM displacement ``v_c = d_origin + R(dtheta) c - c``; the inverse of the network's
        output conversion.
    """
    n = torch.as_tensor(np.array(normals_out, dtype=np.float64))
    c = np.asarray(com, dtype=np.float64)[..., None, None, :]
    mo = np.asarray(motion, dtype=np.float64)
    th = mo[..., 2]
    cos, sin = np.cos(th), np.sin(th)
    vx = mo[..., 0] + cos * c[..., 0] - sin * c[..., 1] - c[..., 0]
    vy = mo[..., 1] + sin * c[..., 0] + cos * c[..., 1] - c[..., 1]
    e_n, e_t = (e.numpy()[..., None, :] for e in _contact_frame(n))
    return np.stack([(vx * e_n[..., 0] + vy * e_n[..., 1]) / TRANSLATION_SCALE,
                     (vx * e_t[..., 0] + vy * e_t[..., 1]) / TRANSLATION_SCALE,
                     th / ROTATION_SCALE], -1)


# ------------------------------------------------------------------------------ network
class AffordanceNet(nn.Module):
    """The CNN of the module docstring.

    Parameters
    ----------
    channels : tuple of 3 int
        Channels of the three convolution layers of the shape-feature CNN.
    hidden : int
        Units of the two hidden layers of the motion head.
    grid, resolution : int, float
        Shape encoding geometry the network was trained with.
    """

    def __init__(self, channels: tuple[int, int, int] = (16, 32, 32), hidden: int = 128,
                 grid: int = GRID, resolution: float = RESOLUTION) -> None:
        super().__init__()
        self.grid, self.resolution = int(grid), float(resolution)
        c1, c2, c3 = channels
        self.conv1 = nn.Conv2d(6, c1, 3, padding=1)
        self.conv2 = nn.Conv2d(c1, c2, 3, padding=1)
        self.conv3 = nn.Conv2d(c2, c3, 3, padding=1)
        n_point = c1 + c2 + c3 + c3 + 2  # sampled maps, global max, lever arm
        self.point_in = nn.Linear(n_point, hidden)
        self.push_in = nn.Linear(3, hidden, bias=False)
        self.hidden = nn.Linear(hidden, hidden)
        self.out = nn.Linear(hidden, 3)
        self.register_buffer("pushes", push_features())

    def forward(self, encoding: torch.Tensor, com: torch.Tensor, points: torch.Tensor,
                normals_out: torch.Tensor) -> torch.Tensor:
        """Scaled contact-frame predictions.

        Parameters
        ----------
        encoding : (B, 4, G, G) static channels (:func:`shape_encoding`)
        com : (B, 2) COM offsets, metres
        points, normals_out : (B, P, 2) contact points and outward normals, object frame

        Returns
        -------
        torch.Tensor, shape (B, P, 10, 3)
            COM displacement along the inward normal and the tangent (cm) and rotation (units
            of 5 deg) for every point x representative push.
        """
        x = torch.cat([encoding, com_channels(com, self.grid, self.resolution)], 1)
        f1 = F.max_pool2d(F.relu(self.conv1(x)), 2)
        f2 = F.max_pool2d(F.relu(self.conv2(f1)), 2)
        f3 = F.max_pool2d(F.relu(self.conv3(f2)), 2)
        half = self.grid * self.resolution / 2.0
        uv = (points / half)[:, :, None, :]  # (B, P, 1, 2), x -> width, y -> height
        sampled = [F.grid_sample(f, uv, mode="bilinear", padding_mode="border",
                                 align_corners=False)[..., 0].transpose(1, 2)
                   for f in (f1, f2, f3)]  # (B, P, C)
        glob = f3.amax(dim=(2, 3))[:, None, :].expand(-1, points.shape[1], -1)
        e_n, e_t = _contact_frame(normals_out)
        lever = points - com[:, None, :]
        arm = torch.stack([(lever * e_n).sum(-1), (lever * e_t).sum(-1)], -1) / LEVER_SCALE
        feats = torch.cat([*sampled, glob, arm], -1)  # (B, P, F)
        h = F.relu(self.point_in(feats)[:, :, None, :] + self.push_in(self.pushes)[None, None])
        h = F.relu(self.hidden(h))
        return self.out(h)

    def origin_motion(self, encoding: torch.Tensor, com: torch.Tensor, points: torch.Tensor,
                      normals_out: torch.Tensor) -> torch.Tensor:
        """Predicted origin motion in the object frame, (B, P, 10, 3), metres and radians."""
        y = self.forward(encoding, com, points, normals_out)
        e_n, e_t = _contact_frame(normals_out)
        v = (y[..., 0:1] * e_n[:, :, None, :] + y[..., 1:2] * e_t[:, :, None, :])
        twist = torch.cat([v * TRANSLATION_SCALE, y[..., 2:3] * ROTATION_SCALE], -1)
        zero = torch.zeros_like(twist)
        return apply_twist(zero, twist, com[:, None, None, :].expand_as(twist[..., :2]))


class LearnedAffordances:
    """Callable affordance model for the planner (:class:`push_core.affordances.AffordanceModel`).

    Parameters
    ----------
    net : AffordanceNet
        Trained network (put in eval mode here).
    meta : dict, optional
        What the weights file says about the model (data, metrics).
    """

    def __init__(self, net: AffordanceNet, meta: dict[str, Any] | None = None) -> None:
        self.net = net.eval()
        self.meta = dict(meta or {})
        self._cache: dict[bytes, torch.Tensor] = {}

    def encoding(self, points: NDArray[np.float64], normals_out: NDArray[np.float64]
                 ) -> torch.Tensor:
        """Static shape encoding (1, 4, G, G), cached per outline (a few outlines kept)."""
        key = hashlib.sha1(np.ascontiguousarray(points).tobytes()
                           + np.ascontiguousarray(normals_out).tobytes()).digest()
        enc = self._cache.get(key)
        if enc is None:
            enc = torch.from_numpy(shape_encoding(points, normals_out, self.net.grid,
                                                  self.net.resolution))[None]
            if len(self._cache) >= 8:
                self._cache.pop(next(iter(self._cache)))
            self._cache[key] = enc
        return enc

    def __call__(self, points: ArrayLike, normals_out: ArrayLike, com: ArrayLike,
                 l: float = 0.0, m: float = 0.0) -> NDArray[np.float64]:  # noqa: E741
        """Affordances (N, 10, 3): origin motion in the object frame (m, m, rad); ``l`` and
        ``m`` are ignored (see :func:`push_core.affordances.analytical_affordances`)."""
        p = np.asarray(points, dtype=np.float64)
        n = np.asarray(normals_out, dtype=np.float64)
        with torch.no_grad():
            enc = self.encoding(p, n)
            out = self.net.origin_motion(
                enc, torch.as_tensor(np.asarray(com, dtype=np.float32)).reshape(1, 2),
                torch.from_numpy(p.astype(np.float32))[None],
                torch.from_numpy(n.astype(np.float32))[None])
        return out[0].double().numpy()


def load_affordance_model(path: str | Path) -> LearnedAffordances:
    """Load weights written by the training script (``pushbot train affordances``).

    Raises
    ------
    ValueError
        Not a weights file of this format.
    OSError
        Unreadable file.
    """
    data = torch.load(Path(path), map_location="cpu", weights_only=True)
    if not isinstance(data, dict) or data.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{path}: not a learned affordance model (format {FORMAT_VERSION})")
    cfg = data["config"]
    net = AffordanceNet(channels=tuple(cfg["channels"]), hidden=int(cfg["hidden"]),
                        grid=int(cfg["grid"]), resolution=float(cfg["resolution"]))
    net.load_state_dict(data["state_dict"])
    return LearnedAffordances(net, data.get("meta"))
