"""Perception training data: procedural shapes, depth encoding, reproducible shards."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from push_core.geometry import closest_point_on_polyline, object_to_world
from push_core.objects import TEST_OBJECTS, library_names, object_from_dict
from pushbot.experiments.perception_data import (
    SHAPE_KINDS,
    DataConfig,
    decode_depth,
    encode_depth,
    generate,
    generate_shard,
    iter_samples,
    random_shape,
    training_objects,
)
from sim_bridge.camera import deproject

SMALL = {"width": 160, "height": 120}


def test_training_objects_hold_out_the_test_objects() -> None:
    names = training_objects()
    assert not set(names) & set(TEST_OBJECTS)
    assert set(names) | set(TEST_OBJECTS) == set(library_names())


@pytest.mark.parametrize("kind", SHAPE_KINDS)
def test_random_shapes_are_valid_specs_of_the_right_size(kind: str) -> None:
    rng = np.random.default_rng(7)
    convex = []
    for _ in range(30):
        spec = object_from_dict(random_shape(rng, kind))
        extent = np.ptp(spec.polyline(), axis=0).max()
        assert 0.049 <= extent <= 0.181
        assert 0.005 <= spec.thickness <= 0.025
        convex.append(spec.shape.is_convex)
    if kind in ("convex", "ellipse"):
        assert all(convex)
    else:  # the non-convex families really are non-convex (most of the time)
        assert sum(convex) < 10


def test_random_shape_rejects_unknown_kind() -> None:
    with pytest.raises(ValueError, match="kind"):
        random_shape(np.random.default_rng(0), "torus")


def test_depth_encoding_round_trip() -> None:
    depth = np.array([[0.5, np.nan], [0.81234, 6.5]], dtype=np.float32)
    back = decode_depth(encode_depth(depth))
    assert np.isnan(back[0, 1])
    np.testing.assert_allclose(back[[0, 1, 1], [0, 0, 1]], [0.5, 0.8123, 6.5], atol=6e-5)
    with pytest.raises(ValueError, match="depth"):
        encode_depth(np.array([7.0]))


def test_config_validation() -> None:
    with pytest.raises(ValueError, match="n:"):
        DataConfig(n=0)
    with pytest.raises(ValueError, match="pusher_near"):
        DataConfig(n=1, pusher_near=0.8, pusher_elsewhere=0.4)
    assert DataConfig(n=250, shard_size=100).shard_length(2) == 50


def test_shard_is_reproducible_and_matches_its_ground_truth(tmp_path: Path) -> None:
    cfg = DataConfig(n=6, seed=3, shard_size=6, poses_per_scene=2, library_fraction=0.5,
                     pusher_near=0.5, **SMALL)
    a = generate_shard(cfg, 0, tmp_path)
    b = generate_shard(cfg, 0, tmp_path)
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert a["rgb"].shape == (6, 120, 160, 3) and a["depth"].dtype == np.uint16
    assert not set(a["object"].tolist()) & set(TEST_OBJECTS)
    other = generate_shard(DataConfig(**{**cfg.__dict__, "seed": 4}), 0, tmp_path)
    assert not np.array_equal(other["rgb"], a["rgb"])
    # Every object pixel deprojects onto the object: inside its outline at the recorded pose
    # (within a pixel's footprint of about 5 mm at this resolution) and below its top face.
    off = a["outline_offsets"]
    checked = 0
    for i in range(6):
        mask = a["mask"][i] & (a["depth"][i] > 0)
        if mask.sum() < 20:
            continue
        depth = decode_depth(a["depth"][i])
        pts = deproject(depth, a["camera_matrix"][i], a["T_world_camera"][i],
                        np.argwhere(mask))
        outline = object_to_world(a["pose"][i], a["outline_points"][off[i]:off[i + 1]])
        _, _, dist, _ = closest_point_on_polyline(outline, pts[:, :2])
        assert np.quantile(dist, 0.99) < 0.005
        assert np.all(pts[:, 2] < a["thickness"][i] + 0.005)
        checked += 1
    assert checked >= 3


def test_generate_writes_shards_resumes_and_refuses_another_config(tmp_path: Path) -> None:
    cfg = DataConfig(n=3, seed=1, shard_size=2, poses_per_scene=2, **SMALL)
    generate(cfg, tmp_path, progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "meta.json", "shard_00000.npz", "shard_00001.npz"]
    meta = json.loads((tmp_path / "meta.json").read_text())
    assert meta["config"]["n"] == 3 and meta["held_out"] == list(TEST_OBJECTS)
    samples = list(iter_samples(tmp_path))
    assert len(samples) == 3
    assert samples[0].rgb.shape == (120, 160, 3) and samples[0].depth.dtype == np.float32
    assert samples[0].outline_points.shape == samples[0].outline_normals.shape
    stamp = (tmp_path / "shard_00000.npz").stat().st_mtime_ns
    generate(cfg, tmp_path, progress=False)  # resumes: nothing to do
    assert (tmp_path / "shard_00000.npz").stat().st_mtime_ns == stamp
    with pytest.raises(ValueError, match="another configuration"):
        generate(DataConfig(n=4, seed=1, shard_size=2, **SMALL), tmp_path, progress=False)
