"""In-process tests of segmentation_node: real rendered frames in, pose/outline/mask out.

The node and a test node share one rclpy context and executor; frames rendered by the pybullet
world travel as real Image/CameraInfo/TransformStamped messages over DDS (localhost). Camera
topics are best effort, so the test re-publishes a frame until the node's answer arrives;
every wait is bounded and event-driven (no sleeps).
"""

from __future__ import annotations

import math
import time
from array import array
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros]

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import (  # noqa: E402
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from push_perception.segmentation_node import PARAMETERS, SegmentationNode  # noqa: E402
from push_ros.frames import CAMERA_FRAME, WORLD_FRAME  # noqa: E402
from push_ros.images import (  # noqa: E402
    camera_info_msg,
    depth_image_msg,
    image_to_array,
    rgb_image_msg,
)
from push_ros.occlusion import read_occlusion  # noqa: E402
from push_ros.outline import outline_from_cloud  # noqa: E402
from push_ros.poses import transform_msg, xytheta_from_pose  # noqa: E402
from push_ros.refusal import stamp_key  # noqa: E402
from push_ros.stamps import stamp_from_seconds  # noqa: E402
from pushbot.ros2cli.discovery import spin_until  # noqa: E402

RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
TIMEOUT = 30.0  # s per wait; a frame takes well under a second even on the loaded machine
NODE = "segmentation_node"


@dataclass(frozen=True)
class Rendered:
    rgb: np.ndarray
    depth: np.ndarray
    mask: np.ndarray
    k: np.ndarray
    t: np.ndarray
    pose: np.ndarray


@pytest.fixture(scope="module")
def frames(world_factory: Callable[..., Any]) -> dict[str, Rendered]:
    """Butter seen by the default 640 x 480 camera at a few poses (rendered once)."""
    world = world_factory(object="butter", object_pose=(0.02, -0.05, 0.4))
    out = {}
    for name, pose in (("a", (0.02, -0.05, 0.4)), ("b", (0.06, 0.01, 0.95)),
                       ("gone", (1.4, 0.0, 0.0)), ("edge", (0.0, 0.38, 0.0))):
        world.set_object_pose(pose)
        f = world.render()
        out[name] = Rendered(f.rgb, f.depth, f.mask, f.camera_matrix, f.T_world_camera,
                             f.object_pose)
    return out


class Harness:
    """The node under test plus a test node that feeds it and records what it publishes."""

    def __init__(self, context: Any, anchor_timeout: float = 0.0,
                 overrides: tuple[Parameter, ...] = ()) -> None:
        # No re-anchoring wait after start-up unless a test asks for it (the restart test).
        self.node = SegmentationNode(context=context, parameter_overrides=[
            Parameter("anchor_timeout", value=float(anchor_timeout)), *overrides])
        self.client = rclpy.create_node("perception_test_client", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.client)
        c = self.client
        sensor = qos_profile_sensor_data
        self.pub_rgb = c.create_publisher(Image, "camera/color/image_raw", sensor)
        self.pub_depth = c.create_publisher(Image, "camera/aligned_depth_to_color/image_raw",
                                            sensor)
        self.pub_info = c.create_publisher(CameraInfo, "camera/color/camera_info", sensor)
        self.pub_extrinsics = c.create_publisher(TransformStamped, "camera/color/extrinsics",
                                                 LATCHED)
        self.poses: list[PoseWithCovarianceStamped] = []
        self.outlines: list[PointCloud2] = []
        self.masks: list[Image] = []
        self.diagnostics: list[dict[str, str]] = []
        c.create_subscription(PoseWithCovarianceStamped, "perception/object_pose",
                              self.poses.append, RELIABLE)
        c.create_subscription(PointCloud2, "perception/outline", self.outlines.append, LATCHED)
        c.create_subscription(Image, "perception/mask", self.masks.append, sensor)
        c.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, RELIABLE)
        self.reset_client = c.create_client(Trigger, f"/{NODE}/reset")
        self.time = 100.0
        self.wait(lambda: (self.pub_rgb.get_subscription_count() > 0
                           and self.pub_depth.get_subscription_count() > 0
                           and self.pub_info.get_subscription_count() > 0
                           and self.pub_extrinsics.get_subscription_count() > 0
                           and self.reset_client.service_is_ready()), "discovery")

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.startswith(f"/{NODE}:"):
                values = {kv.key: kv.value for kv in status.values}
                values["_level"] = str(int.from_bytes(status.level, "little"))
                values["_message"] = status.message
                self.diagnostics.append(values)

    def wait(self, predicate: Callable[[], Any], what: str, timeout: float = TIMEOUT,
             resend: Callable[[], None] | None = None) -> Any:
        """Spin until ``predicate()``; call ``resend`` about every 0.5 s meanwhile."""
        deadline = time.monotonic() + timeout
        while True:
            if resend is not None:
                resend()
            if spin_until(self.executor, predicate, min(deadline, time.monotonic() + 0.5)):
                return predicate()
            if time.monotonic() >= deadline:
                pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}; "
                            f"diagnostics: {self.diagnostics[-1:] or 'none'}")

    def send_extrinsics(self, t: np.ndarray) -> None:
        self.pub_extrinsics.publish(transform_msg(t, stamp_from_seconds(self.time), WORLD_FRAME,
                                                  CAMERA_FRAME))

    def frame_messages(self, f: Rendered) -> tuple[Image, Image, CameraInfo]:
        """Messages of a frame with a fresh stamp."""
        self.time += 0.5
        stamp = stamp_from_seconds(self.time)
        h, w = f.depth.shape
        return (rgb_image_msg(f.rgb, stamp), depth_image_msg(f.depth, stamp),
                camera_info_msg(f.k, w, h, stamp))

    def publish(self, msgs: tuple[Any, ...]) -> None:
        rgb, depth, info = msgs
        for pub, msg in ((self.pub_rgb, rgb), (self.pub_depth, depth), (self.pub_info, info)):
            if msg is not None:
                pub.publish(msg)

    def pose_for(self, f: Rendered) -> PoseWithCovarianceStamped:
        """Send a frame (re-sent while lost) and return the pose the node publishes for it."""
        msgs = self.frame_messages(f)
        stamp = msgs[0].header.stamp
        return self.wait(lambda: next((p for p in self.poses if p.header.stamp == stamp), None),
                         "a pose for the frame", resend=lambda: self.publish(msgs))

    def counter(self, kind: str) -> int:
        return max((int(d[kind]) for d in self.diagnostics if kind in d), default=0)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.client.destroy_node()


@pytest.fixture
def harness(ros_context: Any) -> Iterator[Harness]:
    h = Harness(ros_context)
    try:
        yield h
    finally:
        h.close()


def test_parameter_yaml_documents_every_parameter_with_its_default() -> None:
    import yaml

    path = Path(__file__).resolve().parents[2] / "src/pushbot_bringup/config/push_perception.yaml"
    nested = yaml.safe_load(path.read_text())[NODE]["ros__parameters"]
    params = {f"{k}.{kk}": vv for k, v in nested.items() if isinstance(v, dict)
              for kk, vv in v.items()}
    params.update({k: v for k, v in nested.items() if not isinstance(v, dict)})
    assert params["use_sim_time"] is True
    for spec in PARAMETERS:
        if spec.default is None:  # an optional parameter without a value (a string array)
            continue
        assert spec.name in params, f"{spec.name} is not in {path.name}"
        value = params[spec.name]
        assert value == spec.default and type(value) is type(spec.default), spec.name


def test_rendered_frames_give_pose_outline_and_mask(harness: Harness,
                                                    frames: dict[str, Rendered]) -> None:
    h, a, b = harness, frames["a"], frames["b"]
    # Real-robot default: wall time unless use_sim_time is set (YAML, graph runner).
    assert h.node.get_parameter("use_sim_time").value is False
    h.send_extrinsics(a.t)
    first = h.pose_for(a)
    assert first.header.frame_id == WORLD_FRAME
    xyt = xytheta_from_pose(first.pose.pose)
    assert np.linalg.norm(xyt[:2] - a.pose[:2]) < 0.003  # the object frame origin, world
    assert xyt[2] == pytest.approx(0.0, abs=1e-9)  # the reference frame of the episode
    cov = np.array(first.pose.covariance).reshape(6, 6)
    assert 0 < cov[0, 0] == cov[1, 1] < 1e-4 and 0 < cov[5, 5] < 0.01
    # The outline (latched) and the mask of that frame.
    outline = h.wait(lambda: h.outlines[-1] if h.outlines else None, "the outline")
    assert outline.header.frame_id == "object" and outline.header.stamp == first.header.stamp
    points, normals = outline_from_cloud(outline)
    assert len(points) > 100
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
    x, y = points[:, 0], points[:, 1]
    assert np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y) > 0  # counter-clockwise
    mask_msg = h.wait(lambda: next((m for m in h.masks
                                    if m.header.stamp == first.header.stamp), None), "the mask")
    mask = image_to_array(mask_msg) > 0
    assert np.count_nonzero(mask & a.mask) / np.count_nonzero(mask | a.mask) > 0.9
    # A second frame: position against the truth, yaw relative to the first frame.
    second = xytheta_from_pose(h.pose_for(b).pose.pose)
    assert np.linalg.norm(second[:2] - b.pose[:2]) < 0.003
    turn = (b.pose[2] - a.pose[2] + math.pi) % (2 * math.pi) - math.pi
    assert math.degrees(abs(second[2] - turn)) < 2.0
    # ~/reset: a new episode, so b becomes the reference (yaw 0) with a new outline.
    future = h.reset_client.call_async(Trigger.Request())
    assert h.wait(future.done, "the reset response") and future.result().success
    n_outlines = len(h.outlines)
    third = xytheta_from_pose(h.pose_for(b).pose.pose)
    assert third[2] == pytest.approx(0.0, abs=1e-9)
    h.wait(lambda: len(h.outlines) > n_outlines, "the new outline")


def test_frames_of_the_previous_episode_are_skipped_after_reset(
        harness: Harness, frames: dict[str, Rendered]) -> None:
    # The simulator re-publishes its last frame (same stamp) while idle; after ~/reset such a
    # frame must not become the new episode's reference (found running the graph).
    h, a, b = harness, frames["a"], frames["b"]
    h.send_extrinsics(a.t)
    old = h.frame_messages(a)
    h.wait(lambda: any(p.header.stamp == old[0].header.stamp for p in h.poses),
           "a pose for the old frame", resend=lambda: h.publish(old))
    future = h.reset_client.call_async(Trigger.Request())
    assert h.wait(future.done, "the reset response") and future.result().success
    n_poses = len(h.poses)
    h.wait(lambda: h.counter("previous_episode") >= 1, "a previous_episode count",
           resend=lambda: h.publish(old))
    assert len(h.poses) == n_poses  # the repeated old frame gave no pose
    first = xytheta_from_pose(h.pose_for(b).pose.pose)  # a newer frame: the new reference
    assert first[2] == pytest.approx(0.0, abs=1e-9)
    assert np.linalg.norm(first[:2] - b.pose[:2]) < 0.003
    # A restarted clock (older stamps than before the reset) is not mistaken for the old scene.
    future = h.reset_client.call_async(Trigger.Request())
    assert h.wait(future.done, "the reset response") and future.result().success
    rgb, depth, info = h.frame_messages(a)
    for msg in (rgb, depth, info):
        msg.header.stamp = stamp_from_seconds(1.0)
    restarted = h.wait(lambda: next((p for p in h.poses if p.header.stamp == rgb.header.stamp),
                                    None), "a pose for an older-stamped frame",
                       resend=lambda: h.publish((rgb, depth, info)))
    assert xytheta_from_pose(restarted.pose.pose)[2] == pytest.approx(0.0, abs=1e-9)


def _bad_color_encoding(h: Harness, f: Rendered) -> tuple[Any, ...]:
    rgb, depth, info = h.frame_messages(f)
    rgb.encoding = "rgba8"
    return rgb, depth, info


def _short_color(h: Harness, f: Rendered) -> tuple[Any, ...]:
    rgb, depth, info = h.frame_messages(f)
    rgb.data = array("B", bytes(rgb.data)[: -rgb.step])  # one row missing: height * step
    return rgb, depth, info


def _bad_depth_encoding(h: Harness, f: Rendered) -> tuple[Any, ...]:
    rgb, depth, info = h.frame_messages(f)
    depth.encoding = "8UC1"
    return rgb, depth, info


def _depth_of_other_size(h: Harness, f: Rendered) -> tuple[Any, ...]:
    rgb, depth, info = h.frame_messages(f)
    return rgb, depth_image_msg(f.depth[::2, ::2].copy(), depth.header.stamp), info


def _depth_filled_with(value: float) -> Callable[[Harness, Rendered], tuple[Any, ...]]:
    def make(h: Harness, f: Rendered) -> tuple[Any, ...]:
        rgb, _, info = h.frame_messages(f)
        return rgb, depth_image_msg(np.full_like(f.depth, value), rgb.header.stamp), info

    return make


def _camera_info_of_other_size(h: Harness, f: Rendered) -> tuple[Any, ...]:
    rgb, depth, info = h.frame_messages(f)
    info.width = 320
    return rgb, depth, info


#: case -> (the input, the /diagnostics counter it increments: refusals of an input are
#: ``refused_<kind>``, a blind camera is the measurement outcome ``no_depth``).
BAD_INPUTS = {
    "bad_color": (_bad_color_encoding, "refused_color"),
    "bad_color_step": (_short_color, "refused_color"),
    "bad_depth": (_bad_depth_encoding, "refused_depth"),
    "size_mismatch": (_depth_of_other_size, "refused_size_mismatch"),
    "no_depth_nan": (_depth_filled_with(np.nan), "no_depth"),
    "no_depth_zero": (_depth_filled_with(0.0), "no_depth"),
    "bad_camera_info": (_camera_info_of_other_size, "refused_camera_info"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_frames_are_reported_and_the_node_keeps_working(
        case: str, harness: Harness, frames: dict[str, Rendered],
        capfd: pytest.CaptureFixture[str]) -> None:
    make, key = BAD_INPUTS[case]
    h = harness
    h.send_extrinsics(frames["a"].t)
    msgs = make(h, frames["a"])
    h.wait(lambda: h.counter(key) >= 1, f"a {key} count on /diagnostics",
           resend=lambda: h.publish(msgs))
    last = h.diagnostics[-1]
    assert last["_level"] == "1" and key in last["_message"]  # WARN, naming the problem
    assert key in last["last_problem"]
    if key.startswith("refused_"):  # a refusal: counted in refused too, and kept
        assert int(last["refused"]) >= 1 and last["last_refusal"]
    assert h.counter("poses") == 0 and not h.poses
    h.pose_for(frames["a"])  # still working
    err = capfd.readouterr().err
    assert ("refused " if key.startswith("refused_") else f"no pose ({key})") in err


def test_missing_extrinsics_then_recovery(harness: Harness,
                                          frames: dict[str, Rendered]) -> None:
    h, a = harness, frames["a"]
    msgs = h.frame_messages(a)
    h.wait(lambda: h.counter("refused_no_extrinsics") >= 1, "refused_no_extrinsics",
           resend=lambda: h.publish(msgs))
    assert not h.poses
    h.send_extrinsics(a.t)
    h.pose_for(a)


def test_missing_camera_info_is_reported(harness: Harness, frames: dict[str, Rendered]) -> None:
    h, a = harness, frames["a"]
    h.send_extrinsics(a.t)

    def send_without_info() -> None:
        rgb, depth, _ = h.frame_messages(a)
        h.publish((rgb, depth, None))

    h.wait(lambda: h.counter("refused_missing_camera_info") >= 1,
           "refused_missing_camera_info",
           resend=send_without_info)
    assert not h.poses
    h.pose_for(a)


@pytest.mark.parametrize(("name", "kind"), [("gone", "empty_mask"), ("edge", "out_of_view")])
def test_object_out_of_view_gives_no_pose(name: str, kind: str, harness: Harness,
                                          frames: dict[str, Rendered]) -> None:
    h, f = harness, frames[name]
    h.send_extrinsics(f.t)
    msgs = h.frame_messages(f)
    h.wait(lambda: h.counter(kind) >= 1, kind, resend=lambda: h.publish(msgs))
    assert not h.poses
    h.pose_for(frames["a"])


def test_a_restarted_node_re_anchors_to_the_estimators_episode(
        ros_context: Any, frames: dict[str, Rendered]) -> None:
    # A perception restarted mid-episode keeps the episode's orientation reference:
    # it matches its first frame against the estimator's latched outline (near the latched
    # estimate's yaw) instead of starting a new yaw 0, and re-publishes that outline unchanged.
    a, b = frames["a"], frames["b"]
    first = Harness(ros_context, anchor_timeout=5.0)
    try:
        first.send_extrinsics(a.t)
        first.pose_for(a)
        outline = first.wait(lambda: first.outlines[-1] if first.outlines else None,
                             "the outline")
        yaw_b = xytheta_from_pose(first.pose_for(b).pose.pose)[2]
        stamp_after = first.time
    finally:
        first.close()
    assert abs(yaw_b) > 0.3  # b is turned against a: a new reference would say 0
    restarted = Harness(ros_context, anchor_timeout=5.0)
    try:
        restarted.time = stamp_after
        c = restarted.client
        pub_outline = c.create_publisher(PointCloud2, "estimator/outline", LATCHED)
        pub_estimate = c.create_publisher(PoseWithCovarianceStamped, "estimator/object_pose",
                                          LATCHED)
        pub_outline.publish(outline)
        estimate = PoseWithCovarianceStamped()
        estimate.header.frame_id = WORLD_FRAME
        estimate.header.stamp = stamp_from_seconds(stamp_after)
        stale = yaw_b - 0.2  # a push has turned the object since the last estimate
        estimate.pose.pose.orientation.z = math.sin(stale / 2)
        estimate.pose.pose.orientation.w = math.cos(stale / 2)
        pub_estimate.publish(estimate)
        restarted.send_extrinsics(a.t)
        got = xytheta_from_pose(restarted.pose_for(b).pose.pose)
        assert got[2] == pytest.approx(yaw_b, abs=math.radians(1.0))
        republished = restarted.wait(lambda: restarted.outlines[-1] if restarted.outlines
                                     else None, "the re-published outline")
        assert republished.header.stamp == outline.header.stamp
        np.testing.assert_array_equal(outline_from_cloud(republished)[0],
                                      outline_from_cloud(outline)[0])
        restarted.wait(lambda: restarted.counter("anchored") == 1, "the anchored counter")
    finally:
        restarted.close()


# --------------------------------------------------------------------------------------------
# The robot in view (robot_filter.enabled)
# --------------------------------------------------------------------------------------------
#: tri1 at its reference pose, then at a later pose with the arm parked and posed over it
#: (tool tips; the shares the arm hides are checked in tests/perception/test_occlusion.py).
ARM_SHOTS = {"reference": ((0.0, 0.05, 0.3), None),
             "little": ((0.01, 0.06, 0.45), (0.12, 0.094, 0.072)),
             "much": ((0.01, 0.06, 0.45), (0.191, -0.002, 0.048))}


@pytest.fixture(scope="module")
def arm_frames(world_factory: Callable[..., Any]) -> dict[str, Any]:
    """Rendered shots of the arm scene with the joint state of each, and the URDF."""
    world = world_factory(robot="arm", object="tri1", object_pose=ARM_SHOTS["reference"][0])
    arm = world.arm
    out: dict[str, Any] = {"urdf": world.robot_description}
    for name, (pose, tip) in ARM_SHOTS.items():
        world.set_object_pose(pose)
        arm.set_positions(world.config.arm_park if tip is None else arm.inverse_kinematics(tip))
        f = world.render()
        out[name] = (Rendered(f.rgb, f.depth, f.mask, f.camera_matrix, f.T_world_camera,
                              f.object_pose), arm.state())
    return out


class ArmHarness(Harness):
    """The node with robot_filter.enabled; the test node also sends the robot's messages."""

    def __init__(self, context: Any) -> None:
        super().__init__(context, overrides=(Parameter("robot_filter.enabled", value=True),))
        c = self.client
        self.pub_description = c.create_publisher(String, "/robot_description", LATCHED)
        self.pub_joints = c.create_publisher(JointState, "/joint_states", RELIABLE)
        self.occlusion: list[Any] = []
        c.create_subscription(DiagnosticStatus, "perception/occlusion",
                              lambda m: self.occlusion.append(read_occlusion(m)), RELIABLE)
        self.wait(lambda: self.pub_joints.get_subscription_count() > 0
                  and self.pub_description.get_subscription_count() > 0, "discovery")

    def send_extrinsics(self, t: np.ndarray) -> None:
        super().send_extrinsics(t)  # latched: waited for, so no frame is refused for it
        self.wait(lambda: self.node._extrinsics.lookup(CAMERA_FRAME)[0] is not None,
                  "the extrinsics")

    def send_model(self, urdf: str) -> None:
        self.pub_description.publish(String(data=urdf))
        self.wait(lambda: self.node._robot.filter.robot is not None, "the robot model")

    def send_joints(self, stamp: Any, state: Any) -> None:
        """A joint state at ``stamp``, waited for (the frame must not overtake it)."""
        n = len(self.node._robot.filter.joints)
        msg = JointState(name=list(state.names), position=state.positions.tolist())
        msg.header.stamp = stamp
        self.pub_joints.publish(msg)
        self.wait(lambda: len(self.node._robot.filter.joints) > n, "the joint state")

    def occlusion_for(self, msgs: tuple[Any, ...]) -> Any:
        """Send a frame (re-sent while lost) and return its perception/occlusion report."""
        key = stamp_key(msgs[0].header.stamp)
        return self.wait(lambda: next((o for o in self.occlusion if o.stamp == key), None),
                         "the frame's perception/occlusion", resend=lambda: self.publish(msgs))


@pytest.fixture
def arm_harness(ros_context: Any) -> Iterator[ArmHarness]:
    h = ArmHarness(ros_context)
    try:
        yield h
    finally:
        h.close()


def test_the_node_reports_the_occluded_share_and_measures_the_visible_part(
        arm_harness: ArmHarness, arm_frames: dict[str, Any]) -> None:
    h = arm_harness
    h.send_extrinsics(arm_frames["reference"][0].t)
    h.send_model(arm_frames["urdf"])
    reports, poses = {}, {}
    for name in ("reference", "little", "much"):
        frame, state = arm_frames[name]
        msgs = h.frame_messages(frame)
        h.send_joints(msgs[0].header.stamp, state)
        reports[name] = h.occlusion_for(msgs)
        poses[name] = next((p for p in h.poses if p.header.stamp == msgs[0].header.stamp),
                           None)
    assert reports["reference"].outcome == "pose" and reports["reference"].occluded_share == 0
    assert reports["little"].outcome == "pose" and 0.05 < reports["little"].occluded_share < 0.3
    assert reports["little"].robot_pixels > 1000 and poses["little"] is not None
    moved = xytheta_from_pose(poses["little"].pose.pose)[:2] - xytheta_from_pose(
        poses["reference"].pose.pose)[:2]
    truth = np.subtract(ARM_SHOTS["little"][0], ARM_SHOTS["reference"][0])[:2]
    assert np.linalg.norm(moved - truth) < 1e-3
    much = reports["much"]
    assert much.outcome == "occluded" and much.occluded_share > 0.3 and poses["much"] is None
    assert "the robot hides" in much.reason
    h.wait(lambda: h.counter("occluded") >= 1, "the occluded count on /diagnostics")


def test_a_frame_whose_robot_pixels_cannot_be_computed_is_refused_with_the_reason(
        arm_harness: ArmHarness, arm_frames: dict[str, Any]) -> None:
    h = arm_harness
    frame, state = arm_frames["reference"]
    h.send_extrinsics(frame.t)
    assert h.occlusion_for(h.frame_messages(frame)).outcome == "no_robot_model"
    h.send_model(arm_frames["urdf"])
    assert h.occlusion_for(h.frame_messages(frame)).outcome == "no_joint_state"
    msgs = h.frame_messages(frame)
    h.send_joints(stamp_from_seconds(h.time - 1.0), state)  # a second before the frame
    stale = h.occlusion_for(msgs)
    assert stale.outcome == "stale_joint_state" and "1.000 s from the frame" in stale.reason
    assert not h.poses
    h.wait(lambda: h.counter("refused_stale_joint_state") >= 1
           and h.counter("refused_no_joint_state") >= 1
           and h.counter("refused_no_robot_model") >= 1, "the refusals on /diagnostics")
    msgs = h.frame_messages(frame)
    h.send_joints(msgs[0].header.stamp, state)
    assert h.occlusion_for(msgs).outcome == "pose"  # with a fresh joint state it measures
