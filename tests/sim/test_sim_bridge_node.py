"""Graph tests of sim_bridge_node: the bridge runs as a separate process, the test talks DDS.

One bridge process (320 x 240 camera for speed) serves the module; every test that changes the
scene starts with ``~/reset`` to a known scene, so the tests do not depend on their order.
Separate short-lived processes check the 640 x 480 default and start-up validation.
Every wait is bounded and event-driven (matched endpoints, received messages); no sleeps.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import Path
from rcl_interfaces.srv import SetParameters
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image
from std_srvs.srv import Trigger

from push_core.objects import load_object
from push_ros.images import camera_matrix_from_info, image_to_array
from push_ros.paths import points_from_path
from push_ros.poses import matrix_from_transform, xytheta_from_pose
from push_ros.stamps import seconds_from_stamp
from pushbot.ros2cli.discovery import cli_node, spin_until

if TYPE_CHECKING:  # the fixtures come from tests/conftest.py
    from conftest import ProcessManager

pytestmark = [pytest.mark.ros, pytest.mark.graph, pytest.mark.slow]

BRIDGE = "sim_bridge_node"
WIDTH, HEIGHT = 320, 240
STARTUP_TIMEOUT = 90.0  # s; building the scene and discovery on a loaded 2-core machine
PUSH_TIMEOUT = 30.0  # s; a push, settle and render are well under a second of wall time
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
# What rclpy's TimeSource uses for /clock (best effort, keep last 1); keep a few more here.
CLOCK_SUB = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
SMALL_CAMERA = ("-p", f"image_width:={WIDTH}", "-p", f"image_height:={HEIGHT}")
# The physics runs ~100x faster than real time (a 5 cm push takes tens of ms of wall time), so
# the module's bridge publishes /clock at a high rate to show ticks *during* a push.
FAST_CLOCK = ("-p", "clock_rate:=500.0")


@dataclass
class Received:
    """Messages received by the client, in arrival order."""

    rgb: list[Image]
    depth: list[Image]
    info: list[CameraInfo]
    extrinsics: list[TransformStamped]
    clock: list[Clock]
    pose: list[PoseStamped]
    executed: list[Path]
    diagnostics: list[dict[str, str]]


class BridgeClient:
    """A test node that talks to one bridge process over DDS."""

    def __init__(self, node: Node, executor: Executor, describe: Callable[[], str]) -> None:
        self.node, self.executor = node, executor
        self._describe = describe
        self.got = Received([], [], [], [], [], [], [], [])
        sub = self.node.create_subscription
        sensor = qos_profile_sensor_data
        sub(Image, "camera/color/image_raw", self.got.rgb.append, sensor)
        sub(Image, "camera/aligned_depth_to_color/image_raw", self.got.depth.append, sensor)
        sub(CameraInfo, "camera/color/camera_info", self.got.info.append, sensor)
        sub(TransformStamped, "camera/color/extrinsics", self.got.extrinsics.append, LATCHED)
        sub(Clock, "/clock", self.got.clock.append, CLOCK_SUB)
        sub(PoseStamped, "sim/object_pose", self.got.pose.append, RELIABLE)
        sub(Path, "pusher/executed", self.got.executed.append, RELIABLE)
        sub(DiagnosticArray, "/diagnostics", self._on_diagnostics, RELIABLE)
        self.push_pub = self.node.create_publisher(Path, "planner/push", RELIABLE)
        self.knock_pub = self.node.create_publisher(PoseStamped, "sim/knock", RELIABLE)
        self.reset_client = self.node.create_client(Trigger, f"/{BRIDGE}/reset")
        self.param_client = self.node.create_client(SetParameters, f"/{BRIDGE}/set_parameters")

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.startswith(f"/{BRIDGE}:"):
                values = {kv.key: kv.value for kv in status.values}
                values["_message"] = status.message
                values["_level"] = str(int.from_bytes(status.level, "little"))  # a byte field
                self.got.diagnostics.append(values)

    # ---- waiting ----------------------------------------------------------------------------
    def spin_until(self, predicate: Callable[[], Any], timeout: float, what: str) -> Any:
        """Spin until ``predicate()`` is truthy and return it; fail after ``timeout`` s."""
        if not spin_until(self.executor, predicate, time.monotonic() + timeout):
            pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}\n{self._describe()}")
        return predicate()

    def wait_ready(self, timeout: float = STARTUP_TIMEOUT) -> None:
        """Wait until the bridge is discovered, serving, and has sent a frame and a pose."""
        self.spin_until(
            lambda: (self.push_pub.get_subscription_count() > 0
                     and self.reset_client.service_is_ready()
                     and self.param_client.service_is_ready()
                     and self.got.info and self.got.pose and self.got.extrinsics),
            timeout, "the bridge to come up (planner/push matched, services, first frame)")

    def call(self, client: Any, request: Any, timeout: float = 60.0) -> Any:
        future = client.call_async(request)
        self.spin_until(future.done, timeout, f"a response from {client.srv_name}")
        return future.result()

    # ---- commands ---------------------------------------------------------------------------
    def try_set_parameters(self, **values: Any) -> list[tuple[str, str]]:
        """Set parameters; return (name, reason) of every refused one."""
        params = [Parameter(name.replace("__", "."), Parameter.Type.DOUBLE_ARRAY, v)
                  if isinstance(v, list) else Parameter(name.replace("__", "."), value=v)
                  for name, v in values.items()]
        params = [p.to_parameter_msg() for p in params]
        result = self.call(self.param_client, SetParameters.Request(parameters=params))
        return [(p.name, r.reason) for p, r in zip(params, result.results, strict=True)
                if not r.successful]

    def set_parameters(self, **values: Any) -> None:
        failed = self.try_set_parameters(**values)
        assert not failed, f"set_parameters failed: {failed}"

    def reset(self, **values: Any) -> Trigger.Response:
        """Set parameters (``initial_pose__x`` for ``initial_pose.x``), then call ~/reset."""
        if values:
            self.set_parameters(**values)
        last = self.pose_stamp()
        response = self.call(self.reset_client, Trigger.Request())
        if response.success:  # the new scene's stamps are strictly later (/clock continues)
            self.spin_until(lambda: self.pose_stamp() > last, 10.0, "the pose after reset")
        return response

    def send_push(self, points: Any, frame_id: str = "world") -> None:
        msg = Path()
        msg.header.frame_id = frame_id
        for x, y in points:
            pose = PoseStamped()
            pose.header.frame_id = frame_id
            pose.pose.position.x, pose.pose.position.y = float(x), float(y)
            pose.pose.orientation.w = 1.0
            msg.poses.append(pose)
        self.push_pub.publish(msg)

    # ---- queries ----------------------------------------------------------------------------
    def object_pose(self) -> np.ndarray:
        return xytheta_from_pose(self.got.pose[-1])

    def pose_stamp(self) -> float:
        """Stamp of the newest ground-truth pose, s (-1 before the first)."""
        return seconds_from_stamp(self.got.pose[-1].header.stamp) if self.got.pose else -1.0

    def diagnostics_since(self, index: int) -> list[dict[str, str]]:
        return self.got.diagnostics[index:]

    def latest_frame(self) -> tuple[Image, Image, CameraInfo] | None:
        """The newest (rgb, depth, info) triple that shares one stamp, if any."""
        def key(m: Any) -> tuple[int, int]:
            return (m.header.stamp.sec, m.header.stamp.nanosec)
        depth = {key(m): m for m in self.got.depth}
        info = {key(m): m for m in self.got.info}
        for rgb in reversed(self.got.rgb):
            if key(rgb) in depth and key(rgb) in info:
                return rgb, depth[key(rgb)], info[key(rgb)]
        return None

    def frame_after(self, t: float, timeout: float = 10.0) -> tuple[Image, Image, CameraInfo]:
        def fresh() -> Any:
            frame = self.latest_frame()
            return frame if frame and seconds_from_stamp(frame[0].header.stamp) >= t else None
        return self.spin_until(fresh, timeout, f"a camera frame stamped >= {t:.3f} s")


# --------------------------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bridge(module_processes: ProcessManager) -> Iterator[BridgeClient]:
    """One bridge process (butter at the origin, 320 x 240) and a client that is ready."""
    proc = module_processes.node(BRIDGE, "--ros-args", *SMALL_CAMERA, *FAST_CLOCK)

    def describe() -> str:
        state = "running" if proc.poll() is None else f"exited with {proc.returncode}"
        return f"bridge process {state}; its output:\n{module_processes.output(proc)}"

    with cli_node("sim_bridge_test") as (node, executor):
        client = BridgeClient(node, executor, describe)
        client.wait_ready()
        yield client
    assert proc.poll() is None, f"the bridge died during the tests\n{describe()}"


@pytest.fixture
def fresh(bridge: BridgeClient) -> BridgeClient:
    """The bridge reset to rect1 (a 9 cm square) at the origin with default physics, no fault
    injection."""
    response = bridge.reset(object="rect1", initial_pose__x=0.0, initial_pose__y=0.0,
                            initial_pose__theta=0.0, faults__frame_drop=0.0,
                            faults__frame_delay=0.0, faults__push_refusal=0.0)
    assert response.success, response.message
    return bridge


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------
def deproject(depth: np.ndarray, k: np.ndarray, t_world_camera: np.ndarray) -> np.ndarray:
    """World points (H, W, 3) of every depth pixel (NaN where depth is NaN)."""
    h, w = depth.shape
    v, u = np.mgrid[0:h, 0:w].astype(float)
    cam = np.stack([(u - k[0, 2]) / k[0, 0] * depth, (v - k[1, 2]) / k[1, 1] * depth, depth], -1)
    return cam @ t_world_camera[:3, :3].T + t_world_camera[:3, 3]


def pixel_footprints(depth: np.ndarray, k: np.ndarray, t_world_camera: np.ndarray) -> np.ndarray:
    """Area (m^2) each pixel covers on a horizontal surface (corrects perspective sampling)."""
    h, w = depth.shape
    v, u = np.mgrid[0:h, 0:w].astype(float)
    rays = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones_like(u)], -1)
    unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    up_in_camera = t_world_camera[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    cos_incidence = np.abs(unit @ up_in_camera)
    cos_off_axis = unit[..., 2]
    return depth**2 / (k[0, 0] * k[1, 1] * cos_off_axis * cos_incidence)


def executed_push(bridge: BridgeClient, points: list[tuple[float, float]]) -> tuple[Path, float]:
    """Send a push and wait for its pusher/executed; return it and the time it was sent."""
    n_executed = len(bridge.got.executed)
    clock_before = seconds_from_stamp(bridge.got.clock[-1].clock) if bridge.got.clock else 0.0
    bridge.send_push(points)
    bridge.spin_until(lambda: len(bridge.got.executed) > n_executed, PUSH_TIMEOUT,
                      "pusher/executed")
    executed = bridge.got.executed[-1]
    end = seconds_from_stamp(executed.header.stamp)
    # The ground truth after the push is published right after pusher/executed.
    bridge.spin_until(lambda: bridge.pose_stamp() >= end, 10.0, "the object pose after the push")
    return executed, clock_before


def counter(values: dict[str, str], name: str) -> int:
    return int(values[name])


# --------------------------------------------------------------------------------------------
# The parameter YAML (no process needed)
# --------------------------------------------------------------------------------------------
def test_parameter_yaml_documents_every_parameter_with_its_default() -> None:
    import yaml

    from sim_bridge.params import PARAMETERS

    path = FilePath(__file__).resolve().parents[2] / "src/pushbot_bringup/config/sim_bridge.yaml"
    text = path.read_text()
    params = yaml.safe_load(text)["sim_bridge_node"]["ros__parameters"]
    assert params["use_sim_time"] is False  # the bridge is the clock source
    flat = {f"{k}.{kk}": vv for k, v in params.items() if isinstance(v, dict)
            for kk, vv in v.items()}
    flat.update({k: v for k, v in params.items() if not isinstance(v, dict)})
    for spec in PARAMETERS:
        assert spec.default is not None, f"{spec.name} has no value (breaks parameter dumps)"
        assert spec.name in flat, f"{spec.name} is not in {path.name}"
        value = flat[spec.name]
        assert value == spec.default and type(value) is type(spec.default), spec.name


# --------------------------------------------------------------------------------------------
# Interface: topics, types, QoS, camera model
# --------------------------------------------------------------------------------------------
SENSOR = (ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE)
EXPECTED_PUBLISHERS = {
    "/camera/color/image_raw": ("sensor_msgs/msg/Image", SENSOR),
    "/camera/aligned_depth_to_color/image_raw": ("sensor_msgs/msg/Image", SENSOR),
    "/camera/color/camera_info": ("sensor_msgs/msg/CameraInfo", SENSOR),
    "/camera/color/extrinsics": ("geometry_msgs/msg/TransformStamped",
                                 (ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL)),
    "/clock": ("rosgraph_msgs/msg/Clock",
               (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)),
    "/sim/object_pose": ("geometry_msgs/msg/PoseStamped",
                         (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)),
    "/pusher/executed": ("nav_msgs/msg/Path",
                         (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)),
    "/pusher/refused": ("diagnostic_msgs/msg/DiagnosticStatus",
                        (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)),
    "/diagnostics": ("diagnostic_msgs/msg/DiagnosticArray",
                     (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)),
}


def test_topics_services_types_and_qos(bridge: BridgeClient) -> None:
    node = bridge.node
    for topic, (msg_type, (reliability, durability)) in EXPECTED_PUBLISHERS.items():
        infos = bridge.spin_until(
            lambda t=topic: [i for i in node.get_publishers_info_by_topic(t)
                             if i.node_name == BRIDGE],
            10.0, f"the bridge's publisher on {topic}")
        assert len(infos) == 1, f"{topic}: {len(infos)} publishers from the bridge"
        info = infos[0]
        assert info.topic_type == msg_type, topic
        assert info.qos_profile.reliability == reliability, topic
        assert info.qos_profile.durability == durability, topic
    subs = [i for i in node.get_subscriptions_info_by_topic("/planner/push")
            if i.node_name == BRIDGE]
    assert len(subs) == 1 and subs[0].topic_type == "nav_msgs/msg/Path"
    assert subs[0].qos_profile.reliability == ReliabilityPolicy.RELIABLE
    services = dict(node.get_service_names_and_types_by_node(BRIDGE, "/"))
    assert services[f"/{BRIDGE}/reset"] == ["std_srvs/srv/Trigger"]
    try:
        import tf2_msgs  # noqa: F401
    except ImportError:  # pip install: no tf2_msgs, so no /tf (docs/design/topics.md#tf-note)
        assert not [i for i in node.get_publishers_info_by_topic("/tf")
                    if i.node_name == BRIDGE]


def test_frame_triple_shares_stamp_frame_and_size(bridge: BridgeClient) -> None:
    rgb, depth, info = bridge.spin_until(bridge.latest_frame, 10.0, "a complete camera frame")
    for msg in (rgb, depth, info):
        assert msg.header.frame_id == "camera_color_optical_frame"
        assert (msg.width, msg.height) == (WIDTH, HEIGHT)
    assert (rgb.encoding, rgb.step) == ("rgb8", 3 * WIDTH)
    assert (depth.encoding, depth.step) == ("32FC1", 4 * WIDTH)
    k = camera_matrix_from_info(info)
    # Principal point inside the image (near its centre), square-ish pixels, P = [K | 0].
    assert 0.4 * WIDTH < k[0, 2] < 0.6 * WIDTH and 0.4 * HEIGHT < k[1, 2] < 0.6 * HEIGHT
    assert k[0, 0] == pytest.approx(k[1, 1], rel=0.05)
    np.testing.assert_array_equal(np.reshape(info.p, (3, 4))[:, :3], k)
    assert info.distortion_model == "plumb_bob" and not any(info.d)
    assert image_to_array(rgb).shape == (HEIGHT, WIDTH, 3)
    assert image_to_array(depth).dtype == np.float32
    extrinsics = bridge.got.extrinsics[-1]
    assert (extrinsics.header.frame_id, extrinsics.child_frame_id) == (
        "world", "camera_color_optical_frame")


def test_the_camera_streams_still_frames_while_the_world_rests(fresh: BridgeClient) -> None:
    # A real camera does not stop when nothing moves: the resting world's frames come with
    # advancing stamps (sim time runs as wall time while idle), /clock ahead of or at each, the
    # object where it was, and fresh sensor noise.
    assert fresh.reset(depth_noise=True).success
    try:
        n_rgb = len(fresh.got.rgb)
        fresh.spin_until(lambda: len(fresh.got.rgb) >= n_rgb + 3, 10.0, "three more frames")
    finally:
        fresh.set_parameters(depth_noise=False)  # applies at the next test's reset
    frames = fresh.got.rgb[n_rgb:]
    stamps = [seconds_from_stamp(m.header.stamp) for m in frames]
    assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False)), stamps
    clock = seconds_from_stamp(fresh.got.clock[-1].clock)
    assert clock >= stamps[-1]
    poses = [xytheta_from_pose(m) for m in fresh.got.pose[-3:]]
    np.testing.assert_allclose(poses[0], poses[-1], atol=1e-12)  # nothing moved
    depth = {seconds_from_stamp(m.header.stamp): image_to_array(m) for m in fresh.got.depth}
    both = [t for t in stamps if t in depth]
    assert len(both) >= 2
    a, b = depth[both[0]], depth[both[-1]]
    assert not np.array_equal(np.nan_to_num(a), np.nan_to_num(b))  # fresh noise per frame


def test_table_pixels_deproject_to_the_table_plane(bridge: BridgeClient) -> None:
    bridge.spin_until(lambda: bridge.got.pose, 10.0, "sim/object_pose")
    _, depth_msg, info = bridge.spin_until(bridge.latest_frame, 10.0, "a camera frame")
    depth = image_to_array(depth_msg)
    points = deproject(depth, camera_matrix_from_info(info),
                       matrix_from_transform(bridge.got.extrinsics[-1]))
    obj = bridge.object_pose()
    # Pixels well inside the image, at least 15 cm from the object: table only.
    for fu, fv in [(0.15, 0.2), (0.85, 0.2), (0.15, 0.85), (0.85, 0.85), (0.5, 0.1), (0.5, 0.95)]:
        u, v = int(fu * WIDTH), int(fv * HEIGHT)
        p = points[v, u]
        assert np.all(np.isfinite(p)), f"no depth at pixel ({u}, {v})"
        assert np.linalg.norm(p[:2] - obj[:2]) > 0.15, f"pixel ({u}, {v}) is near the object"
        assert abs(p[2]) < 0.002, f"pixel ({u}, {v}) deprojects to z = {p[2] * 1000:.2f} mm"


def test_object_pixels_project_to_the_ground_truth_pose(fresh: BridgeClient) -> None:
    response = fresh.reset(initial_pose__x=0.04, initial_pose__y=-0.03, initial_pose__theta=0.3)
    assert response.success, response.message
    truth = fresh.object_pose()
    _, depth_msg, info = fresh.frame_after(fresh.pose_stamp())
    depth = image_to_array(depth_msg)
    k, t_wc = camera_matrix_from_info(info), matrix_from_transform(fresh.got.extrinsics[-1])
    points = deproject(depth, k, t_wc)
    thickness = load_object("rect1").thickness
    # Segment by height: the top face of the object (anything else is the table or the pusher,
    # whose top is far above and whose side is a thin strip, removed by the distance gate).
    top = np.abs(points[..., 2] - thickness) < 0.002
    centre = np.nanmedian(points[top][:, :2], axis=0)
    top &= np.linalg.norm(points[..., :2] - centre, axis=-1) < 0.08
    assert top.sum() > 200, f"only {top.sum()} object pixels"
    weights = pixel_footprints(depth, k, t_wc)[top]
    xy = points[top][:, :2]
    centroid = weights @ xy / weights.sum()
    assert np.linalg.norm(centroid - truth[:2]) < 0.003, (centroid, truth)
    # The square's principal axes are degenerate; its edge directions give theta mod pi/2.
    area = weights.sum()
    assert area == pytest.approx(0.09 * 0.09, rel=0.1)
    d = xy - centroid
    radius = np.linalg.norm(d, axis=1)
    corners = d[radius > np.quantile(radius, 0.99)]
    corner_angle = np.arctan2(corners[:, 1], corners[:, 0]) - math.pi / 4
    wrapped = (corner_angle - truth[2] + math.pi / 4) % (math.pi / 2) - math.pi / 4
    assert np.median(np.abs(wrapped)) < math.radians(4)


def test_default_camera_is_640x480(processes: ProcessManager) -> None:
    # Its own namespace, and the absolute topics remapped: the module's bridge stays the only
    # /clock and /diagnostics source of the session.
    proc = processes.node(BRIDGE, "--ros-args", "-r", "__ns:=/default_camera",
                          "-r", "/clock:=/default_camera/clock",
                          "-r", "/diagnostics:=/default_camera/diagnostics")
    infos: list[CameraInfo] = []
    with cli_node("sim_bridge_default_camera") as (node, executor):
        node.create_subscription(CameraInfo, "/default_camera/camera/color/camera_info",
                                 infos.append, qos_profile_sensor_data)
        spin_until(executor, lambda: infos or proc.poll() is not None,
                   time.monotonic() + STARTUP_TIMEOUT)
    assert infos, f"no camera_info from the default bridge\n{processes.output(proc)}"
    assert (infos[-1].width, infos[-1].height) == (640, 480)
    k = camera_matrix_from_info(infos[-1])
    assert k[0, 2] == pytest.approx(319.5, abs=2) and k[1, 2] == pytest.approx(239.5, abs=2)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (("-p", "object:=no_such_object"), "no_such_object"),
        (("-p", "image_width:=5"), "image_width"),
        (("-p", "com_offset:=[0.01]"), "com_offset"),
    ],
)
def test_bad_parameters_fail_start_up_clearly(
    processes: ProcessManager, args: tuple[str, ...], expected: str
) -> None:
    proc = processes.node(BRIDGE, "--ros-args", *SMALL_CAMERA, *args)
    try:
        code = proc.wait(timeout=STARTUP_TIMEOUT)
    except Exception:
        pytest.fail(f"the bridge did not exit on a bad parameter\n{processes.output(proc)}")
    output = processes.output(proc)
    assert code != 0, output
    assert expected in output, output


# --------------------------------------------------------------------------------------------
# Pushing
# --------------------------------------------------------------------------------------------
HALF = 0.045  # rect1 half width, m
THROUGH_CENTRE = [(-HALF - 0.03, 0.0), (-HALF, 0.0), (-HALF + 0.05, 0.0)]


def test_push_through_the_centre_moves_the_object_forward(fresh: BridgeClient) -> None:
    before = fresh.object_pose()
    executed, clock_before = executed_push(fresh, THROUGH_CENTRE)
    assert executed.header.frame_id == "world" and len(executed.poses) == 2
    t_start, t_end = (seconds_from_stamp(p.header.stamp) for p in executed.poses)
    assert t_start >= clock_before and t_end > t_start
    start, end = points_from_path(executed)
    assert np.linalg.norm(end - THROUGH_CENTRE[2]) < 0.01, end
    # Straight motion at push_speed (0.02 m/s): duration agrees with the distance.
    assert t_end - t_start == pytest.approx(np.linalg.norm(end - start) / 0.02, rel=0.2)
    # The fresh frame and the ground truth after the push come after the push ended.
    frame = fresh.frame_after(t_end)
    assert seconds_from_stamp(frame[0].header.stamp) >= t_end
    after = fresh.object_pose()
    moved = after - before
    assert 0.03 < moved[0] < 0.06, moved
    assert abs(moved[1]) < 0.005, moved
    assert abs(moved[2]) < math.radians(3), moved
    clock_after = fresh.spin_until(
        lambda: [c for c in fresh.got.clock if seconds_from_stamp(c.clock) >= t_end],
        5.0, "/clock at the end of the push")
    assert seconds_from_stamp(clock_after[-1].clock) > clock_before
    # /clock ticked while the push ran (at clock_rate), not only at its end, and never went
    # backwards, not even across the resets before.
    during = {seconds_from_stamp(c.clock) for c in fresh.got.clock
              if clock_before < seconds_from_stamp(c.clock) < t_end}
    assert during, "no /clock message while the push ran"
    times = [seconds_from_stamp(c.clock) for c in fresh.got.clock]
    assert np.all(np.diff(times) >= 0), "/clock went backwards"


def test_push_that_misses_leaves_the_object_in_place(fresh: BridgeClient) -> None:
    before = fresh.object_pose()
    executed_push(fresh, [(-0.12, 0.12), (-0.08, 0.12), (0.05, 0.12)])
    moved = fresh.object_pose() - before
    assert np.all(np.abs(moved[:2]) < 0.0005) and abs(moved[2]) < 0.005, moved


def test_push_while_busy_is_rejected_not_queued(fresh: BridgeClient) -> None:
    n_executed, n_diag = len(fresh.got.executed), len(fresh.got.diagnostics)
    fresh.send_push(THROUGH_CENTRE)
    fresh.send_push([(0.1, 0.1), (0.08, 0.1), (0.0, 0.1)])  # arrives while the first runs
    rejected = fresh.spin_until(
        lambda: [d for d in fresh.diagnostics_since(n_diag) if "busy" in d["last_refusal"]],
        PUSH_TIMEOUT, "a diagnostic rejecting the push sent while busy")
    assert rejected[0]["_level"] == "1"  # WARN
    fresh.spin_until(lambda: len(fresh.got.executed) > n_executed, PUSH_TIMEOUT,
                     "pusher/executed of the first push")
    n_after = len(fresh.got.diagnostics)
    idle = fresh.spin_until(
        lambda: [d for d in fresh.diagnostics_since(n_after) if d["state"] == "idle"],
        10.0, "an idle diagnostic after the push")
    # Exactly one push ran; the second one is counted as rejected, never executed later.
    assert len(fresh.got.executed) == n_executed + 1
    first = fresh.got.diagnostics[n_diag]
    assert counter(idle[-1], "pushes_executed") == counter(first, "pushes_executed") + 1
    assert counter(idle[-1], "pushes_rejected_busy") >= 1


def _bad_path(kind: str) -> tuple[list[tuple[float, float]], str]:
    points = list(THROUGH_CENTRE)
    if kind == "two poses":
        return points[:2], "world"
    if kind == "nan":
        return [points[0], (math.nan, 0.0), points[2]], "world"
    if kind == "out of workspace":
        return [(-3.0, 0.0), points[1], points[2]], "world"
    return points, "camera_color_optical_frame"


@pytest.mark.parametrize(
    ("kind", "reason"),
    [
        ("two poses", "path has 2 poses, expected exactly 3"),
        ("nan", "pose 1 position is not finite"),
        ("out of workspace", "outside the workspace"),
        ("wrong frame", "frame_id is 'camera_color_optical_frame', expected 'world'"),
    ],
)
def test_malformed_push_is_rejected_and_the_node_keeps_running(
    fresh: BridgeClient, kind: str, reason: str
) -> None:
    before = fresh.object_pose()
    n_executed, n_diag = len(fresh.got.executed), len(fresh.got.diagnostics)
    points, frame_id = _bad_path(kind)
    fresh.send_push(points, frame_id=frame_id)
    fresh.spin_until(
        lambda: [d for d in fresh.diagnostics_since(n_diag) if reason in d["last_refusal"]],
        10.0, f"a diagnostic naming the problem ({reason!r})")
    assert len(fresh.got.executed) == n_executed
    np.testing.assert_allclose(fresh.object_pose(), before, atol=1e-6)
    # The node is still alive and accepts the next valid push.
    executed_push(fresh, THROUGH_CENTRE)
    assert fresh.object_pose()[0] > before[0] + 0.02


# --------------------------------------------------------------------------------------------
# Knock and fault injection
# --------------------------------------------------------------------------------------------
def _knock(bridge: BridgeClient, delta: tuple[float, float, float],
           frame_id: str = "world") -> None:
    from push_ros.poses import pose_stamped_msg
    from push_ros.stamps import stamp_from_seconds

    msg = pose_stamped_msg(np.zeros(3), stamp_from_seconds(0.0), frame_id)
    msg.pose.position.x, msg.pose.position.y = float(delta[0]), float(delta[1])  # NaN too
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(delta[2] / 2), math.cos(delta[2] / 2)
    bridge.knock_pub.publish(msg)


def test_a_knock_displaces_the_object_at_rest(fresh: BridgeClient) -> None:
    before, t_before = fresh.object_pose(), fresh.pose_stamp()
    n_executed = len(fresh.got.executed)
    fresh.spin_until(lambda: fresh.knock_pub.get_subscription_count() > 0, 10.0, "sim/knock")
    _knock(fresh, (0.02, -0.01, 0.3))
    fresh.spin_until(lambda: np.linalg.norm(fresh.object_pose()[:2] - before[:2]) > 0.01,
                     PUSH_TIMEOUT, "the knocked pose")
    after = fresh.object_pose()
    np.testing.assert_allclose(after - before, [0.02, -0.01, 0.3], atol=1e-3)
    assert fresh.pose_stamp() > t_before  # a fresh frame of the knocked scene (sim time ran)
    fresh.frame_after(fresh.pose_stamp())
    assert len(fresh.got.executed) == n_executed  # nothing the robot did
    # Refused knocks change nothing and are counted.
    n_diag = len(fresh.got.diagnostics)
    for delta, frame_id, reason in (((0.2, 0.0, 0.0), "world", "larger than 0.1 m"),
                                    ((0.01, 0.0, 0.0), "object", "expected 'world'"),
                                    ((math.nan, 0.0, 0.0), "world", "finite")):
        _knock(fresh, delta, frame_id)
        fresh.spin_until(lambda r=reason: [d for d in fresh.diagnostics_since(n_diag)
                                           if r in d["last_refusal"]], 10.0, reason)
    np.testing.assert_allclose(fresh.object_pose(), after, atol=1e-6)
    idle = fresh.spin_until(lambda: [d for d in fresh.diagnostics_since(n_diag)
                                     if counter(d, "knocks_rejected") >= 3], 10.0, "counts")
    assert counter(idle[-1], "knocks") >= 1


def test_fault_injection_refuses_pushes_and_drops_frames(fresh: BridgeClient) -> None:
    try:
        assert fresh.reset(faults__push_refusal=1.0, faults__frame_drop=0.9,
                           faults__seed=3).success
        before, n_executed = fresh.object_pose(), len(fresh.got.executed)
        n_diag = len(fresh.got.diagnostics)
        fresh.send_push(THROUGH_CENTRE)
        fresh.spin_until(lambda: [d for d in fresh.diagnostics_since(n_diag)
                                  if counter(d, "pushes_refused_fault") >= 1], 10.0,
                         "the refused push")
        # Idle re-publications at 2 Hz, each dropped with probability 0.9: some are dropped.
        fresh.spin_until(lambda: [d for d in fresh.diagnostics_since(n_diag)
                                  if counter(d, "frames_dropped") >= 1], 20.0, "a dropped frame")
        assert len(fresh.got.executed) == n_executed
        np.testing.assert_allclose(fresh.object_pose(), before, atol=1e-6)
    finally:
        assert fresh.reset(faults__push_refusal=0.0, faults__frame_drop=0.0).success
    executed_push(fresh, THROUGH_CENTRE)  # off again: pushes run


# --------------------------------------------------------------------------------------------
# Reset
# --------------------------------------------------------------------------------------------
def test_reset_after_set_parameters_rebuilds_the_scene(fresh: BridgeClient) -> None:
    executed_push(fresh, THROUGH_CENTRE)  # disturb the scene first
    response = fresh.reset(object="butter", initial_pose__x=0.05, initial_pose__y=-0.04,
                           initial_pose__theta=0.7)
    assert response.success, response.message
    assert "butter" in response.message
    np.testing.assert_allclose(fresh.object_pose(), [0.05, -0.04, 0.7], atol=0.002)
    n_diag = len(fresh.got.diagnostics)
    fresh.spin_until(lambda: [d for d in fresh.diagnostics_since(n_diag)
                              if d["object"] == "butter"], 10.0, "diagnostics naming butter")


def test_an_invalid_parameter_is_refused_when_set(fresh: BridgeClient) -> None:
    # push_ros.node: the on-set callback validates with SimBridgeParams.from_values, so a
    # value the next ~/reset would refuse is refused at once, with the reason.
    failed = fresh.try_set_parameters(object="no_such_object")
    assert len(failed) == 1 and "unknown object 'no_such_object'" in failed[0][1], failed
    assert fresh.reset().success  # nothing changed


def test_reset_with_a_bad_parameter_is_refused_and_keeps_the_scene(
    fresh: BridgeClient,
) -> None:
    executed_push(fresh, THROUGH_CENTRE)  # a scene that differs from the initial one
    before = fresh.object_pose()
    response = fresh.reset(use_com_offset=True, com_offset=[0.5, 0.0])  # COM outside: refused
    assert not response.success
    assert "com" in response.message, response.message
    fresh.set_parameters(object="rect1", use_com_offset=False, com_offset=[0.0, 0.0])
    n_poses = len(fresh.got.pose)
    fresh.spin_until(lambda: len(fresh.got.pose) > n_poses, 10.0, "an idle ground-truth pose")
    np.testing.assert_allclose(fresh.object_pose(), before, atol=1e-6)
    assert fresh.reset().success  # and the node still works


def test_reset_while_a_push_runs_is_refused(fresh: BridgeClient) -> None:
    # A slow push (5 cm at 2 mm/s = 25 s of sim time) keeps the bridge busy long enough.
    assert fresh.reset(push_speed=0.002).success
    n_executed, n_diag = len(fresh.got.executed), len(fresh.got.diagnostics)
    fresh.send_push(THROUGH_CENTRE)
    fresh.spin_until(lambda: [d for d in fresh.diagnostics_since(n_diag) if d["state"] == "busy"],
                     10.0, "a busy diagnostic")
    response = fresh.call(fresh.reset_client, Trigger.Request())
    assert not response.success and "busy" in response.message, response.message
    fresh.spin_until(lambda: len(fresh.got.executed) > n_executed, PUSH_TIMEOUT,
                     "pusher/executed of the slow push")
    assert fresh.reset(push_speed=0.02).success
