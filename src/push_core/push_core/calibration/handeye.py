"""Eye-to-hand calibration: the camera's pose in ``world`` from a board carried by the arm.

The camera is fixed in ``world``; a planar target (a ChArUco board, :mod:`.charuco`) is fixed
on the tool. For each view ``i`` the arm's forward kinematics of the measured joints give the
tool pose ``T_world_tool[i]`` and the camera image gives the pixels of some of the board's
corners. A corner ``p`` (board frame, metres) is seen at

    u = project(K, d, inv(T_world_camera) @ T_world_tool[i] @ T_tool_board @ p)

with two unknown rigid transforms: ``T_world_camera`` (the extrinsics the pipeline needs)
and ``T_tool_board`` (where the board was mounted; nobody measures it to a tenth of a
millimetre). :func:`solve_eye_to_hand` finds both:

1. *Seed*: the board's pose in the camera per view (``cv2.solvePnP``, IPPE for a planar
   target); then ``A_i X = Z B_i`` with ``A_i = T_world_tool[i]``, ``B_i = T_camera_board[i]``,
   ``X = T_tool_board``, ``Z = T_world_camera``. Pairs of views give ``A X = X B`` (with
   ``A = inv(A_i) A_j``, ``B = inv(B_i) B_j``): the rotation axes satisfy ``a = R_X b`` (a
   Kabsch fit over all pairs), the translations ``(R_A - I) t_X = R_X t_B - t_A`` (linear
   least squares); ``Z`` is the chordal mean of ``A_i X inv(B_i)``.
2. *Refinement*: ``scipy.optimize.least_squares`` over the reprojection error of every corner
   of every view (a robust ``soft_l1`` loss, so a few bad corners do not pull the answer),
   the 12 unknowns as rotation-vector increments about the seed and translations.
3. *Outlier views*: a view whose RMS residual exceeds ``max(outlier_px, 3 x median)`` (a
   mis-detection, a view taken while the arm still moved) is dropped and the rest refit.
4. *Uncertainty*: the covariance ``s^2 (J^T J)^-1`` at the solution (``s^2`` the residual
   variance), reported as the 1-sigma of the camera position (mm) and orientation (deg)
   along their worst direction.

Frames: ``world`` (z up), the camera's REP 103 optical frame, the tool frame of the forward
kinematics (the flange), the board frame of :mod:`.charuco` (corners on its z = 0 plane).
Pixels are OpenCV's; the distortion model and coefficient order those of
:mod:`push_core.camera_model`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from push_core.camera_model import distort_normalised

__all__ = [
    "CalibrationRefused",
    "HandEyeResult",
    "SolveConfig",
    "View",
    "rotation_spread_deg",
    "solve_eye_to_hand",
]


class CalibrationRefused(ValueError):
    """The views cannot give a trustworthy calibration; ``kind`` names why, the message is
    one line for the operator.

    ``kind`` is one of ``"board"`` (too few views show enough of the board), ``"degenerate"``
    (the tool poses do not make the unknowns observable) or ``"residual"`` (the fit does not
    explain the images to the bound).
    """

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


@dataclass(frozen=True)
class View:
    """One arm pose and what the camera saw of the board there.

    Attributes
    ----------
    tool_pose : (4, 4) ndarray
        ``T_world_tool``: the tool frame in ``world`` by forward kinematics of the measured
        joints, metres.
    ids : (N,) ndarray of int
        Board corner ids seen (indices into the board's corner array).
    pixels : (N, 2) ndarray of float
        Their image coordinates ``(u, v)``, px, as detected (distorted if the lens is).
    """

    tool_pose: NDArray[np.float64]
    ids: NDArray[np.int64]
    pixels: NDArray[np.float64]


@dataclass(frozen=True)
class SolveConfig:
    """Bounds of :func:`solve_eye_to_hand`.

    Attributes
    ----------
    min_views : int
        Fewest views (each with ``min_corners`` corners) to solve with, after outliers.
    min_corners : int
        Fewest corners for a view to count (solvePnP of a plane needs 4; more averages noise).
    min_spread_deg : float
        Least RMS spread of the tool orientations about their second principal axis,
        degrees: rotations about a single axis (or none, pure translations) leave the
        board's mounting and the camera's pose inseparable.
    outlier_px : float
        A view whose RMS reprojection residual is above ``max(outlier_px, 3 x median)`` px is
        dropped and the rest refit.
    max_rms_px : float
        Refuse when the RMS residual of the kept corners is above this, px.
    loss_scale_px : float
        Scale of the robust ``soft_l1`` loss, px (residuals above it count linearly).
    """

    min_views: int = 6
    min_corners: int = 6
    min_spread_deg: float = 3.0
    outlier_px: float = 2.0
    max_rms_px: float = 1.0
    loss_scale_px: float = 1.0


@dataclass(frozen=True)
class HandEyeResult:
    """A solved eye-to-hand calibration.

    Attributes
    ----------
    world_camera : (4, 4) ndarray
        ``T_world_camera`` of the optical frame, metres.
    tool_board : (4, 4) ndarray
        ``T_tool_board``: the board's mounting on the tool, metres.
    position_sigma_mm : float
        1-sigma of the camera position along its worst direction, mm.
    rotation_sigma_deg : float
        1-sigma of the camera orientation about its worst axis, degrees.
    rms_px : float
        RMS reprojection residual over the kept corners, px.
    view_rms_px : (V,) ndarray
        RMS residual per input view, px (NaN for a view with too few corners).
    view_rms_mm : (V,) ndarray
        The same as a lateral offset at each corner's depth, mm (residual x z / f).
    used : (V,) ndarray of bool
        The views the result was fit to (not too few corners, not an outlier).
    """

    world_camera: NDArray[np.float64]
    tool_board: NDArray[np.float64]
    position_sigma_mm: float
    rotation_sigma_deg: float
    rms_px: float
    view_rms_px: NDArray[np.float64]
    view_rms_mm: NDArray[np.float64]
    used: NDArray[np.bool_]


def _pose(rotation: NDArray[np.float64], translation: ArrayLike) -> NDArray[np.float64]:
    t = np.eye(4)
    t[:3, :3] = rotation
    t[:3, 3] = translation
    return t


def _inverse(t: NDArray[np.float64]) -> NDArray[np.float64]:
    r = t[..., :3, :3]
    out = np.zeros_like(t)
    out[..., :3, :3] = np.swapaxes(r, -1, -2)
    out[..., :3, 3] = -np.einsum("...ji,...j->...i", r, t[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def _project_rotation(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotation nearest ``m`` (3, 3) in the Frobenius norm (the chordal mean's step)."""
    u, _, vt = np.linalg.svd(m)
    return u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt


def rotation_spread_deg(rotations: ArrayLike) -> NDArray[np.float64]:
    """RMS spread of a set of orientations about their three principal axes, degrees.

    Parameters
    ----------
    rotations : (V, 3, 3) array
        Rotation matrices (e.g. of the tool in ``world``).

    Returns
    -------
    (3,) ndarray
        Singular values of the rotation vectors of ``R_mean^T R_i`` over ``sqrt(V)``,
        descending: the second is near zero when all rotations share one axis.
    """
    r = np.asarray(rotations, dtype=np.float64)
    mean = _project_rotation(r.sum(axis=0))
    vectors = Rotation.from_matrix(np.einsum("ji,vjk->vik", mean, r)).as_rotvec()
    return np.degrees(np.linalg.svd(vectors / np.sqrt(len(r)), compute_uv=False))


def _view_pnp(points: NDArray[np.float64], pixels: NDArray[np.float64], k: NDArray[np.float64],
              d: NDArray[np.float64]) -> NDArray[np.float64] | None:
    ok, rvec, tvec = cv2.solvePnP(points, pixels, k, d, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return None
    ok_refined = cv2.solvePnPRefineLM(points, pixels, k, d, rvec, tvec)
    rvec, tvec = ok_refined if isinstance(ok_refined, tuple) else (rvec, tvec)
    return _pose(cv2.Rodrigues(rvec)[0], tvec.ravel())


def _seed(a: NDArray[np.float64], b: NDArray[np.float64]
          ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(Z, X)`` of ``A_i X = Z B_i`` in closed form (module docstring, step 1)."""
    i, j = np.triu_indices(len(a), k=1)
    rel_a = _inverse(a[i]) @ a[j]
    rel_b = _inverse(b[i]) @ b[j]
    axis_a = Rotation.from_matrix(rel_a[:, :3, :3]).as_rotvec()
    axis_b = Rotation.from_matrix(rel_b[:, :3, :3]).as_rotvec()
    r_x = _project_rotation(axis_a.T @ axis_b)
    lhs = (rel_a[:, :3, :3] - np.eye(3)).reshape(-1, 3)
    rhs = (rel_b[:, :3, 3] @ r_x.T - rel_a[:, :3, 3]).reshape(-1)
    t_x = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    x = _pose(r_x, t_x)
    zs = a @ x @ _inverse(b)
    z = _pose(_project_rotation(zs[:, :3, :3].sum(axis=0)), zs[:, :3, 3].mean(axis=0))
    return z, x


class _Problem:
    """The stacked corners of the kept views and their reprojection residuals."""

    def __init__(self, views: Sequence[View], board: NDArray[np.float64], k: NDArray[np.float64],
                 d: NDArray[np.float64]) -> None:
        self.k, self.d = k, d
        self.view = np.concatenate([np.full(len(v.ids), n) for n, v in enumerate(views)])
        self.points = np.concatenate([board[v.ids] for v in views])
        self.pixels = np.concatenate([v.pixels for v in views])
        self.tools = np.stack([v.tool_pose for v in views])

    def camera_points(self, z: NDArray[np.float64], x: NDArray[np.float64]
                      ) -> NDArray[np.float64]:
        chain = _inverse(z)[None] @ self.tools @ x[None]  # camera <- board, per view
        c = chain[self.view]
        return np.einsum("nij,nj->ni", c[:, :3, :3], self.points) + c[:, :3, 3]

    def project(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        z = np.maximum(p[:, 2], 1e-9)
        xd, yd = distort_normalised(p[:, 0] / z, p[:, 1] / z, self.d)
        return np.stack([self.k[0, 0] * xd + self.k[0, 2], self.k[1, 1] * yd + self.k[1, 2]], 1)

    def residuals(self, z: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.project(self.camera_points(z, x)) - self.pixels


def _increment(seed: NDArray[np.float64], params: NDArray[np.float64]) -> NDArray[np.float64]:
    """``seed`` rotated by the world-side rotation vector ``params[:3]`` with translation
    ``params[3:]`` (so the covariance of the parameters is in the pose's parent frame)."""
    return _pose(Rotation.from_rotvec(params[:3]).as_matrix() @ seed[:3, :3], params[3:])


def _refine(problem: _Problem, z0: NDArray[np.float64], x0: NDArray[np.float64],
            config: SolveConfig) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                          NDArray[np.float64]]:
    def fun(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return problem.residuals(_increment(z0, p[:6]), _increment(x0, p[6:])).ravel()

    start = np.concatenate([np.zeros(3), z0[:3, 3], np.zeros(3), x0[:3, 3]])
    fit = least_squares(fun, start, jac="3-point", loss="soft_l1", f_scale=config.loss_scale_px,
                        x_scale=np.array([1.0] * 3 + [0.1] * 3 + [1.0] * 3 + [0.1] * 3),
                        xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)
    p = fit.x
    z, x = _increment(z0, p[:6]), _increment(x0, p[6:])
    # Gauss-Newton covariance re-linearised at the solution with the plain (not robust)
    # residuals: the robust loss only guards the fit against a few bad corners.
    jac = _numeric_jacobian(lambda q: problem.residuals(_increment(z, q[:6]),
                                                        _increment(x, q[6:])).ravel(),
                            np.concatenate([np.zeros(3), z[:3, 3], np.zeros(3), x[:3, 3]]))
    return z, x, jac


def _numeric_jacobian(fun, p: NDArray[np.float64], step: float = 1e-7) -> NDArray[np.float64]:
    cols = []
    for n in range(len(p)):
        dp = np.zeros_like(p)
        dp[n] = step
        cols.append((fun(p + dp) - fun(p - dp)) / (2 * step))
    return np.stack(cols, axis=1)


def _check_observable(jac: NDArray[np.float64]) -> None:
    s = np.linalg.svd(jac, compute_uv=False)
    if s[-1] <= 1e-9 * s[0]:
        raise CalibrationRefused(
            "degenerate", "degenerate pose set: the camera pose and the board's mounting are "
            f"not separable from these views (Jacobian condition {s[0] / max(s[-1], 1e-300):.3g})")


def _per_view(problem: _Problem, z: NDArray[np.float64], x: NDArray[np.float64],
              count: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    p = problem.camera_points(z, x)
    err = np.linalg.norm(problem.project(p) - problem.pixels, axis=1)
    lateral = err * p[:, 2] / np.mean(np.diag(problem.k)[:2])
    n = np.bincount(problem.view, minlength=count).astype(np.float64)
    n[n == 0] = np.nan
    px = np.sqrt(np.bincount(problem.view, err ** 2, count) / n)
    m = np.sqrt(np.bincount(problem.view, lateral ** 2, count) / n)
    return px, m * 1000.0


def _check_views(views: Sequence[View], config: SolveConfig) -> NDArray[np.bool_]:
    enough = np.array([len(v.ids) >= config.min_corners for v in views], dtype=bool)
    if enough.sum() < config.min_views:
        raise CalibrationRefused(
            "board", f"board seen in {int(enough.sum())} of {len(views)} poses (at least "
            f"{config.min_corners} corners each); need {config.min_views}")
    spread = rotation_spread_deg(np.stack([views[n].tool_pose[:3, :3]
                                           for n in np.flatnonzero(enough)]))
    if spread[1] < config.min_spread_deg:
        raise CalibrationRefused(
            "degenerate", f"degenerate pose set: tool rotation spread {spread[0]:.1f} / "
            f"{spread[1]:.1f} deg about its two main axes, need >= {config.min_spread_deg:g} "
            "deg about two axes (pure translations or one rotation axis cannot separate the "
            "camera pose from the board's mounting)")
    return enough


def _as_views(views: Sequence[View], n_corners: int) -> list[View]:
    out = []
    for n, v in enumerate(views):
        tool = np.asarray(v.tool_pose, dtype=np.float64)
        ids = np.asarray(v.ids, dtype=np.int64).ravel()
        px = np.asarray(v.pixels, dtype=np.float64).reshape(-1, 2)
        if tool.shape != (4, 4) or not np.all(np.isfinite(tool)):
            raise ValueError(f"view {n}: tool_pose must be a finite (4, 4) array")
        if len(ids) != len(px) or not np.all(np.isfinite(px)):
            raise ValueError(f"view {n}: {len(ids)} ids and {len(px)} finite pixels must match")
        if len(ids) and (ids.min() < 0 or ids.max() >= n_corners
                         or len(np.unique(ids)) != len(ids)):
            raise ValueError(f"view {n}: corner ids must be unique in [0, {n_corners})")
        out.append(View(tool, ids, px))
    return out


def solve_eye_to_hand(views: Sequence[View], board_points: ArrayLike, k: ArrayLike,
                      d: ArrayLike = (), config: SolveConfig | None = None) -> HandEyeResult:
    """Camera pose in ``world`` and board pose on the tool from arm poses and board corners.

    Parameters
    ----------
    views : sequence of View
        The arm poses and the board corners seen at each (module docstring).
    board_points : (M, 3) array
        Corner positions in the board frame, metres (``ids`` index its rows).
    k : (3, 3) array
        Camera matrix of the colour stream, px.
    d : array, optional
        Its distortion coefficients (OpenCV's order; empty: an ideal pinhole).
    config : SolveConfig, optional
        The bounds (defaults of :class:`SolveConfig`).

    Returns
    -------
    HandEyeResult

    Raises
    ------
    CalibrationRefused
        Too few views see the board, the tool poses are degenerate, or the residual after
        outlier rejection is above ``config.max_rms_px`` (the message says which, one line).
    ValueError
        Malformed input (shapes, non-finite values, corner ids out of range).
    """
    config = config or SolveConfig()
    board = np.asarray(board_points, dtype=np.float64)
    if board.ndim != 2 or board.shape[1] != 3 or not np.all(np.isfinite(board)):
        raise ValueError(f"board_points must be a finite (M, 3) array, got {board.shape}")
    kk = np.asarray(k, dtype=np.float64)
    if kk.shape != (3, 3) or not np.all(np.isfinite(kk)) or kk[0, 0] <= 0 or kk[1, 1] <= 0:
        raise ValueError("k must be a finite (3, 3) camera matrix with positive focal lengths")
    dd = np.asarray(d, dtype=np.float64).ravel()
    views = _as_views(views, len(board))
    enough = _check_views(views, config)
    used = enough.copy()
    seeds = {}
    for n in np.flatnonzero(used):
        pose = _view_pnp(board[views[n].ids], views[n].pixels, kk, dd)
        if pose is None:
            used[n] = False
        else:
            seeds[n] = pose
    z, x = None, None
    while True:
        kept = np.flatnonzero(used)
        if len(kept) < config.min_views:
            raise CalibrationRefused(
                "board", f"{len(kept)} of {len(views)} poses left after dropping outlier "
                f"views (RMS residual above the bound); need {config.min_views}")
        if z is None:
            z, x = _seed(np.stack([views[n].tool_pose for n in kept]),
                         np.stack([seeds[n] for n in kept]))
        problem = _Problem([views[n] for n in kept], board, kk, dd)
        z, x, jac = _refine(problem, z, x, config)
        px, _ = _per_view(problem, z, x, len(kept))
        bound = max(config.outlier_px, 3.0 * float(np.median(px)))
        if not np.any(px > bound):
            break
        used[kept[px > bound]] = False
    _check_observable(jac)
    res = problem.residuals(z, x).ravel()
    rms = float(np.sqrt(np.mean(np.sum(res.reshape(-1, 2) ** 2, axis=1))))
    if rms > config.max_rms_px:
        raise CalibrationRefused(
            "residual", f"residual {rms:.2f} px RMS over {len(kept)} poses is above the "
            f"bound {config.max_rms_px:g} px (a wrong camera matrix, a moving board, or "
            "a bad detection)")
    dof = max(len(res) - jac.shape[1], 1)
    cov = float(res @ res) / dof * np.linalg.pinv(jac.T @ jac)
    view_px, view_mm = _per_view(_Problem(views, board, kk, dd), z, x, len(views))
    view_px[~enough], view_mm[~enough] = np.nan, np.nan
    return HandEyeResult(
        world_camera=z, tool_board=x,
        position_sigma_mm=float(np.sqrt(np.linalg.eigvalsh(cov[3:6, 3:6])[-1]) * 1000.0),
        rotation_sigma_deg=float(np.degrees(np.sqrt(np.linalg.eigvalsh(cov[:3, :3])[-1]))),
        rms_px=rms, view_rms_px=view_px, view_rms_mm=view_mm, used=used)
