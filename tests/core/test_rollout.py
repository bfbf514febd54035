"""Unit tests of push_core.rollout: straight pushes of a disc pusher against an outline."""

import numpy as np
import pytest

from push_core.geometry import closest_point_on_polyline, object_to_world, world_to_object
from push_core.rollout import rollout_push

A = 0.05  # half side of a 10 cm square, metres
SQUARE = np.array([[-A, -A], [A, -A], [A, A], [-A, A]])  # counter-clockwise, object frame
R_P = 0.0048  # pusher radius
TOL = 5e-4  # contact tolerance (the default)
L, M = 0.04, 0.3  # l ~ 0.38 x side for a uniformly loaded square


def in_contact(result, b: int, k: int) -> bool:
    """Re-derive the contact test of substep k from the returned trajectory: the pusher touches
    the outline (linearised at the closest point) within the substep and moves into it."""
    q_start = world_to_object(result.poses[b, k], result.pusher[b, k])
    q_end = world_to_object(result.poses[b, k], result.pusher[b, k + 1])
    _, n_out, sd, _ = closest_point_on_polyline(SQUARE, q_start)
    approach = -(q_end - q_start) @ n_out
    return bool(approach > 0 and sd - R_P - approach <= TOL)


def test_push_through_the_com_translates_by_push_length_minus_gap():
    # Item 0: COM at the centre, pusher 12 mm (surface to surface) left of the left face,
    # pushing 5 cm along +x through the centre. Item 1: the same in a rotated, shifted world pose,
    # with the COM at (0, 0.01) and the pusher on the line through it (object frame).
    # Either way r' is parallel to n and the push sticks, so the object translates along the push
    # by 0.05 - 0.012 = 0.038 m without rotating. The pusher ends the first two substeps (travel
    # 5 and 10 mm) short of the face, touches during the third (travel 15 mm: the last 3 mm of
    # that substep push), and pushes in every later substep.
    pose0 = np.array([[0.0, 0.0, 0.0], [0.1, -0.2, 0.7]])
    com = np.array([[0.0, 0.0], [0.0, 0.01]])
    start_obj = np.array([[-A - R_P - 0.012, 0.0], [-A - R_P - 0.012, 0.01]])
    start = object_to_world(pose0, start_obj)
    push = object_to_world(pose0, start_obj + [0.05, 0.0]) - start
    result = rollout_push(SQUARE, pose0, com, L, M, start, push)

    assert result.poses.shape == (2, 11, 3) and result.contact.shape == (2, 10)
    np.testing.assert_array_equal(result.n_steps, [10, 10])
    np.testing.assert_allclose(result.poses[:, -1, :2] - pose0[:, :2], 0.76 * push, atol=1e-15)
    np.testing.assert_allclose(result.poses[:, -1, 2], pose0[:, 2], atol=1e-15)
    np.testing.assert_array_equal(result.contact, [[False, False] + [True] * 8] * 2)
    np.testing.assert_allclose(result.pusher[:, -1], start + push, atol=1e-15)
    np.testing.assert_allclose(result.contact_points[:, 2:], np.broadcast_to(
        start_obj[:, None] + [R_P + 0.012, 0], (2, 8, 2)), atol=1e-15)
    # The end-of-substep centre is 0.2 mm inside the face (5 mm substep, R_P = 4.8 mm) in the
    # rotated frame of item 1, so the normal (c - q)/|c - q| carries rounding of ~1e-17 / 2e-4.
    np.testing.assert_allclose(result.normals[:, 2:], np.broadcast_to([-1.0, 0.0], (2, 8, 2)),
                               atol=1e-12)
    assert not result.lost_contact.any()
    np.testing.assert_array_equal(result.first_lost_step, [-1, -1])


def test_substeps_and_shortened_last_substep():
    # 23 mm -> ceil(23 / 5) = 5 substeps: travel 5, 10, 15, 20, 23 mm; 50 mm -> exactly 10.
    result = rollout_push(SQUARE, [0.0, 0.0, 0.0], [0.0, 0.0], L, M,
                          [[0.0, 0.2], [0.0, 0.3]], [[0.0, 0.023], [0.05, 0.0]])
    np.testing.assert_array_equal(result.n_steps, [5, 10])
    travel = np.linalg.norm(result.pusher[0] - result.pusher[0, 0], axis=-1)
    np.testing.assert_allclose(travel[:6], [0.0, 0.005, 0.01, 0.015, 0.02, 0.023], atol=1e-15)
    # After its last substep, an item repeats its final state.
    np.testing.assert_array_equal(result.pusher[0, 5:], np.broadcast_to([0.0, 0.223], (6, 2)))


def test_push_that_never_touches_leaves_the_pose_unchanged():
    # The pusher passes above the square: its centre stays at y = 0.08 > A + R_P + TOL.
    pose0 = np.array([0.3, -0.1, 2.0])
    start = object_to_world(pose0, [-0.1, 0.08])
    push = object_to_world(pose0, [0.1, 0.08]) - start
    result = rollout_push(SQUARE, pose0, [0.01, 0.0], L, M, start, push)
    np.testing.assert_array_equal(result.poses, np.broadcast_to(pose0, (1, 41, 3)))
    assert not result.contact.any() and not result.lost_contact.any()
    np.testing.assert_array_equal(result.first_lost_step, [-1])
    # A zero-length push has no substeps.
    empty = rollout_push(SQUARE, pose0, [0.0, 0.0], L, M, start, [0.0, 0.0])
    assert empty.poses.shape == (1, 1, 3) and empty.contact.shape == (1, 0)
    np.testing.assert_array_equal(empty.n_steps, [0])
    np.testing.assert_array_equal(empty.first_lost_step, [-1])


def test_near_tangential_push_past_a_corner_loses_contact():
    # The pusher touches the left face (centre at x = -A - R_P) at y = 23.5 mm and moves almost
    # along the face towards the corner (-A, A): direction (sin b, cos b), b = 0.01 rad, 40 mm in
    # 8 substeps. Per substep it pushes the face in by only 5 mm * sin(b) = 0.05 mm, so the object
    # barely moves (drift and rotation below 0.3 mm at the corner). Starts of substeps in y:
    # 23.5, 28.5, ..., 48.5 mm (substep 5: on the face, 1.5 mm below the corner, so it touches
    # for the first part of the substep), then 53.5 mm (substep 6): 3.5 mm past the corner,
    # where the outward normal of the corner vertex is about (-R_P, 3.5 mm)/|.| and the push
    # (0.01, 1) moves away from it. So substeps 0-5 are in contact and 6 is the first without.
    b = 0.01
    start = np.array([-A - R_P, 0.0235])
    push = 0.04 * np.array([np.sin(b), np.cos(b)])
    result = rollout_push(SQUARE, [0.0, 0.0, 0.0], [0.0, 0.0], L, M, start, push)
    np.testing.assert_array_equal(result.contact[0], [True] * 6 + [False] * 2)
    np.testing.assert_array_equal(result.lost_contact, [True])
    np.testing.assert_array_equal(result.first_lost_step, [6])
    np.testing.assert_allclose(result.contact_points[0, :6, 0], -A, atol=1e-15)  # on the face
    np.testing.assert_allclose(result.contact_points[0, 6], [-A, A], atol=1e-15)  # the corner
    for k in range(8):
        assert in_contact(result, 0, k) == result.contact[0, k]


def test_angled_push_near_the_end_of_a_face_slides_off():
    # 60 deg from the inward normal (1, 0) towards the near corner, 10 mm below it, with
    # m = 0.2 (friction cone +-11.3 deg): the contact slides up the face, rounds the corner and
    # is lost; afterwards the pusher moves up and away over the top face (direction
    # (cos 60, sin 60)) and never touches again.
    start = np.array([-A - R_P, A - 0.01])
    push = 0.05 * np.array([np.cos(np.pi / 3), np.sin(np.pi / 3)])
    result = rollout_push(SQUARE, [0.0, 0.0, 0.0], [0.0, 0.0], L, 0.2, start, push)
    k = int(result.first_lost_step[0])
    assert result.lost_contact[0] and 0 < k < 10
    assert result.contact[0, :k].all() and not result.contact[0, k:].any()
    # The contact point climbs the left face while in contact (sliding towards the corner).
    y = result.contact_points[0, :k, 1]
    assert np.all(np.diff(y) > 0) and y[-1] > y[0] + 0.004
    # Where contact is lost the pusher centre is past the corner in the object frame.
    assert world_to_object(result.poses[0, k], result.pusher[0, k])[1] > A
    for j in range(10):
        assert in_contact(result, 0, j) == result.contact[0, j]
    # The pushed object turned clockwise (pushed above its COM) and moved.
    assert result.poses[0, -1, 2] < -0.01 and result.poses[0, -1, 0] > 0.001


def test_contact_point_is_recomputed_on_the_moved_outline():
    # Off-centre push along +x, 20 mm above the COM, low friction (m = 0.1, sliding). The push
    # rotates the object clockwise: omega = (r'x v_py - r'y v_px) / D < 0 for r' = (-A, 0.02)
    # and v_p ~ +x. In the object frame the pusher's path turns, so the contact point moves
    # along the face. A contact point that were not recomputed would stay at y = 0.02.
    start = np.array([-A - R_P, 0.02])
    result = rollout_push(SQUARE, [0.0, 0.0, 0.0], [0.0, 0.0], L, 0.1, start, [0.05, 0.0])
    assert result.contact.all()
    theta = result.poses[0, :, 2]
    assert np.all(np.diff(theta) < 0) and theta[-1] < -0.1
    points = result.contact_points[0]
    np.testing.assert_allclose(points[:, 0], -A, atol=1e-15)
    assert np.max(np.abs(points[:, 1] - 0.02)) > 0.003
    # Each contact point is the projection onto the face of the pusher centre at the start of
    # the substep, in the object frame moved by the earlier substeps.
    q_start = world_to_object(result.poses[0, :-1], result.pusher[0, :-1])
    np.testing.assert_allclose(points[:, 1], q_start[:, 1], atol=1e-15)
    # The pusher stays in touch: after each substep its centre is R_P from the face of the moved
    # square, up to the first-order error of one substep of the model (0.3 mm here).
    q_after = world_to_object(result.poses[0, 1:], result.pusher[0, 1:])
    np.testing.assert_allclose(-A - q_after[:, 0], R_P, atol=3e-4)


def test_batched_result_equals_per_item_results():
    rng = np.random.default_rng(30)
    batch = 6
    pose0 = np.column_stack([rng.uniform(-0.1, 0.1, (batch, 2)), rng.uniform(-np.pi, np.pi, batch)])
    com = rng.uniform(-0.01, 0.01, (batch, 2))
    l = rng.uniform(0.02, 0.06, batch)  # noqa: E741
    m = rng.uniform(0.05, 1.0, batch)
    # Pusher 1-10 mm outside the left face at random heights, pushing within +-60 deg of +x
    # (object frame) over 1-5 cm: lengths that are not multiples of the substep.
    start_obj = np.column_stack([-A - R_P - rng.uniform(0.001, 0.01, batch),
                                 rng.uniform(-0.045, 0.045, batch)])
    ang = rng.uniform(-np.pi / 3, np.pi / 3, batch)
    length = rng.uniform(0.01, 0.05, batch)
    push_obj = length[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    start = object_to_world(pose0, start_obj)
    push = object_to_world(pose0, start_obj + push_obj) - start
    result = rollout_push(SQUARE, pose0, com, l, m, start, push)
    assert result.contact.any()
    for b in range(batch):
        single = rollout_push(SQUARE, pose0[b], com[b], l[b], m[b], start[b], push[b])
        s = int(single.n_steps[0])
        assert s == result.n_steps[b]
        np.testing.assert_allclose(result.poses[b, : s + 1], single.poses[0], atol=1e-15)
        np.testing.assert_allclose(result.pusher[b, : s + 1], single.pusher[0], atol=1e-15)
        np.testing.assert_array_equal(result.contact[b, :s], single.contact[0])
        np.testing.assert_allclose(result.contact_points[b, :s], single.contact_points[0],
                                   atol=1e-15)
        np.testing.assert_allclose(result.normals[b, :s], single.normals[0], atol=1e-15)
        assert result.lost_contact[b] == single.lost_contact[0]
        assert result.first_lost_step[b] == single.first_lost_step[0]
        assert not result.contact[b, s:].any()
        np.testing.assert_array_equal(result.poses[b, s:], np.broadcast_to(
            result.poses[b, s], result.poses[b, s:].shape))


def test_bad_inputs_raise_value_errors_naming_the_argument():
    ok = {"outline": SQUARE, "pose0": np.zeros(3), "com": np.zeros(2), "l": L, "m": M,
          "pusher_start": np.zeros(2), "push": np.array([0.01, 0.0])}
    cases = [
        ({"outline": SQUARE[::-1]}, r"outline must be counter-clockwise"),
        ({"pose0": np.zeros(2)}, r"pose0 must have shape \(\.\.\., 3\)"),
        ({"push": np.zeros((2, 3))}, r"push must have shape \(\.\.\., 2\)"),
        ({"com": np.zeros((2, 2, 2))}, r"com must be unbatched or have one batch axis"),
        ({"pose0": np.zeros((3, 3)), "m": np.ones(2)}, r"batch sizes do not broadcast"),
    ]
    for changes, message in cases:
        with pytest.raises(ValueError, match=message):
            rollout_push(**{**ok, **changes})
    with pytest.raises(ValueError, match=r"substep must be > 0"):
        rollout_push(**ok, substep=0.0)
    with pytest.raises(ValueError, match=r"pusher_radius must be >= 0"):
        rollout_push(**ok, pusher_radius=-1.0)
