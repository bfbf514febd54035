"""push_core.affordances: the analytical affordances against hand-derived pushes of a square.

The sticking push is solved by hand with the ellipsoidal limit surface (Lynch et al. 1992): a
contact force ``f`` gives the COM twist ``(f_x, f_y, tau / l^2)`` with ``tau = r' x f``, and
sticking means the contact point moves with the pusher.
"""

from __future__ import annotations

import numpy as np
import pytest

from push_core.affordances import N_ANGLES, N_PUSHES, analytical_affordances
from push_core.model import REPRESENTATIVE_ANGLES_DEG, REPRESENTATIVE_LENGTHS

#: The middle of the right face of a 10 cm square and 2 cm above it; outward normal +x.
POINTS = np.array([[0.05, 0.0], [0.05, 0.02]])
NORMALS = np.array([[1.0, 0.0], [1.0, 0.0]])
L, M = 0.05, 0.3  # limit surface (m) and a friction cone of atan(0.3) = 16.7 deg


def test_the_representative_set_is_length_major() -> None:
    assert N_ANGLES == len(REPRESENTATIVE_ANGLES_DEG) == 5
    assert N_PUSHES == 10 and REPRESENTATIVE_LENGTHS == (0.01, 0.05)
    aff = analytical_affordances(POINTS, NORMALS, [0.0, 0.0], L, M)
    assert aff.shape == (2, N_PUSHES, 3) and aff.dtype == np.float64
    # Through the COM along the inward normal: a pure translation by the push length.
    np.testing.assert_allclose(aff[0, 0], [-0.01, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(aff[0, N_ANGLES], [-0.05, 0.0, 0.0], atol=1e-12)


def test_an_off_centre_sticking_push_is_the_hand_solution() -> None:
    # r' = (0.05, 0.02), l^2 = 0.0025: omega = (0.05 f_y - 0.02 f_x) / 0.0025 = 20 f_y - 8 f_x;
    # contact v_y = f_y + 0.05 omega = 2 f_y - 0.4 f_x = 0 -> f_y = 0.2 f_x, omega = -4 f_x;
    # contact v_x = f_x - 0.02 omega = 1.08 f_x = -0.01 -> f_x = -0.01 / 1.08.
    # f_y / f_x = 0.2 (11.3 deg) lies inside the cone (16.7 deg): the contact sticks.
    fx = -0.01 / 1.08
    aff = analytical_affordances(POINTS, NORMALS, [0.0, 0.0], L, M)
    np.testing.assert_allclose(aff[1, 0], [fx, 0.2 * fx, -4.0 * fx], rtol=1e-9)
    assert aff[1, 0, 2] > 0.0  # pushed -x above the COM: counter-clockwise


def test_the_origin_follows_an_offset_com() -> None:
    # COM at (0.01, 0): the push at (0.05, 0) still passes through it, so the object (and its
    # origin) translates by the push.
    aff = analytical_affordances(POINTS[:1], NORMALS[:1], [0.01, 0.0], L, M)
    np.testing.assert_allclose(aff[0, 0], [-0.01, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(aff[0, N_ANGLES], [-0.05, 0.0, 0.0], atol=1e-12)


def test_mirrored_directions_give_mirrored_motions() -> None:
    # Point and COM on the x axis: the +a and -a pushes mirror about it (dy, dtheta flip).
    aff = analytical_affordances(POINTS[:1], NORMALS[:1], [0.0, 0.0], L, M)[0]
    for plus, minus in ((1, 2), (3, 4)):
        for k in (0, N_ANGLES):
            np.testing.assert_allclose(aff[k + minus], aff[k + plus] * [1.0, -1.0, -1.0],
                                       atol=1e-12)
    # Outside the friction cone (30 and 60 deg > 16.7 deg) the contact slides: the COM moves
    # less far along the push direction than the pusher does.
    for j in (1, 3):
        direction = np.array([-np.cos(np.radians(REPRESENTATIVE_ANGLES_DEG[j])),
                              np.sin(np.radians(REPRESENTATIVE_ANGLES_DEG[j]))])
        assert aff[j, :2] @ direction < 0.01


def test_affordances_scale_with_the_push_length_for_a_small_rotation() -> None:
    # Homogeneous of degree one in the push: the 5 cm push is 5 x the 1 cm twist about the COM
    # (COM at the origin, so the origin's motion is the COM's).
    aff = analytical_affordances(POINTS, NORMALS, [0.0, 0.0], L, M)
    np.testing.assert_allclose(aff[:, N_ANGLES:], 5.0 * aff[:, :N_ANGLES], rtol=1e-9, atol=1e-15)


def test_bad_shapes_name_the_argument() -> None:
    with pytest.raises(ValueError, match="normal"):
        analytical_affordances(POINTS, NORMALS[:1], [0.0, 0.0], L, M)
    with pytest.raises(ValueError, match="com"):
        analytical_affordances(POINTS, NORMALS, [0.0, 0.0, 0.0], L, M)
