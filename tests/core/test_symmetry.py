"""push_core.symmetry: when an outline's orientation is observable (hand-derived values)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.objects import load_object
from push_core.shapes import Ellipse
from push_core.symmetry import (
    CONTINUOUS_SYMMETRY_TOLERANCE,
    UNOBSERVED_VARIANCE,
    has_continuous_symmetry,
    orientation_observed,
    rotation_mismatch,
)

A = 0.04
SQUARE = np.array([[A, -A], [A, A], [-A, A], [-A, -A]])


def test_square_vertices_turned_by_45_deg_miss_the_outline_by_a_sqrt2_minus_a() -> None:
    # A vertex at distance a sqrt(2) lands on an axis, a (sqrt(2) - 1) outside the edge.
    got = rotation_mismatch(SQUARE, [math.pi / 4, math.pi / 2])
    assert got[0] == pytest.approx(A * (math.sqrt(2.0) - 1.0), rel=1e-9)
    assert got[1] == pytest.approx(0.0, abs=1e-12)  # 4-fold symmetric


def test_mismatch_is_taken_about_the_area_centroid() -> None:
    shifted = SQUARE + np.array([0.3, -0.2])
    assert rotation_mismatch(shifted, [math.pi / 2])[0] == pytest.approx(0.0, abs=1e-12)


def test_a_disc_is_continuously_symmetric_and_other_library_objects_are_not() -> None:
    disc = load_object("ellip1")  # MIT ellip1: a disc of radius 52.5 mm
    assert has_continuous_symmetry(disc.polyline())
    assert has_continuous_symmetry(disc.outline(0.002)[0] + 0.1)  # sampled, anywhere
    for name in ("ellip2", "ellip3", "hex", "butter", "tri1", "rect1"):
        assert not has_continuous_symmetry(load_object(name).polyline()), name


def test_nearly_round_ellipse_is_symmetric_within_the_tolerance_only() -> None:
    # Semi-axes a, b: turned by 90 deg the boundary moves by about (a - b) at the axes.
    near = Ellipse(0.050, 0.0505).polyline()
    far = Ellipse(0.050, 0.054).polyline()
    assert has_continuous_symmetry(near)
    assert not has_continuous_symmetry(far)
    assert rotation_mismatch(far, [math.pi / 2])[0] > CONTINUOUS_SYMMETRY_TOLERANCE


def test_orientation_observed_by_variance() -> None:
    assert orientation_observed(1e-4)
    assert not orientation_observed(UNOBSERVED_VARIANCE)
    assert not orientation_observed(math.pi**2)
    assert not orientation_observed(float("nan"))


def test_bad_input_names_the_argument() -> None:
    with pytest.raises(ValueError, match="points"):
        has_continuous_symmetry(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="tolerance"):
        has_continuous_symmetry(SQUARE, tolerance=0.0)
