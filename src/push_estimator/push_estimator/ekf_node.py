"""``ekf_node``: EKF over the object pose, centre of mass, limit surface and friction.

A thin ROS wrapper around :class:`push_core.estimator.PushEKF` (the filter, its state, noise
model, Jacobian and gating are documented there). Message <-> array conversion lives in
:mod:`push_estimator.conversions`.

State ``x = (x, y, theta, c_x, c_y, l, m)``: object frame pose in ``world`` (m, rad; ``theta``
continuous, not wrapped, so a symmetric object's orientation stays continuous), COM in the
``object`` frame (m), limit-surface parameter ``l`` (m), pusher-object friction ``m``.

Subscriptions (relative names, remappable; QoS as in the README topic table):

- ``perception/outline`` (sensor_msgs/PointCloud2; latched = reliable + transient local,
  depth 1): fields ``x, y, z, normal_x, normal_y, normal_z`` (FLOAT32) in the ``object``
  frame, points counter-clockwise. Builds the filter (decimated outline, ``l_0``, symmetry).
  A different outline starts a new episode; the same one again is ignored.
- ``perception/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``;
  reliable): the first one after the outline (or a reset) initialises the filter, every later
  one is fused. Its x, y, yaw covariance is used when ``observation.use_message_covariance``
  is true and it is symmetric positive definite; otherwise ``observation.*_sigma``.
- ``pusher/executed`` (nav_msgs/Path, ``world``; reliable): the executed push, two poses
  (start, end) each with its stamp; drives the prediction.
- ``/clock`` (``use_sim_time`` is true by default: the pipeline runs on simulated time).

Inputs are applied in stamp order (an observation at its stamp, a push from its start to its
end stamp). DDS does not order messages across topics (a reliable sample repaired after a lost
packet arrives late), so the post-push observation can overtake its ``pusher/executed``: the
node keeps the last ``HISTORY`` applied inputs with filter snapshots, and a push that arrives
after inputs it precedes is inserted and the later observations re-applied (``replayed``;
the estimate is published again). Dropped, each with a log line (at most one per kind every
``LOG_THROTTLE_S``) and a counter on ``/diagnostics``: observations or pushes with NaN/inf
values (``dropped_nan``), malformed or wrong-frame messages (``dropped_invalid``), an
observation with the stamp of the previous one or a push seen before (``dropped_duplicate``;
the perception re-publishes while the scene is idle, not logged), an observation older than
the last applied input, or a push that cannot be placed (before the first observation,
overlapping an observation or another push, older than the history: ``dropped_out_of_order``),
a push before the filter is initialised (``dropped_before_init``), observations before any
outline (``dropped_before_outline``), a bad outline (``rejected_outlines``). An observation
that fails the Mahalanobis gate re-initialises the pose (``gated``, status WARN; re-filtering
updates the count).

Publications (after every applied observation, stamped with the observation's stamp):

- ``estimator/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``; reliable):
  x, y, yaw and their covariance (z, roll, pitch variance 0).
- ``estimator/center_of_mass`` (geometry_msgs/PointStamped, ``object``; reliable).
- ``estimator/state`` (std_msgs/Float64MultiArray; reliable): dim 0 label ``state`` size 7
  (``x,y,theta,c_x,c_y,l,m``), dim 1 label ``covariance_row_major`` size 49; data = the 7
  values then the 7 x 7 covariance (:func:`push_estimator.conversions.state_array_msg`).
- ``/tf`` world -> object (tf2_msgs/TFMessage; reliable): only where ``tf2_msgs`` is
  importable (full ROS install; see the tf note in ARCHITECTURE.md) and ``publish_tf``.
- ``/diagnostics`` (diagnostic_msgs/DiagnosticArray; reliable): one status, every
  ``diagnostics_period`` seconds of wall time and on every event.

Services: ``~/reset`` (std_srvs/srv/Trigger): start a new episode (the outline is kept; the
next observation initialises the filter). An observation with the stamp of the last one applied
before the reset is a repetition of the previous episode's frame (the perception re-publishes
while the scene is idle) and is dropped (``dropped_duplicate``), so it cannot initialise the new
episode (found driving the graph, issue 7).

Parameters: declared below with descriptions and ranges, read once at start-up into
:class:`EkfNodeParams` (frozen) and validated by building the filter's
:class:`~push_core.estimator.EKFConfig`; defaults, units and meaning in
``ros_ws/config/push_estimator.yaml``. A bad value fails start-up with a clear message (exit
status 2). Frames: ``world`` and ``object`` (parameters ``world_frame``, ``object_frame``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Path
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
)
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from push_core.estimator import STATE_LABELS, EKFConfig, PushEKF
from push_estimator.conversions import (
    NonFiniteError,
    center_of_mass_msg,
    observation_from_msg,
    outline_from_cloud,
    pose_with_covariance_msg,
    push_from_path,
    stamp_from_seconds,
    state_array_msg,
    transform_msg,
)

try:  # Only on a full ROS install: tf2_msgs has no PyPI wheel (ARCHITECTURE.md, tf note).
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the install
    TFMessage = None

__all__ = ["EkfNode", "EkfNodeParams", "main"]

NODE_NAME = "ekf_node"
RELIABLE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Seconds between repeated log lines of one kind (the counters count every event).
LOG_THROTTLE_S = 2.0
#: Tolerance (m) under which a re-published outline counts as the same outline.
SAME_OUTLINE_TOL = 1e-6

_DEFAULTS = EKFConfig()
#: (parameter name, EKFConfig field or None, default, description, (low, high) or None,
#: read_only). Node-only parameters have no EKFConfig field.
PARAMETERS: tuple[tuple[str, str | None, Any, str, tuple[float, float] | None, bool], ...] = (
    ("world_frame", None, "world", "Frame of observations, pushes and the estimated pose.",
     None, True),
    ("object_frame", None, "object", "Frame of the outline and the COM.", None, True),
    ("publish_tf", None, True, "Publish world -> object on /tf (only where tf2_msgs exists).",
     None, True),
    ("diagnostics_period", None, 1.0, "Period of the regular /diagnostics message, s (wall "
     "time).", (0.1, 60.0), True),
    ("observation.use_message_covariance", None, True, "Use the covariance of "
     "perception/object_pose when it is symmetric positive definite.", None, False),
    ("observation.position_sigma", "position_sigma", _DEFAULTS.position_sigma,
     "Observation noise of x and y (standard deviation), m.", (1e-5, 0.1), False),
    ("observation.angle_sigma", "angle_sigma", _DEFAULTS.angle_sigma,
     "Observation noise of theta (standard deviation), rad.", (1e-5, 1.0), False),
    ("symmetry_order", "symmetry_order", 0, "Rotational symmetry order of the object's "
     "outline: 1 = none, k = looks the same after 2 pi / k, 0 = detect from the outline.",
     (0, 64), False),
    ("symmetry_tolerance", "symmetry_tolerance", _DEFAULTS.symmetry_tolerance,
     "Largest outline mismatch of a symmetry when detecting it, m.", (1e-5, 0.02), False),
    ("pusher_radius", "pusher_radius", _DEFAULTS.pusher_radius, "Radius of the pusher, m.",
     (0.0, 0.05), False),
    ("substep", "substep", _DEFAULTS.substep, "Longest model step along a push, m.",
     (1e-4, 0.2), False),
    ("contact_tol", "contact_tol", _DEFAULTS.contact_tol, "Contact test tolerance, m.",
     (0.0, 0.01), False),
    ("outline_tolerance", "outline_tolerance", _DEFAULTS.outline_tolerance,
     "Douglas-Peucker tolerance of the contact outline, m.", (1e-5, 0.01), False),
    ("iterations", "iterations", _DEFAULTS.iterations, "Linearisations of a push per "
     "observation (1 = plain EKF, 2 = one re-linearisation).", (1, 10), False),
    ("initial.com_prior_fraction", "com_prior_fraction", _DEFAULTS.com_prior_fraction,
     "COM prior covariance = fraction^2 x the outline area's second moment (1 = anywhere in "
     "the object).", (1e-3, 10.0), False),
    ("initial.l_sigma_fraction", "l_sigma_fraction", _DEFAULTS.l_sigma_fraction,
     "Initial standard deviation of l as a fraction of l_0.", (1e-3, 10.0), False),
    ("initial.m", "m_init", _DEFAULTS.m_init, "Initial pusher-object friction coefficient.",
     (0.01, 5.0), False),
    ("initial.m_sigma", "m_sigma", _DEFAULTS.m_sigma, "Initial standard deviation of m.",
     (1e-4, 5.0), False),
    ("limits.l_min_fraction", "l_min_fraction", _DEFAULTS.l_min_fraction,
     "Lower clip of l as a fraction of l_0 (upper clip: outline radius).", (1e-3, 0.99),
     False),
    ("limits.m_min", None, _DEFAULTS.m_range[0], "Lower clip of m.", (1e-3, 5.0), False),
    ("limits.m_max", None, _DEFAULTS.m_range[1], "Upper clip of m.", (1e-3, 5.0), False),
    ("process_noise.position_min", "position_noise_min", _DEFAULTS.position_noise_min,
     "x, y process noise per push, constant part, m.", (0.0, 0.1), False),
    ("process_noise.position_per_metre", "position_noise_per_metre",
     _DEFAULTS.position_noise_per_metre, "x, y process noise per metre of pusher travel in "
     "contact, m/m.", (0.0, 10.0), False),
    ("process_noise.angle_min", "angle_noise_min", _DEFAULTS.angle_noise_min,
     "theta process noise per push, constant part, rad.", (0.0, 1.0), False),
    ("process_noise.angle_per_metre", "angle_noise_per_metre",
     _DEFAULTS.angle_noise_per_metre, "theta process noise per metre of pusher travel in "
     "contact, rad/m.", (0.0, 100.0), False),
    ("process_noise.com", "com_noise", _DEFAULTS.com_noise, "COM random walk per push "
     "(each axis), m.", (0.0, 0.1), False),
    ("process_noise.l", "l_noise", _DEFAULTS.l_noise, "l random walk per push, m.",
     (0.0, 0.1), False),
    ("process_noise.m", "m_noise", _DEFAULTS.m_noise, "m random walk per push.", (0.0, 1.0),
     False),
    ("gate_probability", "gate_probability", _DEFAULTS.gate_probability, "Chi-square "
     "probability (3 dof) of the innovation gate; 1 disables gating.", (1e-6, 1.0), False),
)


@dataclass(frozen=True)
class EkfNodeParams:
    """The node's parameters, typed and validated.

    Attributes
    ----------
    config : EKFConfig
        The filter's settings.
    world_frame, object_frame : str
    publish_tf : bool
    diagnostics_period : float
        s (wall time).
    use_message_covariance : bool
    """

    config: EKFConfig
    world_frame: str
    object_frame: str
    publish_tf: bool
    diagnostics_period: float
    use_message_covariance: bool

    @classmethod
    def from_values(cls, values: dict[str, Any]) -> EkfNodeParams:
        """Build from ``{parameter name: value}``.

        Raises
        ------
        ValueError
            Naming the parameter (through :class:`EKFConfig` validation where it is a filter
            setting).
        """
        kwargs = {field: values[name] for name, field, *_ in PARAMETERS if field is not None}
        kwargs["m_range"] = (values["limits.m_min"], values["limits.m_max"])
        try:
            config = EKFConfig(**kwargs)
        except ValueError as exc:
            names = {field: name for name, field, *_ in PARAMETERS if field is not None}
            names["m_range"] = "limits.m_min/limits.m_max"
            field = next((f.name for f in fields(EKFConfig) if str(exc).startswith(f.name)),
                         None)
            raise ValueError(f"parameter {names.get(field, field)!r}: {exc}") from None
        for name in ("world_frame", "object_frame"):
            if not str(values[name]).strip():
                raise ValueError(f"parameter {name!r} must not be empty")
        return cls(config=config, world_frame=str(values["world_frame"]),
                   object_frame=str(values["object_frame"]),
                   publish_tf=bool(values["publish_tf"]),
                   diagnostics_period=float(values["diagnostics_period"]),
                   use_message_covariance=bool(values["observation.use_message_covariance"]))


def _descriptor(description: str, bounds: tuple[float, float] | None, read_only: bool,
                integer: bool) -> ParameterDescriptor:
    desc = ParameterDescriptor(description=description, read_only=read_only)
    if bounds is not None and integer:
        desc.integer_range = [IntegerRange(from_value=int(bounds[0]), to_value=int(bounds[1]),
                                           step=1)]
    elif bounds is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=float(bounds[0]),
                                                        to_value=float(bounds[1]), step=0.0)]
    return desc


@dataclass
class _Applied:
    """An input the filter has applied, with the filter's state around it (for re-filtering).

    ``key``: stamp of an observation, end stamp of a push (s). ``data``: (pose, covariance or
    None) of an observation, (start, end) of a push. ``push``: (t_start, t_end) of a push,
    None for an observation. ``before`` / ``after``: filter snapshots. ``gated``: the
    observation re-initialised the pose.
    """

    key: float
    data: tuple
    before: tuple
    push: tuple[float, float] | None = None
    after: tuple = ()
    gated: bool = False


def push_key(push: Any) -> tuple[float, float]:
    """(t_start, t_end) of an executed push: its identity for duplicate detection."""
    return (push.t_start, push.t_end)


#: Applied inputs kept for re-filtering a push that arrives after later inputs.
HISTORY = 32

_COUNTERS = ("observations", "pushes", "replayed", "gated", "resets", "outlines",
             "rejected_outlines",
             "dropped_nan", "dropped_invalid", "dropped_duplicate", "dropped_out_of_order",
             "dropped_before_init", "dropped_before_outline")


class EkfNode(Node):
    """ROS wrapper of :class:`push_core.estimator.PushEKF`; see the module docstring.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        At construction, if a parameter is invalid.
    """

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        # use_sim_time defaults to true here (the pipeline runs on /clock); an explicit value
        # (command line, parameter file, constructor override) wins. rclpy declares the
        # parameter itself, so "was it given" can only be read from its override table.
        if "use_sim_time" not in getattr(self, "_parameter_overrides", {}):
            self.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])
        for name, _, default, description, bounds, read_only in PARAMETERS:
            integer = isinstance(default, int) and not isinstance(default, bool)
            self.declare_parameter(name, default,
                                   _descriptor(description, bounds, read_only, integer))
        self.params = EkfNodeParams.from_values(
            {name: self.get_parameter(name).value for name, *_ in PARAMETERS})

        self._ekf: PushEKF | None = None
        self._outline: np.ndarray | None = None
        self._counts = dict.fromkeys(_COUNTERS, 0)
        self._history: list[_Applied] = []  # the last HISTORY applied inputs, in stamp order
        self._last_observation = -math.inf
        self._previous_episode = math.nan  # stamp of the last observation before ~/reset
        self._last_nis = math.nan
        self._problem = ""  # the most recent problem, "" after a good input
        self._logged: dict[str, tuple[float, int]] = {}  # kind -> (last log time, suppressed)

        self._pub_pose = self.create_publisher(PoseWithCovarianceStamped,
                                               "estimator/object_pose", RELIABLE)
        self._pub_com = self.create_publisher(PointStamped, "estimator/center_of_mass",
                                              RELIABLE)
        self._pub_state = self.create_publisher(Float64MultiArray, "estimator/state", RELIABLE)
        self._pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", RELIABLE)
        self._pub_tf = None
        if TFMessage is not None and self.params.publish_tf:
            self._pub_tf = self.create_publisher(TFMessage, "/tf", RELIABLE)
        self.create_subscription(PointCloud2, "perception/outline", self._on_outline, LATCHED)
        self.create_subscription(PoseWithCovarianceStamped, "perception/object_pose",
                                 self._on_observation, RELIABLE)
        self.create_subscription(Path, "pusher/executed", self._on_push, RELIABLE)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.create_timer(self.params.diagnostics_period, self._publish_diagnostics,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"ekf_node ready (use_sim_time={self.get_parameter('use_sim_time').value}, "
            f"iterations={self.params.config.iterations}); waiting for perception/outline")

    # ---- state ---------------------------------------------------------------------------
    @property
    def filter(self) -> PushEKF | None:
        """The current filter (None before the first outline)."""
        return self._ekf

    def _status(self) -> str:
        if self._ekf is None:
            return "waiting for outline"
        return "tracking" if self._ekf.initialized else "waiting for first observation"

    def _drop(self, counter: str, text: str, error: bool = False) -> None:
        """Count a dropped input, remember it for /diagnostics and log it (at most once per
        ``LOG_THROTTLE_S`` per kind; the count says how many were not logged)."""
        self._counts[counter] += 1
        self._problem = text
        now = time.monotonic()
        last, suppressed = self._logged.get(counter, (-math.inf, 0))
        if now - last >= LOG_THROTTLE_S:
            if suppressed:
                text += f" ({suppressed} more of this kind since the last message)"
            if error:
                self.get_logger().error(text)
            else:
                self.get_logger().warning(text)
            self._logged[counter] = (now, 0)
        else:
            self._logged[counter] = (last, suppressed + 1)
        self._publish_diagnostics()

    def _parse(self, parse: Callable[[Any, str], Any], msg: Any, topic: str) -> Any:
        """``parse(msg, world_frame)``, or None after counting and logging a bad message."""
        try:
            return parse(msg, self.params.world_frame)
        except NonFiniteError as exc:
            self._drop("dropped_nan", f"dropped {topic}: {exc}")
        except ValueError as exc:
            self._drop("dropped_invalid", f"dropped {topic}: {exc}")
        return None

    def _new_episode(self) -> None:
        self._history.clear()
        self._last_observation = -math.inf

    # ---- callbacks -----------------------------------------------------------------------
    def _on_outline(self, msg: PointCloud2) -> None:
        try:
            points, normals = outline_from_cloud(msg, self.params.object_frame)
            if (self._outline is not None and self._outline.shape == points.shape
                    and np.allclose(self._outline, points, rtol=0.0, atol=SAME_OUTLINE_TOL)):
                return  # the same latched outline again
            ekf = PushEKF(points, normals, self.params.config)
        except ValueError as exc:
            self._drop("rejected_outlines", f"rejected perception/outline: {exc}", error=True)
            return
        replaced = self._ekf is not None
        self._ekf, self._outline = ekf, points
        self._new_episode()
        self._counts["outlines"] += 1
        self._problem = ""
        o = ekf.outline
        self.get_logger().info(
            f"{'new ' if replaced else ''}outline: {len(points)} points -> {len(o.vertices)} "
            f"contact vertices, l_0 = {1e3 * o.limit_surface:.1f} mm, symmetry order "
            f"{o.symmetry_order}{'; new episode' if replaced else ''}")
        self._publish_diagnostics()

    def _on_observation(self, msg: PoseWithCovarianceStamped) -> None:
        if self._ekf is None:
            self._drop("dropped_before_outline", "dropped perception/object_pose: no outline "
                       "yet (waiting for perception/outline)")
            return
        obs = self._parse(observation_from_msg, msg, "perception/object_pose")
        if obs is None:
            return
        if obs.stamp in (self._last_observation, self._previous_episode):
            self._counts["dropped_duplicate"] += 1  # normal while the scene is idle: no log
            return
        last = self._history[-1].key if self._history else -math.inf
        if obs.stamp < last:
            self._drop("dropped_out_of_order", f"dropped perception/object_pose stamped "
                       f"{obs.stamp:.6f} s: older than the last applied input ({last:.6f} s)")
            return
        cov = obs.covariance if self.params.use_message_covariance else None
        entry = _Applied(obs.stamp, (obs.pose, cov), self._ekf.snapshot())
        result = self._apply(entry)
        self._record(entry)
        self._counts["observations"] += 1
        if result.reinitialized:
            self._problem = (f"observation at {obs.stamp:.3f} s failed the gate (NIS "
                             f"{result.nis:.1f} > {self._ekf.config.gate_threshold:.1f}): pose "
                             "re-initialised, c, l, m kept")
            self.get_logger().warning(self._problem)
        else:
            self._problem = ""
            if result.initialized:
                self.get_logger().info(f"initialised from the observation at {obs.stamp:.3f} s")
        self._publish_estimate(obs.stamp)
        self._publish_diagnostics()

    def _on_push(self, msg: Path) -> None:
        if self._ekf is None or not self._ekf.initialized:
            self._drop("dropped_before_init", "dropped pusher/executed: the filter is not "
                       "initialised yet (needs the outline and a first observation)")
            return
        push = self._parse(push_from_path, msg, "pusher/executed")
        if push is None:
            return
        if any(e.push == push_key(push) for e in self._history):
            self._counts["dropped_duplicate"] += 1
            return
        # Inputs after which this push belongs: every applied input up to its start.
        i = len(self._history)
        while i > 0 and self._history[i - 1].key > push.t_start:
            i -= 1
        later = self._history[i:]
        if later and (i == 0 or any(e.push is not None or e.key < push.t_end for e in later)):
            self._drop("dropped_out_of_order", f"dropped pusher/executed {push.t_start:.6f} -> "
                       f"{push.t_end:.6f} s: it cannot be placed among the applied inputs "
                       "(before the first observation, overlapping an observation or another "
                       "push, or older than the kept history)")
            return
        before = later[0].before if later else self._ekf.snapshot()
        entry = _Applied(push.t_end, (push.start, push.end), before, push=push_key(push))
        try:
            self._ekf.restore(before)
            pred = self._apply(entry)
        except ValueError as exc:
            self._ekf.restore(self._history[-1].after if later else before)
            self._drop("dropped_invalid", f"dropped pusher/executed: {exc}")
            return
        self._counts["pushes"] += 1
        self._problem = ""
        contact = (f"contact over {1e3 * pred.contact_length:.1f} mm" if pred.touched
                   else "no contact")
        self.get_logger().info(f"push {push.t_start:.3f} -> {push.t_end:.3f} s: {contact}, "
                               f"{pred.n_substeps} substeps"
                               + (f"; arrived after {len(later)} later input(s), re-filtered"
                                  if later else ""))
        self._history.insert(i, entry)
        if later:  # the push arrived after inputs it precedes: re-apply them after it
            self._counts["replayed"] += 1
            for e in later:
                e.before = self._ekf.snapshot()
                was_gated = e.gated
                self._apply(e)
                self._counts["gated"] += int(e.gated) - int(was_gated)
            if any(e.gated for e in later):
                self._problem = ("after re-filtering a late pusher/executed, an observation "
                                 "still fails the gate")
            self._publish_estimate(self._last_observation)
        self._trim_history()
        self._publish_diagnostics()

    def _apply(self, entry: _Applied) -> Any:
        """Apply one input to the filter; record its outcome in ``entry``."""
        if entry.push is not None:
            start, end = entry.data
            result = self._ekf.predict_push(start, end)
        else:
            pose, cov = entry.data
            result = self._ekf.update_pose(pose, cov)
            entry.gated = result.reinitialized
            self._last_nis = result.nis
            self._last_observation = entry.key
        entry.after = self._ekf.snapshot()
        return result

    def _record(self, entry: _Applied) -> None:
        self._counts["gated"] += int(entry.gated)
        self._history.append(entry)
        self._trim_history()

    def _trim_history(self) -> None:
        del self._history[:-HISTORY]

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        self._counts["resets"] += 1
        self._previous_episode = self._last_observation
        self._new_episode()
        self._problem = ""
        if self._ekf is not None:
            self._ekf.reset()
            response.message = "new episode: waiting for the first observation"
        else:
            response.message = "new episode: waiting for perception/outline"
        response.success = True
        self.get_logger().info(f"~/reset: {response.message}")
        self._publish_diagnostics()
        return response

    # ---- publishing ----------------------------------------------------------------------
    def _publish_estimate(self, stamp_s: float) -> None:
        x, p = self._ekf.state, self._ekf.covariance
        stamp = stamp_from_seconds(max(stamp_s, 0.0))
        world, obj = self.params.world_frame, self.params.object_frame
        self._pub_pose.publish(pose_with_covariance_msg(x[0:3], p[0:3, 0:3], stamp, world))
        self._pub_com.publish(center_of_mass_msg(x[3:5], stamp, obj))
        self._pub_state.publish(state_array_msg(x, p))
        if self._pub_tf is not None:
            self._pub_tf.publish(TFMessage(transforms=[transform_msg(x[0:3], stamp, world,
                                                                     obj)]))

    def _publish_diagnostics(self) -> None:
        status = DiagnosticStatus()
        status.name = f"{self.get_fully_qualified_name()}: estimator"
        status.hardware_id = "push_estimator"
        status.level = DiagnosticStatus.WARN if self._problem else DiagnosticStatus.OK
        status.message = self._status() + (f"; {self._problem}" if self._problem else "")
        values = {"state": self._status(), **{k: str(v) for k, v in self._counts.items()},
                  "last_problem": self._problem, "last_nis": f"{self._last_nis:.3f}"}
        if self._ekf is not None:
            values["symmetry_order"] = str(self._ekf.outline.symmetry_order)
            if self._ekf.initialized:
                values.update({label: f"{v:.6g}"
                               for label, v in zip(STATE_LABELS, self._ekf.state, strict=True)})
        status.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._pub_diag.publish(array)


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ekf_node`` (``ros2 run push_estimator ekf_node`` / ``pushbot run``)."""
    rclpy.init(args=args)
    try:
        node = EkfNode()
    except (ValueError, ParameterException) as exc:
        rclpy.logging.get_logger(NODE_NAME).fatal(f"invalid configuration: {exc}")
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
