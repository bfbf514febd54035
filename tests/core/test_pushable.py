"""push_core.pushable: the library's object and pusher, with hand-worked frames and values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.estimator.contact import limit_surface_of_polygon
from push_core.pushable import Pusher, PushObject

#: A 0.1 x 0.04 m rectangle given about its lower-left corner (centroid at (0.05, 0.02)).
RECT = np.array([[0.0, 0.0], [0.1, 0.0], [0.1, 0.04], [0.0, 0.04]])


def test_from_polygon_centres_the_shape_on_its_centroid() -> None:
    obj = PushObject.from_polygon(RECT)
    np.testing.assert_allclose(obj.shape.centroid, [0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(obj.origin, [-0.05, -0.02])  # the input's origin, object frame
    np.testing.assert_allclose(obj.com, [0.0, 0.0])
    # Default l: the uniform-pressure guess about the COM (sampled: within 0.5 % of exact).
    centred = RECT - [0.05, 0.02]
    assert obj.limit_surface == pytest.approx(limit_surface_of_polygon(centred), rel=5e-3)
    assert obj.friction == 0.25 and obj.notes == ()
    np.testing.assert_allclose(obj.state([0.1, 0.2, 0.3]),
                               [0.1, 0.2, 0.3, 0.0, 0.0, obj.limit_surface, 0.25])


def test_com_is_given_in_the_input_frame() -> None:
    obj = PushObject.from_polygon(RECT, com=(0.06, 0.02), friction=0.5, limit_surface=0.03)
    np.testing.assert_allclose(obj.com, [0.01, 0.0], atol=1e-15)
    assert obj.limit_surface == 0.03 and obj.friction == 0.5


def test_clockwise_vertices_are_reoriented_with_a_note() -> None:
    with pytest.warns(UserWarning, match="vertices were clockwise"):
        obj = PushObject.from_polygon(RECT[::-1])
    assert obj.notes and "re-oriented" in obj.notes[0]
    assert obj.shape.area == pytest.approx(0.004)


def test_source_and_object_poses_are_inverse() -> None:
    obj = PushObject.from_polygon(RECT)
    # The input frame at (1, 2) turned by 90 deg: its point (0.05, 0.02) (the centroid) lies at
    # (1 - 0.02, 2 + 0.05) in the world.
    pose = obj.to_object_pose([1.0, 2.0, math.pi / 2])
    np.testing.assert_allclose(pose, [0.98, 2.05, math.pi / 2])
    np.testing.assert_allclose(obj.to_source_pose(pose), [1.0, 2.0, math.pi / 2])
    world = obj.world_polygon(pose)
    np.testing.assert_allclose(obj.in_object_frame(pose, world), obj.outline.polyline,
                               atol=1e-12)


def test_pose_error_wraps_the_angle() -> None:
    obj = PushObject.from_ellipse(0.05, 0.03)
    dist, angle = obj.pose_error([0.0, 0.0, 3.0], [0.3, 0.4, -3.0])
    assert dist == pytest.approx(0.5)
    assert angle == pytest.approx(2 * math.pi - 6.0)
    assert obj.shape.area == pytest.approx(math.pi * 0.05 * 0.03)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"com": (math.nan, 0.0)}, "com"),
    ({"friction": -0.1}, "friction: must be finite and >= 0, got -0.1"),
    ({"limit_surface": 0.0}, "limit_surface: must be finite and > 0, got 0.0"),
    ({"spacing": 0.0}, "spacing: must be finite and > 0, got 0.0"),
])
def test_from_polygon_names_the_bad_argument(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        PushObject.from_polygon(RECT, **kwargs)
    with pytest.raises(ValueError, match="vertices"):
        PushObject.from_polygon(RECT[:2])


def test_pusher_is_the_one_place_for_the_radius() -> None:
    pusher = Pusher(radius=0.015)
    assert pusher.planner_config().pusher_radius == 0.015
    obj = PushObject.from_polygon(RECT, com=(0.06, 0.02))
    ekf = pusher.estimator(obj)
    assert ekf.config.pusher_radius == 0.015
    assert ekf.config.known_com == pytest.approx((0.01, 0.0))
    for make in (pusher.planner_config, lambda **o: pusher.estimator(obj, **o)):
        with pytest.raises(ValueError, match=r"pusher_radius: set it once, in Pusher"):
            make(pusher_radius=0.01)
    for bad in (-0.001, math.inf, True):
        with pytest.raises(ValueError, match="radius: must be a finite number >= 0"):
            Pusher(radius=bad)
