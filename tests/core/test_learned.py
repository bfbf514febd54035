"""push_core.learned: the shape encoding, the contact-frame targets and the model wrapper
(hand-derived targets, encoding geometry of a library object, weights round trip)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from push_core.affordances import analytical_affordances
from push_core.learned import (
    GRID,
    RESOLUTION,
    ROTATION_SCALE,
    TRANSLATION_SCALE,
    AffordanceNet,
    LearnedAffordances,
    contact_frame_targets,
    load_affordance_model,
    shape_encoding,
)
from push_core.objects import load_object


def test_targets_are_the_com_motion_in_the_contact_frame_by_hand() -> None:
    # Outward normal +x: e_n = (-1, 0) (inward), e_t = (0, -1). Units: cm and 5 deg.
    assert TRANSLATION_SCALE == 0.01 and ROTATION_SCALE == pytest.approx(math.radians(5.0))
    points, normals = np.array([[0.05, 0.0]]), np.array([[1.0, 0.0]])
    # COM at the origin, origin moved 1 cm inwards: 1 cm along e_n.
    t = contact_frame_targets(points, normals, [0.0, 0.0], [[[-0.01, 0.0, 0.0]]])
    np.testing.assert_allclose(t, [[[1.0, 0.0, 0.0]]], atol=1e-12)
    # COM at (0.01, 0), a quarter turn about the origin: the COM moves by R c - c =
    # (-0.01, 0.01) m = 1 cm along e_n and -1 cm along e_t; 90 deg = 18 x 5 deg.
    t = contact_frame_targets(points, normals, [0.01, 0.0], [[[0.0, 0.0, math.pi / 2]]])
    np.testing.assert_allclose(t, [[[1.0, -1.0, 18.0]]], atol=1e-12)


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
