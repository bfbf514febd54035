"""The arm mode of the world: tool tip FK, trajectory following, the rod pushing an object."""

from __future__ import annotations

import numpy as np
import pytest

from sim_bridge.arm import TrajectoryCommand, TrajectoryFollower, check_trajectory
from sim_bridge.arm_robot import ARM_JOINTS, ROD_LENGTH
from sim_bridge.world import PushWorld, WorldConfig, quiet_stdout


@pytest.fixture(scope="module")
def world():
    with quiet_stdout():
        w = PushWorld(WorldConfig(object="rect1", object_pose=(0.05, 0.0, 0.0), robot="arm"))
    yield w
    w.close()


def _rot(axis: str, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def fk_tip(q: np.ndarray, base: tuple) -> np.ndarray:
    """Tip from the Panda's URDF joint origins (hand-written chain, independent of pybullet)."""
    h = np.pi / 2
    # (xyz, rpy-x) of each joint origin; every joint turns about its z.
    origins = [((0, 0, 0.333), 0), ((0, 0, 0), -h), ((0, -0.316, 0), h), ((0.0825, 0, 0), h),
               ((-0.0825, 0.384, 0), -h), ((0, 0, 0), h), ((0.088, 0, 0), h)]
    t = np.eye(4)
    t[:3, :3] = _rot("z", base[3])
    t[:3, 3] = base[:3]
    for (xyz, rx), qi in zip(origins, q, strict=True):
        step = np.eye(4)
        step[:3, :3] = _rot("x", rx) @ _rot("z", qi)
        step[:3, 3] = xyz
        t = t @ step
    return (t @ np.array([0, 0, 0.107 + ROD_LENGTH, 1.0]))[:3]


def test_tip_forward_kinematics_matches_the_urdf_chain(world) -> None:
    rng = np.random.default_rng(0)
    arm = world.arm
    for _ in range(5):
        q = rng.uniform(arm.limits[:, 0], arm.limits[:, 1])
        arm.set_positions(q)
        np.testing.assert_allclose(arm.tip_position(), fk_tip(q, world.config.arm_base_pose),
                                   atol=1e-6)
    arm.set_positions(world.config.arm_park)
    assert "pusher_tip" in world.robot_description
    assert "package://" not in world.robot_description


def _follow(world, q_goal: np.ndarray, duration: float) -> tuple:
    state = world.arm_state()
    times = np.linspace(duration / 20, duration, 20)
    u = times / duration
    s = 3 * u**2 - 2 * u**3
    ds = (6 * u - 6 * u**2) / duration
    pos = state.positions + s[:, None] * (q_goal - state.positions)
    vel = ds[:, None] * (q_goal - state.positions)
    traj = check_trajectory(TrajectoryCommand(list(ARM_JOINTS), 0.0, times, pos.tolist(),
                                              vel.tolist()), ARM_JOINTS, world.sim_time)
    follower = TrajectoryFollower(ARM_JOINTS)
    follower.offer(traj)
    samples = []
    run = world.run_arm(follower, 24, lambda t, st: samples.append((t, st.positions)))
    return run, samples, traj


def test_trajectory_is_followed_within_tolerance(world) -> None:
    arm = world.arm
    start_t = world.sim_time
    q_goal = arm.inverse_kinematics([-0.1, 0.1, 0.05], world.config.arm_park)
    run, samples, traj = _follow(world, q_goal, 2.0)
    assert run.settled and run.t_done >= start_t + 2.0
    np.testing.assert_allclose(world.arm_state().positions, q_goal, atol=2e-3)
    for t, q in samples:  # tracking error along the way (one sample per 0.1 s)
        if t - start_t <= 2.0:
            want, _ = traj.sample(t, start_t, samples[0][1], np.zeros(7))
            assert np.max(np.abs(q - want)) < 0.02
    assert len(run.tip_times) == len(run.tip_positions) > 10


def test_rod_pushes_the_object(world) -> None:
    arm = world.arm
    before = world.object_pose()
    rest = world.arm_state().positions
    q_a = arm.inverse_kinematics([-0.06, 0.0, 0.01], rest)  # behind rect1 (half length < 5 cm)
    _follow(world, q_a, 1.5)
    assert np.linalg.norm(world.object_pose()[:2] - before[:2]) < 1e-3  # not touched yet
    q_e = arm.inverse_kinematics([0.04, 0.0, 0.01], q_a)
    _follow(world, q_e, 4.0)
    assert world.object_pose()[0] - before[0] > 0.02  # pushed along +x


def test_real_time_factor_paces_the_run(world) -> None:
    # Sleeping only ever slows the run down: sim time never runs ahead of factor x wall time.
    import time

    arm = world.arm
    q_goal = np.asarray(world.config.arm_park) + 0.05
    state = world.arm_state()
    times = np.linspace(0.05, 0.5, 10)
    u = times / 0.5
    pos = state.positions + (3 * u**2 - 2 * u**3)[:, None] * (q_goal - state.positions)
    vel = ((6 * u - 6 * u**2) / 0.5)[:, None] * (q_goal - state.positions)
    traj = check_trajectory(TrajectoryCommand(list(ARM_JOINTS), 0.0, times, pos.tolist(),
                                              vel.tolist()), ARM_JOINTS, world.sim_time)
    follower = TrajectoryFollower(ARM_JOINTS)
    follower.offer(traj)
    wall0 = time.monotonic()
    run = world.run_arm(follower, 24, real_time_factor=2.0)
    wall = time.monotonic() - wall0
    assert run.t_done - run.t_start >= 0.5
    assert wall >= (run.t_done - run.t_start) / 2.0 - 0.01
    arm.set_positions(world.config.arm_park)
