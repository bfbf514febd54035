"""Fuzz tests of push_executor_node: hostile messages on every subscribed topic.

The project's fuzz pattern (tests/ros/test_fuzz_planner.py): in-process against the real node
class, the test calls the guarded callbacks the node subscribed (found by topic) with real
message objects built by hypothesis strategies, no DDS, 2,000 messages per topic:

- ``planner/push``: NaN / inf / huge coordinates, 0-50 poses, other frames, bad stamps;
- ``/joint_states``: wrong sizes, mismatched name / position lengths, NaN / inf, repeated and
  unknown names, huge arrays, bad and future stamps -- while idle and while a push is running;
- ``executor/joint_goal``: the joint states' shapes and values as goals (each answered once);
- ``/robot_description``: garbage XML, truncated and mutated URDFs, other robots, a 10 MB
  string;
- the clear pose's inputs and the episode's state (a second node with the simulator's URDF, so
  that a push is planned with a real robot image and clear view): ``camera/color/camera_info``
  (absurd sizes and intrinsics), ``camera/color/extrinsics`` (NaN / non-unit quaternions, 1e30 m),
  ``perception/outline`` (NaN, huge and too many points, broken layouts),
  ``estimator/object_pose`` (NaN, huge, other frames, absurd covariances) and ``planner/status``
  (any state, goal and number of values), pushes planned between them.

After every message no exception reached a guard (``callback_errors`` stays 0). Afterwards the
node still plans a push (dry run: ``executor/path`` and a ``disabled`` refusal; with the scene
inputs, to a clear pose), held state is bounded (model text, recorded samples) and the traced
memory did not grow by more than a few MB over a second round of the same messages.
Reproducible: hypothesis derandomized, numpy generators seeded from its draws.
"""

from __future__ import annotations

import math
import tracemalloc
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

hypothesis = pytest.importorskip("hypothesis")

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue  # noqa: E402
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, TransformStamped  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from nav_msgs.msg import Path  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import CameraInfo, JointState, PointCloud2  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from push_core.objects import load_object  # noqa: E402
from push_core.robot_view import MAX_URDF_CHARS  # noqa: E402
from push_core.rollout import PUSHER_RADIUS  # noqa: E402
from push_executor.kinematics import ArmKinematics, ToolSpec  # noqa: E402
from push_executor.motion_types import PANDA_PARK  # noqa: E402
from push_executor.push_executor_node import HELD_STATES, PushExecutorNode  # noqa: E402
from push_executor.state_check import StateCheckConfig  # noqa: E402
from push_executor.tracking import MAX_SAMPLES  # noqa: E402
from push_ros.frames import CAMERA_FRAME  # noqa: E402
from push_ros.images import camera_info_msg  # noqa: E402
from push_ros.outline import outline_cloud_msg  # noqa: E402
from push_ros.paths import push_path  # noqa: E402
from push_ros.poses import pose_with_covariance_msg, transform_msg  # noqa: E402
from push_ros.refusal import read_refusal  # noqa: E402
from push_ros.stamps import stamp_from_seconds  # noqa: E402

from .test_kinematics import panda_urdf  # noqa: E402

N_FUZZ = 2000
#: Hostile postures each followed by a push (a posture within the limits is planned: slower).
N_POSTURES = 300
FUZZ = settings(max_examples=N_FUZZ, deadline=None, derandomize=True, database=None,
                suppress_health_check=list(HealthCheck))
ARM = [f"panda_joint{i}" for i in range(1, 8)]
SPECIAL = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1e300, -1e300, 1e-320, 0.05, -0.2]
FLOAT = st.one_of(st.sampled_from(SPECIAL), st.floats(-0.3, 0.3),
                  st.floats(allow_nan=True, allow_infinity=True))
FRAME = st.sampled_from(["world"] * 4 + ["", "map", "World", "x" * 300])
STAMP = st.one_of(st.floats(0.0, 50.0).map(stamp_from_seconds),
                  st.builds(Time, sec=st.integers(-(2**31), 2**31 - 1),
                            nanosec=st.integers(0, 2**32 - 1)))
URDF = panda_urdf()
#: Joint positions far outside every Panda joint's limits (the probe's 100 and -1e6 rad).
FAR = st.one_of(st.sampled_from([100.0, -1e6, 1e6, 1e300, -1e300, 7.0, -4.0]),
                st.floats(10.0, 1e12), st.floats(-1e12, -10.0))
_PANDA = ArmKinematics(URDF, "panda_link0", ToolSpec())
PANDA_LOWER, PANDA_UPPER = tuple(_PANDA.lower), tuple(_PANDA.upper)
STATE_MARGIN = StateCheckConfig().state_margin
#: The node's simulated clock, s: valid joint states are stamped at it (their age is checked).
CLOCK = 10.0
#: The clock while a push runs under fuzzing, s.
MOVING_CLOCK = 60.0


class Probe:
    """The node, its subscription callbacks by topic and what it publishes (captured)."""

    def __init__(self, node: PushExecutorNode) -> None:
        self.node = node
        namespace = node.get_namespace().rstrip("/") + "/"
        self.callbacks = {sub.topic_name.removeprefix(namespace).lstrip("/"): sub.callback
                          for sub in node.subscriptions}
        self.trajectories: list[Any] = []
        self.refused: list[Any] = []
        self.paths: list[Any] = []
        node._pub_traj.publish = self.trajectories.append
        node._pub_refused.publish = self.refused.append
        node._pub_path.publish = self.paths.append

    def set_clock(self, seconds: float) -> None:
        """The node's simulated clock, through its own ``/clock`` callback."""
        self.callbacks["clock"](Clock(clock=stamp_from_seconds(seconds)))

    def send(self, topic: str, msg: Any) -> None:
        self.callbacks[topic](msg)
        assert self.errors == 0, self.node.health.last_error

    @property
    def errors(self) -> int:
        return self.node.health.get("callback_errors")


def valid_state(stamp: float = CLOCK, q: Any = PANDA_PARK) -> JointState:
    msg = JointState(name=[*ARM, "panda_finger_joint1"], position=[*q, 0.0])
    msg.header.stamp = stamp_from_seconds(stamp)
    return msg


@pytest.fixture(scope="module")
def probe(module_ros_context: Any) -> Iterator[Probe]:
    node = PushExecutorNode(context=module_ros_context, parameter_overrides=[
        Parameter("start_enabled", value=False), Parameter("use_sim_time", value=True)])
    try:
        p = Probe(node)
        p.set_clock(CLOCK)
        p.send("robot_description", String(data=URDF))
        assert node._arm is not None
        yield p
    finally:
        node.destroy_node()


@st.composite
def pushes(draw: Callable) -> Path:
    msg = Path()
    msg.header.frame_id = draw(FRAME)
    msg.header.stamp = draw(STAMP)
    n = draw(st.sampled_from([3, 3, 3, 0, 1, 2, 4, 50]))
    for _ in range(n):
        pose = PoseStamped()
        pose.header.frame_id = draw(st.sampled_from(["", "world", "map"]))
        pose.pose.position.x, pose.pose.position.y = draw(FLOAT), draw(FLOAT)
        pose.pose.position.z = draw(st.sampled_from([0.0, math.nan, 1.0]))
        msg.poses.append(pose)
    return msg


@st.composite
def joint_states(draw: Callable, far: bool = True, around: float | None = None) -> JointState:
    """Hostile joint states; stamped 0-20 s, or (``around``) within the last 1.5 s before it
    (an older stamp would be a restarted clock, which stops a running motion at once)."""
    kind = draw(st.sampled_from(["ok", "ok", "nan", *(["far"] if far else []), "short", "long",
                                 "mismatch", "repeat", "unknown", "huge", "stamp", "empty"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    q = np.array(PANDA_PARK) + rng.normal(0.0, draw(st.sampled_from([1e-3] * 20 + [0.2])), 7)
    msg = valid_state(draw(st.floats(0.0, 20.0) if around is None
                           else st.floats(around - 1.5, around)), q)
    if kind == "nan":
        msg.position[int(rng.integers(7))] = draw(st.sampled_from(SPECIAL[:3]))
    elif kind == "far":  # a glitched encoder: far outside the joint's limits
        msg.position[int(rng.integers(7))] = draw(FAR)
    elif kind == "short":
        msg.position = msg.position[:int(rng.integers(0, 7))]
    elif kind == "long":
        msg.position = list(msg.position) + [0.0] * int(rng.integers(1, 50))
    elif kind == "mismatch":
        msg.name = msg.name[:int(rng.integers(0, 7))]
    elif kind == "repeat":
        msg.name[1] = msg.name[0]
    elif kind == "unknown":
        msg.name[int(rng.integers(7))] = draw(st.sampled_from(["", "x" * 500, "joint_1"]))
    elif kind == "huge":
        n = int(rng.choice([1001, 100_000]))
        msg.name = [f"j{i}" for i in range(n)]
        msg.position = np.zeros(n).tolist()
    elif kind == "stamp":  # while moving mostly late, sometimes a restarted clock or far ahead
        anywhere = around is None or draw(st.integers(0, 9)) == 0
        msg.header.stamp = draw(STAMP) if anywhere else stamp_from_seconds(
            draw(st.floats(around - 1.5, around)))
    elif kind == "empty":
        msg.name, msg.position = [], []
    msg.velocity = draw(st.sampled_from([[], [math.nan] * 3, [0.0] * 8]))
    return msg


@st.composite
def descriptions(draw: Callable) -> String:
    kind = draw(st.sampled_from(["garbage", "truncated", "mutated", "other", "empty",
                                 "tags"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if kind == "garbage":
        text = draw(st.text(max_size=200))
    elif kind == "truncated":
        text = URDF[:int(rng.integers(0, len(URDF)))]
    elif kind == "mutated":
        data = bytearray(URDF.encode())
        for i in rng.integers(0, len(data), int(rng.integers(1, 20))):
            data[i] = int(rng.integers(32, 127))
        text = data.decode(errors="replace")
    elif kind == "other":
        text = URDF.replace("panda_link0", draw(st.sampled_from(["base", "", "panda_link1"])))
    elif kind == "tags":
        text = "<robot name='x'>" + "<link name='l'/>" * int(rng.integers(0, 200)) + "</robot>"
    else:
        text = ""
    return String(data=text)


# ---- in-process fuzzing ------------------------------------------------------------------------
def test_fuzz_robot_description(probe: Probe) -> None:
    @FUZZ
    @given(descriptions())
    def run(msg: String) -> None:
        probe.send("robot_description", msg)
        assert len(probe.node._urdf) <= MAX_URDF_CHARS

    run()
    probe.send("robot_description", String(data="<robot>" + "x" * 10_000_000 + "</robot>"))
    assert "characters" in probe.node.health.last_refusal
    probe.send("robot_description", String(data=URDF))
    assert probe.node._arm is not None and probe.node._urdf == URDF


def test_fuzz_joint_states(probe: Probe) -> None:
    @FUZZ
    @given(joint_states())
    def run(msg: JointState) -> None:
        probe.send("joint_states", msg)

    run()
    probe.send("joint_states", valid_state())
    np.testing.assert_allclose(probe.node.measured.q, PANDA_PARK)


def test_fuzz_joint_states_while_moving(probe: Probe) -> None:
    """A push is running (enabled, a controller 'matched'): hostile joint states may stop it
    (deviation, a far-future stamp, a restarted clock) but never raise; samples stay bounded.
    Most states are stamped up to 1.5 s before the motion's start (tracked against its start
    posture, as a delayed stream would be), a few anywhere (the ``stamp`` case: a restarted
    clock); impossible postures are never tracked (they are not a posture the arm can be in)."""
    node = probe.node
    node._enabled = True
    node._pub_traj.get_subscription_count = lambda: 1  # the captured publisher is "matched"
    probe.set_clock(MOVING_CLOCK)
    probe.send("joint_states", valid_state(MOVING_CLOCK))
    stops = 0

    @settings(FUZZ, max_examples=N_FUZZ)
    @given(joint_states(around=MOVING_CLOCK))
    def run(msg: JointState) -> None:
        nonlocal stops
        if node._run is None:
            stops += 1
            for _ in range(HELD_STATES):  # the arm held: the push is planned at once
                probe.send("joint_states", valid_state(MOVING_CLOCK))
            probe.send("planner/push", push_path((-0.055, 0.02), (-0.05, 0.02), (0.0, 0.02),
                                                 5.0, 0.02))
        probe.send("joint_states", msg)
        assert node._run is None or node._run.samples <= MAX_SAMPLES

    try:
        run()
    finally:
        node._enabled = False
        node._run = None
        probe.set_clock(CLOCK)
        probe.send("joint_states", valid_state())
    holds = [t for t in probe.trajectories if len(t.points) == 1]
    assert stops >= 2 and len(holds) >= stops - 1


@st.composite
def postures(draw: Callable) -> list[float]:
    """A posture as a glitching encoder reports it: mostly one joint far out (or non-finite),
    sometimes one just inside or just outside the limits widened by state_margin."""
    q = list(PANDA_PARK)
    j = draw(st.integers(0, 6))
    kind = draw(st.sampled_from(["far"] * 6 + ["nonfinite", "outside", "outside", "inside"]))
    lower, upper = PANDA_LOWER[j], PANDA_UPPER[j]
    if kind == "far":
        q[j] = draw(FAR)
    elif kind == "nonfinite":
        q[j] = draw(st.sampled_from(SPECIAL[:3]))
    elif kind == "outside":
        q[j] = draw(st.sampled_from([upper, lower])) + draw(st.sampled_from([1, -1])) * \
            draw(st.floats(STATE_MARGIN * 1.01, 3.0))
        q[j] = q[j] if not lower - STATE_MARGIN <= q[j] <= upper + STATE_MARGIN else upper + 1.0
    else:
        q[j] = upper + draw(st.floats(0.0, 0.9 * STATE_MARGIN))
    return q


def test_fuzz_impossible_postures_then_a_push(probe: Probe) -> None:
    """Enabled, a controller matched: after each hostile posture a valid push. A posture
    outside the limits (+ state_margin) or non-finite is refused with kind ``state`` naming
    the joint and nothing is sent; one just inside is planned and sent with its first point
    at the measured posture."""
    node = probe.node
    node._enabled = True
    node._pub_traj.get_subscription_count = lambda: 1
    planned = 0

    @settings(FUZZ, max_examples=N_POSTURES)
    @given(postures())
    def run(q: list[float]) -> None:
        nonlocal planned
        node._run = None  # the previous push's motion is not watched here
        for _ in range(HELD_STATES):  # the arm held at q: the push is planned at once
            probe.send("joint_states", valid_state(CLOCK, q))
        sent, refused = len(probe.trajectories), len(probe.refused)
        probe.send("planner/push", push_path((-0.055, 0.02), (-0.05, 0.02), (0.0, 0.02), 5.0,
                                             0.02))
        inside = all(math.isfinite(v) and lo - STATE_MARGIN <= v <= hi + STATE_MARGIN
                     for v, lo, hi in zip(q, PANDA_LOWER, PANDA_UPPER, strict=True))
        if inside:  # not refused for its state (the push's own motion may still be refused)
            refusals = [read_refusal(r) for r in probe.refused[refused:]]
            assert all(r.kind not in ("state", "plan") for r in refusals), refusals
            if len(probe.trajectories) == sent + 1:
                order = [probe.trajectories[-1].joint_names.index(j) for j in ARM]
                np.testing.assert_allclose(np.array(probe.trajectories[-1].points[0]
                                                    .positions)[order], q)
                planned += 1
        else:
            assert len(probe.trajectories) == sent
            refusal = read_refusal(probe.refused[-1])
            assert len(probe.refused) == refused + 1 and refusal.kind == "state", refusal
            assert ARM[int(np.argmax([not (math.isfinite(v) and lo - STATE_MARGIN <= v
                                                <= hi + STATE_MARGIN)
                                         for v, lo, hi in zip(q, PANDA_LOWER, PANDA_UPPER,
                                                              strict=True)]))] in refusal.reason

    try:
        run()
    finally:
        node._enabled = False
        node._run = None
        probe.send("joint_states", valid_state())
    assert planned >= 1


def test_fuzz_pushes(probe: Probe) -> None:
    probe.trajectories.clear()

    @FUZZ
    @given(pushes())
    def run(msg: Path) -> None:
        probe.send("joint_states", valid_state())  # fresh: a valid push is planned
        before = len(probe.refused)
        probe.send("planner/push", msg)
        assert len(probe.refused) == before + 1  # every push is answered (dry run)

    run()
    assert not probe.trajectories  # disabled: nothing ever sent


def _kind(answer: Any) -> str:
    """The ``kind`` of an answer (its stamp may be the hostile goal's, not a readable one)."""
    return {kv.key: kv.value for kv in answer.values}["kind"]


def test_fuzz_joint_goals(probe: Probe) -> None:
    """Hostile goals on ``executor/joint_goal`` (the joint-state shapes, far positions): each is
    answered once on ``executor/goal_result``; disabled, nothing is sent."""
    probe.trajectories.clear()
    answers: list[Any] = []
    probe.node._pub_goal.publish = answers.append

    @settings(FUZZ, max_examples=N_FUZZ // 4)
    @given(joint_states())
    def run(msg: JointState) -> None:
        probe.send("joint_states", valid_state())
        before = len(answers)
        probe.send("executor/joint_goal", msg)
        assert len(answers) == before + 1
        assert _kind(answers[-1]) != "reached"

    run()
    assert not probe.trajectories
    kinds = {_kind(a) for a in answers}
    assert {"invalid", "disabled"} <= kinds, kinds


def assert_second_round_bounded(round_trip: Callable[[], None]) -> None:
    """The traced memory grows by less than 5 MB over a second ``round_trip()``."""
    tracemalloc.start()
    try:
        round_trip()
        first = tracemalloc.get_traced_memory()[0]
        round_trip()
        second = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert second - first < 5e6, f"traced memory grew by {(second - first) / 1e6:.1f} MB"


def test_memory_is_bounded(probe: Probe) -> None:
    """A second round of hostile messages on every topic does not grow the traced memory."""
    messages = []

    @settings(FUZZ, max_examples=300)
    @given(descriptions(), joint_states(), pushes())
    def collect(d: String, j: JointState, p: Path) -> None:
        messages.append((d, j, p))

    collect()

    def round_trip() -> None:
        for d, j, p in messages:
            probe.send("robot_description", d)
            probe.send("joint_states", j)
            probe.send("planner/push", p)
        probe.send("robot_description", String(data=URDF))
        probe.refused.clear()
        probe.paths.clear()
        probe.trajectories.clear()

    assert_second_round_bounded(round_trip)


def test_after_fuzzing_the_node_still_plans(probe: Probe) -> None:
    node = probe.node
    probe.send("robot_description", String(data=URDF))
    probe.set_clock(30.0)
    probe.send("joint_states", valid_state(30.0))
    probe.refused.clear()
    probe.paths.clear()
    probe.send("planner/push", push_path((-0.055, 0.02), (-0.05, 0.02), (0.0, 0.02), 9.0, 0.02))
    assert read_refusal(probe.refused[-1]).kind == "disabled"
    assert len(probe.paths) == 1 and len(probe.paths[0].poses) > 100
    assert probe.errors == 0 and node.health.get("refused") > N_FUZZ


# ---- the clear pose's inputs and the episode's state -----------------------------------------
#: Messages of one topic between two pushes planned with whatever the node holds then.
PUSH_EVERY = 250
#: Sides of a camera image (px): valid ones, the limit (8192), beyond it.
SIDES = [0, 1, 2, 48, 64, 640, 8192, 8193, 2**31, 2**32 - 1]
WIDE = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1e300, -1e300, 1e30, 1e-320, 1.0, -1.0])
#: The scene messages come from seeded numpy generators, not hypothesis: its engine cost more
#: per message than the node (10,000 messages).
SCENE_SEED = 33


def _wide(rng: np.random.Generator, n: int) -> np.ndarray:
    """n values, half special (NaN, inf, 1e300, 0, tiny), half random over many decades."""
    return np.where(rng.random(n) < 0.5, rng.choice(WIDE, n),
                    rng.standard_normal(n) * 10.0 ** rng.integers(-3, 40, n))


def _camera() -> tuple[np.ndarray, int, int, np.ndarray]:
    """The simulated camera (sim_bridge.camera defaults): K, width, height, T_world_camera."""
    from sim_bridge.camera import CameraConfig, intrinsics, look_at_pose

    cfg = CameraConfig()
    return intrinsics(cfg), cfg.width, cfg.height, look_at_pose(cfg)


def valid_scene() -> dict[str, Any]:
    """One valid message per scene topic: the simulated camera, butter at the origin and an
    episode that is pushing."""
    k, w, h, t = _camera()
    stamp = stamp_from_seconds(CLOCK)
    points, normals = load_object("butter").outline()
    status = DiagnosticStatus(name="planner", message="pushing step 1", values=[
        KeyValue(key="state", value="pushing"), KeyValue(key="goal", value="0.1 0 0.35")])
    return {"camera/color/camera_info": camera_info_msg(k, w, h, stamp),
            "camera/color/extrinsics": transform_msg(t, stamp, "world", CAMERA_FRAME),
            "perception/outline": outline_cloud_msg(points, normals, stamp),
            "estimator/object_pose": pose_with_covariance_msg((0.0, 0.0, 0.0),
                                                              np.eye(3) * 1e-6, stamp),
            "planner/status": status}


def _stamp(msg: Any, rng: np.random.Generator) -> None:
    msg.header.stamp = stamp_from_seconds(float(rng.uniform(0.0, 50.0))) if rng.random() < 0.7 \
        else Time(sec=int(rng.integers(-2**31, 2**31)), nanosec=int(rng.integers(0, 2**32)))


def hostile_camera_info(rng: np.random.Generator) -> CameraInfo:
    """Absurd sizes (0, beyond 8192, 2^32 - 1) and intrinsics (NaN, inf, 0, 1e300)."""
    n_bad = int(rng.integers(0, 10))
    k, w, h, _ = _camera()
    msg = camera_info_msg(k, w, h, stamp_from_seconds(CLOCK))
    _stamp(msg, rng)
    msg.header.frame_id = str(rng.choice([CAMERA_FRAME] * 3 + ["", "other"]))
    if rng.random() < 0.7:
        msg.width, msg.height = (int(rng.choice(SIDES)) for _ in range(2))
    values = np.array(msg.k)
    values[rng.choice(9, n_bad, replace=False)] = _wide(rng, n_bad)
    msg.k = values.tolist()
    return msg


def hostile_transform(rng: np.random.Generator) -> TransformStamped:
    """NaN, non-unit and zero quaternions, 1e30 m translations, other frames."""
    wild = bool(rng.random() < 0.5)
    msg = TransformStamped()
    _stamp(msg, rng)
    msg.header.frame_id = str(rng.choice(["world", "world", "", "map"]))
    msg.child_frame_id = str(rng.choice([CAMERA_FRAME] * 3 + ["", "other"]))
    t = _wide(rng, 3) if rng.random() < 0.5 else rng.uniform(-2.0, 2.0, 3)
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = \
        (float(v) for v in t)
    v = _wide(rng, 4) if wild else rng.standard_normal(4)
    if not wild:
        v = v / np.linalg.norm(v) * rng.choice([1.0, 1.0 + 5e-4, 1.01, 0.0])
    q = msg.transform.rotation
    q.x, q.y, q.z, q.w = (float(c) for c in v)
    return msg


def hostile_outline(rng: np.random.Generator) -> PointCloud2:
    """NaN / inf / huge values, 0 to 20,000 points, sizes that disagree with the data."""
    kind = str(rng.choice(["values", "count", "layout"]))
    n = int(rng.choice([0, 1, 2, 3, 8, 100, 1000, 4001, 20_000])) if kind == "count" \
        else int(rng.integers(3, 200))
    points = rng.uniform(-0.05, 0.05, (n, 2))
    normals = points / np.maximum(np.linalg.norm(points, axis=1, keepdims=True), 1e-9)
    msg = outline_cloud_msg(points, normals, stamp_from_seconds(CLOCK))
    if kind == "values" and n:  # NaN, inf, huge values in the float32 fields (the writer
        raw = np.frombuffer(bytes(msg.data), dtype="<f4").reshape(n, 6).copy()  # refuses them)
        bad = rng.random(raw.shape) < 0.1
        with np.errstate(over="ignore"):
            raw[bad] = _wide(rng, int(bad.sum())).astype(np.float32)
        msg.data = raw.tobytes()
    msg.header.frame_id = str(rng.choice(["object"] * 3 + ["", "world"]))
    if kind == "layout":  # sizes that disagree with the data
        field = str(rng.choice(["width", "height", "point_step", "row_step", "data"]))
        if field == "data":
            msg.data = bytes(rng.integers(0, 256, int(rng.integers(0, 100)), dtype=np.uint8))
        else:
            setattr(msg, field, int(rng.choice([0, 1, 7, 23, 25, 2**31, 2**32 - 1])))
    return msg


def hostile_object_pose(rng: np.random.Generator) -> PoseWithCovarianceStamped:
    """NaN / huge positions and quaternions, other frames, absurd covariances."""
    n_bad = int(rng.integers(0, 7))
    values = np.array([*rng.uniform(-0.3, 0.3, 2), rng.uniform(-4.0, 4.0)])
    msg = pose_with_covariance_msg(values, np.eye(3) * 1e-6, stamp_from_seconds(CLOCK))
    _stamp(msg, rng)
    msg.header.frame_id = str(rng.choice(["world"] * 3 + ["", "map"]))
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    fields = [(p, "x"), (p, "y"), (p, "z"), (q, "x"), (q, "y"), (q, "z"), (q, "w")]
    for i in rng.choice(len(fields), min(n_bad, len(fields)), replace=False):
        obj, name = fields[i]
        setattr(obj, name, float(_wide(rng, 1)[0]))
    if rng.random() < 0.3:
        msg.pose.covariance = _wide(rng, 36).tolist()
    return msg


def hostile_status(rng: np.random.Generator) -> DiagnosticStatus:
    """Any state and goal (the episode over or not), none to 2,000 values, huge texts."""
    n = int(rng.choice([0, 1, 2, 2, 2, 5, 2000]))
    words = ["state", "goal", "step", "", "x" * 1000]
    states = ["reached", "failed", "left", "pushing", "waiting", "unavailable", "", "x" * 1000]
    goals = ["0.1 0 0.35", "", "nan nan nan", "x", "1e308 1e308 1"]
    values = [KeyValue(key="state", value=str(rng.choice(states))),
              KeyValue(key="goal", value=str(rng.choice(goals)))][:n]
    extra = KeyValue(key=str(rng.choice(words)), value=str(rng.choice(states + goals)))
    values += [extra] * max(0, n - 2)  # one message many times: the node reads each
    return DiagnosticStatus(level=bytes([int(rng.integers(0, 256))]), name="planner",
                            message=str(rng.choice(["", "pushing", "x" * 5000])), values=values)


SCENE = {"camera/color/camera_info": hostile_camera_info,
         "camera/color/extrinsics": hostile_transform,
         "perception/outline": hostile_outline,
         "estimator/object_pose": hostile_object_pose,
         "planner/status": hostile_status}


@pytest.fixture(scope="module")
def scene_probe(module_ros_context: Any) -> Iterator[Probe]:
    """A dry-run node with the simulator's URDF (meshes found: the robot image exists) and
    valid scene inputs: its pushes are planned to a clear pose."""
    from sim_bridge.arm_robot import arm_urdf

    node = PushExecutorNode(context=module_ros_context, namespace="scene",
                            parameter_overrides=[Parameter("start_enabled", value=False),
                                                 Parameter("use_sim_time", value=True)])
    try:
        p = Probe(node)
        p.set_clock(CLOCK)
        p.send("robot_description", String(data=arm_urdf(PUSHER_RADIUS)))
        assert node._arm is not None and node._robot is not None
        for topic, msg in valid_scene().items():
            p.send(topic, msg)
        yield p
    finally:
        node.destroy_node()


def scene_push(probe: Probe) -> str:
    """A push planned with whatever the node holds (dry run: always answered); the clear
    pose's word on it (``executor/status`` value ``view``)."""
    for _ in range(HELD_STATES):
        probe.send("joint_states", valid_state())
    before = len(probe.refused)
    probe.send("planner/push", push_path((-0.055, 0.02), (-0.05, 0.02), (0.0, 0.02), 5.0, 0.02))
    assert len(probe.refused) == before + 1
    assert read_refusal(probe.refused[-1]).kind == "disabled"
    return probe.node._plan_values["view"]


def _fuzz_topic(probe: Probe, topic: str, make: Callable[[np.random.Generator], Any],
                seed: int) -> int:
    """N_FUZZ messages of ``make`` on ``topic``, a push every PUSH_EVERY; how many sent."""
    rng = np.random.default_rng(seed)
    for sent in range(1, N_FUZZ + 1):
        probe.send(topic, make(rng))
        if sent % PUSH_EVERY == 0:
            scene_push(probe)
    return N_FUZZ


def test_fuzz_scene_inputs(scene_probe: Probe) -> None:
    """2,000 hostile messages on each of the clear pose's inputs and planner/status, a push
    planned every PUSH_EVERY of them with whatever was accepted; then, the valid inputs again,
    the push ends at a clear pose."""
    probe = scene_probe
    assert scene_push(probe) == "clear pose"
    for i, (topic, make) in enumerate(SCENE.items()):
        assert _fuzz_topic(probe, topic, make, SCENE_SEED + i) == N_FUZZ
        probe.send(topic, valid_scene()[topic])
        assert scene_push(probe) == "clear pose", topic
    assert probe.node.health.get("refused_invalid") > 0


def test_scene_memory_is_bounded(scene_probe: Probe) -> None:
    """A second round of hostile scene messages (and pushes) does not grow the traced memory."""
    rng = np.random.default_rng(SCENE_SEED)
    messages = [[make(rng) for make in SCENE.values()] for _ in range(100)]
    probe = scene_probe

    def round_trip() -> None:
        for i, msgs in enumerate(messages):
            for topic, msg in zip(SCENE, msgs, strict=True):
                probe.send(topic, msg)
            if i % 25 == 0:
                scene_push(probe)
        for topic, msg in valid_scene().items():
            probe.send(topic, msg)
        probe.refused.clear()
        probe.paths.clear()

    assert_second_round_bounded(round_trip)
