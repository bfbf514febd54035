"""In-process tests of the ROS-free pybullet world (``sim_bridge.world``); real pybullet, seeded.

Camera geometry, push physics against expectations from geometry and the quasi-static model,
input validation, determinism and randomisation ranges.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from push_core.geometry import closest_point_on_polyline, object_to_world
from push_core.model import push_twist
from push_core.objects import load_object
from sim_bridge.camera import CameraConfig, deproject, project
from sim_bridge.scene import _area, support_cells
from sim_bridge.world import (
    COM_SHRINK,
    FRICTION_PUSHER_RANGE,
    FRICTION_TABLE_RANGE,
    MASS_FACTOR_RANGE,
    PushWorld,
    WorldConfig,
    push_points,
)

R_P = 0.0048  # default pusher radius
RECT_HALF = 0.045  # rect1 is a 90 mm square


@pytest.fixture(scope="module")
def rect_world():
    world = PushWorld(WorldConfig(object="rect1"))
    yield world
    world.close()


@pytest.fixture(scope="module")
def posed_frame():
    """rect1 away from the origin and rotated, with its true pose and one frame."""
    pose = (0.06, -0.04, 0.5)
    with PushWorld(WorldConfig(object="rect1", object_pose=pose)) as world:
        yield world.object_spec, world.object_outline(), world.object_pose(), world.render()


# ------------------------------------------------------------------- camera
def test_intrinsics_follow_the_image_size():
    full = PushWorld(WorldConfig(camera=CameraConfig(width=640, height=480)))
    small = PushWorld(WorldConfig(camera=CameraConfig(width=320, height=240)))
    k = full.camera_matrix
    assert k[0, 0] == pytest.approx(615.0) and k[1, 1] == pytest.approx(615.0)
    assert (k[0, 2], k[1, 2]) == (319.5, 239.5)
    np.testing.assert_allclose(small.camera_matrix[:2, :2], k[:2, :2] / 2)
    frame = small.render()
    assert frame.rgb.shape == (240, 320, 3) and frame.rgb.dtype == np.uint8
    assert frame.depth.shape == (240, 320) and frame.depth.dtype == np.float32
    assert frame.mask.shape == (240, 320) and frame.mask.dtype == bool
    # A proper rotation; optical axis looking down at 55 degrees; camera 0.8 m from its aim.
    t = full.T_world_camera
    np.testing.assert_allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(t[:3, :3]) == pytest.approx(1.0)
    assert np.degrees(np.arcsin(-t[2, 2])) == pytest.approx(55.0)
    assert np.linalg.norm(t[:3, 3] - [0.03, 0.0, 0.0]) == pytest.approx(0.8)
    # The whole workspace is in view (corners at table and object-top height).
    (x0, x1), (y0, y1) = full.workspace
    corners = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (0.0, 0.013)])
    uv = project(corners, k, t)
    assert np.all(uv >= 0) and np.all(uv[:, 0] <= 639) and np.all(uv[:, 1] <= 479)
    full.close()
    small.close()


def test_table_pixels_deproject_to_the_table_plane(posed_frame):
    _, _, _, frame = posed_frame
    table = ~frame.mask & np.isfinite(frame.depth)
    assert table.mean() > 0.9
    points = deproject(frame.depth, frame.camera_matrix, frame.T_world_camera)
    assert np.abs(points[..., 2][table]).max() < 2e-3
    # One pixel, spelled out: deproject with K and T_world_camera by hand.
    v, u = 400, 100
    k, t = frame.camera_matrix, frame.T_world_camera
    z = float(frame.depth[v, u])
    cam = np.array([(u - k[0, 2]) / k[0, 0] * z, (v - k[1, 2]) / k[1, 1] * z, z])
    assert abs((t[:3, :3] @ cam + t[:3, 3])[2]) < 2e-3


def test_object_pixels_deproject_onto_the_true_object(posed_frame):
    spec, outline, pose, frame = posed_frame
    points = deproject(frame.depth, frame.camera_matrix, frame.T_world_camera)[frame.mask]
    assert len(points) > 1000
    _, _, dist, _ = closest_point_on_polyline(outline, points[:, :2])
    assert np.mean(dist < 1e-3) > 0.99  # inside the true outline (side walls lie on it)
    assert dist.max() < 3e-3
    on_top = np.abs(points[:, 2] - spec.thickness) < 1e-3
    assert on_top.mean() > 0.8  # the rest is the side walls facing the camera
    centre = np.array([pose[0], pose[1], spec.thickness])
    u, v = np.round(project(centre, frame.camera_matrix, frame.T_world_camera)).astype(int)
    assert frame.mask[v, u]
    np.testing.assert_allclose(frame.object_pose, pose)


def test_depth_is_nan_where_nothing_is_hit():
    cam = CameraConfig(width=160, height=120, elevation_deg=15.0)  # sees past the table
    with PushWorld(WorldConfig(camera=cam)) as world:
        frame = world.render()
    sky = np.isnan(frame.depth)
    assert 0.05 < sky.mean() < 0.9
    assert not np.any(frame.mask & sky)
    assert sky[0].mean() > 0.8 and not sky[-1].any()  # the top row sees past the table


def test_depth_noise_and_appearance_randomisation_are_seeded():
    cfg = WorldConfig(camera=CameraConfig(width=320, height=240), depth_noise=True,
                      randomize_appearance=True, randomize_camera=True, seed=5)
    with PushWorld(cfg) as world:
        first = world.render()
        second = world.render()
        world.reset(cfg)
        again = world.render()
        clean = PushWorld(WorldConfig(camera=CameraConfig(width=320, height=240)))
        reference = clean.render()
    np.testing.assert_array_equal(first.rgb, again.rgb)
    np.testing.assert_array_equal(first.depth, again.depth)
    assert not np.array_equal(np.nan_to_num(first.depth), np.nan_to_num(second.depth))
    assert not np.allclose(first.rgb.mean(axis=(0, 1)), reference.rgb.mean(axis=(0, 1)), atol=2)
    assert not np.allclose(first.T_world_camera, reference.T_world_camera)
    dropped = np.isnan(first.depth) & ~np.isnan(reference.depth)
    assert 0.002 < dropped.mean() < 0.05
    # Depth stays metric: table pixels still deproject to z = 0 within the noise.
    table = ~first.mask & np.isfinite(first.depth)
    z = deproject(first.depth, first.camera_matrix, first.T_world_camera)[..., 2][table]
    assert abs(np.median(z)) < 1e-3 and 2e-4 < np.std(z) < 3e-3
    clean.close()


# ------------------------------------------------------------------- pushing
def test_central_push_moves_the_object_forward(rect_world):
    world = rect_world
    world.reset()
    t0 = world.sim_time
    contact = np.array([-RECT_HALF - R_P, 0.0])
    approach, end = contact - [0.01, 0.0], contact + [0.05, 0.0]
    wall = time.perf_counter()
    res = world.execute_push(approach, contact, end)
    wall = time.perf_counter() - wall
    moved = res.pose_after - res.pose_before
    assert res.touched and res.settled
    assert moved[0] == pytest.approx(0.05, abs=1.5e-3)  # stroke 60 mm minus the 10 mm gap
    assert abs(moved[1]) < 1e-3
    assert abs(np.degrees(moved[2])) < 3.0
    np.testing.assert_allclose(res.pusher_start, approach, atol=5e-4)
    np.testing.assert_allclose(res.pusher_end, end, atol=1e-3)
    assert res.t_end - res.t_start == pytest.approx(0.06 / 0.02, abs=0.01)
    assert t0 < res.t_start < res.t_end <= res.t_done == world.sim_time
    np.testing.assert_allclose(world.object_pose(), res.pose_after)
    assert world.sim_time - t0 > 3 * wall  # much faster than real time


def test_push_that_misses_leaves_the_object_in_place(rect_world):
    world = rect_world
    world.reset()
    y = RECT_HALF + R_P + 0.002
    res = world.execute_push([-0.1, y], [0.0, y], [0.1, y])
    assert not res.touched
    assert np.linalg.norm(res.pose_after[:2] - res.pose_before[:2]) < 5e-4
    assert abs(res.pose_after[2] - res.pose_before[2]) < np.radians(0.1)


@pytest.mark.parametrize("offset", [0.03, -0.03])
def test_off_centre_push_rotates_as_the_model_predicts(rect_world, offset):
    world = rect_world
    world.reset()
    spec = world.object_spec
    contact = np.array([-RECT_HALF - R_P, offset])
    res = world.execute_push(contact - [0.01, 0.0], contact, contact + [0.03, 0.0])
    predicted = push_twist([0.03, 0.0], [-RECT_HALF, offset], [1.0, 0.0], spec.com,
                           spec.limit_surface_guess(), spec.friction_pusher)
    turned = res.pose_after[2] - res.pose_before[2]
    assert np.sign(turned) == np.sign(predicted[2]) == -np.sign(offset)
    assert abs(np.degrees(turned)) > 3.0
    assert res.pose_after[0] - res.pose_before[0] > 0.01


def test_butter_is_pushed_into_its_waist():
    """Butter's waist (x = -27.7 mm at y = 0) is 20 mm inside its convex hull (x = -47.8 mm):
    the pusher must reach it, proving the collision shape keeps the concavity."""
    with PushWorld(WorldConfig(object="butter")) as world:
        waist = -0.0277 - R_P
        approach = np.array([-0.075, 0.0])
        short = world.execute_push(approach, [waist, 0.0], [waist - 0.0015, 0.0])
        assert not short.touched
        assert short.pusher_end[0] + R_P > -0.0478 + 0.015  # 15 mm inside the convex hull
        assert np.linalg.norm(short.pose_after - short.pose_before) < 5e-4
        res = world.execute_push(approach, [waist, 0.0], [waist + 0.02, 0.0])
    assert res.touched
    moved = res.pose_after - res.pose_before
    # 20 mm past the waist contact; the convex hull would have given about 40 mm.
    assert moved[0] == pytest.approx(0.02, abs=2e-3)
    assert abs(np.degrees(moved[2])) < 3.0


BAD_PUSHES = [
    (([np.nan, 0.0], [-0.05, 0.0], [0.0, 0.0]), r"approach: must be finite"),
    (([-0.06, 0.0], [-0.05, np.inf], [0.0, 0.0]), r"contact: must be finite"),
    (([-0.06, 0.0], [-0.05, 0.0], [0.0, 0.0, 0.0]), r"end: expected a point \(x, y\) of shape"),
    (("a", [-0.05, 0.0], [0.0, 0.0]), r"approach: expected a point"),
    (([-0.06, 0.0], [-0.05, 0.0], [0.3, 0.0]), r"end: .* outside the workspace"),
    (([-0.06, 0.0], [-0.05, 0.0], [-0.0495, 0.0]), r"push too short"),
    (([-0.24, 0.0], [-0.23, 0.0], [0.0, 0.0]), r"push too long"),
    (([-0.06, 0.005], [-0.05, 0.0], [0.0, 0.0]), r"contact: .* off the straight line"),
    (([-0.2, 0.0], [-0.05, 0.0], [0.0, 0.0]), r"approach: .* from the contact point"),
    (([-0.03, 0.0], [-0.02, 0.0], [0.0, 0.0]), r"approach: .* inside the object"),
    (([-0.048, 0.0], [-0.045, 0.0], [0.0, 0.0]), r"approach: .* mm from the object's outline"),
]


def test_bad_pushes_raise_clear_errors_and_the_world_keeps_working(rect_world):
    world = rect_world
    world.reset()
    pose, t, pusher = world.object_pose(), world.sim_time, world.pusher_position()
    for args, message in BAD_PUSHES:
        with pytest.raises(ValueError, match=message):
            world.execute_push(*args)
    np.testing.assert_array_equal(world.object_pose(), pose)
    np.testing.assert_array_equal(world.pusher_position(), pusher)
    assert world.sim_time == t
    res = world.execute_push([-0.065, 0.0], [-0.0498, 0.0], [-0.03, 0.0])
    assert res.touched and res.pose_after[0] > 0.015


def test_push_points_and_check_push(rect_world):
    world = rect_world
    world.reset()
    # Outline point in the middle of rect1's -x face, outward normal -x, 30 deg off the normal.
    a, c, e = push_points((0.0, 0.0, np.pi / 2), [-RECT_HALF, 0.0], [-1.0, 0.0],
                          np.radians(30.0), 0.04, pusher_radius=R_P, gap=0.01)
    # The object is turned by 90 deg, so that face now looks along -y.
    np.testing.assert_allclose(c, [0.0, -RECT_HALF - R_P], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(e - c), 0.04)
    np.testing.assert_allclose(np.linalg.norm(c - a), 0.01)
    direction = (e - c) / 0.04
    assert np.degrees(np.arccos(direction @ [0.0, 1.0])) == pytest.approx(30.0)
    world.set_object_pose((0.0, 0.0, np.pi / 2))
    checked = world.check_push(a, c, e)
    np.testing.assert_array_equal(checked[1], c)
    with pytest.raises(ValueError, match="push too short"):
        world.check_push(a, c, c + 1e-4 * direction)


def test_invalid_configs_raise_and_reset_keeps_the_previous_scene(rect_world):
    with pytest.raises(ValueError, match="object_pose: position"):
        WorldConfig(object_pose=(0.5, 0.0, 0.0))
    with pytest.raises(ValueError, match="push_speed"):
        WorldConfig(push_speed=-0.02)
    with pytest.raises(ValueError, match="mass"):
        WorldConfig(mass=0.0)
    with pytest.raises(ValueError, match="camera.width"):
        CameraConfig(width=0)
    for cell in (0.001, 0.2, -0.01, float("nan"), True):
        with pytest.raises(ValueError, match="support_cell"):
            WorldConfig(support_cell=cell)
    world = rect_world
    world.reset(WorldConfig(object="rect1"))
    with pytest.raises(ValueError, match="unknown object 'no_such_object'"):
        world.reset(WorldConfig(object="no_such_object"))
    with pytest.raises(ValueError, match="com_offset"):
        world.reset(WorldConfig(object="rect1", com_offset=(0.2, 0.0)))  # outside the outline
    assert world.object_spec.name == "rect1"
    assert world.execute_push([-0.065, 0.0], [-0.0498, 0.0], [-0.04, 0.0]).touched


def test_reset_with_the_same_seed_reproduces_exactly():
    cfg = WorldConfig(object="hex", object_pose=(0.02, 0.01, 0.3), randomize=True, seed=11)
    push = ([-0.09, 0.02], [-0.06, 0.025], [0.0, 0.035])
    with PushWorld(cfg) as world:
        first = world.execute_push(*push)
        spec = world.object_spec
        world.reset()
        second = world.execute_push(*push)
        again = world.object_spec
        assert (again.mass, again.friction_table, again.friction_pusher) == (
            spec.mass, spec.friction_table, spec.friction_pusher)
        np.testing.assert_array_equal(again.com, spec.com)
        world.reset(WorldConfig(object="hex", object_pose=(0.02, 0.01, 0.3), randomize=True,
                                seed=12))
        assert world.object_spec.mass != spec.mass
    assert first.touched
    np.testing.assert_array_equal(first.pose_after, second.pose_after)
    np.testing.assert_array_equal(first.pusher_end, second.pusher_end)
    assert first.t_done == second.t_done


def test_randomisation_stays_in_the_documented_ranges():
    base = load_object("butter")
    shrunk = base.polyline() * (1.0 - COM_SHRINK)
    masses, coms = [], []
    for seed in range(8):
        with PushWorld(WorldConfig(object="butter", randomize=True, seed=seed)) as world:
            spec = world.object_spec
        assert MASS_FACTOR_RANGE[0] <= spec.mass / base.mass <= MASS_FACTOR_RANGE[1]
        assert FRICTION_TABLE_RANGE[0] <= spec.friction_table <= FRICTION_TABLE_RANGE[1]
        assert FRICTION_PUSHER_RANGE[0] <= spec.friction_pusher <= FRICTION_PUSHER_RANGE[1]
        assert closest_point_on_polyline(shrunk, spec.com)[2] < 0
        masses.append(spec.mass)
        coms.append(spec.com)
    assert len(set(masses)) == 8 and np.ptp(np.array(coms), axis=0).min() > 0.005
    # Explicit overrides win and do not change the other random draws.
    over = PushWorld(WorldConfig(object="butter", randomize=True, seed=0, mass=2.0,
                                 friction_pusher=0.3))
    plain = PushWorld(WorldConfig(object="butter", randomize=True, seed=0))
    assert over.object_spec.mass == 2.0 and over.object_spec.friction_pusher == 0.3
    np.testing.assert_array_equal(over.object_spec.com, plain.object_spec.com)
    assert over.object_spec.friction_table == plain.object_spec.friction_table
    over.close()
    plain.close()


def test_com_offset_moves_the_inertial_frame_not_the_object_frame():
    com = (0.02, -0.01)
    with PushWorld(WorldConfig(object="rect1", object_pose=(0.03, 0.02, 0.7),
                               com_offset=com)) as world:
        np.testing.assert_allclose(world.object_pose(), [0.03, 0.02, 0.7], atol=1e-4)
        np.testing.assert_array_equal(world.object_spec.com, com)
        client = world._client  # the pybullet COM must sit at the offset, in world
        com_world = client.getBasePositionAndOrientation(world._object)[0]
        expected = object_to_world(world.object_pose(), np.array(com))
        np.testing.assert_allclose(com_world[:2], expected, atol=2e-5)  # tilt < 0.2 deg
        # Pushing through the object centre on a line that misses the COM rotates it.
        res = world.execute_push([-0.05, 0.02], [-0.03, 0.02], [0.0, 0.02])
    assert res.touched and abs(res.pose_after[2] - res.pose_before[2]) > np.radians(1)


def test_worlds_in_one_process_are_independent():
    a = PushWorld(WorldConfig(object="rect1"))
    b = PushWorld(WorldConfig(object="rect1"))
    a.execute_push([-0.065, 0.0], [-0.0498, 0.0], [-0.02, 0.0])
    assert a.object_pose()[0] > 0.02
    assert abs(b.object_pose()[0]) < 1e-4
    assert b.sim_time < a.sim_time
    a.close()
    b.close()


def test_place_pusher_refuses_overlap_and_parks_again(rect_world):
    pose = rect_world.object_pose()
    parked = rect_world.pusher_position()
    half_x = 0.5 * np.ptp(rect_world.object_spec.shape.vertices[:, 0])
    inside = object_to_world(pose, np.array([0.0, 0.0]))
    touching = object_to_world(pose, np.array([half_x + 0.001, 0.0]))  # 1 mm < pusher radius
    for bad in (inside, touching):
        with pytest.raises(ValueError, match="overlap"):
            rect_world.place_pusher(bad)
    with pytest.raises(ValueError, match="lift"):
        rect_world.place_pusher(object_to_world(pose, np.array([half_x + 0.02, 0.0])), -0.01)
    beside = object_to_world(pose, np.array([half_x + 0.02, 0.0]))
    before = rect_world.render()
    rect_world.place_pusher(beside)
    np.testing.assert_allclose(rect_world.pusher_position(), beside, atol=1e-9)
    assert np.any(rect_world.render().rgb != before.rgb)  # the pusher is in view
    rect_world.park_pusher()
    np.testing.assert_allclose(rect_world.pusher_position(), parked, atol=1e-9)
    np.testing.assert_allclose(rect_world.object_pose(), pose, atol=1e-9)  # never touched


def test_quiet_stdout_silences_c_level_prints_only_inside(capfd):
    import os

    from sim_bridge.world import quiet_stdout

    os.write(1, b"before\n")
    with quiet_stdout():
        os.write(1, b"inside\n")  # what pybullet's C code does
    os.write(1, b"after\n")
    assert capfd.readouterr().out == "before\nafter\n"


# ------------------------------------------------------------------- non-convex outlines
#: A U (10 x 8 cm, 2 cm arms and base, area centroid in the gap, 8.18 mm above the source
#: origin) and a cross (10 cm, 3 cm arms), counter-clockwise, source frames.
U_SHAPE = [[-0.05, -0.04], [0.05, -0.04], [0.05, 0.04], [0.03, 0.04], [0.03, -0.02],
           [-0.03, -0.02], [-0.03, 0.04], [-0.05, 0.04]]
CROSS = [[0.015, -0.015], [0.05, -0.015], [0.05, 0.015], [0.015, 0.015], [0.015, 0.05],
         [-0.015, 0.05], [-0.015, 0.015], [-0.05, 0.015], [-0.05, -0.015], [-0.015, -0.015],
         [-0.015, -0.05], [0.015, -0.05]]


def _spec_file(tmp_path, name, vertices):
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"shape:\n  type: polygon\n  vertices: {vertices}\nthickness: 0.013\n"
                    "density: 7850\n")
    return path


@pytest.mark.parametrize("name, vertices, pose", [("u", U_SHAPE, (0.02, -0.01, 0.4)),
                                                  ("cross", CROSS, (0.0, 0.03, -0.3))])
def test_non_convex_mask_matches_the_footprint(tmp_path, name, vertices, pose):
    from push_core.objects import _sample_area

    with PushWorld(WorldConfig(object=_spec_file(tmp_path, name, vertices),
                               object_pose=pose)) as world:
        spec, outline, frame = world.object_spec, world.object_outline(), world.render()
    assert not spec.shape.is_convex
    # Every mask pixel is on the object (a pixel in a concavity would deproject onto the table
    # there, millimetres outside the outline), and the whole top face is in the mask.
    points = deproject(frame.depth, frame.camera_matrix, frame.T_world_camera)[frame.mask]
    _, _, dist, _ = closest_point_on_polyline(outline, points[:, :2])
    assert len(points) > 2000 and dist.max() < 1e-4
    top = object_to_world(frame.object_pose,
                          _sample_area(spec.shape, 3000, np.random.default_rng(0)))
    uv = project(np.column_stack([top, np.full(len(top), spec.thickness)]),
                 frame.camera_matrix, frame.T_world_camera)
    u, v = np.round(uv).T.astype(int)
    assert frame.mask[v, u].mean() > 0.98  # the rest are pixel-boundary roundings


def test_u_is_pushed_inside_its_gap_and_the_cross_into_its_corner(tmp_path):
    """The pusher reaches the U's inner base edge (20 mm below the hull's top edge) and the
    cross's reflex corner (18 mm inside its hull): the collision shape keeps the concavities."""
    with PushWorld(WorldConfig(object=_spec_file(tmp_path, "u", U_SHAPE))) as world:
        inner = -0.02 + world.object_spec.source_origin[1]  # the base's inner edge, object y
        contact = np.array([0.0, inner + R_P])
        res = world.execute_push([0.0, 0.07], contact, contact - [0.0, 0.02])
    moved = res.pose_after - res.pose_before  # a hull would be met 60 mm earlier
    assert res.touched and moved[1] == pytest.approx(-0.02, abs=2e-3)
    assert abs(moved[0]) < 1e-3 and abs(np.degrees(moved[2])) < 1.0
    with PushWorld(WorldConfig(object=_spec_file(tmp_path, "cross", CROSS))) as world:
        d = -np.ones(2) / np.sqrt(2)
        contact = np.full(2, 0.015 + R_P)  # touching both edges of the corner
        res = world.execute_push(contact - 0.03 * d, contact, contact + 0.02 * d)
    moved = res.pose_after - res.pose_before
    # 20 mm along the push (a hull-shaped collision body would be met 18 mm before the corner
    # and moved about 40 mm); the
    # orientation is not checked, a push into a right-angled corner turns it a few degrees.
    assert res.touched and moved[:2] @ d == pytest.approx(0.02, abs=2e-3)


def test_random_com_of_a_u_lies_in_its_area_in_base_and_arms(tmp_path):
    path = _spec_file(tmp_path, "u", U_SHAPE)
    coms = []
    for seed in range(12):
        with PushWorld(WorldConfig(object=path, randomize=True, seed=seed)) as world:
            coms.append(world.object_spec.com)
            outline = world.object_spec.polyline()
    coms = np.array(coms)
    assert np.all(closest_point_on_polyline(outline, coms)[2] < 0)  # in the area, not the gap
    base_top = -0.02 + load_object(path).source_origin[1]
    assert np.any(coms[:, 1] < base_top) and np.any(coms[:, 1] > base_top)


# ------------------------------------------------------------------- support cells
def test_support_cells_of_a_rectangle_and_a_triangle_by_hand():
    rect = np.array([[0.0, 0.0], [0.03, 0.0], [0.03, 0.02], [0.0, 0.02]])
    cells = support_cells([rect], 0.01)
    assert len(cells) == 6  # 3 x 2 squares of 1 cm
    for c in cells:
        assert len(c) == 4 and _area(c) == pytest.approx(1e-4)
    tri = np.array([[0.0, 0.0], [0.04, 0.0], [0.0, 0.04]])  # area 8 cm^2, legs on grid lines
    cells = support_cells([tri], 0.01)
    # 6 full squares below the diagonal, 4 half squares on it
    assert sorted(round(_area(c) * 1e4, 6) for c in cells) == [0.5] * 4 + [1.0] * 6
    assert sum(_area(c) for c in cells) == pytest.approx(8e-4)
    offset = tri + [0.005, 0.0]  # off the grid: cut into more, smaller pieces, same total
    assert sum(_area(c) for c in support_cells([offset], 0.01)) == pytest.approx(8e-4)
    with pytest.raises(ValueError, match="support cell"):
        support_cells([tri], 0.0)


def _table_contacts(world: PushWorld) -> int:
    points, force = world.support_contacts()
    assert points.shape == (len(force), 2) and np.all(force >= 0.0)
    # at rest the table carries the object's weight (g = 9.81)
    assert force.sum() == pytest.approx(9.81 * world.object_spec.mass, rel=0.05)
    return len(force)


def test_cut_support_spreads_the_contacts_and_pushes_as_before():
    # Whole, tri1's single convex piece rests on its 3 corners; cut into 15 mm cells, on many
    # points across its footprint. A central push still moves it straight ahead.
    with PushWorld(WorldConfig(object="tri1", com_offset=(0.0, 0.0))) as whole:
        assert _table_contacts(whole) <= 4
    cfg = WorldConfig(object="rect1", support_cell=0.015)
    with PushWorld(cfg) as world:
        assert _table_contacts(world) >= 20
        contact = np.array([-RECT_HALF - R_P, 0.0])
        res = world.execute_push(contact - [0.01, 0.0], contact, contact + [0.05, 0.0])
        moved = res.pose_after - res.pose_before
        assert res.touched and res.settled
        assert moved[0] == pytest.approx(0.05, abs=1.5e-3) and abs(moved[1]) < 1e-3
        assert abs(np.degrees(moved[2])) < 3.0
