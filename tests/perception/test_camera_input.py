"""Driver-shaped frames (sim_bridge's camera profiles: distortion, own depth frame, noise,
resolutions) made the ideal aligned frame by push_perception.camera_input, then segmented and
measured as the node does: the pose stays that of the ideal camera's."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from push_perception.camera_input import CameraModel, FrameRectifier
from push_perception.model import Segmenter
from push_perception.perception_config import PerceptionConfig
from push_perception.tracker import EpisodeTracker
from sim_bridge.camera_profiles import PROFILES, driver_frame

POSE = (0.12, 0.2, 0.7)  # off-centre, where the lenses bend most


@pytest.fixture(scope="module")
def segmenter() -> Segmenter:
    return Segmenter.load(None)


def _measure(segmenter: Segmenter, rgb: np.ndarray, depth: np.ndarray, k: np.ndarray,
             t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    seg = segmenter(rgb, depth, k, t)
    return seg.mask, EpisodeTracker(PerceptionConfig()).update(seg.mask, depth, k, t).pose


@pytest.mark.parametrize("name", ["d415", "d435", "orbbec", "zed"])
def test_a_profiles_frame_measures_as_the_ideal_camera(
        name: str, world_factory: Callable[..., Any], segmenter: Segmenter) -> None:
    prof = PROFILES[name]
    world = world_factory(object="butter", object_pose=POSE, camera=prof.camera_config())
    f = world.render()
    sent = driver_frame(prof, f.rgb, f.clean_depth, f.camera_matrix, np.random.default_rng(7))
    assert sent.rgb.shape[:2] == (prof.height, prof.width)
    color = CameraModel(f.camera_matrix, np.asarray(prof.distortion), (prof.width, prof.height))
    own = None if sent.depth_k is None else CameraModel(sent.depth_k, np.zeros(5),
                                                        sent.depth.shape[::-1])
    rectifier = FrameRectifier(prof.t_color_depth())
    rgb, depth = rectifier.color(sent.rgb, color), rectifier.depth(sent.depth, color, own)
    mask, pose = _measure(segmenter, rgb, depth, f.camera_matrix, f.T_world_camera)
    iou = np.count_nonzero(mask & f.mask) / np.count_nonzero(mask | f.mask)
    assert iou > 0.95
    assert np.linalg.norm(pose[:2] - f.object_pose[:2]) < 0.0025  # noisy depth: one frame
