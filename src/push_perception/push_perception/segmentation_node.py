"""``segmentation_node``: object mask, pose and outline from the RGB-D camera (SPEC 2, steps 1-2).

A thin ROS wrapper: the CNN is :class:`push_perception.model.Segmenter`, the geometry
(position, relative orientation, outline, covariance) :class:`push_perception.core.EpisodeTracker`;
every message is converted by the codecs of :mod:`push_ros` (images and camera info:
:mod:`push_ros.images`; pose: :mod:`push_ros.poses`; outline: :mod:`push_ros.outline`), QoS,
parameters, logging and ``main()`` are :mod:`push_ros`'s too. It never imports the simulator
(``sim_bridge``, pybullet): it runs on a robot with a RealSense driver.

Subscriptions (names relative and remappable; "sensor" = ``qos_profile_sensor_data``,
"latched" = reliable + transient local, depth 1):

- ``camera/color/image_raw`` (sensor_msgs/Image, ``rgb8`` or ``bgr8``; sensor)
- ``camera/aligned_depth_to_color/image_raw`` (sensor_msgs/Image, ``32FC1`` metres or
  ``16UC1`` millimetres, aligned to colour; sensor)
- ``camera/color/camera_info`` (sensor_msgs/CameraInfo; sensor). Colour, depth and camera
  info are matched by identical header stamps (the last ``sync_queue`` stamps are kept).
- Camera extrinsics ``T_world_camera`` (:class:`push_ros.extrinsics.CameraExtrinsics`): from
  tf2 where ``tf2_ros`` is importable (a full ROS install: ``/tf_static``, lookup ``world`` ->
  the image's frame, e.g. a static transform publisher for the camera mount), otherwise, and
  whenever tf2 has no such transform, from the latched ``camera/color/extrinsics``
  (geometry_msgs/TransformStamped, ``world`` -> ``camera_color_optical_frame``; latched; the
  pip install's fallback, published by ``sim_bridge_node``). The latest one is used.
- ``estimator/outline`` (sensor_msgs/PointCloud2, ``object``; latched) and
  ``estimator/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``; latched): the
  episode's outline and the last estimate, read only to *re-anchor* after a restart (below).
- ``/clock`` only with ``use_sim_time`` true. The default is false (a real camera stamps with
  wall time); the simulation (``pushbot demo``, the graph runner, the bringup YAML) sets it.

Publications:

- ``perception/mask`` (sensor_msgs/Image ``mono8``, 255 = object, frame of the colour image;
  sensor): every frame that was segmented, also when the mask is empty.
- ``perception/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, frame ``world``;
  reliable, depth 10): position = area centroid of the top-down footprint (the ``object``
  frame origin), yaw = orientation relative to the first frame of the episode (continuous for
  symmetric objects: the symmetric equivalent closest to the previous one); covariance over
  (x, y, z, roll, pitch, yaw) with the model of :mod:`push_perception.core` for x, y, yaw and
  ``UNMEASURED_VARIANCE`` (1e6) for z, roll, pitch. Stamp = the camera frame's stamp.
- ``perception/outline`` (sensor_msgs/PointCloud2, float32 ``x, y, z, normal_x, normal_y,
  normal_z``, frame ``object``; latched): the outline counter-clockwise (a closed polyline,
  about ``outline_spacing`` apart) with outward unit normals, z = 0. Published once per
  episode, from its first good frame.
- ``/diagnostics`` (diagnostic_msgs/DiagnosticArray; reliable): one status named
  ``<node>: perception``; OK after a frame that gave a pose, WARN after one that did not
  (message = the reason); values: counters per outcome, last error, median latency, whether
  the episode has a reference. At 1 Hz (steady clock) and whenever the level changes.

Restart recovery (re-anchoring; docs/ARCHITECTURE.md, "Faults and recovery"). A node started
while an episode runs (a crash and restart) must not take its first frame as a new yaw 0: the
estimator and the goal live in the episode frame. Until its first ``~/reset`` the node waits
at most ``anchor_timeout`` seconds (steady clock) from start-up for the estimator's latched
``estimator/outline`` and ``estimator/object_pose`` (the estimate stamped no earlier than the
outline), skipping frames meanwhile (``waiting_for_anchor``). With both, the next good frame is
matched against that outline (:meth:`push_perception.core.EpisodeTracker.anchor`: rotation
search near the estimate's yaw, which picks the symmetric equivalent), its yaw in the episode
frame is reported and the estimator's outline message is re-published unchanged on
``perception/outline`` (same stamp and points: the estimator and the planner see the same
outline); ``anchored`` counts it. An anchor that does not match the frame (chamfer cost above
``ANCHOR_MAX_COST``, 3 mm: another object) is dropped, and so is the wait when nothing arrives in
time (a fresh graph): the frame becomes a new reference as usual. ``~/reset`` ends the wait
(an explicit new episode). ``anchor_timeout: 0.0`` disables re-anchoring.

Services: ``~/reset`` (std_srvs/srv/Trigger): new episode. The next good frame becomes the
orientation reference and its outline is published (the previous outline stays latched
until then). Frames with the stamp of the newest frame processed before the reset belong to
the previous episode (the simulator re-publishes its last frame, same stamp, while idle; older
frames cannot follow a newer one on a topic): they are skipped without a pose and counted
(``previous_episode``), so a repeated frame of the old scene cannot become the new episode's
reference. Older stamps (a restarted clock) are processed. The geometry
parameters are re-read and validated; invalid values refuse the reset and keep the old ones.

Bad input never stops the node and never produces a pose for that frame; each class is
logged (at most once per second per class, with the number suppressed) and counted on
``/diagnostics``. Every message is checked when it arrives, by its codec's rules
(:mod:`push_ros.images`, :mod:`push_ros.poses`): a rejected one is counted, never enters the
stamp matching (so it cannot push a good pending image out) and never replaces the latched
extrinsics. Per message: ``bad_color`` (encoding not ``rgb8``/``bgr8``, width or height
outside [1, 8192], ``step`` smaller than a row, ``len(data) != height * step``),
``bad_depth`` (the same for ``32FC1``/``16UC1``/``mono16``), ``bad_camera_info`` (size
outside [1, 8192], K not finite, fx or fy outside [1, 1e5] px, last row not (0, 0, 1),
principal point more than half the image size outside the image), ``bad_extrinsics`` (NaN /
inf, |translation| > 100 m, quaternion not of unit norm within 1e-3), ``bad_stamp`` (a
negative ``sec`` or ``nanosec >= 1e9``). Per frame: ``size_mismatch`` (colour vs depth),
``bad_camera_info`` (camera_info of another size), ``frame_mismatch`` (image frame vs the
extrinsics' child frame), ``missing_camera_info`` (colour and depth without camera_info of
the same stamp), ``no_extrinsics``, ``empty_mask``, ``out_of_view`` (mask on the image
border), ``few_pixels`` (also a footprint under 9 cells), ``no_depth`` (too few mask pixels
with a valid depth), ``fragmented`` (the top-down view falls apart, e.g. a sliver narrower
than a few millimetres), ``too_large`` (object points more than 2048 raster cells apart or
1 km from the origin: absurd depth, intrinsics or extrinsics; checked before the raster is
allocated). Work per frame is bounded (:mod:`push_perception.core`, "Bounded work per
frame": outline at most 1000 points). Every callback (subscriptions, the reset service, the
diagnostics timer) is wrapped by :func:`push_ros.node.guarded`: an exception that still
escaped would be logged, counted as ``callback_errors`` and reported, and the node keeps
running (the fuzz tests, ``tests/ros/test_fuzz_perception.py``, expect none).

Parameters (declared below with descriptions and ranges; defaults and units commented in
``pushbot_bringup/config/push_perception.yaml``): ``weights``, ``torch_threads``,
``sync_queue`` (read only), ``threshold``, ``min_coarse_cells``, ``publish_mask`` and the
geometry of :class:`push_perception.core.PerceptionConfig` (``resolution``, ``min_height``,
``closing_radius``, ``outline_spacing``, ``outline_smoothing``, ``outline_offset``,
``symmetry_tolerance``, ``min_pixels``, ``min_valid_fraction``, ``max_border_pixels``,
``sigma_position``, ``sigma_theta``, ``match_cost_floor``). A bad value fails start-up with
a clear message (exit status 2) and is refused when set at run time (with the reason); valid
geometry values take effect on the next ``~/reset``.

Frames: ``camera_color_optical_frame`` (REP 103 optical), ``world`` (table, z up), ``object``.
The heavy work runs in the subscription callback of the default single-threaded executor
(latency per frame: docs/RESULTS.md, ``bench_perception``); frames that arrive meanwhile wait
in the sensor queues (depth 5) and the oldest are dropped, which is what a camera stream wants.
Camera images between processes need the bundled DDS profile (docs/ARCHITECTURE.md, "DDS
profile"; delivery measured in docs/RESULTS.md, ``graph``).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import time
from collections import OrderedDict, deque
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_srvs.srv import Trigger

from push_perception.core import (
    MAX_OUTLINE_POINTS,
    EpisodeTracker,
    PerceptionConfig,
    PerceptionError,
)
from push_ros.diagnostics import DiagnosticsPublisher
from push_ros.extrinsics import CameraExtrinsics
from push_ros.frames import OBJECT_FRAME, WORLD_FRAME
from push_ros.images import (
    camera_matrix_from_info,
    check_image_layout,
    depth_to_metres,
    image_to_array,
    mask_image_msg,
)
from push_ros.node import (
    ParamSpec,
    ThrottledLog,
    declare_config,
    guarded,
    parameter_values,
    run_node,
)
from push_ros.outline import outline_cloud_msg, outline_from_cloud
from push_ros.poses import check_frame, pose_with_covariance_msg, xytheta_from_pose
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS
from push_ros.stamps import seconds_from_stamp

__all__ = ["PARAMETERS", "SegmentationNode", "SegmentationParams", "main"]

NODE_NAME = "segmentation_node"
#: Seconds between two log lines of the same kind (every event is counted on /diagnostics).
LOG_THROTTLE_S = 1.0
#: Period of the regular /diagnostics message, seconds of steady time.
DIAGNOSTICS_PERIOD_S = 1.0
#: Smallest fraction of valid depth pixels in a frame (below it the camera is blind).
MIN_VALID_DEPTH = 0.05
#: Frames whose processing time enters the median latency on /diagnostics.
LATENCY_WINDOW = 100
#: Outcome counters reported on /diagnostics, in this order.
FAILURE_KINDS = ("bad_color", "bad_depth", "size_mismatch", "bad_camera_info",
                 "bad_extrinsics", "bad_stamp", "frame_mismatch", "missing_camera_info",
                 "no_extrinsics", "empty_mask", "out_of_view", "few_pixels", "no_depth",
                 "fragmented", "too_large", "bad_input", "callback_errors")
#: Encodings of the colour and the depth stream.
COLOR_ENCODINGS = ("rgb8", "bgr8")
DEPTH_ENCODINGS = ("32FC1", "16UC1", "mono16")


# --------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------
_GEOMETRY = {f.name: f.default for f in dataclasses.fields(PerceptionConfig)}
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("weights", "", "Segmentation network weights (.pt); empty = the bundled "
              "push_perception/models/segmentation.pt.", read_only=True),
    ParamSpec("torch_threads", 1, "torch intra-op threads for the CNN.", (1, 16),
              read_only=True),
    ParamSpec("sync_queue", 5, "Stamps kept per stream while matching colour, depth and "
              "camera_info.", (1, 100), read_only=True),
    ParamSpec("threshold", 0.5, "Probability above which a pixel is the object.",
              (0.01, 0.99), read_only=True),
    ParamSpec("min_coarse_cells", 3, "Smallest coarse CNN component accepted as the object, "
              "cells of 8 x 8 px at 640 x 480.", (1, 10000), read_only=True),
    ParamSpec("publish_mask", True, "Publish perception/mask."),
    ParamSpec("anchor_timeout", 5.0, "Seconds (steady) after start-up to wait for the "
              "estimator's latched outline and estimate to continue a running episode after a "
              "restart; 0 = never re-anchor.", (0.0, 60.0), read_only=True),
    ParamSpec("resolution", _GEOMETRY["resolution"], "Cell size of the top-down view, m.",
              (5e-4, 3e-3)),
    ParamSpec("min_height", _GEOMETRY["min_height"], "Mask points lower than this above the "
              "table are dropped (table pixels), m.", (0.0, 0.01)),
    ParamSpec("closing_radius", _GEOMETRY["closing_radius"], "Morphological closing of the "
              "top-down view, cells; closing_radius * resolution in [1, 10] mm.", (2, 10)),
    ParamSpec("outline_spacing", _GEOMETRY["outline_spacing"], "Distance between outline "
              "points, m (at most 1000 points: a longer outline is spaced wider).",
              (5e-4, 0.01)),
    ParamSpec("outline_smoothing", _GEOMETRY["outline_smoothing"], "Gaussian smoothing "
              "along the outline (standard deviation), m.", (0.0, 0.01)),
    ParamSpec("outline_offset", _GEOMETRY["outline_offset"], "Extra outward offset of the "
              "outline (calibration), m.", (-0.005, 0.005)),
    ParamSpec("symmetry_tolerance", _GEOMETRY["symmetry_tolerance"], "Orientation minima "
              "within this chamfer cost of the best are symmetric equivalents, m.",
              (0.0, 0.01)),
    ParamSpec("min_pixels", _GEOMETRY["min_pixels"], "Fewer mask pixels (with depth) than "
              "this: no pose.", (3, 10**7)),
    ParamSpec("min_valid_fraction", _GEOMETRY["min_valid_fraction"], "Smaller fraction of "
              "mask pixels with depth than this: no pose.", (0.0, 1.0)),
    ParamSpec("max_border_pixels", _GEOMETRY["max_border_pixels"], "More mask pixels than "
              "this on the image border: object out of view, no pose.", (0, 10**7)),
    ParamSpec("sigma_position", _GEOMETRY["sigma_position"], "Base standard deviation of x "
              "and y (5000 pixels, full depth), m.", (1e-6, 1.0)),
    ParamSpec("sigma_theta", _GEOMETRY["sigma_theta"], "Base standard deviation of the "
              "relative yaw, rad.", (1e-6, math.pi)),
    ParamSpec("match_cost_floor", _GEOMETRY["match_cost_floor"], "Chamfer residual of a "
              "correct rotation match; only the excess widens the yaw's deviation, m.",
              (0.0, 0.01)),
)
_GEOMETRY_NAMES = tuple(n for n in _GEOMETRY if any(p.name == n for p in PARAMETERS))


@dataclass(frozen=True)
class SegmentationParams:
    """The node's parameters, typed and validated (see ``PARAMETERS`` for units).

    Attributes
    ----------
    weights : str
        Weights file; "" = bundled.
    torch_threads, sync_queue, min_coarse_cells : int
    threshold : float
    publish_mask : bool
    geometry : PerceptionConfig
        The mask-to-state parameters.
    anchor_timeout : float
        Seconds to wait for a re-anchoring after start-up (module docstring).
    """

    weights: str
    torch_threads: int
    sync_queue: int
    threshold: float
    min_coarse_cells: int
    publish_mask: bool
    geometry: PerceptionConfig
    anchor_timeout: float = 5.0

    @classmethod
    def from_values(cls, values: dict[str, Any]) -> SegmentationParams:
        """Build from ``{name: value}``; raises ``ValueError`` naming a bad parameter."""
        geometry = {n: values[n] for n in _GEOMETRY_NAMES}
        try:
            config = PerceptionConfig(**geometry)
        except ValueError as exc:
            raise ValueError(f"invalid geometry parameter: {exc}") from None
        return cls(weights=str(values["weights"]), torch_threads=int(values["torch_threads"]),
                   sync_queue=int(values["sync_queue"]), threshold=float(values["threshold"]),
                   min_coarse_cells=int(values["min_coarse_cells"]),
                   publish_mask=bool(values["publish_mask"]), geometry=config,
                   anchor_timeout=float(values["anchor_timeout"]))


# --------------------------------------------------------------------------------------------
# The node
# --------------------------------------------------------------------------------------------
class SegmentationNode(Node):
    """ROS wrapper of the perception pipeline; see the module docstring.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        At construction, for an invalid parameter or unreadable weights.
    """

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._params = declare_config(self, PARAMETERS, SegmentationParams.from_values)

        import torch

        from push_perception.model import Segmenter

        torch.set_num_threads(self._params.torch_threads)
        cv2.setNumThreads(1)  # small images: OpenCV's thread pool only adds latency
        self._segmenter = Segmenter.load(self._params.weights or None,
                                         threshold=self._params.threshold,
                                         min_coarse_cells=self._params.min_coarse_cells)
        self._tracker = EpisodeTracker(self._params.geometry)

        self._pending: OrderedDict[tuple[int, int], dict[str, Any]] = OrderedDict()
        self._counts = {"frames": 0, "poses": 0, "resets": 0, "previous_episode": 0,
                        "waiting_for_anchor": 0, "anchored": 0,
                        **dict.fromkeys(FAILURE_KINDS, 0)}
        # Re-anchoring after a restart (module docstring): until this steady time (None = not
        # waiting) the first frame waits for the estimator's latched outline and estimate.
        self._anchor_until: float | None = (time.monotonic() + self._params.anchor_timeout
                                            if self._params.anchor_timeout > 0.0 else None)
        self._anchor_outline: tuple[PointCloud2, np.ndarray, np.ndarray, float] | None = None
        self._anchor_estimate: tuple[float, float] | None = None  # (stamp, yaw)
        self._anchor_msg: PointCloud2 | None = None  # the outline to re-publish
        self._last_error = ""
        self._ok: bool | None = None
        self._latency: deque[float] = deque(maxlen=LATENCY_WINDOW)
        self._last_stamp = 0.0
        self._last_frame = -math.inf  # stamp (s) of the last frame processed
        self._episode_after = -math.inf  # frames with this stamp belong to the last episode
        self._log = ThrottledLog(self.get_logger(), LOG_THROTTLE_S)

        self._pub_mask = self.create_publisher(Image, "perception/mask",
                                               SENSOR_QOS)
        self._pub_pose = self.create_publisher(PoseWithCovarianceStamped,
                                               "perception/object_pose", RELIABLE_QOS)
        self._pub_outline = self.create_publisher(PointCloud2, "perception/outline",
                                                  LATCHED_QOS)
        self._diagnostics = DiagnosticsPublisher(self, "perception", "rgbd_camera")
        sensor = SENSOR_QOS
        # Every callback is guarded: no exception leaves it (it is logged, counted as
        # callback_errors and reported on /diagnostics). The guarded callables are attributes
        # so tests can call them directly with real messages.
        self.on_color = self._guard(self._on_color)
        self.on_depth = self._guard(self._on_depth)
        self.on_camera_info = self._guard(self._on_camera_info)
        self.on_reset = self._guard(self._on_reset)
        self.on_estimator_outline = self._guard(self._on_estimator_outline)
        self.on_estimate = self._guard(self._on_estimate)
        if self._anchor_until is not None:
            self.create_subscription(PointCloud2, "estimator/outline",
                                     self.on_estimator_outline, LATCHED_QOS)
            self.create_subscription(PoseWithCovarianceStamped, "estimator/object_pose",
                                     self.on_estimate, LATCHED_QOS)
        self.create_subscription(Image, "camera/color/image_raw", self.on_color, sensor)
        self.create_subscription(Image, "camera/aligned_depth_to_color/image_raw",
                                 self.on_depth, sensor)
        self.create_subscription(CameraInfo, "camera/color/camera_info", self.on_camera_info,
                                 sensor)
        self._extrinsics = CameraExtrinsics(
            self, lambda exc: self._fail("bad_extrinsics", f"rejected camera extrinsics: {exc}"),
            wrap=self._guard)
        self.on_extrinsics = self._extrinsics.on_message
        self.create_service(Trigger, "~/reset", self.on_reset)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._guard(self._publish_diagnostics),
                          clock=steady)
        self.get_logger().info(
            f"segmentation node ready (use_sim_time="
            f"{self.get_parameter('use_sim_time').value}, torch threads "
            f"{self._params.torch_threads}, weights {self._params.weights or 'bundled'})")

    # ---- parameters --------------------------------------------------------------------------
    def _read_params(self) -> SegmentationParams:
        return SegmentationParams.from_values(parameter_values(self, PARAMETERS))

    # ---- inputs ------------------------------------------------------------------------------
    def _guard(self, callback: Any) -> Any:
        return guarded(callback, self._log, self._on_callback_error)

    def _on_callback_error(self, name: str, message: str) -> None:
        """An exception inside a callback (already logged by ``guarded``): count, report."""
        self._counts["callback_errors"] += 1
        self._last_error = f"callback_errors: {name}: {message}"
        self._ok = False
        self._publish_diagnostics()

    def _on_color(self, msg: Image) -> None:
        self._accept("rgb", msg, "bad_color", lambda m: check_image_layout(m, COLOR_ENCODINGS))

    def _on_depth(self, msg: Image) -> None:
        self._accept("depth", msg, "bad_depth", lambda m: check_image_layout(m, DEPTH_ENCODINGS))

    def _on_camera_info(self, msg: CameraInfo) -> None:
        self._accept("info", msg, "bad_camera_info", camera_matrix_from_info)

    def _accept(self, stream: str, msg: Any, kind: str, check: Any) -> None:
        """Check one message with its codec's rules; a rejected one is counted as ``kind``,
        logged and reported, and never reaches the pending triples."""
        try:
            check(msg)
        except ValueError as exc:
            self._fail(kind, f"{stream} message rejected: {exc}")
            return
        self._on_stream(stream, msg)

    def _on_stream(self, stream: str, msg: Any) -> None:
        """Collect colour, depth and camera_info by stamp; process a complete triple.

        Only messages that passed their stream's checks get here, so a rejected message
        never evicts a pending one. A stamp outside [0, 2^31) s is rejected too.
        """
        stamp = msg.header.stamp
        if not (0 <= stamp.sec and 0 <= stamp.nanosec < 1_000_000_000):
            self._fail("bad_stamp", f"{stream} message rejected: header.stamp ({stamp.sec} s, "
                       f"{stamp.nanosec} ns) is not a time in [0, 2^31) s")
            return
        key = (stamp.sec, stamp.nanosec)
        entry = self._pending.setdefault(key, {})
        entry[stream] = msg
        if len(entry) == 3:
            # Everything older than a complete stamp is stale: drop it (and say why).
            for old in list(self._pending):
                if old == key:
                    break
                self._evict(old)
            del self._pending[key]
            self._process(entry["rgb"], entry["depth"], entry["info"])
            return
        while len(self._pending) > self._params.sync_queue:
            self._evict(next(iter(self._pending)))

    def _evict(self, key: tuple[int, int]) -> None:
        entry = self._pending.pop(key)
        if "rgb" in entry and "depth" in entry:  # a whole image pair without camera info
            self._fail("missing_camera_info", f"colour and depth at t={key[0] + key[1] * 1e-9:.3f}"
                       " s have no camera_info with the same stamp; frame dropped")

    # ---- re-anchoring after a restart ----------------------------------------------------------
    def _on_estimator_outline(self, msg: PointCloud2) -> None:
        try:
            points, normals = outline_from_cloud(msg, OBJECT_FRAME, MAX_OUTLINE_POINTS)
            stamp = seconds_from_stamp(msg.header.stamp)
        except ValueError as exc:
            self._fail("bad_input", f"estimator/outline rejected: {exc}")
            return
        self._anchor_outline = (msg, points, normals, stamp)

    def _on_estimate(self, msg: PoseWithCovarianceStamped) -> None:
        try:
            check_frame(msg.header.frame_id, WORLD_FRAME)
            yaw = float(xytheta_from_pose(msg.pose.pose)[2])
            stamp = seconds_from_stamp(msg.header.stamp)
        except ValueError as exc:
            self._fail("bad_input", f"estimator/object_pose rejected: {exc}")
            return
        self._anchor_estimate = (stamp, yaw)

    def _waiting_for_anchor(self) -> bool:
        """Decide on re-anchoring before the first frame of a (re)started node (module
        docstring); True while the frame must wait."""
        if self._anchor_until is None or self._tracker.outline is not None:
            self._anchor_until = None
            return False
        outline, estimate = self._anchor_outline, self._anchor_estimate
        if outline is not None and estimate is not None and estimate[0] >= outline[3]:
            self._tracker.anchor(outline[1], outline[2], estimate[1])
            self._anchor_msg = outline[0]
            self._anchor_until = None
            self.get_logger().info(
                f"re-anchoring to the running episode: the estimator's outline of "
                f"t={outline[3]:.3f} s and estimate of t={estimate[0]:.3f} s (yaw "
                f"{estimate[1]:.4f} rad)")
            return False
        if time.monotonic() < self._anchor_until:
            self._counts["waiting_for_anchor"] += 1
            return True
        self._anchor_until = None
        return False

    # ---- processing --------------------------------------------------------------------------
    def _process(self, rgb_msg: Image, depth_msg: Image, info: CameraInfo) -> None:
        started = time.perf_counter()
        stamp = rgb_msg.header.stamp
        stamp_s = seconds_from_stamp(stamp)
        if stamp_s == self._episode_after:  # a repeated frame of the previous episode
            self._counts["previous_episode"] += 1
            return
        if self._waiting_for_anchor():
            return
        self._last_frame = stamp_s
        self._counts["frames"] += 1
        try:
            rgb = self._decode_color(rgb_msg)
            try:
                depth = depth_to_metres(depth_msg)
            except ValueError as exc:
                raise PerceptionError("bad_depth", f"depth image: {exc}") from None
            valid = np.count_nonzero(np.isfinite(depth)) / depth.size
            if valid < MIN_VALID_DEPTH:
                raise PerceptionError("no_depth", f"only {100 * valid:.1f} % of the depth image "
                                      f"is valid (NaN, zero or negative elsewhere; need "
                                      f"{100 * MIN_VALID_DEPTH:.0f} %)")
            if rgb.shape[:2] != depth.shape:
                raise PerceptionError("size_mismatch", f"colour is {rgb.shape[1]}x"
                                      f"{rgb.shape[0]} but depth is {depth.shape[1]}x"
                                      f"{depth.shape[0]}; depth must be aligned to colour")
            try:
                k = camera_matrix_from_info(info)
            except ValueError as exc:
                raise PerceptionError("bad_camera_info", f"camera_info: {exc}") from None
            if (info.width, info.height) != (depth.shape[1], depth.shape[0]):
                raise PerceptionError("bad_camera_info", f"camera_info is for {info.width}x"
                                      f"{info.height} images, the images are "
                                      f"{depth.shape[1]}x{depth.shape[0]}")
            frame = rgb_msg.header.frame_id
            extrinsics, extrinsics_frame = self._extrinsics.lookup(frame)
            if extrinsics is None:
                raise PerceptionError("no_extrinsics", "no camera extrinsics yet (tf2 world -> "
                                      f"{frame[:64]!r} or the latched camera/color/extrinsics)")
            if frame != depth_msg.header.frame_id or (extrinsics_frame
                                                      and frame != extrinsics_frame):
                raise PerceptionError("frame_mismatch", f"colour frame {frame[:64]!r}, depth frame "
                                      f"{depth_msg.header.frame_id[:64]!r} and extrinsics child "
                                      f"{extrinsics_frame[:64]!r} must be the same frame")
            seg = self._segmenter(rgb, depth, k, extrinsics)
            if self._params.publish_mask:
                self._pub_mask.publish(mask_image_msg(seg.mask, stamp, frame))
            if seg.box is None:
                raise PerceptionError("empty_mask", "the CNN found no object in the frame")
            meas = self._tracker.update(seg.mask, depth, k, extrinsics)
        except PerceptionError as exc:
            self._fail(exc.kind, str(exc))
            return
        if meas.anchored:  # the episode's outline, unchanged (same stamp and points)
            self._pub_outline.publish(self._anchor_msg)
            self._counts["anchored"] += 1
            self.get_logger().info(
                f"re-anchored at t={seconds_from_stamp(stamp):.3f} s: object at "
                f"({meas.pose[0]:.4f}, {meas.pose[1]:.4f}) m, yaw {meas.pose[2]:.4f} rad in the "
                f"episode frame (match cost {1e3 * meas.match_cost:.2f} mm)")
        elif meas.is_reference:  # the outline first: consumers need it for this pose
            points, normals = self._tracker.outline
            self._pub_outline.publish(outline_cloud_msg(points, normals, stamp))
            if self._anchor_msg is not None:
                self.get_logger().warning("the estimator's outline did not match the first "
                                          "frame: a new episode reference instead")
                self._anchor_msg = None
            self.get_logger().info(
                f"new episode reference at t={seconds_from_stamp(stamp):.3f} s: object at "
                f"({meas.pose[0]:.4f}, {meas.pose[1]:.4f}) m, area "
                f"{meas.area * 1e4:.1f} cm^2, outline of {len(points)} points")
        self._pub_pose.publish(pose_with_covariance_msg(meas.pose, meas.covariance, stamp))
        self._counts["poses"] += 1
        self._latency.append(time.perf_counter() - started)
        self._last_stamp = seconds_from_stamp(stamp)
        if self._ok is not True:
            self._ok = True
            self._publish_diagnostics()

    def _decode_color(self, msg: Image) -> np.ndarray:
        if msg.encoding not in ("rgb8", "bgr8"):
            raise PerceptionError("bad_color", f"colour image encoding {msg.encoding!r}; "
                                  "expected rgb8 or bgr8")
        try:
            rgb = image_to_array(msg)
        except ValueError as exc:
            raise PerceptionError("bad_color", f"colour image: {exc}") from None
        return np.ascontiguousarray(rgb[:, :, ::-1]) if msg.encoding == "bgr8" else rgb

    def _fail(self, kind: str, message: str) -> None:
        """Count, rate-limit-log and report a frame (or input) that gave no pose."""
        self._counts[kind] += 1
        self._last_error = f"{kind}: {message}"
        self._log.warning(kind, f"no pose ({kind}): {message}")
        if self._ok is not False:
            self._ok = False
            self._publish_diagnostics()

    # ---- services and diagnostics ------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        try:
            params = self._read_params()
        except ValueError as exc:
            response.success, response.message = False, f"reset refused: {exc}"
            self.get_logger().error(response.message)
            return response
        self._params = params
        self._tracker = EpisodeTracker(params.geometry)
        self._anchor_until = None  # an explicit new episode: no re-anchoring
        self._anchor_msg = None
        self._episode_after = self._last_frame
        self._counts["resets"] += 1
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
            message = f"no pose for the last frame: {self._last_error}"
        latency = (f"{1e3 * statistics.median(self._latency):.1f}" if self._latency else "")
        values = {**self._counts, "last_error": self._last_error, "latency_ms_median": latency,
                  "has_reference": str(self._tracker.outline is not None).lower(),
                  "last_stamp": f"{self._last_stamp:.6f}"}
        self._diagnostics.publish(level, message, values)


def main(args: list[str] | None = None) -> None:
    """Entry point of ``segmentation_node`` (``ros2 run`` / ``pushbot run``)."""
    run_node(SegmentationNode, NODE_NAME, args)


if __name__ == "__main__":
    main()
