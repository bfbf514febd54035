"""push_core.estimator.active: informative pushes (geometry of the push against a disc, by hand)
and the
choice of the most informative one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator import active
from push_core.estimator.ekf import PushEKF
from push_core.geometry import wrap_angle
from push_core.objects import load_object

R_DISC = 0.04  # m
#: A disc of radius 4 cm: 72 points, outward normals radial.
_PHI = np.linspace(0.0, 2.0 * np.pi, 72, endpoint=False)
DISC_NORMALS = np.stack([np.cos(_PHI), np.sin(_PHI)], axis=1)
DISC = R_DISC * DISC_NORMALS


def library_outline(name: str) -> tuple[np.ndarray, np.ndarray]:
    return load_object(name).outline(0.002)


def test_constants_are_the_documented_push_ranges() -> None:
    assert active.PUSH_ANGLE == pytest.approx(math.radians(30.0))
    assert active.PUSH_LENGTH == (0.02, 0.04) and active.PUSH_GAP == (0.005, 0.015)


def test_a_push_against_a_disc_touches_at_radius_plus_pusher_and_aims_near_the_centre() -> None:
    # On a disc the direction to the centre is the inward normal, so every draw is kept
    # (within 30 deg of it, far from grazing); the pusher axis touches at R + r from the centre.
    rng = np.random.default_rng(3)
    pose = np.array([0.1, -0.05, 0.7])
    r = 0.0048
    for _ in range(50):
        start, contact, end = active.informative_push(DISC, DISC_NORMALS, pose, rng, r)
        centre = pose[:2]
        assert np.linalg.norm(contact - centre) == pytest.approx(R_DISC + r, abs=1e-12)
        gap, length = np.linalg.norm(contact - start), np.linalg.norm(end - contact)
        assert 0.005 <= gap <= 0.015 and 0.02 <= length <= 0.04
        d = (end - contact) / length
        np.testing.assert_allclose((contact - start) / gap, d, atol=1e-12)  # collinear
        to_centre = (centre - contact) / np.linalg.norm(centre - contact)
        off = abs(wrap_angle(math.atan2(d[1], d[0]) - math.atan2(to_centre[1], to_centre[0])))
        assert off <= math.radians(30.0) + 1e-12


def test_towards_keeps_only_pushes_along_it_and_an_impossible_one_raises() -> None:
    rng = np.random.default_rng(5)
    pose = np.array([0.0, 0.0, 0.3])
    for _ in range(30):
        start, _, end = active.informative_push(DISC, DISC_NORMALS, pose, rng,
                                                towards=np.array([1.0, 0.0]))
        assert end[0] > start[0]
    with pytest.raises(RuntimeError, match="direction"):
        active.informative_push(DISC, DISC_NORMALS, pose, rng, towards=np.zeros(2))


def test_the_same_seed_draws_the_same_push() -> None:
    points, normals = library_outline("butter")
    pose = np.array([0.0, 0.0, 0.0])
    a = active.informative_push(points, normals, pose, np.random.default_rng(9))
    b = active.informative_push(points, normals, pose, np.random.default_rng(9))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_most_informative_push_prefers_a_push_that_touches() -> None:
    points, normals = library_outline("butter")
    ekf = PushEKF(points, normals)
    ekf.update_pose([0.0, 0.0, 0.0])
    rng = np.random.default_rng(4)
    touching = active.informative_push(points, normals, ekf.state[:3], rng)
    far = tuple(np.asarray(q) + [0.3, 0.0] for q in touching)  # the same push, 30 cm away
    assert active.most_informative_push(ekf, [far, touching]) == 1
    assert active.most_informative_push(ekf, [touching, far]) == 0
    with pytest.raises(ValueError, match="empty"):
        active.most_informative_push(ekf, [])
