"""Small rclpy helpers shared by the CLI tools (``pushbot topic``, the doctor probe).

Every tool runs one short-lived node in its own :class:`rclpy.context.Context`, so the CLI
never touches the default context and can be used from tests that hold one. rclpy is imported
lazily inside the functions: importing this module must work (and ``pushbot --help`` must
print) even when rclpy is broken, so that ``pushbot doctor`` can explain what is missing.
"""

from __future__ import annotations

import importlib
import os
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
            f'rclpy cannot be imported ({type(exc).__name__}: {exc}): run make venv'
        ) from exc
    return rclpy


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
            f'_pushbot_{role}_{os.getpid()}',
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
    parts = type_string.split('/')
    if len(parts) == 2:
        package, kind, name = parts[0], 'msg', parts[1]
    elif len(parts) == 3:
        package, kind, name = parts
    else:
        raise LookupError(f"malformed message type '{type_string}': expected 'pkg/msg/Type'")
    try:
        module = importlib.import_module(f'{package}.{kind}')
    except ImportError as exc:
        raise LookupError(
            f"cannot decode '{type_string}': interface package '{package}' is not installed "
            f'({exc})'
        ) from exc
    try:
        cls = getattr(module, name)
    except AttributeError as exc:
        raise LookupError(
            f"cannot decode '{type_string}': '{package}.{kind}' has no type '{name}'"
        ) from exc
    return cls
