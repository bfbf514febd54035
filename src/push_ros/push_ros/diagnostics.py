"""DiagnosticStatus / DiagnosticArray building: the one diagnostics codec of the nodes.

Every node publishes one status on ``/diagnostics`` (reliable): ``name`` =
``<node fully qualified name>: <what>``, ``level`` OK / WARN / ERROR, a ``message`` and string
key-values; ``planner/status`` is the planner's status on its own latched topic.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

__all__ = ["diagnostic_array", "status_msg"]


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
