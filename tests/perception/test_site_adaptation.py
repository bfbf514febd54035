"""Record -> train on a tiny site data set, in-process: frames of the simulator's site look
labelled by SiteLabeller, written by SiteWriter, fine-tuned from the bundled weights."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from push_perception.site_labels import LabelRule, SiteLabeller, mask_iou
from pushbot.experiments import perception_training
from pushbot.experiments.site_record import SiteWriter
from sim_bridge.rendering import still_frame
from sim_bridge.world import PushWorld, WorldConfig


def _record(out: Path) -> tuple[SiteLabeller, list[float]]:
    rule = LabelRule(window=3)
    labeller = SiteLabeller(rule)
    writer = SiteWriter(out, rule, {"test": True})
    ious = []
    with PushWorld(WorldConfig(object="rect1", look="site", seed=1, depth_noise=True,
                               camera=WorldConfig().camera)) as world:
        for scene, (obj, pose) in enumerate((("rect1", (0.03, 0.02, 0.3)),
                                             ("ellip2", (-0.05, 0.04, -1.0)))):
            world.reset(WorldConfig(object=obj, look="site", seed=scene, depth_noise=True,
                                    object_pose=pose))
            first = world.render()
            rng = np.random.default_rng(scene)
            for k in range(3):
                f = first if k == 0 else still_frame(first, True, 2.0, rng)
                kept = labeller.add(f.rgb, f.depth, f.camera_matrix, f.T_world_camera,
                                    10.0 * scene + k)
                ious += [mask_iou(x.mask, first.mask) for x in kept]
                writer.add(kept)
    labeller.finish()
    writer.close(labeller)
    return labeller, ious


@pytest.mark.slow
def test_recorded_site_frames_fine_tune_the_bundled_network(tmp_path: Path) -> None:
    data = tmp_path / "site"
    labeller, ious = _record(data)
    assert labeller.kept == 6 and labeller.scene == 1
    assert min(ious) > 0.9  # the labels against the simulator's truth
    meta = json.loads((data / "meta.json").read_text())
    assert meta["kind"] == "site" and meta["frames"] == 6 and meta["shards"] == 2
    assert meta["dropped"] == {"plane": 0, "disagree": 0, "short_run": 0, "empty": 0}
    with np.load(data / "shard_00000.npz") as z:
        assert set(z.files) >= {"rgb", "depth", "mask", "camera_matrix", "T_world_camera"}
        assert z["depth"].dtype == np.uint16 and z["mask"].shape == (3, 480, 640)
    out = tmp_path / "adapted" / "seg.pt"
    args = argparse.Namespace(data=data, out=out, install=False, init="bundled", steps=2,
                              batch=2, lr=None, seed=0, threads=1, val_shards=1,
                              no_progress=True)
    assert perception_training.run(args) == 0
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["train_config"]["init"] == "bundled"
    assert report["train_config"]["lr"] == perception_training.FINE_TUNE.lr
    assert report["train_frames"] == 3 and report["validation"]["frames"] == 3
    card = out.with_suffix(".md").read_text()
    assert "adapted to a site" in card and "dropped: plane 0" in card


def test_init_with_install_and_an_unreadable_init_are_refused(tmp_path: Path) -> None:
    args = argparse.Namespace(data=tmp_path, out=tmp_path / "x.pt", install=True,
                              init="bundled", steps=None, batch=2, lr=None, seed=0, threads=1,
                              val_shards=1, no_progress=True)
    with pytest.raises(ValueError, match="--install"):
        perception_training.run(args)
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    args.install, args.init = False, str(bad)
    with pytest.raises(ValueError, match="not a segmentation network checkpoint"):
        perception_training.run(args)
