"""Details of push_core.robot_view.model: joint states, dilation, frames, bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

import push_core.robot_view.model as model
from push_core.robot_view import RobotGeometry, check_rigid_transform, dilate, joint_positions

ONE_BOX = """<robot name="one"><link name="root"/>
  <joint name="fix" type="fixed"><parent link="root"/><child link="body"/>
    <origin xyz="0 0 1"/></joint>
  <link name="body"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
    <visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link></robot>"""


def test_joint_positions_pick_the_chain_out_of_a_joint_state() -> None:
    q = joint_positions(("a", "b"), ["x", "b", "a"], [9.0, 2.0, 1.0])
    assert q.tolist() == [1.0, 2.0]
    for names, positions, match in [(["a"], [1.0, 2.0], "1 names but 2"),
                                    (["a", "a"], [1.0, 2.0], "twice"),
                                    (["a", "x"], [1.0, 2.0], "missing"),
                                    (["a", "b"], [1.0, math.nan], "non-finite")]:
        with pytest.raises(ValueError, match=match):
            joint_positions(("a", "b"), names, positions)


def test_a_robot_without_joints_and_its_visual_geometry() -> None:
    robot = RobotGeometry.from_urdf(ONE_BOX)
    assert robot.joint_names == () and robot.base_link == "root"
    tri, closed = robot.triangles([], [])
    assert np.allclose(tri.reshape(-1, 3).max(axis=0), [0.1, 0.1, 1.1]) and closed.all()
    visual = RobotGeometry.from_urdf(ONE_BOX, kind="visual")
    tri_v, _ = visual.triangles([], [])
    assert np.allclose(tri_v.reshape(-1, 3).max(axis=0), [0.05, 0.05, 1.05])
    # In another frame: world -> frame shifts everything by -1 m along z.
    t = np.eye(4)
    t[2, 3] = -1.0
    tri_f, _ = robot.triangles([], [], t)
    assert np.allclose(tri_f, tri - [0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="kind"):
        RobotGeometry.from_urdf(ONE_BOX, kind="inertial")


def test_the_triangle_count_is_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(model, "MAX_TRIANGLES", 11)
    with pytest.raises(ValueError, match="12 triangles, more than 11"):
        RobotGeometry.from_urdf(ONE_BOX)


def test_dilate_grows_by_a_disc_and_takes_the_nearest_depth() -> None:
    mask = np.zeros((9, 9), dtype=bool)
    mask[4, 4] = mask[4, 5] = True
    depth = np.full((9, 9), np.nan, dtype=np.float32)
    depth[4, 4], depth[4, 5] = 2.0, 1.0
    grown, grown_depth = dilate(mask, depth, 2)
    yy, xx = np.mgrid[:9, :9]
    disc = ((yy - 4) ** 2 + (xx - 4) ** 2 <= 4) | ((yy - 4) ** 2 + (xx - 5) ** 2 <= 4)
    assert np.array_equal(grown, disc)
    assert grown_depth[4, 4] == 2.0  # a robot pixel keeps its own depth
    assert grown_depth[4, 7] == 1.0 and grown_depth[4, 2] == 2.0
    assert np.all(np.isnan(grown_depth[~grown]))


def test_rigid_transform_check() -> None:
    assert check_rigid_transform(np.eye(4), "t").dtype == np.float64
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="t must be"):
        check_rigid_transform(mirror, "t")
