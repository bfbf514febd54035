"""Fuzz tests of sim_bridge_node: hostile pushes and parameters.

In-process against the real node class (a 160 x 120 camera for speed): the test calls the
subscribed, guarded ``node.on_push`` directly with real ``nav_msgs/Path`` objects built by
hypothesis (no DDS): 2,000 paths with 0 to 300 poses, NaN / inf / 1e300 coordinates, wrong
frames, extreme stamps, and valid pushes in between (executed by the worker; pushes arriving
meanwhile are refused as busy). 2,000 parameter sets go through the node's own parameter
path (``set_parameters_atomically``, what the ``~/set_parameters`` service calls): wrong
types, out-of-range and NaN values, object names and paths (``/etc/passwd``, directories,
files that are not specifications and files holding a secret). Afterwards:

- no exception reached the guard (``callback_errors`` stays 0) and none left the parameter
  path;
- no answer, refusal reason or ``~/reset`` message quotes a file's content;
- a rejected push or parameter changed nothing; after ``~/reset`` the bridge still executes a
  valid push through the object's centre, which moves it forward.

A smaller over-DDS run publishes 100 hostile paths on ``planner/push`` of a spun node and
checks it is alive and answers ``~/reset``. Reproducible: derandomized, no deadline.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path as FilePath
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("hypothesis")
pytest.importorskip("pybullet")

from geometry_msgs.msg import PoseStamped  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from nav_msgs.msg import Path  # noqa: E402
from rclpy.exceptions import ParameterNotDeclaredException  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from push_ros.frames import WORLD_FRAME  # noqa: E402
from push_ros.paths import push_path, push_points_from_path  # noqa: E402
from pushbot.ros2cli.discovery import spin_until  # noqa: E402
from sim_bridge.params import PARAMETERS, SimBridgeParams  # noqa: E402
from sim_bridge.sim_bridge_node import SimBridgeNode  # noqa: E402

N_FUZZ = 2000
FUZZ = settings(max_examples=N_FUZZ, deadline=None, derandomize=True, database=None,
                suppress_health_check=list(HealthCheck))
SMALL = [Parameter("image_width", value=160), Parameter("image_height", value=120),
         Parameter("object", value="rect1"), Parameter("push_speed", value=0.2)]
HALF = 0.045  # rect1 is a 9 cm square at the origin
THROUGH_CENTRE = [(-HALF - 0.03, 0.0), (-HALF, 0.0), (-HALF + 0.05, 0.0)]
SECRET = "TOPSECRET-7f3a"
SPECIAL = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1e300, -1e300, 1e30, 5e-324, 0.05,
                    -0.1, 3.0])


# ---- strategies ------------------------------------------------------------------------------
@st.composite
def hostile_paths(draw: Callable[..., Any]) -> Path:
    """Paths of 0-300 poses with odd frames, NaN / huge coordinates and stamps; a sixth of
    them well-formed pushes somewhere in (or out of) the workspace."""
    n = draw(st.sampled_from([0, 1, 2, 3, 3, 3, 4, 10, 300]))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    if n == 3 and rng.random() < 0.5:  # well formed: the world decides
        start = rng.uniform(-0.2, 0.2, 2)
        a = rng.uniform(-np.pi, np.pi)
        way = np.array([math.cos(a), math.sin(a)])
        pts = (start, start + 0.005 * way, start + rng.uniform(0.01, 0.3) * way)
        return push_path(*pts, stamp_seconds=float(rng.uniform(0, 1e6)), speed=0.02)
    msg = Path()
    msg.header.frame_id = str(rng.choice([WORLD_FRAME, WORLD_FRAME, "", "camera", "ü" * 40]))
    msg.header.stamp.sec = int(rng.integers(-2**31, 2**31))
    msg.header.stamp.nanosec = int(rng.integers(0, 2**32))
    xyz = np.where(rng.random((n, 3)) < 0.3, rng.choice(SPECIAL, (n, 3)),
                   rng.uniform(-0.3, 0.3, (n, 3)))
    frames = rng.choice([WORLD_FRAME, "", "pusher"], n, p=[0.8, 0.1, 0.1])
    for (x, y, z), frame in zip(xyz, frames, strict=True):
        pose = PoseStamped()
        pose.header.frame_id = str(frame)
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z
        pose.pose.orientation.w = float(rng.choice([1.0, 0.0, np.nan]))
        msg.poses.append(pose)
    return msg


@st.composite
def hostile_parameters(draw: Callable[..., Any], files: dict[str, str]) -> Parameter:
    """One parameter of the table (or an undeclared one) with a value of any type."""
    names = [spec.name for spec in PARAMETERS] + ["no_such_parameter", "use_sim_time"]
    name, kind, seed = (draw(st.sampled_from(names)), draw(st.integers(0, 6)),
                        draw(st.integers(0, 2**32 - 1)))
    rng = np.random.default_rng(seed)
    values: list[Any] = [
        bool(rng.random() < 0.5),
        int(rng.choice([0, -1, 1, 2**31, -2**63, 2**63 - 1, int(rng.integers(-100, 100))])),
        float(rng.choice(SPECIAL)),
        str(rng.choice(list(files.values()) + ["butter", "", " ", "/", "\x00", "rect1",
                                                "nonexistent.yaml", "a" * 5000])),
        [float(v) for v in rng.choice(SPECIAL, int(rng.integers(0, 4)))],
        [int(v) for v in rng.integers(-5, 5, int(rng.integers(0, 4)))],
        ["x"] * int(rng.integers(0, 3)),
    ]
    return Parameter(name, value=values[kind])


# ---- fixtures --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """Paths the object parameter must refuse without echoing them (and one valid spec)."""
    d = tmp_path_factory.mktemp("objects")
    out = {"passwd": "/etc/passwd", "dir": str(d), "dir_yaml": str(d / "sub.yaml")}
    (d / "sub.yaml").mkdir()
    texts = {
        "key.yaml": f"{SECRET}: 1\nshape: {{type: polygon}}\n",
        "line.yaml": f"shape: [\n  {SECRET} {{\n",
        "value.json": f'{{"shape": {{"type": "{SECRET}"}}, "thickness": 0.01, "mass": 1}}',
        "number.yaml": f"shape: {{type: ellipse, semi_axes: [0.05, 0.03]}}\nthickness: {SECRET}\n"
                       "mass: 0.2\n",
        "list.yml": f"- {SECRET}\n",
        "secret.txt": f"{SECRET}\n",
        "big.yaml": "# " + "x" * (2 << 20) + "\n",
    }
    for name, text in texts.items():
        (d / name).write_text(text)
        out[name] = str(d / name)
    (d / "binary.json").write_bytes(b"\xff\xfe" + SECRET.encode() + b"\x00\x81")
    out["binary.json"] = str(d / "binary.json")
    good = d / "good_box.yaml"
    good.write_text("shape: {type: polygon, vertices: [[0.04, 0.03], [-0.04, 0.03], "
                    "[-0.04, -0.03], [0.04, -0.03]]}\nthickness: 0.013\nmass: 0.3\n")
    out["good"] = str(good)
    return out


@pytest.fixture(scope="module")
def node(module_ros_context: Any) -> Iterator[SimBridgeNode]:
    n = SimBridgeNode(node_name="fuzz_sim_bridge_node", context=module_ros_context,
                      parameter_overrides=SMALL)
    yield n
    n.destroy_node()


def _counts(n: SimBridgeNode) -> dict[str, int]:
    return n.health.counts


def _wait_idle(n: SimBridgeNode, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while n.worker.busy:
        assert time.monotonic() < deadline, f"still busy: {n.worker.busy}"
        time.sleep(0.005)


def _object_pose(n: SimBridgeNode) -> np.ndarray:
    return np.asarray(n.worker.call(n._world.object_pose).result())


# ---- the object parameter never echoes a file --------------------------------------------------
def test_object_parameter_refuses_files_without_quoting_them(files: dict[str, str]) -> None:
    base = {spec.name: spec.default for spec in PARAMETERS}
    assert SimBridgeParams.from_values({**base, "object": files["good"]}).object == files["good"]
    for key, path in files.items():
        if key == "good":
            continue
        with pytest.raises(ValueError) as info:
            SimBridgeParams.from_values({**base, "object": path})
        text = str(info.value)
        assert SECRET not in text and "root:" not in text, (key, text)
        assert "parameter 'object'" in text, text
    for key in ("key.yaml", "value.json", "number.yaml"):
        with pytest.raises(ValueError, match="not a valid object specification"):
            SimBridgeParams.from_values({**base, "object": files[key]})


def test_reset_answer_never_quotes_a_spec_file_edited_after_it_was_set(
        node: SimBridgeNode, files: dict[str, str], tmp_path: Any) -> None:
    spec = tmp_path / "edited.yaml"
    spec.write_text(FilePath(files["good"]).read_text())
    assert node.set_parameters_atomically([Parameter("object", value=str(spec))]).successful
    spec.write_text(f"shape: {{type: polygon, vertices: {SECRET}}}\nthickness: 0.01\n")
    response = node.on_reset(Trigger.Request(), Trigger.Response())
    assert not response.success and "not a valid object specification" in response.message
    assert SECRET not in response.message, response.message
    assert node.set_parameters_atomically([Parameter("object", value="rect1")]).successful


# ---- in-process fuzzing ------------------------------------------------------------------------
def test_fuzz_push_paths(node: SimBridgeNode) -> None:
    """2,000 hostile paths through the subscribed callback (hypothesis inside)."""

    @FUZZ
    @given(msg=hostile_paths())
    def one(msg: Path) -> None:
        # Whether the codec refuses the message is decided here, independently of the node's
        # counters (the world's own refusals of accepted pushes are counted by the worker
        # thread at any moment, so counting cannot tell which message was refused).
        try:
            push_points_from_path(msg)
            decodable = True
        except ValueError:
            decodable = False
        before = _counts(node)
        seq = node.worker.pushes
        assert node.on_push(msg) is None
        after = _counts(node)
        if not decodable:
            assert node.worker.pushes == seq, "a refused push was handed to the world"
            assert after["pushes_rejected_invalid"] > before["pushes_rejected_invalid"]
        assert after["callback_errors"] == 0, node.health.values()

    one()
    _wait_idle(node)
    counts = _counts(node)
    assert counts["pushes_executed"] > 0 and counts["pushes_rejected_invalid"] > 0, counts


def test_fuzz_parameters(node: SimBridgeNode, files: dict[str, str]) -> None:
    """2,000 parameter sets through the node's parameter path (hypothesis inside)."""
    valid_object = node.get_parameter("object").value
    refused = []

    @FUZZ
    @given(param=hostile_parameters(files))
    def one(param: Parameter) -> None:
        before = {spec.name: node.get_parameter(spec.name).value for spec in PARAMETERS
                  if spec.default is not None}
        try:
            result = node.set_parameters_atomically([param])
        except ParameterNotDeclaredException:  # the service answers this one itself
            return
        if not result.successful:
            assert SECRET not in result.reason and "root:" not in result.reason, result.reason
            after = {name: node.get_parameter(name).value for name in before}
            assert after == before, "a refused set changed a parameter"
            refused.append(result.reason)
        if param.name == "object" and result.successful:
            assert param.value in ("butter", "rect1", files["good"]), param.value

    one()
    assert refused
    assert _counts(node)["callback_errors"] == 0
    # Back to the small, known scene for the last test.
    node.set_parameters_atomically([*SMALL, Parameter("object", value=valid_object)])


@st.composite
def hostile_knocks(draw: Callable[..., Any]) -> PoseStamped:
    """``sim/knock`` displacements: any frame, NaN / inf / huge / small positions, unit, scaled,
    tilted and special quaternions."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    msg = PoseStamped()
    msg.header.frame_id = draw(st.sampled_from(["world"] * 5 + ["object", "", "x" * 200]))
    small = rng.uniform(-0.05, 0.05, 2)
    xy = np.where(rng.random(2) < 0.6, small, rng.choice(SPECIAL, 2))
    msg.pose.position.x, msg.pose.position.y = (float(v) for v in xy)
    yaw = float(rng.uniform(-4.0, 4.0))
    q = draw(st.sampled_from(["yaw", "yaw", "yaw", "scaled", "tilted", "special"]))
    values = {"yaw": (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)),
              "scaled": (0.0, 0.0, 3 * math.sin(yaw / 2), 3 * math.cos(yaw / 2)),
              "tilted": (0.3826834, 0.0, 0.0, 0.9238795),
              "special": tuple(float(v) for v in rng.choice(SPECIAL, 4))}[q]
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = values
    return msg


def test_fuzz_knocks(node: SimBridgeNode) -> None:
    """2,000 hostile sim/knock messages through the subscribed callback (hypothesis inside)."""
    from push_ros.poses import check_frame, xytheta_from_pose
    from sim_bridge.commands import MAX_KNOCK_SHIFT

    @FUZZ
    @given(msg=hostile_knocks())
    def one(msg: PoseStamped) -> None:
        try:  # decided from the codec and the size rule, independently of the node
            check_frame(msg.header.frame_id, "world")
            acceptable = math.hypot(*xytheta_from_pose(msg)[:2]) <= MAX_KNOCK_SHIFT
        except ValueError:
            acceptable = False
        before = _counts(node)
        assert node.on_knock(msg) is None
        after = _counts(node)
        if not acceptable:
            assert after["knocks_rejected"] > before["knocks_rejected"]
        assert after["callback_errors"] == 0, node.health.values()

    one()
    _wait_idle(node)
    counts = _counts(node)
    assert counts["knocks"] > 0 and counts["knocks_rejected"] > 0, counts


def test_after_the_fuzz_the_bridge_executes_a_valid_push(node: SimBridgeNode) -> None:
    """Runs after the fuzz tests above (file order)."""
    _wait_idle(node)
    defaults = {spec.name: spec.default for spec in PARAMETERS if not spec.read_only}
    defaults.update({"object": "rect1", "image_width": 160, "image_height": 120})
    params = [Parameter(name, value=value) for name, value in defaults.items()]
    result = node.set_parameters_atomically(params)
    assert result.successful, result.reason
    response = node.on_reset(Trigger.Request(), Trigger.Response())
    assert response.success, response.message
    assert SECRET not in response.message
    before = _object_pose(node)
    executed = _counts(node)["pushes_executed"]
    node.on_push(push_path(*THROUGH_CENTRE, stamp_seconds=1.0, speed=0.02))
    deadline = time.monotonic() + 30.0
    while _counts(node)["pushes_executed"] == executed:
        assert time.monotonic() < deadline, node.health.values()
        time.sleep(0.01)
    _wait_idle(node)
    moved = _object_pose(node) - before
    assert 0.02 < moved[0] < 0.06 and abs(moved[1]) < 0.005, moved
    assert abs(moved[2]) < math.radians(3), moved
    assert _counts(node)["callback_errors"] == 0


# ---- over DDS ----------------------------------------------------------------------------------
def test_fuzz_over_dds_bridge_stays_alive_and_answers_reset(module_ros_context: Any) -> None:
    node = SimBridgeNode(node_name="fuzz_dds_sim_bridge_node", context=module_ros_context,
                         parameter_overrides=SMALL)
    client = rclpy.create_node("fuzz_dds_bridge_client", context=module_ros_context)
    executor = SingleThreadedExecutor(context=module_ros_context)
    executor.add_node(node)
    executor.add_node(client)
    try:
        pub = client.create_publisher(Path, "planner/push",
                                      QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        reset = client.create_client(Trigger, "/fuzz_dds_sim_bridge_node/reset")
        assert spin_until(executor, lambda: pub.get_subscription_count() > 0
                          and reset.service_is_ready(), time.monotonic() + 30.0)
        rng = np.random.default_rng(15)

        def handled() -> int:
            return sum(_counts(node)[k] for k in ("pushes_rejected_invalid",
                                                  "pushes_rejected_busy", "pushes_executed"))

        for i in range(100):  # one at a time: a reliable keep-last queue drops a burst
            pub.publish(_dds_path(rng))
            assert spin_until(executor, lambda i=i: handled() > i, time.monotonic() + 10.0)
        _wait_idle(node)
        future = reset.call_async(Trigger.Request())
        assert spin_until(executor, future.done, time.monotonic() + 30.0)
        assert future.result().success, future.result().message
        assert _counts(node)["callback_errors"] == 0
    finally:
        executor.shutdown()
        node.destroy_node()
        client.destroy_node()


def _dds_path(rng: np.random.Generator) -> Path:
    msg = Path()
    msg.header.frame_id = str(rng.choice([WORLD_FRAME, "", "camera"]))
    for _ in range(int(rng.choice([0, 2, 3, 3, 50]))):
        pose = PoseStamped()
        pose.header.frame_id = WORLD_FRAME
        pose.pose.position.x = float(rng.choice(SPECIAL))
        pose.pose.position.y = float(rng.uniform(-0.3, 0.3))
        msg.poses.append(pose)
    return msg

