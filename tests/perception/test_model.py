"""The segmentation CNN: input preparation, stage alignment, BN folding, loading, and the whole
pipeline (CNN + geometry) on rendered frames of the held-out objects."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from push_core.geometry import closest_point_on_polyline, object_to_world
from push_core.objects import TEST_OBJECTS
from push_perception.model import (
    HEIGHT_SCALE,
    HeightMap,
    SegmentationNet,
    Segmenter,
    crop_grid,
    normalise_inputs,
)
from push_perception.tracker import EpisodeTracker
from sim_bridge.camera import deproject


def test_height_map_is_world_z_of_the_deprojected_pixel() -> None:
    rng = np.random.default_rng(0)
    k = np.array([[300.0, 0.0, 15.5], [0.0, 310.0, 11.5], [0.0, 0.0, 1.0]])
    angle = 1.0
    t = np.eye(4)
    t[:3, :3] = [[1, 0, 0], [0, -math.cos(angle), math.sin(angle)],
                 [0, -math.sin(angle), -math.cos(angle)]]
    t[:3, 3] = [0.1, -0.4, 0.7]
    depth = rng.uniform(0.5, 1.0, (24, 32)).astype(np.float32)
    depth[3, 4] = np.nan
    height = HeightMap()(depth, k, t)
    expected = deproject(depth, k, t)[..., 2]
    np.testing.assert_allclose(height, expected, atol=1e-5, equal_nan=True)
    assert np.isnan(height[3, 4])


def test_normalise_inputs_scales_colour_and_height() -> None:
    rgb = np.array([[[0, 255, 51]]], dtype=np.uint8)
    x = normalise_inputs(rgb, np.array([[np.nan]]))
    np.testing.assert_allclose(x[:, 0, 0], [-0.5, 0.5, -0.3, 0.0], atol=1e-6)
    x = normalise_inputs(rgb, np.array([[0.013]]))
    assert x[3, 0, 0] == pytest.approx(0.013 / HEIGHT_SCALE)
    assert normalise_inputs(rgb, np.array([[1.0]]))[3, 0, 0] == 4.0  # clipped


def test_crop_grid_lines_coarse_cells_up_with_full_resolution_pixels() -> None:
    # A ramp I(u) = u averaged over 4 x 4 blocks and sampled back at the pixel centres of a
    # crop gives I(u) exactly (away from the image border): the stages share coordinates.
    w, h = 64, 48
    ramp = torch.arange(w, dtype=torch.float64).expand(h, w)[None, None]
    coarse = F.avg_pool2d(ramp, 4)
    box = (10, 5, 30, 21)
    sampled = F.grid_sample(coarse, crop_grid(box, (w, h), torch.float64), mode="bilinear",
                            padding_mode="border", align_corners=False)
    assert sampled.shape == (1, 1, 16, 20)
    np.testing.assert_allclose(sampled[0, 0].numpy(), ramp[0, 0, 5:21, 10:30].numpy(),
                               atol=1e-9)


def test_fused_network_equals_the_batchnorm_network() -> None:
    torch.manual_seed(0)
    net = SegmentationNet()
    for m in net.modules():  # non-trivial running statistics and affine parameters
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-0.5, 0.5)
            m.running_var.uniform_(0.5, 2.0)
            m.weight.data.uniform_(0.5, 1.5)
            m.bias.data.uniform_(-0.2, 0.2)
    net.eval()
    fused = net.fused()
    assert not any(isinstance(m, torch.nn.BatchNorm2d) for m in fused.modules())
    x = torch.randn(2, 4, 24, 32)
    xf = torch.randn(2, 5, 20, 28)
    with torch.no_grad():
        torch.testing.assert_close(fused.coarse(x), net.coarse(x), atol=1e-5, rtol=1e-5)
        torch.testing.assert_close(fused.fine(xf), net.fine(xf), atol=1e-5, rtol=1e-5)


def test_load_rejects_missing_and_foreign_files(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="do not exist"):
        Segmenter.load(tmp_path / "nothing.pt")
    bad = tmp_path / "bad.pt"
    torch.save({"state_dict": {"x": torch.zeros(1)}}, bad)
    with pytest.raises(ValueError, match="not a segmentation network"):
        Segmenter.load(bad)
    with pytest.raises(ValueError, match="threshold"):
        Segmenter(SegmentationNet(), threshold=1.0)


# --------------------------------------------------------------------------------------------
# The bundled network on the held-out objects
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def segmenter() -> Segmenter:
    torch.set_num_threads(1)
    return Segmenter.load()


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return np.count_nonzero(a & b) / max(np.count_nonzero(a | b), 1)


@pytest.mark.parametrize("obj", TEST_OBJECTS)
def test_pipeline_on_rendered_frames_of_held_out_objects(
        obj: str, segmenter: Segmenter, world_factory: Callable[..., Any]) -> None:
    """CNN mask, pose, relative orientation and outline against the rendered ground truth,
    with the randomised appearance, camera jitter and depth noise of training."""
    world = world_factory(object=obj, object_pose=(0.05, -0.08, 0.7), seed=11,
                          randomize_appearance=True, randomize_camera=True, depth_noise=True)
    tracker = EpisodeTracker()
    first = world.render()
    seg = segmenter(first.rgb, first.depth, first.camera_matrix, first.T_world_camera)
    assert _iou(seg.mask, first.mask) > 0.93
    meas = tracker.update(seg.mask, first.depth, first.camera_matrix, first.T_world_camera)
    assert np.linalg.norm(meas.pose[:2] - first.object_pose[:2]) < 0.003
    points, normals = tracker.outline
    truth = object_to_world(first.object_pose, world.object_spec.polyline())
    _, true_normals, dist, _ = closest_point_on_polyline(truth, points + meas.pose[:2])
    assert np.median(np.abs(dist)) < 0.002
    angles = np.degrees(np.arccos(np.clip(np.sum(true_normals * normals, axis=1), -1, 1)))
    assert np.median(angles) < 10.0
    world.set_object_pose(first.object_pose + [-0.1, 0.12, 0.35])
    second = world.render()
    seg = segmenter(second.rgb, second.depth, second.camera_matrix, second.T_world_camera)
    assert _iou(seg.mask, second.mask) > 0.93
    meas = tracker.update(seg.mask, second.depth, second.camera_matrix, second.T_world_camera)
    assert np.linalg.norm(meas.pose[:2] - second.object_pose[:2]) < 0.003
    turn = second.object_pose[2] - first.object_pose[2]
    assert abs(math.degrees(math.remainder(meas.pose[2] - turn, 2 * math.pi))) < 2.0


def test_empty_scene_gives_an_empty_mask(segmenter: Segmenter,
                                         world_factory: Callable[..., Any]) -> None:
    world = world_factory(object="hex")
    world.set_object_pose((1.4, 0.0, 0.0))  # behind the camera
    frame = world.render()
    seg = segmenter(frame.rgb, frame.depth, frame.camera_matrix, frame.T_world_camera)
    assert seg.box is None and not seg.mask.any() and seg.coarse_pixels == 0
