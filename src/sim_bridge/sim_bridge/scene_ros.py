"""The scene's ROS endpoints of ``sim_bridge_node`` (composed by the node; no physics here):
camera frames, extrinsics, ``/clock``, ground truth, ``pusher/executed`` / ``pusher/refused``,
the monitor stream and the optional tf. Topics and QoS: the topic table in
docs/INTERFACES.md. Every method may be called from any thread (rclpy publishers are thread-safe)
and publishes nothing once the node is closing."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import Path
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import CameraInfo, Image

from push_ros.frames import CAMERA_FRAME, PUSHER_FRAME, WORLD_FRAME
from push_ros.images import camera_info_msg, depth_image_msg, rgb_image_msg
from push_ros.node import ThrottledLog
from push_ros.paths import path_from_points
from push_ros.poses import pose_stamped_msg, transform_msg
from push_ros.qos import CLOCK_QOS, LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS
from push_ros.refusal import refusal_msg
from push_ros.stamps import stamp_from_seconds
from push_ros.tf import tf_publisher
from sim_bridge.worker import Timeline
from sim_bridge.world import Frame, PushWorld

__all__ = ["Capture", "SceneEndpoints"]


@dataclass(frozen=True)
class Capture:
    """Messages describing the scene at one published time ``time`` (s)."""

    rgb: Image
    depth: Image
    info: CameraInfo
    object_pose: PoseStamped
    pusher_xy: np.ndarray
    time: float
    frame: Frame | None = None  # the rendered frame (its clean images make still frames)


class SceneEndpoints:
    """Publishers of the scene and their message conversion.

    Parameters
    ----------
    node : rclpy.node.Node
    timeline : Timeline
        Published time = ``epoch + sim_time`` (``/clock`` never goes back).
    closing : callable
        True once the node is being destroyed.
    frames : callable
        ``frames(capture)``: the captures to publish for one publication (fault injection).
    log : push_ros.node.ThrottledLog
        Where a monitor frame that could not be published is reported.
    """

    def __init__(self, node: Any, timeline: Timeline, closing: Callable[[], bool],
                 frames: Callable[[Capture], list[Capture]], log: ThrottledLog) -> None:
        self._node, self.timeline, self._closing, self._frames = node, timeline, closing, frames
        self._log = log
        pub = node.create_publisher
        self.pub_rgb = pub(Image, "camera/color/image_raw", SENSOR_QOS)
        self.pub_depth = pub(Image, "camera/aligned_depth_to_color/image_raw", SENSOR_QOS)
        self.pub_info = pub(CameraInfo, "camera/color/camera_info", SENSOR_QOS)
        self.pub_extrinsics = pub(TransformStamped, "camera/color/extrinsics", LATCHED_QOS)
        self.pub_clock = pub(ClockMsg, "/clock", CLOCK_QOS)
        self.pub_pose = pub(PoseStamped, "sim/object_pose", RELIABLE_QOS)
        self.pub_executed = pub(Path, "pusher/executed", RELIABLE_QOS)
        self.pub_refused = pub(DiagnosticStatus, "pusher/refused", RELIABLE_QOS)
        self.pub_monitor = pub(Image, "sim/monitor/image_raw", SENSOR_QOS)
        self.pub_monitor_info = pub(CameraInfo, "sim/monitor/camera_info", SENSOR_QOS)
        self._tf = tf_publisher(node)
        self._tf_static = tf_publisher(node, static=True)
        #: Called with each published frame's time after its messages (arm mode: the joint
        #: state at that time, so a self-filter finds one for every frame).
        self.after_frame: Callable[[float], None] | None = None

    def publish(self, publisher: Any, msg: Any) -> None:
        """``publisher.publish(msg)`` unless the node is closing."""
        if not self._closing():
            publisher.publish(msg)

    # ---- conversion ------------------------------------------------------------------------
    def capture(self, world: PushWorld) -> Capture:
        """Render and convert one frame with the ground truth at its time (worker thread)."""
        frame = world.render()
        return self._convert(frame, world.camera_matrix, world.object_pose(),
                             np.asarray(world.pusher_position(), dtype=float))

    def still(self, previous: Capture, world: PushWorld) -> Capture:
        """A still frame of the resting scene (:meth:`PushWorld.still_frame` of
        ``previous.frame``) at the timeline's current time, and ``/clock`` at it; no pybullet
        call, so only while no job runs."""
        frame = world.still_frame(previous.frame)
        capture = self._convert(frame, frame.camera_matrix, frame.object_pose, previous.pusher_xy)
        self.clock(capture.time)
        return capture

    def _convert(self, frame: Frame, camera_matrix: np.ndarray, object_pose: np.ndarray,
                 pusher_xy: np.ndarray) -> Capture:
        t = self.timeline.at(frame.stamp)
        stamp = stamp_from_seconds(t)
        height, width = frame.depth.shape
        return Capture(
            rgb=rgb_image_msg(frame.rgb, stamp), depth=depth_image_msg(frame.depth, stamp),
            info=camera_info_msg(camera_matrix, width, height, stamp),
            object_pose=pose_stamped_msg(object_pose, stamp), pusher_xy=pusher_xy, time=t,
            frame=frame)

    def executed(self, start: Any, end: Any, t_start: float, t_end: float) -> Path:
        """``pusher/executed``: the pusher at the push's start and end (world, m; times s)."""
        return path_from_points(np.array([start, end], dtype=float),
                                [stamp_from_seconds(t_start), stamp_from_seconds(t_end)])

    # ---- publishing ------------------------------------------------------------------------
    def clock(self, time: float) -> None:
        """``/clock`` at ``time`` (s) if it is later than the last one."""
        if not self._closing():
            self.timeline.advance(time, self._publish_clock)

    def _publish_clock(self, time: float) -> None:
        self.pub_clock.publish(ClockMsg(clock=stamp_from_seconds(time)))

    def frame(self, capture: Capture) -> None:
        """Publish a frame (through the fault injection), then the small reliable messages.

        Order matters: with Fast DDS (2.14, UDPv4 and shared memory alike) a small reliable
        sample published just *before* a large best-effort burst (the images) to the same
        subscriber is sometimes only delivered by the next heartbeat, up to 3 s later; after
        the burst it arrives at once. So reliable messages follow the images everywhere.
        """
        for shown in self._frames(capture):
            for publisher, msg in ((self.pub_rgb, shown.rgb), (self.pub_depth, shown.depth),
                                   (self.pub_info, shown.info)):
                self.publish(publisher, msg)
        self.publish(self.pub_pose, capture.object_pose)
        if self._tf is not None and not self._closing():
            pusher = np.eye(4)
            pusher[:2, 3] = capture.pusher_xy
            self._tf.publish(transform_msg(pusher, capture.info.header.stamp, WORLD_FRAME,
                                           PUSHER_FRAME))
        if self.after_frame is not None and not self._closing():
            self.after_frame(capture.time)

    def camera_pose(self, T_world_camera: np.ndarray, time: float) -> None:
        """The latched extrinsics (and ``/tf_static``): the camera pose in world at ``time``."""
        extrinsics = transform_msg(T_world_camera, stamp_from_seconds(time), WORLD_FRAME,
                                   CAMERA_FRAME)
        self.publish(self.pub_extrinsics, extrinsics)
        if self._tf_static is not None and not self._closing():
            self._tf_static.publish(extrinsics)

    def refusal(self, push_stamp: Any, kind: str, reason: str) -> None:
        """Answer a push on ``pusher/refused`` (:mod:`push_ros.refusal`)."""
        self.publish(self.pub_refused, refusal_msg(
            self._node.get_fully_qualified_name(), push_stamp, kind, reason,
            hardware_id="pybullet pusher"))

    def monitor(self, frame: Frame) -> None:
        """One monitor frame (worker thread, during a push). Never raises: an exception here
        would stop the physics in the middle of the push."""
        try:
            stamp = stamp_from_seconds(self.timeline.at(frame.stamp))
            height, width = frame.rgb.shape[:2]
            self.publish(self.pub_monitor, rgb_image_msg(frame.rgb, stamp))
            self.publish(self.pub_monitor_info,
                         camera_info_msg(frame.camera_matrix, width, height, stamp))
        except Exception as exc:  # e.g. the context shut down meanwhile: the push goes on
            self._log.warning("monitor", f"monitor frame not published: "
                                         f"{type(exc).__name__}: {exc}")
