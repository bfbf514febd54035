"""The camera extrinsics ``T_world_camera``: from tf2 where it exists, else the latched topic.

Two sources, in this order:

1. **tf2** (a full ROS install: ``tf2_ros`` importable): a ``tf2_ros.Buffer`` filled by a
   ``tf2_ros.TransformListener`` (``/tf`` and ``/tf_static``), queried with
   ``buffer.lookup_transform(world_frame, camera_frame, rclpy.time.Time())`` (the latest
   transform; ``lookup_transform(target, source)`` returns the pose of ``source`` in
   ``target``, i.e. ``T_world_camera``). This is how a RealSense driver plus a static transform
   publisher (the camera mounting) provide it on a robot.
2. **The latched topic** ``camera/color/extrinsics`` (geometry_msgs/TransformStamped,
   ``world`` -> camera optical frame; reliable + transient local, depth 1): the pip install's
   fallback (``tf2_ros`` has no PyPI wheel), published by ``sim_bridge_node``. It is always
   subscribed, and used whenever tf2 is missing or has no such transform yet.

``tf2_ros`` cannot be installed on the pip-only machines this project is tested on, so the tf2
path is written against tf2's documented Python API and guarded by the import; the tests
exercise the fallback.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from geometry_msgs.msg import TransformStamped

from push_ros.frames import WORLD_FRAME
from push_ros.poses import matrix_from_transform
from push_ros.qos import LATCHED_QOS

try:  # Only on a full ROS install (no PyPI wheel).
    import tf2_ros
except ImportError:  # pragma: no cover - depends on the install
    tf2_ros = None

__all__ = ["EXTRINSICS_TOPIC", "CameraExtrinsics"]

EXTRINSICS_TOPIC = "camera/color/extrinsics"


class CameraExtrinsics:
    """``T_world_camera`` (4, 4) of the node's camera; see the module docstring.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner of the subscription (and of the tf listener).
    on_error : callable
        Called with the ``ValueError`` of an invalid extrinsics message (it is ignored).
    world_frame : str
        The frame the extrinsics map into.
    use_tf : bool
        Use tf2 when it is importable.
    wrap : callable, optional
        Applied to the subscription callback before it is subscribed (a node passes
        ``push_ros.node.guarded`` here); the subscribed callable is :attr:`on_message`.

    A rejected message (:func:`push_ros.poses.matrix_from_transform` raises) leaves the last
    good transform in place.
    """

    def __init__(self, node: Any, on_error: Callable[[ValueError], None],
                 world_frame: str = WORLD_FRAME, use_tf: bool = True,
                 wrap: Callable[[Callable[[TransformStamped], None]],
                                Callable[[TransformStamped], None]] | None = None) -> None:
        self.world_frame = world_frame
        self._on_error = on_error
        self._matrix: np.ndarray | None = None
        self._child_frame = ""
        self._buffer = self._listener = None
        if use_tf and tf2_ros is not None:
            self._buffer = tf2_ros.Buffer()
            self._listener = tf2_ros.TransformListener(self._buffer, node)
        self.on_message = self._on_msg if wrap is None else wrap(self._on_msg)
        node.create_subscription(TransformStamped, EXTRINSICS_TOPIC, self.on_message,
                                 LATCHED_QOS)

    @property
    def source(self) -> str:
        """``tf2 + topic`` or ``topic``: which sources are in use."""
        return "tf2 + topic" if self._buffer is not None else "topic"

    def _on_msg(self, msg: TransformStamped) -> None:
        try:
            self._matrix = matrix_from_transform(msg)
        except ValueError as exc:
            self._on_error(exc)
            return
        self._child_frame = msg.child_frame_id

    def lookup(self, camera_frame: str) -> tuple[np.ndarray | None, str]:
        """``(T_world_camera or None, child frame it is for)``.

        tf2 first (for exactly ``camera_frame``), then the latest latched message (for its
        ``child_frame_id``, which the caller compares with the image frame).
        """
        if self._buffer is not None:
            from rclpy.time import Time

            try:
                tf = self._buffer.lookup_transform(self.world_frame, camera_frame, Time())
                return matrix_from_transform(tf), camera_frame
            except (tf2_ros.TransformException, ValueError):  # not (yet) in tf: the topic
                pass
        return self._matrix, self._child_frame
