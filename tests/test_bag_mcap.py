"""Bags written by ``pushbot.ros2cli.bag_mcap`` as rosbag2 Jazzy writes them.

ROS-free: messages serialized with the ``rosbags`` Jazzy type store are written with
:class:`~pushbot.ros2cli.bag_mcap.Rosbag2McapWriter` at chosen times, then read back with the
official readers (``mcap`` with CRC validation, ``mcap-ros2-support`` decoding) and with
``rosbags`` (what ``pushbot bag info/play`` use): CRCs validate (and a flipped byte fails them),
channels
carry ``offered_qos_profiles`` and ``topic_type_hash``, publish and log times are the given
ones, ``ros_distro`` is Jazzy's, counts agree with metadata.yaml.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import pytest
import yaml

LOG = (1_700_000_000_000_000_000, 1_700_000_000_250_000_000, 1_700_000_001_000_000_000)
SENT = (1_700_000_000_000_000_000 - 3_000, 1_700_000_000_250_000_000 - 5_000, None)


def _qos(durability: str = "VOLATILE"):
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    zero = QosTime(sec=0, nsec=0)
    return Qos(history=QosHistory.KEEP_LAST, depth=10, reliability=QosReliability.RELIABLE,
               durability=QosDurability[durability], deadline=zero, lifespan=zero,
               liveliness=QosLiveliness.AUTOMATIC, liveliness_lease_duration=zero,
               avoid_ros_namespace_conventions=False)


def _write(path: Path, compress: bool = True) -> None:
    """/chatter: 3 Strings ``m0``, ``m1``, ``m2`` at LOG (two with a publish time SENT, one
    unknown); /pose: one latched PoseStamped."""
    from rosbags.typesys import Stores, get_typestore

    from pushbot.ros2cli.bag_mcap import Rosbag2McapWriter
    from pushbot.ros2cli.bag_store import message_definition

    store = get_typestore(Stores.ROS2_JAZZY)
    string = store.types["std_msgs/msg/String"]
    with Rosbag2McapWriter(path, compress=compress) as writer:
        msgdef, rihs01 = message_definition("std_msgs/msg/String")
        chatter = writer.add_topic("/chatter", "std_msgs/msg/String", msgdef, rihs01, [_qos()])
        msgdef, rihs01 = message_definition("geometry_msgs/msg/PoseStamped")
        pose_id = writer.add_topic("/pose", "geometry_msgs/msg/PoseStamped", msgdef, rihs01,
                                   [_qos("TRANSIENT_LOCAL")])
        for k, (log, sent) in enumerate(zip(LOG, SENT, strict=True)):
            writer.write(chatter, log, bytes(store.serialize_cdr(string(data=f"m{k}"),
                                                                 "std_msgs/msg/String")), sent)
        t = store.types
        pose = t["geometry_msgs/msg/PoseStamped"](
            header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](
                sec=1_700_000_000, nanosec=500), frame_id="world"),
            pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=1.25, y=0.0, z=0.0),
                orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
        writer.write(pose_id, LOG[1] + 1, bytes(store.serialize_cdr(
            pose, "geometry_msgs/msg/PoseStamped")), LOG[1])


@pytest.fixture
def bag(tmp_path: Path, monkeypatch) -> Path:
    monkeypatch.delenv("ROS_DISTRO", raising=False)
    path = tmp_path / "bag"
    _write(path)
    return path


def test_official_reader_validates_crcs_and_decodes(bag: Path) -> None:
    from mcap.reader import NonSeekingReader, make_reader
    from mcap.records import Chunk, DataEnd
    from mcap.stream_reader import StreamReader
    from mcap_ros2.decoder import DecoderFactory

    data = (bag / "bag_0.mcap").read_bytes()
    # Every chunk and the data section carry a CRC (0 would mean "none": readers skip it)...
    with (bag / "bag_0.mcap").open("rb") as f:
        records = list(StreamReader(f, emit_chunks=True).records)
    crcs = [r.uncompressed_crc for r in records if isinstance(r, Chunk)]
    assert crcs and all(crcs)
    assert [r.data_section_crc != 0 for r in records if isinstance(r, DataEnd)] == [True]
    # ... and NonSeekingReader checks them all.
    with (bag / "bag_0.mcap").open("rb") as f:
        records = list(NonSeekingReader(f, validate_crcs=True).iter_messages())
    assert len(records) == 4
    with (bag / "bag_0.mcap").open("rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        assert header.profile == "ros2"
        summary = reader.get_summary()
        decoded = [(c.topic, m.log_time, m.publish_time, d)
                   for _, c, m, d in reader.iter_decoded_messages()]
    # Summary CRC (footer): crc32 of the summary section up to the footer's summary_crc field.
    summary_start, _offsets, summary_crc = struct.unpack("<QQI", data[-8 - 20:-8])
    assert summary_start > 0 and summary_crc != 0
    assert zlib.crc32(data[summary_start:-8 - 4]) == summary_crc
    assert all(ci.compression == "zstd" for ci in summary.chunk_indexes)
    chatter = [d for d in decoded if d[0] == "/chatter"]
    assert [d[3].data for d in chatter] == ["m0", "m1", "m2"]
    # log_time = receive time; publish_time = the sender's stamp, the log time when unknown.
    assert [(d[1], d[2]) for d in chatter] == [(LOG[0], SENT[0]), (LOG[1], SENT[1]),
                                               (LOG[2], LOG[2])]
    (pose,) = [d for d in decoded if d[0] == "/pose"]
    assert pose[3].pose.position.x == 1.25 and pose[3].header.stamp.nanosec == 500


def test_a_changed_byte_fails_the_chunk_crc(tmp_path: Path) -> None:
    # Uncompressed chunks (zstd would notice the damage itself): message text m1 -> n1.
    from mcap.reader import make_reader
    from mcap.stream_reader import CRCValidationError

    _write(tmp_path / "bag", compress=False)
    data = (tmp_path / "bag" / "bag_0.mcap").read_bytes()
    assert data.count(b"m1\x00") == 1
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(data.replace(b"m1\x00", b"n1\x00"))
    with broken.open("rb") as f:  # without validation the damage goes unnoticed
        texts = [m.data for _, _, m in make_reader(f).iter_messages(topics=["/chatter"])]
    assert any(b"n1" in t for t in texts)
    with broken.open("rb") as f, pytest.raises(CRCValidationError):
        list(make_reader(f, validate_crcs=True).iter_messages())


def test_channels_carry_qos_and_type_hash(bag: Path) -> None:
    from mcap.reader import make_reader

    from pushbot.ros2cli.bag_store import message_definition

    with (bag / "bag_0.mcap").open("rb") as f:
        summary = make_reader(f).get_summary()
    channels = {c.topic: c for c in summary.channels.values()}
    schemas = {s.id: s for s in summary.schemas.values()}
    _, rihs01 = message_definition("std_msgs/msg/String")
    chatter = channels["/chatter"]
    assert chatter.message_encoding == "cdr"
    assert chatter.metadata["topic_type_hash"] == rihs01 and rihs01.startswith("RIHS01_")
    assert schemas[chatter.schema_id].name == "std_msgs/msg/String"
    assert schemas[chatter.schema_id].encoding == "ros2msg"
    (qos,) = yaml.safe_load(channels["/pose"].metadata["offered_qos_profiles"])
    assert qos["durability"] == "transient_local" and qos["reliability"] == "reliable"
    assert qos["depth"] == 10 and qos["history"] == "keep_last"
    assert summary.statistics.channel_message_counts == {chatter.id: 3,
                                                         channels["/pose"].id: 1}


def test_metadata_is_jazzy_and_agrees_with_the_file(bag: Path) -> None:
    from mcap.reader import make_reader

    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["ros_distro"] == "jazzy" and info["version"] == 9
    assert info["storage_identifier"] == "mcap" and info["relative_file_paths"] == ["bag_0.mcap"]
    assert info["message_count"] == 4
    assert info["starting_time"]["nanoseconds_since_epoch"] == LOG[0]
    assert info["duration"]["nanoseconds"] == LOG[2] - LOG[0]
    assert info["files"] == [{"path": "bag_0.mcap", "message_count": 4,
                              "starting_time": {"nanoseconds_since_epoch": LOG[0]},
                              "duration": {"nanoseconds": LOG[2] - LOG[0]}}]
    counts = {t["topic_metadata"]["name"]: t["message_count"]
              for t in info["topics_with_message_count"]}
    assert counts == {"/chatter": 3, "/pose": 1}
    hashes = {t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
              for t in info["topics_with_message_count"]}
    with (bag / "bag_0.mcap").open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        (record,) = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
    assert {c.topic: c.metadata["topic_type_hash"]
            for c in summary.channels.values()} == hashes
    # The rosbag2 metadata record: the same metadata (rosbag2_storage_mcap reads ros_distro
    # from it when metadata.yaml is lost, e.g. `ros2 bag reindex`).
    assert yaml.safe_load(record.metadata["serialized_metadata"]) == info


def test_ros_distro_follows_the_environment(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("ROS_DISTRO", "kilted")
    _write(tmp_path / "bag")
    info = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())
    assert info["rosbag2_bagfile_information"]["ros_distro"] == "kilted"


def test_rosbags_reads_it_as_bag_info_and_play_do(bag: Path, capsys) -> None:
    from pushbot import cli
    from pushbot.ros2cli.bag_store import open_reader, read_messages

    with open_reader(bag) as reader:
        assert reader.ros_distro == "jazzy"
        assert {c.topic: c.msgcount for c in reader.connections} == {"/chatter": 3, "/pose": 1}
        stamps = [t for _, t, _ in read_messages(reader, reader.connections)]
    assert stamps == sorted([*LOG, LOG[1] + 1])
    assert cli.main(["bag", "info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "ROS Distro:        jazzy" in out and "Messages:          4" in out


def test_message_times_follow_rosbag2() -> None:
    from pushbot.ros2cli.bag_store import message_times

    info = {"source_timestamp": 11, "received_timestamp": 22,
            "publication_sequence_number": 1, "reception_sequence_number": 1}
    assert message_times(info) == (22, 11)
    log, sent = message_times({"source_timestamp": 0, "received_timestamp": 0})
    assert sent is None and log > 1_600_000_000 * 10**9  # now, wall clock
    log, sent = message_times(None)
    assert sent is None and log > 1_600_000_000 * 10**9


def test_an_existing_folder_is_refused(tmp_path: Path) -> None:
    from pushbot.ros2cli.bag_mcap import Rosbag2McapWriter

    (tmp_path / "bag").mkdir()
    with pytest.raises(FileExistsError):
        Rosbag2McapWriter(tmp_path / "bag").open()


def test_bag_info_and_play_read_a_bag_as_rosbag2_writes_it_by_default(tmp_path: Path,
                                                                     capsys) -> None:
    # rosbag2 Jazzy's own defaults (rosbag2_storage_mcap): uncompressed chunks without chunk
    # CRCs, a `rosbag2` metadata record at open (no topics yet) and one at close, QoS and
    # type hash in the channel metadata, metadata.yaml with `custom_data: ~`. Written here
    # with the mcap library; `pushbot bag info` and the reader of `bag play` must take it.
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    from pushbot import cli
    from pushbot.ros2cli.bag_mcap import dump_qos
    from pushbot.ros2cli.bag_store import message_definition, open_reader, read_messages

    store = get_typestore(Stores.ROS2_JAZZY)
    bag = tmp_path / "rosbag2_2026_12_03-10_00_00"
    bag.mkdir()
    name = f"{bag.name}_0.mcap"
    msgdef, rihs01 = message_definition("std_msgs/msg/String")
    qos = yaml.safe_dump(dump_qos([_qos()]))
    topic = {"name": "/chatter", "type": "std_msgs/msg/String", "serialization_format": "cdr",
             "offered_qos_profiles": dump_qos([_qos()]), "type_description_hash": rihs01}
    times = (LOG[0], LOG[0] + 10**8)

    def metadata(count: int) -> dict:
        return {"version": 9, "storage_identifier": "mcap", "duration": {
            "nanoseconds": times[1] - times[0] if count else 0},
            "starting_time": {"nanoseconds_since_epoch": times[0]}, "message_count": count,
            "topics_with_message_count": [{"topic_metadata": topic, "message_count": count}]
            if count else [], "compression_format": "", "compression_mode": "",
            "relative_file_paths": [name], "files": [{
                "path": name, "starting_time": {"nanoseconds_since_epoch": times[0]},
                "duration": {"nanoseconds": times[1] - times[0]}, "message_count": count}],
            "custom_data": None, "ros_distro": "jazzy"}

    with (bag / name).open("wb") as f:
        writer = Writer(f, compression=CompressionType.NONE, enable_crcs=False)
        writer.start(profile="ros2", library="libmcap 1.4.0")
        writer.add_metadata("rosbag2", {"serialized_metadata": yaml.safe_dump(metadata(0))})
        schema = writer.register_schema("std_msgs/msg/String", "ros2msg", msgdef.encode())
        channel = writer.register_channel("/chatter", "cdr", schema, {
            "offered_qos_profiles": qos, "topic_type_hash": rihs01})
        for k, t in enumerate(times):
            data = store.serialize_cdr(store.types["std_msgs/msg/String"](data=f"r{k}"),
                                       "std_msgs/msg/String")
            writer.add_message(channel, log_time=t, data=bytes(data), publish_time=t - 7)
        writer.add_metadata("rosbag2", {"serialized_metadata": yaml.safe_dump(metadata(2))})
        writer.finish()
    (bag / "metadata.yaml").write_text(yaml.safe_dump(
        {"rosbag2_bagfile_information": metadata(2)}).replace("custom_data: null",
                                                              "custom_data: ~"))
    assert cli.main(["bag", "info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "ROS Distro:        jazzy" in out and "Messages:          2" in out
    assert "Topic: /chatter | Type: std_msgs/msg/String | Count: 2" in out
    with open_reader(bag) as reader:
        got = [(t, store.deserialize_cdr(d, c.msgtype).data)
               for c, t, d in read_messages(reader, reader.connections)]
    assert got == [(times[0], "r0"), (times[1], "r1")]
