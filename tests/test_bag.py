"""``pushbot bag record|info|play`` on real DDS messages.

A publisher in this process, ``pushbot bag record`` / ``bag play`` as child processes (the
way a user runs them): record until Ctrl-C, read the bag back with ``rosbags`` (counts, a
decoded field, metadata.yaml as rosbag2 Jazzy writes it), ``bag info``, then play it back into
a subscriber here. Reliable publishers wait for their matched reader and for every sample to
be acknowledged, so the counts are exact.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from pushbot import cli

pytestmark = [pytest.mark.ros, pytest.mark.graph]  # starts node processes

N_MESSAGES = 5


def _latched_qos():
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _acked(publisher, seconds: float = 10.0) -> bool:
    from rclpy.duration import Duration

    return publisher.wait_for_all_acked(Duration(seconds=seconds))


PUSHBOT = str(Path(sys.executable).parent / "pushbot")


@pytest.fixture(scope="module")
def recorded_bag(tmp_path_factory, module_processes) -> tuple[Path, str, dict[str, int]]:
    """A bag of ``chatter`` (N_MESSAGES Strings) and ``latched`` (one PoseStamped published
    before the recorder started) recorded by ``pushbot bag record`` and ended with SIGINT;
    shared by the module's tests (one recording). Also returns the senders' source timestamps
    of the chatter messages (ns, by text) as a listener here received them."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from pushbot.ros2cli.discovery import spin_until

    context = Context()
    rclpy.init(args=[], context=context)
    node = rclpy.create_node("bag_test_talker", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        chatter = node.create_publisher(String, "chatter", 10)
        latched = node.create_publisher(PoseStamped, "latched", _latched_qos())
        sent: dict[str, int] = {}

        def heard(msg: String, info: Any) -> None:  # 2 arguments: rclpy's message info
            sent[msg.data] = info["source_timestamp"]

        node.create_subscription(String, "chatter", heard, 10)
        pose = PoseStamped()
        pose.header.frame_id = "world"
        pose.pose.position.x = 1.25
        pose.pose.orientation.w = 1.0
        latched.publish(pose)
        bag = tmp_path_factory.mktemp("bags") / "bag"
        # Started as a script's background job is (`cmd &`: SIGINT ignored), which pushbot's
        # main undoes: the SIGINT below must still end the recording cleanly.
        proc = module_processes.start(["sh", "-c", 'trap "" INT; exec "$0" "$@"', PUSHBOT,
                                       "bag", "record", "-o", str(bag), "chatter", "/latched"],
                                      name="record")
        assert spin_until(executor, lambda: chatter.get_subscription_count() > 0
                          and latched.get_subscription_count() > 0, time.monotonic() + 30.0), \
            module_processes.output(proc)
        for i in range(N_MESSAGES):
            chatter.publish(String(data=f"message {i}"))
        assert _acked(chatter) and _acked(latched)
        assert spin_until(executor, lambda: len(sent) == N_MESSAGES, time.monotonic() + 30.0)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0, module_processes.output(proc)
        return bag, module_processes.output(proc), sent
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_record_reads_back_with_rosbags(recorded_bag: tuple[Path, str, dict[str, int]]) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    bag, output, _ = recorded_bag
    assert f"/chatter [std_msgs/msg/String]: {N_MESSAGES}" in output
    assert "/latched [geometry_msgs/msg/PoseStamped]: 1" in output
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        topics = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        assert topics == {"/chatter": ("std_msgs/msg/String", N_MESSAGES),
                          "/latched": ("geometry_msgs/msg/PoseStamped", 1)}
        decoded = {c.topic: [] for c in reader.connections}
        for conn, _, data in reader.messages():
            decoded[conn.topic].append(store.deserialize_cdr(data, conn.msgtype))
    assert [m.data for m in decoded["/chatter"]] == [f"message {i}" for i in range(N_MESSAGES)]
    assert decoded["/latched"][0].pose.position.x == 1.25
    assert decoded["/latched"][0].header.frame_id == "world"


def test_metadata_is_what_rosbag2_jazzy_writes(
        recorded_bag: tuple[Path, str, dict[str, int]]) -> None:
    from pushbot.ros2cli.bag_store import message_definition

    bag, _, _ = recorded_bag
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["bag_0.mcap"] and (bag / "bag_0.mcap").is_file()
    assert info["message_count"] == N_MESSAGES + 1
    assert info["compression_mode"] == "" and info["compression_format"] == ""
    assert info["files"][0]["path"] == "bag_0.mcap"
    assert info["duration"]["nanoseconds"] >= 0
    assert info["starting_time"]["nanoseconds_since_epoch"] > 0
    assert info["ros_distro"] == (os.environ.get("ROS_DISTRO") or "jazzy")
    by_name = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    latched = by_name["/latched"]["topic_metadata"]
    assert latched["type"] == "geometry_msgs/msg/PoseStamped"
    assert latched["serialization_format"] == "cdr"
    assert latched["type_description_hash"].startswith("RIHS01_")
    assert latched["type_description_hash"] == message_definition(latched["type"])[1]
    # Version 9: the offered QoS profiles are a YAML list of mappings (not a string).
    (qos,) = latched["offered_qos_profiles"]
    assert qos["durability"] == "transient_local" and qos["reliability"] == "reliable"
    assert set(qos) >= {"history", "depth", "deadline", "lifespan", "liveliness",
                        "liveliness_lease_duration", "avoid_ros_namespace_conventions"}
    # The MCAP file: ros2 profile, one ros2msg schema with the full definition per type.
    head = (bag / "bag_0.mcap").read_bytes()[:64]
    assert head.startswith(b"\x89MCAP0\r\n") and b"ros2" in head


def test_official_mcap_readers_verify_and_decode_the_recording(
        recorded_bag: tuple[Path, str, dict[str, int]]) -> None:
    # The official readers: python mcap (every chunk CRC and the data section CRC checked)
    # with mcap-ros2-support decoding; the channels carry the type hash and the QoS profiles;
    # publish_time is the sender's source timestamp, log_time the receive time (after it).
    from mcap.reader import NonSeekingReader, make_reader
    from mcap_ros2.decoder import DecoderFactory

    bag, _, sent = recorded_bag
    with (bag / "bag_0.mcap").open("rb") as f:
        assert len(list(NonSeekingReader(f, validate_crcs=True).iter_messages())) == \
            N_MESSAGES + 1
    with (bag / "bag_0.mcap").open("rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        messages = [(c.topic, m, d) for _, c, m, d in reader.iter_decoded_messages()]
        (record,) = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    for channel in summary.channels.values():
        meta = topics[channel.topic]
        assert channel.metadata["topic_type_hash"] == \
            meta["topic_metadata"]["type_description_hash"]
        assert yaml.safe_load(channel.metadata["offered_qos_profiles"]) == \
            meta["topic_metadata"]["offered_qos_profiles"]
        assert summary.statistics.channel_message_counts[channel.id] == meta["message_count"]
    assert yaml.safe_load(record.metadata["serialized_metadata"])["ros_distro"] == \
        info["ros_distro"]
    chatter = [(m, d) for topic, m, d in messages if topic == "/chatter"]
    assert [d.data for _, d in chatter] == [f"message {i}" for i in range(N_MESSAGES)]
    for m, d in chatter:
        assert m.publish_time == sent[d.data]
        assert m.publish_time <= m.log_time < m.publish_time + 10 * 10**9
    ((_, latched, pose),) = [x for x in messages if x[0] == "/latched"]
    assert pose.pose.position.x == 1.25
    assert latched.publish_time < latched.log_time  # published before the recorder started


def test_info_and_play_round_trip(recorded_bag: tuple[Path, str, dict[str, int]], ros_context,
                                  wait_for, processes, capsys) -> None:
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from std_msgs.msg import String

    bag, _, _ = recorded_bag
    assert cli.main(["bag", "info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "Storage id:        mcap" in out and f"Messages:          {N_MESSAGES + 1}" in out
    assert f"Topic: /chatter | Type: std_msgs/msg/String | Count: {N_MESSAGES}" in out

    node = rclpy.create_node("bag_test_listener", context=ros_context)
    executor = rclpy.executors.SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    got: list[str] = []
    poses: list[float] = []
    try:
        node.create_subscription(String, "chatter", lambda m: got.append(m.data), 10)
        node.create_subscription(PoseStamped, "latched",
                                 lambda m: poses.append(m.pose.position.x), _latched_qos())
        proc = processes.start([PUSHBOT, "bag", "play", str(bag),
                                "--rate", "4", "--wait-for-subscribers", "30"], name="play")
        assert wait_for(lambda: len(got) == N_MESSAGES and poses, 30.0, executor), \
            processes.output(proc)
        assert proc.wait(timeout=30) == 0, processes.output(proc)
    finally:
        executor.shutdown()
        node.destroy_node()
    assert got == [f"message {i}" for i in range(N_MESSAGES)]
    assert poses == [1.25]
    assert f"published {N_MESSAGES + 1} messages" in processes.output(proc)


@pytest.mark.parametrize("argv, message", [
    (["bag", "record"], "name the topics to record or give --all"),
    (["bag", "record", "--all", "--exclude", "("], "is not a regular expression"),
    (["bag", "record", "x", "--duration", "-1"], "--duration must be a positive"),
    (["bag", "info", "."], "has no metadata.yaml"),
    (["bag", "play", "/nonexistent/bag"], "is not a bag folder"),
])
def test_bad_input_is_one_line_and_exit_2(argv: list[str], message: str, capsys) -> None:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_play_rejects_a_bad_rate_and_unknown_topics(recorded_bag, capsys) -> None:
    bag, _, _ = recorded_bag
    assert cli.main(["bag", "play", str(bag), "--rate", "0"]) == 2
    assert "--rate must be a positive number" in capsys.readouterr().err
    assert cli.main(["bag", "play", str(bag), "--topics", "nope"]) == 2
    assert "topics not in the bag: /nope" in capsys.readouterr().err


def test_a_truncated_bag_is_reported_not_raised(recorded_bag, tmp_path: Path, capsys) -> None:
    bag, _, _ = recorded_bag
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "metadata.yaml").write_text((bag / "metadata.yaml").read_text())
    (broken / "bag_0.mcap").write_bytes((bag / "bag_0.mcap").read_bytes()[:40])
    assert cli.main(["bag", "info", str(broken)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pushbot bag: cannot read bag") and "Traceback" not in err


def test_a_failing_write_is_counted_not_silent(tmp_path: Path, ros_context, wait_for) -> None:
    # The in-process recorder (as pushbot demo uses it): a write that raises (a full disk)
    # drops that message, is counted per topic, and the recording goes on.
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rosbags.rosbag2 import Reader
    from std_msgs.msg import String

    from pushbot.ros2cli.bag_record import BagRecorder, TopicSelection

    node = rclpy.create_node("bag_test_failing", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        pub = node.create_publisher(String, "disk_full", 10)
        recorder = BagRecorder(tmp_path / "bag", TopicSelection(("/disk_full",)))
        with recorder:
            assert not recorder.wait_for_topics(["/disk_full"], 30.0)
            assert wait_for(lambda: pub.get_subscription_count() > 0, 30.0, executor)
            real_write, calls = recorder._writer.write, []

            def write(channel_id, stamp, data, publish_time=None):
                calls.append(stamp)
                if len(calls) == 1:
                    raise OSError(28, "No space left on device")
                real_write(channel_id, stamp, data, publish_time)

            recorder._writer.write = write
            for i in range(3):
                pub.publish(String(data=f"m{i}"))
            assert _acked(pub)
            assert wait_for(lambda: len(calls) == 3, 30.0)
        assert recorder.counts() == {"/disk_full": 2}
        assert recorder.errors == {"write /disk_full": 1}
    finally:
        executor.shutdown()
        node.destroy_node()
    with Reader(tmp_path / "bag") as reader:
        assert reader.message_count == 2


# --- bag play leaves command topics out ----------------------------------------------------

def _write_bag(path: Path, topics: dict[str, tuple[str, Any]]) -> None:
    """A bag of one message per topic (``{topic: (msgtype, message)}``), written as ``bag
    record`` writes it."""
    from rosbags.typesys import Stores, get_typestore

    from pushbot.ros2cli.bag_mcap import Rosbag2McapWriter
    from pushbot.ros2cli.bag_store import message_definition

    store = get_typestore(Stores.ROS2_JAZZY)
    with Rosbag2McapWriter(path) as writer:
        for k, (name, (msgtype, message)) in enumerate(sorted(topics.items())):
            msgdef, rihs01 = message_definition(msgtype)
            channel = writer.add_topic(name, msgtype, msgdef, rihs01, [])
            writer.write(channel, 1_000_000_000 + k * 1_000_000,
                         bytes(store.serialize_cdr(message, msgtype)))


def test_command_topics_are_recognised() -> None:
    from pushbot.ros2cli.bag import is_command_topic

    string = "std_msgs/msg/String"
    for name in ("/goal_pose", "/planner/push", "/sim/knock", "/robot1/goal_pose",
                 "/executor/cancel", "/cmd_vel"):
        assert is_command_topic(name, string), name
    assert is_command_topic("/arm/joint_trajectory", "trajectory_msgs/msg/JointTrajectory")
    for name in ("/planner/status", "/planner/pushes", "/estimator/state", "/my_goal_pose",
                 "/camera/color/image_raw", "/pusher/executed"):
        assert not is_command_topic(name, string), name


def test_play_leaves_command_topics_out_unless_asked(tmp_path: Path, capsys) -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    string = store.types["std_msgs/msg/String"]
    pose = store.types["geometry_msgs/msg/PoseStamped"]
    header = store.types["std_msgs/msg/Header"](
        stamp=store.types["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="world")
    point = store.types["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0)
    quat = store.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    goal = pose(header=header, pose=store.types["geometry_msgs/msg/Pose"](
        position=point, orientation=quat))
    trajectory = store.types["trajectory_msgs/msg/JointTrajectory"](
        header=header, joint_names=["j1"], points=[])
    bag = tmp_path / "bag"
    _write_bag(bag, {
        "/chatter": ("std_msgs/msg/String", string(data="hello")),
        "/goal_pose": ("geometry_msgs/msg/PoseStamped", goal),
        "/planner/push": ("std_msgs/msg/String", string(data="push")),
        "/arm/trajectory": ("trajectory_msgs/msg/JointTrajectory", trajectory),
    })
    assert cli.main(["bag", "play", str(bag), "--rate", "100"]) == 0
    captured = capsys.readouterr()
    assert "published 1 messages: /chatter 1" in captured.out
    assert ("leaving out the command topics /arm/trajectory, /goal_pose, /planner/push"
            in captured.err)
    assert cli.main(["bag", "play", str(bag), "--rate", "100", "--include-commands"]) == 0
    captured = capsys.readouterr()
    assert ("published 4 messages: /arm/trajectory 1, /chatter 1, /goal_pose 1, "
            "/planner/push 1") in captured.out
    assert "leaving out" not in captured.err
    assert cli.main(["bag", "play", str(bag), "--rate", "100", "--topics", "goal_pose"]) == 0
    captured = capsys.readouterr()
    assert "published 1 messages: /goal_pose 1" in captured.out and "leaving" not in captured.err


# --- record: short-lived publishers and the default folder ---------------------------------

def test_record_all_catches_a_short_lived_publisher(tmp_path: Path, processes) -> None:
    # What `pushbot goal` does: a new process, a new topic, one message once a subscriber
    # matched (waiting at most 4 s, DDS discovery of the new process included), the publisher
    # gone 2 s later. `bag record --all`, already running, must subscribe within that window
    # (a recorder that looks for new topics too rarely misses the message).
    from rosbags.rosbag2 import Reader

    from pushbot.ros2cli.bag_record import BagRecorder, TopicSelection

    topic = f"/short_lived_{time.monotonic_ns()}"
    with BagRecorder(tmp_path / "bag", TopicSelection(all_topics=True)) as recorder:
        proc = processes.start([PUSHBOT, "topic", "pub", topic, "std_msgs/msg/String",
                                "{data: once}", "--once", "-w", "1", "--max-wait-time-secs", "4",
                                "--keep-alive", "2"],
                               name="pub")
        assert proc.wait(timeout=60) == 0, processes.output(proc)
        deadline = time.monotonic() + 30.0  # the sample's way to the recorder
        while recorder.counts().get(topic, 0) < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        counts = recorder.counts()
    assert counts.get(topic) == 1, (counts, processes.output(proc))
    with Reader(tmp_path / "bag") as reader:
        assert {c.topic: c.msgcount for c in reader.connections}[topic] == 1


def test_record_all_catches_the_goal_of_pushbot_goal(tmp_path: Path, processes) -> None:
    # `pushbot goal` (no --wait) waits for the planner, sends the latched goal and lingers, so a
    # recorder discovering the new process meanwhile still gets it. The linger here is long
    # (20 s, the default 2 s) so that discovery on a loaded machine stays far inside it; the goal
    # is interrupted once the recorder holds the message.
    from pushbot.ros2cli.bag_record import BagRecorder, TopicSelection

    planner = processes.node("planner_node")
    with BagRecorder(tmp_path / "bag", TopicSelection(all_topics=True)) as recorder:
        goal = processes.start([PUSHBOT, "goal", "0.03", "0", "0", "--linger", "20"],
                               name="goal")
        deadline = time.monotonic() + 60
        while recorder.counts().get("/goal_pose", 0) < 1 and time.monotonic() < deadline \
                and goal.poll() is None:
            time.sleep(0.1)
        if goal.poll() is None:
            goal.send_signal(signal.SIGINT)
        assert goal.wait(timeout=90) in (0, 130), processes.output(goal)
        time.sleep(0.5)  # a second sample would have had time to arrive
        counts = recorder.counts()
    assert planner.poll() is None, processes.output(planner)
    assert processes.output(goal).startswith("goal sent: x 0.03 m")
    assert counts.get("/goal_pose") == 1, (counts, processes.output(goal))


def test_record_without_output_writes_under_out(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert cli.main(["bag", "record", "/nobody_publishes_this", "--duration", "0.5"]) == 1
    out = capsys.readouterr().out
    (bag,) = (tmp_path / "out").iterdir()
    assert bag.name.startswith("rosbag2_") and (bag / "metadata.yaml").is_file()
    assert f"recording to out/{bag.name}" in out
    assert not list(tmp_path.glob("rosbag2_*"))
