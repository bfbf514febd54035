"""push_perception.depth_segmentation: the object from depth alone on synthetic and rendered
frames, the tall things and the robot's pixels left out, and the CNN's fallback to it."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from push_perception.depth_segmentation import (
    DepthSegmentationConfig,
    DepthSegmenter,
    FallbackSegmenter,
)
from push_perception.model import Segmenter

SQUARE = np.array([[-0.03, -0.03], [0.03, -0.03], [0.03, 0.03], [-0.03, 0.03]])


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return np.count_nonzero(a & b) / np.count_nonzero(a | b)


def test_a_plate_on_a_tilted_table_is_found_whole(make_frame: Callable[..., Any]) -> None:
    f = make_frame(SQUARE, np.array([0.05, -0.02, 0.3]), thickness=0.005)
    rgb = np.zeros((*f.depth.shape, 3), np.uint8)
    # the table 4 mm higher on one side than on the other (an extrinsic slightly off)
    ramp = np.linspace(-0.002, 0.002, f.depth.shape[1], dtype=np.float32)[None, :]
    seg = DepthSegmenter()(rgb, f.depth - ramp, f.camera_matrix, f.T_world_camera)
    assert seg.box is not None and _iou(seg.mask, f.mask) > 0.98


def test_nothing_on_the_table_and_things_outside_the_workspace_give_an_empty_mask(
        make_frame: Callable[..., Any]) -> None:
    f = make_frame(SQUARE, np.array([0.0, 0.0, 0.0]))
    rgb = np.zeros((*f.depth.shape, 3), np.uint8)
    table = np.full_like(f.depth, 0.6)
    assert DepthSegmenter()(rgb, table, f.camera_matrix, f.T_world_camera).box is None
    small = DepthSegmenter(DepthSegmentationConfig(workspace=(0.1, 0.2, 0.1, 0.2), margin=0.0))
    assert small(rgb, f.depth, f.camera_matrix, f.T_world_camera).box is None


def test_a_tall_thing_and_the_robots_pixels_are_not_the_object(
        make_frame: Callable[..., Any]) -> None:
    f = make_frame(SQUARE, np.array([0.0, 0.0, 0.0]), thickness=0.013)
    depth = f.depth.copy()
    # a pusher (6 cm tall, 1.5 cm across) 8 mm from the plate's right edge
    pusher = np.zeros_like(f.mask)
    u = int(f.camera_matrix[0, 2] + 600 * 0.05 / 0.6)  # its top 45-52 mm from the centre
    pusher[230:250, u - 8:u + 8] = True
    depth[pusher] = 0.54
    rgb = np.zeros((*depth.shape, 3), np.uint8)
    seg = DepthSegmenter()(rgb, depth, f.camera_matrix, f.T_world_camera)
    assert not np.any(seg.mask & pusher) and _iou(seg.mask, f.mask) > 0.97
    robot = np.zeros_like(f.mask)
    robot[:, 310:330] = True  # an arm link across the plate
    seg = DepthSegmenter()(rgb, f.depth, f.camera_matrix, f.T_world_camera, robot=robot)
    assert not np.any(seg.mask & robot)
    assert _iou(seg.mask, f.mask & ~robot) > 0.97  # both halves, joined across the link


def test_rendered_frames_with_depth_noise(world_factory: Callable[..., Any]) -> None:
    world = world_factory(object="butter", object_pose=(0.1, 0.1, 2.0), depth_noise=True)
    f = world.render()
    seg = DepthSegmenter()(f.rgb, f.depth, f.camera_matrix, f.T_world_camera)
    assert _iou(seg.mask, f.mask) > 0.9


def test_the_cnn_falls_back_to_depth_below_its_confidence(
        world_factory: Callable[..., Any]) -> None:
    world = world_factory(object="butter", object_pose=(0.02, -0.05, 0.4))
    f = world.render()
    cnn = Segmenter.load(None)
    args = (f.rgb, f.depth, f.camera_matrix, f.T_world_camera)
    sure = FallbackSegmenter(cnn, DepthSegmenter(), 0.5)
    assert _iou(sure(*args).mask, f.mask) > 0.95 and sure.last_source == "cnn"
    assert sure.fallbacks == 0 and 0.5 < cnn(*args).confidence <= 1.0
    never_sure = FallbackSegmenter(cnn, DepthSegmenter(), 1.0)
    seg = never_sure(*args)
    assert never_sure.last_source == "depth" and never_sure.fallbacks == 1
    assert seg.confidence == 1.0 and _iou(seg.mask, f.mask) > 0.95
    with pytest.raises(ValueError, match="min_confidence"):
        FallbackSegmenter(cnn, DepthSegmenter(), 1.5)
