"""``pushbot view [--host H] [--port P] [--topics ...]``: the live graph in Foxglove.

Serves the graph's topics over the Foxglove WebSocket protocol with ``foxglove-sdk``: in
Foxglove, *Open connection* -> *Foxglove WebSocket* -> ``ws://127.0.0.1:8765``. Clients may
offer the subprotocol ``foxglove.sdk.v1`` (current Foxglove; the one ``foxglove_bridge`` 3
speaks) or the older ``foxglove.websocket.v1`` (older Foxglove builds, Lichtblick builds from
before it learnt the new name in December 2025, other ``ws-protocol`` clients): the SDK server
accepts only the first, so a relay on the public port accepts both and passes every frame
through unchanged (:mod:`pushbot.viz.view_relay`; the two are one protocol under two names).

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

Time: the server advertises the ``time`` capability and sends the graph's ``/clock`` as the
server time (sim time), and logs every message at its header stamp (a message without a
header: at the last ``/clock``; without ``/clock``: at the wall clock), so Foxglove's timeline
and the message stamps agree (:mod:`pushbot.viz.view_frames`).

Frames: the pip install has no ``/tf`` (docs/design/topics.md#tf-note), so the view sends
Foxglove ``FrameTransforms`` on the channel ``/pushbot/frames``: ``world`` -> ``object`` from
``estimator/object_pose`` (the estimate), ``world`` -> ``camera_color_optical_frame`` from
``camera/color/extrinsics`` and ``world`` -> ``pusher`` from the end pose of the last
``pusher/executed``; a 3D panel with display frame ``world`` then places the ``object``-frame
outline and centre of mass, the camera and the pusher. The latest transforms are sent again
to a new subscriber.

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

from push_ros.frames import OBJECT_FRAME, PUSHER_FRAME
from pushbot.ros2cli.bag_record import TopicSelection
from pushbot.ros2cli.bag_store import BagError, message_definition
from pushbot.ros2cli.discovery import (
    RosUnavailableError,
    cli_node,
    compatible_qos,
    import_message_class,
)
from pushbot.viz.view_frames import (
    NS_PER_S,
    FrameTree,
    SimTime,
    Transform,
    header_stamp_ns,
    make_transform,
)
from pushbot.viz.view_relay import ACCEPTED, SubprotocolRelay

if TYPE_CHECKING:
    from rclpy.topic_endpoint_info import TopicEndpointInfo

DEFAULT_PORT = 8765
LOOPBACK = ("127.0.0.1", "localhost", "::1")
#: Seconds between two looks at the graph for new topics.
DISCOVERY_PERIOD = 1.0
#: Seconds after which named topics that have not appeared are reported (once).
MISSING_NOTE_AFTER = 10.0
#: The Foxglove channel of the frame transforms (foxglove.FrameTransforms).
FRAMES_TOPIC = "/pushbot/frames"


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * NS_PER_S + int(header.stamp.nanosec)


def _vector(v: Any) -> tuple[float, float, float]:
    return (v.x, v.y, v.z)


def _quaternion(q: Any) -> tuple[float, float, float, float]:
    return (q.x, q.y, q.z, q.w)  # ROS order (x, y, z, w), as Foxglove's


def object_transform(msg: Any) -> Transform:
    """``world`` -> ``object`` of an estimate (geometry_msgs/PoseWithCovarianceStamped)."""
    pose = msg.pose.pose
    return make_transform(msg.header.frame_id, OBJECT_FRAME, _stamp_ns(msg.header),
                          _vector(pose.position), _quaternion(pose.orientation))


def camera_transform(msg: Any) -> Transform:
    """Parent -> camera frame of the extrinsics (geometry_msgs/TransformStamped)."""
    t = msg.transform
    return make_transform(msg.header.frame_id, msg.child_frame_id, _stamp_ns(msg.header),
                          _vector(t.translation), _quaternion(t.rotation))


def pusher_transform(msg: Any) -> Transform:
    """``world`` -> ``pusher`` at the end of an executed push (nav_msgs/Path)."""
    if not msg.poses:
        raise ValueError("pusher/executed without poses")
    pose = msg.poses[-1].pose
    return make_transform(msg.header.frame_id, PUSHER_FRAME, _stamp_ns(msg.header),
                          _vector(pose.position), _quaternion(pose.orientation))


#: (topic, message type, QoS name of push_ros.qos, conversion) of the frame transforms.
FRAME_SOURCES = (
    ("/estimator/object_pose", "geometry_msgs/msg/PoseWithCovarianceStamped", "LATCHED_QOS",
     object_transform),
    ("/camera/color/extrinsics", "geometry_msgs/msg/TransformStamped", "LATCHED_QOS",
     camera_transform),
    ("/pusher/executed", "nav_msgs/msg/Path", "RELIABLE_QOS", pusher_transform),
)


def _has_header(cls: Any) -> bool:
    """Whether messages of ``cls`` start with a ``std_msgs/Header header``."""
    fields = iter(cls.get_fields_and_field_types().items())
    return next(fields, None) == ("header", "std_msgs/Header")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot view``."""
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to bind (default: %(default)s; any other address is "
                        "reachable by others: no authentication)")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help="TCP port (default: %(default)s; 0 picks a free one)")
    parser.add_argument("--topics", nargs="+", default=None, metavar="TOPIC",
                        help="serve only these topics (default: every topic but /rosout and "
                        "/parameter_events)")
    parser.add_argument("-e", "--exclude", default=None, metavar="REGEX",
                        help="leave out the topics this regular expression matches")


def _foxglove() -> Any:
    try:
        import foxglove
        import foxglove.channels
        import foxglove.messages
        import foxglove.websocket
    except ImportError as exc:
        raise BagError(f"foxglove-sdk is not installed ({exc}): run make venv") from exc
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
        self._headers: set[str] = set()
        self.sim = SimTime()
        self.frames = FrameTree()
        #: Set once the server runs: ``broadcast_time(ns)`` of the foxglove server.
        self.broadcast_time: Any = None
        self.frames_channel = _foxglove().channels.FrameTransformsChannel(
            FRAMES_TOPIC, context=context)
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
        """foxglove ServerListener: send a latched topic's last sample, or the latest frame
        transforms, to a new subscriber."""
        if channel.topic == FRAMES_TOPIC:
            self._log_frames()
        data = self.latched.get(channel.topic)
        if data is not None:
            self.channels[channel.topic].log(data, log_time=self._log_time(channel.topic, data))

    def start_time_and_frames(self) -> None:
        """Subscribe to ``/clock`` and to the sources of the frame transforms (decoded)."""
        from rosgraph_msgs.msg import Clock

        from push_ros import qos

        def on_clock(msg: Any) -> None:
            self.sim.on_clock(int(msg.clock.sec) * NS_PER_S + int(msg.clock.nanosec))
            if self.broadcast_time is not None:
                self.broadcast_time(self.sim.clock_ns)

        self.node.create_subscription(Clock, "/clock", self.guard(on_clock, "clock"),
                                      qos.CLOCK_QOS)
        for topic, msgtype, qos_name, convert in FRAME_SOURCES:
            def on_frame(msg: Any, convert: Any = convert) -> None:
                self.frames.update(convert(msg))
                self._log_frames()

            self.node.create_subscription(import_message_class(msgtype), topic,
                                          self.guard(on_frame, f"frame {topic}"),
                                          getattr(qos, qos_name))

    def _log_frames(self) -> None:
        foxglove = _foxglove()
        transforms = list(self.frames.transforms.values())
        if not transforms or not self.frames_channel.has_sinks():
            return
        fs = foxglove.messages
        message = fs.FrameTransforms(transforms=[fs.FrameTransform(
            timestamp=fs.Timestamp(*divmod(t.stamp_ns, NS_PER_S)),
            parent_frame_id=t.parent, child_frame_id=t.child,
            translation=fs.Vector3(x=t.translation[0], y=t.translation[1], z=t.translation[2]),
            rotation=fs.Quaternion(x=t.rotation[0], y=t.rotation[1], z=t.rotation[2],
                                   w=t.rotation[3]))
            for t in transforms])
        self.frames_channel.log(message, log_time=self.sim.log_time(self.frames.latest_ns()))

    def _log_time(self, topic: str, data: bytes) -> int:
        """Log time of a message of ``topic``: its header stamp or the graph's time."""
        return self.sim.log_time(header_stamp_ns(data) if topic in self._headers else None)

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
            self.skipped[name] = f"published with several types {sorted(types)}"
        else:
            try:
                cls = import_message_class(types[0])
                msgdef, _ = message_definition(types[0])
            except (LookupError, BagError) as exc:
                self.skipped[name] = str(exc)
        if name in self.skipped:
            print(f"pushbot view: not serving {name}: {self.skipped[name]}", file=sys.stderr)
            return
        schema = foxglove.Schema(name=types[0], encoding="ros2msg", data=msgdef.encode())
        channel = foxglove.Channel(name, schema=schema, message_encoding="cdr",
                                   context=self.context)
        self.channels[name] = channel
        self.forwarded[name] = 0
        if _has_header(cls):
            self._headers.add(name)

        qos = compatible_qos(publishers, depth=10)
        latched = qos.durability == DurabilityPolicy.TRANSIENT_LOCAL

        def forward(data: bytes, channel: Any = channel, name: str = name) -> None:
            if latched:
                self.latched[name] = bytes(data)
            if channel.has_sinks():
                channel.log(bytes(data), log_time=self._log_time(name, data))
                self.forwarded[name] += 1

        self.subscriptions[name] = self.node.create_subscription(
            cls, name, self.guard(forward, f"forward {name}"), qos, raw=True)
        print(f"serving {name} [{types[0]}]", flush=True)


def run_view(args: argparse.Namespace) -> int:
    """Handler of ``pushbot view``."""
    if not 0 <= args.port <= 65535:
        print(f"pushbot view: --port must be in [0, 65535], got {args.port}", file=sys.stderr)
        return 2
    try:
        exclude = re.compile(args.exclude) if args.exclude else None
    except re.error as exc:
        print(f"pushbot view: --exclude {args.exclude!r} is not a regular expression: {exc}",
              file=sys.stderr)
        return 2
    topics = tuple(t if t.startswith("/") else "/" + t for t in args.topics or ())
    selection = TopicSelection(topics, all_topics=not topics, exclude=exclude)
    if args.host not in LOOPBACK:
        print(f"pushbot view: WARNING: serving on {args.host}: anyone who can reach port "
              f"{args.port} there sees every topic (the protocol has no authentication)",
              file=sys.stderr)
    try:
        return _serve(args.host, args.port, selection)
    except BagError as exc:
        print(f"pushbot view: {exc}", file=sys.stderr)
        return 1
    except RosUnavailableError as exc:
        print(f"pushbot view: {exc}", file=sys.stderr)
        return 1


def _serve(host: str, port: int, selection: TopicSelection) -> int:
    from rclpy.executors import ExternalShutdownException

    from pushbot.ros2cli.discovery import sigterm_as_keyboard_interrupt

    foxglove = _foxglove()
    context = foxglove.Context()
    with sigterm_as_keyboard_interrupt(), cli_node("view") as (node, executor):
        view = LiveView(node, selection, context)
        resend = view.guard(view.on_subscribe, "on_subscribe")

        class Listener(foxglove.websocket.ServerListener):  # the other callbacks: no-ops
            def on_subscribe(self, client: Any, channel: Any) -> None:
                resend(client, channel)

        try:  # the SDK server on a private loopback port, the relay on the public address
            server = foxglove.start_server(
                name="pushbot", host="127.0.0.1", port=0, context=context,
                capabilities=[foxglove.websocket.Capability.Time], server_listener=Listener())
        except Exception as exc:  # the SDK raises its own error types for bind failures
            print(f"pushbot view: cannot start the Foxglove server: {exc}", file=sys.stderr)
            return 1
        relay = SubprotocolRelay(host, port, server.port)
        try:
            relay.start()
        except (OSError, ImportError) as exc:
            server.stop()
            print(f"pushbot view: cannot serve on {host}:{port}: {exc}", file=sys.stderr)
            return 1
        try:
            shown = f"[{host}]" if ":" in host else host
            print(f'serving the ROS graph to Foxglove on ws://{shown}:{relay.port} '
                  f'(subprotocols {", ".join(ACCEPTED)}; Foxglove: Open connection -> '
                  'Foxglove WebSocket; Ctrl-C to stop)', flush=True)
            view.broadcast_time = server.broadcast_time
            view.start_time_and_frames()
            view.discover()
            node.create_timer(DISCOVERY_PERIOD, view.guard(view.discover, "discover"))
            try:
                while node.context.ok():
                    executor.spin_once(timeout_sec=0.1)
            except (KeyboardInterrupt, ExternalShutdownException):
                pass
        finally:
            relay.stop()
            server.stop()
    print("forwarded " + (", ".join(f"{t} {n}" for t, n in sorted(view.forwarded.items()))
                          or "nothing"))
    return 0
