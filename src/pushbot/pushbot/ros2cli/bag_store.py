"""What a rosbag2/MCAP folder holds and how it is read: message definitions, the offered QoS
profiles and receive times as rosbag2 stores them, and the ``rosbags`` reader with one-line
errors. Shared by ``pushbot bag`` (:mod:`pushbot.ros2cli.bag`), the recorder
(:mod:`pushbot.ros2cli.bag_record`), the viewer and the episode renderer.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rclpy.topic_endpoint_info import TopicEndpointInfo

__all__ = ["BagError", "message_definition", "message_times", "offered_qos", "open_reader",
           "read_messages", "rosbags_package"]


class BagError(ValueError):
    """A bag that cannot be written or read; the message is the one-line diagnostic."""


def rosbags_package() -> Any:
    """Import ``rosbags`` (a pip-only dependency, hence optional here) with a one-line error
    when it is missing; returns the package with ``interfaces``, ``rosbag2`` and ``typesys``
    loaded."""
    try:
        import rosbags.interfaces
        import rosbags.rosbag2
        import rosbags.typesys
    except ImportError as exc:
        raise BagError(f"the rosbags package is not installed ({exc}): run make venv") from exc
    return rosbags


_TYPESTORE: Any = None


def message_definition(msgtype: str) -> tuple[str, str]:
    """The full ``ros2msg`` definition and RIHS01 hash of ``msgtype`` (``pkg/msg/Type``).

    The definition is the one rosbag2 stores in an MCAP schema: the type's fields followed by
    every nested type, each after a ``MSG: pkg/msg/Type`` separator line. Types come from the
    ROS 2 Jazzy type store of ``rosbags``; a type missing there is loaded from the ``.msg`` file
    of the installed interface package (``<prefix>/share/<pkg>/msg``).

    Raises
    ------
    BagError
        When the type is unknown.
    """
    global _TYPESTORE
    rosbags = rosbags_package()
    typesys = rosbags.typesys
    if _TYPESTORE is None:
        _TYPESTORE = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    store = _TYPESTORE
    if msgtype not in store.fielddefs:
        parts = msgtype.split("/")
        found = [Path(prefix) / "share" / parts[0] / "msg" / f"{parts[-1]}.msg"
                 for prefix in {sys.prefix, "/opt/ros/jazzy"}] if len(parts) == 3 else []
        path = next((p for p in found if p.is_file()), None)
        if path is None:
            raise BagError(f"unknown message type '{msgtype}' (neither in the Jazzy type store "
                           "nor installed as a .msg file)")
        store.register(typesys.get_types_from_msg(path.read_text(), msgtype))
    try:
        msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
        return msgdef, store.hash_rihs01(msgtype)
    except (KeyError, typesys.TypesysError) as exc:
        raise BagError(f"cannot describe message type '{msgtype}': {exc}") from exc


def _qos_time(duration: Any) -> Any:
    sec, nsec = divmod(int(duration.nanoseconds), 1_000_000_000)
    return rosbags_package().interfaces.QosTime(sec=sec, nsec=nsec)


def offered_qos(publishers: Sequence[TopicEndpointInfo]) -> list[Any]:
    """The publishers' QoS profiles as ``rosbags`` ``Qos`` tuples (metadata.yaml's
    ``offered_qos_profiles``)."""
    i = rosbags_package().interfaces
    out = []
    for info in publishers:
        q = info.qos_profile
        out.append(i.Qos(
            history=i.QosHistory[q.history.name],
            depth=int(q.depth),
            reliability=i.QosReliability[q.reliability.name],
            durability=i.QosDurability[q.durability.name],
            deadline=_qos_time(q.deadline),
            lifespan=_qos_time(q.lifespan),
            liveliness=i.QosLiveliness[q.liveliness.name],
            liveliness_lease_duration=_qos_time(q.liveliness_lease_duration),
            avoid_ros_namespace_conventions=bool(q.avoid_ros_namespace_conventions),
        ))
    return out


def message_times(info: Any) -> tuple[int, int | None]:
    """(log time, publish time) of a received message, ns since the Unix epoch, as rosbag2
    records them: the message info's ``received_timestamp`` (now if the info has none) and
    its ``source_timestamp`` (the sender's clock; None when unknown).

    Parameters
    ----------
    info : dict or None
        rclpy's message info of a two-argument subscription callback.
    """
    def stamp(key: str) -> int | None:
        value = info.get(key) if isinstance(info, dict) else None
        ok = isinstance(value, int) and not isinstance(value, bool) and value > 0
        return int(value) if ok else None

    return stamp("received_timestamp") or time.time_ns(), stamp("source_timestamp")


def _check_bag_folder(path: Path) -> Path:
    if not path.is_dir():
        raise BagError(f"{path} is not a bag folder")
    if not (path / "metadata.yaml").is_file():
        raise BagError(f"{path} has no metadata.yaml: not a rosbag2 folder")
    return path


@contextmanager
def open_reader(path: Path) -> Iterator[Any]:
    """The opened ``rosbags`` reader of the bag folder ``path`` (a context manager).

    Raises
    ------
    BagError
        When the folder is no bag or cannot be read (one-line message).
    """
    rosbags = rosbags_package()
    reader = rosbags.rosbag2.Reader(_check_bag_folder(Path(path)))
    try:
        reader.open()
    except Exception as exc:  # any reader error is a broken bag, reported in one line
        raise BagError(f"cannot read bag {path}: {type(exc).__name__}: {exc}") from exc
    try:
        yield reader
    finally:
        reader.close()


def read_messages(reader: Any, connections: Sequence[Any]) -> Iterator[tuple[Any, int, bytes]]:
    """``(connection, receive time ns, CDR bytes)`` of ``connections`` in time order; a
    damaged file raises :class:`BagError` (one line) instead of the reader's exception."""
    try:
        yield from reader.messages(connections=connections)
    except Exception as exc:  # any reader error is a damaged bag
        raise BagError(f"cannot read the messages of the bag: {type(exc).__name__}: {exc}"
                       ) from exc
