"""``/tf`` and ``/tf_static`` publishers where ``tf2_msgs`` exists.

``tf2_msgs`` has no PyPI wheel (docs/design/topics.md#tf-note): on a pip-only install the
nodes run without tf output; on a full ROS install they publish it. The optional import is
written here once; a node asks :func:`tf_publisher` and gets None where tf cannot be published.

- ``/tf``: reliable, volatile (``push_ros.qos.RELIABLE_QOS``), the dynamic transforms;
- ``/tf_static``: latched (``push_ros.qos.LATCHED_QOS``), the static ones (a late subscriber
  gets them).
"""

from __future__ import annotations

from typing import Any

from push_ros.qos import LATCHED_QOS, RELIABLE_QOS

try:  # only on a full ROS install
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the install
    TFMessage = None

__all__ = ["TFMessage", "TransformPublisher", "tf_available", "tf_publisher"]


def tf_available() -> bool:
    """Whether ``tf2_msgs`` is importable here."""
    return TFMessage is not None


class TransformPublisher:
    """Publishes ``geometry_msgs/TransformStamped`` s as one ``tf2_msgs/TFMessage``.

    Parameters
    ----------
    node : rclpy.node.Node
    static : bool
        ``/tf_static`` (latched) instead of ``/tf``.
    """

    def __init__(self, node: Any, static: bool = False) -> None:
        if TFMessage is None:
            raise RuntimeError("tf2_msgs is not installed: no tf publisher (see tf_publisher)")
        self.publisher = node.create_publisher(
            TFMessage, "/tf_static" if static else "/tf", LATCHED_QOS if static else RELIABLE_QOS)

    def publish(self, *transforms: Any) -> None:
        """Publish the transforms (geometry_msgs/TransformStamped) in one message."""
        self.publisher.publish(TFMessage(transforms=list(transforms)))


def tf_publisher(node: Any, enabled: bool = True, static: bool = False
                 ) -> TransformPublisher | None:
    """A :class:`TransformPublisher` on ``node``, or None when not ``enabled`` or where
    ``tf2_msgs`` is missing."""
    return TransformPublisher(node, static) if enabled and TFMessage is not None else None
