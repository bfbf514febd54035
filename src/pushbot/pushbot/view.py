"""``pushbot view [--host H] [--port P] [--topics ...]``: the live graph in Foxglove.

Serves the graph's topics over the Foxglove WebSocket protocol with ``foxglove-sdk``
(WebSocket subprotocol ``foxglove.sdk.v1``): in
Foxglove, *Open connection* -> *Foxglove WebSocket* -> ``ws://127.0.0.1:8765``.

Each ROS topic becomes one channel with the topic's absolute name, message encoding ``cdr``
and a ``ros2msg`` schema holding the full message definition (the type's fields followed by
its nested types, as rosbag2 writes in MCAP), so Foxglove decodes the messages itself and its
Image, 3D (PointCloud2, MarkerArray, PoseWithCovarianceStamped, Path), Plot and Raw Messages
panels show them as they would from a ROS bridge. Messages are never decoded here: a hidden
node subscribes with ``raw=True`` (QoS compatible with the topic's publishers: best effort if
any is, transient local if all are, so latched topics arrive too) and forwards the CDR bytes
of a channel only while a client is subscribed to it. The last sample of a latched topic
(every publisher transient local: ``perception/outline``, ``estimator/*``, ``planner/status``,
``camera/color/extrinsics``) is kept and sent when a client subscribes, as a late ROS
subscriber would get it. Topics that appear later are picked up (the graph is looked at every
second).

The server binds to 127.0.0.1 by default; ``--host`` with another address prints a warning
(the protocol has no authentication: whoever reaches the port sees every topic).

Exit codes: 0 after Ctrl-C, 1 no rclpy / the port cannot be bound, 2 bad input.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from pushbot.bag import BagError, TopicSelection, message_definition
from pushbot.graph import RosUnavailableError, cli_node, compatible_qos, import_message_class

if TYPE_CHECKING:
    from rclpy.topic_endpoint_info import TopicEndpointInfo

DEFAULT_PORT = 8765
LOOPBACK = ('127.0.0.1', 'localhost', '::1')
#: Seconds between two looks at the graph for new topics.
DISCOVERY_PERIOD = 1.0
#: Seconds after which named topics that have not appeared are reported (once).
MISSING_NOTE_AFTER = 10.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot view``."""
    parser.add_argument('--host', default='127.0.0.1',
                        help='address to bind (default: %(default)s; any other address is '
                        'reachable by others: no authentication)')
    parser.add_argument('--port', type=int, default=DEFAULT_PORT,
                        help='TCP port (default: %(default)s; 0 picks a free one)')
    parser.add_argument('--topics', nargs='+', default=None, metavar='TOPIC',
                        help='serve only these topics (default: every topic but /rosout and '
                        '/parameter_events)')
    parser.add_argument('-e', '--exclude', default=None, metavar='REGEX',
                        help='leave out the topics this regular expression matches')


def _foxglove() -> Any:
    try:
        import foxglove
        import foxglove.websocket
    except ImportError as exc:
        raise BagError(f'foxglove-sdk is not installed ({exc}): run make venv') from exc
    return foxglove


class LiveView:
    """Forwards topics of the ROS graph to a Foxglove WebSocket server (module docstring).

    Parameters
    ----------
    node : rclpy.node.Node
        The hidden node that subscribes.
    selection : TopicSelection
    context : foxglove.Context
        The foxglove context of the server the channels log to.
    """

    def __init__(self, node: Any, selection: TopicSelection, context: Any) -> None:
        self.node = node
        self.selection = selection
        self.context = context
        self.channels: dict[str, Any] = {}
        self.subscriptions: dict[str, Any] = {}
        self.skipped: dict[str, str] = {}
        self.forwarded: dict[str, int] = {}
        self.latched: dict[str, bytes] = {}
        self.errors: dict[str, int] = {}
        self._started = time.monotonic()
        self._noted_missing = False
        from push_ros.node import ThrottledLog

        self._log = ThrottledLog(node.get_logger(), 5.0)

    def guard(self, callback: Any, name: str) -> Any:
        """``callback`` that never raises (push_ros.node.guarded); failures are counted."""
        from push_ros.node import guarded

        def count(label: str, _message: str) -> None:
            self.errors[label] = self.errors.get(label, 0) + 1

        return guarded(callback, self._log, on_error=count, name=name)

    def on_subscribe(self, client: Any, channel: Any) -> None:
        """foxglove ServerListener: send a latched topic's last sample to a new subscriber."""
        data = self.latched.get(channel.topic)
        if data is not None:
            self.channels[channel.topic].log(data, log_time=time.time_ns())

    def discover(self) -> None:
        """Add a channel and a subscription for every new wanted topic with a publisher."""
        for name, types in self.node.get_topic_names_and_types():
            if name in self.channels or name in self.skipped or not self.selection.wants(name):
                continue
            publishers = self.node.get_publishers_info_by_topic(name)
            if publishers:
                self._add(name, types, publishers)
        missing = [t for t in self.selection.topics if t not in self.channels]
        if (missing and not self._noted_missing
                and time.monotonic() - self._started > MISSING_NOTE_AFTER):
            self._noted_missing = True
            print(f'pushbot view: no publisher yet for {", ".join(missing)} (still '
                  'waiting; same ROS_DOMAIN_ID?)', file=sys.stderr, flush=True)

    def _add(self, name: str, types: Sequence[str],
             publishers: Sequence[TopicEndpointInfo]) -> None:
        from rclpy.qos import DurabilityPolicy

        foxglove = _foxglove()
        if len(types) != 1:
            self.skipped[name] = f'published with several types {sorted(types)}'
        else:
            try:
                cls = import_message_class(types[0])
                msgdef, _ = message_definition(types[0])
            except (LookupError, BagError) as exc:
                self.skipped[name] = str(exc)
        if name in self.skipped:
            print(f'pushbot view: not serving {name}: {self.skipped[name]}', file=sys.stderr)
            return
        schema = foxglove.Schema(name=types[0], encoding='ros2msg', data=msgdef.encode())
        channel = foxglove.Channel(name, schema=schema, message_encoding='cdr',
                                   context=self.context)
        self.channels[name] = channel
        self.forwarded[name] = 0

        qos = compatible_qos(publishers, depth=10)
        latched = qos.durability == DurabilityPolicy.TRANSIENT_LOCAL

        def forward(data: bytes, channel: Any = channel, name: str = name) -> None:
            if latched:
                self.latched[name] = bytes(data)
            if channel.has_sinks():
                channel.log(bytes(data), log_time=time.time_ns())
                self.forwarded[name] += 1

        self.subscriptions[name] = self.node.create_subscription(
            cls, name, self.guard(forward, f'forward {name}'), qos, raw=True)
        print(f'serving {name} [{types[0]}]', flush=True)


def run_view(args: argparse.Namespace) -> int:
    """Handler of ``pushbot view``."""
    if not 0 <= args.port <= 65535:
        print(f'pushbot view: --port must be in [0, 65535], got {args.port}', file=sys.stderr)
        return 2
    try:
        exclude = re.compile(args.exclude) if args.exclude else None
    except re.error as exc:
        print(f'pushbot view: --exclude {args.exclude!r} is not a regular expression: {exc}',
              file=sys.stderr)
        return 2
    topics = tuple(t if t.startswith('/') else '/' + t for t in args.topics or ())
    selection = TopicSelection(topics, all_topics=not topics, exclude=exclude)
    if args.host not in LOOPBACK:
        print(f'pushbot view: WARNING: serving on {args.host}: anyone who can reach port '
              f'{args.port} there sees every topic (the protocol has no authentication)',
              file=sys.stderr)
    try:
        return _serve(args.host, args.port, selection)
    except BagError as exc:
        print(f'pushbot view: {exc}', file=sys.stderr)
        return 1
    except RosUnavailableError as exc:
        print(f'pushbot view: {exc}', file=sys.stderr)
        return 1


def _serve(host: str, port: int, selection: TopicSelection) -> int:
    from rclpy.executors import ExternalShutdownException

    from pushbot.graph_nodes import sigterm_as_keyboard_interrupt

    foxglove = _foxglove()
    context = foxglove.Context()
    with sigterm_as_keyboard_interrupt(), cli_node('view') as (node, executor):
        view = LiveView(node, selection, context)
        resend = view.guard(view.on_subscribe, 'on_subscribe')

        class Listener(foxglove.websocket.ServerListener):  # the other callbacks: no-ops
            def on_subscribe(self, client: Any, channel: Any) -> None:
                resend(client, channel)

        try:
            server = foxglove.start_server(name='pushbot', host=host, port=port,
                                           context=context, server_listener=Listener())
        except Exception as exc:  # the SDK raises its own error types for bind failures
            print(f'pushbot view: cannot serve on {host}:{port}: {exc}', file=sys.stderr)
            return 1
        try:
            shown = f'[{host}]' if ':' in host else host
            print(f'serving the ROS graph to Foxglove on ws://{shown}:{server.port} '
                  '(Foxglove: Open connection -> Foxglove WebSocket; Ctrl-C to stop)',
                  flush=True)
            view.discover()
            node.create_timer(DISCOVERY_PERIOD, view.guard(view.discover, 'discover'))
            try:
                while node.context.ok():
                    executor.spin_once(timeout_sec=0.1)
            except (KeyboardInterrupt, ExternalShutdownException):
                pass
        finally:
            server.stop()
    print('forwarded ' + (', '.join(f'{t} {n}' for t, n in sorted(view.forwarded.items()))
                          or 'nothing'))
    return 0
