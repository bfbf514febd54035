"""``pushbot bag record``'s recorder: topics of the live graph into a new rosbag2/MCAP folder.

A hidden node (own rclpy context) spins in a background thread, subscribes to each selected
topic as soon as it has a publisher, with a QoS compatible with all its publishers, and
stores the CDR bytes rclpy receives (``raw=True``, never decoded) with the publishers' offered
QoS profiles (:mod:`pushbot.ros2cli.bag_mcap` writes the files). ``pushbot demo`` records its
episode with it.
"""

from __future__ import annotations

import re
import sys
import threading
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pushbot.ros2cli.bag_mcap import Rosbag2McapWriter
from pushbot.ros2cli.bag_store import (
    BagError,
    message_definition,
    message_times,
    offered_qos,
    rosbags_package,
)
from pushbot.ros2cli.discovery import cli_node, compatible_qos, import_message_class, spin_until

if TYPE_CHECKING:
    from rclpy.topic_endpoint_info import TopicEndpointInfo

__all__ = ["DEFAULT_EXCLUDED", "DISCOVERY_PERIOD", "BagRecorder", "TopicSelection"]

#: Topics ``record --all`` leaves out unless named: rosout and the parameter event stream.
DEFAULT_EXCLUDED = ("/rosout", "/parameter_events")
#: Seconds between two looks at the graph for new topics while recording: short, so that a
#: short-lived publisher (``pushbot goal``, ``topic pub --once``) is subscribed while it lives
#: (a look costs well under a millisecond on a graph of this size).
DISCOVERY_PERIOD = 0.1


@dataclass
class _Topic:
    name: str
    msgtype: str
    channel_id: int
    subscription: Any
    count: int = 0


@dataclass
class TopicSelection:
    """Which topics to record: the named ones (exact, resolved names), or all but those
    matching ``exclude``."""

    topics: tuple[str, ...] = ()
    all_topics: bool = False
    exclude: re.Pattern[str] | None = None

    def wants(self, name: str) -> bool:
        """Whether topic ``name`` (absolute) is recorded."""
        if self.exclude is not None and self.exclude.search(name):
            return False
        if self.topics:
            return name in self.topics
        return self.all_topics and name not in DEFAULT_EXCLUDED


@dataclass
class BagRecorder:
    """Records topics of the live graph into a new rosbag2/MCAP folder; a context manager.

    ``start()`` opens the bag and spins a hidden node (own rclpy context) in a background
    thread; ``stop()`` ends it and writes the MCAP summary and ``metadata.yaml``. Topics are
    subscribed as soon as they have a publisher.

    Parameters
    ----------
    path : Path
        The bag folder; must not exist.
    selection : TopicSelection
    """

    path: Path
    selection: TopicSelection
    topics: dict[str, _Topic] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    #: Callback failures (e.g. a full disk) per callback name: those messages are not in the
    #: bag; :func:`pushbot.ros2cli.bag.cmd_record` reports them.
    errors: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._writer: Any = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._node: Any = None

    def __enter__(self) -> BagRecorder:
        self.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def start(self) -> None:
        """Open the bag and start recording in the background."""
        rosbags_package()
        if self.path.exists():
            raise BagError(f"{self.path} exists already: choose another -o folder")
        # zstd-compressed chunks (compression_mode stays '' in the metadata: the storage
        # compresses, not rosbag2).
        writer = Rosbag2McapWriter(self.path)
        try:
            writer.open()
        except ImportError as exc:
            raise BagError(str(exc)) from exc
        except OSError as exc:
            raise BagError(f"cannot create bag {self.path}: {exc}") from exc
        self._writer = writer
        self._thread = threading.Thread(target=self._spin, name="bag_record", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            self.stop()
            raise self._error

    def _spin(self) -> None:
        try:
            with cli_node("bag_record") as (node, executor):
                from push_ros.node import ThrottledLog

                self._node = node
                self._log = ThrottledLog(node.get_logger(), 5.0)
                self._discover()
                node.create_timer(DISCOVERY_PERIOD, self._guard(self._discover, "discover"))
                self._ready.set()
                while not self._stop.is_set() and node.context.ok():
                    executor.spin_once(timeout_sec=0.05)
                self._node = None
        except BaseException as exc:  # reported by start() or stop()
            self._error = exc
        finally:
            self._ready.set()

    def _discover(self) -> None:
        node = self._node
        for name, types in node.get_topic_names_and_types():
            if name in self.topics or name in self.skipped or not self.selection.wants(name):
                continue
            publishers = node.get_publishers_info_by_topic(name)
            if not publishers:
                continue
            self._subscribe(name, types, publishers)

    def _subscribe(self, name: str, types: Sequence[str],
                   publishers: Sequence[TopicEndpointInfo]) -> None:
        if len(types) != 1:
            self.skipped[name] = f"published with several types {sorted(types)}"
            print(f"bag record: skipping {name}: {self.skipped[name]}", file=sys.stderr)
            return
        msgtype = types[0]
        try:
            cls = import_message_class(msgtype)
            msgdef, rihs01 = message_definition(msgtype)
        except (LookupError, BagError) as exc:
            self.skipped[name] = str(exc)
            print(f"bag record: skipping {name}: {exc}", file=sys.stderr)
            return
        qos = compatible_qos(publishers, depth=100)
        with self._lock:
            channel_id = self._writer.add_topic(name, msgtype, msgdef, rihs01,
                                                offered_qos(publishers))
        entry = _Topic(name, msgtype, channel_id, None)
        guarded_write = self._guard(lambda data, info, e=entry: self._write(e, data, info),
                                    f"write {name}")

        def write(data: bytes, info: Any) -> None:  # 2 arguments: rclpy passes message info
            guarded_write(data, info)

        entry.subscription = self._node.create_subscription(cls, name, write, qos, raw=True)
        self.topics[name] = entry

    def _guard(self, callback: Any, name: str) -> Any:
        """``callback`` that never raises (push_ros.node.guarded); failures are counted."""
        from push_ros.node import guarded

        def count(label: str, _message: str) -> None:
            self.errors[label] = self.errors.get(label, 0) + 1

        return guarded(callback, self._log, on_error=count, name=name)

    def _write(self, entry: _Topic, data: bytes, info: Any = None) -> None:
        log_time, publish_time = message_times(info)
        with self._lock:
            if self._writer is None:
                return
            self._writer.write(entry.channel_id, log_time, data, publish_time)
            entry.count += 1

    def wait_for_topics(self, names: Iterable[str], timeout: float) -> list[str]:
        """Wait until every topic of ``names`` is subscribed; returns those still missing."""
        names = list(names)
        spin_until(None, lambda: all(n in self.topics for n in names),
                   time.monotonic() + timeout)
        return [n for n in names if n not in self.topics]

    @property
    def running(self) -> bool:
        """Whether the recording thread still spins (False after rclpy shut its context down,
        e.g. on a SIGINT that rclpy's own signal handler took)."""
        return self._thread is not None and self._thread.is_alive()

    def counts(self) -> dict[str, int]:
        """Messages written per recorded topic."""
        return {name: t.count for name, t in sorted(self.topics.items())}

    def stop(self) -> None:
        """Stop recording and close the bag (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
            self._thread = None
        with self._lock:
            writer, self._writer = self._writer, None
        if writer is not None:
            writer.close()
