"""push_core.camera_model: the lens model, its inverse, the remap tables and depth registration,
against values computed by hand and against OpenCV's own lens model."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from push_core.camera_model import (
    distort_normalised,
    distortion_maps,
    register_depth,
    undistort_normalised,
    undistortion_maps,
)

K = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])
PLUMB_BOB = np.array([0.08, -0.12, 0.001, -0.0006, 0.03])
RATIONAL = np.array([0.08, -0.12, 0.0006, -0.0004, 0.03, 0.01, -0.02, 0.01])


@pytest.mark.parametrize("d", [PLUMB_BOB, RATIONAL], ids=["plumb_bob", "rational_polynomial"])
def test_the_lens_model_is_opencvs_and_its_inverse_is_exact(d: np.ndarray) -> None:
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-0.6, 0.6, 200), rng.uniform(-0.45, 0.45, 200)
    xd, yd = distort_normalised(x, y, d)
    # OpenCV projects the same normalised points through the same coefficients.
    ref, _ = cv2.projectPoints(np.column_stack([x, y, np.ones_like(x)]), np.zeros(3),
                               np.zeros(3), np.eye(3), d)
    np.testing.assert_allclose(np.column_stack([xd, yd]), ref[:, 0], atol=1e-12)
    xu, yu = undistort_normalised(xd, yd, d)
    np.testing.assert_allclose(xu, x, atol=1e-9)
    np.testing.assert_allclose(yu, y, atol=1e-9)


def test_zero_distortion_maps_are_the_identity_and_the_two_maps_are_inverse() -> None:
    u, v = undistortion_maps(K, np.zeros(5), (640, 480))
    np.testing.assert_allclose(u, np.arange(640)[None, :].repeat(480, 0), atol=1e-4)
    np.testing.assert_allclose(v, np.arange(480)[:, None].repeat(640, 1), atol=1e-4)
    # ideal -> distorted -> ideal: sampling the distortion map at the undistortion map's
    # positions gives back the pixel grid.
    du, dv = distortion_maps(K, PLUMB_BOB, (640, 480))
    uu, uv = undistortion_maps(K, PLUMB_BOB, (640, 480))
    back_u = cv2.remap(du, uu, uv, cv2.INTER_LINEAR)
    inner = (slice(40, 440), slice(40, 600))
    np.testing.assert_allclose(back_u[inner], np.arange(640)[None, 40:600].repeat(400, 0),
                               atol=0.01)
    # the corner of a barrel-free (k1 > 0) lens lies further out in the distorted image
    assert uu[0, 0] < 0.0 and uv[0, 0] < 0.0
    with pytest.raises(ValueError, match="coefficients"):
        undistortion_maps(K, [0.1, 0.2, 0.3], (640, 480))


def test_registration_of_a_plane_seen_by_a_shifted_depth_camera() -> None:
    # A fronto-parallel plane at 0.8 m seen by a depth camera 25 mm to the colour camera's
    # left: in colour pixels the depth is the same plane, shifted by f * 0.025 / 0.8 px.
    depth = np.full((480, 640), 0.8, dtype=np.float32)
    depth[200:280, 300:340] = 0.7  # a box nearer the camera
    t = np.eye(4)
    t[0, 3] = -0.025
    out = register_depth(depth, K, K, t, (640, 480))
    assert out.shape == (480, 640) and out.dtype == np.float32
    np.testing.assert_allclose(out[10:470, 40:600][np.isfinite(out[10:470, 40:600])
                                                   & (out[10:470, 40:600] > 0.75)], 0.8)
    shift_far, shift_near = 600 * 0.025 / 0.8, 600 * 0.025 / 0.7
    # the box's columns moved by f * 25 mm / 0.7 m (21.4 px) to the left
    cols = np.nonzero(np.isclose(out[240], 0.7))[0]
    assert cols.min() == pytest.approx(300 - shift_near, abs=1.0)
    assert cols.max() == pytest.approx(339 - shift_near, abs=1.0)
    # no gaps in the plane away from the box (2 x 2 splatting); beside the box, the strip of
    # plane the depth camera cannot see behind it (its shadow, shift_near - shift_far wide)
    away = np.r_[0:199, 281:480]
    assert np.all(np.isfinite(out[away, 40:600]))
    shadow = np.count_nonzero(np.isnan(out[240, 40:600]))
    assert shadow == pytest.approx(shift_near - shift_far, abs=1.0)
    assert np.all(np.isnan(out[:, 640 - int(shift_far) + 1:]))
    # the nearer surface wins where both land (z-buffer)
    assert np.all(out[240, cols] == np.float32(0.7))


def test_registration_ignores_missing_depth() -> None:
    depth = np.full((48, 64), np.nan, dtype=np.float32)
    depth[10, 10] = 0.5
    out = register_depth(depth, K / [[10], [10], [1]], K / [[10], [10], [1]], np.eye(4),
                         (64, 48))
    assert np.count_nonzero(np.isfinite(out)) == 4 and np.nanmax(out) == np.float32(0.5)
