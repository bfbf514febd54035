"""Lens distortion and depth registration of RGB-D cameras, ROS-free (numpy).

What a ROS camera driver publishes is rarely the ideal, aligned pinhole the perception measures
with: a colour stream with lens distortion (``plumb_bob``, ``rational_polynomial``), depth in
its own optical frame with its own intrinsics. This module holds the geometry that turns such
frames into the ideal pinhole image of the colour camera (same K, no distortion, depth aligned
to it) and, for the simulator, the inverse: an ideal rendering into what a distorted lens gives.

Conventions: pixels are OpenCV's (``u`` right, ``v`` down, integer coordinates at pixel
centres); normalised coordinates are ``(x, y) = ((u - cx) / fx, (v - cy) / fy)``; the
distortion coefficients are OpenCV's order ``(k1, k2, p1, p2, k3[, k4, k5, k6])``:

    r2 = x^2 + y^2
    radial = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3)
    x_d = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
    y_d = y radial + p1 (r2 + 2 y^2) + 2 p2 x y

Maps are ``(map_u, map_v)`` float32 (H, W) arrays in the convention of ``cv2.remap``: the
output pixel ``(v, u)`` takes the input at ``(map_v[v, u], map_u[v, u])``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "distort_normalised",
    "distortion_maps",
    "register_depth",
    "undistort_normalised",
    "undistortion_maps",
]

#: Fixed-point iterations of :func:`undistort_normalised` (OpenCV's undistortPoints uses 5 by
#: default; 20 bring a 0.2-strong radial term within 1e-6 px at the image corners).
UNDISTORT_ITERATIONS = 20


def _coefficients(d: ArrayLike) -> NDArray[np.float64]:
    d = np.asarray(d, dtype=np.float64).ravel()
    if d.size not in (0, 4, 5, 8) or not np.all(np.isfinite(d)):
        raise ValueError(f"distortion coefficients: 0, 4, 5 or 8 finite values, got {d.size}")
    return np.concatenate([d, np.zeros(8 - d.size)])


def distort_normalised(x: NDArray[np.floating], y: NDArray[np.floating], d: ArrayLike
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Distorted normalised coordinates of ideal ones (the lens model of the module docstring).

    Parameters
    ----------
    x, y : ndarray
        Ideal normalised coordinates, any equal shapes.
    d : (0,), (4,), (5,) or (8,) array
        Coefficients, OpenCV's order (missing ones are zero).

    Returns
    -------
    (x_d, y_d) : ndarray
        Same shape as ``x``.
    """
    k1, k2, p1, p2, k3, k4, k5, k6 = _coefficients(d)
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    r2 = x * x + y * y
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return xd, yd


def undistort_normalised(xd: NDArray[np.floating], yd: NDArray[np.floating], d: ArrayLike
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Ideal normalised coordinates of distorted ones: the inverse of
    :func:`distort_normalised` by fixed-point iteration (as OpenCV's ``undistortPoints``).

    Returns
    -------
    (x, y) : ndarray
        Same shape as ``xd``; exact to about 1e-9 for the moderate distortion of RGB-D camera
        lenses (``|k1| < 0.5`` within the image).
    """
    k1, k2, p1, p2, k3, k4, k5, k6 = _coefficients(d)
    xd = np.asarray(xd, dtype=np.float64)
    yd = np.asarray(yd, dtype=np.float64)
    x, y = xd.copy(), yd.copy()
    for _ in range(UNDISTORT_ITERATIONS):
        r2 = x * x + y * y
        inv_radial = (1 + r2 * (k4 + r2 * (k5 + r2 * k6))) / (1 + r2 * (k1 + r2 * (k2 + r2 * k3)))
        dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        x = (xd - dx) * inv_radial
        y = (yd - dy) * inv_radial
    return x, y


def _pixel_grid(k: NDArray[np.float64], size: tuple[int, int]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    return (u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1]


def undistortion_maps(k: ArrayLike, d: ArrayLike, size: tuple[int, int]
                      ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Remap tables from a distorted image to the ideal pinhole image with the same K.

    Parameters
    ----------
    k : (3, 3) array
        Camera matrix, px (the driver's K: the same for the distorted and the ideal image).
    d : array
        Distortion coefficients, OpenCV's order.
    size : (width, height)
        Image size, px.

    Returns
    -------
    (map_u, map_v) : (H, W) float32
        For each ideal pixel, where it lies in the distorted image (``cv2.remap`` order).
    """
    k = np.asarray(k, dtype=np.float64)
    x, y = _pixel_grid(k, size)
    xd, yd = distort_normalised(x, y, d)
    return ((xd * k[0, 0] + k[0, 2]).astype(np.float32),
            (yd * k[1, 1] + k[1, 2]).astype(np.float32))


def distortion_maps(k: ArrayLike, d: ArrayLike, size: tuple[int, int]
                    ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Remap tables from an ideal pinhole image to the image the distorted lens gives (a
    simulator renders the ideal one; the inverse of :func:`undistortion_maps`).

    Returns
    -------
    (map_u, map_v) : (H, W) float32
        For each distorted pixel, where it lies in the ideal image.
    """
    k = np.asarray(k, dtype=np.float64)
    xd, yd = _pixel_grid(k, size)
    x, y = undistort_normalised(xd, yd, d)
    return ((x * k[0, 0] + k[0, 2]).astype(np.float32),
            (y * k[1, 1] + k[1, 2]).astype(np.float32))


def register_depth(depth: NDArray[np.floating], k_depth: ArrayLike, k_color: ArrayLike,
                   t_color_depth: ArrayLike, color_size: tuple[int, int]) -> NDArray[np.float32]:
    """Depth of the depth camera re-projected into the colour camera's pixels (registration).

    Every valid depth pixel is deprojected with ``k_depth``, moved into the colour optical
    frame and projected with ``k_color``; it covers the 2 x 2 colour pixels around the point
    it lands on (so a depth image of similar resolution leaves no gaps), and where several
    land on one pixel the nearest wins (z-buffer: the foreground hides what is behind it).
    Both images must be ideal pinholes already (undistorted).

    Parameters
    ----------
    depth : (H_d, W_d) float
        z-depth of the depth camera, metres; NaN = no return.
    k_depth, k_color : (3, 3)
        Intrinsics of the depth and of the colour camera, px.
    t_color_depth : (4, 4)
        Pose of the depth optical frame in the colour optical frame (colour <- depth), m.
    color_size : (width, height)
        Size of the colour image, px.

    Returns
    -------
    (H_c, W_c) float32
        z-depth in the colour optical frame, metres; NaN where no depth pixel lands.
    """
    z = np.asarray(depth, dtype=np.float64)
    kd = np.asarray(k_depth, dtype=np.float64)
    kc = np.asarray(k_color, dtype=np.float64)
    t = np.asarray(t_color_depth, dtype=np.float64)
    w, h = (int(s) for s in color_size)
    out = np.full(h * w, np.inf)
    v, u = np.nonzero(np.isfinite(z) & (z > 0))
    zz = z[v, u]
    pts = np.stack([(u - kd[0, 2]) / kd[0, 0] * zz, (v - kd[1, 2]) / kd[1, 1] * zz, zz], -1)
    pc = pts @ t[:3, :3].T + t[:3, 3]
    front = pc[:, 2] > 1e-6
    pc = pc[front]
    uc = kc[0, 0] * pc[:, 0] / pc[:, 2] + kc[0, 2]
    vc = kc[1, 1] * pc[:, 1] / pc[:, 2] + kc[1, 2]
    u0, v0 = np.floor(uc).astype(np.int64), np.floor(vc).astype(np.int64)
    for du in (0, 1):
        for dv in (0, 1):
            uu, vv = u0 + du, v0 + dv
            inside = (uu >= 0) & (uu < w) & (vv >= 0) & (vv < h)
            np.minimum.at(out, vv[inside] * w + uu[inside], pc[inside, 2])
    out[~np.isfinite(out)] = np.nan
    return out.reshape(h, w).astype(np.float32)
