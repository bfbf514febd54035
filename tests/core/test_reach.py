"""push_core.reach: what one push of the model can do, and the physical minimum."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.reach import model_min_pushes, one_push_reaches, turn_radius

#: A 10 cm square centred on its COM, counter-clockwise.
SQUARE = np.array([[-0.05, -0.05], [0.05, -0.05], [0.05, 0.05], [-0.05, 0.05]])
#: Its uniform-pressure l: the mean distance of the area from the centre,
#: a (sqrt(2) + ln(1 + sqrt(2))) / 3 for half-side a.
SQUARE_L = 0.05 * (math.sqrt(2.0) + math.log(1.0 + math.sqrt(2.0))) / 3.0
TOL = (0.0075, math.radians(5.0))


def test_turn_radius_by_hand() -> None:
    # l^2 / rho with rho the corner distance a sqrt(2): 0.038260^2 / 0.070711 = 0.020701 m
    assert turn_radius(SQUARE, [0.0, 0.0], SQUARE_L) == pytest.approx(0.0207014, rel=1e-5)
    # a COM 2 cm right of the centre: the far corners are sqrt(0.07^2 + 0.05^2) away
    assert turn_radius(SQUARE, [0.02, 0.0], 0.03) == pytest.approx(0.03**2 / math.hypot(0.07, 0.05))


def test_the_square_cannot_turn_half_a_radian_in_place_in_one_push() -> None:
    # the COM moves >= 2 kappa sin(phi / 2) for a turn phi >= 0.5 rad - 5 deg:
    # 2 * 0.020701 * sin(0.20637) = 8.48 mm > 7.5 mm, so no single push reaches the goal
    assert not one_push_reaches(SQUARE, [0.0, 0.0], SQUARE_L, [0.0, 0.0, 0.5], TOL, 0.05)
    assert not one_push_reaches(SQUARE, [0.0, 0.0], SQUARE_L, [0.0, 0.0, -0.5], TOL, 0.05)
    assert model_min_pushes([0.0, 0.0, 0.5], TOL, 0.05, SQUARE, [0.0, 0.0], SQUARE_L) == 2
    # a quarter turn 4 cm away is out of one push's reach as well
    assert not one_push_reaches(SQUARE, [0.0, 0.0], SQUARE_L, [0.04, 0.0, math.pi / 2], TOL,
                                0.05)


def test_one_push_reaches_a_small_turn_and_a_straight_move() -> None:
    # 0.25 rad: the bound allows 2 * 0.020701 * sin(0.0814) = 3.4 mm, and a push finds it
    assert one_push_reaches(SQUARE, [0.0, 0.0], SQUARE_L, [0.0, 0.0, 0.25], TOL, 0.05)
    assert model_min_pushes([0.0, 0.0, 0.25], TOL, 0.05, SQUARE, [0.0, 0.0], SQUARE_L) == 1
    # 4 cm straight along x: a push through the COM
    assert one_push_reaches(SQUARE, [0.0, 0.0], SQUARE_L, [0.04, 0.0, 0.0], TOL, 0.05)
    # but not 6 cm: the pusher advances at most 5 cm past the contact
    assert not one_push_reaches(SQUARE, [0.0, 0.0], SQUARE_L, [0.06, 0.0, 0.0], TOL, 0.05)


def test_no_push_the_search_finds_breaks_the_turning_bound() -> None:
    # the module's claim, checked against the search: wherever 2 kappa sin(phi_min / 2) exceeds
    # the position tolerance, no single push reaches a turn in place
    kappa = turn_radius(SQUARE, [0.0, 0.0], SQUARE_L)
    for theta in (0.3, 0.4, 0.5, 0.6):
        bound = 2.0 * kappa * math.sin((theta - TOL[1]) / 2.0)
        if bound > TOL[0]:
            assert not one_push_reaches(SQUARE, [0.0, 0.0], SQUARE_L, [0.0, 0.0, theta], TOL,
                                        0.05), theta


def test_model_minimum_keeps_the_geometric_bound_otherwise() -> None:
    # 20 cm needs 4 pushes whatever the model; inside the region none; a square turned by a
    # quarter turn is in an equivalent pose (order 4)
    assert model_min_pushes([0.2, 0.0, 0.0], TOL, 0.05, SQUARE, [0.0, 0.0], SQUARE_L) == 4
    assert model_min_pushes([0.003, 0.0, 0.02], TOL, 0.05, SQUARE, [0.0, 0.0], SQUARE_L) == 0
    assert model_min_pushes([0.0, 0.0, math.pi / 2], TOL, 0.05, SQUARE, [0.0, 0.0], SQUARE_L,
                            order=4) == 0


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"l": 0.0}, "l"), ({"l": float("nan")}, "l"), ({"com": [0.0]}, "com"),
    ({"offset": [0.0, 0.0]}, "offset"), ({"tolerances": (0.0, 0.1)}, "tolerances"),
    ({"max_push_length": -1.0}, "max_push_length"), ({"polyline": SQUARE[::-1]}, "polyline")])
def test_bad_arguments_name_the_field(kwargs, field) -> None:
    args = {"polyline": SQUARE, "com": [0.0, 0.0], "l": SQUARE_L, "offset": [0.0, 0.0, 0.5],
            "tolerances": TOL, "max_push_length": 0.05}
    args.update(kwargs)
    with pytest.raises(ValueError, match=field):
        one_push_reaches(**args)
