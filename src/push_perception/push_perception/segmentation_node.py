"""``segmentation_node``: object mask, pose and outline from the RGB-D camera.

Role: pairs colour, depth and camera_info by stamp (:class:`push_perception.inputs.FrameSync`),
segments with :class:`push_perception.model.Segmenter` and measures with
:class:`push_perception.tracker.EpisodeTracker`; publishes the mask, the pose (stamped with the
frame) and, once per episode, the latched outline. Extrinsics:
:class:`push_ros.extrinsics.CameraExtrinsics`. After a restart it re-anchors to the estimator's
latched outline and estimate (:class:`push_perception.inputs.AnchorWait`); ``~/reset`` starts
an episode, skipping frames taken before it. Input rules:
:mod:`push_perception.inputs`; parameters: :mod:`push_perception.config`.

With the robot in the camera's view (``robot_filter.enabled``, read-only, default false) it also
subscribes ``/joint_states`` and ``/robot_description`` (or loads ``robot_filter.description_file``)
and publishes ``perception/occlusion`` (:class:`push_perception.robot_inputs.RobotInputs`): each
frame's robot pixels come from the robot's model posed by the joint state at the frame's stamp
(:mod:`push_perception.robot_filter`); they are cleared before the CNN and never object pixels;
the pose comes from the visible part and a frame in which the robot hides more than
``max_occluded`` of the object gives no pose (outcome ``occluded``); a frame whose robot pixels
cannot be computed (no model, no or stale joint state) is refused with the reason, never
measured as if no robot were there (docs/design/arm-in-view.md). Without it, nothing changes.

Invariants: a refused message never enters the stamp matching and never replaces the latched
extrinsics; a frame without a pose publishes no pose; work per frame is bounded; no exception
leaves a callback (:class:`push_ros.health.NodeHealth` on ``/diagnostics``); it never imports the
simulator.

Topics, services and parameters: docs/INTERFACES.md; the pipeline and re-anchoring:
docs/design/perception.md, docs/design/faults.md and docs/design/node-runtime.md.
"""

from __future__ import annotations

import math
import statistics
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import cv2
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_srvs.srv import Trigger

from push_perception.config import NODE_NAME, PARAMETERS, SegmentationParams
from push_perception.inputs import (
    COLOR_ENCODINGS,
    DEPTH_ENCODINGS,
    REFUSAL_KINDS,
    AnchorWait,
    FrameSync,
    InputError,
    check_depth_coverage,
    check_frame_ids,
    check_frame_inputs,
    check_stamp,
    rgb_from_color,
)
from push_perception.outline import MAX_OUTLINE_POINTS
from push_perception.perception_config import PerceptionError
from push_perception.robot_filter import segment
from push_perception.robot_inputs import RobotInputs
from push_perception.tracker import EpisodeTracker, Measurement
from push_ros.extrinsics import CameraExtrinsics
from push_ros.frames import OBJECT_FRAME, WORLD_FRAME
from push_ros.health import NodeHealth
from push_ros.images import (
    camera_matrix_from_info,
    check_image_layout,
    depth_to_metres,
    image_to_array,
    mask_image_msg,
)
from push_ros.node import declare_config, parameter_values, run_node
from push_ros.outline import outline_cloud_msg, outline_from_cloud
from push_ros.poses import check_frame, pose_with_covariance_msg, xytheta_from_pose
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS
from push_ros.stamps import episode_boundary, seconds_from_stamp

__all__ = ["PARAMETERS", "SegmentationNode", "SegmentationParams", "main"]

#: Seconds between two log lines of the same kind (every event is counted on /diagnostics).
LOG_THROTTLE_S = 1.0
#: Period of the regular /diagnostics message, seconds of steady time.
DIAGNOSTICS_PERIOD_S = 1.0
#: Frames whose processing time enters the median latency on /diagnostics.
LATENCY_WINDOW = 100
#: Outcomes of a frame that gave no pose (``PerceptionError`` kinds of the measurement).
OUTCOME_KINDS = ("empty_mask", "out_of_view", "few_pixels", "no_depth", "fragmented",
                 "too_large", "occluded", "bad_input")
#: The node's counters, all on /diagnostics from the first status on.
COUNTERS = ("frames", "poses", "resets", "previous_episode", "waiting_for_anchor", "anchored",
            *OUTCOME_KINDS, *(f"refused_{kind}" for kind in REFUSAL_KINDS))


def _decode(kind: str, what: str, decode: Callable[[Any], Any], msg: Any) -> Any:
    """``decode(msg)``; a codec's ``ValueError`` becomes an :class:`InputError` of ``kind``."""
    try:
        return decode(msg)
    except InputError:
        raise
    except ValueError as exc:
        raise InputError(kind, f"{what}: {exc}") from None


class SegmentationNode(Node):
    """ROS wrapper of the perception pipeline; see the module docstring.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        At construction, for an invalid parameter or unreadable weights.
    """

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.health = NodeHealth(self, "perception", "rgbd_camera", COUNTERS, LOG_THROTTLE_S,
                                 on_error=self._on_callback_error)
        self._params = declare_config(self, PARAMETERS, SegmentationParams.from_values)

        import torch

        from push_perception.model import Segmenter

        torch.set_num_threads(self._params.torch_threads)
        cv2.setNumThreads(1)  # small images: OpenCV's thread pool only adds latency
        self._segmenter = Segmenter.load(self._params.weights or None,
                                         threshold=self._params.threshold,
                                         min_coarse_cells=self._params.min_coarse_cells)
        self._tracker = EpisodeTracker(self._params.geometry)
        self._robot_pixels = -1  # the robot's pixels in the frame being processed
        self._robot = None if self._params.robot_filter is None else RobotInputs(
            self, self._params.robot_filter, self._params.description_file, self.health)
        self._sync = FrameSync(self._params.sync_queue)
        self._anchor = AnchorWait(self._params.anchor_timeout, time.monotonic())
        self._anchor_msg: PointCloud2 | None = None  # the estimator's outline to re-publish
        self._problem = ""
        self._ok: bool | None = None
        self._latency: deque[float] = deque(maxlen=LATENCY_WINDOW)
        self._last_stamp = 0.0

        self._pub_mask = self.create_publisher(Image, "perception/mask", SENSOR_QOS)
        self._pub_pose = self.create_publisher(PoseWithCovarianceStamped,
                                               "perception/object_pose", RELIABLE_QOS)
        self._pub_outline = self.create_publisher(PointCloud2, "perception/outline",
                                                  LATCHED_QOS)
        # The guarded callables are attributes so tests can call them with real messages.
        guard = self.health.guard
        self.on_color = guard(self._on_color)
        self.on_depth = guard(self._on_depth)
        self.on_camera_info = guard(self._on_camera_info)
        self.on_reset = guard(self._on_reset)
        self.on_estimator_outline = guard(self._on_estimator_outline)
        self.on_estimate = guard(self._on_estimate)
        if self._anchor.waiting:
            self.create_subscription(PointCloud2, "estimator/outline",
                                     self.on_estimator_outline, LATCHED_QOS)
            self.create_subscription(PoseWithCovarianceStamped, "estimator/object_pose",
                                     self.on_estimate, LATCHED_QOS)
        self.create_subscription(Image, "camera/color/image_raw", self.on_color, SENSOR_QOS)
        self.create_subscription(Image, "camera/aligned_depth_to_color/image_raw",
                                 self.on_depth, SENSOR_QOS)
        self.create_subscription(CameraInfo, "camera/color/camera_info", self.on_camera_info,
                                 SENSOR_QOS)
        self._extrinsics = CameraExtrinsics(
            self, lambda exc: self._fail(InputError("extrinsics", f"rejected camera extrinsics: "
                                                    f"{exc}"), "camera extrinsics"),
            wrap=guard)
        self.on_extrinsics = self._extrinsics.on_message
        self.create_service(Trigger, "~/reset", self.on_reset)
        self.create_timer(DIAGNOSTICS_PERIOD_S, guard(self._publish_diagnostics),
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"segmentation node ready (use_sim_time="
            f"{self.get_parameter('use_sim_time').value}, torch threads "
            f"{self._params.torch_threads}, weights {self._params.weights or 'bundled'})")

    # ---- inputs ------------------------------------------------------------------------------
    def _on_callback_error(self, name: str, message: str) -> None:
        """An exception reached the guard (counted and logged by it): report it."""
        self._problem = f"callback_errors: {name}: {message}"
        self._ok = False
        self._publish_diagnostics()

    def _on_color(self, msg: Image) -> None:
        self._accept("rgb", msg, "color", lambda m: check_image_layout(m, COLOR_ENCODINGS))

    def _on_depth(self, msg: Image) -> None:
        self._accept("depth", msg, "depth", lambda m: check_image_layout(m, DEPTH_ENCODINGS))

    def _on_camera_info(self, msg: CameraInfo) -> None:
        self._accept("info", msg, "camera_info", camera_matrix_from_info)

    def _accept(self, stream: str, msg: Any, kind: str, check: Callable[[Any], Any]) -> None:
        """Check one message (its codec's rules, then its stamp); a refused one never reaches
        the stamp matching. Process a frame once its three messages are in."""
        try:
            check(msg)
            key = check_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        except InputError as exc:
            self._fail(exc, f"{stream} message")
            return
        except ValueError as exc:
            self._fail(InputError(kind, str(exc)), f"{stream} message")
            return
        frame, missing = self._sync.add(stream, key, msg)
        for sec, nanosec in missing:
            self._fail(InputError("missing_camera_info", f"colour and depth at t="
                                  f"{sec + nanosec * 1e-9:.3f} s have no camera_info with the "
                                  "same stamp; frame dropped"), "frame")
        if frame is not None:
            self._process(*frame)

    def _on_estimator_outline(self, msg: PointCloud2) -> None:
        try:
            points, normals = outline_from_cloud(msg, OBJECT_FRAME, MAX_OUTLINE_POINTS)
            self._anchor.offer_outline(points, normals, seconds_from_stamp(msg.header.stamp),
                                       msg)
        except ValueError as exc:
            self._fail(InputError("estimator_outline", str(exc)), "estimator/outline")

    def _on_estimate(self, msg: PoseWithCovarianceStamped) -> None:
        try:
            check_frame(msg.header.frame_id, WORLD_FRAME)
            self._anchor.offer_estimate(seconds_from_stamp(msg.header.stamp),
                                        float(xytheta_from_pose(msg.pose.pose)[2]))
        except ValueError as exc:
            self._fail(InputError("estimator_pose", str(exc)), "estimator/object_pose")

    # ---- processing --------------------------------------------------------------------------
    def _process(self, rgb_msg: Image, depth_msg: Image, info: CameraInfo) -> None:
        started = time.perf_counter()
        stamp = rgb_msg.header.stamp
        action = self._anchor.admit(seconds_from_stamp(stamp), self._tracker.outline is not None,
                                    time.monotonic())
        if action in ("previous", "wait"):
            self.health.count("previous_episode" if action == "previous"
                              else "waiting_for_anchor")
            return
        if action == "anchor":
            self._start_anchor()
        self.health.count("frames")
        self._robot_pixels = -1
        try:
            meas = self._measure(rgb_msg, depth_msg, info)
        except PerceptionError as exc:
            self._fail(exc, "frame")
            if self._robot is not None:
                self._robot.report(stamp, exc.kind, exc.occluded_share, self._robot_pixels,
                                   str(exc))
            return
        if self._robot is not None:
            self._robot.report(stamp, "pose", meas.occluded_share, self._robot_pixels)
        self._publish_measurement(meas, stamp)
        self._latency.append(time.perf_counter() - started)
        self._last_stamp = seconds_from_stamp(stamp)
        self._problem = ""
        if self._ok is not True:
            self._ok = True
            self._publish_diagnostics()

    def _start_anchor(self) -> None:
        outline, (stamp, yaw) = self._anchor.outline, self._anchor.estimate
        self._tracker.anchor(outline.points, outline.normals, yaw)
        self._anchor_msg = outline.payload
        self.get_logger().info(
            f"re-anchoring to the running episode: the estimator's outline of "
            f"t={outline.stamp:.3f} s and estimate of t={stamp:.3f} s (yaw {yaw:.4f} rad)")

    def _measure(self, rgb_msg: Image, depth_msg: Image, info: CameraInfo) -> Measurement:
        """The frame's measurement; raises :class:`InputError` (refused) or
        :class:`PerceptionError` (no pose)."""
        rgb = _decode("color", "colour image",
                      lambda m: rgb_from_color(image_to_array(m), m.encoding), rgb_msg)
        depth = _decode("depth", "depth image", depth_to_metres, depth_msg)
        check_depth_coverage(depth)
        k = _decode("camera_info", "camera_info", camera_matrix_from_info, info)
        check_frame_inputs(rgb.shape[1::-1], depth.shape[::-1], (info.width, info.height))
        frame = rgb_msg.header.frame_id
        extrinsics, extrinsics_frame = self._extrinsics.lookup(frame)
        if extrinsics is None:
            raise InputError("no_extrinsics", "no camera extrinsics yet (tf2 world -> "
                             f"{frame[:64]!r} or the latched camera/color/extrinsics)")
        check_frame_ids(frame, depth_msg.header.frame_id, extrinsics_frame)
        robot = None  # the robot's pixels (robot_filter.enabled), or no robot in view
        if self._robot is not None:
            robot = self._robot.pixels(seconds_from_stamp(rgb_msg.header.stamp), k, extrinsics,
                                       depth)
            self._robot_pixels = int(robot.mask.sum())
        seg = segment(self._segmenter, rgb, depth, k, extrinsics,
                      None if robot is None else robot.mask)
        if self._params.publish_mask:
            self._pub_mask.publish(mask_image_msg(seg.mask, rgb_msg.header.stamp, frame))
        if seg.box is None:
            raise PerceptionError("empty_mask", "the CNN found no object in the frame")
        return self._tracker.update(seg.mask, depth, k, extrinsics,
                                    *(() if robot is None else (robot.mask, robot.cover)))

    def _publish_measurement(self, meas: Measurement, stamp: Any) -> None:
        at = (f"t={seconds_from_stamp(stamp):.3f} s: object at ({meas.pose[0]:.4f}, "
              f"{meas.pose[1]:.4f}) m")
        if meas.anchored:  # the episode's outline, unchanged (same stamp and points)
            self._pub_outline.publish(self._anchor_msg)
            self.health.count("anchored")
            self.get_logger().info(f"re-anchored at {at}, yaw {meas.pose[2]:.4f} rad in the "
                                   f"episode frame (match cost {1e3 * meas.match_cost:.2f} mm)")
        elif meas.is_reference:  # the outline first: consumers need it for this pose
            points, normals = self._tracker.outline
            self._pub_outline.publish(outline_cloud_msg(points, normals, stamp))
            if self._anchor_msg is not None:
                self.get_logger().warning("the estimator's outline did not match the first "
                                          "frame: a new episode reference instead")
                self._anchor_msg = None
            self.get_logger().info(f"new episode reference at {at}, area "
                                   f"{meas.area * 1e4:.1f} cm^2, outline of {len(points)} points")
        self._pub_pose.publish(pose_with_covariance_msg(meas.pose, meas.covariance, stamp))
        self.health.count("poses")

    def _fail(self, exc: PerceptionError, what: str) -> None:
        """Count, log (throttled) and report a refused input (``refused_<kind>``) or a frame
        that gave no pose (its outcome kind)."""
        if isinstance(exc, InputError):
            key, text = f"refused_{exc.kind}", self.health.refuse(what, str(exc), exc.kind)
        else:
            key, text = exc.kind, str(exc)
            self.health.count(key)
            self.health.log.warning(key, f"no pose ({key}): {text}")
        self._problem = f"{key}: {text}"
        if self._ok is not False:
            self._ok = False
            self._publish_diagnostics()

    # ---- services and diagnostics ------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        try:
            params = SegmentationParams.from_values(parameter_values(self, PARAMETERS))
        except ValueError as exc:
            response.success, response.message = False, f"reset refused: {exc}"
            self.get_logger().error(response.message)
            return response
        self._params = params
        self._tracker = EpisodeTracker(params.geometry)
        # an explicit new episode: no re-anchoring; frames taken before it are skipped
        self._anchor.reset(episode_boundary(-math.inf, self.get_clock()))
        self._anchor_msg = None
        self.health.count("resets")
        response.success = True
        response.message = "new episode: the next good frame becomes the reference"
        self.get_logger().info(f"~/reset: {response.message}")
        return response

    def _publish_diagnostics(self) -> None:
        if self._ok is None:
            level, message = DiagnosticStatus.OK, "waiting for camera frames"
        elif self._ok:
            level, message = DiagnosticStatus.OK, "tracking"
        else:
            level = DiagnosticStatus.WARN
            message = f"no pose for the last frame: {self._problem}"
        latency = (f"{1e3 * statistics.median(self._latency):.1f}" if self._latency else "")
        self.health.publish(level, message, {
            "last_problem": self._problem, "latency_ms_median": latency,
            "has_reference": str(self._tracker.outline is not None).lower(),
            "last_stamp": f"{self._last_stamp:.6f}",
            "robot_filter": "off" if self._robot is None else "on",
            "occluded_share": "" if self._robot is None else f"{self._robot.last_share:.4f}"})


def main(args: list[str] | None = None) -> None:
    """Entry point of ``segmentation_node`` (``ros2 run`` / ``pushbot run``)."""
    run_node(SegmentationNode, NODE_NAME, args)


if __name__ == "__main__":
    main()
