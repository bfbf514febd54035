"""push_executor.kinematics: chain extraction, FK (hand-derived and against pybullet), IK.

No rclpy. The Panda is pybullet_data's franka_panda/panda.urdf (fingers included: their joints
are not in the base -> flange chain and must be ignored).
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from push_core.robot_view import MAX_URDF_CHARS, base_transform
from push_executor.kinematics import DEFAULT_ACCELERATION, DEFAULT_JERK, ArmKinematics, ToolSpec
from push_executor.motion_types import PANDA_READY

PLANAR = """<robot name="planar">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="flange"/>
  <link name="other"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <joint name="f" type="fixed"><parent link="l2"/><child link="flange"/>
    <origin xyz="0.2 0 0" rpy="3.141592653589793 0 0"/></joint>
  <joint name="side" type="prismatic"><parent link="base"/><child link="other"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="1" velocity="1" effort="1"/></joint>
</robot>"""
"""Two revolute joints about z (links 0.3 m and 0.2 m, shoulder 0.1 m up), a flange turned
upside down (its z axis points down) and a side joint that is not in the chain."""


def panda_urdf() -> str:
    pybullet_data = pytest.importorskip("pybullet_data")
    return open(os.path.join(pybullet_data.getDataPath(), "franka_panda", "panda.urdf")).read()


BASE_POSE = (-0.55, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def panda() -> ArmKinematics:
    return ArmKinematics(panda_urdf(), "panda_link0", ToolSpec(), BASE_POSE)


def test_planar_chain_and_limits() -> None:
    arm = ArmKinematics(PLANAR, "base", ToolSpec("flange", 0.01, 0.05, 0.005))
    assert arm.joint_names == ("j1", "j2")  # "side" is not between base and flange
    np.testing.assert_array_equal(arm.lower, [-3, -3])
    np.testing.assert_array_equal(arm.velocity_limits, [2, 2])
    np.testing.assert_array_equal(arm.acceleration_limits, [DEFAULT_ACCELERATION] * 2)
    np.testing.assert_array_equal(arm.jerk_limits, [DEFAULT_JERK] * 2)


@pytest.mark.parametrize("q", [(0.0, 0.0), (0.5, -1.0), (-2.0, 2.5), (math.pi / 2, 0.3)])
@pytest.mark.parametrize("base_pose", [(0, 0, 0, 0), (0.4, -0.2, 0.05, 0.7)])
def test_planar_fk_matches_hand_derived(q: tuple[float, float], base_pose: tuple) -> None:
    arm = ArmKinematics(PLANAR, "base", ToolSpec("flange", 0.01, 0.05, 0.005), base_pose)
    a, b = q
    # In the base frame: elbow at 0.3 (cos a, sin a), flange 0.2 further at angle a + b; the
    # flange z points down, so the tip is 0.06 m below the flange (offset 0.01 + length 0.05).
    x = 0.3 * math.cos(a) + 0.2 * math.cos(a + b)
    y = 0.3 * math.sin(a) + 0.2 * math.sin(a + b)
    tip_base = np.array([x, y, 0.1 - 0.06, 1.0])
    expected = (base_transform(base_pose) @ tip_base)[:3]
    position, axis = arm.tip_pose(q)
    np.testing.assert_allclose(position, expected, atol=1e-12)
    np.testing.assert_allclose(axis, [0, 0, -1], atol=1e-12)


def test_planar_jacobian_matches_finite_differences() -> None:
    arm = ArmKinematics(PLANAR, "base", ToolSpec("flange"), (0.1, 0.2, 0.0, 0.3))
    q = np.array([0.4, -0.7])
    j = arm.task_jacobian(q)
    eps = 1e-7
    for k in range(2):
        dq = np.zeros(2)
        dq[k] = eps
        numeric = (arm.tip_pose(q + dq)[0] - arm.tip_pose(q - dq)[0]) / (2 * eps)
        np.testing.assert_allclose(j[:3, k], numeric, atol=1e-7)
    np.testing.assert_allclose(j[3:], 0.0, atol=1e-12)  # rotation about z only


def test_panda_fk_matches_pybullet(panda: ArmKinematics) -> None:
    """Tip = panda_link8's origin + (offset + length) along its z, from pybullet's own FK."""
    p = pytest.importorskip("pybullet")
    pybullet_data = pytest.importorskip("pybullet_data")
    client = p.connect(p.DIRECT)
    try:
        robot = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "franka_panda",
                                        "panda.urdf"), basePosition=BASE_POSE[:3],
                           useFixedBase=True, physicsClientId=client)
        joints = {p.getJointInfo(robot, i, physicsClientId=client)[1].decode(): i
                  for i in range(p.getNumJoints(robot, physicsClientId=client))}
        link8 = next(i for i in range(p.getNumJoints(robot, physicsClientId=client))
                     if p.getJointInfo(robot, i, physicsClientId=client)[12] == b"panda_link8")
        rng = np.random.default_rng(7)
        for _ in range(50):
            q = rng.uniform(panda.lower, panda.upper)
            for name, value in zip(panda.joint_names, q, strict=True):
                p.resetJointState(robot, joints[name], value, physicsClientId=client)
            state = p.getLinkState(robot, link8, computeForwardKinematics=True,
                                   physicsClientId=client)
            origin = np.array(state[4])  # URDF link frame (not the inertial frame)
            rotation = np.array(p.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            expected = origin + panda.tool.tip_distance * rotation[:, 2]
            position, axis = panda.tip_pose(q)
            np.testing.assert_allclose(position, expected, atol=1e-6)
            np.testing.assert_allclose(axis, rotation[:, 2], atol=1e-6)
    finally:
        p.disconnect(client)


def test_panda_chain_ignores_the_fingers(panda: ArmKinematics) -> None:
    assert panda.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert np.all(panda.velocity_limits > 2.0)


def test_ik_over_the_workspace(panda: ArmKinematics) -> None:
    """Tip positions on an 11 x 13 grid (x in [-0.25, 0.25], y in [-0.3, 0.3]) at the push
    height: which solve to the residual, and that every solution is a true solution."""
    ready = np.array(PANDA_READY)
    solved = []
    for x in np.linspace(-0.25, 0.25, 11):
        for y in np.linspace(-0.3, 0.3, 13):
            result = panda.solve_ik([x, y, 0.01], ready, ready)
            ok = result.position_error < 1e-6 and result.axis_error < 1e-6
            if ok:
                position, axis = panda.tip_pose(result.q)
                np.testing.assert_allclose(position, [x, y, 0.01], atol=1e-6)
                assert axis[2] < -1 + 1e-9
                assert np.all(result.q >= panda.lower) and np.all(result.q <= panda.upper)
            solved.append((x, y, ok))
    n_ok = sum(ok for *_, ok in solved)
    print(f"IK solved {n_ok}/{len(solved)} grid points at z = 0.01 m, base at x = -0.55 m")
    # Everything within 0.65 m of the base's axis is reachable (the rest is at the Panda's
    # reach limit with a 0.2 m rod held vertically).
    near = [ok for x, y, ok in solved if math.hypot(x + 0.55, y) <= 0.65]
    assert all(near) and n_ok >= 0.8 * len(solved)


def test_ik_is_continuous_along_a_line(panda: ArmKinematics) -> None:
    ready = np.array(PANDA_READY)
    q = panda.solve_ik([-0.05, 0.02, 0.01], ready, ready).q
    previous = q
    for x in np.linspace(-0.05, 0.05, 101):
        result = panda.solve_ik([x, 0.02, 0.01], previous, ready)
        assert result.position_error < 1e-9
        assert np.max(np.abs(result.q - previous)) < 0.02  # 1 mm steps: small joint steps
        previous = result.q


def test_manipulability_drops_at_a_singular_posture(panda: ArmKinematics) -> None:
    assert panda.manipulability(PANDA_READY) > 0.05
    stretched = np.zeros(7)  # arm straight up: the tip's z-velocity is lost
    assert panda.manipulability(stretched) < 1e-6


@pytest.mark.parametrize("urdf, base, flange, match", [
    ("", "panda_link0", "panda_link8", "empty"),
    ("<robot", "panda_link0", "panda_link8", "not a valid URDF"),
    ("x" * (MAX_URDF_CHARS + 1), "panda_link0", "panda_link8", "characters"),
    (None, "nope", "panda_link8", "no link 'nope'"),
    (None, "panda_link8", "panda_link0", "not below"),
    (None, "panda_link8", "panda_hand", "no movable joint"),
])
def test_bad_models_are_refused(urdf: str | None, base: str, flange: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ArmKinematics(panda_urdf() if urdf is None else urdf, base, ToolSpec(flange))


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match="base_pose"):
        ArmKinematics(PLANAR, "base", ToolSpec("flange"), (0, 0, math.nan, 0))
    with pytest.raises(ValueError, match="acceleration limits"):
        ArmKinematics(PLANAR, "base", ToolSpec("flange"), acceleration_limits=[1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="acceleration limits"):
        ArmKinematics(PLANAR, "base", ToolSpec("flange"), acceleration_limits=0.0)
    with pytest.raises(ValueError, match="jerk limits"):
        ArmKinematics(PLANAR, "base", ToolSpec("flange"), jerk_limits=[math.inf])
    with pytest.raises(ValueError, match="tool.length"):
        ToolSpec("flange", length=0.0)
    no_limits = PLANAR.replace('velocity="2"', 'velocity="0"', 1)
    with pytest.raises(ValueError, match="no finite position limits or velocity limit"):
        ArmKinematics(no_limits, "base", ToolSpec("flange"))
    with pytest.raises(ValueError, match="more than one degree of freedom"):
        ArmKinematics(PLANAR.replace('type="revolute"', 'type="continuous"', 1), "base",
                      ToolSpec("flange"))
