"""The site labeller's consistency rule on synthetic depth frames (a camera looking straight
down at a table with a 10 mm plate on it)."""

from __future__ import annotations

import numpy as np
import pytest

from push_perception.site_labels import LabelRule, SiteLabeller, mask_iou

W, H, F = 160, 120, 150.0
K = np.array([[F, 0.0, W / 2 - 0.5], [0.0, F, H / 2 - 0.5], [0.0, 0.0, 1.0]])
#: Camera 0.8 m above the table origin looking down (optical z = -world z, x = world -y).
T = np.array([[0.0, -1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.8],
              [0.0, 0.0, 0.0, 1.0]])


def frame(u0: int, v0: int, rng: np.random.Generator, table_noise: float = 0.0):
    """rgb, depth and the true mask of a 30 x 20 px plate at column u0, row v0."""
    depth = np.full((H, W), 0.8, dtype=np.float32)
    depth += (table_noise * rng.standard_normal((H, W))).astype(np.float32)
    truth = np.zeros((H, W), dtype=bool)
    truth[v0:v0 + 20, u0:u0 + 30] = True
    depth[truth] = 0.79
    depth += (2e-4 * rng.standard_normal((H, W))).astype(np.float32)
    rgb = np.full((H, W, 3), 128, dtype=np.uint8)
    return rgb, depth, truth


def feed(labeller: SiteLabeller, frames: list) -> list:
    out = []
    for i, (rgb, depth, _) in enumerate(frames):
        out += labeller.add(rgb, depth, K, T, float(i))
    return out


def test_agreeing_frames_are_kept_with_one_label() -> None:
    rng = np.random.default_rng(0)
    frames = [frame(60, 50, rng) for _ in range(5)]
    labeller = SiteLabeller(LabelRule(window=5))
    kept = feed(labeller, frames)
    assert len(kept) == 5 and labeller.kept == 5
    assert sum(labeller.dropped.values()) == 0
    assert mask_iou(kept[0].mask, frames[0][2]) > 0.9
    assert all(np.array_equal(k.mask, kept[0].mask) for k in kept)
    assert [k.stamp for k in kept] == [0.0, 1.0, 2.0, 3.0, 4.0]


def test_a_disagreeing_frame_is_dropped_and_counted() -> None:
    rng = np.random.default_rng(1)
    frames = [frame(60, 50, rng) for _ in range(3)] + [frame(100, 20, rng)] \
        + [frame(60, 50, rng) for _ in range(2)]
    labeller = SiteLabeller(LabelRule(window=5))
    kept = feed(labeller, frames)
    assert len(kept) == 5 and 3.0 not in [k.stamp for k in kept]
    assert labeller.dropped == {"plane": 0, "disagree": 1, "short_run": 0, "empty": 0}
    assert labeller.scene == 0


def test_a_new_scene_ends_a_short_run_and_a_rough_table_is_dropped() -> None:
    rng = np.random.default_rng(2)
    labeller = SiteLabeller(LabelRule(window=4))
    feed(labeller, [frame(60, 50, rng) for _ in range(3)])
    feed(labeller, [frame(20, 80, rng, table_noise=0.01)])  # a table 10 mm rough
    kept = feed(labeller, [frame(100, 20, rng) for _ in range(4)])
    assert labeller.dropped["plane"] == 1
    assert labeller.dropped["short_run"] == 3 and labeller.scene == 1
    assert len(kept) == 4 and all(k.scene == 1 for k in kept)
    labeller.finish()
    assert labeller.kept + sum(labeller.dropped.values()) == 8


def test_rule_values_are_checked() -> None:
    with pytest.raises(ValueError, match="window"):
        LabelRule(window=1)
    with pytest.raises(ValueError, match="min_iou"):
        LabelRule(min_iou=0.0)
