"""Fuzz tests of push_executor_node: hostile messages on every subscribed topic.

The project's fuzz pattern (tests/ros/test_fuzz_planner.py): in-process against the real node
class, the test calls the guarded callbacks the node subscribed (found by topic) with real
message objects built by hypothesis strategies, no DDS, 2,000 messages per topic:

- ``planner/push``: NaN / inf / huge coordinates, 0-50 poses, other frames, bad stamps;
- ``/joint_states``: wrong sizes, mismatched name / position lengths, NaN / inf, repeated and
  unknown names, huge arrays, bad and future stamps -- while idle and while a push is running;
- ``/robot_description``: garbage XML, truncated and mutated URDFs, other robots, a 10 MB
  string.

After every message no exception reached a guard (``callback_errors`` stays 0). Afterwards the
node still plans a push (dry run: ``executor/path`` and a ``disabled`` refusal), held state is
bounded (model text, recorded samples) and the traced memory did not grow by more than a few
MB over a second round of the same messages. Reproducible: hypothesis derandomized.
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
from geometry_msgs.msg import PoseStamped  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from nav_msgs.msg import Path  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from push_core.robot_view import MAX_URDF_CHARS  # noqa: E402
from push_executor.kinematics import ArmKinematics, ToolSpec  # noqa: E402
from push_executor.motion_types import PANDA_PARK  # noqa: E402
from push_executor.push_executor_node import HELD_STATES, PushExecutorNode  # noqa: E402
from push_executor.state_check import StateCheckConfig  # noqa: E402
from push_executor.tracking import MAX_SAMPLES  # noqa: E402
from push_ros.paths import push_path  # noqa: E402
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
#: The clock while a push runs under fuzzing: ahead of every drawn joint state stamp (0-50 s).
MOVING_CLOCK = 60.0


class Probe:
    """The node, its subscription callbacks by topic and what it publishes (captured)."""

    def __init__(self, node: PushExecutorNode) -> None:
        self.node = node
        self.callbacks = {sub.topic_name.lstrip("/"): sub.callback for sub in node.subscriptions}
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
def joint_states(draw: Callable, far: bool = True) -> JointState:
    kind = draw(st.sampled_from(["ok", "ok", "nan", *(["far"] if far else []), "short", "long",
                                 "mismatch", "repeat", "unknown", "huge", "stamp", "empty"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    q = np.array(PANDA_PARK) + rng.normal(0.0, draw(st.sampled_from([1e-3] * 20 + [0.2])), 7)
    msg = valid_state(draw(st.floats(0.0, 20.0)), q)
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
    elif kind == "stamp":
        msg.header.stamp = draw(STAMP)
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
    (deviation, a far-future stamp) but never raise; samples stay bounded. The clock is ahead
    of the drawn stamps (0-50 s), so most states are older than the motion's start (tracked
    against its start posture, as a delayed stream would be); impossible postures are never
    tracked (they are not a posture the arm can be in)."""
    node = probe.node
    node._enabled = True
    node._pub_traj.get_subscription_count = lambda: 1  # the captured publisher is "matched"
    probe.set_clock(MOVING_CLOCK)
    probe.send("joint_states", valid_state(MOVING_CLOCK))
    stops = 0

    @settings(FUZZ, max_examples=N_FUZZ)
    @given(joint_states())
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

    tracemalloc.start()
    try:
        round_trip()
        first = tracemalloc.get_traced_memory()[0]
        round_trip()
        second = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert second - first < 5e6, f"traced memory grew by {(second - first) / 1e6:.1f} MB"


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
