"""A node's health: callback guard, counters, refusals, last error and ``/diagnostics``.

One object per node replaces the guard / counter / refusal / last-error code each node used to
write for itself. The key scheme on ``/diagnostics`` is the same for every node:

- ``callback_errors``: exceptions stopped by :meth:`NodeHealth.guard` (logged with the
  traceback's last frame, throttled); ``last_error`` holds the newest (``<callback>: <type>:
  <message>``).
- ``refused``: every input or request the node refused (:meth:`NodeHealth.refuse`), plus the
  refusal's own class counter (``refused_<class>``, e.g. ``refused_stamp``); ``last_refusal``
  holds the newest (``<what>: <reason>``).
- the node's own event counters (:meth:`NodeHealth.count`), declared up front so that every
  key is on ``/diagnostics`` from the first status on (a missing key and a zero look
  different to a monitor).

Strings are capped at ``MAX_TEXT`` characters (an attacker's 1 MB frame id must not end up in
every status). All methods are thread-safe (a worker thread may count while a callback runs).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus

from push_ros.diagnostics import DiagnosticsPublisher
from push_ros.node import ThrottledLog, guarded

__all__ = ["MAX_TEXT", "NodeHealth"]

#: Longest ``last_error`` / ``last_refusal`` / log text kept, characters.
MAX_TEXT = 500


class NodeHealth:
    """Guard, counters, refusals and the ``/diagnostics`` status of one node.

    Parameters
    ----------
    node : rclpy.node.Node
    what : str
        What the status is about (``<node fqn>: <what>`` on ``/diagnostics``; empty: the node
        name alone).
    hardware_id : str
    counters : iterable of str
        The node's own event counters, all starting at 0.
    log_period : float
        Seconds between two log lines of one kind (:class:`push_ros.node.ThrottledLog`).
    on_error : callable, optional
        ``on_error(name, message)`` after a callback error was counted (e.g. publish a status).
    """

    def __init__(self, node: Any, what: str = "", hardware_id: str = "",
                 counters: Iterable[str] = (), log_period: float = 2.0,
                 on_error: Callable[[str, str], None] | None = None) -> None:
        self.log = ThrottledLog(node.get_logger(), log_period)
        self.diagnostics = DiagnosticsPublisher(node, what, hardware_id)
        self._lock = threading.Lock()
        self._counts: dict[str, int] = {"callback_errors": 0, "refused": 0}
        for name in counters:
            self._counts.setdefault(str(name), 0)
        self.last_error = ""
        self.last_refusal = ""
        self._on_error = on_error

    # ---- counting ---------------------------------------------------------------------------
    def count(self, counter: str, n: int = 1) -> int:
        """Add ``n`` to ``counter`` (created at 0 if new); return the new value."""
        with self._lock:
            value = self._counts.get(counter, 0) + int(n)
            self._counts[counter] = value
        return value

    def get(self, counter: str) -> int:
        """The value of ``counter`` (0 if never counted)."""
        with self._lock:
            return self._counts.get(counter, 0)

    @property
    def counts(self) -> dict[str, int]:
        """A copy of every counter."""
        with self._lock:
            return dict(self._counts)

    def reset_counts(self, keep: Iterable[str] = ()) -> None:
        """Zero every counter except those in ``keep`` (a new episode; errors usually kept)."""
        kept = set(keep)
        with self._lock:
            for name in self._counts:
                if name not in kept:
                    self._counts[name] = 0

    # ---- refusals and errors ----------------------------------------------------------------
    def refuse(self, what: str, reason: str, kind: str = "input", error: bool = False) -> str:
        """Count and log a refused input or request; return its one-line text.

        Parameters
        ----------
        what : str
            What was refused (a topic, a service, ``push``).
        reason : str
            Why, in words a user can act on.
        kind : str
            The refusal class: counted as ``refused_<kind>`` besides ``refused``.
        error : bool
            Log at error level instead of warning.
        """
        text = f"refused {what}: {reason}"[:MAX_TEXT]
        with self._lock:
            self._counts["refused"] += 1
            key = f"refused_{kind}"
            self._counts[key] = self._counts.get(key, 0) + 1
            self.last_refusal = f"{what}: {reason}"[:MAX_TEXT]
        (self.log.error if error else self.log.warning)(f"refused:{what}:{kind}", text)
        return text

    def guard(self, callback: Callable[..., Any], name: str | None = None) -> Callable[..., Any]:
        """``callback`` that never raises (:func:`push_ros.node.guarded`); errors are counted
        as ``callback_errors`` and kept as ``last_error``."""
        return guarded(callback, self.log, self._callback_error,
                       name or getattr(callback, "__name__", "callback"))

    def _callback_error(self, name: str, message: str) -> None:
        with self._lock:
            self._counts["callback_errors"] += 1
            self.last_error = f"{name}: {message}"[:MAX_TEXT]
        if self._on_error is not None:
            self._on_error(name, message)

    # ---- reporting ----------------------------------------------------------------------------
    def values(self, extra: Mapping[str, object] | None = None) -> dict[str, object]:
        """Counters, ``last_refusal``, ``last_error`` and ``extra`` (in that order)."""
        with self._lock:
            values: dict[str, object] = dict(self._counts)
            values["last_refusal"] = self.last_refusal
            values["last_error"] = self.last_error
        if extra:
            values.update(extra)
        return values

    def status(self, level: bytes, message: str, extra: Mapping[str, object] | None = None
               ) -> DiagnosticStatus:
        """This node's ``DiagnosticStatus`` with :meth:`values`."""
        return self.diagnostics.status(level, message, self.values(extra))

    def publish(self, level: bytes, message: str, extra: Mapping[str, object] | None = None,
                stamp: Any = None) -> DiagnosticStatus:
        """Publish the status on ``/diagnostics`` (stamped ``stamp``, default now); return it."""
        status = self.status(level, message, extra)
        self.diagnostics.publisher.publish(self.diagnostics.array(status, stamp))
        return status
