"""DiagnosticStatus / DiagnosticArray building: the one diagnostics codec of the nodes.

Every node publishes one status on ``/diagnostics`` (reliable): ``name`` =
``<node fully qualified name>: <what>``, ``level`` OK / WARN / ERROR, a ``message`` and string
key-values; ``planner/status`` is the planner's status on its own latched topic.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from push_ros.qos import RELIABLE_QOS

__all__ = ["DiagnosticsPublisher", "diagnostic_array", "status_msg"]


def status_msg(name: str, level: bytes, message: str,
               values: Mapping[str, object] | Sequence[tuple[str, object]] = (),
               hardware_id: str = "") -> DiagnosticStatus:
    """A ``DiagnosticStatus``: level, message and the values as strings (in order)."""
    items = values.items() if isinstance(values, Mapping) else values
    return DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=str(k), value=str(v)) for k, v in items])


def diagnostic_array(statuses: Sequence[DiagnosticStatus] | DiagnosticStatus, stamp: Time
                     ) -> DiagnosticArray:
    """A ``DiagnosticArray`` of one or more statuses, stamped ``stamp``."""
    if isinstance(statuses, DiagnosticStatus):
        statuses = [statuses]
    array = DiagnosticArray(status=list(statuses))
    array.header.stamp = stamp
    return array


class DiagnosticsPublisher:
    """A node's ``/diagnostics`` (reliable): one status, ``<node fqn>: <what>``.

    Parameters
    ----------
    node : rclpy.node.Node
    what : str
        What the status is about (``perception``, ``estimator``, ``simulation``); empty: the
        status is named after the node alone.
    hardware_id : str
    """

    def __init__(self, node: Any, what: str = "", hardware_id: str = "") -> None:
        self._node = node
        fqn = node.get_fully_qualified_name()
        self.name = f"{fqn}: {what}" if what else fqn
        self.hardware_id = hardware_id
        self.publisher = node.create_publisher(DiagnosticArray, "/diagnostics", RELIABLE_QOS)

    def status(self, level: bytes, message: str,
               values: Mapping[str, object] | Sequence[tuple[str, object]] = ()
               ) -> DiagnosticStatus:
        """This node's status message (see :func:`status_msg`)."""
        return status_msg(self.name, level, message, values, self.hardware_id)

    def array(self, status: DiagnosticStatus, stamp: Time | None = None) -> DiagnosticArray:
        """The ``/diagnostics`` message of ``status``, stamped ``stamp`` (default: now)."""
        return diagnostic_array(status, stamp if stamp is not None
                                else self._node.get_clock().now().to_msg())

    def publish(self, level: bytes, message: str,
                values: Mapping[str, object] | Sequence[tuple[str, object]] = (),
                stamp: Time | None = None) -> DiagnosticStatus:
        """Build and publish the status; return it."""
        status = self.status(level, message, values)
        self.publisher.publish(self.array(status, stamp))
        return status
