"""The object's outline from its footprint: smoothed, offset, resampled, with outward normals.

ROS-free (numpy, scipy). A step of the mask-to-state pipeline (:mod:`push_perception.tracker`):
the footprint's boundary (``cv2.findContours``, cell centres;
:attr:`push_perception.footprint.TopDownView.boundary`) is resampled, smoothed along its length
with a Gaussian (``outline_smoothing``, metres), moved outward by half a cell (the cell centres
lie half a cell inside the boundary) and resampled at ``outline_spacing`` (2 mm); normals are
the outward unit normals of the smoothed curve, points counter-clockwise
(:func:`smooth_outline`). On the first frame of an episode this is the shape encoding, in the
object frame (origin at the centroid, axes = world axes at the first frame).

Bounded work: an outline has at most ``MAX_OUTLINE_POINTS`` (1000) points (a longer boundary is
resampled with the spacing widened to fit: 2 m of perimeter at the default 2 mm); the dense
curve it is smoothed on has at most ``MAX_DENSE_POINTS``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

__all__ = ["MAX_DENSE_POINTS", "MAX_OUTLINE_POINTS", "smooth_outline"]

#: Most outline points of one frame; a longer boundary is resampled with a wider spacing.
MAX_OUTLINE_POINTS = 1000
#: Most samples of the dense curve an outline is smoothed on.
MAX_DENSE_POINTS = 65536


def smooth_outline(boundary: NDArray[np.float64], spacing: float, smoothing: float,
                   offset: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Smooth, offset and resample a closed counter-clockwise boundary.

    Parameters
    ----------
    boundary : (P, 2) float
        Closed polyline (first point not repeated), counter-clockwise, metres.
    spacing : float
        Arc-length spacing of the output points, metres.
    smoothing : float
        Standard deviation of the Gaussian applied along the curve, metres (0: none).
    offset : float
        Distance the curve is moved along its outward normal, metres.

    Returns
    -------
    points, normals : (K, 2) float64
        Points counter-clockwise at the centres of ``round(length / spacing)`` equal arcs
        (like ``push_core.shapes.Polygon.outline``) and their outward unit normals; at most
        ``MAX_OUTLINE_POINTS`` (the spacing widened to fit).
    """
    pts = np.asarray(boundary, dtype=np.float64)
    closed = np.vstack([pts, pts[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    length = float(s[-1])
    step = min(spacing / 4.0, max(smoothing / 2.0, 1e-5)) if smoothing > 0 else spacing / 4.0
    n_dense = max(16, min(int(math.ceil(length / step)), MAX_DENSE_POINTS))
    sd = np.arange(n_dense) * (length / n_dense)
    x = np.interp(sd, s, closed[:, 0])
    y = np.interp(sd, s, closed[:, 1])
    if smoothing > 0:
        sigma = smoothing / (length / n_dense)
        x = gaussian_filter1d(x, sigma, mode="wrap")
        y = gaussian_filter1d(y, sigma, mode="wrap")
    tx = np.roll(x, -1) - np.roll(x, 1)
    ty = np.roll(y, -1) - np.roll(y, 1)
    norm = np.hypot(tx, ty)
    norm[norm == 0] = 1.0
    nx, ny = ty / norm, -tx / norm  # outward for a counter-clockwise curve
    x, y = x + offset * nx, y + offset * ny
    # Resample by arc length of the smoothed, offset curve.
    closed = np.stack([np.append(x, x[0]), np.append(y, y[0])], axis=1)
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n_out = max(3, min(int(round(s[-1] / spacing)), MAX_OUTLINE_POINTS))
    so = (np.arange(n_out) + 0.5) * (s[-1] / n_out)
    px = np.interp(so, s, closed[:, 0])
    py = np.interp(so, s, closed[:, 1])
    nxo = np.interp(so, s, np.append(nx, nx[0]))
    nyo = np.interp(so, s, np.append(ny, ny[0]))
    nn = np.hypot(nxo, nyo)
    nn[nn == 0] = 1.0
    return np.stack([px, py], axis=1), np.stack([nxo / nn, nyo / nn], axis=1)
