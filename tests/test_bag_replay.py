"""``pushbot replay`` on a small synthesised episode bag.

The bag holds real CDR (``rclpy.serialization`` of messages built with the ``push_ros``
codecs the nodes use), written with ``rosbags`` as ``pushbot bag record`` writes it: small
160 x 120 camera frames (one repeated with the same stamp, as the bridge repeats idle frames),
a mask per frame, camera info, extrinsics, the outline, estimates, ground truth, a goal, a push
and affordance markers; optionally the simulator's monitor frames (80 x 60, dark blue, 4 Hz of
sim time between the camera frames, one of them received late). No ROS graph is needed (the
renderer only reads files).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from pushbot import cli
from pushbot.viz.render import GOAL_RGB

#: Distinct camera stamps (s); the second frame is published twice.
STAMPS = (10.0, 11.0, 11.0, 12.5, 14.0)
#: Monitor frames: every 0.25 s of sim time after each new camera frame up to the next one (the
#: one at the next camera frame's stamp is left out of the video: the camera frame shows it).
MONITOR_PERIOD = 0.25
MONITOR_RGB = (30, 30, 120)


def _square(half: float = 0.03) -> tuple[np.ndarray, np.ndarray]:
    s = np.linspace(-half, half, 10, endpoint=False)
    pts = np.concatenate([np.column_stack([s, np.full(10, -half)]),
                          np.column_stack([np.full(10, half), s]),
                          np.column_stack([-s, np.full(10, half)]),
                          np.column_stack([np.full(10, -half), -s])])
    normals = np.repeat([[0, -1], [1, 0], [0, 1], [-1, 0]], 10, axis=0).astype(float)
    return pts, normals


def _markers(pts_world: np.ndarray, stamp):
    from geometry_msgs.msg import Point
    from std_msgs.msg import ColorRGBA
    from visualization_msgs.msg import Marker, MarkerArray

    def _points(xy: np.ndarray, z: float) -> list:
        return [Point(x=float(x), y=float(y), z=z) for x, y in xy]

    outline = Marker(ns="planner/outline", id=0, type=Marker.SPHERE_LIST)
    outline.header.frame_id, outline.header.stamp = "world", stamp
    outline.points = _points(pts_world, 0.015)
    outline.colors = [ColorRGBA(r=float(v), g=1.0 - float(v), b=0.0, a=1.0)
                      for v in np.linspace(0, 1, len(pts_world))]
    cand = Marker(ns="planner/candidates", id=1, type=Marker.SPHERE_LIST)
    cand.header.frame_id, cand.header.stamp = "world", stamp
    cand.points = _points(pts_world[:3], 0.015)
    return MarkerArray(markers=[outline, cand])


def monitor_stamps() -> list[float]:
    """Stamps of the monitor frames of :func:`write_episode_bag` (``with_monitor``)."""
    distinct = sorted(set(STAMPS))
    return [float(a + MONITOR_PERIOD * m) for a, b in itertools.pairwise(distinct)
            for m in range(1, round((b - a) / MONITOR_PERIOD) + 1)]


def write_episode_bag(path: Path, *, with_extrinsics: bool = True,
                      with_monitor: bool = False) -> int:
    """Write the synthetic episode; returns the number of distinct camera frames."""
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer

    from push_core.geometry import object_to_world
    from push_ros.images import camera_info_msg, mask_image_msg, rgb_image_msg
    from push_ros.outline import outline_cloud_msg
    from push_ros.paths import push_path
    from push_ros.poses import pose_stamped_msg, pose_with_covariance_msg, transform_msg
    from push_ros.stamps import stamp_from_seconds
    from pushbot.ros2cli.bag_store import message_definition
    from sim_bridge.camera import CameraConfig, intrinsics, look_at_pose, project

    cfg = CameraConfig(width=160, height=120)
    k, t_wc = intrinsics(cfg), look_at_pose(cfg)
    pts, normals = _square()
    messages = []  # (topic, message, receive time s)
    t0 = stamp_from_seconds(STAMPS[0])
    messages.append(("/camera/color/camera_info", camera_info_msg(k, 160, 120, t0), 0.0))
    if with_extrinsics:
        messages.append(("/camera/color/extrinsics",
                         transform_msg(t_wc, t0, "world", "camera_color_optical_frame"), 0.0))
    messages.append(("/perception/outline", outline_cloud_msg(pts, normals, t0), 0.1))
    goal = np.array([0.04, 0.02, 0.3])
    messages.append(("/goal_pose", pose_stamped_msg(goal, t0), 0.2))
    for i, stamp_s in enumerate(STAMPS):
        stamp = stamp_from_seconds(stamp_s)
        pose = np.array([0.01 * i, 0.005 * i, 0.05 * i])
        rgb = np.full((120, 160, 3), 200, dtype=np.uint8)
        uv = project(np.column_stack([object_to_world(pose, pts), np.zeros(len(pts))]), k,
                     t_wc)
        mask = np.zeros((120, 160), dtype=bool)
        lo, hi = np.floor(uv.min(axis=0)).astype(int), np.ceil(uv.max(axis=0)).astype(int)
        mask[max(lo[1], 0):hi[1], max(lo[0], 0):hi[0]] = True
        t = 1.0 + i
        messages.append(("/camera/color/image_raw", rgb_image_msg(rgb, stamp), t))
        messages.append(("/perception/mask", mask_image_msg(mask, stamp), t + 0.05))
        messages.append(("/sim/object_pose", pose_stamped_msg(pose, stamp), t))
        messages.append(("/estimator/object_pose",
                         pose_with_covariance_msg(pose + 0.002, np.diag([1e-6, 1e-6, 1e-4]),
                                                  stamp), t + 0.1))
        world = np.asarray(object_to_world(pose, pts))
        messages.append(("/planner/affordances", _markers(world, stamp), t + 0.2))
        messages.append(("/planner/push", push_path(world[5] - [0, 0.02], world[5],
                                                    world[5] + [0, 0.02], stamp_s, 0.05),
                         t + 0.2))
        later = [m for m in monitor_stamps() if stamp_s < m <= stamp_s + 1.5] \
            if with_monitor and stamp_s not in STAMPS[:i] else []
        for j, m in enumerate(later):  # pushing: after the push, before the next frame
            m_stamp = stamp_from_seconds(m)
            small = np.full((60, 80, 3), MONITOR_RGB, dtype=np.uint8)
            # The last one of the episode arrives after the camera frame that follows it.
            late = m == monitor_stamps()[-1]
            messages.append(("/sim/monitor/image_raw", rgb_image_msg(small, m_stamp),
                             t + (1.02 if late else 0.3 + 0.05 * j)))
            k_small = np.diag([0.5, 0.5, 1.0]) @ k
            messages.append(("/sim/monitor/camera_info",
                             camera_info_msg(k_small, 80, 60, m_stamp), t + 0.3 + 0.05 * j))
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {}
        for topic, msg, t in sorted(messages, key=lambda m: m[2]):
            if topic not in conns:
                msgtype = type(msg).__module__.split(".")[0] + "/msg/" + type(msg).__name__
                msgdef, rihs01 = message_definition(msgtype)
                conns[topic] = writer.add_connection(topic, msgtype, msgdef=msgdef,
                                                     rihs01=rihs01)
            writer.write(conns[topic], int(1e9 * (1000.0 + t)), serialize_message(msg))
    return len(set(STAMPS))


@pytest.fixture(scope="module")
def episode_bag(tmp_path_factory) -> tuple[Path, int]:
    bag = tmp_path_factory.mktemp("replay") / "episode"
    return bag, write_episode_bag(bag)


def test_replay_writes_one_video_frame_per_camera_frame(episode_bag, tmp_path: Path,
                                                         capsys) -> None:
    import imageio.v2 as imageio
    import imageio_ffmpeg

    bag, frames = episode_bag
    out = tmp_path / "video.mp4"
    assert cli.main(["replay", str(bag), "-o", str(out), "--gif"]) == 0
    assert f"rendered {frames} frames" in capsys.readouterr().out
    assert imageio_ffmpeg.count_frames_and_secs(str(out))[0] == frames
    assert (tmp_path / "video.gif").is_file() and (tmp_path / "video_estimate.png").is_file()
    with imageio.get_reader(out) as reader:
        first = reader.get_data(0)
    assert first.shape[1] >= 480 and first.shape[0] % 16 == 0 and first.shape[1] % 16 == 0
    # The goal outline (magenta) is drawn: pixels close to GOAL_RGB (H.264 shifts colours).
    close = np.abs(first.astype(int) - np.asarray(GOAL_RGB)).sum(axis=-1) < 90
    assert close.sum() > 20


def test_replay_default_output_next_to_the_bag(episode_bag, capsys) -> None:
    bag, frames = episode_bag
    assert cli.main(["replay", str(bag)]) == 0
    assert (bag.parent / "episode.mp4").is_file()
    assert (bag.parent / "episode_estimate.png").is_file()


def test_replay_without_extrinsics_is_a_clear_error(tmp_path: Path, capsys) -> None:
    bag = tmp_path / "noext"
    write_episode_bag(bag, with_extrinsics=False)
    assert cli.main(["replay", str(bag), "-o", str(tmp_path / "x.mp4")]) == 1
    err = capsys.readouterr().err
    assert "lacks /camera/color/camera_info or /camera/color/extrinsics" in err
    assert err.count("\n") == 1


@pytest.mark.parametrize("argv, message", [
    (["replay", "/nonexistent"], "is not a bag folder"),
    (["replay", ".", "--fps", "0"], "--fps must be in (0, 120]"),
    (["replay", ".", "-o", "video.avi"], "the output must be an .mp4 file"),
])
def test_replay_bad_input(argv: list[str], message: str, capsys) -> None:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_replay_merges_monitor_frames_in_time_order(tmp_path: Path, capsys) -> None:
    """Camera + monitor frames, each once, in stamp order (the late one waits its turn), at
    2 x the monitor rate; monitor frames are scaled to the camera's size and drawn on."""
    import imageio.v2 as imageio

    from pushbot.viz.render import MONITOR_SPEEDUP, PUSH_RGB

    bag = tmp_path / "monitored"
    cameras = write_episode_bag(bag, with_monitor=True)
    stamps = sorted([(s, "camera") for s in set(STAMPS)]
                    + [(s, "monitor") for s in monitor_stamps() if s not in STAMPS])
    assert len(stamps) == cameras + 13  # 4 + 6 + 6 monitor frames, 3 at camera stamps
    out = tmp_path / "monitored.mp4"
    assert cli.main(["replay", str(bag), "-o", str(out), "--gif"]) == 0
    assert f"rendered {len(stamps)} frames" in capsys.readouterr().out
    with imageio.get_reader(out) as reader:
        fps = reader.get_meta_data()["fps"]
        frames = [f for f in reader]
    assert fps == pytest.approx(MONITOR_SPEEDUP / MONITOR_PERIOD)
    assert len({f.shape for f in frames}) == 1
    kinds = []
    for f in frames:  # below the 30 px time bar, above the legend: grey camera, blue monitor
        body = f[40:-60].reshape(-1, 3).astype(float)
        kinds.append("monitor" if np.median(body[:, 1]) < 100 else "camera")
    assert kinds == [k for _, k in stamps]
    # The push arrow (cyan) is drawn on the monitor frames too.
    first_monitor = frames[kinds.index("monitor")].astype(int)
    assert (np.abs(first_monitor - np.asarray(PUSH_RGB)).sum(axis=-1) < 90).sum() > 20
    assert (tmp_path / "monitored.gif").is_file()
