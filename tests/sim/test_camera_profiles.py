"""sim_bridge.camera_profiles: each profile's stream shape, its noise model, and the refusal of
an unknown profile name."""

from __future__ import annotations

import numpy as np
import pytest

from sim_bridge.camera_profiles import PROFILES, DepthNoise, driver_frame, profile


def test_an_unknown_profile_is_refused_with_the_known_names() -> None:
    with pytest.raises(ValueError, match=r"camera.profile must be one of \['d415'"):
        profile("kinect")


@pytest.mark.parametrize("name", sorted(PROFILES))
def test_each_profile_sends_its_streams_shape(name: str) -> None:
    prof = profile(name)
    cfg = prof.camera_config()
    assert (cfg.width, cfg.height) == (prof.width, prof.height)
    k = np.array([[prof.focal_px, 0, (prof.width - 1) / 2], [0, prof.focal_px,
                                                              (prof.height - 1) / 2], [0, 0, 1]])
    rgb = np.full((prof.height, prof.width, 3), 128, np.uint8)
    depth = np.full((prof.height, prof.width), 0.8, np.float32)
    sent = driver_frame(prof, rgb, depth, k, np.random.default_rng(0))
    assert sent.rgb.shape == rgb.shape
    assert (sent.depth_k is None) == prof.depth_aligned
    valid = sent.depth[np.isfinite(sent.depth)]
    assert valid.size > 0.9 * depth.size * (0.9 if prof.depth_aligned else 0.8)
    if prof.noise is not None and prof.noise.unit:  # the driver's millimetres
        np.testing.assert_allclose(valid * 1e3, np.round(valid * 1e3), atol=1e-3)


def test_structured_light_quantises_disparity_and_stereo_adds_gaussian_noise() -> None:
    z = np.full((200, 200), 0.8, np.float32)
    z[:, 100:] = 0.85
    light = DepthNoise("structured_light", 575.0, 0.075, 0.125, unit=0.0, drop=0.0)
    out = light.apply(z, np.random.default_rng(0))
    levels = np.unique(out[np.isfinite(out)])
    fb = 575.0 * 0.075
    np.testing.assert_allclose(fb / levels / 0.125, np.round(fb / levels / 0.125), atol=1e-3)
    assert 0.4 < np.isnan(out[:, 99:101]).mean() < 0.6  # edge_drop 0.5 at the step
    assert not np.isnan(out[:, :98]).any()  # and nowhere else (drop 0)
    stereo = DepthNoise("stereo", 447.0, 0.05, 0.08, unit=0.0, drop=0.0, edge_drop=0.0)
    noisy = stereo.apply(z[:, :100], np.random.default_rng(0))
    expected = 0.8**2 * 0.08 / (447.0 * 0.05)  # sigma_z = z^2 sigma_d / (f B)
    assert np.std(noisy) == pytest.approx(expected, rel=0.05)
