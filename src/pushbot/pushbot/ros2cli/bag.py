"""``pushbot bag record|info|play``: rosbag2 folders in MCAP storage without ``ros2 bag``.

A bag is what ``ros2 bag record -s mcap`` writes on ROS 2 Jazzy: a folder with
``metadata.yaml`` (rosbag2 metadata version 9: per topic its type, ``cdr`` serialization,
the offered QoS profiles as a list and the RIHS01 type hash) and one ``<folder>_0.mcap`` (MCAP
profile ``ros2``, one ``ros2msg`` schema per type holding the full message definition,
``cdr`` channels whose metadata carries ``offered_qos_profiles`` and ``topic_type_hash``,
zstd-compressed chunks with CRCs, a ``rosbag2`` metadata record with ``ros_distro: jazzy``).
The files are written by :mod:`pushbot.ros2cli.bag_mcap` with the official ``mcap`` library
(:mod:`pushbot.ros2cli.bag_record` records) and read with the ``rosbags`` library
(:mod:`pushbot.ros2cli.bag_store`); messages are never decoded on the way: the recorder subscribes
with ``raw=True`` and stores the CDR bytes rclpy receives, the player publishes the stored bytes.
So these bags are what ``ros2 bag info/play/reindex`` of a full install expect (the channel
metadata carries what ``reindex`` rebuilds metadata.yaml from), Foxglove and any MCAP reader
read them and can verify their CRCs, and these commands read bags of ``ros2 bag record -s
mcap``.

- ``record [-o DIR] [--duration S] [TOPICS... | --all] [--exclude REGEX]``: subscribes to each
  topic as soon as it has a publisher (topics may appear later), with a QoS compatible with
  all its publishers (best effort if any publisher is, transient local if all are, so a
  latched topic's last sample is recorded too) and stores the publishers' offered QoS
  profiles. As rosbag2 does, a message's log time is its receive time and its publish time
  the sender's source timestamp (both wall clock, nanoseconds). Ctrl-C, SIGTERM or
  ``--duration`` end it cleanly: the MCAP summary and metadata.yaml are written and the
  message count of every topic is printed.
- ``info DIR``: files, size, duration, start and end, message counts and types per topic.
- ``play DIR [--rate R] [--topics ...] [--include-commands] [--clock [HZ]]``: publishes the
  messages with their recorded spacing divided by ``--rate``, with the recorded QoS (transient
  local where every recorded publisher was), optionally ``/clock`` with the bag time. Command
  topics (:func:`is_command_topic`: goals, pushes, knocks, joint trajectories, cancels,
  velocity commands) are left out unless ``--include-commands`` is given or they are named in
  ``--topics``, and the player says which it left out: played into a running graph they would
  move the object, or the robot, again.

Exit codes: 0 success, 1 a runtime failure (no rclpy, nothing recorded), 2 bad input.
"""

from __future__ import annotations

import argparse
import datetime
import math
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pushbot.ros2cli.bag_record import DEFAULT_EXCLUDED, BagRecorder, TopicSelection
from pushbot.ros2cli.bag_store import BagError, open_reader, read_messages, rosbags_package
from pushbot.ros2cli.discovery import (
    RosUnavailableError,
    cli_node,
    import_message_class,
    spin_until,
)

#: Where ``record`` without ``-o`` creates its bag folder (git-ignored), as
#: ``rosbag2_YYYY_MM_DD-HH_MM_SS`` under it.
DEFAULT_BAG_DIR = Path("out")
#: Default rate of ``/clock`` during ``play --clock`` (rosbag2's default), Hz.
CLOCK_HZ = 40.0
#: Command topics of the graph (matched as the last segments of a topic name, so namespaced
#: copies count too): a goal, a push for the pusher, a knock of the simulated object.
COMMAND_TOPICS = ("goal_pose", "planner/push", "sim/knock")
#: Last segments of topic names that command something in any ROS graph.
COMMAND_SUFFIXES = ("cancel", "cmd_vel")
#: Message types that command motion wherever they are published.
COMMAND_TYPES = ("trajectory_msgs/msg/JointTrajectory",
                 "trajectory_msgs/msg/MultiDOFJointTrajectory")


def is_command_topic(name: str, msgtype: str) -> bool:
    """Whether topic ``name`` of type ``msgtype`` commands the graph (``bag play`` leaves it
    out unless asked): a name ending in one of :data:`COMMAND_TOPICS` or
    :data:`COMMAND_SUFFIXES`, or a type of :data:`COMMAND_TYPES`."""
    path = name.strip("/")
    ends = (*COMMAND_TOPICS, *COMMAND_SUFFIXES)
    return msgtype in COMMAND_TYPES or any(path == e or path.endswith("/" + e) for e in ends)


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Sub-subcommands of ``pushbot bag``."""
    sub = parser.add_subparsers(dest="bag_command", metavar="{record,info,play}")
    sub.required = True

    p = sub.add_parser("record", help="record topics into a rosbag2 folder (MCAP)",
                       description="Record topics of the live graph into a new rosbag2 folder "
                       "(metadata.yaml + MCAP) until Ctrl-C or --duration.")
    p.add_argument("topics", nargs="*", metavar="TOPIC",
                   help="topics to record (relative names are made absolute)")
    p.add_argument("-a", "--all", action="store_true",
                   help=f'record every topic (except {", ".join(DEFAULT_EXCLUDED)})')
    p.add_argument("-o", "--output", type=Path, default=None,
                   help=f"bag folder to create (default: {DEFAULT_BAG_DIR}/"
                   "rosbag2_YYYY_MM_DD-HH_MM_SS)")
    p.add_argument("--duration", type=float, default=None,
                   help="stop after this many seconds (default: until Ctrl-C)")
    p.add_argument("-e", "--exclude", default=None, metavar="REGEX",
                   help="leave out the topics this regular expression matches (re.search)")
    p.set_defaults(bag_handler=cmd_record)

    p = sub.add_parser("info", help="duration, start, end, message counts and types of a bag",
                       description="Print what `ros2 bag info` prints for a rosbag2 folder.")
    p.add_argument("bag", type=Path, metavar="DIR")
    p.set_defaults(bag_handler=cmd_info)

    p = sub.add_parser("play", help="publish the messages of a bag with their recorded timing",
                       description="Publish the messages of a rosbag2 folder with their "
                       "recorded spacing (divided by --rate) and QoS.")
    p.add_argument("bag", type=Path, metavar="DIR")
    p.add_argument("-r", "--rate", type=float, default=1.0,
                   help="playback speed factor (default: %(default)s)")
    p.add_argument("--topics", nargs="+", default=None, metavar="TOPIC",
                   help="play only these topics, command topics included (default: all but "
                   "the command topics)")
    p.add_argument("--include-commands", action="store_true",
                   help="also play the command topics (" + ", ".join(COMMAND_TOPICS)
                   + ", */cancel, */cmd_vel, joint trajectories): they move the object or the "
                   "robot again in a running graph")
    p.add_argument("--clock", type=float, nargs="?", const=CLOCK_HZ, default=None,
                   metavar="HZ", help=f"also publish /clock with the bag time at HZ "
                   f"(default {CLOCK_HZ:g} Hz when given without a value)")
    p.add_argument("--wait-for-subscribers", type=float, default=0.0, metavar="S",
                   help="before playing, wait up to S seconds until every played topic has a "
                   "matched subscriber (default: 0, do not wait)")
    p.set_defaults(bag_handler=cmd_play)


def run_bag(args: argparse.Namespace) -> int:
    """Handler of ``pushbot bag``."""
    try:
        return args.bag_handler(args)
    except BagError as exc:
        print(f"pushbot bag: {exc}", file=sys.stderr)
        return 2
    except RosUnavailableError as exc:
        print(f"pushbot bag: {exc}", file=sys.stderr)
        return 1


def _absolute(name: str) -> str:
    return name if name.startswith("/") else "/" + name


def cmd_record(args: argparse.Namespace) -> int:
    """``pushbot bag record``."""
    from pushbot.ros2cli.discovery import sigterm_as_keyboard_interrupt

    if bool(args.topics) == bool(args.all):
        raise BagError("name the topics to record or give --all (not both)")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise BagError(f"--duration must be a positive number of seconds, got {args.duration}")
    try:
        exclude = re.compile(args.exclude) if args.exclude else None
    except re.error as exc:
        raise BagError(f"--exclude {args.exclude!r} is not a regular expression: {exc}") from exc
    out = args.output or DEFAULT_BAG_DIR / datetime.datetime.now().strftime(
        "rosbag2_%Y_%m_%d-%H_%M_%S")
    selection = TopicSelection(tuple(_absolute(t) for t in args.topics), args.all, exclude)
    recorder = BagRecorder(out, selection)
    deadline = math.inf if args.duration is None else time.monotonic() + args.duration
    print(f"recording to {out} (Ctrl-C to stop)", flush=True)
    try:
        with sigterm_as_keyboard_interrupt():
            recorder.start()
            try:
                while time.monotonic() < deadline and recorder.running:
                    time.sleep(min(0.1, max(0.0, deadline - time.monotonic())))
            except KeyboardInterrupt:
                pass
    finally:
        recorder.stop()
    counts = recorder.counts()
    total = sum(counts.values())
    print(f"wrote {out}: {total} messages on {len(counts)} topics")
    for name, count in counts.items():
        print(f"  {name} [{recorder.topics[name].msgtype}]: {count}")
    for label, n in sorted(recorder.errors.items()):
        print(f"  {label} failed {n} times (see the errors above): those messages are not in "
              "the bag", file=sys.stderr)
    for name in selection.topics:
        if name not in counts:
            print(f'  {name}: not recorded ({recorder.skipped.get(name, "no publisher seen")})',
                  file=sys.stderr)
    return 0 if total and not recorder.errors else 1


def _human_size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024
    return f"{n:.1f} GiB"


def _time_text(ns: int) -> str:
    when = datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.UTC)
    return f'{when.strftime("%b %d %Y %H:%M:%S.%f")[:-3]} UTC ({ns / 1e9:.9f})'


def bag_summary(path: Path) -> str:
    """The ``bag info`` text of the bag folder ``path``."""
    with open_reader(path) as reader:
        files = sorted(p.name for p in path.iterdir() if p.suffix == ".mcap")
        size = sum(p.stat().st_size for p in path.iterdir() if p.is_file())
        count = reader.message_count
        lines = [
            f'Files:             {", ".join(files)}',
            f"Bag size:          {_human_size(size)}",
            "Storage id:        mcap" if files else "Storage id:        sqlite3",
            f'ROS Distro:        {reader.ros_distro or "unknown"}',
            f"Duration:          {reader.duration / 1e9:.9f}s",
            f'Start:             {_time_text(reader.start_time) if count else "-"}',
            f'End:               {_time_text(reader.end_time) if count else "-"}',
            f"Messages:          {count}",
        ]
        conns = sorted(reader.connections, key=lambda c: c.topic)
        width = max((len(c.topic) for c in conns), default=0)
        for i, c in enumerate(conns):
            head = "Topic information: " if i == 0 else " " * 19
            fmt = getattr(c.ext, "serialization_format", "cdr")
            lines.append(f"{head}Topic: {c.topic:<{width}} | Type: {c.msgtype} | "
                         f"Count: {c.msgcount} | Serialization Format: {fmt}")
        if not conns:
            lines.append("Topic information: none")
    return "\n".join(lines)


def cmd_info(args: argparse.Namespace) -> int:
    """``pushbot bag info DIR``."""
    print(bag_summary(args.bag))
    return 0


def _play_qos(offered: Sequence[Any]) -> Any:
    """Publisher QoS from the recorded offered profiles: reliable unless every recorded
    publisher was best effort, transient local if all were, depth = the largest depth."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    i = rosbags_package().interfaces
    best_effort = bool(offered) and all(q.reliability == i.QosReliability.BEST_EFFORT
                                        for q in offered)
    latched = bool(offered) and all(q.durability == i.QosDurability.TRANSIENT_LOCAL
                                    for q in offered)
    depth = max([int(q.depth) for q in offered if q.depth > 0] or [10])
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def cmd_play(args: argparse.Namespace) -> int:
    """``pushbot bag play DIR``."""
    from pushbot.ros2cli.discovery import sigterm_as_keyboard_interrupt

    if not (math.isfinite(args.rate) and args.rate > 0):
        raise BagError(f"--rate must be a positive number, got {args.rate}")
    if args.clock is not None and not (math.isfinite(args.clock) and args.clock > 0):
        raise BagError(f"--clock must be a positive rate in Hz, got {args.clock}")
    with open_reader(args.bag) as reader:
        wanted = None if args.topics is None else {_absolute(t) for t in args.topics}
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        if wanted is not None and (missing := wanted - {c.topic for c in conns}):
            raise BagError(f'topics not in the bag: {", ".join(sorted(missing))}')
        if wanted is None and not args.include_commands:
            commands = sorted({c.topic for c in conns if is_command_topic(c.topic, c.msgtype)})
            conns = [c for c in conns if c.topic not in commands]
            if commands:
                print(f'bag play: leaving out the command topics {", ".join(commands)} (they '
                      'would move the object or the robot again); --include-commands or '
                      '--topics plays them', file=sys.stderr, flush=True)
        classes = {}
        for c in conns:
            try:
                classes[c.topic] = import_message_class(c.msgtype)
            except LookupError as exc:
                raise BagError(str(exc)) from exc
        counts = dict.fromkeys(classes, 0)
        with sigterm_as_keyboard_interrupt(), cli_node("bag_play") as (node, executor):
            publishers = {c.topic: node.create_publisher(
                classes[c.topic], c.topic, _play_qos(c.ext.offered_qos_profiles)) for c in conns}
            clock_pub = None
            if args.clock is not None:
                from rosgraph_msgs.msg import Clock

                from push_ros.qos import CLOCK_QOS

                clock_pub = node.create_publisher(Clock, "/clock", CLOCK_QOS)
            if args.wait_for_subscribers > 0:
                spin_until(executor, lambda: all(p.get_subscription_count() > 0
                                                 for p in publishers.values()),
                           time.monotonic() + args.wait_for_subscribers)
            print(f"playing {args.bag} ({sum(c.msgcount for c in conns)} messages, "
                  f"{reader.duration / 1e9:.1f} s at rate {args.rate:g}; Ctrl-C to stop)",
                  flush=True)
            t0_bag, t0_wall = reader.start_time, time.monotonic()
            next_clock = 0.0
            try:
                for conn, stamp, data in read_messages(reader, conns):
                    due = t0_wall + (stamp - t0_bag) / 1e9 / args.rate
                    while (now := time.monotonic()) < due:
                        if clock_pub is not None and now >= next_clock:
                            _publish_clock(clock_pub, t0_bag + (now - t0_wall) * args.rate * 1e9)
                            next_clock = now + 1.0 / args.clock
                        executor.spin_once(timeout_sec=min(0.01, due - now))
                    if clock_pub is not None:
                        _publish_clock(clock_pub, stamp)
                    publishers[conn.topic].publish(bytes(data))
                    counts[conn.topic] += 1
                # Give reliable readers a moment to take the last samples before the
                # publishers go away (nothing to wait for on a latched topic).
                spin_until(executor, lambda: False, time.monotonic() + 0.5)
            except KeyboardInterrupt:
                print("interrupted", file=sys.stderr)
    print(f"published {sum(counts.values())} messages: "
          + ", ".join(f"{t} {n}" for t, n in sorted(counts.items())))
    return 0


def _publish_clock(publisher: Any, ns: float) -> None:
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock

    sec, nsec = divmod(int(ns), 1_000_000_000)
    publisher.publish(Clock(clock=Time(sec=sec, nanosec=nsec)))
