"""The world's monitor stream: frames rendered *during* a push at a
sim-time rate, reading only: the push and every later camera frame are bit-identical to a
push without it. Real pybullet, seeded."""

from __future__ import annotations

import numpy as np
import pytest

from sim_bridge.world import CameraConfig, Frame, MonitorConfig, PushWorld, WorldConfig

# A seeded, randomised scene with depth and colour noise: a monitor that drew from the
# sensor-noise stream or disturbed the physics would change the results below.
CONFIG = WorldConfig(object="hex", object_pose=(0.02, 0.01, 0.3), randomize=True, seed=11,
                     depth_noise=True, randomize_appearance=True,
                     camera=CameraConfig(width=160, height=120))
PUSH = ([-0.09, 0.02], [-0.06, 0.025], [0.0, 0.035])
MONITOR = MonitorConfig(rate=10.0, width=80, height=60)


@pytest.fixture(scope="module")
def pushed():
    """(result, camera frame after) without and with the monitor, and the monitor frames."""
    frames: list[Frame] = []
    with PushWorld(CONFIG) as world:
        plain = world.execute_push(*PUSH), world.render()
        world.reset()
        t0 = world.sim_time
        watched = world.execute_push(*PUSH, monitor=MONITOR, on_frame=frames.append), \
            world.render()
    return plain, watched, frames, t0


def test_monitor_leaves_the_push_and_the_camera_bit_identical(pushed):
    (plain, after_plain), (watched, after_watched), frames, _ = pushed
    assert frames
    np.testing.assert_array_equal(plain.pose_after, watched.pose_after)
    np.testing.assert_array_equal(plain.pusher_start, watched.pusher_start)
    np.testing.assert_array_equal(plain.pusher_end, watched.pusher_end)
    assert (plain.t_start, plain.t_end, plain.t_done) == \
        (watched.t_start, watched.t_end, watched.t_done)
    np.testing.assert_array_equal(after_plain.rgb, after_watched.rgb)  # same noise draws
    np.testing.assert_array_equal(after_plain.depth, after_watched.depth)


def test_monitor_frames_come_at_the_sim_time_rate_within_the_push(pushed):
    _, (result, _), frames, t0 = pushed
    dt = CONFIG.time_step
    every = MONITOR.every(dt)
    assert every == 24  # 10 Hz at 240 steps per second
    stamps = np.array([f.stamp for f in frames])
    steps = np.round((stamps - t0) / dt).astype(int)
    total = round((result.t_done - t0) / dt)
    # One frame every 24 physics steps from the call on: steps 24, 48, ... <= the last step.
    np.testing.assert_array_equal(steps, np.arange(every, total + 1, every))
    assert t0 < stamps[0] and stamps[-1] <= result.t_done
    assert np.any((stamps > result.t_start) & (stamps < result.t_end))  # the push itself
    for f in frames:
        assert f.rgb.shape == (60, 80, 3) and f.rgb.dtype == np.uint8


def test_monitor_frames_show_the_motion(pushed):
    """The pusher and the object move between frames during the push; the frames follow the
    ground truth (the stored pose changes as the object is pushed)."""
    _, (result, _), frames, _ = pushed
    during = [f for f in frames if result.t_start < f.stamp < result.t_end]
    assert len(during) >= 2
    assert not np.array_equal(during[0].rgb, during[-1].rgb)
    np.testing.assert_allclose(frames[0].object_pose, result.pose_before, atol=1e-4)
    np.testing.assert_allclose(frames[-1].object_pose, result.pose_after, atol=1e-4)
    assert np.linalg.norm(during[-1].object_pose[:2] - result.pose_before[:2]) > 0.01


def test_monitor_intrinsics_are_the_camera_scaled():
    from sim_bridge.camera import intrinsics

    with PushWorld(WorldConfig(object="rect1", camera=CameraConfig(width=160, height=120))) as w:
        frames: list[Frame] = []
        contact = np.array([-0.045 - 0.0048, 0.0])
        w.execute_push(contact - [0.01, 0.0], contact, contact + [0.01, 0.0],
                       monitor=MonitorConfig(rate=20.0, width=80, height=60),
                       on_frame=frames.append)
        np.testing.assert_array_equal(frames[0].T_world_camera, w.T_world_camera)
    expected = intrinsics(CameraConfig(width=80, height=60))  # the D415 scaled to 80 x 60
    np.testing.assert_allclose(frames[0].camera_matrix, expected, atol=1e-9)


@pytest.mark.parametrize("kwargs, match", [
    ({"rate": 0.0}, r"monitor.rate: must be in \(0, 240\]"),
    ({"rate": float("nan")}, "monitor.rate"),
    ({"width": 4}, r"monitor.width: expected an integer in \[8, 4096\]"),
    ({"height": 2.5}, "monitor.height"),
])
def test_monitor_config_rejects_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        MonitorConfig(**kwargs)
