"""Unit tests of push_core.scores: eq. (5.1), the desired motion and the contact sampling."""

import math

import numpy as np
import pytest

from push_core.scores import (
    desired_motion,
    motion_score,
    point_scores,
    sample_contacts,
    softmax_probabilities,
)


def test_motion_score_units_mm_and_lambda_per_degree():
    # 3-4-5 mm translation and 10 degrees with lambda = 2 mm/deg: 5 + 20.
    residual = [0.003, 0.004, math.radians(10.0)]
    assert motion_score(residual, 2.0) == pytest.approx(25.0, abs=1e-12)
    # The rotation is wrapped: 350 degrees is -10 degrees.
    assert motion_score([0.0, 0.0, math.radians(350.0)], 1.0) == pytest.approx(10.0, abs=1e-9)

def test_point_scores_equal_eq_5_1_by_hand():
    desired = np.array([0.01, 0.0, 0.1])
    aff = np.array([
        [[0.01, 0.0, 0.0], [0.0, 0.0, 0.1]],  # residual (0, 0, 0.1) / (0.01, 0, 0)
        [[0.0, 0.0, 0.0], [0.02, 0.0, 0.1]],  # residual (0.01, 0, 0.1) / (-0.01, 0, 0)
    ])
    lam = 2.0
    rot = lam * math.degrees(0.1)  # 11.459 mm
    expected = [min(rot, 10.0), min(10.0 + rot, 10.0)]
    np.testing.assert_allclose(point_scores(aff, desired, lam), expected, atol=1e-12)
    np.testing.assert_allclose(point_scores(aff, desired, 0.5),
                               [0.5 * math.degrees(0.1), 10.0], atol=1e-12)

def test_desired_motion_in_object_frame_and_wrapped():
    pose = [0.1, 0.2, math.pi / 2]
    goal = [0.1, 0.3, -math.pi + 0.1]  # 10 cm along world +y = object +x
    d = desired_motion(pose, goal)
    # R(-pi/2) (0, 0.1) = (0.1, 0); (-pi + 0.1) - pi/2 = -3 pi/2 + 0.1 wraps to pi/2 + 0.1.
    np.testing.assert_allclose(d, [0.1, 0.0, math.pi / 2 + 0.1], atol=1e-12)

def test_softmax_probabilities_by_hand():
    p = softmax_probabilities([1.0, 2.0, np.inf], 0.5)
    w = np.array([1.0, math.exp(-2.0), 0.0])
    np.testing.assert_allclose(p, w / w.sum(), atol=1e-15)

def test_sampling_is_reproducible_with_a_seed():
    scores = np.linspace(0.0, 10.0, 50)
    a = sample_contacts(scores, 3, 2.0, np.random.default_rng(7))
    b = sample_contacts(scores, 3, 2.0, np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
    assert len(set(a.tolist())) == 3

def test_sampling_follows_the_softmax():
    scores = np.array([0.0, 1.0, 2.0, 5.0, np.inf])
    p = softmax_probabilities(scores, 1.0)
    rng = np.random.default_rng(0)
    n = 20000
    draws = np.array([sample_contacts(scores, 1, 1.0, rng)[0] for _ in range(n)])
    freq = np.bincount(draws, minlength=5) / n
    sigma = np.sqrt(p * (1 - p) / n)
    assert np.all(np.abs(freq - p) <= 4.5 * sigma + 1e-12), (freq, p)
    assert freq[4] == 0.0
    # Without replacement: P(second = j | first = i) = p_j / (1 - p_i); check P(0 then 1).
    pairs = [tuple(sample_contacts(scores, 2, 1.0, rng)) for _ in range(n)]
    p01 = p[0] * p[1] / (1 - p[0])
    freq01 = sum(1 for pr in pairs if pr == (0, 1)) / n
    assert abs(freq01 - p01) <= 4.5 * math.sqrt(p01 * (1 - p01) / n)
    assert all(a != b for a, b in pairs)

def test_bad_sampling_arguments_name_the_argument():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="^k"):
        sample_contacts([0.0, 1.0], 0, 1.0, rng)
    with pytest.raises(ValueError, match="temperature"):
        softmax_probabilities([0.0, 1.0], 0.0)
    with pytest.raises(ValueError, match="scores"):
        softmax_probabilities([np.inf, np.inf], 1.0)
