"""``sim_bridge_node``: the simulated robot and RGB-D camera behind standard ROS 2 topics.

A thin ROS wrapper around :class:`sim_bridge.world.PushWorld` (pybullet, DIRECT mode): a table,
one flat object, a vertical cylindrical pusher and a D415-like camera. The node owns ``/clock``.
Messages are converted by the codecs of :mod:`push_ros` (the same ones the pipeline nodes read
them with); QoS profiles, parameters, logging and ``main()`` are :mod:`push_ros`'s too.

Publications (QoS as in ``docs/ARCHITECTURE.md``; "sensor" = ``qos_profile_sensor_data``,
"reliable" = reliable/volatile/depth 10, "latched" = reliable/transient local/depth 1):

- ``camera/color/image_raw`` (sensor_msgs/Image, ``rgb8``; sensor),
  ``camera/aligned_depth_to_color/image_raw`` (sensor_msgs/Image, ``32FC1`` metres along the
  optical axis, NaN = no return; sensor), ``camera/color/camera_info`` (sensor_msgs/CameraInfo,
  plumb_bob, zero distortion; sensor). All three share one stamp (the sim time of the render)
  and the frame ``camera_color_optical_frame``. A fresh frame is rendered after every push
  (after the object settled) and after every reset; in between the last frame is re-published
  at ``idle_frame_rate`` so late subscribers get data (the scene is static while idle).
- ``camera/color/extrinsics`` (geometry_msgs/TransformStamped; latched): world ->
  ``camera_color_optical_frame``, i.e. the camera pose in ``world`` (maps optical-frame
  points to world points). Re-published after each reset.
- ``/clock`` (rosgraph_msgs/Clock; reliable, keep last 1, volatile: matches the best-effort
  ``/clock`` subscription of rclpy/rclcpp nodes with ``use_sim_time`` and reliable ones too).
- ``sim/object_pose`` (geometry_msgs/PoseStamped; reliable): ground truth of the object frame
  in ``world``, for evaluation only; after every push/reset and at ``idle_frame_rate``.
- ``pusher/executed`` (nav_msgs/Path; reliable): frame ``world``, two poses: the pusher at the
  start and at the end of the executed straight push, each stamped with its sim time (header
  stamp = end). Orientation identity, z = 0 (the ``pusher`` frame is at table height).
  After a push the bridge publishes, in this order: ``/clock`` (time after settling), the fresh
  frame, ``sim/object_pose``, ``pusher/executed``, ``/diagnostics``; it is already idle then,
  so a client may send the next push as soon as any of them arrives.
- ``sim/monitor/image_raw`` (sensor_msgs/Image, ``rgb8``; sensor) and
  ``sim/monitor/camera_info`` (sensor_msgs/CameraInfo; sensor): the *monitor*, only when
  ``monitor.rate`` > 0: frames rendered while a push executes (the pusher lowering, pushing,
  retracting, the object settling), every ``1 / monitor.rate`` s of sim time (rounded to whole
  physics steps) from the same camera pose at ``monitor.width`` x ``monitor.height`` (the
  intrinsics scaled), no noise, frame ``camera_color_optical_frame``, stamp = sim time of the
  render (epoch included). Published from the worker thread as each is rendered, so all of
  a push's monitor frames go out before its ``pusher/executed``. A visualisation stream of the
  simulator (videos, ``pushbot view``), not an input of the pipeline: no node subscribes
  (ARCHITECTURE.md, "Monitor stream"); never subject to fault injection.
- ``/diagnostics`` (diagnostic_msgs/DiagnosticArray; reliable): one status, level OK when the
  last command succeeded, WARN after a rejected or failed one; message ``idle`` /
  ``busy: ...``; values: state, object, counters, last_error, sim_time. Published at 1 Hz and
  on every change.
- ``/tf_static`` (latched, world -> ``camera_color_optical_frame``) and ``/tf`` (reliable,
  world -> ``pusher``): only when ``tf2_msgs`` is importable (full ROS install; see the tf note
  in ARCHITECTURE.md). The pipeline never depends on them.

- ``pusher/refused`` (diagnostic_msgs/DiagnosticStatus; reliable; codec
  :mod:`push_ros.refusal`): one per ``planner/push`` the bridge does not execute (pusher mode),
  ``push_stamp`` = the push's header stamp, ``kind`` ``busy``, ``invalid`` (malformed, or a
  geometry the world refuses), ``workspace`` (a point outside it) or ``fault``
  (``faults.push_refusal``).
- Arm mode (``robot: arm``, read-only): ``/joint_states``, ``/robot_description``,
  ``sim/tool_tip`` and the ``arm.controller_topic`` subscription, see :mod:`sim_bridge.arm_ros`.
  A run of trajectories advances ``/clock`` like a push and ends with a fresh frame and
  ``sim/object_pose`` (no ``pusher/executed``: push_executor_node reports pushes).
  ``planner/push`` is ignored (counted ``pushes_ignored_arm_mode``, logged throttled), not
  refused: a refusal would make the planner drop the push the executor is carrying out.

Subscriptions:

- ``planner/push`` (nav_msgs/Path; reliable): frame ``world``, exactly three poses: approach,
  contact and end point of one straight push (positions only). The world moves the pusher to
  the approach point without touching the object, pushes at ``push_speed`` through contact to
  the end point, retracts and lets the object settle. Rejected with a logged reason and a
  diagnostic, never queued: wrong frame, not three poses, NaN/inf, a point outside the
  workspace, a push that the world refuses (approach inside the object), and any push that
  arrives while another push or a reset is running.

- ``sim/knock`` (geometry_msgs/PoseStamped; reliable): a documented way to displace the object
  (fault scenarios, tests, demos): frame ``world``, position (dx, dy) m and the yaw of the
  orientation dyaw rad are *added* to the object's pose at rest (its frame origin moves by
  (dx, dy), it turns by dyaw about that origin); z ignored. Read with the pose codec's rules
  (finite, planar unit quaternion), ``|(dx, dy)| <= MAX_KNOCK_SHIFT`` (0.1 m), the new origin
  on the workspace. Runs in the worker like a push (refused while busy, never queued): the
  object is placed, settles (``INITIAL_SETTLE_STEPS``), and a fresh frame and
  ``sim/object_pose`` are published (no ``pusher/executed``: nothing the robot did). Counted
  as ``knocks`` / ``knocks_rejected``. Example (full ROS install; the README shows the same
  from Python): ``ros2 topic pub --once /sim/knock geometry_msgs/msg/PoseStamped "{header:
  {frame_id: world}, pose: {position: {x: 0.03}, orientation: {z: 0.0998, w: 0.995}}}"``
  (3 cm along x, 0.2 rad).

Services:

- ``~/reset`` (std_srvs/srv/Trigger): re-read the current parameters and rebuild the scene;
  refused while busy. ``message`` says what was built or why not.

Fault injection (``faults.*`` parameters, :class:`FaultConfig`, all off by default; read on
start-up and ``~/reset``, draws re-seeded from ``faults.seed`` on every reset): each publication
of a camera frame (colour, depth, camera_info together; also the idle re-publications) is
dropped with probability ``faults.frame_drop``, or held back with probability
``faults.frame_delay`` and published right after the next publication of a newer frame (late
and out of order: delayed and reordered delivery through DDS); a valid push is refused with
probability ``faults.push_refusal`` (``pushes_refused_fault``; the planner's ``push_timeout``
then counts it lost). Ground truth (``sim/object_pose``) is never dropped. Counters
``frames_dropped``, ``frames_delayed``, ``frames_reordered`` (held frames released after a newer
one) on ``/diagnostics``.

Parameters (declared once below with descriptions and ranges; documented with defaults and
units in ``pushbot_bringup/config/sim_bridge.yaml``): ``object``, ``initial_pose.{x,y,theta}``,
``com_offset``, ``mass``, ``friction_table``, ``friction_pusher``, ``seed``, ``randomize``,
``image_width``, ``image_height``, ``depth_noise``, ``randomize_appearance``,
``randomize_camera``, ``push_speed``, ``pusher_radius``, ``faults.{frame_drop,frame_delay,
push_refusal,seed}``, ``monitor.{rate,width,height}`` (all read on start-up and on
``~/reset``), and the read-only
``idle_frame_rate`` and ``clock_rate`` (timer rates, Hz of wall time). A bad value fails
start-up with a clear message (exit status 2); a set that the
node can check (e.g. an unknown object) is refused with the reason, what only the world can
check (e.g. a COM outside the outline) makes the next ``~/reset`` fail and keep the scene.
``object`` accepts a library name or the path of a regular ``.json``/``.yaml``/``.yml``
object specification file of at most 1 MiB, parsed as a specification; anything else is
refused, and no refusal, ``~/reset`` answer or log line quotes a file's content (the errors
name the specification field and its rule: ``not a valid object specification: thickness:
must be a finite number > 0 (m)``).

Bad input. Every callback (``planner/push``, ``~/reset``, the timers) is wrapped by
:func:`push_ros.node.guarded`: an exception that still escaped is logged, counted as
``callback_errors`` on ``/diagnostics`` and the node keeps running (never left busy); the fuzz
tests (``tests/ros/test_fuzz_bridge.py``) expect none. A rejected push (see Subscriptions) or
parameter changes nothing.

Frames: ``world`` (table frame, z up, origin on the table at the workspace centre),
``camera_color_optical_frame`` (REP 103 optical frame), ``pusher``.

Time and threading. The bridge *is* the clock source, so it never runs on sim time itself
(``use_sim_time`` false; its timers use the steady clock, so even a launch file that sets
``use_sim_time`` globally cannot make it wait for its own ``/clock``). Published time is
``epoch + world.sim_time``: sim time advances only while the physics runs (building a scene,
pushes, settling) and stands still while idle; ``epoch`` keeps ``/clock`` monotonic across
resets (``PushWorld.reset`` restarts ``sim_time``; the new episode continues where the old one
stopped, so its stamps are strictly later).

All pybullet calls run in one worker thread, one job (build, push, reset) at a time. The
default single-threaded executor only validates, dispatches and publishes, so ``/clock`` keeps
ticking (at ``clock_rate``) while a push runs and the node stays responsive (a push arriving
meanwhile is rejected at once). The one exception is ``~/reset``: its callback waits for the
rebuild in the worker (an rclpy coroutine awaiting another thread busy-polls the executor,
which would be worse); nothing is lost meanwhile, messages wait in their queues.
"""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable
from concurrent.futures import Future as ThreadFuture
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import CameraInfo, Image
from std_srvs.srv import Trigger

from push_ros.diagnostics import DiagnosticsPublisher
from push_ros.frames import CAMERA_FRAME, PUSHER_FRAME, WORLD_FRAME
from push_ros.images import camera_info_msg, depth_image_msg, rgb_image_msg
from push_ros.node import ThrottledLog, declare_config, guarded, parameter_values, run_node
from push_ros.paths import path_from_points, push_points_from_path
from push_ros.poses import check_frame, pose_stamped_msg, transform_msg, xytheta_from_pose
from push_ros.qos import CLOCK_QOS, LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS
from push_ros.refusal import refusal_msg
from push_ros.stamps import stamp_from_seconds
from sim_bridge.arm import Trajectory
from sim_bridge.arm_ros import ArmEndpoints
from sim_bridge.params import PARAMETERS, FaultConfig, SimBridgeParams, check_object_parameter
from sim_bridge.world import Frame, PushWorld, WorldConfig

try:  # Only on a full ROS install: tf2_msgs has no PyPI wheel (ARCHITECTURE.md, tf note).
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the install
    TFMessage = None

__all__ = ["PARAMETERS", "FaultConfig", "SimBridgeNode", "SimBridgeParams",
           "check_object_parameter", "main"]
#: The worker's state while the arm follows trajectories.
ARM_BUSY = "following joint trajectories"

#: Seconds between repeated log lines of the same kind (the diagnostics count every event).
LOG_THROTTLE_S = 1.0
#: Period of the regular /diagnostics message, seconds of wall time.
DIAGNOSTICS_PERIOD_S = 1.0
#: Largest displacement of the object one ``sim/knock`` may ask for, m.
MAX_KNOCK_SHIFT = 0.1
# --------------------------------------------------------------------------------------------
# The node
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Capture:
    """Messages describing the scene at one sim time (built in the worker thread)."""

    rgb: Image
    depth: Image
    info: CameraInfo
    object_pose: PoseStamped
    pusher_xy: np.ndarray
    time: float


class SimBridgeNode(Node):
    """ROS wrapper of :class:`~sim_bridge.world.PushWorld`; see the module docstring.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        At construction, if a parameter is invalid or the world cannot be built.
    """

    def __init__(self, node_name: str = "sim_bridge_node", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._params = declare_config(self, PARAMETERS, SimBridgeParams.from_values)
        if self.get_parameter("use_sim_time").value:
            self.get_logger().warning(
                "use_sim_time is true, but the sim bridge is the /clock source; its timers run "
                "on the steady clock regardless"
            )
        config = self._params.world_config()

        self._lock = threading.Lock()  # guards the state below, not pybullet
        self._busy = ""  # "" = idle, else what the worker is doing
        self._pushing = False  # the physics is running a push: /clock follows sim_time
        self._push_seq = 0  # number of pushes handed to the worker
        self._closing = False
        self._counts = {"pushes_executed": 0, "pushes_rejected_busy": 0,
                        "pushes_rejected_invalid": 0, "pushes_failed": 0, "resets": 0,
                        "callback_errors": 0, "knocks": 0, "knocks_rejected": 0,
                        "pushes_refused_fault": 0, "frames_dropped": 0, "frames_delayed": 0,
                        "frames_reordered": 0, "pushes_ignored_arm_mode": 0,
                        "trajectories_accepted": 0, "trajectories_rejected": 0,
                        "trajectory_runs": 0, "trajectory_runs_failed": 0}
        # Fault injection (FaultConfig): its draws and the held-back frame; any thread.
        self._fault_lock = threading.Lock()
        self._fault_rng = np.random.default_rng(self._params.faults.seed)
        self._held: _Capture | None = None
        self._last_error = ""
        self._error_active = False
        self._log = ThrottledLog(self.get_logger(), LOG_THROTTLE_S)
        self._clock_lock = threading.Lock()  # makes /clock monotonic across threads
        self._last_clock = -1.0
        self._epoch = 0.0  # published time = epoch + world.sim_time
        self._capture: _Capture | None = None

        # Every pybullet call happens in this one thread.
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="sim_bridge_world")
        try:
            self._world: PushWorld = self._worker.submit(PushWorld, config).result()
        except BaseException:
            self._worker.shutdown(wait=False, cancel_futures=True)
            raise

        self._pub_rgb = self.create_publisher(
            Image, "camera/color/image_raw", SENSOR_QOS)
        self._pub_depth = self.create_publisher(
            Image, "camera/aligned_depth_to_color/image_raw", SENSOR_QOS)
        self._pub_info = self.create_publisher(
            CameraInfo, "camera/color/camera_info", SENSOR_QOS)
        self._pub_extrinsics = self.create_publisher(
            TransformStamped, "camera/color/extrinsics", LATCHED_QOS)
        self._pub_clock = self.create_publisher(ClockMsg, "/clock", CLOCK_QOS)
        self._pub_pose = self.create_publisher(PoseStamped, "sim/object_pose", RELIABLE_QOS)
        self._pub_executed = self.create_publisher(Path, "pusher/executed", RELIABLE_QOS)
        self._pub_refused = self.create_publisher(DiagnosticStatus, "pusher/refused",
                                                  RELIABLE_QOS)
        self._pub_monitor = self.create_publisher(Image, "sim/monitor/image_raw", SENSOR_QOS)
        self._pub_monitor_info = self.create_publisher(
            CameraInfo, "sim/monitor/camera_info", SENSOR_QOS)
        self._diagnostics = DiagnosticsPublisher(self, "simulation", "pybullet")
        self._pub_tf = self._pub_tf_static = None
        if TFMessage is not None:
            self._pub_tf = self.create_publisher(TFMessage, "/tf", RELIABLE_QOS)
            self._pub_tf_static = self.create_publisher(TFMessage, "/tf_static", LATCHED_QOS)

        # Every callback is guarded: no exception leaves it (logged, counted as
        # callback_errors, reported on /diagnostics); the guarded callables are attributes so
        # tests can call them directly with real messages.
        self.on_push = self._guard(self._on_push)
        self.on_reset = self._guard(self._on_reset)
        self.on_knock = self._guard(self._on_knock)
        self.create_subscription(Path, "planner/push", self.on_push, RELIABLE_QOS)
        self.create_subscription(PoseStamped, "sim/knock", self.on_knock, RELIABLE_QOS)
        self.create_service(Trigger, "~/reset", self.on_reset)
        self._arm: ArmEndpoints | None = None  # arm mode (sim_bridge.arm_ros)
        self._arm_queued = 0  # arm runs submitted to the worker and not started yet
        if self._params.robot == "arm":
            self._arm = ArmEndpoints(
                self, self._params.arm_controller_topic, self._params.arm_max_duration,
                lambda: self._epoch + float(self._world.sim_time), self._guard,
                lambda reason: self._reject(reason, "trajectories_rejected"),
                self._on_trajectory)

        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(1.0 / self._params.clock_rate, self._guard(self._on_clock_timer),
                          clock=steady)
        self.create_timer(1.0 / self._params.idle_frame_rate, self._guard(self._on_idle_timer),
                          clock=steady)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._guard(self._publish_diagnostics),
                          clock=steady)

        self._worker.submit(self._after_build).result()
        self.get_logger().info(f"sim bridge ready: {self._params.summary()}")

    # ---- parameters --------------------------------------------------------------------------
    def _read_params(self) -> SimBridgeParams:
        return SimBridgeParams.from_values(parameter_values(self, PARAMETERS))

    # ---- worker-thread jobs (all pybullet calls live here) -----------------------------------
    def _capture_scene(self) -> _Capture:
        """Render and convert one frame with the ground truth at its time (worker thread)."""
        frame = self._world.render()
        t = self._epoch + float(frame.stamp)
        stamp = stamp_from_seconds(t)
        height, width = frame.depth.shape
        return _Capture(
            rgb=rgb_image_msg(frame.rgb, stamp),
            depth=depth_image_msg(frame.depth, stamp),
            info=camera_info_msg(self._world.camera_matrix, width, height, stamp),
            object_pose=pose_stamped_msg(self._world.object_pose(), stamp),
            pusher_xy=np.asarray(self._world.pusher_position(), dtype=float),
            time=t,
        )

    def _after_build(self) -> str:
        """Publish everything that describes a freshly built scene; return its summary."""
        capture = self._capture_scene()
        stamp = stamp_from_seconds(capture.time)
        extrinsics = transform_msg(self._world.T_world_camera, stamp, WORLD_FRAME, CAMERA_FRAME)
        self._publish_clock(capture.time)
        self._capture = capture
        if self._arm is not None:
            self._arm.follower.hold(self._world.arm_state().positions)
            self._arm.publish_description(self._world.robot_description)
            self._publish_joint_state(float(self._world.sim_time), self._world.arm_state())
        self._publish_capture(capture)
        self._publish_safely(self._pub_extrinsics, extrinsics)
        if self._pub_tf_static is not None:
            self._publish_safely(self._pub_tf_static, TFMessage(transforms=[extrinsics]))
        spec = self._world.object_spec
        return (
            f"built {spec.name!r} (mass {spec.mass:.4g} kg, COM ({spec.com[0]:.4f}, "
            f"{spec.com[1]:.4f}) m, friction table {spec.friction_table:.3g}, pusher "
            f"{spec.friction_pusher:.3g}) at pose {np.round(self._world.object_pose(), 4) + 0.0} "
            f"(world, m/rad); camera {capture.info.width}x{capture.info.height}"
        )

    def _run_push(self, seq: int, points: tuple[np.ndarray, np.ndarray, np.ndarray],
                  stamp: Any) -> None:
        self._pushing = True
        monitor = self._params.monitor
        try:
            result = self._world.execute_push(
                *points, monitor=monitor,
                on_frame=None if monitor is None else self._publish_monitor)
        except ValueError as exc:  # the world moved nothing (workspace, geometry of the push)
            reason = f"rejected push command on planner/push: {exc}"
            self._finish_job(reason, "pushes_rejected_invalid")
            self._publish_refusal(stamp, getattr(exc, "kind", "invalid"), reason)
            return
        except Exception as exc:  # keep the node alive; report everything else loudly
            self.get_logger().error(f"push {seq} crashed:\n{traceback.format_exc()}")
            self._finish_job(f"push {seq} failed: {type(exc).__name__}: {exc}", "pushes_failed")
            return
        finally:
            self._pushing = False
        t_start = self._epoch + float(result.t_start)
        t_end = self._epoch + float(result.t_end)
        executed = path_from_points(
            np.array([result.pusher_start, result.pusher_end], dtype=float),
            [stamp_from_seconds(t_start), stamp_from_seconds(t_end)],
        )
        try:
            capture = self._capture_scene()
        except Exception as exc:
            self.get_logger().error(f"render after push {seq} failed:\n{traceback.format_exc()}")
            self._publish_safely(self._pub_executed, executed)
            self._finish_job(f"render after push {seq} failed: {exc}", "pushes_failed")
            return
        self._capture = capture
        # Idle before the results go out: a client that answers pusher/executed or the fresh
        # frame with the next push at once must not find the bridge busy.
        self._finish_job(None, "pushes_executed", publish=False)
        self._publish_clock(capture.time)
        self._publish_capture(capture)
        self._publish_safely(self._pub_executed, executed)
        self._publish_diagnostics()
        moved = np.asarray(result.pose_after) - np.asarray(result.pose_before)
        self.get_logger().info(
            f"push {seq} done: pusher {np.round(result.pusher_start, 4)} -> "
            f"{np.round(result.pusher_end, 4)} m, sim {t_start:.3f} -> {t_end:.3f} s, "
            f"touched={bool(result.touched)}, object moved {np.round(moved, 4)} (m, m, rad)"
        )
        if not getattr(result, "settled", True):
            self.get_logger().warning(f"push {seq}: the object had not come to rest when the "
                                      "settle timeout ended; the frame shows it moving")

    def _run_reset(self, config: WorldConfig, params: SimBridgeParams) -> tuple[bool, str]:
        time_before = self._epoch + float(self._world.sim_time)
        try:
            self._world.reset(config)
        except ValueError as exc:  # PushWorld.reset keeps the previous scene on ValueError
            message = f"reset failed: {exc}; kept the previous scene"
            self._finish_job(message, None)
            return False, message
        except Exception as exc:
            self.get_logger().error(f"reset crashed:\n{traceback.format_exc()}")
            message = f"reset failed: {type(exc).__name__}: {exc}"
            self._epoch = time_before  # a rebuilt world restarts its sim_time at 0
            try:  # never leave the node without a usable scene
                self._world.reset(self._params.world_config())
                self._after_build()
                message += "; rebuilt the previous configuration"
            except Exception as exc2:
                message += f"; rebuilding the previous configuration failed too: {exc2}"
            self._finish_job(message, None)
            return False, message
        # PushWorld.reset restarts sim_time at 0: the new episode continues /clock where the old
        # one stopped, so the new scene's stamps (after its initial settling) are strictly later.
        self._epoch = time_before
        self._params = params
        with self._fault_lock:  # a held frame of the old scene must never follow the new one
            self._fault_rng = np.random.default_rng(params.faults.seed)
            self._held = None
        try:
            summary = self._after_build()
        except Exception as exc:
            self.get_logger().error(f"publishing the new scene failed:\n{traceback.format_exc()}")
            self._finish_job(f"reset failed: {exc}", None)
            return False, f"reset failed: {exc}"
        self._finish_job(None, "resets")
        return True, summary

    def _finish_job(self, error: str | None, counter: str | None, publish: bool = True) -> None:
        """Mark the worker idle, count the outcome, log an error, publish the diagnostic."""
        with self._lock:
            self._busy = ARM_BUSY if self._arm_queued else ""
            if counter is not None:
                self._counts[counter] += 1
            if error is not None:
                self._last_error = error
            self._error_active = error is not None
        if error is not None:
            self._log_limited(counter or "reset", error)
        if publish:
            self._publish_diagnostics()

    # ---- publishing (any thread; rclpy publishers are thread-safe) ---------------------------
    def _publish_safely(self, publisher: Any, msg: Any) -> None:
        if not self._closing:
            publisher.publish(msg)

    def _publish_clock(self, time: float) -> None:
        with self._clock_lock:
            if time <= self._last_clock or self._closing:
                return
            self._last_clock = time
            self._pub_clock.publish(ClockMsg(clock=stamp_from_seconds(time)))

    def _publish_capture(self, capture: _Capture) -> None:
        """Publish a frame, then the small reliable messages (ground truth, tf).

        Order matters: with Fast DDS (2.14, UDPv4 and shared memory alike) a small reliable
        sample published just *before* a large best-effort burst (the images) to the same
        subscriber is sometimes only delivered by the next heartbeat, up to 3 s later; after
        the burst it arrives at once. So reliable messages follow the images everywhere.
        """
        for frame in self._camera_faults(capture):
            for publisher, msg in ((self._pub_rgb, frame.rgb), (self._pub_depth, frame.depth),
                                   (self._pub_info, frame.info)):
                self._publish_safely(publisher, msg)
        self._publish_safely(self._pub_pose, capture.object_pose)
        if self._pub_tf is not None:
            pusher = np.eye(4)
            pusher[:2, 3] = capture.pusher_xy
            tf = transform_msg(pusher, capture.info.header.stamp, WORLD_FRAME, PUSHER_FRAME)
            self._publish_safely(self._pub_tf, TFMessage(transforms=[tf]))

    def _camera_faults(self, capture: _Capture) -> list[_Capture]:
        """The frames to publish now for one publication of ``capture``, in order
        (:class:`FaultConfig`): none (dropped), ``capture``, and a held-back older frame after
        it once ``capture`` is newer (delayed and reordered); ``capture`` itself may be held
        back (one frame at a time)."""
        faults = self._params.faults
        if faults.frame_drop <= 0.0 and faults.frame_delay <= 0.0 and self._held is None:
            return [capture]
        with self._fault_lock:
            out = [capture]
            if faults.frame_drop > 0.0 and self._fault_rng.random() < faults.frame_drop:
                out = []
                self._count("frames_dropped")
            if (out and self._held is None and faults.frame_delay > 0.0
                    and self._fault_rng.random() < faults.frame_delay):
                self._held, out = capture, []
                self._count("frames_delayed")
            elif self._held is not None and self._held.time < capture.time:
                out.append(self._held)  # an older frame right after a newer one
                self._held = None
                self._count("frames_reordered")
        return out

    def _publish_monitor(self, frame: Frame) -> None:
        """Publish one monitor frame (worker thread, during a push; module docstring). Never
        raises: an exception here would stop the physics in the middle of the push."""
        try:
            stamp = stamp_from_seconds(self._epoch + float(frame.stamp))
            height, width = frame.rgb.shape[:2]
            self._publish_safely(self._pub_monitor, rgb_image_msg(frame.rgb, stamp))
            self._publish_safely(self._pub_monitor_info,
                                 camera_info_msg(frame.camera_matrix, width, height, stamp))
        except Exception as exc:  # e.g. the context shut down meanwhile: the push goes on
            self._log_limited("monitor", f"monitor frame not published: "
                                         f"{type(exc).__name__}: {exc}", warning=True)

    def _count(self, counter: str) -> None:
        with self._lock:
            self._counts[counter] += 1

    def _publish_diagnostics(self) -> None:
        with self._lock:
            busy, counts = self._busy, dict(self._counts)
            last_error, error_active = self._last_error, self._error_active
        message = f"busy: {busy}" if busy else "idle"
        if error_active:
            message += f"; last error: {last_error}"
        values = {"state": "busy" if busy else "idle", "object": self._params.object,
                  **counts, "last_error": last_error,
                  "sim_time": f"{max(self._last_clock, 0.0):.6f}"}
        level = DiagnosticStatus.WARN if error_active else DiagnosticStatus.OK
        status = self._diagnostics.status(level, message, values)
        array = self._diagnostics.array(status, stamp_from_seconds(max(self._last_clock, 0.0)))
        self._publish_safely(self._diagnostics.publisher, array)

    # ---- executor callbacks ------------------------------------------------------------------
    def _on_clock_timer(self) -> None:
        """While a push runs, publish its sim time.

        ``PushWorld.sim_time`` is plain Python arithmetic on a step counter (no pybullet call),
        so reading it here while the worker steps is safe; a stale value is harmless and
        ``_publish_clock`` never lets /clock go backwards.
        """
        if self._pushing:
            self._publish_clock(self._epoch + float(self._world.sim_time))

    def _on_idle_timer(self) -> None:
        """Re-publish the last frame, pose and time so late subscribers get data."""
        capture = self._capture
        if self._busy or capture is None:
            return
        with self._clock_lock:  # the current time, unchanged while idle
            if self._last_clock >= 0.0 and not self._closing:
                self._pub_clock.publish(ClockMsg(clock=stamp_from_seconds(self._last_clock)))
        self._publish_capture(capture)

    def _on_push(self, msg: Path) -> None:
        if self._arm is not None:  # the arm is driven by push_executor_node's trajectories
            self._count("pushes_ignored_arm_mode")
            self._log.warning("arm_mode", "planner/push ignored: robot is 'arm' (the push "
                                          "executor turns pushes into joint trajectories)")
            return
        stamp = msg.header.stamp
        try:
            points = push_points_from_path(msg)
        except ValueError as exc:
            self._reject(f"rejected push command on planner/push: {exc}",
                         "pushes_rejected_invalid", stamp, "invalid")
            return
        if self._params.faults.push_refusal > 0.0 and not self._busy:
            with self._fault_lock:
                refuse = self._fault_rng.random() < self._params.faults.push_refusal
            if refuse:
                self._reject("refused push command on planner/push (fault injection: "
                             f"faults.push_refusal = {self._params.faults.push_refusal})",
                             "pushes_refused_fault", stamp, "fault")
                return
        with self._lock:
            busy = self._busy
            if not busy:
                self._push_seq += 1
                seq = self._push_seq
                self._busy = f"executing push {seq}"
        if busy:
            self._reject(f"rejected push command on planner/push: busy ({busy}); pushes are "
                         "never queued, resend when idle", "pushes_rejected_busy", stamp, "busy")
            return
        try:
            self._publish_diagnostics()
            self._submit(self._run_push, seq, points, stamp)
        except BaseException:  # never left busy without a job that ends it
            with self._lock:
                self._busy = ""
            raise

    def _on_knock(self, msg: PoseStamped) -> None:
        """``sim/knock``: displace the object at rest by (dx, dy, dyaw) (module docstring)."""
        try:
            check_frame(msg.header.frame_id, WORLD_FRAME)
            delta = xytheta_from_pose(msg)
            shift = float(np.hypot(delta[0], delta[1]))
            if shift > MAX_KNOCK_SHIFT:
                raise ValueError(f"displacement {shift:.4f} m is larger than {MAX_KNOCK_SHIFT} m")
        except ValueError as exc:
            self._reject(f"rejected knock on sim/knock: {exc}", "knocks_rejected")
            return
        with self._lock:
            busy = self._busy
            if not busy:
                self._busy = "knocking the object"
        if busy:
            self._reject(f"rejected knock on sim/knock: busy ({busy}); knocks are never "
                         "queued", "knocks_rejected")
            return
        try:
            self._publish_diagnostics()
            self._submit(self._run_knock, delta)
        except BaseException:  # never left busy without a job that ends it
            with self._lock:
                self._busy = ""
            raise

    def _run_knock(self, delta: np.ndarray) -> None:
        """Worker thread: teleport the object by ``delta``, settle, publish a fresh frame."""
        before = np.asarray(self._world.object_pose(), dtype=float)
        after = before + delta
        (x0, x1), (y0, y1) = self._world.workspace
        if not (x0 <= after[0] <= x1 and y0 <= after[1] <= y1):
            self._finish_job(f"rejected knock on sim/knock: the object would leave the "
                             f"workspace (to x {after[0]:.4f}, y {after[1]:.4f} m)",
                             "knocks_rejected")
            return
        try:
            self._world.set_object_pose(after)
            capture = self._capture_scene()
        except Exception as exc:
            self.get_logger().error(f"knock failed:\n{traceback.format_exc()}")
            self._finish_job(f"knock failed: {type(exc).__name__}: {exc}", "knocks_rejected")
            return
        self._capture = capture
        self._finish_job(None, "knocks", publish=False)
        self._publish_clock(capture.time)
        self._publish_capture(capture)
        self._publish_diagnostics()
        self.get_logger().info(f"knocked the object by {np.round(delta, 4)} (m, m, rad): "
                               f"now at {np.round(self._world.object_pose(), 4)}")

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        """Rebuild the scene from the current parameters (blocks the executor while the worker
        rebuilds: an rclpy coroutine awaiting a thread would busy-poll the executor instead)."""
        try:
            params = self._read_params()
            config = params.world_config()
        except (ValueError, TypeError) as exc:
            response.success, response.message = False, f"invalid parameters: {exc}"
            self.get_logger().error(f"~/reset refused: {response.message}")
            return response
        with self._lock:
            busy = self._busy
            if not busy:
                self._busy = f"resetting to {params.object!r}"
        if busy:
            response.success = False
            response.message = f"reset refused: busy ({busy})"
            self.get_logger().warning(response.message)
            return response
        try:  # _run_reset logs and reports its own failures
            self._publish_diagnostics()
            response.success, response.message = self._submit(
                self._run_reset, config, params).result()
        except Exception as exc:  # a last resort: the job itself broke
            with self._lock:  # never left busy without a job that ends it
                self._busy = ""
            response.success, response.message = False, f"reset failed: {exc}"
            self.get_logger().error(f"~/reset: {response.message}")
        if response.success:
            self.get_logger().info(f"~/reset: {response.message}")
        return response

    # ---- helpers -----------------------------------------------------------------------------
    def _guard(self, callback: Callable[..., Any]) -> Callable[..., Any]:
        return guarded(callback, self._log, self._on_callback_error)

    def _on_callback_error(self, name: str, message: str) -> None:
        """An exception inside a callback (already logged by ``guarded``): count, report."""
        with self._lock:
            self._counts["callback_errors"] += 1
            self._last_error = f"{name} failed: {message}"
            self._error_active = True
        self._publish_diagnostics()

    def _submit(self, job: Callable[..., Any], *args: Any) -> ThreadFuture:
        return self._worker.submit(job, *args)

    def _reject(self, reason: str, counter: str, push_stamp: Any = None, kind: str = "") -> None:
        """Count, log and report a rejected input; a push (``push_stamp`` given) is also
        answered on ``pusher/refused`` with ``kind``."""
        with self._lock:
            self._counts[counter] += 1
            self._last_error = reason
            self._error_active = True
        self._log_limited(counter, reason, warning=counter == "pushes_rejected_busy")
        if push_stamp is not None:
            self._publish_refusal(push_stamp, kind, reason)
        self._publish_diagnostics()

    def _publish_refusal(self, push_stamp: Any, kind: str, reason: str) -> None:
        self._publish_safely(self._pub_refused, refusal_msg(
            self.get_fully_qualified_name(), push_stamp, kind, reason,
            hardware_id="pybullet pusher"))

    # ---- arm mode (endpoints in sim_bridge.arm_ros, physics in sim_bridge.arm_motion) -------
    def _on_trajectory(self, trajectory: Trajectory) -> str | None:
        """An accepted trajectory: to the running physics loop, or start one; a reason if the
        worker is busy with something else (a reset, a knock)."""
        if trajectory.stamp != 0.0:  # the world's sim_time has no epoch
            trajectory = replace(trajectory, stamp=max(trajectory.stamp - self._epoch, 1e-9))
        follower = self._arm.follower
        with self._lock:
            if self._busy and self._busy != ARM_BUSY:
                return f"the simulator is busy ({self._busy})"
            self._counts["trajectories_accepted"] += 1
            if follower.offer(trajectory):
                return None  # the running loop picks it up, replacing the current one
            follower.open()
            self._busy, self._arm_queued = ARM_BUSY, self._arm_queued + 1
        self._submit(self._run_arm)
        return None

    def _run_arm(self) -> None:
        """Worker: step the physics while the arm follows trajectories, then publish the tool
        tip path, a fresh frame and the ground truth (ARCHITECTURE.md, arm mode)."""
        with self._lock:
            self._arm_queued -= 1
        self._pushing = True
        monitor, dt = self._params.monitor, self._world.config.time_step
        try:
            run = self._world.run_arm(
                self._arm.follower, max(1, round(1.0 / (self._params.arm_joint_state_rate * dt))),
                self._publish_joint_state, monitor,
                None if monitor is None else self._publish_monitor,
                self._params.arm_real_time_factor)
            capture = self._capture_scene()
        except Exception as exc:  # keep the node alive; the arm holds where it is
            self.get_logger().error(f"arm run failed:\n{traceback.format_exc()}")
            self._arm.follower.hold(self._world.arm_state().positions)
            self._finish_job(f"arm run failed: {type(exc).__name__}: {exc}",
                             "trajectory_runs_failed")
            return
        finally:
            self._pushing = False
        self._capture = capture
        self._finish_job(None, "trajectory_runs", publish=False)
        self._publish_clock(capture.time)
        self._arm.publish_tool_tip(run, self._epoch)
        self._publish_capture(capture)
        self._publish_diagnostics()
        if not run.settled:
            self.get_logger().warning("arm run: the arm or the object had not come to rest "
                                      "when the settle timeout ended")

    def _publish_joint_state(self, sim_time: float, state: Any) -> None:
        """``/joint_states`` at ``epoch + sim_time`` (any thread; never raises)."""
        if self._closing:
            return
        try:
            self._arm.publish_state(self._epoch + sim_time, state)
        except Exception as exc:  # e.g. the context shut down meanwhile
            self._log_limited("joint_states", f"joint state not published: {exc}", warning=True)

    def _log_limited(self, kind: str, message: str, warning: bool = False) -> None:
        """Log at most one line per ``kind`` every ``LOG_THROTTLE_S`` s (any thread); every
        event is also counted on /diagnostics, so nothing goes unnoticed."""
        if warning:
            self._log.warning(kind, message)
        else:
            self._log.error(kind, message)

    def destroy_node(self) -> None:
        """Let a running push finish, stop the worker, then destroy the ROS entities."""
        self._closing = True
        self._worker.submit(self._world.close)  # queued behind a running push, if any
        self._worker.shutdown(wait=True)
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``sim_bridge_node`` (``ros2 run`` / ``pushbot run``)."""
    run_node(SimBridgeNode, "sim_bridge_node", args)


if __name__ == "__main__":
    main()
