"""Tests of the learned affordance model (push_core.learned), its data and its training."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from push_core.affordances import analytical_affordances
from push_core.learned import (
    GRID,
    RESOLUTION,
    AffordanceNet,
    LearnedAffordances,
    contact_frame_targets,
    load_affordance_model,
    shape_encoding,
)
from push_core.objects import load_object
from push_core.planner import Planner, PlannerConfig, prepare_outline
from push_planner.models import default_weights
from pushbot.experiments.affordance_training import MIRROR_PUSH


def test_shape_encoding_geometry():
    spec = load_object("tri1")  # right angle at (0.042, 0.042): spans x, y in [-0.084, 0.042]
    points, normals = spec.outline(0.002)
    enc = shape_encoding(points, normals)
    assert enc.shape == (4, GRID, GRID)
    assert enc[0].sum() * RESOLUTION**2 == pytest.approx(spec.area, rel=0.08)
    rows, cols = np.nonzero(enc[0])
    centre = GRID / 2 - 0.5
    for idx in (rows, cols):  # rows run along +y, columns along +x
        lo, hi = (idx.min() - centre) * RESOLUTION, (idx.max() - centre) * RESOLUTION
        # within 2 pixels: no pixel centre may fall into the thin acute corners
        assert lo == pytest.approx(-0.084, abs=0.008) and hi == pytest.approx(0.042, abs=0.008)
    on = enc[1] > 0
    assert np.allclose(np.hypot(enc[2], enc[3])[on], 1.0, atol=1e-6)
    assert np.all(enc[2:, ~on] == 0.0)
    # The hypotenuse (outward normal (-1, -1)/sqrt 2) lies towards low x and y.
    r, c = np.nonzero(on & (enc[2] < -0.5) & (enc[3] < -0.5))
    assert r.size > 5 and np.all(r + c < 2 * centre + 2)


def test_targets_and_output_conversion_are_inverse():
    spec = load_object("hex")
    points, normals = spec.outline(0.004)
    com = np.array([0.01, -0.02])
    aff = analytical_affordances(points, normals, com, 0.04, 0.3)
    targets = contact_frame_targets(points[None], normals[None], com[None], aff[None])
    net = AffordanceNet()
    net.forward = lambda *a: torch.tensor(targets, dtype=torch.float32)  # type: ignore
    back = net.origin_motion(torch.zeros(1, 4, GRID, GRID), torch.tensor(com[None]).float(),
                             torch.tensor(points[None]).float(),
                             torch.tensor(normals[None]).float())
    np.testing.assert_allclose(back[0].numpy(), aff, atol=1e-6)
    # A push along the inward normal through the contact moves the COM along the normal.
    straight = targets[0, :, 5]
    assert np.all(straight[:, 0] > 0.0)


def test_mirror_augmentation_matches_the_physics():
    # The analytical model of a mirrored object (y -> -y, outline reversed to stay CCW) must
    # give the mirrored targets: pushes +-a swap, tangential motion and rotation change sign.
    spec = load_object("tri2")
    points, normals = spec.outline(0.004)
    com = np.array([0.005, 0.012])
    m = np.array([1.0, -1.0])
    t = contact_frame_targets(points, normals, com,
                              analytical_affordances(points, normals, com, 0.04, 0.3))
    mp, mn = (points * m)[::-1], (normals * m)[::-1]
    tm = contact_frame_targets(mp, mn, com * m,
                               analytical_affordances(mp, mn, com * m, 0.04, 0.3))
    np.testing.assert_allclose(tm[::-1], t[:, MIRROR_PUSH] * [1.0, -1.0, -1.0], atol=1e-9)


def test_callable_model_shapes_cache_and_weights_round_trip(tmp_path: Path):
    torch.manual_seed(0)
    net = AffordanceNet()
    model = LearnedAffordances(net, {"note": "random weights"})
    points, normals = load_object("rect1").outline(0.002)
    out = model(points, normals, [0.0, 0.01])
    assert out.shape == (len(points), 10, 3) and out.dtype == np.float64
    assert len(model._cache) == 1
    model(points, normals, [0.01, 0.0])
    assert len(model._cache) == 1  # the static encoding is reused, the COM is not cached
    path = tmp_path / "w.pt"
    torch.save({"format_version": 1, "config": {"channels": [16, 32, 32], "hidden": 128,
                                                "grid": GRID, "resolution": RESOLUTION},
                "state_dict": net.state_dict(), "meta": model.meta}, path)
    loaded = load_affordance_model(path)
    np.testing.assert_allclose(loaded(points, normals, [0.0, 0.01]), out, atol=1e-7)
    assert loaded.meta == {"note": "random weights"}
    torch.save({"something": 1}, tmp_path / "bad.pt")
    with pytest.raises(ValueError, match="not a learned affordance model"):
        load_affordance_model(tmp_path / "bad.pt")


@pytest.mark.skipif(not default_weights().exists(), reason="no bundled weights yet")
def test_bundled_model_plans_and_beats_no_motion_on_a_straight_push():
    model = load_affordance_model(default_weights())
    assert model.meta["test_metrics"], "the bundled model was evaluated on held-out objects"
    spec = load_object("butter")
    outline = prepare_outline(*spec.outline(0.002))
    aff = model(outline.points, outline.normals, spec.com)
    # Pushing 5 cm along the inward normal moves the object by a good part of that, inwards.
    straight = aff[:, 5, :2]
    inward = -outline.normals
    assert np.median(np.sum(straight * inward, axis=1)) > 0.02
    for direct in (False, True):
        plan = Planner(PlannerConfig(method="lrn", direct=direct), model).plan(
            outline, [0.0, 0.0, 0.0, *spec.com, 0.045, 0.25], [0.06, 0.0, 0.3])
        assert plan.score < plan.current_score


@pytest.mark.slow
def test_data_generation_and_training_end_to_end(tmp_path: Path):
    from pushbot.experiments.affordance_data import DataConfig, generate, load
    from pushbot.experiments.affordance_training import add_arguments, run

    cfg = DataConfig(n_samples=2, shard_size=2, points_per_sample=2, library_fraction=1.0)
    generate(cfg, tmp_path / "train", progress=False)
    data = load(tmp_path / "train")
    assert data["motion"].shape == (2, 2, 10, 3) and data["valid"].shape == (2, 2, 10)
    assert set(data["object"].tolist()) <= {"rect1", "rect2", "rect3", "tri2", "tri3",
                                            "ellip1", "ellip2", "ellip3"}
    ok = data["valid"]
    assert ok.sum() >= 30
    assert np.all(np.isfinite(data["motion"][ok])) and np.all(np.isnan(data["motion"][~ok]))
    # Straight 5 cm pushes move the object's COM inwards along the normal by centimetres.
    t = contact_frame_targets(data["points"], data["normals"], data["com"],
                              np.nan_to_num(data["motion"]))
    straight = t[:, :, 5][ok[:, :, 5]]
    assert np.all(straight[:, 0] > 1.0)  # > 1 cm
    np.testing.assert_allclose(generate_again(cfg, tmp_path), data["motion"], equal_nan=True)

    out = tmp_path / "model" / "w.pt"
    parser = argparse.ArgumentParser()
    add_arguments(parser)  # the command's own parser: every option has its real default
    args = parser.parse_args(["--data", str(tmp_path / "train"), "--test-data",
                              str(tmp_path / "train"), "--out", str(out), "--minutes", "5",
                              "--epochs", "2", "--batch", "4", "--lr", "1e-3", "--rotations",
                              "2", "--seed", "0", "--channels", "4", "8", "8", "--hidden", "16"])
    assert run(args) == 0
    model = load_affordance_model(out)
    assert model.meta["epochs"] == 2 and model.meta["samples"] == 2
    card = (out.parent / "MODEL_CARD.md").read_text()
    assert "## Metrics against pybullet" in card and "| lrn |" in card
    assert math.isfinite(model.meta["best_validation_loss"])


def generate_again(cfg, tmp_path: Path) -> np.ndarray:
    """The same shard generated again: the data are reproducible."""
    from pushbot.experiments.affordance_data import generate, load

    generate(cfg, tmp_path / "again", progress=False)
    return load(tmp_path / "again")["motion"]
