"""The robot-geometry API (push_core.robot_view): link poses and a rendered robot, by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.robot_view import RobotGeometry, base_transform

TOY = """<robot name="toy">
  <link name="base"><collision><origin xyz="0 0 0.05"/><geometry><box size="0.1 0.1 0.1"/>
    </geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="arm"><collision><origin xyz="0.2 0 0"/><geometry><box size="0.4 0.05 0.05"/>
    </geometry></collision></link>
  <joint name="j2" type="continuous"><parent link="arm"/><child link="tool"/>
    <origin xyz="0.4 0 0"/><axis xyz="1 0 0"/></joint>
  <link name="tool"/>
  <joint name="slide" type="prismatic"><parent link="tool"/><child link="finger"/>
    <axis xyz="0 0 -1"/><limit lower="0" upper="0.1" effort="1" velocity="1"/></joint>
  <link name="finger"/>
</robot>"""
JOINTS = ["slide", "j2", "j1"]


def rz(a: float) -> np.ndarray:
    t = np.eye(4)
    t[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    return t


def rx(a: float) -> np.ndarray:
    t = np.eye(4)
    t[1:3, 1:3] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    return t


def shift(x: float, y: float, z: float) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t


def test_link_poses_by_hand() -> None:
    robot = RobotGeometry.from_urdf(TOY, base_pose=(1.0, 2.0, 0.5, math.pi / 2))
    assert robot.joint_names == ("j1", "j2", "slide")
    assert set(robot.link_names) == {"base", "arm", "tool", "finger"}
    q = {"j1": 0.7, "j2": 0.3, "slide": 0.05}
    poses = robot.link_poses(list(q), list(q.values()))
    base = base_transform((1.0, 2.0, 0.5, math.pi / 2))
    arm = base @ shift(0, 0, 0.1) @ rz(0.7)
    tool = arm @ shift(0.4, 0, 0) @ rx(0.3)
    finger = tool @ shift(0, 0, -0.05)
    for name, expected in (("base", base), ("arm", arm), ("tool", tool), ("finger", finger)):
        assert np.allclose(poses[name], expected, atol=1e-12), name
    # A continuous joint one turn further is the same posture; extra names are ignored.
    again = robot.link_poses([*q, "other"], [0.7, 0.3 + 2 * math.pi, 0.05, 9.0])
    assert np.allclose(again["finger"], finger, atol=1e-12)


def camera_above(x: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """K (f = 500 px, 640 x 480) and T_world_camera of a camera at (x, 0, height) looking
    straight down, image x along world x, image y along world -y."""
    k = np.array([[500.0, 0.0, 319.5], [0.0, 500.0, 239.5], [0.0, 0.0, 1.0]])
    t = np.eye(4)
    t[:3, :3] = np.column_stack([[1, 0, 0], [0, -1, 0], [0, 0, -1]])
    t[:3, 3] = (x, 0.0, height)
    return k, t


def test_render_by_hand() -> None:
    robot = RobotGeometry.from_urdf(TOY)
    k, t = camera_above(0.2, 2.125)
    mask, depth = robot.render(k, t, 640, 480, JOINTS, [0.0, 0.0, 0.0])
    # The arm's top face (z = 0.125) is 2.0 m below the camera, the base's (z = 0.1) 2.025 m.
    # Column 320 is x = 0.202 m; the arm spans |y| <= 0.025 m: v = 239.5 -+ 500 * 0.025 / 2.
    assert depth[240, 320] == pytest.approx(2.0)
    assert np.array_equal(np.nonzero(mask[:, 320])[0], np.arange(234, 246))
    u_base = int(round(319.5 + 500 * (-0.025 - 0.2) / 2.025))  # x = -0.025 m: base only
    assert depth[240, u_base] == pytest.approx(2.025)
    assert not mask[240, int(319.5 + 500 * (-0.1 - 0.2) / 2.025)]  # x = -0.1 m: nothing
    assert np.all(np.isnan(depth[~mask]))
    # Dilation by 3 px: three more rows each side, with the depth of the nearest robot pixel.
    grown, grown_depth = robot.render(k, t, 640, 480, JOINTS, [0.0, 0.0, 0.0], dilate_px=3)
    assert np.array_equal(np.nonzero(grown[:, 320])[0], np.arange(231, 249))
    assert grown_depth[231, 320] == pytest.approx(2.0)
    # Turned by j1 = 90 degrees the arm lies along +y: the pixel above (0.35, 0) m is free.
    turned, _ = robot.render(k, t, 640, 480, JOINTS, [0.0, 0.0, math.pi / 2])
    u = int(round(319.5 + 500 * (0.35 - 0.2) / 2.0))
    assert mask[240, u] and not turned[240, u]
    assert turned[164, 270]  # above (0.002, 0.302) m: the turned arm


def test_bad_input_is_a_clear_error() -> None:
    robot = RobotGeometry.from_urdf(TOY)
    k, t = camera_above(0.2, 2.125)
    with pytest.raises(ValueError, match=r"joints \['slide'\] missing"):
        robot.link_poses(["j1", "j2"], [0.0, 0.0])
    with pytest.raises(ValueError, match="non-finite"):
        robot.link_poses(JOINTS, [0.0, math.nan, 0.0])
    with pytest.raises(ValueError, match="appears twice"):
        robot.link_poses([*JOINTS, "j1"], [0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="rigid transform"):
        robot.render(k, t * 2, 640, 480, JOINTS, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="dilate_px"):
        robot.render(k, t, 640, 480, JOINTS, [0.0, 0.0, 0.0], dilate_px=-1)
    with pytest.raises(ValueError, match="base link 'arm' moves with joint 'j1'"):
        RobotGeometry.from_urdf(TOY, base_link="arm")
    with pytest.raises(ValueError, match="no link 'nothing'"):
        RobotGeometry.from_urdf(TOY, base_link="nothing")
    with pytest.raises(ValueError, match="base_pose"):
        RobotGeometry.from_urdf(TOY, base_pose=(0.0, 0.0, math.inf, 0.0))
    with pytest.raises(ValueError, match="not a valid URDF|not XML"):
        RobotGeometry.from_urdf("<robot name='x'><link></robot>")
    with pytest.raises(ValueError, match="empty"):
        RobotGeometry.from_urdf("  ")
    with pytest.raises(ValueError, match="characters"):
        RobotGeometry.from_urdf(TOY + " " * 4_000_000)
