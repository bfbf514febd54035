"""``pushbot topic``: the project's replacement for ``ros2 topic`` (list, echo, hz, info, pub).

Built on rclpy graph introspection only (``get_topic_names_and_types``,
``get_publishers_info_by_topic``, ``get_subscriptions_info_by_topic``), since the PyPI install
has no ``ros2`` CLI and no ``rosidl_runtime_py``. There is no daemon: each command starts a
hidden node and waits until what it prints has stopped changing for 2 s, after at least
3 s (``pushbot.ros2cli.discovery.wait_for_stable_graph``, the rule of every graph command), bounded
by its timeout. ``pub`` takes YAML as ``ros2 topic pub`` does (``pushbot.ros2cli.messages``, the
CLI's one message codec) and waits for matching subscriptions before the first message.

Exit codes: 0 success, 1 when the topic did not appear (or, with ``echo --count``, the messages
did not arrive) within ``--timeout``, 2 for usage errors (unknown type, fields or values that do
not fit the message).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from pushbot.ros2cli.discovery import (
    EXIT_USAGE,
    add_spin_time,
    cli_node,
    compatible_qos,
    import_message_class,
    run_graph_command,
    spin_until,
    topic_types,
    wait_for_graph,
    wait_for_stable_graph,
)
from pushbot.ros2cli.messages import (
    DEFAULT_MAX_ARRAY,
    MessageFieldError,
    message_from_yaml,
    message_to_dict,
    to_yaml,
    zero_time,
)

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node
    from rclpy.topic_endpoint_info import TopicEndpointInfo

DEFAULT_TIMEOUT = 10.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Sub-subcommands of ``pushbot topic``."""
    sub = parser.add_subparsers(dest="topic_command", metavar="{list,echo,hz,info,pub}")
    sub.required = True

    p = sub.add_parser("list", help="list the topics in the graph",
                       description="List the topics of the graph once discovery has settled "
                                   "(at least 3 s, then nothing new for 2 s; at most "
                                   "--spin-time).")
    p.add_argument("-t", "--show-types", action="store_true", help="also print the types")
    add_spin_time(p)
    p.set_defaults(topic_handler=cmd_list)

    p = sub.add_parser(
        "echo", help="print the messages of a topic",
        description="Print the messages of a topic as YAML, separated by ---. The type comes "
                    "from the graph; the subscription QoS matches the publishers (best effort "
                    "if any publisher is, transient local if all are).")
    p.add_argument("topic")
    count = p.add_mutually_exclusive_group()
    count.add_argument("-n", "--count", type=int, default=None,
                       help="exit after N messages (default: run until Ctrl-C)")
    count.add_argument("--once", dest="count", action="store_const", const=1,
                       help="exit after the first message (as `ros2 topic echo --once`)")
    p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT,
                   help="seconds to wait for a publisher of the topic and, with --count, for "
                        "the N messages (default: %(default)s)")
    p.add_argument("--max-array", type=int, default=DEFAULT_MAX_ARRAY,
                   help="summarise arrays longer than this; 0 prints everything "
                        "(default: %(default)s)")
    p.set_defaults(topic_handler=cmd_echo)

    p = sub.add_parser(
        "hz", help="measure the publishing rate of a topic",
        description="Print the receive rate of a topic once per second (wall clock), over the "
                    "last --window messages.")
    p.add_argument("topic")
    p.add_argument("-w", "--window", type=int, default=10000,
                   help="number of recent messages the statistics use (default: %(default)s)")
    p.add_argument("--duration", type=float, default=None,
                   help="stop after measuring this many seconds (default: run until Ctrl-C)")
    p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT,
                   help="seconds to wait for a publisher of the topic (default: %(default)s)")
    p.set_defaults(topic_handler=cmd_hz)

    p = sub.add_parser("info", help="type, publishers and subscribers of a topic with their QoS",
                       description="Print the type of a topic and every endpoint with its QoS, "
                                   "once its endpoints have not changed for 2 s (after at "
                                   "least 3 s).")
    p.add_argument("topic")
    p.add_argument("--timeout", type=float, default=10.0,
                   help="seconds to wait for the topic to appear and its endpoints to settle "
                        "(default: %(default)s)")
    p.set_defaults(topic_handler=cmd_info)

    p = sub.add_parser(
        "pub", help="publish a message given as YAML",
        description='Publish a message to a topic, like ros2 topic pub: the type as '
                    'pkg/msg/Type or pkg/Type, the values as a YAML mapping (fields left out '
                    'keep their defaults; a time field may be now, a header auto), e.g. '
                    'pushbot topic pub goal_pose geometry_msgs/msg/PoseStamped "{header: '
                    '{frame_id: world, stamp: now}, pose: {position: {x: 0.05}}}" --once. '
                    'Waits (at most --max-wait-time-secs) for --wait-matching-subscriptions '
                    'subscriptions before the first message. The publisher is reliable and '
                    'transient local, which matches every subscription (reliable or best '
                    'effort, volatile or transient local).')
    p.add_argument("topic")
    p.add_argument("type", help="message type, e.g. geometry_msgs/msg/PoseStamped")
    p.add_argument("values", nargs="?", default="",
                   help="YAML mapping of the fields (default: the default message)")
    times = p.add_mutually_exclusive_group()
    times.add_argument("-1", "--once", action="store_true",
                       help="publish one message and exit")
    times.add_argument("-t", "--times", type=int, default=None,
                       help="publish this many messages and exit (default: until Ctrl-C)")
    p.add_argument("-r", "--rate", type=float, default=1.0,
                   help="messages per second (default: %(default)s)")
    p.add_argument("-w", "--wait-matching-subscriptions", type=int, default=1,
                   help="matching subscriptions to wait for before the first message "
                        "(default: %(default)s)")
    p.add_argument("--max-wait-time-secs", type=float, default=DEFAULT_TIMEOUT,
                   help="longest wait for them; then it publishes anyway, with a warning "
                        "(default: %(default)s)")
    p.add_argument("--keep-alive", type=float, default=2.0,
                   help="seconds to wait after the last message until every subscription "
                        "acknowledged it (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="do not print each message")
    p.set_defaults(topic_handler=cmd_pub)


def run_topic(args: argparse.Namespace) -> int:
    """Handler of ``pushbot topic``: dispatch to the sub-subcommand."""
    return run_graph_command(args, args.topic_handler, "topic")


@contextmanager
def _until_interrupted() -> Iterator[None]:
    """Treat Ctrl-C (and the context shutdown rclpy's signal handler causes) as a normal end."""
    from rclpy.executors import ExternalShutdownException

    try:
        yield
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


def cmd_list(args: argparse.Namespace) -> int:
    """``pushbot topic list [-t]``."""
    with cli_node("topic_list") as (node, executor):
        _, topics, _ = wait_for_graph(node, executor, args.spin_time)
    for name, types in topics:
        print(f'{name} [{", ".join(types)}]' if args.show_types else name)
    return 0


def wait_for_publishers(
    node: Node, executor: Executor, topic: str, timeout: float
) -> tuple[str, list[TopicEndpointInfo]] | str:
    """Wait until ``topic`` has a publisher; returns ``(type, publisher infos)`` or an error."""
    deadline = time.monotonic() + timeout
    spin_until(executor, lambda: bool(node.get_publishers_info_by_topic(topic)), deadline)
    publishers = node.get_publishers_info_by_topic(topic)
    types = topic_types(node, topic)
    if not publishers:
        if types:
            return (f'topic {topic} [{", ".join(types)}] has no publisher '
                    f'(waited {timeout:g} s)')
        return (f"topic {topic} did not appear within {timeout:g} s: is the publisher running "
                "with the same ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE?")
    pub_types = sorted({p.topic_type for p in publishers})
    if len(pub_types) > 1:
        return f'topic {topic} is published with several types ({", ".join(pub_types)})'
    return pub_types[0], publishers


def subscribe_matching(
    node: Node,
    executor: Executor,
    args: argparse.Namespace,
    callback: Callable[[Any], None],
    raw: bool = False,
) -> str | None:
    """Wait for a publisher of ``args.topic``, subscribe with a QoS compatible with it.

    The type comes from the graph. Returns the resolved topic name, or ``None`` after printing
    why on stderr (no publisher within ``args.timeout``).
    """
    topic = node.resolve_topic_name(args.topic)
    found = wait_for_publishers(node, executor, topic, args.timeout)
    if isinstance(found, str):
        print(f"pushbot topic {args.topic_command}: {found}", file=sys.stderr)
        return None
    type_string, publishers = found
    node.create_subscription(import_message_class(type_string), topic, callback,
                             compatible_qos(publishers), raw=raw)
    return topic


def cmd_echo(args: argparse.Namespace) -> int:
    """``pushbot topic echo <topic> [--count N] [--timeout S]``."""
    if args.count is not None and args.count < 1:
        print("pushbot topic echo: --count must be >= 1", file=sys.stderr)
        return 2
    start = time.monotonic()
    received = 0

    def on_message(msg: object) -> None:
        nonlocal received
        if args.count is not None and received >= args.count:
            return
        received += 1
        print(to_yaml(message_to_dict(msg, args.max_array)), "---", sep="\n", flush=True)

    with cli_node("topic_echo") as (node, executor), _until_interrupted():
        topic = subscribe_matching(node, executor, args, on_message)
        if topic is None:
            return 1
        if args.count is None:
            spin_until(executor, lambda: False, math.inf)
        elif not spin_until(executor, lambda: received >= args.count, start + args.timeout):
            print(f"pushbot topic echo: received {received} of {args.count} messages on "
                  f"{topic} within {args.timeout:g} s", file=sys.stderr)
            return 1
    return 0


class RateMeter:
    """Receive-rate statistics over a sliding window of arrival times (seconds)."""

    def __init__(self, window: int) -> None:
        self.stamps: deque[float] = deque(maxlen=max(window, 1) + 1)
        self.total = 0

    def tick(self, stamp: float) -> None:
        """Record one arrival at ``stamp`` (monotonic seconds)."""
        self.stamps.append(stamp)
        self.total += 1

    def rate(self) -> float | None:
        """Mean rate in Hz over the window, ``None`` before two messages arrived."""
        if len(self.stamps) < 2:
            return None
        span = self.stamps[-1] - self.stamps[0]
        return (len(self.stamps) - 1) / span if span > 0 else math.inf

    def summary(self) -> str | None:
        """``ros2 topic hz``-style text, or ``None`` before two messages arrived."""
        rate = self.rate()
        if rate is None:
            return None
        stamps = list(self.stamps)
        gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
        return (f"average rate: {rate:.3f}\n"
                f"\tmin: {min(gaps):.3f}s max: {max(gaps):.3f}s "
                f"std dev: {statistics.pstdev(gaps):.5f}s window: {len(gaps)}")


def cmd_hz(args: argparse.Namespace) -> int:
    """``pushbot topic hz <topic> [--window N] [--duration S]``."""
    meter = RateMeter(args.window)
    topic = args.topic
    with cli_node("topic_hz") as (node, executor), _until_interrupted():
        # raw=True: no deserialisation, so hz stays cheap on image topics.
        topic = subscribe_matching(
            node, executor, args, lambda _: meter.tick(time.monotonic()), raw=True)
        if topic is None:
            return 1
        end = time.monotonic() + args.duration if args.duration is not None else math.inf
        seen = 0
        while time.monotonic() < end:
            spin_until(executor, lambda: False, min(time.monotonic() + 1.0, end))
            text = meter.summary() if meter.total > seen else None
            seen = meter.total
            print(text or f"no new messages on {topic}", flush=True)
    if meter.total == 0:
        print(f"pushbot topic hz: no message received on {topic}", file=sys.stderr)
        return 1
    return 0


def _qos_text(info: TopicEndpointInfo) -> str:
    """Reliability and durability: DDS discovery does not carry history and depth."""
    qos = info.qos_profile
    return (f"reliability={qos.reliability.name}, durability={qos.durability.name}, "
            f"liveliness={qos.liveliness.name}")


def cmd_info(args: argparse.Namespace) -> int:
    """``pushbot topic info <topic>``: type, counts and every endpoint's QoS."""
    with cli_node("topic_info") as (node, executor):
        topic = node.resolve_topic_name(args.topic)
        deadline = time.monotonic() + args.timeout
        if not spin_until(executor, lambda: bool(topic_types(node, topic)), deadline):
            print(f"pushbot topic info: topic {topic} did not appear within "
                  f"{args.timeout:g} s", file=sys.stderr)
            return 1
        # Endpoints arrive one by one after the first sighting (the measured "0 publishers"
        # of a running ekf_node): wait until they stop changing.
        wait_for_stable_graph(executor, lambda: _endpoints(node, topic), deadline)
        types = topic_types(node, topic)
        publishers = node.get_publishers_info_by_topic(topic)
        subscriptions = node.get_subscriptions_info_by_topic(topic)
    print(f"Topic: {topic}")
    print(f'Type: {", ".join(types)}')
    for label, endpoints in (("Publisher", publishers), ("Subscription", subscriptions)):
        print(f"{label} count: {len(endpoints)}")
        for info in endpoints:
            name = f'{info.node_namespace.rstrip("/")}/{info.node_name}'
            print(f"  - node: {name}")
            print(f"    type: {info.topic_type}")
            print(f"    qos: {_qos_text(info)}")
    return 0


def _endpoints(node: Node, topic: str) -> tuple[list[tuple[str, str, str]], ...]:
    """The publishers and subscriptions of ``topic`` as comparable (node, namespace, type)."""
    def view(infos: list[TopicEndpointInfo]) -> list[tuple[str, str, str]]:
        return sorted((i.node_name, i.node_namespace, i.topic_type) for i in infos)

    return (view(node.get_publishers_info_by_topic(topic)),
            view(node.get_subscriptions_info_by_topic(topic)))


def publisher_qos(depth: int = 10) -> Any:
    """Reliable + transient local: matches every subscription (a reliable writer serves
    best-effort readers too, a transient-local writer volatile readers too), like
    ``ros2 topic pub``'s default of matching the existing subscriptions."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def wait_for_subscriptions(node: Node, executor: Executor, publisher: Any, count: int,
                           timeout: float, what: str) -> bool:
    """Spin until ``publisher`` matches ``count`` subscriptions (at most ``timeout`` s); warn
    on stderr when it does not (the caller publishes anyway, as ``ros2 topic pub`` does)."""
    if count <= 0:
        return True
    matched = spin_until(executor, lambda: publisher.get_subscription_count() >= count,
                         time.monotonic() + max(timeout, 0.0))
    if not matched:
        print(f"{what}: {publisher.get_subscription_count()} of {count} matching "
              f"subscription(s) on {publisher.topic_name} after {timeout:g} s; publishing "
              "anyway", file=sys.stderr)
    return matched


def cmd_pub(args: argparse.Namespace) -> int:
    """``pushbot topic pub <topic> <type> [values] [--once | --times N] [--rate HZ]``."""
    from rclpy.duration import Duration

    if args.times is not None and args.times < 1:
        print("pushbot topic pub: --times must be >= 1", file=sys.stderr)
        return EXIT_USAGE
    if not (args.rate > 0 and math.isfinite(args.rate)):
        print("pushbot topic pub: --rate must be a positive number of messages per second",
              file=sys.stderr)
        return EXIT_USAGE
    try:
        message_class = import_message_class(args.type)
        # Checked once before any ROS work; built again per message below, so that ``now``
        # and ``auto`` stamps are the time of each message.
        message_from_yaml(message_class, args.values, now=zero_time)
    except (LookupError, MessageFieldError) as exc:
        print(f"pushbot topic pub: {exc}", file=sys.stderr)
        return EXIT_USAGE
    total = 1 if args.once else args.times
    with cli_node("topic_pub") as (node, executor), _until_interrupted():
        try:
            publisher = node.create_publisher(message_class, args.topic, publisher_qos())
        except Exception as exc:  # rclpy's InvalidTopicNameException and kin
            print(f"pushbot topic pub: {str(exc).splitlines()[0]}", file=sys.stderr)
            return EXIT_USAGE
        wait_for_subscriptions(node, executor, publisher, args.wait_matching_subscriptions,
                               args.max_wait_time_secs, "pushbot topic pub")
        if not args.quiet:
            print("publisher: beginning loop", flush=True)
        sent = 0
        next_time = time.monotonic()
        while total is None or sent < total:
            spin_until(executor, lambda: False, next_time)
            msg = message_from_yaml(message_class, args.values,
                                    now=lambda: node.get_clock().now().to_msg())
            publisher.publish(msg)
            sent += 1
            if not args.quiet:
                print(f"publishing #{sent}: {msg!r}", flush=True)
            next_time += 1.0 / args.rate
        publisher.wait_for_all_acked(Duration(seconds=max(args.keep_alive, 0.0)))
    return 0
