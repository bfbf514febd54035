"""Unit tests of push_core.geometry: rotations, pose transforms, closest points, validators."""

import json
from importlib import resources

import numpy as np
import pytest
import torch

from push_core.geometry import (
    check_points,
    check_polyline,
    check_poses,
    check_vector,
    closest_point_on_polyline,
    object_to_world,
    rot2,
    world_to_object,
    wrap_angle,
)

# Square of side 2 centred on the origin, counter-clockwise. Segments: 0 bottom (y = -1),
# 1 right (x = 1), 2 top (y = 1), 3 left (x = -1).
SQUARE = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
# L shape = union of [0, 2] x [0, 1] and [0, 1] x [0, 2], counter-clockwise; notch at (1, 1)-(2, 2).
L_SHAPE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]])


def butter_outline() -> np.ndarray:
    """The 637-vertex non-convex butter outline of the bundled MIT pushing objects."""
    path = resources.files("push_core") / "data" / "mit_push_objects.json"
    return np.array(json.loads(path.read_text())["objects"]["butter"]["polygon_m"])


def winding_number(vertices: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """Independent inside test: total signed angle swept by the polygon seen from each query."""
    a = vertices[None, :, :] - queries[:, None, :]
    b = np.roll(vertices, -1, axis=0)[None, :, :] - queries[:, None, :]
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    dot = np.sum(a * b, axis=-1)
    return np.rint(np.sum(np.arctan2(cross, dot), axis=1) / (2 * np.pi)).astype(int)


# ---------------------------------------------------------------- rotations and transforms


def test_rot2_quarter_turn_and_broadcasting():
    # R(pi/2) (1, 0) = (0, 1); R(pi/2) (0, 1) = (-1, 0).
    np.testing.assert_allclose(rot2(np.pi / 2) @ [1.0, 0.0], [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(rot2(np.pi / 2) @ [0.0, 1.0], [-1.0, 0.0], atol=1e-15)
    theta = np.random.default_rng(0).uniform(-10, 10, size=(4, 5))
    r = rot2(theta)
    assert r.shape == (4, 5, 2, 2)
    # Orthonormal with determinant 1, and R(a) R(b) = R(a + b).
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(2), r.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)
    np.testing.assert_allclose(r[0] @ r[1:], rot2(theta[0] + theta[1:]),
                               atol=1e-13)


def test_wrap_angle_values_and_interval():
    # pi stays pi, -pi maps to pi (half-open interval (-pi, pi]), 3 pi / 2 -> -pi / 2.
    np.testing.assert_allclose(wrap_angle([np.pi, -np.pi, 1.5 * np.pi, 0.0, 2 * np.pi + 0.1]),
                               [np.pi, np.pi, -0.5 * np.pi, 0.0, 0.1], atol=1e-12)
    theta = np.random.default_rng(1).uniform(-50, 50, size=1000)
    w = wrap_angle(theta)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    # Same direction: the difference is a multiple of 2 pi.
    k = (theta - w) / (2 * np.pi)
    np.testing.assert_allclose(k, np.rint(k), atol=1e-9)


def test_object_to_world_hand_value():
    # Pose (1, 2, pi/2): object x axis = world y axis. Object point (1, 0) -> (1, 2) + (0, 1).
    np.testing.assert_allclose(object_to_world([1.0, 2.0, np.pi / 2], [1.0, 0.0]), [1.0, 3.0],
                               atol=1e-15)
    np.testing.assert_allclose(world_to_object([1.0, 2.0, np.pi / 2], [1.0, 3.0]), [1.0, 0.0],
                               atol=1e-15)


def test_transform_round_trip_and_broadcasting():
    rng = np.random.default_rng(2)
    poses = rng.uniform(-3, 3, size=(7, 1, 3))
    points = rng.uniform(-1, 1, size=(7, 11, 2))
    world = object_to_world(poses, points)
    assert world.shape == (7, 11, 2)
    np.testing.assert_allclose(world_to_object(poses, world), points, atol=1e-14)
    # Distances between points are preserved (rigid motion).
    np.testing.assert_allclose(np.linalg.norm(world[:, 1:] - world[:, :1], axis=-1),
                               np.linalg.norm(points[:, 1:] - points[:, :1], axis=-1), atol=1e-14)


def test_torch_paths_match_numpy():
    rng = np.random.default_rng(3)
    poses = rng.uniform(-3, 3, size=(5, 3))
    points = rng.uniform(-1, 1, size=(5, 2))
    for fn, args in [(object_to_world, (poses, points)), (world_to_object, (poses, points)),
                     (rot2, (poses[:, 2],)), (wrap_angle, (10 * poses[:, 2],))]:
        out = fn(*(torch.tensor(a) for a in args))
        assert isinstance(out, torch.Tensor) and out.dtype == torch.float64
        np.testing.assert_allclose(out.numpy(), fn(*args), rtol=0, atol=1e-14)


# ---------------------------------------------------------------- closest point on a polyline


@pytest.mark.parametrize(
    ("query", "closest", "normal", "distance", "segment"),
    [
        # Outside the right face: straight projection, normal +x, distance 1.
        ((2.0, 0.5), (1.0, 0.5), (1.0, 0.0), 1.0, 1),
        # Inside, nearest to the right face (0.5 away, the top face is 0.8 away).
        ((0.5, 0.2), (1.0, 0.2), (1.0, 0.0), -0.5, 1),
        # Inside near the corner: right face 0.1 away beats top face 0.2 away.
        ((0.9, 0.8), (1.0, 0.8), (1.0, 0.0), -0.1, 1),
        # Inside, nearest to the bottom face.
        ((0.2, -0.7), (0.2, -1.0), (0.0, -1.0), -0.3, 0),
        # Vertex region of (1, 1): closest point the vertex, normal along (1, 2) / sqrt(5),
        # distance sqrt(1 + 4). Segments 1 and 2 tie; the first in index order is reported.
        ((2.0, 3.0), (1.0, 1.0), (1 / np.sqrt(5), 2 / np.sqrt(5)), np.sqrt(5), 1),
        # Vertex region of (-1, -1): the closing segment 3 and segment 0 tie -> 0.
        ((-2.0, -2.0), (-1.0, -1.0), (-np.sqrt(0.5), -np.sqrt(0.5)), np.sqrt(2), 0),
        # On the left face: distance 0, the segment's outward normal (dy, -dx)/len = (-1, 0).
        ((-1.0, 0.3), (-1.0, 0.3), (-1.0, 0.0), 0.0, 3),
    ],
)
def test_closest_point_on_square(query, closest, normal, distance, segment):
    c, n, d, s = closest_point_on_polyline(SQUARE, query)
    np.testing.assert_allclose(c, closest, atol=1e-15)
    np.testing.assert_allclose(n, normal, atol=1e-15)
    np.testing.assert_allclose(d, distance, atol=1e-15)
    assert s == segment
    assert c.shape == (2,) and n.shape == (2,) and d.shape == () and s.shape == ()


def test_closest_point_random_queries_are_consistent():
    rng = np.random.default_rng(4)
    queries = rng.uniform(-3, 3, size=(3, 50, 2))
    c, n, d, s = closest_point_on_polyline(SQUARE, queries)
    assert c.shape == (3, 50, 2) and n.shape == (3, 50, 2) and d.shape == (3, 50)
    assert s.shape == (3, 50)
    # The query is the closest point plus the signed distance along the outward normal.
    np.testing.assert_allclose(c + d[..., None] * n, queries, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-14)
    # Inside the square iff max(|x|, |y|) < 1; the distance to the square is known in closed form.
    inside = np.max(np.abs(queries), axis=-1) < 1
    np.testing.assert_array_equal(d < 0, inside)
    outside_dist = np.linalg.norm(np.maximum(np.abs(queries) - 1, 0), axis=-1)
    inside_dist = 1 - np.max(np.abs(queries), axis=-1)
    np.testing.assert_allclose(np.abs(d), np.where(inside, inside_dist, outside_dist), atol=1e-14)


def test_signed_distance_sign_on_non_convex_l_shape():
    # Points in the notch (1, 2) x (1, 2) are outside although they lie inside the convex hull.
    _, n, d, _ = closest_point_on_polyline(L_SHAPE, [[1.5, 1.5], [1.8, 1.2], [0.5, 1.5],
                                                     [1.5, 0.5], [0.5, 0.5]])
    np.testing.assert_array_equal(d > 0, [True, True, False, False, False])
    # From (1.5, 1.5) the notch corner (1, 1) is sqrt(0.5) away, the faces 0.5 away.
    np.testing.assert_allclose(d[:2], [0.5, 0.2], atol=1e-15)
    # (1.8, 1.2) is nearest to the notch floor y = 1 (0.2 away): outward normal +y.
    np.testing.assert_allclose(n[1], [0.0, 1.0], atol=1e-15)
    rng = np.random.default_rng(5)
    q = rng.uniform(-0.5, 2.5, size=(2000, 2))
    _, _, d, _ = closest_point_on_polyline(L_SHAPE, q)
    in_union = (((q[:, 0] > 0) & (q[:, 0] < 2) & (q[:, 1] > 0) & (q[:, 1] < 1))
                | ((q[:, 0] > 0) & (q[:, 0] < 1) & (q[:, 1] > 0) & (q[:, 1] < 2)))
    np.testing.assert_array_equal(d < 0, in_union)


def test_signed_distance_on_butter_outline_matches_winding_number():
    outline = butter_outline()
    assert outline.shape == (637, 2)
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    q = np.random.default_rng(6).uniform(lo - 0.01, hi + 0.01, size=(3000, 2))
    c, _, d, s = closest_point_on_polyline(outline, q)
    np.testing.assert_array_equal(d < 0, winding_number(outline, q) == 1)
    # Exactness: no outline vertex is closer than the reported closest point, and the closest
    # point lies on its segment.
    vertex_dist = np.min(np.linalg.norm(q[:, None, :] - outline[None], axis=-1), axis=1)
    assert np.all(np.abs(d) <= vertex_dist + 1e-15)
    a, b = outline[s], np.roll(outline, -1, axis=0)[s]
    cross = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    np.testing.assert_allclose(cross, 0.0, atol=1e-15)


def test_repeated_vertex_does_not_break_the_normal():
    square = np.insert(SQUARE, 2, SQUARE[1], axis=0)  # vertex (1, -1) twice
    _, n, d, _ = closest_point_on_polyline(square, [[1.0, -1.0], [1.0, 0.0]])
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0)
    np.testing.assert_allclose(d, 0.0, atol=1e-15)


# ---------------------------------------------------------------- validators


def test_validators_name_the_argument_and_shape():
    with pytest.raises(ValueError, match=r"points must have shape \(\.\.\., 2\), got shape \(3,\)"):
        check_points(np.zeros(3))
    with pytest.raises(ValueError, match=r"pose0 must have shape \(\.\.\., 3\), got shape \(4,"):
        check_poses(np.zeros((4, 2)), "pose0")
    with pytest.raises(ValueError, match=r"outline must have shape \(P, 2\) with P >= 3"):
        check_polyline(np.zeros((2, 2)), "outline")
    with pytest.raises(ValueError, match=r"vertices must be counter-clockwise"):
        check_polyline(SQUARE[::-1])
    with pytest.raises(ValueError, match=r"vertices must be finite"):
        check_polyline(np.where(SQUARE == 1.0, np.nan, SQUARE))
    with pytest.raises(ValueError, match=r"queries must have shape \(\.\.\., 2\)"):
        closest_point_on_polyline(SQUARE, np.zeros((5, 3)))
    with pytest.raises(ValueError, match=r"pose must have shape \(\.\.\., 3\)"):
        object_to_world(np.zeros(2), np.zeros(2))
    # Valid inputs pass through.
    np.testing.assert_array_equal(check_polyline(SQUARE), SQUARE)


def test_the_one_quaternion_rule():
    # push_core.geometry.QUATERNION_TOLERANCE: finite, unit norm within 1e-3; a planar pose also
    # |q_x|, |q_y| <= 1e-3 (every message reader of push_ros applies it).
    from push_core.geometry import (
        QUATERNION_TOLERANCE,
        NonFiniteError,
        check_quaternion,
        quaternion_from_yaw,
        yaw_from_quaternion,
    )

    assert QUATERNION_TOLERANCE == 1e-3
    for theta in (0.0, 0.3, -2.0, np.pi):
        assert yaw_from_quaternion(quaternion_from_yaw(theta)) == pytest.approx(
            np.arctan2(np.sin(theta), np.cos(theta)))
    slightly_off = quaternion_from_yaw(0.5) * (1 + 0.9e-3) + [0.9e-3, -0.9e-3, 0.0, 0.0]
    assert yaw_from_quaternion(slightly_off) == pytest.approx(0.5, abs=1e-2)
    np.testing.assert_allclose(np.linalg.norm(check_quaternion([0, 0, 0, 1.0005])), 1.0)
    with pytest.raises(ValueError, match="unit length"):
        check_quaternion([0.0, 0.0, 0.0, 1.01])
    with pytest.raises(ValueError, match="about z"):
        yaw_from_quaternion([0.01, 0.0, 0.0, 1.0])
    with pytest.raises(NonFiniteError, match="not finite"):
        yaw_from_quaternion([0.0, 0.0, np.nan, 1.0])
    with pytest.raises(ValueError, match="zero norm"):
        check_quaternion(np.zeros(4))


def test_check_vector_copies_a_finite_vector_and_names_a_bad_one() -> None:
    given = [1.0, 2.0, 3.0]
    out = check_vector(given, 3, "goal")
    assert out.dtype == np.float64 and out.tolist() == given
    with pytest.raises(ValueError, match=r"^goal: expected 3 numbers"):
        check_vector(["a", 1, 2], 3, "goal")
    with pytest.raises(ValueError, match=r"^goal: expected shape \(3,\), got shape \(2,\)"):
        check_vector([1.0, 2.0], 3, "goal")
    with pytest.raises(ValueError, match=r"^pose: must be finite"):
        check_vector([0.0, np.inf, 0.0], 3, "pose")
