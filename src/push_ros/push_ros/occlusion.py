"""``perception/occlusion``: how much of the object the robot hid in each camera frame.

``segmentation_node`` with its self-filter on (``robot_filter.enabled``) publishes one
``diagnostic_msgs/DiagnosticStatus`` (reliable, volatile, depth 10) per camera frame it
processed, so a consumer (the planner, a viewer, an evaluation) knows which frames the arm hid
the object in, and why a frame gave no pose:

- ``level`` OK when the frame gave a pose, WARN when it did not; ``name`` the node's fully
  qualified name, ``message`` the reason in words (empty for a pose), ``hardware_id``
  ``robot_filter``;
- ``values``: ``stamp`` = the frame's header stamp as ``"<sec>.<nanosec, 9 digits>"`` (exact:
  it matches the ``perception/object_pose`` of that frame), ``outcome`` = ``pose`` or the kind
  of the frame's problem (``occluded``: the robot hid more than ``max_occluded`` of the object;
  ``no_robot_model``, ``no_joint_state``, ``stale_joint_state``, ``robot_pose``: the robot's
  pixels could not be computed, so the frame was not used; or another perception outcome such
  as ``empty_mask``), ``occluded_share`` = the share of the object's predicted silhouette the
  robot hid, ``"%.4f"`` in [0, 1] (``nan`` when it is not known), ``robot_pixels`` = the
  robot's pixels in the frame (an integer; ``-1`` when not computed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from push_ros.refusal import check_stamp_key, stamp_key

__all__ = ["HARDWARE_ID", "MAX_REASON", "Occlusion", "occlusion_msg", "read_occlusion"]

#: ``hardware_id`` of the messages.
HARDWARE_ID = "robot_filter"
#: Longest reason kept, characters.
MAX_REASON = 500


@dataclass(frozen=True)
class Occlusion:
    """A decoded ``perception/occlusion`` message (module docstring)."""

    who: str
    stamp: str
    outcome: str
    occluded_share: float
    robot_pixels: int
    reason: str


def occlusion_msg(who: str, stamp: Time, outcome: str, occluded_share: float,
                  robot_pixels: int, reason: str = "") -> DiagnosticStatus:
    """The ``perception/occlusion`` message of one frame (module docstring)."""
    share = f"{occluded_share:.4f}" if math.isfinite(occluded_share) else "nan"
    return DiagnosticStatus(
        level=DiagnosticStatus.OK if outcome == "pose" else DiagnosticStatus.WARN, name=who,
        message=str(reason)[:MAX_REASON], hardware_id=HARDWARE_ID,
        values=[KeyValue(key="stamp", value=stamp_key(stamp)),
                KeyValue(key="outcome", value=str(outcome)),
                KeyValue(key="occluded_share", value=share),
                KeyValue(key="robot_pixels", value=str(int(robot_pixels)))])


def read_occlusion(msg: DiagnosticStatus) -> Occlusion:
    """Decode ``perception/occlusion``.

    Raises
    ------
    ValueError
        A ``stamp`` not of the form ``<sec>.<9 digits>``, an ``occluded_share`` that is not a
        number in [0, 1] or ``nan``, a ``robot_pixels`` that is not an integer >= -1.
    """
    values = {kv.key: kv.value for kv in msg.values[:16]}
    key = check_stamp_key(values.get("stamp", ""), "perception/occlusion: stamp")
    try:
        share = float(values.get("occluded_share", "nan"))
        pixels = int(values.get("robot_pixels", "-1"))
    except ValueError:
        raise ValueError("perception/occlusion: occluded_share and robot_pixels must be "
                         "numbers") from None
    if not (math.isnan(share) or 0.0 <= share <= 1.0) or pixels < -1:
        raise ValueError(f"perception/occlusion: occluded_share {share!r} not in [0, 1] or "
                         f"robot_pixels {pixels} < -1")
    return Occlusion(who=msg.name[:200], stamp=key, outcome=values.get("outcome", "")[:64],
                     occluded_share=share, robot_pixels=pixels, reason=msg.message[:MAX_REASON])
