"""The demo's recording: ``pushbot demo`` writes an MCAP bag of its
episode that reads back with ``rosbags`` (topics, types, counts consistent with the episode
record), a video with one frame per camera frame of the episode and one per monitor frame of
the bridge (on in the demo: rendered during the pushes, so the video has more frames than
camera frames), and ``pushbot bag play`` republishes it so that ``pushbot topic echo`` sees
it. One demo run (~15-20 s) for all.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.graph]

PUSHBOT = str(Path(sys.executable).parent / "pushbot")
EXPECTED = {
    "/camera/color/image_raw": "sensor_msgs/msg/Image",
    "/camera/color/camera_info": "sensor_msgs/msg/CameraInfo",
    "/camera/color/extrinsics": "geometry_msgs/msg/TransformStamped",
    "/perception/mask": "sensor_msgs/msg/Image",
    "/perception/outline": "sensor_msgs/msg/PointCloud2",
    "/perception/object_pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/estimator/object_pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/estimator/state": "std_msgs/msg/Float64MultiArray",
    "/goal_pose": "geometry_msgs/msg/PoseStamped",
    "/planner/push": "nav_msgs/msg/Path",
    "/planner/affordances": "visualization_msgs/msg/MarkerArray",
    "/planner/status": "diagnostic_msgs/msg/DiagnosticStatus",
    "/pusher/executed": "nav_msgs/msg/Path",
    "/sim/object_pose": "geometry_msgs/msg/PoseStamped",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/sim/monitor/image_raw": "sensor_msgs/msg/Image",
    "/sim/monitor/camera_info": "sensor_msgs/msg/CameraInfo",
}


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("demo")
    result = subprocess.run([PUSHBOT, "demo", "--skip-doctor", "--object", "rect1", "--com",
                             "centre", "--out", str(out)], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    return out, json.loads((out / "episode.json").read_text())


def test_demo_bag_reads_back_with_rosbags(demo_out) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    out, record = demo_out
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(out / "episode_bag") as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert EXPECTED.items() <= types.items(), types
        assert "/camera/aligned_depth_to_color/image_raw" not in types  # raw depth skipped
        pushes = [store.deserialize_cdr(d, c.msgtype)
                  for c, _, d in reader.messages([c for c in reader.connections
                                                  if c.topic == "/planner/push"])]
    assert counts["/planner/push"] == record["steps"]
    assert counts["/pusher/executed"] == record["steps"] - record["refused"]
    assert counts["/goal_pose"] >= 1
    # The pushes in the bag are the ones of the episode record (world frame, 3 poses each).
    for msg, push in zip(pushes, record["pushes"], strict=True):
        assert msg.header.frame_id == "world" and len(msg.poses) == 3
        assert [msg.poses[1].pose.position.x, msg.poses[1].pose.position.y] == \
            pytest.approx(push[1], abs=1e-9)


def test_demo_video_has_every_episode_frame_and_the_pushes(demo_out) -> None:
    import imageio_ffmpeg
    from rclpy.serialization import deserialize_message
    from rosbags.rosbag2 import Reader
    from sensor_msgs.msg import Image

    out, record = demo_out
    start = min(record["frame_stamps"])
    stamps: dict[str, set[float]] = {"/camera/color/image_raw": set(),
                                     "/sim/monitor/image_raw": set()}
    with Reader(out / "episode_bag") as reader:
        conns = [c for c in reader.connections if c.topic in stamps]
        for conn, _, data in reader.messages(conns):
            s = deserialize_message(bytes(data), Image).header.stamp
            stamps[conn.topic].add(s.sec + 1e-9 * s.nanosec)
    camera = {s for s in stamps["/camera/color/image_raw"] if s >= start - 1e-9}
    monitor = {s for s in stamps["/sim/monitor/image_raw"] if s >= start - 1e-9} - camera
    assert len(camera) >= record["steps"] - record["refused"] + 1
    # The bridge's monitor frames come during the pushes (10 Hz of sim time; a push of a few
    # cm at 20 mm/s lasts seconds): the video shows the pusher move the object.
    assert monitor and min(monitor) > min(camera)
    video_frames = imageio_ffmpeg.count_frames_and_secs(str(out / "episode.mp4"))[0]
    assert video_frames == len(camera) + len(monitor) > len(camera)
    assert (out / "episode.gif").stat().st_size > 0
    assert (out / "episode_estimate.png").stat().st_size > 10_000


def test_demo_bag_plays_back_to_topic_echo(demo_out) -> None:
    out, record = demo_out
    echo = subprocess.Popen([PUSHBOT, "topic", "echo", "planner/push", "--count",
                             str(record["steps"]), "--timeout", "60"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        play = subprocess.run([PUSHBOT, "bag", "play", str(out / "episode_bag"), "--topics",
                               "planner/push", "--rate", "20", "--wait-for-subscribers", "60"],
                              capture_output=True, text=True, timeout=120)
        echoed, _ = echo.communicate(timeout=90)
    finally:
        if echo.poll() is None:
            echo.kill()
            echo.wait()
    assert play.returncode == 0, play.stdout + play.stderr
    assert f'published {record["steps"]} messages' in play.stdout
    assert echo.returncode == 0, echoed
    assert echoed.count("frame_id: world") >= record["steps"], echoed


@pytest.mark.parametrize("value", ["-1", "nan", "61"])
def test_demo_rejects_a_bad_monitor_rate_before_starting_anything(value: str,
                                                                  tmp_path: Path) -> None:
    result = subprocess.run([PUSHBOT, "demo", "--skip-doctor", "--monitor-rate", value,
                             "--out", str(tmp_path)], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2
    assert "--monitor-rate must be in [0, 60] Hz" in result.stderr
    assert result.stderr.count("\n") == 1
    assert not (tmp_path / "graph_logs").exists()  # no node was started
