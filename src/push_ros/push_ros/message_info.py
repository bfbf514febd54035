"""Who sent a sample: rclpy message infos, for readers that take one topic twice.

rclpy (Jazzy) hands a two-argument subscription callback a *message info*: a dict with
``publication_sequence_number`` (a writer numbers its samples 1, 2, 3, ...) and
``source_timestamp`` (ns), but no publisher GID (a later rclpy adds ``publisher_gid``).

- :func:`sample_key`: (sequence number, source timestamp) identifies one sample of one writer,
  so a sample received on two readers of one topic (volatile and transient local) is taken once.
- :class:`GoalSources`: de-duplicates ``goal_pose`` samples and decides whether a goal comes
  from another publisher than the current goal's: by GID when the info has one, otherwise by
  the sequence number (a goal whose number does not follow the previous ``goal_pose``
  message's comes from another, or a restarted, publisher). Never for an episode's first goal.

- :func:`subscribe_goals`: the two ``goal_pose`` readers of a planner, both calling one
  callback with the message info.

Anything else (None, a dict without the entries, wrong types) is "unknown", never an error.
"""

from __future__ import annotations

from collections import deque
from typing import Any

__all__ = ["GoalSources", "publisher_of", "publishers_text", "sample_key", "subscribe_goals"]


def _int(value: Any) -> int | None:
    return int(value) if isinstance(value, int) and not isinstance(value, bool) else None


def sample_key(info: Any) -> tuple[int, int] | None:
    """(publication sequence number, source timestamp in ns) of a message info, or None."""
    if not isinstance(info, dict):
        return None
    sequence = _int(info.get("publication_sequence_number"))
    stamp = _int(info.get("source_timestamp"))
    return None if sequence is None or stamp is None else (sequence, stamp)


def publisher_of(info: Any) -> tuple[str, int | None]:
    """(``"gid <hex bytes>"`` or "", publication sequence number or None) of a message info."""
    if not isinstance(info, dict):
        return "", None
    gid = info.get("publisher_gid")
    data = gid.get("data") if isinstance(gid, dict) else gid
    source = ""
    if data is not None:
        try:
            source = "gid " + ".".join(format(int(x), "02x") for x in data)
        except (TypeError, ValueError):
            source = ""
    return source, _int(info.get("publication_sequence_number"))


class GoalSources:
    """The senders of ``goal_pose`` samples (module docstring).

    Per sample: :meth:`duplicate` (drop it if True), then :meth:`arrived` (every sample, taken
    or refused, so the sequence rule sees them all), then :meth:`take` for a goal that is
    taken.

    Parameters
    ----------
    kept : int
        Sample keys remembered for :meth:`duplicate`.

    Attributes
    ----------
    source : str
        Who sent the current goal (:func:`publisher_of`), "" = unknown or nobody yet.
    """

    def __init__(self, kept: int = 16) -> None:
        self._samples: deque[tuple[int, int]] = deque(maxlen=int(kept))
        self.source = ""
        self._sequence: int | None = None
        self._arrived: tuple[str, int | None, int | None] = ("", None, None)

    def forget(self) -> None:
        """A new episode: no current goal, no previous sequence number."""
        self.source, self._sequence = "", None

    def duplicate(self, info: Any) -> bool:
        """Whether this sample was already received (on the other reader); remembers it."""
        key = sample_key(info)
        if key is None:
            return False
        if key in self._samples:
            return True
        self._samples.append(key)
        return False

    def arrived(self, info: Any) -> str:
        """A ``goal_pose`` sample arrived (taken or not); returns its source."""
        source, sequence = publisher_of(info)
        self._arrived = (source, sequence, self._sequence)
        self._sequence = sequence
        return source

    def take(self, have_goal: bool) -> bool:
        """The last arrived goal is taken; whether it replaces one from another publisher.

        Parameters
        ----------
        have_goal : bool
            A goal of this episode was taken before (the first never counts as a switch).
        """
        source, sequence, previous = self._arrived
        if not have_goal:
            switched = False
        elif source or self.source:
            switched = source != self.source
        else:
            switched = sequence is not None and previous is not None and sequence != previous + 1
        self.source = source
        return switched


def publishers_text(node: Any, topic: str) -> str:
    """The publishers of ``topic`` now, for a log line: ``<namespace>/<node> (gid <hex>)``, ...;
    ``none``, or ``unknown (<error>)`` if the graph cannot be read."""
    try:
        infos = node.get_publishers_info_by_topic(node.resolve_topic_name(topic))
    except Exception as exc:  # noqa: BLE001 - only for a log line
        return f"unknown ({exc})"
    return ", ".join(f"{i.node_namespace.rstrip('/')}/{i.node_name} (gid "
                     f"{'.'.join(format(x, '02x') for x in i.endpoint_gid)})"
                     for i in infos) or "none"


def subscribe_goals(node: Any, callback: Any, topic: str = "goal_pose") -> None:
    """Take ``topic`` (geometry_msgs/PoseStamped) twice, both readers calling
    ``callback(msg, info)`` (:class:`GoalSources` takes a sample once): reliable volatile (every
    publisher, RViz's "2D Goal Pose" too) and reliable transient local (a (re)started node gets
    a latched sender's last goal; a volatile writer cannot match it, an expected mismatch logged
    at debug level only)."""
    from geometry_msgs.msg import PoseStamped
    from rclpy.event_handler import SubscriptionEventCallbacks

    from push_ros.qos import LATCHED_QOS, RELIABLE_QOS

    def with_info(msg: Any, info: Any) -> None:  # two arguments: rclpy adds the message info
        callback(msg, info)

    node.create_subscription(PoseStamped, topic, with_info, RELIABLE_QOS)
    node.create_subscription(
        PoseStamped, topic, with_info, LATCHED_QOS,
        event_callbacks=SubscriptionEventCallbacks(
            incompatible_qos=lambda event: node.get_logger().debug(
                f"a volatile {topic} publisher (e.g. RViz) does not match the latched goal "
                "reader; its goals arrive on the volatile one")))
