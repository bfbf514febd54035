"""``pushbot demo`` as a user runs it, once for the whole module: the doctor's checks, then
the closed loop through the four node processes to the goal (summary printed from the episode
record, the node logs, the GIF and trajectory plot), and its recording: an MCAP bag of the
episode that reads back with ``rosbags`` (topics, types, counts consistent with the episode
record), a video with one frame per camera frame of the episode and one per monitor frame of
the bridge (on in the demo: rendered during the pushes, so the video has more frames than
camera frames), and ``pushbot bag play`` republishes it so that ``pushbot topic echo`` sees
it. Bad arguments are refused before anything starts.
"""

from __future__ import annotations

import json
import re
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


#: The demo's nodes: each runs as a process and writes its log.
NODES = ("sim_bridge_node", "segmentation_node", "ekf_node", "planner_node")


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory) -> tuple[Path, dict, str]:
    """One ``pushbot demo`` (doctor included): (output folder, episode record, stdout)."""
    out = tmp_path_factory.mktemp("demo")
    result = subprocess.run([PUSHBOT, "demo", "--object", "rect1", "--com", "centre", "--out",
                             str(out)], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    return out, json.loads((out / "episode.json").read_text()), result.stdout


@pytest.fixture
def demo_out(demo_run) -> tuple[Path, dict]:
    return demo_run[0], demo_run[1]


def test_demo_runs_doctor_then_the_closed_loop_through_the_graph(demo_run) -> None:
    tmp_path, record, out = demo_run
    assert "checks passed" in out
    # The four nodes ran as processes: each wrote its log.
    for name in NODES:
        assert (tmp_path / "graph_logs" / f"{name}.log").stat().st_size > 0, name
    assert record["trial"]["object"] == "rect1" and record["trial"]["task"] == "mixed"
    assert record["reason"] == "goal reached" and record["success"], out
    # a push the bridge refused (e.g. still busy with the scene) is a step without a new pose
    assert 1 <= record["steps"] == len(record["pushes"])
    assert len(record["poses_true"]) == record["steps"] - record["refused"] + 1
    # The summary prints the ground-truth figures of the record.
    match = re.search(r"^result: goal reached after (\d+) pushes \(success by ground truth\)$",
                      out, re.M)
    assert match and int(match.group(1)) == record["steps"], out
    match = re.search(r"^true end-pose error: ([\d.]+) mm, ([\d.]+) deg", out, re.M)
    assert match, out
    assert float(match.group(1)) == pytest.approx(1e3 * record["end_error_xy"], abs=0.06)
    assert float(match.group(1)) <= 7.5 and float(match.group(2)) <= 5.0
    assert re.search(r"^centre of mass \(object frame, mm\): estimated \(.*\), true \(.*\), "
                     r"error [\d.]+ mm$", out, re.M), out
    # figures: docs/results/graph.md
    assert re.search(r"^wall time: ([\d.]+) s in all", out, re.M), out
    # Robot (simulated) time: goal to the final stop, and one cycle per push after the first.
    robot = re.search(r"^robot time: ([\d.]+) s from the goal to the final stop", out, re.M)
    assert robot and float(robot.group(1)) == pytest.approx(record["robot_time_s"], abs=0.06)
    assert record["robot_time_s"] > 0 and len(record["cycle_s"]) == record["steps"] - 1, out
    assert all(c > 0 for c in record["cycle_s"]) and sum(record["cycle_s"]) < \
        record["robot_time_s"]
    from PIL import Image

    from pushbot.viz.render import GIF_MAX_FRAMES

    # Camera frames (one lost in transport is skipped) and the bridge's monitor frames of the
    # pushes, subsampled to at most GIF_MAX_FRAMES.
    with Image.open(tmp_path / "episode.gif") as gif:
        assert record["steps"] + 1 < gif.n_frames <= GIF_MAX_FRAMES
    assert (tmp_path / "trajectory.png").stat().st_size > 10_000


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
