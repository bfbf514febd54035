"""What push_executor_node hears of the camera, the object and the episode (its ROS inputs
besides the arm's), composed by the node.

Subscriptions (docs/design/arm.md; docs/design/cycle.md):

- ``camera/color/camera_info`` (sensor_msgs/CameraInfo, sensor QoS): K and the image size;
- the camera pose ``T_world_camera``: tf2 where installed, else the latched
  ``camera/color/extrinsics`` (:class:`push_ros.extrinsics.CameraExtrinsics`);
- ``perception/outline`` (sensor_msgs/PointCloud2, latched): the object's outline, object frame;
- ``estimator/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, latched): its pose;
- ``planner/status`` (diagnostic_msgs/DiagnosticStatus, latched): the episode's state; the
  episode is over (the arm may park) when its ``state`` is ``reached``, ``failed`` or ``left``,
  or no goal is set.

:meth:`SceneInputs.view` builds the :class:`push_executor.clearance.ClearView` of one push from
the latest of each, or says why it cannot (no camera yet, no object estimate, no robot
image): the push then ends parked, as before. Invalid messages are refused with a reason
(``refuse(topic, reason)``) and change nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from numpy.typing import NDArray
from sensor_msgs.msg import CameraInfo, PointCloud2

from push_executor.clearance import CameraView, ClearView, object_region
from push_ros.extrinsics import CameraExtrinsics
from push_ros.images import camera_matrix_from_info
from push_ros.outline import outline_from_cloud
from push_ros.poses import pose_with_covariance_from_msg
from push_ros.qos import LATCHED_QOS, SENSOR_QOS, latched_reader_qos

__all__ = ["OVER_STATES", "SceneInputs"]

#: ``planner/status`` states of an episode that pushes no more.
OVER_STATES = ("reached", "failed", "left")
#: A robot image at a camera: ``factory(camera) -> robot_mask(q)``.
RobotMaskFactory = Callable[[CameraView], Callable[[NDArray[np.float64]], NDArray[np.bool_]]]


class SceneInputs:
    """The node's camera, object and episode inputs (module docstring).

    Parameters
    ----------
    node : rclpy.node.Node
    guard : callable
        Wraps each callback (the node's health guard: no exception escapes).
    refuse : callable
        ``refuse(topic, reason)``: count and report an invalid message.
    clear : dict
        The ``clear.*`` parameters without the prefix: ``margin``, ``turn``,
        ``object_height``, ``distance``, ``rise``, ``scale``.
    on_episode_over : callable
        Called when ``planner/status`` turns to an episode that pushes no more.
    """

    def __init__(self, node: Any, guard: Callable[..., Any], refuse: Callable[[str, str], None],
                 clear: dict[str, float], on_episode_over: Callable[[], None]) -> None:
        self._refuse, self._clear = refuse, dict(clear)
        self._on_over = on_episode_over
        self.camera_matrix: NDArray[np.float64] | None = None
        self.size = (0, 0)
        self.camera_frame = ""
        self.outline: NDArray[np.float64] | None = None
        self.pose: NDArray[np.float64] | None = None
        self.episode_over = True
        self.extrinsics = CameraExtrinsics(node, lambda exc: refuse("camera/color/extrinsics",
                                                                    str(exc)), wrap=guard)
        for msg_type, topic, callback, qos in (
                (CameraInfo, "camera/color/camera_info", self._on_info, SENSOR_QOS),
                (PointCloud2, "perception/outline", self._on_outline, LATCHED_QOS),
                (PoseWithCovarianceStamped, "estimator/object_pose", self._on_pose,
                 latched_reader_qos(1)),
                (DiagnosticStatus, "planner/status", self._on_status, LATCHED_QOS)):
            node.create_subscription(msg_type, topic, guard(callback), qos)

    def _on_info(self, msg: CameraInfo) -> None:
        try:
            self.camera_matrix = camera_matrix_from_info(msg)
        except ValueError as exc:
            return self._refuse("camera/color/camera_info", str(exc))
        self.size, self.camera_frame = (int(msg.width), int(msg.height)), msg.header.frame_id
        return None

    def _on_outline(self, msg: PointCloud2) -> None:
        try:
            points, _ = outline_from_cloud(msg)
        except ValueError as exc:
            return self._refuse("perception/outline", str(exc))
        if len(points) < 3:
            return self._refuse("perception/outline", f"{len(points)} points")
        self.outline = np.asarray(points, dtype=float)
        return None

    def _on_pose(self, msg: PoseWithCovarianceStamped) -> None:
        try:
            self.pose = np.asarray(pose_with_covariance_from_msg(msg).pose, dtype=float)
        except ValueError as exc:
            self._refuse("estimator/object_pose", str(exc))

    def _on_status(self, msg: DiagnosticStatus) -> None:
        values = {kv.key: kv.value for kv in msg.values}
        over = values.get("state", "") in OVER_STATES or not values.get("goal", "")
        was, self.episode_over = self.episode_over, over
        if over and not was:
            self._on_over()

    def view(self, contact: NDArray[np.float64], end: NDArray[np.float64],
             robot: RobotMaskFactory | None) -> tuple[ClearView | None, str]:
        """The clear view of a push (contact, end: (2,) m), or ``(None, why not)``."""
        if robot is None:
            return None, "no robot image"
        if self.camera_matrix is None:
            return None, "no camera_info yet"
        t_world_camera, frame = self.extrinsics.lookup(self.camera_frame)
        if t_world_camera is None or (self.camera_frame and frame != self.camera_frame):
            return None, "no camera extrinsics yet"
        if self.outline is None or self.pose is None:
            return None, "no object estimate yet"
        c = self._clear
        try:
            camera = CameraView(self.camera_matrix, *self.size, t_world_camera).scaled(
                c["scale"])
            region = object_region(self.outline, self.pose, contact, end, c["margin"],
                                   c["turn"])
            return ClearView(camera, region, c["object_height"], robot(camera), c["distance"],
                             c["rise"]), ""
        except ValueError as exc:
            return None, f"no clear view: {exc}"
