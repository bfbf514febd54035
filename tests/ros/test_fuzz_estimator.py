"""Fuzz tests of ekf_node: hostile messages on every subscribed topic and hostile parameter sets.

In-process against the real node class: the tests call the guarded callables the node
subscribed (``node.subscriptions``, ``node.services``) directly with real message objects built
by hypothesis strategies, no DDS. At least 2,000 messages per topic:

- ``perception/object_pose``: NaN / inf / 1e300 positions, unnormalised, zero, non-planar and
  NaN quaternions, absurd covariances (negative, NaN, 1e-320, 1e300, asymmetric), extreme
  stamps (negative ``sec``, ``nanosec >= 1e9``, ``2147483647 s 999999999 ns``, far future),
  wrong frames;
- ``pusher/executed``: 0-40 poses, NaN / inf, 10^9 m pushes, extreme and reversed stamps, wrong
  frames (a 10,000-pose path as an explicit example);
- ``perception/outline``: wrong / missing fields, datatypes, counts, offsets, ``point_step``,
  ``row_step`` and data sizes, big-endian, NaN, 1e30 coordinates, clockwise and random point
  sets, point counts up to 5,000 (a valid 100,000-point circle and a 3,000-point one as explicit
  examples);
- parameter sets: every declared parameter, in and out of range and of the wrong type.

Afterwards: no exception reached the guard (``callback_errors`` stays 0: every rejection was a
checked one, counted under its kind); a rejected message changed nothing (filter state, history,
counters other than its own); the work was bounded (a push longer than ``max_push_length`` never
reaches the process model: the model calls are counted; every push took at most ``max_substeps``
substeps; an outline above ``MAX_OUTLINE_CLOUD_POINTS`` is refused and one above
``OUTLINE_WORKING_POINTS`` decimated); and the node still estimates correctly (outline +
observation + push + observation moves the estimate as ``tests/estimator/test_ekf_node.py``
expects). No timing assertion anywhere.

A smaller over-DDS run publishes 100 hostile messages per topic on the real topics and checks
that the node is alive and answers ``~/reset``.

Reproducible: hypothesis runs derandomized (fixed seed), no deadline, no example database.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

rclpy = pytest.importorskip("rclpy")
hypothesis = pytest.importorskip("hypothesis")

from builtin_interfaces.msg import Time  # noqa: E402
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped  # noqa: E402
from hypothesis import HealthCheck, example, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from nav_msgs.msg import Path  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import PointCloud2, PointField  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

import push_core.estimator.ekf as ekf_module  # noqa: E402
from push_core.estimator import EKFConfig, PushEKF, predict_push  # noqa: E402
from push_estimator import ekf_node as node_module  # noqa: E402
from push_estimator.ekf_node import PARAMETERS, EkfNode  # noqa: E402
from push_estimator.inputs import MAX_OUTLINE_CLOUD_POINTS  # noqa: E402
from push_ros.outline import outline_cloud_msg  # noqa: E402
from push_ros.poses import pose_with_covariance_msg  # noqa: E402
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS  # noqa: E402
from push_ros.stamps import stamp_from_seconds  # noqa: E402

#: Messages per topic of the in-process run (at least 2,000: rare malformations get hit).
N_FUZZ = 2000
FUZZ = settings(max_examples=N_FUZZ, deadline=None, derandomize=True, database=None,
                suppress_health_check=list(HealthCheck))
#: Parameter sets (each one builds a filter on the current outline to check it).
N_PARAMETERS = 300

HALF = 0.03
_CORNERS = np.array([[HALF, -HALF], [HALF, HALF], [-HALF, HALF], [-HALF, -HALF]])
#: The 6 cm square of tests/estimator/test_ekf_node.py: 10 points per side, CCW.
SQUARE = np.concatenate([a + np.arange(10)[:, None] / 10 * (b - a)
                         for a, b in zip(_CORNERS, np.roll(_CORNERS, -1, 0), strict=True)])
SQUARE_NORMALS = np.repeat([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]], 10, axis=0)

INT32 = (-(2**31), 2**31 - 1)
UINT32 = (0, 2**32 - 1)
SPECIAL = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1e300, -1e300, 1e9, -1e9, 1e-320, 1.0,
           -1.0, 0.05, 100.0, 100.0001]
FRAMES = ["world", "object", "", "map", "World", "world ", "x" * 200]


# ---- strategies ------------------------------------------------------------------------------
def floats() -> st.SearchStrategy[float]:
    return st.one_of(st.sampled_from(SPECIAL), st.floats(-0.2, 0.2), st.floats(allow_nan=True,
                                                                                allow_infinity=True))


def stamps(past: float = 5.0) -> st.SearchStrategy[Time]:
    """Extreme stamps and plausible ones (a few seconds around ``past``)."""
    plausible = st.floats(0.0, 2 * past).map(stamp_from_seconds)
    extreme = st.builds(Time, sec=st.integers(*INT32), nanosec=st.integers(*UINT32))
    special = st.sampled_from([Time(sec=2147483647, nanosec=999_999_999),
                               Time(sec=2147483646, nanosec=0), Time(sec=-1, nanosec=0),
                               Time(sec=0, nanosec=1_000_000_000), Time(sec=0, nanosec=0),
                               Time(sec=2147483647, nanosec=999_999_000)])
    return st.one_of(plausible, extreme, special)


# Built once: hypothesis pays for every strategy object it validates.
FLOATS = floats()
STAMPS = stamps()
WORLD_FRAMES = st.sampled_from(FRAMES[:1] * 6 + FRAMES)
POSE_FRAMES = st.sampled_from(["", "", "world", "map"])
BOOLS = st.booleans()
SEEDS = st.integers(0, 2**16)


@st.composite
def observations(draw: Callable) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = draw(WORLD_FRAMES)
    msg.header.stamp = draw(STAMPS)
    p = msg.pose.pose.position
    p.x, p.y, p.z = draw(FLOATS), draw(FLOATS), draw(st.sampled_from([0.0, 0.0, 1.0, math.nan]))
    kind = draw(st.sampled_from(["yaw", "yaw", "scaled", "zero", "tilted", "random"]))
    yaw = draw(st.floats(-10.0, 10.0))
    q = [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]
    if kind == "scaled":
        q = [v * draw(st.sampled_from([0.5, 1.0005, 1.01, 2.0, 1e300, math.nan])) for v in q]
    elif kind == "zero":
        q = [0.0, 0.0, 0.0, 0.0]
    elif kind == "tilted":
        q = [0.3, 0.0, q[2] * 0.9, q[3] * 0.9]
    elif kind == "random":
        q = [draw(FLOATS) for _ in range(4)]
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = q
    ckind = draw(st.sampled_from(["zero", "diag", "diag", "random", "asymmetric"]))
    cov = np.zeros((6, 6))
    if ckind == "diag":
        for i in (0, 1, 5):
            cov[i, i] = draw(st.sampled_from([1e-6, 1e-4, 1e6, 0.0, -1.0, 1e-320, 1e300,
                                              math.nan, math.inf]))
    elif ckind in ("random", "asymmetric"):
        block = np.array([[draw(FLOATS) for _ in range(3)] for _ in range(3)])
        if ckind == "random":
            with np.errstate(all="ignore"):
                block = block @ block.T if np.all(np.isfinite(block)) else block
        cov[np.ix_((0, 1, 5), (0, 1, 5))] = block
    with np.errstate(all="ignore"):
        msg.pose.covariance = [float(v) for v in cov.ravel()]
    return msg


@st.composite
def paths(draw: Callable) -> Path:
    msg = Path()
    msg.header.frame_id = draw(WORLD_FRAMES)
    msg.header.stamp = draw(STAMPS)
    n = draw(st.sampled_from([2] * 8 + [0, 1, 3, 12]))
    length = draw(st.sampled_from([0.0, 0.02, 0.5, 1.0, 1.0001, 5.0, 1e4, 1e9, math.inf,
                                   math.nan]))
    x0, y0 = draw(FLOATS), draw(FLOATS)
    angle = draw(st.floats(-4.0, 4.0))
    reversed_stamps = draw(BOOLS)
    t0 = draw(STAMPS)
    for i in range(n):
        pose = PoseStamped()
        pose.header.frame_id = draw(POSE_FRAMES)
        if draw(BOOLS):  # structured: a straight push
            frac = i / max(n - 1, 1)
            with np.errstate(all="ignore"):
                pose.pose.position.x = float(x0 + frac * length * math.cos(angle))
                pose.pose.position.y = float(y0 + frac * length * math.sin(angle))
            sec = t0.sec + (-i if reversed_stamps else i)
            pose.header.stamp = Time(sec=min(max(sec, 0), 2**31 - 1), nanosec=t0.nanosec)
        else:
            pose.pose.position.x, pose.pose.position.y = draw(FLOATS), draw(FLOATS)
            pose.header.stamp = draw(STAMPS)
        msg.poses.append(pose)
    return msg


def _circle(n: int, radius: float = 0.04) -> tuple[np.ndarray, np.ndarray]:
    a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    normals = np.stack([np.cos(a), np.sin(a)], axis=1)
    return radius * normals, normals


@st.composite
def clouds(draw: Callable) -> PointCloud2:
    kind = draw(st.sampled_from(["valid", "garbage", "layout", "layout", "count"]))
    frame = draw(st.sampled_from(["object"] * 6 + FRAMES))
    if kind == "valid":  # a noisy circle: sometimes an outline the filter takes
        n = draw(st.integers(0, 24))
        pts, normals = _circle(max(n, 1), draw(st.sampled_from([0.04, 1e-9, 0.5, 99.0, 1e30])))
        noise = draw(st.sampled_from([0.0, 1e-4, 0.02]))
        rng = np.random.default_rng(draw(SEEDS))
        pts = pts[:n] + noise * rng.standard_normal((n, 2))
        normals = normals[:n]
        if draw(BOOLS):
            pts, normals = pts[::-1], normals[::-1]  # clockwise
        if n and draw(st.integers(0, 9)) == 0:
            pts[draw(st.integers(0, n - 1)), 0] = draw(st.sampled_from([math.nan, math.inf]))
        with np.errstate(all="ignore"):
            data = np.zeros((n, 6), dtype="<f4")
            data[:, 0:2], data[:, 3:5] = pts, normals
        msg = outline_cloud_msg(np.zeros((0, 2)), np.zeros((0, 2)), frame_id=frame)
        msg.width, msg.height, msg.row_step = n, 1, 24 * n
        msg.data = array("B", data.tobytes())
        return msg
    msg = outline_cloud_msg(np.zeros((0, 2)), np.zeros((0, 2)), frame_id=frame)
    names = ["x", "y", "z", "normal_x", "normal_y", "normal_z"]
    if kind == "layout":
        names = draw(st.lists(st.sampled_from(names + ["rgb", ""]), min_size=0, max_size=8))
    msg.fields = [PointField(name=name,
                             offset=draw(st.sampled_from([4 * i] * 4 + [0, 2, 1000, 2**32 - 1])),
                             datatype=draw(st.sampled_from([PointField.FLOAT32] * 6 + [0, 1, 8,
                                                                                       255])),
                             count=draw(st.sampled_from([1] * 6 + [0, 3])))
                  for i, name in enumerate(names)]
    msg.point_step = draw(st.sampled_from([24] * 4 + [0, 4, 23, 25, 4096, 2**32 - 1]))
    n = draw(st.sampled_from([3, 40, 1001, 4000, 4001, 5000]) if kind == "count"
             else st.integers(0, 64))
    msg.width = n
    msg.height = draw(st.sampled_from([1] * 6 + [0, 2, 2**32 - 1]))
    msg.row_step = draw(st.sampled_from([msg.point_step * n] * 4 + [0, msg.point_step * n + 8,
                                                                   2**32 - 1]))
    msg.is_bigendian = draw(BOOLS)
    size = min(msg.row_step * min(msg.height, 2), 200_000)
    size = draw(st.sampled_from([size, size, 0, max(size - 1, 0), size + 1]))
    seed = draw(SEEDS)
    msg.data = array("B", np.random.default_rng(seed).integers(0, 256, size, dtype=np.uint8)
                     .tobytes())
    return msg


def parameter_sets() -> st.SearchStrategy[list[Parameter]]:
    def values(spec: Any) -> st.SearchStrategy[Any]:
        wrong = st.sampled_from(["text", True, [1.0, 2.0]])
        if isinstance(spec.default, bool):
            return st.one_of(st.booleans(), wrong)
        if isinstance(spec.default, str):
            return st.one_of(st.sampled_from(["world", "", "map"]), wrong)
        if isinstance(spec.default, int):
            low, high = spec.bounds
            return st.one_of(st.integers(int(low) - 2, int(high) + 2), wrong, st.just(1.5))
        low, high = spec.bounds
        return st.one_of(st.floats(low, high), st.sampled_from([low, high, -1.0, 1e300,
                                                                math.nan, math.inf]),
                         st.floats(low - 1.0, high * 2 + 1.0), wrong)

    one = st.sampled_from(PARAMETERS).flatmap(
        lambda spec: values(spec).map(lambda v, name=spec.name: Parameter(name, value=v)))
    return st.lists(one, min_size=1, max_size=3)


# ---- the node under test --------------------------------------------------------------------
class Harness:
    """The real node, its guarded callbacks by topic, recorded publications and model calls."""

    def __init__(self, context: Any) -> None:
        self.node = EkfNode(context=context,
                            parameter_overrides=[Parameter("use_sim_time", value=False)])
        self.callbacks = {s.topic_name: s.callback for s in self.node.subscriptions}
        self.reset_callback = next(s.callback for s in self.node.services
                                   if s.srv_name.endswith("/reset"))
        self.published: list[Any] = []
        self.node._pub_pose.publish = self.published.append
        self.model_calls: list[int] = []  # n_substeps of every process-model call

    def outline(self, points: np.ndarray = SQUARE, normals: np.ndarray = SQUARE_NORMALS) -> None:
        self.callbacks["/perception/outline"](outline_cloud_msg(points, normals))

    def observe(self, pose: Any, stamp: float) -> None:
        self.callbacks["/perception/object_pose"](pose_with_covariance_msg(
            pose, np.zeros((3, 3)), stamp_from_seconds(stamp)))

    def push(self, start: Any, end: Any, t_start: float, t_end: float) -> None:
        msg = Path()
        msg.header.frame_id = "world"
        msg.header.stamp = stamp_from_seconds(t_end)
        for point, t in ((start, t_start), (end, t_end)):
            pose = PoseStamped()
            pose.header.stamp = stamp_from_seconds(t)
            pose.pose.position.x, pose.pose.position.y = (float(v) for v in point)
            msg.poses.append(pose)
        self.callbacks["/pusher/executed"](msg)

    def reset(self) -> Trigger.Response:
        return self.reset_callback(Trigger.Request(), Trigger.Response())

    def state(self) -> tuple:
        ekf = self.node._ekf
        if ekf is None:
            return (None,)
        x, p, initialized, *_ = ekf.snapshot()
        return (id(ekf), x.tobytes(), p.tobytes(), initialized,
                tuple((e.key, e.push) for e in self.node._replay.entries))

    def check_valid_episode(self) -> None:
        """The test of test_ekf_node.py: outline, observation, push, observation."""
        self.outline()
        assert self.reset().success
        # ~/reset drops observations stamped at or before the newest one it saw (perception's
        # frames of the last episode), which a fuzz may have stamped later than 1 s: the
        # episode starts after that boundary.
        boundary = self.node._inputs.boundary
        t0 = boundary if math.isfinite(boundary) else 0.0
        n_before = len(self.published)
        self.observe((0.0, 0.0, 0.0), t0 + 1.0)
        start = np.array([-HALF - 0.0048 - 0.005, 0.01])
        end = start + [0.03, 0.0]
        truth = np.array([0.0, 0.0, 0.0, 0.004, -0.006, 0.03, 0.3])
        reference = PushEKF(SQUARE.astype(np.float32), SQUARE_NORMALS.astype(np.float32))
        observed = predict_push(truth, reference.outline, start, end).state[:3]
        pushes = self.node.health.counts["pushes"]
        self.push(start, end, t0 + 2.0, t0 + 3.25)
        assert self.node.health.counts["pushes"] == pushes + 1
        self.observe(observed, t0 + 4.0)
        assert len(self.published) == n_before + 2
        pose = self.published[-1].pose.pose.position
        assert pose.x > 0.015  # pushed forward
        np.testing.assert_allclose([pose.x, pose.y], observed[:2], atol=3e-3)
        # Bit-identical to the filter run directly.
        reference.update_pose([0.0, 0.0, 0.0])
        reference.predict_push(start, end)
        reference.update_pose(observed)
        np.testing.assert_array_equal(self.node._ekf.state, reference.state)
        assert self.node.health.counts["callback_errors"] == 0


@pytest.fixture
def harness(ros_context: Any, monkeypatch: pytest.MonkeyPatch) -> Iterator[Harness]:
    h = Harness(ros_context)
    real = ekf_module._predict_push

    def counted(*args: Any) -> Any:
        result = real(*args)
        h.model_calls.append(result.n_substeps)
        return result

    monkeypatch.setattr(ekf_module, "_predict_push", counted)
    try:
        yield h
    finally:
        h.node.destroy_node()


_OWN_COUNTERS = {"refused_nan", "refused_invalid", "refused_out_of_range", "refused_future",
                 "refused_duplicate", "refused_out_of_order", "refused_before_init",
                 "refused_before_outline", "refused_filter_error"}


def _assert_rejected_or_applied(h: Harness, before_state: tuple, before: dict[str, int],
                                applied: str) -> None:
    after = h.node.health.counts
    assert after["callback_errors"] == 0, h.node._problem
    changed = {k for k in after if after[k] != before[k]}
    if applied in changed:
        ekf = h.node._ekf
        assert np.all(np.isfinite(ekf.state)) and np.all(np.isfinite(ekf.covariance))
    else:  # refused: ``refused`` and exactly one refusal class moved, nothing else changed
        assert len(changed & _OWN_COUNTERS) == 1 and "refused" in changed, changed
        assert changed <= _OWN_COUNTERS | {"refused", "replaced_covariance"}, changed
        assert h.state() == before_state


# ---- in-process fuzzing ---------------------------------------------------------------------
def test_fuzz_observations(harness: Harness) -> None:
    h = harness
    h.outline()
    h.observe((0.0, 0.0, 0.0), 1.0)
    assert h.node._ekf.initialized

    @FUZZ
    @given(msg=observations(), reset=st.integers(0, 19))
    @example(msg=pose_with_covariance_msg((0.0, 0.0, 0.0), np.zeros((3, 3)),
                                          Time(sec=2147483646, nanosec=0)), reset=1)
    def run(msg: PoseWithCovarianceStamped, reset: int) -> None:
        if reset == 0:
            assert h.reset().success
        before_state, before = h.state(), h.node.health.counts
        h.callbacks["/perception/object_pose"](msg)
        _assert_rejected_or_applied(h, before_state, before, "observations")

    run()
    counts = h.node.health.counts
    assert counts["refused_future"] > 0 and counts["refused_nan"] > 0
    assert counts["refused_invalid"] > 0 and counts["observations"] > 0
    # The largest stamps: 2147483647 s 999999999 ns is refused when read, and a far-future
    # stamp (2147483646 s) is refused, so it cannot wedge the node.
    stamp = (h.published[-1].header.stamp.sec if h.published else 0)
    assert stamp < 2147483646
    h.check_valid_episode()


def test_fuzz_pushes(harness: Harness) -> None:
    h = harness
    h.outline()
    h.observe((0.0, 0.0, 0.0), 0.0)
    many = Path()
    many.header.frame_id = "world"
    many.poses = [PoseStamped() for _ in range(10_000)]
    limit = h.node.params.max_push_length

    @FUZZ
    @given(msg=paths(), reset=st.integers(0, 49))
    @example(msg=many, reset=1)
    def run(msg: Path, reset: int) -> None:
        if reset == 0:
            assert h.reset().success
            h.observe((0.0, 0.0, 0.0), 0.0)
        before_state, before = h.state(), h.node.health.counts
        calls = len(h.model_calls)
        h.callbacks["/pusher/executed"](msg)
        _assert_rejected_or_applied(h, before_state, before, "pushes")
        if len(msg.poses) == 2:
            a, b = (p.pose.position for p in msg.poses)
            with np.errstate(all="ignore"):
                length = math.hypot(b.x - a.x, b.y - a.y)
            if not length <= limit:  # also NaN: never reaches the process model
                assert len(h.model_calls) == calls
        assert all(n <= h.node.params.config.max_substeps for n in h.model_calls[calls:])

    run()
    counts = h.node.health.counts
    assert counts["refused_out_of_range"] > 0 and counts["pushes"] > 0
    assert counts["refused_invalid"] > 0 and counts["refused_nan"] > 0
    h.check_valid_episode()


def test_a_long_push_is_refused_before_any_model_step_and_the_loop_is_bounded(
        harness: Harness) -> None:
    h = harness
    h.outline()
    h.observe((0.0, 0.0, 0.0), 1.0)
    for length in (1e9, 1e4, 1.5):
        h.push((-0.05, 0.0), (-0.05 + length, 0.0), 2.0, 3.0)
    assert h.model_calls == [] and h.node.health.counts["refused_out_of_range"] == 3
    # A 1 m push with 0.1 mm substeps would take 10,000 model steps: bounded at max_substeps.
    h.node.set_parameters([Parameter("substep", value=1e-4),
                           Parameter("max_substeps", value=500)])
    assert h.reset().success
    h.observe((0.0, 0.0, 0.0), 1.5)  # (1.0 would repeat the previous episode's last frame)
    h.push((-0.5, 0.0), (0.5, 0.0), 2.0, 3.0)
    assert h.node.health.counts["pushes"] == 1 and h.model_calls == [500]
    # The default never binds: 1 m at 1 cm is 100 substeps.
    assert EKFConfig().max_substeps * EKFConfig().substep >= 10 * h.node.params.max_push_length


def test_fuzz_outlines(harness: Harness) -> None:
    h = harness
    big, big_normals = _circle(100_000)
    dense, dense_normals = _circle(3000)

    @FUZZ
    @given(msg=clouds())
    @example(msg=outline_cloud_msg(big, big_normals))
    @example(msg=outline_cloud_msg(dense, dense_normals))
    def run(msg: PointCloud2) -> None:
        before_state, before = h.state(), h.node.health.counts
        h.callbacks["/perception/outline"](msg)
        after = h.node.health.counts
        assert after["callback_errors"] == 0, h.node._problem
        if after["outlines"] == before["outlines"]:
            assert h.state() == before_state  # rejected or the same outline again
        else:
            assert len(h.node._outline) <= node_module.OUTLINE_WORKING_POINTS
            assert len(h.node._ekf.outline.vertices) <= node_module.OUTLINE_WORKING_POINTS
        if msg.width * msg.height > MAX_OUTLINE_CLOUD_POINTS:
            assert after["outlines"] == before["outlines"]

    run()
    counts = h.node.health.counts
    assert counts["refused_outline"] > N_FUZZ // 2
    # After the fuzz the node still takes valid outlines, each a new one (how many valid ones
    # the generator happened to draw depends on its derandomized seed, not on the node).
    for i in range(12):
        points, normals = _circle(200)
        msg = outline_cloud_msg(points * (0.5 + 0.05 * i), normals)
        h.callbacks["/perception/outline"](msg)
    assert h.node.health.counts["outlines"] == counts["outlines"] + 12
    assert h.node.health.counts["callback_errors"] == 0
    assert counts["decimated_outlines"] >= 1  # the 3,000-point circle
    h.check_valid_episode()


def test_fuzz_parameter_sets(harness: Harness) -> None:
    h = harness
    h.outline()
    defaults = [Parameter(s.name, value=s.default) for s in PARAMETERS if not s.read_only]

    @settings(max_examples=N_PARAMETERS, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(sets=parameter_sets(), reset=st.booleans())
    def run(sets: list[Parameter], reset: bool) -> None:
        try:
            results = h.node.set_parameters(sets)
        except Exception as exc:  # noqa: BLE001 - rclpy's own type checks raise for some
            assert type(exc).__module__.startswith("rclpy"), exc
            return
        assert len(results) == len(sets)
        if reset:
            assert h.reset().success, h.node._problem
            # Applied: the node's configuration is built from the current values.
            assert h.node._ekf.config == h.node.params.config
            assert h.node.params == node_module.EkfNodeParams.from_values(
                node_module.parameter_values(h.node, PARAMETERS))
        assert h.node.health.counts["callback_errors"] == 0

    run()
    # Back to the defaults in one atomic set: one at a time, a default can be refused against
    # the fuzzed values still set (initial.m = 0.3 outside a fuzzed [m_min, m_max]).
    result = h.node.set_parameters_atomically(defaults)
    assert result.successful, result.reason
    h.check_valid_episode()


def test_a_parameter_set_takes_effect_at_the_next_reset(harness: Harness) -> None:
    """gate_probability = 1.0 set, then ~/reset: no gate any more (it once still gated at 21.1)."""
    h = harness
    h.outline()
    h.observe((0.0, 0.0, 0.0), 1.0)
    [result] = h.node.set_parameters([Parameter("gate_probability", value=1.0)])
    assert result.successful
    assert h.node._ekf.config.gate_probability == pytest.approx(0.9999)  # until the reset
    response = h.reset()
    assert response.success and "gate_probability=1.0" in response.message
    assert h.node._ekf.config.gate_threshold == math.inf
    h.observe((0.0, 0.0, 0.0), 2.0)
    h.observe((0.12, 0.05, 1.0), 3.0)  # knocked: with gating off it is fused, not gated
    assert h.node.health.counts["gated"] == 0 and h.node.health.counts["observations"] == 3
    # Out of range, or an invalid combination: refused at set time with the reason.
    [bad] = h.node.set_parameters([Parameter("initial.m", value=1.5)])  # > limits.m_max
    assert not bad.successful and "m_init" in bad.reason
    assert h.reset().success and h.node._ekf.config.m_init == pytest.approx(0.3)


def test_stamps_cannot_wedge_the_node_and_reset_clears_them(harness: Harness) -> None:
    h = harness
    h.outline()
    h.observe((0.0, 0.0, 0.0), 1.0)
    msg = pose_with_covariance_msg((0.0, 0.0, 0.0), np.zeros((3, 3)),
                                   Time(sec=2147483646, nanosec=0))
    h.callbacks["/perception/object_pose"](msg)
    assert h.node.health.counts["refused_future"] == 1
    msg.header.stamp = Time(sec=2147483647, nanosec=999_999_999)
    h.callbacks["/perception/object_pose"](msg)
    assert h.node.health.counts["refused_invalid"] == 1
    h.observe((0.001, 0.0, 0.0), 3.0)  # still accepted: not wedged
    assert h.node.health.counts["observations"] == 2
    h.observe((0.001, 0.0, 0.0), 0.5)  # before the episode
    assert h.node.health.counts["refused_out_of_order"] == 1
    assert "before the episode" in h.node._problem
    assert h.reset().success
    h.observe((0.0, 0.0, 0.0), 0.5)  # a new episode may start earlier (a restarted clock)
    assert h.node.health.counts["observations"] == 3 and h.node._ekf.initialized


def sim_time_harness(ros_context: Any) -> Harness:
    """A harness around a node on simulated time (its /clock callback among the callbacks)."""
    node = EkfNode(context=ros_context,
                   parameter_overrides=[Parameter("use_sim_time", value=True)])
    h = Harness.__new__(Harness)
    h.node, h.published = node, []
    h.callbacks = {s.topic_name: s.callback for s in node.subscriptions}
    h.reset_callback = next(s.callback for s in node.services
                            if s.srv_name.endswith("/reset"))
    return h


def test_with_sim_time_before_the_first_clock_the_future_rule_waits_and_reset_recovers(
        ros_context: Any) -> None:
    """The documented case: use_sim_time and no /clock yet (the clock reads 0, not valid)."""
    h = sim_time_harness(ros_context)
    node = h.node
    try:
        h.outline()
        h.observe((0.0, 0.0, 0.0), 1.0)
        h.observe((0.0, 0.0, 0.0), 2147483646.0)  # cannot be judged yet: applied
        assert node.health.counts["observations"] == 2 and node.health.counts["refused_future"] == 0
        h.observe((0.0, 0.0, 0.0), 3.0)  # older than the last applied input
        assert node.health.counts["refused_out_of_order"] == 1
        assert h.reset().success  # clears every "last applied" time
        h.observe((0.0, 0.0, 0.0), 3.0)
        assert node.health.counts["observations"] == 3 and node._ekf.initialized
        assert node.health.counts["callback_errors"] == 0
    finally:
        node.destroy_node()


def test_the_stamp_rule_read_and_write() -> None:
    from push_ros.outline import decimate_outline
    from push_ros.stamps import MAX_STAMP_SECONDS, seconds_from_stamp

    last = Time(sec=2147483647, nanosec=999_999_000)  # 2^31 s - 1 us: still round-trips
    assert stamp_from_seconds(seconds_from_stamp(last)).sec == 2147483647
    for bad, match in ((Time(sec=2147483647, nanosec=999_999_999), "2\\^31"),
                       (Time(sec=-1, nanosec=0), "sec"),
                       (Time(sec=0, nanosec=1_000_000_000), "nanosec")):
        with pytest.raises(ValueError, match=match):
            seconds_from_stamp(bad)
    for bad in (math.nan, math.inf, -1.0, 2.0**31, MAX_STAMP_SECONDS + 5e-7):
        with pytest.raises(ValueError, match="time must be finite"):
            stamp_from_seconds(bad)
    assert stamp_from_seconds(2.0**31, clamp=True) == stamp_from_seconds(MAX_STAMP_SECONDS)
    assert stamp_from_seconds(-5.0, clamp=True) == Time(sec=0, nanosec=0)
    with pytest.raises(ValueError):
        stamp_from_seconds(math.nan, clamp=True)
    # The outline cap: every k-th point, unchanged at or below the bound.
    pts, normals = _circle(3000)
    small, small_normals = decimate_outline(pts, normals, 1000)
    assert len(small) == 1000 and np.array_equal(small, pts[::3])
    assert np.array_equal(small_normals, normals[::3])
    assert decimate_outline(pts[:1000], normals[:1000], 1000)[0] is not None


# ---- over DDS -------------------------------------------------------------------------------
N_DDS = 100


def _draw(strategy: st.SearchStrategy[Any], n: int) -> list[Any]:
    """``n`` examples of ``strategy``, reproducibly (derandomized)."""
    out: list[Any] = []

    @settings(max_examples=n, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(msg=strategy)
    def collect(msg: Any) -> None:
        out.append(msg)

    collect()
    return out[:n]


def test_over_dds_the_node_survives_and_answers_reset(ros_context: Any,
                                                      wait_for: Callable[..., bool]) -> None:
    node = EkfNode(context=ros_context,
                   parameter_overrides=[Parameter("use_sim_time", value=False)])
    tester = rclpy.create_node("ekf_fuzz_tester", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(tester)
    try:
        pubs = {
            "outline": tester.create_publisher(PointCloud2, "perception/outline", LATCHED_QOS),
            "pose": tester.create_publisher(PoseWithCovarianceStamped, "perception/object_pose",
                                            RELIABLE_QOS),
            "push": tester.create_publisher(Path, "pusher/executed", RELIABLE_QOS),
        }
        assert wait_for(lambda: all(p.get_subscription_count() > 0 for p in pubs.values()),
                        executor=executor)
        pubs["outline"].publish(outline_cloud_msg(SQUARE, SQUARE_NORMALS))
        assert wait_for(lambda: node.health.counts["outlines"] == 1, executor=executor)
        pubs["pose"].publish(pose_with_covariance_msg((0.0, 0.0, 0.0), np.zeros((3, 3)),
                                                      stamp_from_seconds(1.0)))
        assert wait_for(lambda: node.health.counts["observations"] == 1, executor=executor)
        received = lambda: sum(node.health.counts.values())  # noqa: E731
        for name, strategy in (("pose", observations()), ("push", paths()),
                               ("outline", clouds())):
            for msg in _draw(strategy, N_DDS):
                pubs[name].publish(msg)
                executor.spin_once(timeout_sec=0.01)
            total = received()
            wait_for(lambda t=total: received() > t, timeout=1.0, executor=executor)
        client = tester.create_client(Trigger, "/ekf_node/reset")
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(Trigger.Request())
        assert wait_for(future.done, executor=executor)
        assert future.result().success
        assert node.health.counts["callback_errors"] == 0
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        tester.destroy_node()


def test_a_restarted_clock_is_followed_and_the_filter_kept(ros_context: Any) -> None:
    """A restarted simulator's clock starts near 0: after the node's clock jumped back, its
    observations are taken at once (not refused until the new clock passes the old one) and
    the filter goes on from its state (the object did not move)."""
    from rosgraph_msgs.msg import Clock

    h = sim_time_harness(ros_context)
    node = h.node
    try:
        clock = h.callbacks["/clock"]
        clock(Clock(clock=stamp_from_seconds(40.0)))
        h.outline()
        h.observe((0.01, 0.0, 0.0), 39.0)
        h.observe((0.01, 0.0, 0.0), 39.5)
        state = node._ekf.state.copy()
        h.observe((0.01, 0.0, 0.0), 3.0)  # the new clock before the jump is seen: refused
        assert node.health.counts["refused_out_of_order"] == 1
        clock(Clock(clock=stamp_from_seconds(3.5)))  # the jump back
        h.observe((0.01, 0.0, 0.0), 3.5)
        assert node.health.counts["observations"] == 3
        assert node.health.counts["refused_out_of_order"] == 1 and node._ekf.initialized
        np.testing.assert_allclose(node._ekf.state[:3], state[:3], atol=2e-3)
        assert node.health.counts["callback_errors"] == 0
    finally:
        node.destroy_node()
