"""push_core.estimator.config: the state layout, the noise models against their formulas,
validation naming the field, and the input check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator.config import STATE_LABELS, STATE_SIZE, EKFConfig, finite_vector


def test_state_layout() -> None:
    assert STATE_LABELS == ("x", "y", "theta", "c_x", "c_y", "l", "m") and STATE_SIZE == 7


def test_process_noise_is_the_documented_formula() -> None:
    cfg = EKFConfig(position_noise_min=0.001, position_noise_per_metre=0.1, angle_noise_min=0.01,
                    angle_noise_per_metre=2.0, com_noise=0.002, l_noise=0.003, m_noise=0.04)
    # 2 cm in contact: position 0.001 + 0.1 * 0.02 = 0.003 m, angle 0.01 + 2 * 0.02 = 0.05 rad.
    q = cfg.process_noise(0.02)
    np.testing.assert_allclose(np.diag(q), [9e-6, 9e-6, 2.5e-3, 4e-6, 4e-6, 9e-6, 1.6e-3],
                               rtol=1e-12)
    assert np.count_nonzero(q - np.diag(np.diag(q))) == 0
    # A known parameter does not walk.
    known = EKFConfig(known_com=(0.0, 0.01), known_l=0.04, known_m=0.3).process_noise(0.0)
    assert np.all(np.diag(known)[3:] == 0.0)


def test_observation_noise_and_the_gate() -> None:
    cfg = EKFConfig(position_sigma=0.002, angle_sigma=0.05)
    np.testing.assert_allclose(cfg.observation_noise, np.diag([4e-6, 4e-6, 2.5e-3]), rtol=1e-12)
    # chi-square with 3 dof: P(X <= x) = erf(sqrt(x/2)) - sqrt(2x/pi) exp(-x/2).
    x = EKFConfig(gate_probability=0.9999).gate_threshold
    cdf = math.erf(math.sqrt(x / 2)) - math.sqrt(2 * x / math.pi) * math.exp(-x / 2)
    assert cdf == pytest.approx(0.9999, abs=1e-12) and x == pytest.approx(21.1, abs=0.01)
    assert EKFConfig(gate_probability=1.0).gate_threshold == math.inf


def test_values_are_normalised() -> None:
    cfg = EKFConfig(max_substeps=5.0, symmetry_order=4.0, m_range=[0.1, 0.9], substep=1)
    assert cfg.max_substeps == 5 and type(cfg.max_substeps) is int
    assert cfg.symmetry_order == 4 and cfg.m_range == (0.1, 0.9)
    assert cfg.substep == 1.0 and type(cfg.substep) is float


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"substep": 0.0}, "substep"),
    ({"pusher_radius": -0.001}, "pusher_radius"),
    ({"m_range": (0.5, 0.1)}, "m_range"),
    ({"m_init": 2.0}, "m_init"),
    ({"gate_probability": 0.0}, "gate_probability"),
    ({"gate_probability": 1.5}, "gate_probability"),
    ({"symmetry_order": -1}, "symmetry_order"),
    ({"symmetry_order": 1.5}, "symmetry_order"),
    ({"com_noise": float("nan")}, "com_noise"),
    ({"l_min_fraction": 1.0}, "l_min_fraction"),
])
def test_bad_config_raises_naming_the_field(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        EKFConfig(**kwargs)


def test_finite_vector_checks_shape_and_finiteness_naming_the_argument() -> None:
    np.testing.assert_array_equal(finite_vector("pose", [1, 2, 3], 3), [1.0, 2.0, 3.0])
    assert finite_vector("pose", (1, 2, 3), 3).dtype == np.float64
    with pytest.raises(ValueError, match=r"pose must have shape \(3,\)"):
        finite_vector("pose", [1.0, 2.0], 3)
    with pytest.raises(ValueError, match="pose must be finite"):
        finite_vector("pose", [1.0, math.inf, 0.0], 3)
    with pytest.raises(ValueError, match="pose must be 3 numbers"):
        finite_vector("pose", ["a", 1, 2], 3)
