"""Small rclpy helpers shared by the CLI tools (``pushbot topic``, the doctor probe).

Every tool runs one short-lived node in its own :class:`rclpy.context.Context`, so the CLI
never touches the default context and can be used from tests that hold one. rclpy is imported
lazily inside the functions: importing this module must work (and ``pushbot --help`` must
print) even when rclpy is broken, so that ``pushbot doctor`` can explain what is missing.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile
    from rclpy.topic_endpoint_info import TopicEndpointInfo


class RosUnavailableError(RuntimeError):
    """rclpy (or its RMW implementation) cannot be imported."""


def import_rclpy() -> Any:
    """Import rclpy, turning any import failure into :class:`RosUnavailableError`.

    A missing RMW shared library surfaces as ``ImportError`` or ``OSError`` depending on the
    wheel, and a half-installed rclpy can raise almost anything, hence the broad except.
    """
    try:
        import rclpy
        import rclpy.executors  # noqa: F401  (fails when the C extension is broken)
    except Exception as exc:
        raise RosUnavailableError(
            f"rclpy cannot be imported ({type(exc).__name__}: {exc}): run make venv"
        ) from exc
    return rclpy


def run_graph_command(args: Any, handler: Callable[[Any], int], command: str) -> int:
    """Run the handler of a graph command (``pushbot topic|node|service|param ...``); an
    unusable rclpy or an unknown interface type becomes one line on stderr and status 1."""
    try:
        return handler(args)
    except (RosUnavailableError, LookupError) as exc:
        print(f"pushbot {command}: {exc}", file=sys.stderr)
        return 1


@contextmanager
def cli_node(role: str) -> Iterator[tuple[Node, Executor]]:
    """Yield a hidden node and a single-threaded executor in a private context.

    Parameters
    ----------
    role
        Short name used in the node name ``_pushbot_<role>_<pid>``; the leading underscore
        hides the node from node listings, like the ``ros2`` CLI's own nodes.

    The node has no rosout publisher and no parameter services: it only watches the graph and
    exchanges messages. Everything is shut down on exit, including after Ctrl-C.
    """
    rclpy = import_rclpy()
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    context = Context()
    rclpy.init(args=[], context=context)
    node = None
    executor = None
    try:
        node = Node(
            f"_pushbot_{role}_{os.getpid()}",
            context=context,
            enable_rosout=False,
            start_parameter_services=False,
        )
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        yield node, executor
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)


@contextmanager
def sigterm_as_keyboard_interrupt() -> Iterator[None]:
    """Treat SIGTERM like Ctrl-C while a command runs (main thread only): ``pushbot up``,
    ``bag``, ``view``, ``demo`` and the graph episodes stop as on Ctrl-C."""
    try:
        previous = signal.signal(signal.SIGTERM, signal.default_int_handler)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def spin_until(
    executor: Executor | None, predicate: Callable[[], Any], deadline: float, step: float = 0.05
) -> bool:
    """Spin ``executor`` until ``predicate()`` is true or ``time.monotonic()`` passes ``deadline``.

    With ``executor=None`` it sleeps between polls instead. Returns the final truth value of
    the predicate. Never call this from inside a callback.
    """
    while True:
        if predicate():
            return True
        remaining = deadline - time.monotonic()
        if remaining <= 0.0:
            return bool(predicate())
        if executor is None:
            time.sleep(min(step, remaining))
        else:
            executor.spin_once(timeout_sec=min(step, remaining))


#: Seconds without an answer after which :func:`call_until_answered` sends a request again.
RESEND_AFTER = 5.0


def call_until_answered(client: Any, request: Any, executor: Executor | None, deadline: float,
                        resend_after: float = RESEND_AFTER) -> Any:
    """Call an *idempotent* service until it answers or ``time.monotonic()`` passes
    ``deadline``: the done future, or None.

    A server can receive a request before it has matched the client's response reader (the
    client matched first: ``wait_for_service`` said ready); Fast DDS then waits 100 ms for the
    match and drops the response (ros2/rmw_fastrtps#390 and #467), which a loaded machine
    makes likely. The request is therefore sent again after ``resend_after`` s without an
    answer (the unanswered one withdrawn): only for services a repeat does not harm (a reset,
    setting parameters, an enable switch).
    """
    while True:
        future = client.call_async(request)
        if spin_until(executor, future.done, min(deadline, time.monotonic() + resend_after)):
            return future
        client.remove_pending_request(future)
        if time.monotonic() >= deadline:
            return None


#: The discovery rule of the graph commands (see :func:`wait_for_stable_graph`): at least
#: MIN_DISCOVERY_TIME seconds, then until nothing changed for SETTLE_TIME seconds. Chosen from
#: discovery timelines on the ``pushbot up`` graph (benchmarks/bench_cli.py,
#: docs/results/cli.md, where shorter rules are replayed on the same timelines).
MIN_DISCOVERY_TIME = 3.0
SETTLE_TIME = 2.0
#: Default bound (seconds) of the graph commands' discovery wait (``--spin-time``).
DEFAULT_SPIN_TIME = 10.0
#: Exit status of every ``pushbot`` command on bad input (argparse's own, as ros2cli).
EXIT_USAGE = 2


def add_spin_time(parser: Any) -> None:
    """The ``--spin-time`` option of a graph-listing command (one definition for all)."""
    parser.add_argument("--spin-time", type=float, default=DEFAULT_SPIN_TIME,
                        help="longest wait for discovery in seconds (default: %(default)s)")


def wait_for_stable_graph(
    executor: Executor,
    snapshot: Callable[[], Any],
    deadline: float,
    settle: float = SETTLE_TIME,
    ready: Callable[[Any], bool] | None = None,
    min_time: float = MIN_DISCOVERY_TIME,
) -> Any:
    """Spin until ``snapshot()`` has not changed for ``settle`` seconds (and ``min_time``
    seconds have passed), or until ``deadline``.

    The one discovery rule of the CLI's graph commands (``topic list|info``, ``node``,
    ``service list``): without a daemon, a fresh node learns the graph participant by
    participant and endpoint by endpoint, so a single look after a fixed pause can miss
    endpoints (the measured "0 publishers" of ``topic info``). ``snapshot`` returns a
    comparable view of what the command prints (e.g. the sorted endpoints of a topic); the wait
    ends when it is ``ready`` (default: always), at least ``min_time`` s passed and it has been
    equal for ``settle`` seconds, at the latest at ``deadline`` (``time.monotonic()``).
    Returns the last snapshot.
    """
    start = time.monotonic()
    current = snapshot()
    since = start
    while True:
        now = time.monotonic()
        if now >= deadline or ((ready is None or ready(current)) and now - since >= settle
                               and now - start >= min_time):
            return current
        executor.spin_once(timeout_sec=min(0.05, max(deadline - now, 0.0)))
        latest = snapshot()
        if latest != current:
            current, since = latest, time.monotonic()


def graph_snapshot(node: Node) -> tuple[tuple[str, ...], tuple[Any, ...], tuple[Any, ...]]:
    """(other nodes' full names, topics with types, services with types), sorted: what the
    graph commands wait on with :func:`wait_for_stable_graph` (``ready``: any other node).
    Hidden services (a name part starting with ``_``, e.g. those of the CLI's own node) are
    left out, as ``ros2 service list`` does."""
    me = node.get_fully_qualified_name()
    nodes = tuple(sorted(full_node_name(name, ns)
                         for name, ns in node.get_node_names_and_namespaces()
                         if full_node_name(name, ns) != me))
    topics = tuple(sorted((n, tuple(t)) for n, t in node.get_topic_names_and_types()))
    services = tuple(sorted((n, tuple(t)) for n, t in node.get_service_names_and_types()
                            if not any(part.startswith("_") for part in n.split("/"))))
    return nodes, topics, services


def full_node_name(name: str, namespace: str) -> str:
    """``/ns/name`` (``/name`` in the root namespace)."""
    return f'{namespace.rstrip("/")}/{name}'


def wait_for_graph(node: Node, executor: Executor, timeout: float) -> Any:
    """:func:`graph_snapshot` once it is stable (some other node seen), at most ``timeout`` s."""
    return wait_for_stable_graph(executor, lambda: graph_snapshot(node),
                                 time.monotonic() + max(timeout, 0.0),
                                 ready=lambda snap: bool(snap[0]))


def topic_types(node: Node, topic: str) -> list[str]:
    """Types under which ``topic`` (fully resolved) appears in the graph; empty if absent."""
    for name, types in node.get_topic_names_and_types():
        if name == topic:
            return list(types)
    return []


def compatible_qos(publishers: Sequence[TopicEndpointInfo], depth: int = 10) -> QoSProfile:
    """A subscription QoS that matches every publisher in ``publishers``.

    Best effort if any publisher is best effort (a reliable reader never matches a best-effort
    writer); transient local if all publishers are (so latched data is received), otherwise
    volatile (a transient-local reader does not match a volatile writer).
    """
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    best_effort = any(
        p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in publishers
    )
    latched = bool(publishers) and all(
        p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers
    )
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def import_message_class(type_string: str) -> type:
    """Import the Python class of an interface type string.

    Parameters
    ----------
    type_string
        ``'pkg/msg/Type'`` as reported by the graph (``'pkg/Type'`` is accepted too).

    Raises
    ------
    LookupError
        When the string is malformed or the package / type is not installed.
    """
    parts = type_string.split("/")
    if len(parts) == 2:
        package, kind, name = parts[0], "msg", parts[1]
    elif len(parts) == 3:
        package, kind, name = parts
    else:
        raise LookupError(f"malformed message type '{type_string}': expected 'pkg/msg/Type'")
    try:
        module = importlib.import_module(f"{package}.{kind}")
    except ImportError as exc:
        raise LookupError(
            f"cannot decode '{type_string}': interface package '{package}' is not installed "
            f"({exc})"
        ) from exc
    try:
        cls = getattr(module, name)
    except AttributeError as exc:
        raise LookupError(
            f"cannot decode '{type_string}': '{package}.{kind}' has no type '{name}'"
        ) from exc
    return cls
