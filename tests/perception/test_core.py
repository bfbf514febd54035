"""The ROS-free perception core: deprojection, top-down view, outline, rotation search, tracker."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from push_core.geometry import closest_point_on_polyline, object_to_world
from push_core.objects import load_object
from push_perception.footprint import MAX_RASTER_SIDE, object_points, top_down_view
from push_perception.orientation import rotation_search
from push_perception.outline import MAX_OUTLINE_POINTS, smooth_outline
from push_perception.perception_config import PerceptionConfig, PerceptionError, check_frame_arrays
from push_perception.tracker import EpisodeTracker, pose_covariance

CFG = PerceptionConfig()
#: An asymmetric polygon (object frame, m): a lopsided pentagon about 10 x 7 cm.
LOPSIDED = np.array([[0.05, -0.02], [0.03, 0.035], [-0.02, 0.04], [-0.05, 0.0],
                     [-0.01, -0.035]])


def plate_points(polygon: np.ndarray, pose: np.ndarray, spacing: float = 0.0013,
                 height: float = 0.013) -> np.ndarray:
    """World points where a camera's regular pixel grid (``spacing`` apart on the table,
    fixed in ``world``) hits the top face of a plate of outline ``polygon`` at ``pose``."""
    outline = object_to_world(pose, polygon)
    lo, hi = outline.min(axis=0) - spacing, outline.max(axis=0) + spacing
    gx, gy = np.meshgrid(np.arange(np.floor(lo[0] / spacing), np.ceil(hi[0] / spacing)),
                         np.arange(np.floor(lo[1] / spacing), np.ceil(hi[1] / spacing)))
    pts = spacing * np.stack([gx.ravel(), gy.ravel()], axis=1)
    _, _, dist, _ = closest_point_on_polyline(outline, pts)
    inside = pts[dist < 0]
    return np.column_stack([inside, np.full(len(inside), height)])


# --------------------------------------------------------------------------------------------
# Deprojection and validation
# --------------------------------------------------------------------------------------------
def test_object_points_deprojects_by_hand() -> None:
    k = np.array([[500.0, 0.0, 2.0], [0.0, 400.0, 1.0], [0.0, 0.0, 1.0]])
    # Camera 1 m above the table, optical axis down, image x along world y.
    t = np.array([[0.0, -1.0, 0.0, 0.1], [1.0, 0.0, 0.0, -0.2], [0.0, 0.0, -1.0, 1.0],
                  [0.0, 0.0, 0.0, 1.0]])
    depth = np.full((3, 5), np.nan, dtype=np.float32)
    depth[2, 4] = 0.8  # pixel (u=4, v=2)
    depth[0, 0] = 0.0  # zero depth = no return
    mask = np.zeros((3, 5), dtype=bool)
    mask[2, 4] = mask[0, 0] = mask[1, 1] = True
    points, n_mask = object_points(mask, depth, k, t)
    assert n_mask == 3 and points.shape == (1, 3)
    # optical point: x = (4 - 2) / 500 * 0.8 = 0.0032, y = (2 - 1) / 400 * 0.8 = 0.002, z = 0.8
    # world = R p + t = (-0.002 + 0.1, 0.0032 - 0.2, -0.8 + 1.0)
    np.testing.assert_allclose(points[0], [0.098, -0.1968, 0.2], atol=1e-7)


@pytest.mark.parametrize(("mask", "depth", "k", "t", "match"), [
    (np.zeros(4, bool), np.zeros((2, 2)), np.eye(3), np.eye(4), "2-D"),
    (np.zeros((2, 3), bool), np.zeros((2, 2)), np.eye(3), np.eye(4), "differ in size"),
    (np.zeros((2, 2), bool), np.zeros((2, 2)), np.diag([0.0, 1.0, 1.0]), np.eye(4), "pinhole"),
    (np.zeros((2, 2), bool), np.zeros((2, 2)), np.eye(3), np.diag([2.0, 1.0, 1.0, 1.0]),
     "rigid"),
    (np.zeros((2, 2), bool), np.zeros((2, 2)), np.eye(3), np.full((4, 4), np.nan), "rigid"),
])
def test_check_frame_arrays_names_the_bad_array(mask, depth, k, t, match) -> None:
    with pytest.raises(PerceptionError, match=match) as info:
        check_frame_arrays(mask, depth, k, t)
    assert info.value.kind == "bad_input"


def test_config_validation_names_the_field() -> None:
    with pytest.raises(ValueError, match="resolution"):
        PerceptionConfig(resolution=0.1)
    with pytest.raises(ValueError, match="closing_radius"):
        PerceptionConfig(closing_radius=1.5)


@pytest.mark.parametrize(("values", "field"), [
    ({"resolution": 2e-4}, "resolution"),        # the view falls apart: no pose
    ({"resolution": 5e-3}, "resolution"),        # 2 deg of yaw error
    ({"closing_radius": 0}, "closing_radius"),   # fragmented
    ({"closing_radius": 1}, "closing_radius"),
    ({"resolution": 3e-3, "closing_radius": 5}, "closing_radius"),  # 15 mm: 4.6 mm, 5 deg off
    ({"outline_spacing": 2e-4}, "outline_spacing"),
    ({"min_height": 0.02}, "min_height"),        # above the objects' 13 mm: no points left
])
def test_config_refuses_values_that_break_the_pose(values, field) -> None:
    with pytest.raises(ValueError, match=f"^{field}"):
        PerceptionConfig(**values)


def test_config_accepts_the_measured_ranges() -> None:
    for values in ({"resolution": 5e-4}, {"resolution": 3e-3}, {"closing_radius": 10},
                   {"resolution": 2e-3, "closing_radius": 5}, {"outline_spacing": 5e-4},
                   {"outline_spacing": 0.01}, {"min_height": 0.01}):
        PerceptionConfig(**values)


# --------------------------------------------------------------------------------------------
# Top-down view and outline
# --------------------------------------------------------------------------------------------
def test_top_down_view_of_a_rectangle() -> None:
    rect = np.array([[-0.03, -0.02], [0.03, -0.02], [0.03, 0.02], [-0.03, 0.02]])
    pose = np.array([0.0123, -0.0456, 0.0])
    pts = plate_points(rect, pose)
    # Table points at the boundary and a few stray low points must not matter.
    table = np.array([[pose[0] + 0.035, pose[1], 0.001]])
    view = top_down_view(np.vstack([pts, table]), CFG)
    np.testing.assert_allclose(view.centroid, pose[:2], atol=4e-4)
    assert view.area == pytest.approx(0.06 * 0.04, rel=0.05)
    assert view.radius_of_gyration == pytest.approx(math.sqrt((0.06**2 + 0.04**2) / 12),
                                                    rel=0.03)
    x, y = view.boundary[:, 0], view.boundary[:, 1]
    assert np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y) > 0  # counter-clockwise
    # SDF: zero on the true boundary (half a cell of quantisation), negative inside.
    assert view.sample_sdf(pose[:2] + np.array([[0.0, 0.0]]), 1.0)[0] < -0.015
    edge = view.sample_sdf(pose[:2] + np.array([[0.03, 0.0], [0.0, 0.02]]), 1.0)
    np.testing.assert_allclose(edge, 0.0, atol=1e-3)


def test_top_down_view_without_object_points_raises() -> None:
    with pytest.raises(PerceptionError, match="above the table") as info:
        top_down_view(np.array([[0.0, 0.0, 0.001], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0]]), CFG)
    assert info.value.kind == "few_pixels"


@pytest.mark.parametrize("far", [100.0, 1e23])
def test_absurd_extent_is_refused_before_the_raster_is_allocated(far: float) -> None:
    # A few points 100 m apart would need a 100 000-cell raster side; 1e23 m is beyond what
    # float64 resolves in millimetres.
    pts = plate_points(LOPSIDED, np.zeros(3))
    pts = np.vstack([pts, [[far, far, 0.013]]]) if far < 1e3 else pts + [far, 0.0, 0.0]
    with pytest.raises(PerceptionError, match="m") as info:
        top_down_view(pts, CFG)
    assert info.value.kind == "too_large"
    assert str(MAX_RASTER_SIDE) in str(info.value) or "origin" in str(info.value)


def test_smooth_outline_of_a_rasterised_circle() -> None:
    # The boundary cells of a disc of radius 40 mm on a 1 mm grid (cell centres, like
    # top_down_view's boundary): smoothing plus the half-cell offset recovers the circle.
    r, res = 0.04, 0.001
    centres = (np.arange(100) - 50.0) * res
    img = (np.hypot(*np.meshgrid(centres, centres)) <= r).astype(np.uint8)  # cell centres in
    contour = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)[0][0][:, 0]
    boundary = (contour[::-1] - 50.0) * res  # cell centres about the disc's centre, CCW, m
    points, normals = smooth_outline(boundary, 0.002, 0.003, 0.5 * res)
    assert len(points) == pytest.approx(2 * np.pi * r / 0.002, abs=2)
    radius = np.linalg.norm(points, axis=1)
    np.testing.assert_allclose(radius, r, atol=4e-4)  # the staircase: +-half a cell
    assert abs(radius.mean() - r) < 1e-4
    radial = points / np.linalg.norm(points, axis=1, keepdims=True)
    errors = np.degrees(np.arccos(np.clip(np.sum(radial * normals, 1), -1, 1)))
    assert np.median(errors) < 1.0 and errors.max() < 2.5
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    angle = np.unwrap(np.arctan2(points[:, 1], points[:, 0]))
    assert np.all(np.diff(angle) > 0)  # counter-clockwise
    gaps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    np.testing.assert_allclose(gaps, 0.002, rtol=0.1)


# --------------------------------------------------------------------------------------------
# Rotation search
# --------------------------------------------------------------------------------------------
def _views(polygon: np.ndarray, pose: np.ndarray):
    view = top_down_view(plate_points(polygon, pose), CFG)
    pts, _ = smooth_outline(view.boundary, CFG.outline_spacing, CFG.outline_smoothing,
                            0.5 * CFG.resolution)
    return view, pts


@pytest.mark.parametrize("turn_deg", [-170.0, -45.0, 0.0, 7.5, 90.0, 179.0])
def test_rotation_search_recovers_known_rotations(turn_deg: float) -> None:
    ref, ref_pts = _views(LOPSIDED, np.array([0.01, 0.02, 0.3]))
    turn = math.radians(turn_deg)
    cur, cur_pts = _views(LOPSIDED, np.array([-0.05, 0.04, 0.3 + turn]))
    result = rotation_search(ref, ref_pts, cur, cur_pts, 0.0, CFG)
    err = (result.theta - turn + math.pi) % (2 * math.pi) - math.pi
    # The 1 mm top-down raster of a 1.3 mm sampling limits the precision to a few tenths of a
    # degree for a 10 cm object (rendered frames: docs/results/eval_perception.md).
    assert abs(math.degrees(err)) < 0.5
    assert len(result.candidates) == 1  # asymmetric: one answer
    assert result.cost < 1e-3


def test_symmetric_object_orientation_stays_continuous(make_frame) -> None:
    hexagon = load_object("hex").polyline()
    tracker = EpisodeTracker()
    # 25 degrees per frame (less than half the 60 degree symmetry) through one and a half
    # turns: every frame has six equally good answers; the one closest to the previous frame's
    # is the true, continuous angle.
    truth = np.radians(np.arange(0.0, 541.0, 25.0))
    out = []
    for turn in truth:
        f = make_frame(hexagon, np.array([0.02, -0.01, 0.4 + turn]))
        meas = tracker.update(f.mask, f.depth, f.camera_matrix, f.T_world_camera)
        out.append(meas.pose[2])
        assert meas.candidates == (1 if meas.is_reference else 6)
    np.testing.assert_allclose(np.degrees(out), np.degrees(truth), atol=1.0)


def test_disc_orientation_is_reported_as_not_observed(make_frame) -> None:
    # ellip1 (a disc of 52.5 mm) crashed the rotation search (cv2.remap SHRT_MAX) and had no
    # orientation to find: it is reported with the unobserved variance, the position still
    # measured to sub-millimetre accuracy.
    disc = load_object("ellip1").polyline()
    tracker = EpisodeTracker()
    for k, pose in enumerate(([0.0, 0.0, 0.0], [0.03, -0.02, 0.7], [-0.04, 0.01, 2.0])):
        f = make_frame(disc, np.array(pose))
        meas = tracker.update(f.mask, f.depth, f.camera_matrix, f.T_world_camera)
        assert not meas.orientation_observed and not tracker.orientation_observable
        assert meas.covariance[2, 2] == 1e6 and meas.pose[2] == 0.0
        assert meas.covariance[0, 0] < 1e-6
        assert math.hypot(*(meas.pose[:2] - pose[:2])) < 1e-3, k


def test_sample_sdf_reads_more_points_than_one_remap_takes(make_frame) -> None:
    # One cv2.remap call takes fewer than 32767 rows: 100 000 points at once give the
    # same values as point by point.
    f = make_frame(LOPSIDED, np.array([0.0, 0.0, 0.3]))
    tracker = EpisodeTracker()
    tracker.update(f.mask, f.depth, f.camera_matrix, f.T_world_camera)
    view = tracker.reference
    rng = np.random.default_rng(0)
    pts = view.centroid + rng.uniform(-0.08, 0.08, (50_000, 2, 2))
    got = view.sample_sdf(pts, 0.005)
    assert got.shape == (50_000, 2)
    few = np.array([view.sample_sdf(pts[i], 0.005) for i in (0, 12_345, 49_999)])
    np.testing.assert_array_equal(got[[0, 12_345, 49_999]], few)


# --------------------------------------------------------------------------------------------
# The tracker
# --------------------------------------------------------------------------------------------
def test_a_long_outline_is_capped_and_the_rotation_search_still_works(make_frame) -> None:
    # A 40 x 30 cm object at 0.5 mm spacing would have ~2400 outline points (more than 820
    # once crashed cv2.remap in the coarse search); it gets MAX_OUTLINE_POINTS, evenly spread.
    big = 4.0 * LOPSIDED
    cfg = PerceptionConfig(outline_spacing=5e-4)
    tracker = EpisodeTracker(cfg)
    f0 = make_frame(big, np.array([0.0, 0.0, 0.0]))
    tracker.update(f0.mask, f0.depth, f0.camera_matrix, f0.T_world_camera)
    points, normals = tracker.outline
    assert len(points) == MAX_OUTLINE_POINTS and normals.shape == points.shape
    gaps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    assert gaps.max() < 1.5 * np.median(gaps)
    f1 = make_frame(big, np.array([0.01, -0.01, 0.2]))
    meas = tracker.update(f1.mask, f1.depth, f1.camera_matrix, f1.T_world_camera)
    assert meas.pose[2] == pytest.approx(0.2, abs=math.radians(0.5))


def test_tracker_measures_pose_and_outline_in_the_object_frame(make_frame) -> None:
    tracker = EpisodeTracker()
    pose0 = np.array([0.03, 0.05, 1.0])
    f = make_frame(LOPSIDED, pose0)
    first = tracker.update(f.mask, f.depth, f.camera_matrix, f.T_world_camera)
    assert first.is_reference and first.pose[2] == 0.0
    # LOPSIDED's vertices are not centred on its area centroid, the object frame origin.
    centroid = object_to_world(pose0, load_centroid(LOPSIDED))
    np.testing.assert_allclose(first.pose[:2], centroid, atol=4e-4)
    points, normals = tracker.outline
    # The outline, in the object frame (origin at the centroid, axes = world axes at the
    # first frame), lies on the true outline.
    truth = object_to_world(np.array([0.0, 0.0, pose0[2]]),
                            LOPSIDED - load_centroid(LOPSIDED))
    _, true_normals, dist, _ = closest_point_on_polyline(truth, points)
    assert np.median(np.abs(dist)) < 5e-4
    angles = np.degrees(np.arccos(np.clip(np.sum(true_normals * normals, axis=1), -1, 1)))
    assert np.median(angles) < 3.0
    second = tracker.update(*_args(make_frame(LOPSIDED, pose0 + [-0.04, 0.01, -0.6])))
    assert not second.is_reference and second.candidates == 1
    assert second.pose[2] == pytest.approx(-0.6, abs=math.radians(0.3))
    assert tracker.outline[0] is points  # computed once per episode
    tracker.reset()
    third = tracker.update(*_args(make_frame(LOPSIDED, pose0 + [-0.04, 0.01, -0.6])))
    assert third.is_reference and third.pose[2] == 0.0


def load_centroid(polygon: np.ndarray) -> np.ndarray:
    from push_core.shapes import Polygon

    return Polygon(polygon).centroid


def _args(frame) -> tuple:
    return frame.mask, frame.depth, frame.camera_matrix, frame.T_world_camera


def test_tracker_rejects_frames_without_a_measurable_object(make_frame) -> None:
    tracker = EpisodeTracker()
    good = make_frame(LOPSIDED, np.array([0.0, 0.0, 0.0]))
    cases = {
        "empty_mask": (np.zeros_like(good.mask), good.depth),
        "no_depth": (good.mask, np.where(good.mask, np.nan, good.depth).astype(np.float32)),
    }
    # Object across the image border (the right edge is at x = 0.31 m on the top face).
    border = make_frame(LOPSIDED, np.array([0.3, 0.0, 0.0]))
    cases["out_of_view"] = (border.mask, border.depth)
    tiny = make_frame(LOPSIDED * 0.05, np.array([0.0, 0.0, 0.0]))
    cases["few_pixels"] = (tiny.mask, tiny.depth)
    for kind, (mask, depth) in cases.items():
        with pytest.raises(PerceptionError) as info:
            tracker.update(mask, depth, good.camera_matrix, good.T_world_camera)
        assert info.value.kind == kind, str(info.value)
        assert tracker.outline is None  # nothing changed
    assert tracker.update(*_args(good)).is_reference


def test_covariance_grows_with_worse_evidence() -> None:
    def sigmas(**kw):
        args = {"n_valid": 5000, "valid_fraction": 1.0, "area_mismatch": 0.0,
                "match_cost": 0.0, "reference_area": 0.01, "radius_of_gyration": 0.03, **kw}
        return np.sqrt(np.diag(pose_covariance(cfg=CFG, **args)))

    base = sigmas()
    np.testing.assert_allclose(base, [CFG.sigma_position, CFG.sigma_position, CFG.sigma_theta])
    for worse in (sigmas(n_valid=500), sigmas(valid_fraction=0.5), sigmas(area_mismatch=0.2),
                  sigmas(match_cost=0.002)):
        assert np.all(worse >= base) and np.any(worse > base * 1.5)
    np.testing.assert_allclose(sigmas(n_valid=1250), 2 * base)
    # The residual a correct match leaves (below the floor) does not widen the yaw.
    np.testing.assert_allclose(sigmas(match_cost=0.9 * CFG.match_cost_floor), base)


@pytest.mark.parametrize("name, stale_deg", [("tri1", 12.0), ("hex", -20.0), ("butter", 25.0)])
def test_an_anchored_tracker_continues_the_episode_frame(make_frame, name: str,
                                                         stale_deg: float) -> None:
    # A restarted perception: a new tracker anchored to the episode's outline and a
    # stale yaw estimate (a push has turned the object since) reports the yaws the first
    # tracker reports, in the episode frame, and keeps the episode's outline.
    poly = load_object(name).polyline()
    pose0 = np.array([0.01, -0.02, 0.3])
    first = EpisodeTracker()
    first.update(*_args(make_frame(poly, pose0)))
    turns = [0.5, 0.8, 1.1]  # steps below half of hex's 60 degree symmetry
    expected = [first.update(*_args(make_frame(poly, pose0 + [0.02 * k, 0.01, t]))).pose[2]
                for k, t in enumerate(turns)]
    second = EpisodeTracker()
    points, normals = first.outline
    second.anchor(points, normals, yaw=turns[0] - math.radians(stale_deg))
    assert second.anchored and second.outline is None
    got = []
    for k, t in enumerate(turns):
        meas = second.update(*_args(make_frame(poly, pose0 + [0.02 * k, 0.01, t])))
        assert meas.is_reference == meas.anchored == (k == 0)
        got.append(meas.pose[2])
    np.testing.assert_allclose(got, expected, atol=math.radians(0.5))
    np.testing.assert_allclose(got, turns, atol=math.radians(1.0))
    np.testing.assert_array_equal(second.outline[0], points)
    assert not second.anchored


def test_an_anchor_of_another_object_is_dropped(make_frame) -> None:
    first = EpisodeTracker()
    first.update(*_args(make_frame(load_object("tri1").polyline(), np.zeros(3))))
    second = EpisodeTracker()
    second.anchor(*first.outline, yaw=0.2)
    meas = second.update(*_args(make_frame(LOPSIDED, np.array([0.0, 0.0, 0.7]))))
    assert meas.is_reference and not meas.anchored and meas.pose[2] == 0.0
    with pytest.raises(ValueError, match="finite"):
        second.anchor(*first.outline, yaw=math.nan)


def test_an_anchored_disc_keeps_the_anchor_yaw(make_frame) -> None:
    disc = load_object("ellip1").polyline()
    first = EpisodeTracker()
    first.update(*_args(make_frame(disc, np.zeros(3))))
    second = EpisodeTracker()
    second.anchor(*first.outline, yaw=0.25)
    for pose in ([0.01, 0.0, 0.0], [0.03, -0.02, 0.7]):
        meas = second.update(*_args(make_frame(disc, np.array(pose))))
        assert meas.pose[2] == 0.25 and not meas.orientation_observed
        assert math.hypot(*(meas.pose[:2] - pose[:2])) < 1e-3
