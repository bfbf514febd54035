"""Fuzz tests of planner_node: hostile messages on every subscribed topic.

In-process against the real node class: the test calls the callbacks the node subscribed (the
guarded callables of its ``rclpy`` subscriptions, found by topic; ``goal_pose`` with a message
info dict, as rclpy passes it) directly with real message objects built by hypothesis
strategies, no DDS, at least 2,000 messages per topic:

- ``goal_pose``: NaN / inf, non-unit and non-planar quaternions, other frames, off the
  workspace, random message infos (sequence numbers, GIDs);
- ``estimator/object_pose`` + ``estimator/state``: bad layouts and sizes, NaN / inf, absurd
  covariances and states (l, m, COM), extreme stamps, pairs that match and pairs that do not;
- ``perception/outline``: bad fields, offsets, steps and sizes, NaN, clockwise and
  self-intersecting outlines, objects larger than the workspace, counts up to 200 (and,
  deterministically, 1,001 and 20,000: decimated to ``MAX_OUTLINE_POINTS``);
- ``pusher/executed``: empty, other frames, NaN poses, extreme and reversed stamps;
- ``pusher/refused``: malformed and foreign ``push_stamp`` values, missing and
  repeated keys, huge names and reasons, and refusals of the push in flight (each a lost push
  and a new plan, until the episode fails and is reset);
- parameter sets (random values of every parameter, then ``~/reset``).

After every message: no exception reached a guard (the node's ``callback_errors`` counter stays 0);
a refused message (``refused`` counter up) changed nothing (:func:`snapshot`). At the end the
node still plans a correct push for a valid outline + estimate + goal. Caps are asserted by
counters and sizes, never by timing.

A smaller over-DDS run publishes 100 hostile messages per topic on the real topics and checks
the node is alive and answers ``~/reset``.

Reproducible: hypothesis runs derandomized, no deadline, no database.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

hypothesis = pytest.importorskip("hypothesis")

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue  # noqa: E402
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped  # noqa: E402
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from nav_msgs.msg import Path  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import PointCloud2, PointField  # noqa: E402
from std_msgs.msg import Float64MultiArray, MultiArrayDimension  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from push_core.objects import load_object  # noqa: E402
from push_core.planner import MAX_OUTLINE_POINTS  # noqa: E402
from push_planner.planner_node import PARAMETERS, PlannerNode  # noqa: E402
from push_ros.outline import outline_cloud_msg  # noqa: E402
from push_ros.poses import pose_with_covariance_msg  # noqa: E402
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS  # noqa: E402
from push_ros.refusal import (  # noqa: E402
    MOVING_KINDS,
    read_readiness,
    read_refusal,
    robot_unavailable,
)
from push_ros.stamps import stamp_from_seconds  # noqa: E402
from push_ros.state import state_array_msg  # noqa: E402

#: Messages per topic of the in-process run (at least 2,000: rare malformations get hit).
N_FUZZ = 2000
FUZZ = settings(max_examples=N_FUZZ, deadline=None, derandomize=True, database=None,
                suppress_health_check=list(HealthCheck))
#: Estimates planned for (goal present): each costs a plan, so fewer.
N_PLANNED = 300
#: Parameter sets, each followed by a ~/reset.
N_PARAMS = 400
#: Messages per topic of the over-DDS run.
N_DDS = 100

SPEC = load_object("rect1")
L_GUESS = SPEC.limit_surface_guess()
POINTS, NORMALS = SPEC.outline(0.002)
#: Far outside the test's stamps (the wall clock is ~1.8e9 s): estimates stamped 1000 s + i.
T0 = 1000.0

SPECIAL = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1e300, -1e300, 1e-320, 1.0, -1.0, 0.05,
           0.3, 1e6]
FRAMES = ["world", "object", "", "map", "World", "world ", "x" * 300]

# Strategies are built once (building one per draw costs hypothesis more than the node costs
# per message); bulk values come from a numpy generator seeded by one drawn integer.
FLOAT = st.one_of(st.sampled_from(SPECIAL), st.floats(-0.2, 0.2),
                  st.floats(allow_nan=True, allow_infinity=True))
WIDE = st.one_of(FLOAT, st.floats(-0.4, 0.4), st.floats(0.0, 20.0))
SEED = st.integers(0, 2**32 - 1)
BOOL = st.booleans()
FRAME = st.sampled_from(FRAMES[:1] * 6 + FRAMES)
_PLAUSIBLE = st.floats(T0, T0 + 50.0).map(stamp_from_seconds)
STAMP = st.one_of(_PLAUSIBLE, _PLAUSIBLE,
                  st.builds(Time, sec=st.integers(-(2**31), 2**31 - 1),
                            nanosec=st.integers(0, 2**32 - 1)),
                  st.sampled_from([Time(sec=2147483647, nanosec=999_999_999),
                                   Time(sec=2147483646, nanosec=0), Time(sec=-1, nanosec=0),
                                   Time(sec=0, nanosec=1_000_000_000), Time(sec=0, nanosec=0)]))
_YAW = st.floats(-10.0, 10.0).map(lambda a: (0.0, 0.0, math.sin(a / 2), math.cos(a / 2)))
QUATERNION = st.one_of(
    _YAW, _YAW,
    st.tuples(_YAW, st.sampled_from([0.5, 1.0005, 1.01, 2.0, 1e300, math.nan, 0.0])).map(
        lambda qs: tuple(v * qs[1] for v in qs[0])),
    _YAW.map(lambda q: (0.3, 0.0, 0.9 * q[2], 0.9 * q[3])),
    st.tuples(FLOAT, FLOAT, FLOAT, FLOAT))
INFO = st.one_of(
    st.none(), st.just({}),
    st.fixed_dictionaries({"publication_sequence_number": st.one_of(
        st.none(), st.integers(0, 2**64 - 1), st.booleans())}),
    st.fixed_dictionaries({"publication_sequence_number": st.integers(0, 50),
                           "publisher_gid": st.one_of(
                               st.none(), st.binary(max_size=24), st.just("bad"),
                               st.fixed_dictionaries({"data": st.lists(
                                   st.integers(-5, 300), max_size=24)}))}))


def values(seed: int, n: int, scale: float = 0.2) -> np.ndarray:
    """n values: a quarter special (NaN, inf, 1e300, ...), the rest within +-scale or wide."""
    rng = np.random.default_rng(seed)
    with np.errstate(all="ignore"):
        wide = rng.standard_normal(n) * 10.0 ** rng.integers(-6, 40, n)
        v = np.where(rng.random(n) < 0.5, rng.uniform(-scale, scale, n), wide)
    return np.where(rng.random(n) < 0.25, rng.choice(SPECIAL, n), v)


@st.composite
def goals(draw: Callable) -> tuple[PoseStamped, dict[str, Any] | None]:
    msg = PoseStamped()
    msg.header.frame_id = draw(FRAME)
    msg.header.stamp = draw(STAMP)
    msg.pose.position.x, msg.pose.position.y = draw(WIDE), draw(WIDE)
    msg.pose.position.z = draw(st.sampled_from([0.0, 0.0, 1.0, math.nan]))
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = draw(QUATERNION)
    return msg, draw(INFO)


COVARIANCE_KIND = st.sampled_from(["zero", "diag", "diag", "full", "psd"])


def covariance(kind: str, seed: int, n: int) -> np.ndarray:
    v = values(seed, n * n, 1e-3).reshape(n, n)
    if kind == "zero":
        return np.zeros((n, n))
    if kind == "diag":
        return np.diag(np.abs(np.diag(v)) * np.where(np.diag(v) < 0, -1.0, 1.0))
    if kind == "psd":
        with np.errstate(all="ignore"):
            return v @ v.T
    return v


STATE_LAYOUT = st.sampled_from(["ok"] * 6 + ["label", "size", "offset", "short", "long",
                                             "dims"])
QUATERNION_KIND = st.sampled_from(["yaw", "yaw", "yaw", "scaled", "tilted", "random", "zero"])
ESTIMATE_KIND = st.sampled_from(["pair", "pair", "pair", "mismatch", "pose", "state"])


def quaternion(kind: str, theta: float, rng: np.random.Generator) -> list[float]:
    with np.errstate(all="ignore"):
        q = np.array([0.0, 0.0, np.sin(theta / 2), np.cos(theta / 2)])
        if kind == "scaled":
            q = q * rng.choice([0.5, 1.0005, 1.01, 2.0, 1e300, math.nan])
        elif kind == "tilted":
            q = np.array([0.3, 0.0, 0.9 * q[2], 0.9 * q[3]])
        elif kind == "random":
            q = values(int(rng.integers(2**32)), 4, 1.0)
        elif kind == "zero":
            q = np.zeros(4)
    return [float(v) for v in q]


def state_msg(pose: np.ndarray, rng: np.random.Generator, cov_kind: str, layout: str
              ) -> Float64MultiArray:
    """A state of ``pose``: COM, l, m plausible or not, any covariance, any layout."""
    extra = values(int(rng.integers(2**32)), 4, 0.2)
    plausible = np.array([0.0, 0.0, L_GUESS, 0.25])
    row = np.concatenate([pose, np.where(rng.random(4) < 0.5, plausible, extra)])
    msg = state_array_msg(np.zeros(7))
    cov = covariance(cov_kind, int(rng.integers(2**32)), 7)
    msg.data = [float(v) for v in np.concatenate([row, cov.ravel()])]
    if layout == "label":
        msg.layout.dim[0].label = "x"
    elif layout == "size":
        msg.layout.dim[1].size = 48
    elif layout == "offset":
        msg.layout.data_offset = 3
    elif layout == "short":
        msg.data = msg.data[:int(rng.integers(0, 56))]
    elif layout == "long":
        msg.data = list(msg.data) + [0.0] * int(rng.integers(1, 100))
    elif layout == "dims":
        msg.layout.dim = [MultiArrayDimension(label="state", size=56, stride=56)]
    return msg


def pose_msg(pose: np.ndarray, rng: np.random.Generator, stamp: Time, frame: str,
             q_kind: str, cov_kind: str) -> PoseWithCovarianceStamped:
    msg = pose_with_covariance_msg([0.0, 0.0, 0.0], np.eye(3) * 1e-6, stamp, frame_id=frame)
    msg.pose.pose.position.x, msg.pose.pose.position.y = float(pose[0]), float(pose[1])
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = quaternion(q_kind, float(pose[2]), rng)
    msg.pose.covariance = [float(v) for v in covariance(cov_kind, int(rng.integers(2**32)),
                                                        6).ravel()]
    return msg


@st.composite
def estimates(draw: Callable) -> list[Any]:
    """A pose and a state: of the same pose (a pair) or not, in either order, or only one."""
    kind = draw(ESTIMATE_KIND)
    rng = np.random.default_rng(draw(SEED))
    pose = values(int(rng.integers(2**32)), 3, 0.2)
    pose_out = pose_msg(pose, rng, draw(STAMP), draw(FRAME), draw(QUATERNION_KIND),
                        draw(COVARIANCE_KIND))
    of = pose if kind == "pair" else values(int(rng.integers(2**32)), 3, 0.2)
    state_out = state_msg(of, rng, draw(COVARIANCE_KIND), draw(STATE_LAYOUT))
    msgs = {"pair": [pose_out, state_out], "mismatch": [pose_out, state_out],
            "pose": [pose_out], "state": [state_out]}[kind]
    return msgs[::-1] if draw(BOOL) else msgs


def star(n: int, radius: float, jitter: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    r = radius * (1.0 + jitter * np.random.default_rng(seed).standard_normal(n))
    normals = np.stack([np.cos(a), np.sin(a)], axis=1)
    return r[:, None] * normals, normals


CLOUD_SIZE = st.sampled_from([0, 1, 2, 3, 4, 8, 40, 40, 40, 40, 100, 200])
CLOUD_RADIUS = st.sampled_from([0.05, 0.05, 1e-9, 0.5, 2.0, 1e3, 1e30])
CLOUD_JITTER = st.sampled_from([0.0, 0.01, 0.5, 3.0])
CLOUD_LAYOUT = st.sampled_from(["ok"] * 5 + ["field", "type", "offset", "step", "row", "bytes",
                                             "height", "endian"])
OUTLINE_FIELDS = ("x", "y", "z", "normal_x", "normal_y", "normal_z")


@st.composite
def clouds(draw: Callable) -> PointCloud2:
    n = draw(CLOUD_SIZE)
    pts, normals = star(max(n, 1), draw(CLOUD_RADIUS), draw(CLOUD_JITTER), draw(SEED))
    pts, normals = pts[:n], normals[:n]
    if draw(BOOL):
        pts, normals = pts[::-1], normals[::-1]  # clockwise
    if n and draw(st.integers(0, 9)) == 0:
        pts[draw(st.integers(0, n - 1)), draw(st.integers(0, 1))] = draw(st.sampled_from(
            [math.nan, math.inf]))
    with np.errstate(all="ignore"):
        data = np.zeros((n, 6), dtype="<f4")
        data[:, 0:2], data[:, 3:5] = pts, normals
    msg = outline_cloud_msg(np.zeros((0, 2)), np.zeros((0, 2)))
    msg.header.frame_id = draw(st.sampled_from(["object"] * 6 + FRAMES))
    msg.width, msg.height, msg.row_step = n, 1, 24 * n
    msg.data = array("B", data.tobytes())
    msg.fields = [PointField(name=f, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, f in enumerate(OUTLINE_FIELDS)]
    layout = draw(CLOUD_LAYOUT)
    if layout == "field":
        msg.fields = msg.fields[:draw(st.integers(0, 5))]
    elif layout == "type":
        msg.fields[draw(st.integers(0, 5))].datatype = draw(st.integers(0, 8))
    elif layout == "offset":
        msg.fields[draw(st.integers(0, 5))].offset = draw(st.sampled_from([21, 24, 2**31]))
    elif layout == "step":
        msg.point_step = draw(st.sampled_from([0, 4, 23, 25]))
    elif layout == "row":
        msg.row_step = draw(st.sampled_from([0, max(24 * n - 1, 0), 24 * n + 8]))
    elif layout == "bytes":
        msg.data = array("B", bytes(draw(st.integers(0, 64))))
    elif layout == "height":
        msg.height = draw(st.sampled_from([0, 2, 2**31]))
    elif layout == "endian":
        msg.is_bigendian = True
    return msg


PATH_SIZE = st.sampled_from([2, 2, 2, 0, 1, 3, 50])
POSE_FRAME = st.sampled_from(["", "world", "map"])


@st.composite
def paths(draw: Callable) -> Path:
    msg = Path()
    msg.header.frame_id = draw(FRAME)
    msg.header.stamp = draw(STAMP)
    n = draw(PATH_SIZE)
    seed = draw(SEED)
    xy = values(seed, 2 * n).reshape(n, 2)
    rng = np.random.default_rng(seed + 1)
    mode = draw(st.sampled_from(["ordered", "reversed", "each"]))
    t0 = draw(STAMP)
    frame = draw(POSE_FRAME)
    for i in range(n):
        pose = PoseStamped()
        pose.header.frame_id = frame
        pose.pose.position.x, pose.pose.position.y = float(xy[i, 0]), float(xy[i, 1])
        if mode == "each":
            pose.header.stamp = Time(sec=int(rng.integers(-(2**31), 2**31)),
                                     nanosec=int(rng.integers(0, 2**32)))
        else:
            sec = t0.sec + (-i if mode == "reversed" else i)
            pose.header.stamp = Time(sec=min(max(sec, -(2**31)), 2**31 - 1), nanosec=t0.nanosec)
        msg.poses.append(pose)
    return msg


TEXT = st.one_of(st.text(max_size=40), st.sampled_from(["", "x" * 100_000, "\x00", "busy"]))
PUSH_STAMP = st.one_of(
    st.just("IN_FLIGHT"),
    st.builds(lambda s, n: f"{s}.{n:09d}", st.integers(0, 2**31), st.integers(0, 10**9 - 1)),
    st.sampled_from(["", "1", "1.5", "-1.000000000", "1.0000000000", "\u00b21.000000000",
                     "1.00000000a", "99999999999.000000000", " 1.000000000", "nan"]),
    TEXT)
KEY = st.sampled_from(["push_stamp", "push_stamp", "kind", "stage", "other", ""])


@st.composite
def refusals(draw: Callable) -> tuple[DiagnosticStatus, bool]:
    """A ``pusher/refused`` message; the flag: its push_stamp is the push in flight's
    (``IN_FLIGHT`` is replaced when sent)."""
    msg = DiagnosticStatus(level=bytes([draw(st.integers(0, 255))]), name=draw(TEXT),
                           message=draw(TEXT), hardware_id=draw(TEXT))
    pairs = draw(st.lists(st.tuples(KEY, st.one_of(PUSH_STAMP, TEXT)), max_size=6))
    stamp = draw(PUSH_STAMP)
    if draw(st.integers(0, 4)):  # mostly with a push_stamp first
        pairs.insert(0, ("push_stamp", stamp))
    msg.values = [KeyValue(key=k, value=v) for k, v in pairs]
    if draw(st.integers(0, 9)) == 0:
        msg.values = [KeyValue(key="other", value="")] * 40 + msg.values
    return msg, any(v == "IN_FLIGHT" for _, v in pairs)


# ---- the node ----------------------------------------------------------------------------------
class Probe:
    """The node, its subscription callbacks by topic, its service and what it publishes."""

    def __init__(self, node: PlannerNode) -> None:
        self.node = node
        self.callbacks = {sub.topic_name.lstrip("/"): sub.callback for sub in node.subscriptions}
        self.reset_callback = next(s.callback for s in node.services
                                   if s.srv_name.endswith("/reset"))
        self.pushes: list[Path] = []
        node._pub_push.publish = self.pushes.append  # captured, not sent

    def send(self, topic: str, msg: Any, info: Any = None) -> None:
        if topic == "goal_pose":
            self.callbacks[topic](msg, info)
        else:
            self.callbacks[topic](msg)

    def reset(self) -> Trigger.Response:
        return self.reset_callback(Trigger.Request(), Trigger.Response())

    @property
    def errors(self) -> int:
        return self.node.health.get("callback_errors")

    @property
    def refused(self) -> int:
        return self.node.health.get("refused")


def snapshot(node: PlannerNode) -> tuple:
    """Everything an input may change (the counters of accepted inputs excepted)."""
    e = node._engine
    latest = None if e.latest is None else (e.latest[0], e.latest[1].tobytes())
    return (None if e.goal is None else e.goal.tobytes(), id(e.outline), latest,
            e.last_push_end, e.steps, e.phase, e.in_flight, len(e._avoid),
            tuple((s, p.tobytes()) for s, p in node._pairing.poses),
            tuple(s.tobytes() for s, _ in node._pairing.states), node._goals.source,
            node.params)


def send_checked(probe: Probe, topic: str, msg: Any, info: Any = None) -> None:
    before, refused = snapshot(probe.node), probe.refused
    probe.send(topic, msg, info)
    assert probe.errors == 0, probe.node.health.last_error
    if probe.refused > refused and topic not in ("estimator/object_pose", "estimator/state"):
        assert snapshot(probe.node) == before, f"refused {topic} changed the state"


def send_estimate_checked(probe: Probe, msgs: list[Any]) -> None:
    for msg in msgs:
        topic = "estimator/state" if isinstance(msg, Float64MultiArray) else \
            "estimator/object_pose"
        before, refused = snapshot(probe.node), probe.refused
        probe.send(topic, msg)
        assert probe.errors == 0, probe.node.health.last_error
        if probe.refused > refused and probe.node.health.last_refusal.startswith(topic):
            assert snapshot(probe.node) == before, f"refused {topic} changed the state"


@pytest.fixture(scope="module")
def probe(module_ros_context: Any) -> Iterator[Probe]:
    node = PlannerNode(context=module_ros_context, parameter_overrides=[
        Parameter("k", value=1), Parameter("seed", value=3)])
    try:
        yield Probe(node)
    finally:
        node.destroy_node()


def valid_cloud() -> PointCloud2:
    return outline_cloud_msg(POINTS, NORMALS)


def valid_goal(x: float = 0.1) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "world"
    msg.pose.position.x, msg.pose.orientation.w = x, 1.0
    return msg


def send_valid_estimate(probe: Probe, pose: tuple[float, float, float], stamp: float) -> None:
    x, y, th = pose
    probe.send("estimator/state", state_array_msg([x, y, th, 0.0, 0.0, L_GUESS, 0.25],
                                                  np.diag([1e-8] * 7)))
    probe.send("estimator/object_pose", pose_with_covariance_msg(
        pose, np.eye(3) * 1e-8, stamp_from_seconds(stamp)))


# ---- in-process fuzzing ------------------------------------------------------------------------
def test_fuzz_goals(probe: Probe) -> None:
    assert probe.reset().success
    probe.send("perception/outline", valid_cloud())  # an outline, no estimate: nothing planned

    @FUZZ
    @given(goals())
    def run(case: tuple[PoseStamped, dict[str, Any] | None]) -> None:
        send_checked(probe, "goal_pose", *case)

    run()
    assert not probe.pushes and probe.errors == 0


def test_fuzz_outlines(probe: Probe) -> None:
    assert probe.reset().success

    @FUZZ
    @given(clouds())
    def run(msg: PointCloud2) -> None:
        send_checked(probe, "perception/outline", msg)
        outline = probe.node._engine.outline
        assert outline is None or len(outline.points) <= MAX_OUTLINE_POINTS

    run()
    # Large but valid clouds: decimated to the cap (by counts, not by timing).
    for n in (MAX_OUTLINE_POINTS + 1, 20000):
        pts, normals = star(n, 0.05, 0.0, 0)
        probe.send("perception/outline", outline_cloud_msg(pts, normals))
        outline = probe.node._engine.outline
        assert outline.source_points == n and len(outline.points) == MAX_OUTLINE_POINTS
    # An object larger than the workspace is refused with the reason.
    pts, normals = star(40, 1000.0, 0.0, 0)
    send_checked(probe, "perception/outline", outline_cloud_msg(pts, normals))
    assert "workspace diagonal" in probe.node.health.last_refusal
    assert probe.errors == 0


def test_fuzz_estimates(probe: Probe) -> None:
    assert probe.reset().success
    probe.send("perception/outline", valid_cloud())  # no goal: stored, never planned

    @FUZZ
    @given(estimates())
    def run(msgs: list[Any]) -> None:
        send_estimate_checked(probe, msgs)

    run()
    assert not probe.pushes and probe.errors == 0


def test_fuzz_estimates_that_are_planned_for(probe: Probe) -> None:
    """With outline and goal: each accepted estimate is decided on (goal check with absurd
    covariances, plans with absurd but accepted states); the pushes are reported executed."""
    assert probe.reset().success
    probe.send("perception/outline", valid_cloud())
    probe.send("goal_pose", valid_goal(), None)
    clock = [T0]

    @settings(FUZZ, max_examples=N_PLANNED)
    @given(estimates())
    def run(msgs: list[Any]) -> None:
        send_estimate_checked(probe, msgs)
        if probe.node._engine.in_flight:
            clock[0] += 1e-3
            probe.send("pusher/executed", executed(clock[0]))
        assert probe.node._engine.steps <= probe.node.params.max_steps

    run()
    assert probe.errors == 0


def test_fuzz_executed(probe: Probe) -> None:
    assert probe.reset().success

    @FUZZ
    @given(paths())
    def run(msg: Path) -> None:
        send_checked(probe, "pusher/executed", msg)

    run()
    assert probe.errors == 0


def start_pushing(probe: Probe) -> None:
    """A new episode with a push in flight."""
    assert probe.reset().success
    probe.send("perception/outline", valid_cloud())
    probe.send("goal_pose", valid_goal(), None)
    send_valid_estimate(probe, (0.0, 0.0, 0.0), T0)
    assert probe.node._engine.in_flight


def test_fuzz_refusals(probe: Probe) -> None:
    start_pushing(probe)
    matched = [0]

    @FUZZ
    @given(refusals())
    def run(case: tuple[DiagnosticStatus, bool]) -> None:
        msg, _ = case
        node = probe.node
        in_flight = node._push_key
        for kv in msg.values:
            if kv.value == "IN_FLIGHT":
                kv.value = in_flight or "0.000000000"
        before, lost, pushes = snapshot(node), node._engine.counts["lost"], len(probe.pushes)
        refused_before = node.health.get("pushes_refused")
        probe.send("pusher/refused", msg)
        assert probe.errors == 0, node.health.last_error
        if node.health.get("pushes_refused") == refused_before:  # refused or ignored: no change
            assert snapshot(node) == before and len(probe.pushes) == pushes
            return
        matched[0] += 1
        refusal = read_refusal(msg)
        if robot_unavailable(refusal):  # the episode waits for the robot: nothing planned
            steps = node._engine.steps
            assert node._engine.phase == "unavailable" and len(probe.pushes) == pushes
            assert node._engine.counts["lost"] == lost + (refusal.kind in MOVING_KINDS)
            assert "robot unavailable" in node.health.status(node._level,
                                                             *node._status_text()).message
            assert node._engine.robot_available(T0) and node._engine.steps == steps
            start_pushing(probe)
            return
        assert node._engine.counts["lost"] == lost + 1
        assert "refused" in node.health.status(node._level, *node._status_text()).message
        if refusal.kind in MOVING_KINDS:  # the robot may move: wait for an estimate
            assert len(probe.pushes) == pushes and not node._engine.in_flight
        else:
            assert len(probe.pushes) == pushes + (node._engine.phase == "pushing")
        if not node._engine.in_flight:  # failed (max steps, no feasible push): a new episode
            start_pushing(probe)

    run()
    assert matched[0] >= N_FUZZ // 20 and probe.errors == 0
    assert probe.refused > 0 and probe.node.health.get("refusals_ignored") > 0


@st.composite
def executor_statuses(draw: Callable) -> DiagnosticStatus:
    """An ``executor/status``: readiness values (``ready``, ``unavailable``, ``session``)
    mostly plausible, sometimes garbage, among other keys."""
    msg = DiagnosticStatus(level=bytes([draw(st.integers(0, 255))]), name=draw(TEXT),
                           message=draw(TEXT))
    pairs = draw(st.lists(st.tuples(KEY, TEXT), max_size=4))
    pairs.append(("ready", draw(st.sampled_from(["true", "false", "true", "", "TRUE", "1",
                                                 "x" * 300]))))
    pairs.append(("session", draw(st.sampled_from(["s1", "s1", "s1", "s2", "", "s" * 500]))))
    pairs.append(("unavailable", draw(TEXT)))
    msg.values = [KeyValue(key=k, value=v) for k, v in draw(st.permutations(pairs))]
    if draw(st.integers(0, 9)) == 0:
        msg.values = [KeyValue(key="other", value="")] * 100 + msg.values
    return msg


def test_fuzz_executor_status(probe: Probe) -> None:
    """Hostile ``executor/status`` messages while pushing, waiting for the robot or idle: no
    exception; a waiting episode resumes only on ``ready: true``; a push in flight is counted
    lost only on a new session; never more steps than ``max_steps``."""
    start_pushing(probe)

    @settings(FUZZ, max_examples=N_PLANNED)  # a push given back is planned again: a plan each
    @given(executor_statuses(), st.sampled_from(["pushing", "pushing", "unavailable"]))
    def run(msg: DiagnosticStatus, mode: str) -> None:
        node = probe.node
        engine = node._engine
        if not engine.in_flight and engine.phase != "unavailable":
            start_pushing(probe)
        if mode == "unavailable" and engine.in_flight:
            engine.robot_unavailable("no_state: fuzz", 0.0)
        phase, lost, session = engine.phase, engine.counts["lost"], node._robot._push_session
        probe.send("executor/status", msg)
        assert probe.errors == 0, node.health.last_error
        readiness = read_readiness(msg)
        if phase == "unavailable" and engine.phase != "unavailable":
            assert readiness.ready is True
        if engine.counts["lost"] > lost:  # a restarted executor: not the push's session
            assert readiness.session not in ("", session) and session != ""
        assert engine.steps <= node.params.max_steps

    run()
    assert probe.errors == 0


def parameter_values() -> st.SearchStrategy[tuple[str, Any]]:
    names = [s.name for s in PARAMETERS]
    values = st.one_of(st.sampled_from(SPECIAL), st.integers(-5, 2000),
                       st.sampled_from(["ana", "geo", "rdn", "best", "", "resume", "report",
                                        "  ana  ", "/etc/passwd"]),
                       st.booleans(), st.floats(-1.0, 1.0))
    return st.tuples(st.sampled_from(names), values)


def test_fuzz_parameter_sets(probe: Probe) -> None:
    node = probe.node
    defaults = [Parameter(s.name, value=node.get_parameter(s.name).value) for s in PARAMETERS
                if not s.read_only]

    @settings(FUZZ, max_examples=N_PARAMS)
    @given(st.lists(parameter_values(), min_size=1, max_size=4))
    def run(changes: list[tuple[str, Any]]) -> None:
        for name, value in changes:
            if name == "method" and value == "lrn":
                continue  # would load the CNN (tested elsewhere)
            node.set_parameters([Parameter(name, value=value)])  # refused or taken, no raise
        response = probe.reset()
        assert probe.errors == 0
        if response.success:
            assert node.params.planner.method in ("ana", "geo", "rdn")

    run()
    assert all(r.successful for r in node.set_parameters(defaults))
    assert probe.reset().success


def executed(t_end: float) -> Path:
    msg = Path()
    msg.header.frame_id = "world"
    msg.header.stamp = stamp_from_seconds(t_end)
    pose = PoseStamped()
    pose.header.frame_id, pose.header.stamp = "world", msg.header.stamp
    msg.poses.append(pose)
    return msg


def test_after_fuzzing_the_node_plans_a_correct_push(probe: Probe) -> None:
    """Runs after the fuzz tests of this module (file order): the same node still works."""
    node = probe.node
    assert probe.reset().success and probe.errors == 0
    probe.pushes.clear()
    probe.send("perception/outline", valid_cloud())
    probe.send("goal_pose", valid_goal(0.1), None)
    send_valid_estimate(probe, (0.0, 0.0, 0.0), 5000.0)
    assert len(probe.pushes) == 1 and node._engine.phase == "pushing"
    pts = np.array([[p.pose.position.x, p.pose.position.y] for p in probe.pushes[0].poses])
    assert pts.shape == (3, 2) and np.all(np.isfinite(pts))
    assert (pts[2] - pts[1])[0] > 0.0  # towards the goal in +x
    assert 0.0099 <= np.linalg.norm(pts[2] - pts[1]) <= 0.0501
    probe.send("pusher/executed", executed(5001.0))
    send_valid_estimate(probe, (0.1, 0.0, 0.0), 5002.0)
    assert node._engine.phase == "reached" and probe.errors == 0


# ---- over DDS ---------------------------------------------------------------------------------
def test_fuzz_over_dds_the_node_stays_alive_and_answers_reset(
        ros_context: Any, wait_for: Callable[..., bool]) -> None:
    node = PlannerNode(context=ros_context)
    client = Node("planner_fuzz_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(client)
    status: list[DiagnosticStatus] = []
    client.create_subscription(DiagnosticStatus, "planner/status", status.append, LATCHED_QOS)
    pubs = {
        "goal_pose": client.create_publisher(PoseStamped, "goal_pose", RELIABLE_QOS),
        "perception/outline": client.create_publisher(PointCloud2, "perception/outline",
                                                      LATCHED_QOS),
        "estimator/state": client.create_publisher(Float64MultiArray, "estimator/state",
                                                   LATCHED_QOS),
        "estimator/object_pose": client.create_publisher(
            PoseWithCovarianceStamped, "estimator/object_pose", LATCHED_QOS),
        "pusher/executed": client.create_publisher(Path, "pusher/executed", RELIABLE_QOS),
        "pusher/refused": client.create_publisher(DiagnosticStatus, "pusher/refused",
                                                  RELIABLE_QOS),
    }
    reset = client.create_client(Trigger, "planner_node/reset")
    try:
        assert wait_for(lambda: all(p.get_subscription_count() > 0 for p in pubs.values())
                        and bool(status), timeout=20.0, executor=executor)
        sent = []

        @settings(FUZZ, max_examples=N_DDS)
        @given(goals(), clouds(), estimates(), paths(), refusals())
        def run(goal: tuple[PoseStamped, Any], cloud: PointCloud2, est: list[Any],
                path: Path, refusal: tuple[DiagnosticStatus, bool]) -> None:
            pubs["goal_pose"].publish(goal[0])
            pubs["perception/outline"].publish(cloud)
            for msg in est:
                pubs["estimator/state" if isinstance(msg, Float64MultiArray)
                     else "estimator/object_pose"].publish(msg)
            pubs["pusher/executed"].publish(path)
            pubs["pusher/refused"].publish(refusal[0])
            sent.append(1)
            executor.spin_once(timeout_sec=0.0)

        run()
        assert len(sent) == N_DDS

        def refused() -> int:
            return int({kv.key: kv.value for kv in status[-1].values}.get("refused", 0))

        assert wait_for(lambda: refused() >= N_DDS // 2, timeout=30.0, executor=executor)
        assert reset.wait_for_service(timeout_sec=10.0)
        future = reset.call_async(Trigger.Request())
        assert wait_for(future.done, timeout=30.0, executor=executor)
        assert future.result().success
        assert wait_for(lambda: "waiting" in status[-1].message, timeout=10.0,
                        executor=executor)
        values = {kv.key: kv.value for kv in status[-1].values}
        assert values["callback_errors"] == "0", values["last_error"]
    finally:
        executor.shutdown()
        client.destroy_node()
        node.destroy_node()
