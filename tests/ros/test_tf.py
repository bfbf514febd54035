"""push_ros.tf: the optional tf publisher, written once."""

from __future__ import annotations

from typing import Any

import pytest

from push_ros import tf

pytestmark = pytest.mark.ros


def test_tf_publisher_exists_only_where_tf2_msgs_does(ros_context: Any) -> None:
    from rclpy.node import Node

    node = Node("tf_probe", context=ros_context)
    try:
        assert tf.tf_publisher(node, enabled=False) is None
        pub = tf.tf_publisher(node)
        if not tf.tf_available():
            assert pub is None
            with pytest.raises(RuntimeError, match="tf2_msgs"):
                tf.TransformPublisher(node)
        else:  # pragma: no cover - full ROS install
            assert pub.publisher.topic_name == "/tf"
            assert tf.tf_publisher(node, static=True).publisher.topic_name == "/tf_static"
    finally:
        node.destroy_node()
