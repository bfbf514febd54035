"""Fuzz tests of segmentation_node: hostile messages on every subscribed topic.

In-process against the real node class: the test calls the node's subscription callbacks (the
guarded callables it subscribed, ``node.on_color`` / ``on_depth`` / ``on_camera_info`` /
``on_extrinsics``) directly with real message objects built by hypothesis strategies, no DDS.
At least 2,000 messages per topic: wrong and unknown encodings, sizes that disagree with
``step`` and ``data``, zero and huge dimensions, NaN / inf depth, absurd intrinsics (one once asked
for a 9.98 TiB remap grid), non-unit quaternions, 1e30 m translations, extreme stamps, and
complete colour + depth + camera_info triples of small valid-layout images with random
content (the whole pipeline: CNN, geometry). Afterwards:

- no exception reached the guard (``callback_errors`` stays 0): every rejection was a checked
  one, counted under its kind;
- a rejected message changed nothing (the pending triples, the latched extrinsics);
- the node still measures a rendered pybullet frame correctly (pose on
  ``perception/object_pose`` within a few millimetres of the ground truth).

A smaller over-DDS run publishes 100 hostile messages per topic on the real topics of a node
spun by an executor and checks it is alive and still answers ``~/reset``.

Reproducible: hypothesis runs derandomized (fixed seed), no deadline.
"""

from __future__ import annotations

import math
import time
from array import array
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

rclpy = pytest.importorskip("rclpy")
hypothesis = pytest.importorskip("hypothesis")

from builtin_interfaces.msg import Time  # noqa: E402
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import (  # noqa: E402
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from sensor_msgs.msg import CameraInfo, Image, PointCloud2  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from push_perception.segmentation_node import SegmentationNode  # noqa: E402
from push_ros.frames import CAMERA_FRAME, WORLD_FRAME  # noqa: E402
from push_ros.images import camera_info_msg, depth_image_msg, rgb_image_msg  # noqa: E402
from push_ros.outline import outline_cloud_msg  # noqa: E402
from push_ros.poses import transform_msg, xytheta_from_pose  # noqa: E402
from push_ros.stamps import stamp_from_seconds  # noqa: E402
from pushbot.ros2cli.discovery import spin_until  # noqa: E402

#: Messages per topic of the in-process run (at least 2,000: rare malformations get hit).
N_FUZZ = 2000
FUZZ = settings(max_examples=N_FUZZ, deadline=None, derandomize=True, database=None,
                suppress_health_check=list(HealthCheck))
#: Complete triples through the whole pipeline (CNN included; slower per example).
N_TRIPLES = 150
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)

# ---- strategies ------------------------------------------------------------------------------
ENCODINGS = ["rgb8", "bgr8", "mono8", "32FC1", "16UC1", "mono16", "rgba8", "8UC3", "", "RGB8",
             "32FC1 ", "x" * 300]
SIDES = [0, 1, 2, 3, 7, 24, 640, 8192, 8193, 2**31, 2**32 - 1]
SPECIAL = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1e6, -1e6, 1e30, 1e-300, 5e-324,
                    600.0, 320.0, -1.0], dtype=np.float64)


def _special(rng: np.random.Generator, n: int) -> np.ndarray:
    """n values, half from the special list (NaN, inf, 1e30, 0, tiny), half random wide."""
    wide = rng.standard_normal(n) * 10.0 ** rng.integers(-3, 40, n)
    return np.where(rng.random(n) < 0.5, rng.choice(SPECIAL, n), wide)


def _float32_bytes(values: np.ndarray) -> bytes:
    with np.errstate(over="ignore"):  # 1e39 -> inf on purpose
        return values.astype(np.float32).tobytes()


def _stamp(msg: Any, rng: np.random.Generator, frame: str) -> None:
    kind = rng.integers(4)
    sec = int(rng.integers(-2**31, 2**31)) if kind == 0 else [0, 100, 2**31 - 1][kind - 1]
    nanosec = int(rng.choice([0, 999_999_999, 10**9, 2**32 - 1, int(rng.integers(0, 2**32))]))
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.header.frame_id = frame


# Few hypothesis draws per message (a case, sizes, a seed) and the bulk from a seeded numpy
# generator: hypothesis' own per-draw cost would otherwise dominate 2,000 messages per topic.
SEEDS = st.integers(0, 2**32 - 1)


@st.composite
def hostile_images(draw: Callable[..., Any]) -> Image:
    """Images whose encoding, size, step, data or stamp are wrong (sometimes all fine)."""
    encoding, consistent, seed = (draw(st.sampled_from(ENCODINGS)), draw(st.booleans()),
                                  draw(SEEDS))
    rng = np.random.default_rng(seed)
    msg = Image()
    _stamp(msg, rng, str(rng.choice([CAMERA_FRAME, "", WORLD_FRAME, "other"])))
    msg.encoding = encoding
    msg.is_bigendian = int(rng.choice([0, 1, 255]))
    if consistent:  # a consistent layout (for some encoding) of random content, NaN/inf too
        msg.width, msg.height = int(rng.integers(0, 25)), int(rng.integers(0, 25))
        msg.step = msg.width * int(rng.choice([1, 2, 3, 4])) + int(rng.integers(0, 4))
        size = msg.height * msg.step
        raw = _float32_bytes(_special(rng, size // 4 + 1))[:size]
        if rng.random() < 0.5:
            raw = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
        msg.data = array("B", raw)
    else:  # absurd dimensions with little data
        msg.width, msg.height, msg.step = (int(rng.choice(SIDES)) if rng.random() < 0.7
                                           else int(rng.integers(0, 2**32)) for _ in range(3))
        msg.data = array("B", rng.integers(0, 256, int(rng.integers(0, 65)), dtype=np.uint8))
    return msg


@st.composite
def hostile_camera_infos(draw: Callable[..., Any]) -> CameraInfo:
    """CameraInfo with absurd sizes and intrinsics (k[2] = 1e6, NaN, 0, huge, negative)."""
    n_bad, seed = draw(st.integers(0, 9)), draw(SEEDS)
    rng = np.random.default_rng(seed)
    msg = CameraInfo()
    _stamp(msg, rng, str(rng.choice([CAMERA_FRAME, "", "other"])))
    msg.width, msg.height = (int(rng.choice(SIDES + [640, 480, 48])) for _ in range(2))
    k = np.array([600.0, 0.0, 320.0, 0.0, 600.0, 240.0, 0.0, 0.0, 1.0])
    k[rng.choice(9, n_bad, replace=False)] = _special(rng, n_bad)
    msg.k = k.tolist()
    msg.distortion_model = str(rng.choice(["plumb_bob", "", "equidistant"]))
    msg.d = _special(rng, int(rng.integers(0, 9))).tolist()
    return msg


@st.composite
def hostile_transforms(draw: Callable[..., Any]) -> TransformStamped:
    """TransformStamped: non-unit / NaN quaternions, 1e30 m translations, odd frames."""
    wild_rotation, seed = draw(st.booleans()), draw(SEEDS)
    rng = np.random.default_rng(seed)
    msg = TransformStamped()
    _stamp(msg, rng, str(rng.choice([WORLD_FRAME, "", "other"])))
    msg.child_frame_id = str(rng.choice([CAMERA_FRAME, "", "other"]))
    t = _special(rng, 3) if rng.random() < 0.7 else rng.uniform(-2, 2, 3)
    tr = msg.transform.translation
    tr.x, tr.y, tr.z = (float(v) for v in t)
    if wild_rotation:
        v = _special(rng, 4)
    else:  # unit, nearly unit, or zero
        v = rng.standard_normal(4)
        v = v / np.linalg.norm(v) * rng.choice([1.0, 1.0 + 5e-4, 1.01, 0.0])
    q = msg.transform.rotation
    q.x, q.y, q.z, q.w = (float(c) for c in v)
    return msg


@st.composite
def hostile_triples(draw: Callable[..., Any]) -> tuple[Image, Image, CameraInfo]:
    """Colour, depth and camera_info with one stamp and valid layouts, random content: they
    reach the CNN and the geometry (depth with NaN/inf/huge values, random intrinsics)."""
    w, h, seed = draw(st.integers(1, 48)), draw(st.integers(1, 40)), draw(SEEDS)
    rng = np.random.default_rng(seed)
    stamp = stamp_from_seconds(float(rng.uniform(0.0, 2.0**31 - 1.0)))
    rgb = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    if rng.random() < 0.5:
        depth = rng.choice(np.array([np.nan, np.inf, -1.0, 0.0, 0.3, 0.6, 1e30, 3e38],
                                    dtype=np.float32), size=(h, w))
    else:
        depth = rng.uniform(0.2, 1.5, (h, w)).astype(np.float32)
    k = np.array([[rng.choice([1.0, 10.0, 600.0, 1e5]), 0.0, rng.uniform(-w / 2, 1.5 * w)],
                  [0.0, rng.choice([1.0, 600.0, 1e5]), rng.uniform(-h / 2, 1.5 * h)],
                  [0.0, 0.0, 1.0]])
    return (rgb_image_msg(rgb, stamp), depth_image_msg(depth, stamp),
            camera_info_msg(k, w, h, stamp))


# ---- the node ----------------------------------------------------------------------------------
class Recorder:
    """Stands in for a publisher's ``publish``: keeps what the node publishes."""

    def __init__(self, publish: Callable[[Any], None]) -> None:
        self.messages: list[Any] = []
        self._publish = publish

    def __call__(self, msg: Any) -> None:
        self.messages.append(msg)
        self._publish(msg)


@pytest.fixture(scope="module")
def rendered() -> dict[str, Any]:
    """Butter at two poses, rendered by the pybullet world (the valid input of the end)."""
    from sim_bridge.world import PushWorld, WorldConfig

    with PushWorld(WorldConfig(object="butter", object_pose=(0.02, -0.05, 0.4))) as world:
        a = world.render()
        world.set_object_pose((0.06, 0.01, 0.95))
        b = world.render()
    return {"a": a, "b": b}


@pytest.fixture(scope="module")
def node(module_ros_context: Any, rendered: dict[str, Any]) -> Iterator[SegmentationNode]:
    # No re-anchoring wait after start-up: frames are processed from the first one on (the
    # estimator topics' callbacks are fuzzed all the same).
    n = SegmentationNode(node_name="fuzz_segmentation_node", context=module_ros_context,
                         parameter_overrides=[Parameter("anchor_timeout", value=0.0)])
    n.poses = Recorder(n._pub_pose.publish)  # type: ignore[attr-defined]
    n._pub_pose.publish = n.poses  # type: ignore[method-assign]
    good = transform_msg(rendered["a"].T_world_camera, stamp_from_seconds(1.0), WORLD_FRAME,
                         CAMERA_FRAME)
    n.on_extrinsics(good)
    yield n
    n.destroy_node()


def _state(n: SegmentationNode) -> tuple[Any, ...]:
    matrix, child = n._extrinsics._matrix, n._extrinsics._child_frame
    return (n._sync.snapshot(), None if matrix is None else matrix.tobytes(), child)


def _rejects(n: SegmentationNode) -> int:
    return sum(n.health.get(f"refused_{k}")
               for k in ("color", "depth", "camera_info", "extrinsics", "stamp"))


def _feed(n: SegmentationNode, callback: Callable[[Any], Any], msg: Any) -> None:
    """Call the subscribed callback; a rejected message must leave the state as it was."""
    before, rejected = _state(n), _rejects(n)
    assert callback(msg) is None
    if _rejects(n) > rejected:
        assert _state(n) == before, "a rejected message changed the node's state"
    assert n.health.get("callback_errors") == 0, n.health.last_error


# ---- in-process fuzzing: >= 2,000 messages per topic -------------------------------------------
@FUZZ
@given(msg=hostile_images())
def test_fuzz_color_images(node: SegmentationNode, msg: Image) -> None:
    _feed(node, node.on_color, msg)


@FUZZ
@given(msg=hostile_images())
def test_fuzz_depth_images(node: SegmentationNode, msg: Image) -> None:
    _feed(node, node.on_depth, msg)


@FUZZ
@given(msg=hostile_camera_infos())
def test_fuzz_camera_info(node: SegmentationNode, msg: CameraInfo) -> None:
    _feed(node, node.on_camera_info, msg)


@FUZZ
@given(msg=hostile_transforms())
def test_fuzz_extrinsics(node: SegmentationNode, msg: TransformStamped,
                         rendered: dict[str, Any]) -> None:
    _feed(node, node.on_extrinsics, msg)
    # Put the good transform back (a valid random one may have replaced it: that is allowed).
    node.on_extrinsics(transform_msg(rendered["a"].T_world_camera, stamp_from_seconds(1.0),
                                     WORLD_FRAME, CAMERA_FRAME))


STAMPS = st.one_of(st.floats(0.0, 2.0**31 - 2.0).map(stamp_from_seconds),
                   st.builds(Time, sec=st.integers(-(2**31), 2**31 - 1),
                             nanosec=st.integers(0, 2**32 - 1)))


def _feed_anchor(n: SegmentationNode, callback: Callable[[Any], Any], msg: Any) -> None:
    """An estimator topic's callback: a rejected message keeps the anchor data as it was."""
    def rejected() -> int:
        return n.health.get("refused_estimator_outline") + n.health.get("refused_estimator_pose")

    before, n_rejected = (n._anchor.outline, n._anchor.estimate), rejected()
    _feed(n, callback, msg)
    if rejected() > n_rejected:
        assert (n._anchor.outline, n._anchor.estimate) == before


def hostile_clouds() -> st.SearchStrategy[PointCloud2]:
    """``estimator/outline`` clouds: valid outlines of random size and scale in any frame,
    with NaN / inf / huge points, broken fields, steps and data lengths."""

    @st.composite
    def build(draw: Callable) -> PointCloud2:
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        n = draw(st.sampled_from([0, 1, 2, 3, 8, 60, 60, 200, 1001, 5000]))
        radius = draw(st.sampled_from([0.04, 0.04, 1e-9, 2.0, 1e30]))
        angles = np.sort(rng.random(n)) * 2 * math.pi
        pts = radius * np.column_stack([np.cos(angles), np.sin(angles)])
        normals = np.column_stack([np.cos(angles), np.sin(angles)])
        special = float(_special(rng, 1)[0]) if n and draw(st.booleans()) else None
        if special is not None and math.isfinite(special):
            pts.flat[rng.integers(0, pts.size)] = special
            special = None
        msg = outline_cloud_msg(pts, normals, draw(STAMPS))
        if special is not None:  # NaN / inf: written into the bytes (the writer refuses them)
            data = bytearray(msg.data)
            at = int(rng.integers(0, n)) * msg.point_step + 4 * int(rng.integers(0, 2))
            data[at:at + 4] = np.float32(special).tobytes()
            msg.data = bytes(data)
        msg.header.frame_id = draw(st.sampled_from(["object"] * 4 + ["world", "", "x" * 99]))
        kind = draw(st.sampled_from(["ok"] * 4 + ["step", "width", "data", "fields"]))
        if kind == "step":
            msg.point_step = draw(st.sampled_from([0, 4, 23, 2**31]))
        elif kind == "width":
            msg.width = draw(st.sampled_from([0, n + 1, 2**32 - 1]))
        elif kind == "data":
            msg.data = bytes(msg.data)[:draw(st.integers(0, max(len(msg.data) - 1, 0)))]
        elif kind == "fields":
            msg.fields = msg.fields[:draw(st.integers(0, 5))]
        return msg

    return build()


def hostile_estimates() -> st.SearchStrategy[PoseWithCovarianceStamped]:
    """``estimator/object_pose``: any frame, stamp, position and (non-unit, tilted, NaN)
    quaternion."""

    @st.composite
    def build(draw: Callable) -> PoseWithCovarianceStamped:
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = draw(st.sampled_from(["world"] * 4 + ["object", ""]))
        msg.header.stamp = draw(STAMPS)
        p = msg.pose.pose
        p.position.x, p.position.y, p.position.z = (float(v) for v in _special(rng, 3))
        yaw = float(rng.uniform(-10, 10))
        q = draw(st.sampled_from(["yaw", "yaw", "scaled", "tilted", "special"]))
        values = {"yaw": (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)),
                  "scaled": (0.0, 0.0, 2 * math.sin(yaw / 2), 2 * math.cos(yaw / 2)),
                  "tilted": (0.7071068, 0.0, 0.0, 0.7071068),
                  "special": tuple(float(v) for v in _special(rng, 4))}[q]
        o = p.orientation
        o.x, o.y, o.z, o.w = values
        return msg

    return build()


@FUZZ
@given(msg=hostile_clouds())
def test_fuzz_estimator_outline(node: SegmentationNode, msg: PointCloud2) -> None:
    _feed_anchor(node, node.on_estimator_outline, msg)
    if node._anchor.outline is not None:  # only a checked outline is kept
        assert np.all(np.isfinite(node._anchor.outline.points))


@FUZZ
@given(msg=hostile_estimates())
def test_fuzz_estimator_pose(node: SegmentationNode, msg: PoseWithCovarianceStamped) -> None:
    _feed_anchor(node, node.on_estimate, msg)
    if node._anchor.estimate is not None:
        assert all(math.isfinite(v) for v in node._anchor.estimate)


def test_fuzz_complete_frames(node: SegmentationNode) -> None:
    """Complete triples through the whole pipeline (hypothesis inside)."""
    frames = node.health.get("frames")

    @settings(FUZZ, max_examples=N_TRIPLES)
    @given(triple=hostile_triples())
    def one(triple: tuple[Image, Image, CameraInfo]) -> None:
        rgb, depth, info = triple
        for callback, msg in ((node.on_color, rgb), (node.on_depth, depth),
                              (node.on_camera_info, info)):
            _feed(node, callback, msg)

    one()
    assert node.health.get("frames") - frames >= N_TRIPLES // 2  # they reached the pipeline


def test_after_the_fuzz_the_node_measures_a_rendered_frame(node: SegmentationNode,
                                                           rendered: dict[str, Any]) -> None:
    """Runs after the fuzz tests above (file order): no escaped exception, correct poses."""
    assert node.health.get("callback_errors") == 0
    response = node.on_reset(Trigger.Request(), Trigger.Response())
    assert response.success, response.message
    poses = []
    for i, name in enumerate(("a", "b")):
        f = rendered[name]
        stamp = stamp_from_seconds(3e8 + i)  # later than every fuzzed stamp that was processed
        h, w = f.depth.shape
        before = len(node.poses.messages)
        node.on_color(rgb_image_msg(f.rgb, stamp))
        node.on_depth(depth_image_msg(f.depth, stamp))
        node.on_camera_info(camera_info_msg(f.camera_matrix, w, h, stamp))
        assert len(node.poses.messages) == before + 1, node.health.values()
        poses.append(xytheta_from_pose(node.poses.messages[-1].pose.pose))
    for pose, name in zip(poses, ("a", "b"), strict=True):
        truth = rendered[name].object_pose
        assert np.hypot(*(pose[:2] - truth[:2])) < 0.003
    turn = rendered["b"].object_pose[2] - rendered["a"].object_pose[2]
    assert abs(math.remainder(poses[1][2] - turn, math.pi)) < math.radians(2.0)
    assert node.health.get("callback_errors") == 0


# ---- the self-filter's inputs (robot_filter.enabled) --------------------------------------------
N_DESCRIPTIONS = 300  # each one is parsed (pinocchio, XML): slower per example
TOY_URDF = """<robot name="toy"><link name="base"/>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="arm"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>
  </link></robot>"""
URDF_PIECES = ["<robot name='r'>", "<link name='a'>", "</link>", "</robot>", "<joint",
               "<mesh filename='/etc/passwd'/>", "<mesh filename='package://x/y.stl'/>",
               "<box size='1 nan 1'/>", "<sphere radius='-1'/>", "<collision><geometry>",
               "</geometry></collision>", "<!DOCTYPE x [<!ENTITY a 'aaaa'>]>", "&a;",
               "\x00", "x" * 1000, TOY_URDF]


@pytest.fixture(scope="module")
def robot_node(module_ros_context: Any) -> Iterator[SegmentationNode]:
    n = SegmentationNode(node_name="fuzz_robot_segmentation_node", context=module_ros_context,
                         parameter_overrides=[Parameter("anchor_timeout", value=0.0),
                                              Parameter("robot_filter.enabled", value=True)])
    yield n
    n.destroy_node()


@st.composite
def hostile_joint_states(draw: Callable[..., Any]) -> Any:
    from sensor_msgs.msg import JointState

    n_names, n_pos, seed = draw(st.integers(0, 300)), draw(st.integers(0, 300)), draw(SEEDS)
    rng = np.random.default_rng(seed)
    msg = JointState()
    msg.name = [rng.choice(["j", "panda_joint1", "", "x" * 200, f"j{i}"]) for i in range(n_names)]
    msg.position = _special(rng, n_pos).tolist()
    _stamp(msg, rng, "")
    return msg


@FUZZ
@given(msg=hostile_joint_states())
def test_fuzz_joint_states(robot_node: SegmentationNode, msg: Any) -> None:
    from push_perception.robot_filter import JOINT_HISTORY

    assert robot_node._robot.on_joint_state(msg) is None
    assert len(robot_node._robot.filter.joints) <= JOINT_HISTORY
    assert robot_node.health.get("callback_errors") == 0, robot_node.health.last_error


@settings(max_examples=N_DESCRIPTIONS, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(pieces=st.lists(st.sampled_from(URDF_PIECES), max_size=12))
def test_fuzz_robot_descriptions(robot_node: SegmentationNode, pieces: list[str]) -> None:
    from std_msgs.msg import String

    assert robot_node._robot.on_description(String(data="".join(pieces))) is None
    assert robot_node.health.get("callback_errors") == 0, robot_node.health.last_error
    robot = robot_node._robot.filter.robot
    assert robot is None or robot.triangle_count <= 200_000


def test_after_the_fuzz_the_robot_model_loads(robot_node: SegmentationNode) -> None:
    from std_msgs.msg import String

    robot_node._robot.on_description(String(data=TOY_URDF))
    assert robot_node._robot.filter.robot is not None
    assert robot_node._robot.filter.robot.joint_names == ("j",)
    assert robot_node.health.get("callback_errors") == 0


# ---- over DDS: 100 hostile messages per topic on the real topics -------------------------------
def test_fuzz_over_dds_node_stays_alive_and_answers_reset(module_ros_context: Any) -> None:
    node = SegmentationNode(node_name="fuzz_dds_segmentation_node", context=module_ros_context)
    client = rclpy.create_node("fuzz_dds_client", context=module_ros_context)
    executor = SingleThreadedExecutor(context=module_ros_context)
    executor.add_node(node)
    executor.add_node(client)
    try:
        sensor = qos_profile_sensor_data
        pubs = {
            "rgb": client.create_publisher(Image, "camera/color/image_raw", sensor),
            "depth": client.create_publisher(Image, "camera/aligned_depth_to_color/image_raw",
                                             sensor),
            "info": client.create_publisher(CameraInfo, "camera/color/camera_info", sensor),
            "tf": client.create_publisher(TransformStamped, "camera/color/extrinsics", LATCHED),
        }
        reset = client.create_client(Trigger, "/fuzz_dds_segmentation_node/reset")
        deadline = time.monotonic() + 30.0
        assert spin_until(executor, lambda: all(p.get_subscription_count() > 0
                                                for p in pubs.values())
                          and reset.service_is_ready(), deadline)
        rng = np.random.default_rng(15)
        for i in range(100):
            msgs = _dds_messages(rng, i)
            for key, msg in msgs.items():
                pubs[key].publish(msg)
            executor.spin_once(timeout_sec=0.0)
        spin_until(executor, lambda: False, time.monotonic() + 1.0)
        future = reset.call_async(Trigger.Request())
        assert spin_until(executor, future.done, time.monotonic() + 30.0)
        assert future.result().success, future.result().message
        assert node.health.get("callback_errors") == 0, node.health.last_error
        assert _rejects(node) > 0
    finally:
        executor.shutdown()
        node.destroy_node()
        client.destroy_node()


def _dds_messages(rng: np.random.Generator, i: int) -> dict[str, Any]:
    """One hostile message per topic (seeded; the in-process run covers the space)."""
    stamp = stamp_from_seconds(10.0 + i)
    img = Image()
    img.header.stamp = stamp
    img.encoding = ["rgb8", "32FC1", "rgba8", ""][i % 4]
    img.width, img.height = int(rng.integers(0, 2**32)), int(rng.integers(0, 64))
    img.step = int(rng.integers(0, 2**32))
    img.data = array("B", rng.integers(0, 256, int(rng.integers(0, 256)), dtype=np.uint8))
    depth = Image()
    depth.header.stamp = stamp
    depth.encoding = ["32FC1", "16UC1", "bgr8"][i % 3]
    depth.width = depth.height = 4
    depth.step = 16 if depth.encoding == "32FC1" else 8
    vals = np.array([np.nan, np.inf, 1e30, -1.0], dtype=np.float32)
    depth.data = array("B", rng.choice(vals, 4 * depth.step // 4).astype(np.float32).tobytes()
                       [: depth.height * depth.step])
    info = CameraInfo()
    info.header.stamp = stamp
    info.width, info.height = 4, 4
    info.k = [float(rng.choice([1e6, np.nan, 0.0, 600.0])), 0.0, 1e6, 0.0, 600.0, 2.0,
              0.0, 0.0, 1.0]
    tf = TransformStamped()
    tf.header.stamp = stamp
    tf.header.frame_id, tf.child_frame_id = WORLD_FRAME, CAMERA_FRAME
    tf.transform.translation.x = float(rng.choice([1e30, np.nan, np.inf, 1e3]))
    tf.transform.rotation.w = float(rng.choice([1.0, 2.0, np.nan]))
    return {"rgb": img, "depth": depth, "info": info, "tf": tf}



# ---- the ROS-free core: hostile arrays of the right shapes -------------------------------------
@st.composite
def hostile_frames(draw: Callable[..., Any]) -> tuple[Any, ...]:
    """A mask blob off the border (so the geometry runs), depth with NaN / inf / 1e30 / 3e38,
    K with focal lengths from 1e-6 to 1e9 px, T with translations up to 1e30 m, and geometry
    parameters anywhere in their ranges."""
    from push_perception.perception_config import PerceptionConfig

    seed, mode = draw(SEEDS), draw(st.integers(0, 3))
    rng = np.random.default_rng(seed)
    h, w = 48, 64
    v, u = np.mgrid[0:h, 0:w]
    cx, cy = rng.uniform(20, 44), rng.uniform(15, 33)
    mask = ((u - cx) / rng.uniform(6, 14)) ** 2 + ((v - cy) / rng.uniform(6, 12)) ** 2 < 1.0
    z0 = rng.uniform(0.3, 1.5)
    depth = np.where(mask, z0 - 0.013, z0).astype(np.float32)
    depth += rng.normal(0.0, 1e-3, (h, w)).astype(np.float32) * (rng.random() < 0.5)
    if mode == 0:
        depth[rng.random((h, w)) < rng.uniform(0, 0.5)] = rng.choice(np.array(
            [np.nan, np.inf, -1.0, 0.0, 1e30, 3e38], dtype=np.float32))
    f = float(10.0 ** rng.uniform(-6, 9)) if mode == 1 else float(rng.uniform(0.5, 2) * z0 / 1e-3)
    k = np.array([[f, 0.0, rng.uniform(-1e6, 1e6) if mode == 1 else 31.5],
                  [0.0, f * rng.uniform(0.9, 1.1), 23.5], [0.0, 0.0, 1.0]])
    # Looking straight down from z0 (optical z = -world z), turned about the vertical.
    a = rng.uniform(-np.pi, np.pi)
    t = np.array([[np.cos(a), np.sin(a), 0.0, 0.0], [np.sin(a), -np.cos(a), 0.0, 0.0],
                  [0.0, 0.0, -1.0, z0], [0.0, 0.0, 0.0, 1.0]])
    if mode == 2:
        t[:3, 3] += rng.standard_normal(3) * 10.0 ** rng.integers(-2, 31)
    cfg = PerceptionConfig(resolution=float(rng.uniform(5e-4, 3e-3)), closing_radius=2,
                           outline_spacing=float(rng.uniform(5e-4, 0.01)),
                           min_height=0.0, min_pixels=3, min_valid_fraction=0.0)
    return mask, depth, k, t, cfg


@settings(FUZZ, max_examples=300)
@given(frame=hostile_frames(), second=hostile_frames())
def test_fuzz_core_bounded_and_only_perception_errors(frame: tuple[Any, ...],
                                                      second: tuple[Any, ...]) -> None:
    from push_perception.outline import MAX_OUTLINE_POINTS
    from push_perception.perception_config import PerceptionError
    from push_perception.tracker import EpisodeTracker

    mask, depth, k, t, cfg = frame
    tracker = EpisodeTracker(cfg)
    started = time.perf_counter()
    for m, d, kk, tt in (frame[:4], second[:4]):
        try:
            meas = tracker.update(m, d, kk, tt)
        except PerceptionError:
            continue
        assert np.all(np.isfinite(meas.pose)) and np.all(np.isfinite(meas.covariance))
        assert len(tracker.outline[0]) <= MAX_OUTLINE_POINTS
    assert time.perf_counter() - started < 10.0
