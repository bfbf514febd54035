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
  ``fault``, ...), ``stage`` = the motion stage that failed its check (or ``""``).

A refusal whose ``push_stamp`` does not match the push in flight (a stale one, another
planner's) is ignored by the planner. After a refusal of a kind in :data:`MOVING_KINDS` the robot
may still be moving (busy with an earlier push, or stopped on the way), so the planner plans its
next push from a newer estimate; after any other refusal nothing moved and it plans at once.
"""

from __future__ import annotations

from dataclasses import dataclass

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

__all__ = ["MOVING_KINDS", "Refusal", "check_stamp_key", "read_refusal", "refusal_msg",
           "stamp_key"]

#: Refusal kinds after which the robot may still be moving or the object have moved.
MOVING_KINDS = frozenset({"busy", "fault", "cancelled"})
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


def refusal_msg(who: str, push_stamp: Time, kind: str, reason: str, stage: str = "",
                hardware_id: str = "") -> DiagnosticStatus:
    """The ``pusher/refused`` message of one refused push (module docstring)."""
    return DiagnosticStatus(
        level=DiagnosticStatus.WARN, name=who, message=str(reason)[:MAX_REASON],
        hardware_id=hardware_id,
        values=[KeyValue(key="push_stamp", value=stamp_key(push_stamp)),
                KeyValue(key="kind", value=str(kind)), KeyValue(key="stage", value=str(stage))])


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
                   stage=values.get("stage", "")[:64], reason=msg.message[:MAX_REASON])
