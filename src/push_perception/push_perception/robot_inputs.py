"""The self-filter's endpoints of ``segmentation_node``: joint states, robot model, occlusion.

Created by the node when ``robot_filter.enabled`` is true (docs/design/arm-in-view.md):

- ``/joint_states`` (sensor_msgs/JointState, in, :data:`push_ros.qos.JOINT_STATE_QOS`): every
  message kept by stamp (:class:`push_perception.robot_filter.JointStateBuffer`); a bad one
  (non-finite stamp, names and positions of different lengths, more than
  ``robot_filter.MAX_JOINTS`` joints) is refused (``refused_joint_states``);
- ``/robot_description`` (std_msgs/String, in, latched), unless
  ``robot_filter.description_file`` names a URDF file (read at start-up; a file that does not
  load stops the start-up): a URDF that does not load is refused
  (``refused_robot_description``) and frames are refused ``no_robot_model`` until a good one
  arrives;
- ``perception/occlusion`` (diagnostic_msgs/DiagnosticStatus, out, reliable): one per processed
  frame (:mod:`push_ros.occlusion`).

The rules are ROS-free (:mod:`push_perception.robot_filter`); this module converts the messages
and publishes.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from push_core.robot_view import MAX_URDF_CHARS
from push_perception.robot_filter import MAX_JOINTS, RobotFilter, RobotFilterConfig, RobotPixels
from push_ros.health import NodeHealth
from push_ros.occlusion import occlusion_msg
from push_ros.qos import JOINT_STATE_QOS, LATCHED_QOS, RELIABLE_QOS
from push_ros.stamps import seconds_from_stamp

__all__ = ["OCCLUSION_TOPIC", "RobotInputs"]

OCCLUSION_TOPIC = "perception/occlusion"


class RobotInputs:
    """The robot's model, its joint states and the occlusion report of one node.

    Parameters
    ----------
    node : rclpy.node.Node
    cfg : RobotFilterConfig
    description_file : str
        A URDF file to load now; "" = subscribe ``/robot_description``.
    health : NodeHealth
        The node's health (guard and refusals).

    Raises
    ------
    ValueError
        ``description_file`` cannot be read or does not load.
    """

    def __init__(self, node: Any, cfg: RobotFilterConfig, description_file: str,
                 health: NodeHealth) -> None:
        self.filter = RobotFilter(cfg)
        self._node, self._health = node, health
        self.last_share = math.nan
        self._urdf = ""
        self.on_joint_state = health.guard(self._on_joint_state)
        self.on_description = health.guard(self._on_description)
        self._pub = node.create_publisher(DiagnosticStatus, OCCLUSION_TOPIC, RELIABLE_QOS)
        node.create_subscription(JointState, "/joint_states", self.on_joint_state,
                                 JOINT_STATE_QOS)
        if description_file:
            try:
                text = Path(description_file).read_text(encoding="utf-8")[:MAX_URDF_CHARS + 1]
            except (OSError, UnicodeDecodeError) as exc:
                raise ValueError(f"parameter robot_filter.description_file: {exc}") from None
            if not self.filter.set_model(text):
                raise ValueError(f"parameter robot_filter.description_file: "
                                 f"{self.filter.model_error}")
        else:
            node.create_subscription(String, "/robot_description", self.on_description,
                                     LATCHED_QOS)

    def _on_joint_state(self, msg: JointState) -> None:
        try:
            if len(msg.name) > MAX_JOINTS:
                raise ValueError(f"{len(msg.name)} joints (at most {MAX_JOINTS})")
            self.filter.joints.add(seconds_from_stamp(msg.header.stamp), list(msg.name),
                                   list(msg.position), list(msg.velocity))
        except ValueError as exc:
            self._health.refuse("/joint_states", str(exc), "joint_states")

    def _on_description(self, msg: String) -> None:
        if msg.data == self._urdf:  # re-latched (the simulator's reset): nothing new
            return
        self._urdf = msg.data
        if self.filter.set_model(msg.data):
            robot = self.filter.robot
            self._node.get_logger().info(f"robot model loaded: {len(robot.joint_names)} joints, "
                                         f"{robot.triangle_count} triangles")
        else:
            self._health.refuse("/robot_description", self.filter.model_error,
                                "robot_description")

    def pixels(self, stamp: float, camera_matrix: Any, t_world_camera: Any, depth: Any
               ) -> RobotPixels:
        """The robot's pixels of the frame stamped ``stamp`` (s); raises
        :class:`push_perception.inputs.InputError` when they cannot be computed."""
        return self.filter.pixels(stamp, camera_matrix, t_world_camera, depth)

    def report(self, stamp: Any, outcome: str, share: float, robot_pixels: int,
               reason: str = "") -> None:
        """Publish the frame's ``perception/occlusion`` (``stamp``: its header stamp)."""
        self.last_share = share
        self._pub.publish(occlusion_msg(self._node.get_fully_qualified_name(), stamp, outcome,
                                        share, robot_pixels, reason))
