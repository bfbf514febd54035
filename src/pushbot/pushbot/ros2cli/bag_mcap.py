"""rosbag2 folders written as ROS 2 Jazzy's ``ros2 bag record -s mcap`` writes them.

:class:`Rosbag2McapWriter` writes one ``<folder>/<folder>_0.mcap`` with the official ``mcap``
library and ``<folder>/metadata.yaml`` itself, with what Jazzy's rosbag2 (``SequentialWriter``
and ``rosbag2_storage_mcap``) puts there:

- MCAP header profile ``ros2``; one ``ros2msg`` schema per message type (the full definition);
  one ``cdr`` channel per topic whose metadata carries ``offered_qos_profiles`` (the YAML list
  of the publishers' QoS profiles) and ``topic_type_hash`` (the type's ``RIHS01_...`` hash);
- per message ``log_time`` = the receive time and ``publish_time`` = the sender's source
  timestamp (rosbag2's ``recv_timestamp`` / ``send_timestamp``), ``sequence`` 0, both in ns
  since the Unix epoch;
- a ``rosbag2`` metadata record with ``serialized_metadata`` (the bag metadata as YAML, with
  ``ros_distro``) before the summary;
- ``metadata.yaml``: rosbag2 metadata version 9 with ``ros_distro`` (``$ROS_DISTRO``, else
  ``jazzy``: the distribution the pip wheels are), files, topics with their message counts,
  QoS profiles and ``type_description_hash``.

Integrity: chunk CRCs, the data section CRC and the summary CRC are written, so any MCAP
reader can verify the file (rosbag2's own defaults leave out the chunk and data CRCs and
compress nothing; the chunks here are zstd-compressed, as with rosbag2's ``zstd_small``
preset). Reading stays with ``rosbags`` (``pushbot.ros2cli.bag``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import yaml

#: rosbag2 metadata version of ROS 2 Jazzy (offered QoS profiles as a YAML list, type hashes).
ROSBAG2_VERSION = 9
#: ``ros_distro`` when ``$ROS_DISTRO`` is not set: the distribution of the pip wheels.
DEFAULT_ROS_DISTRO = "jazzy"
#: Uncompressed bytes per MCAP chunk (the ``mcap`` library's and rosbag2's default, 1 MiB).
CHUNK_SIZE = 1024 * 1024


def ros_distro() -> str:
    """The ``ros_distro`` a bag records: ``$ROS_DISTRO`` (as rosbag2), else ``jazzy``."""
    return os.environ.get("ROS_DISTRO", "").strip() or DEFAULT_ROS_DISTRO


def _missing(package: str, exc: ImportError) -> ImportError:
    return ImportError(f"the {package} package is not installed ({exc}): run make venv")


def dump_qos(profiles: list[Any]) -> list[dict[str, Any]]:
    """Offered QoS profiles (``rosbags.interfaces.Qos``) as metadata version 9 mappings."""
    try:  # pip-only dependencies: a one-line error where they are missing
        from rosbags.rosbag2.metadata import dump_qos_v9
    except ImportError as exc:
        raise _missing("rosbags", exc) from exc
    return dump_qos_v9(list(profiles))


def _yaml(data: Any) -> str:
    return yaml.safe_dump(data, default_flow_style=False, sort_keys=False)


@dataclass
class _Topic:
    name: str
    msgtype: str
    serialization_format: str
    offered_qos_profiles: list[Any]
    type_hash: str
    channel_id: int
    count: int = 0


@dataclass
class Rosbag2McapWriter:
    """Writes a new rosbag2 folder in MCAP storage (module docstring); a context manager.

    Not thread-safe: the caller serialises :meth:`add_topic`, :meth:`write` and :meth:`close`.

    Parameters
    ----------
    path : Path
        The bag folder; created, must not exist.
    compress : bool
        zstd-compress the chunks (default) or store them as they are.
    """

    path: Path
    compress: bool = True
    topics: dict[str, _Topic] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        self._file: IO[bytes] | None = None
        self._mcap: Any = None
        self._schemas: dict[str, int] = {}
        self._channels: dict[int, _Topic] = {}
        self.start_ns: int | None = None
        self.end_ns: int | None = None

    @property
    def mcap_path(self) -> Path:
        """The MCAP file: ``<folder>/<folder name>_0.mcap`` (rosbag2's name of a bag's first
        file)."""
        return self.path / f"{self.path.name}_0.mcap"

    def open(self) -> None:
        """Create the folder and the MCAP file and write its header.

        Raises
        ------
        FileExistsError
            When the folder exists.
        OSError
            When it cannot be created.
        ImportError
            When the ``mcap`` package is missing.
        """
        from importlib.metadata import version

        try:
            from mcap.writer import CompressionType, Writer
        except ImportError as exc:
            raise _missing("mcap", exc) from exc

        self.path.mkdir(parents=True, exist_ok=False)
        self._file = self.mcap_path.open("xb")
        self._mcap = Writer(self._file, chunk_size=CHUNK_SIZE,
                            compression=CompressionType.ZSTD if self.compress
                            else CompressionType.NONE,
                            enable_crcs=True, enable_data_crcs=True)
        self._mcap.start(profile="ros2", library=f'pushbot bag (mcap-python {version("mcap")})')

    def __enter__(self) -> Rosbag2McapWriter:
        self.open()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def add_topic(self, name: str, msgtype: str, msgdef: str, type_hash: str,
                  offered_qos_profiles: list[Any], serialization_format: str = "cdr") -> int:
        """Add a topic (an MCAP channel, and the schema of its type if new).

        Parameters
        ----------
        name : str
            Absolute topic name.
        msgtype : str
            ``pkg/msg/Type``.
        msgdef : str
            Full ``ros2msg`` definition (``pushbot.ros2cli.bag_store.message_definition``).
        type_hash : str
            ``RIHS01_<hex>`` type hash.
        offered_qos_profiles : list of rosbags.interfaces.Qos
            The publishers' QoS profiles.
        serialization_format : str
            The channel's message encoding.

        Returns
        -------
        int
            The channel id to :meth:`write` with.
        """
        if name in self.topics:
            raise ValueError(f"topic {name} was added already")
        if msgtype not in self._schemas:
            self._schemas[msgtype] = self._mcap.register_schema(
                name=msgtype, encoding="ros2msg", data=msgdef.encode())
        qos_text = _yaml(dump_qos(offered_qos_profiles)).strip()
        channel_id = self._mcap.register_channel(
            topic=name, message_encoding=serialization_format,
            schema_id=self._schemas[msgtype],
            metadata={"offered_qos_profiles": qos_text, "topic_type_hash": type_hash})
        topic = _Topic(name, msgtype, serialization_format, list(offered_qos_profiles),
                       type_hash, channel_id)
        self.topics[name] = self._channels[channel_id] = topic
        return channel_id

    def write(self, channel_id: int, log_time: int, data: bytes,
              publish_time: int | None = None) -> None:
        """Write one serialized message.

        Parameters
        ----------
        channel_id : int
            From :meth:`add_topic`.
        log_time : int
            Receive time, ns since the Unix epoch.
        data : bytes
            The serialized (CDR) message.
        publish_time : int, optional
            The sender's source timestamp, ns since the Unix epoch; ``log_time`` when unknown.
        """
        topic = self._channels[channel_id]
        publish = log_time if publish_time is None or publish_time <= 0 else publish_time
        self._mcap.add_message(channel_id=channel_id, log_time=int(log_time), data=bytes(data),
                               publish_time=int(publish), sequence=0)
        topic.count += 1
        self.start_ns = log_time if self.start_ns is None else min(self.start_ns, log_time)
        self.end_ns = log_time if self.end_ns is None else max(self.end_ns, log_time)

    def metadata(self) -> dict[str, Any]:
        """The bag metadata as of now (the ``rosbag2_bagfile_information`` mapping)."""
        start = self.start_ns or 0
        duration = max(0, (self.end_ns or 0) - start)
        count = sum(t.count for t in self.topics.values())
        name = self.mcap_path.name
        return {
            "version": ROSBAG2_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": count,
            "topics_with_message_count": [
                {"topic_metadata": {"name": t.name, "type": t.msgtype,
                                    "serialization_format": t.serialization_format,
                                    "offered_qos_profiles": dump_qos(t.offered_qos_profiles),
                                    "type_description_hash": t.type_hash},
                 "message_count": t.count}
                for t in self.topics.values()],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [name],
            "files": [{"path": name, "starting_time": {"nanoseconds_since_epoch": start},
                       "duration": {"nanoseconds": duration}, "message_count": count}],
            "custom_data": None,
            "ros_distro": ros_distro(),
        }

    def close(self) -> None:
        """Write the ``rosbag2`` metadata record, the MCAP summary and ``metadata.yaml``
        (idempotent)."""
        if self._mcap is None:
            return
        mcap, self._mcap = self._mcap, None
        info = self.metadata()
        try:
            mcap.add_metadata("rosbag2", {"serialized_metadata": _yaml(info)})
            mcap.finish()
        finally:
            if self._file is not None:
                self._file.close()
                self._file = None
        tmp = self.path / "metadata.yaml.tmp"
        tmp.write_text(_yaml({"rosbag2_bagfile_information": info}), encoding="utf-8")
        tmp.replace(self.path / "metadata.yaml")
