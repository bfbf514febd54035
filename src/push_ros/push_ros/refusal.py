"""``pusher/refused``: the one refusal message of whatever executes pushes.

Whoever executes ``planner/push`` (the simulator's free pusher, ``push_executor_node`` on an arm)
answers a push it will not execute with one ``diagnostic_msgs/DiagnosticStatus`` on
``pusher/refused`` (reliable, volatile, depth 10), so the planner counts the push as lost and
re-plans at once instead of waiting for its ``push_timeout``:

- ``level`` WARN, ``name`` the refusing node's fully qualified name, ``message`` the reason in
  words, ``hardware_id`` what executes (``pybullet pusher``, ``arm``);
- ``values``: ``push_stamp`` = the refused ``planner/push`` header stamp as
  ``"<sec>.<nanosec, 9 digits>"`` (exact: the planner matches it against the push it has in
  flight), ``kind`` = the refusal class (``busy``, ``invalid``, ``workspace``, ``ik``,
  ``joint_limits``, ``speed``, ``singular``, ``tool_height``, ``disabled``, ``no_state``,
  ``fault``, ...), ``stage`` = the motion stage that failed its check (or ``""``);
- optional ``available`` (``true`` / ``false``): whether the executor can take a push right
  after this refusal (``push_executor_node`` always says; another executor may leave it out).

A refusal whose ``push_stamp`` does not match the push in flight (a stale one, another
planner's) is ignored by the planner. A refusal that says the robot is not available
(:func:`robot_unavailable`: ``available`` false, or a kind of :data:`UNAVAILABLE_KINDS`) pauses
the episode until the executor says on ``executor/status`` that it is ready again
(:func:`read_readiness`); re-planning cannot change such a refusal. After a refusal of a kind in
:data:`MOVING_KINDS` the robot may still be moving (busy with an earlier push, or stopped on the
way), so the planner plans its next push from a newer estimate; after any other refusal nothing
moved and it plans at once.

``executor/status`` (diagnostic_msgs/DiagnosticStatus, latched) carries the executor's
readiness in three values (:func:`readiness_values` writes them, :func:`read_readiness` reads
them): ``ready`` (``true`` / ``false``), ``unavailable`` (``<kind>: <reason>`` while it cannot
take a push for a reason of :data:`UNAVAILABLE_KINDS`, else empty) and ``session`` (the
executor process's start, unique per start: a new one means a restarted executor, which has
forgotten any push it was given).
"""

from __future__ import annotations

from dataclasses import dataclass

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

__all__ = ["MOVING_KINDS", "UNAVAILABLE_KINDS", "Readiness", "Refusal", "check_stamp_key",
           "read_readiness", "read_refusal", "readiness_values", "refusal_msg",
           "robot_unavailable", "stamp_key"]

#: Refusal kinds after which the robot may still be moving or the object have moved.
MOVING_KINDS = frozenset({"busy", "fault", "cancelled"})
#: Refusal kinds no other push can avoid: the robot is not available (disabled, no joint
#: states, no controller, no model, an impossible or unleavable measured posture).
UNAVAILABLE_KINDS = frozenset({"disabled", "no_state", "no_controller", "no_model", "state"})
#: Longest reason kept, characters.
MAX_REASON = 500


def stamp_key(stamp: Time) -> str:
    """``"<sec>.<nanosec, 9 digits>"``: an exact text form of a stamp (no float rounding)."""
    return f"{int(stamp.sec)}.{int(stamp.nanosec):09d}"


def check_stamp_key(key: str, what: str) -> str:
    """``key`` if it is a :func:`stamp_key` text, else raise ``ValueError`` naming ``what``."""
    sec, _, nanosec = key.partition(".")
    if not (sec.isdigit() and len(nanosec) == 9 and nanosec.isdigit() and len(sec) <= 10):
        raise ValueError(f"{what} must be '<sec>.<9 digits>', got {key[:40]!r}")
    return key


@dataclass(frozen=True)
class Refusal:
    """A decoded ``pusher/refused`` message (module docstring)."""

    who: str
    push_stamp: str
    kind: str
    stage: str
    reason: str
    available: bool | None = None


def robot_unavailable(refusal: Refusal) -> bool:
    """Whether ``refusal`` says the robot cannot take any push now: ``available`` false, or a
    kind of :data:`UNAVAILABLE_KINDS` (module docstring)."""
    return refusal.available is False or refusal.kind in UNAVAILABLE_KINDS


def refusal_msg(who: str, push_stamp: Time, kind: str, reason: str, stage: str = "",
                hardware_id: str = "", available: bool | None = None) -> DiagnosticStatus:
    """The ``pusher/refused`` message of one refused push (module docstring)."""
    values = [KeyValue(key="push_stamp", value=stamp_key(push_stamp)),
              KeyValue(key="kind", value=str(kind)), KeyValue(key="stage", value=str(stage))]
    if available is not None:
        values.append(KeyValue(key="available", value="true" if available else "false"))
    return DiagnosticStatus(level=DiagnosticStatus.WARN, name=who,
                            message=str(reason)[:MAX_REASON], hardware_id=hardware_id,
                            values=values)


def read_refusal(msg: DiagnosticStatus) -> Refusal:
    """Decode ``pusher/refused``.

    Raises
    ------
    ValueError
        No ``push_stamp`` value, or one not of the form ``<sec>.<9 digits>``.
    """
    values = {kv.key: kv.value for kv in msg.values[:16]}
    key = check_stamp_key(values.get("push_stamp", ""), "pusher/refused: push_stamp")
    return Refusal(who=msg.name[:200], push_stamp=key, kind=values.get("kind", "")[:64],
                   stage=values.get("stage", "")[:64], reason=msg.message[:MAX_REASON],
                   available=_flag(values.get("available")))


def _flag(text: str | None) -> bool | None:
    return {"true": True, "false": False}.get(text or "")


@dataclass(frozen=True)
class Readiness:
    """The readiness values of an ``executor/status`` (module docstring).

    Attributes
    ----------
    ready : bool or None
        None when the status does not say (not an executor that reports readiness).
    unavailable : str
        ``<kind>: <reason>``, or empty.
    session : str
        The executor process's start (empty when not said).
    """

    ready: bool | None
    unavailable: str
    session: str


def readiness_values(ready: bool, unavailable: tuple[str, str] | None, session: str
                     ) -> dict[str, str]:
    """The ``executor/status`` values of :class:`Readiness` (``unavailable``: (kind, reason)
    or None)."""
    return {"ready": "true" if ready else "false",
            "unavailable": "" if unavailable is None else
            f"{unavailable[0]}: {unavailable[1]}"[:MAX_REASON],
            "session": session}


def read_readiness(msg: DiagnosticStatus) -> Readiness:
    """Decode the readiness of an ``executor/status`` (missing values: ``ready`` None)."""
    values = {kv.key: kv.value for kv in msg.values[:64]}
    return Readiness(ready=_flag(values.get("ready")),
                     unavailable=values.get("unavailable", "")[:MAX_REASON],
                     session=values.get("session", "")[:64])
