"""The learned affordance model in use: the bundled weights plan, the mirror augmentation of the
training command matches the physics, and data generation and training run end to end (the
model itself: tests/core/test_learned.py)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pytest

from push_core.affordances import analytical_affordances
from push_core.learned import contact_frame_targets, load_affordance_model
from push_core.objects import load_object
from push_core.planner import Planner, PlannerConfig, prepare_outline
from push_planner.models import default_weights
from pushbot.experiments.affordance_training import MIRROR_PUSH


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
