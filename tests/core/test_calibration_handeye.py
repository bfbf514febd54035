"""push_core.calibration.handeye: the eye-to-hand solver against hand-made poses with a known
answer (corners projected exactly, then with pixel noise), and its refusals."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from push_core.calibration.charuco import BoardSpec
from push_core.calibration.handeye import (
    CalibrationRefused,
    SolveConfig,
    View,
    rotation_spread_deg,
    solve_eye_to_hand,
)

K = np.array([[615.0, 0.0, 319.5], [0.0, 615.0, 239.5], [0.0, 0.0, 1.0]])
SIZE = (640, 480)
BOARD = BoardSpec()


def _pose(rotation: np.ndarray, translation) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = rotation
    t[:3, 3] = translation
    return t


#: The true answer: a camera 0.8 m from the table centre looking down at 55 degrees, and a
#: board mounted 6 cm off the tool axis, tilted.
CAMERA = _pose(Rotation.from_euler("xyz", [-145.0, 0.0, 90.0], degrees=True).as_matrix(),
               [0.49, 0.0, 0.66])
MOUNT = _pose(Rotation.from_euler("xyz", [10.0, -5.0, 30.0], degrees=True).as_matrix(),
              [0.06, -0.02, 0.04])


def _views(n: int, seed: int, *, spread_deg: float = 20.0, axes: str = "xyz",
           noise_px: float = 0.0, d: np.ndarray | None = None) -> list[View]:
    """``n`` tool poses whose board faces the camera from 0.45-0.65 m, rotated up to
    ``spread_deg`` about random axes in ``axes``; the corners inside the image, projected
    through the true camera and mount."""
    rng = np.random.default_rng(seed)
    views = []
    centre = BOARD.corners.mean(axis=0)
    while len(views) < n:
        axis = np.zeros(3)
        for a in axes:
            axis["xyz".index(a)] = rng.normal()
        axis /= np.linalg.norm(axis)
        tilt = Rotation.from_rotvec(np.radians(rng.uniform(-spread_deg, spread_deg)) * axis)
        # Board in the camera: in front of it, facing it, then tilted about its centre.
        r_cb = tilt.as_matrix()
        t_cb = np.array([rng.uniform(-0.08, 0.08), rng.uniform(-0.06, 0.06),
                         rng.uniform(0.45, 0.65)]) - r_cb @ centre
        t_wb = CAMERA @ _pose(r_cb, t_cb)
        tool = t_wb @ np.linalg.inv(MOUNT)
        p = BOARD.corners @ r_cb.T + t_cb
        px, _ = cv2.projectPoints(p, np.zeros(3), np.zeros(3), K, np.zeros(5) if d is None else d)
        px = px.reshape(-1, 2) + rng.normal(0.0, noise_px, (len(p), 2))
        inside = (px[:, 0] >= 0) & (px[:, 0] < SIZE[0]) & (px[:, 1] >= 0) & (px[:, 1] < SIZE[1])
        views.append(View(tool, np.flatnonzero(inside), px[inside]))
    return views


def _errors(result) -> tuple[float, float]:
    dp = np.linalg.norm(result.world_camera[:3, 3] - CAMERA[:3, 3]) * 1000.0
    dr = np.degrees(Rotation.from_matrix(result.world_camera[:3, :3].T @ CAMERA[:3, :3])
                    .magnitude())
    return float(dp), float(dr)


def test_exact_corners_recover_the_camera_and_the_mount_to_1e_6() -> None:
    result = solve_eye_to_hand(_views(12, 0), BOARD.corners, K)
    np.testing.assert_allclose(result.world_camera, CAMERA, atol=1e-6)
    np.testing.assert_allclose(result.tool_board, MOUNT, atol=1e-6)
    assert result.rms_px < 1e-6 and np.all(result.used)
    assert np.nanmax(result.view_rms_px) < 1e-6


def test_a_distorted_lens_is_solved_through_its_coefficients() -> None:
    d = np.array([0.08, -0.12, 0.001, -0.0006, 0.03])
    result = solve_eye_to_hand(_views(10, 1, d=d), BOARD.corners, K, d)
    np.testing.assert_allclose(result.world_camera, CAMERA, atol=1e-6)


def test_pixel_noise_gives_a_small_error_within_the_reported_uncertainty() -> None:
    result = solve_eye_to_hand(_views(15, 2, noise_px=0.2), BOARD.corners, K)
    dp, dr = _errors(result)
    assert dp < 1.0 and dr < 0.1
    # The true error is within 4 sigma of the covariance the solver reports.
    assert dp < 4 * result.position_sigma_mm and dr < 4 * result.rotation_sigma_deg
    assert 0.1 < result.rms_px < 0.4
    # Per-view residuals in mm: the px residual at ~0.55 m depth (0.9 mm per px).
    ratio = result.view_rms_mm / result.view_rms_px
    assert np.all((ratio > 0.6) & (ratio < 1.2))


def test_an_outlier_view_is_dropped_and_the_rest_refit() -> None:
    views = _views(12, 3, noise_px=0.1)
    bad = views[4]
    views[4] = View(bad.tool_pose @ _pose(Rotation.from_euler("z", 3, degrees=True)
                                          .as_matrix(), [0.01, 0, 0]), bad.ids, bad.pixels)
    result = solve_eye_to_hand(views, BOARD.corners, K)
    assert not result.used[4] and result.used.sum() == 11
    assert result.view_rms_px[4] > 5.0
    dp, dr = _errors(result)
    assert dp < 1.0 and dr < 0.1


def test_too_few_views_with_the_board_are_refused() -> None:
    views = _views(8, 4)
    for n in range(4):
        views[n] = View(views[n].tool_pose, views[n].ids[:3], views[n].pixels[:3])
    with pytest.raises(CalibrationRefused, match=r"board seen in 4 of 8 poses") as err:
        solve_eye_to_hand(views, BOARD.corners, K)
    assert err.value.kind == "board"


@pytest.mark.parametrize("axes, spread", [("xyz", 0.0), ("z", 25.0)],
                         ids=["pure-translations", "one-rotation-axis"])
def test_a_degenerate_pose_set_is_refused_with_the_reason(axes: str, spread: float) -> None:
    views = _views(10, 5, spread_deg=spread, axes=axes)
    with pytest.raises(CalibrationRefused, match=r"degenerate pose set: tool rotation spread "
                       r".* cannot separate the camera pose") as err:
        solve_eye_to_hand(views, BOARD.corners, K)
    assert err.value.kind == "degenerate"
    assert len(str(err.value).splitlines()) == 1


def test_residuals_above_the_bound_are_refused() -> None:
    views = _views(10, 6)
    wrong_k = K.copy()
    wrong_k[0, 0] = wrong_k[1, 1] = 640.0  # a wrong focal length cannot be fit away
    with pytest.raises(CalibrationRefused, match=r"residual .* px RMS .* above the bound") as err:
        solve_eye_to_hand(views, BOARD.corners, wrong_k, config=SolveConfig(max_rms_px=0.2))
    assert err.value.kind == "residual"


def test_malformed_views_are_a_clear_error() -> None:
    views = _views(6, 7)
    views[2] = View(views[2].tool_pose, views[2].ids + 100, views[2].pixels)
    with pytest.raises(ValueError, match=r"view 2: corner ids must be unique"):
        solve_eye_to_hand(views, BOARD.corners, K)


def test_the_rotation_spread_of_one_axis_has_no_second_axis() -> None:
    r = Rotation.from_euler("z", np.linspace(-20, 20, 9)[:, None], degrees=True).as_matrix()
    spread = rotation_spread_deg(r)
    assert spread[0] > 10 and spread[1] < 1e-9
