"""``ekf_node``: EKF over the object pose, centre of mass, limit surface and friction.

A thin ROS wrapper around :class:`push_core.estimator.PushEKF` (the filter, its state, noise
model, Jacobian and gating are documented there). Every message is converted by the codecs of
:mod:`push_ros` (outline: :mod:`push_ros.outline`; poses, COM, transform:
:mod:`push_ros.poses`; executed push: :mod:`push_ros.paths`; state: :mod:`push_ros.state`);
QoS, parameters, logging and ``main()`` are :mod:`push_ros`'s too. It never imports the
simulator.

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
- ``/clock`` only with ``use_sim_time`` true. The default is false (wall time, a real
  robot); the simulation (``pushbot demo``, the graph runner, the bringup YAML) sets it.

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

Publications (after every applied observation, stamped with the observation's stamp). The
three estimate topics are **latched** (reliable, transient local, depth 1): a subscriber that
starts later (the planner started by hand after the estimator) still gets the last estimate;
subscribers must be transient local too (``push_ros.qos.LATCHED_QOS`` or
``latched_reader_qos``) to get it, volatile ones only get what follows:

- ``estimator/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``; latched):
  x, y, yaw and their covariance (z, roll, pitch variance 0).
- ``estimator/center_of_mass`` (geometry_msgs/PointStamped, ``object``; latched).
- ``estimator/state`` (std_msgs/Float64MultiArray; latched): dim 0 label ``state`` size 7
  (``x,y,theta,c_x,c_y,l,m``), dim 1 label ``covariance_row_major`` size 49; data = the 7
  values then the 7 x 7 covariance (:func:`push_ros.state.state_array_msg`).
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
``pushbot_bringup/config/push_estimator.yaml``. A bad value fails start-up with a clear message
(exit status 2) and is refused when set at run time (with the reason); a valid value set later
has no effect until the node restarts. Frames: ``world`` and ``object`` (parameters
``world_frame``, ``object_frame``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from push_core.estimator import STATE_LABELS, EKFConfig, PushEKF
from push_core.geometry import NonFiniteError
from push_ros.diagnostics import DiagnosticsPublisher
from push_ros.frames import OBJECT_FRAME, WORLD_FRAME
from push_ros.node import ParamSpec, ThrottledLog, declare_config, run_node
from push_ros.outline import outline_from_cloud
from push_ros.paths import executed_push_from_path
from push_ros.poses import (
    center_of_mass_msg,
    planar_matrix,
    pose_with_covariance_from_msg,
    pose_with_covariance_msg,
    transform_msg,
)
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS
from push_ros.stamps import stamp_from_seconds
from push_ros.state import state_array_msg

try:  # Only on a full ROS install: tf2_msgs has no PyPI wheel (ARCHITECTURE.md, tf note).
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the install
    TFMessage = None

__all__ = ["EkfNode", "EkfNodeParams", "main"]

NODE_NAME = "ekf_node"
#: Seconds between repeated log lines of one kind (the counters count every event).
LOG_THROTTLE_S = 2.0
#: Tolerance (m) under which a re-published outline counts as the same outline.
SAME_OUTLINE_TOL = 1e-6

_DEFAULTS = EKFConfig()
#: The parameter table (node-only parameters first); :data:`_FIELDS` maps the others to the
#: :class:`EKFConfig` field they set.
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("world_frame", WORLD_FRAME, "Frame of observations, pushes and the estimated pose.",
              read_only=True),
    ParamSpec("object_frame", OBJECT_FRAME, "Frame of the outline and the COM.", read_only=True),
    ParamSpec("publish_tf", True, "Publish world -> object on /tf (only where tf2_msgs "
              "exists).", read_only=True),
    ParamSpec("diagnostics_period", 1.0, "Period of the regular /diagnostics message, s (wall "
              "time).", (0.1, 60.0), read_only=True),
    ParamSpec("observation.use_message_covariance", True, "Use the covariance of "
              "perception/object_pose when it is symmetric positive definite."),
    ParamSpec("observation.position_sigma", _DEFAULTS.position_sigma,
              "Observation noise of x and y (standard deviation), m.", (1e-5, 0.1)),
    ParamSpec("observation.angle_sigma", _DEFAULTS.angle_sigma,
              "Observation noise of theta (standard deviation), rad.", (1e-5, 1.0)),
    ParamSpec("symmetry_order", 0, "Rotational symmetry order of the object's outline: 1 = "
              "none, k = looks the same after 2 pi / k, 0 = detect from the outline.", (0, 64)),
    ParamSpec("symmetry_tolerance", _DEFAULTS.symmetry_tolerance,
              "Largest outline mismatch of a symmetry when detecting it, m.", (1e-5, 0.02)),
    ParamSpec("pusher_radius", _DEFAULTS.pusher_radius, "Radius of the pusher, m.",
              (0.0, 0.05)),
    ParamSpec("substep", _DEFAULTS.substep, "Longest model step along a push, m.", (1e-4, 0.2)),
    ParamSpec("contact_tol", _DEFAULTS.contact_tol, "Contact test tolerance, m.", (0.0, 0.01)),
    ParamSpec("outline_tolerance", _DEFAULTS.outline_tolerance,
              "Douglas-Peucker tolerance of the contact outline, m.", (1e-5, 0.01)),
    ParamSpec("iterations", _DEFAULTS.iterations, "Linearisations of a push per observation "
              "(1 = plain EKF, 2 = one re-linearisation).", (1, 10)),
    ParamSpec("initial.com_prior_fraction", _DEFAULTS.com_prior_fraction,
              "COM prior covariance = fraction^2 x the outline area's second moment (1 = "
              "anywhere in the object).", (1e-3, 10.0)),
    ParamSpec("initial.l_sigma_fraction", _DEFAULTS.l_sigma_fraction,
              "Initial standard deviation of l as a fraction of l_0.", (1e-3, 10.0)),
    ParamSpec("initial.m", _DEFAULTS.m_init, "Initial pusher-object friction coefficient.",
              (0.01, 5.0)),
    ParamSpec("initial.m_sigma", _DEFAULTS.m_sigma, "Initial standard deviation of m.",
              (1e-4, 5.0)),
    ParamSpec("limits.l_min_fraction", _DEFAULTS.l_min_fraction,
              "Lower clip of l as a fraction of l_0 (upper clip: outline radius).",
              (1e-3, 0.99)),
    ParamSpec("limits.m_min", _DEFAULTS.m_range[0], "Lower clip of m.", (1e-3, 5.0)),
    ParamSpec("limits.m_max", _DEFAULTS.m_range[1], "Upper clip of m.", (1e-3, 5.0)),
    ParamSpec("process_noise.position_min", _DEFAULTS.position_noise_min,
              "x, y process noise per push, constant part, m.", (0.0, 0.1)),
    ParamSpec("process_noise.position_per_metre", _DEFAULTS.position_noise_per_metre,
              "x, y process noise per metre of pusher travel in contact, m/m.", (0.0, 10.0)),
    ParamSpec("process_noise.angle_min", _DEFAULTS.angle_noise_min,
              "theta process noise per push, constant part, rad.", (0.0, 1.0)),
    ParamSpec("process_noise.angle_per_metre", _DEFAULTS.angle_noise_per_metre,
              "theta process noise per metre of pusher travel in contact, rad/m.",
              (0.0, 100.0)),
    ParamSpec("process_noise.com", _DEFAULTS.com_noise, "COM random walk per push (each "
              "axis), m.", (0.0, 0.1)),
    ParamSpec("process_noise.l", _DEFAULTS.l_noise, "l random walk per push, m.", (0.0, 0.1)),
    ParamSpec("process_noise.m", _DEFAULTS.m_noise, "m random walk per push.", (0.0, 1.0)),
    ParamSpec("gate_probability", _DEFAULTS.gate_probability, "Chi-square probability (3 dof) "
              "of the innovation gate; 1 disables gating.", (1e-6, 1.0)),
)
_FIELDS: dict[str, str] = {
    "observation.position_sigma": "position_sigma",
    "observation.angle_sigma": "angle_sigma",
    "symmetry_order": "symmetry_order",
    "symmetry_tolerance": "symmetry_tolerance",
    "pusher_radius": "pusher_radius",
    "substep": "substep",
    "contact_tol": "contact_tol",
    "outline_tolerance": "outline_tolerance",
    "iterations": "iterations",
    "initial.com_prior_fraction": "com_prior_fraction",
    "initial.l_sigma_fraction": "l_sigma_fraction",
    "initial.m": "m_init",
    "initial.m_sigma": "m_sigma",
    "limits.l_min_fraction": "l_min_fraction",
    "process_noise.position_min": "position_noise_min",
    "process_noise.position_per_metre": "position_noise_per_metre",
    "process_noise.angle_min": "angle_noise_min",
    "process_noise.angle_per_metre": "angle_noise_per_metre",
    "process_noise.com": "com_noise",
    "process_noise.l": "l_noise",
    "process_noise.m": "m_noise",
    "gate_probability": "gate_probability",
}


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
        kwargs = {field: values[name] for name, field in _FIELDS.items()}
        kwargs["m_range"] = (values["limits.m_min"], values["limits.m_max"])
        try:
            config = EKFConfig(**kwargs)
        except ValueError as exc:
            names = {field: name for name, field in _FIELDS.items()}
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
        self.params = declare_config(self, PARAMETERS, EkfNodeParams.from_values)

        self._ekf: PushEKF | None = None
        self._outline: np.ndarray | None = None
        self._counts = dict.fromkeys(_COUNTERS, 0)
        self._history: list[_Applied] = []  # the last HISTORY applied inputs, in stamp order
        self._last_observation = -math.inf
        self._previous_episode = math.nan  # stamp of the last observation before ~/reset
        self._last_nis = math.nan
        self._problem = ""  # the most recent problem, "" after a good input
        self._log = ThrottledLog(self.get_logger(), LOG_THROTTLE_S)

        self._pub_pose = self.create_publisher(PoseWithCovarianceStamped,
                                               "estimator/object_pose", LATCHED_QOS)
        self._pub_com = self.create_publisher(PointStamped, "estimator/center_of_mass",
                                              LATCHED_QOS)
        self._pub_state = self.create_publisher(Float64MultiArray, "estimator/state",
                                                LATCHED_QOS)
        self._diagnostics = DiagnosticsPublisher(self, "estimator", "push_estimator")
        self._pub_tf = None
        if TFMessage is not None and self.params.publish_tf:
            self._pub_tf = self.create_publisher(TFMessage, "/tf", RELIABLE_QOS)
        self.create_subscription(PointCloud2, "perception/outline", self._on_outline,
                                 LATCHED_QOS)
        self.create_subscription(PoseWithCovarianceStamped, "perception/object_pose",
                                 self._on_observation, RELIABLE_QOS)
        self.create_subscription(Path, "pusher/executed", self._on_push, RELIABLE_QOS)
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
        if error:
            self._log.error(counter, text)
        else:
            self._log.warning(counter, text)
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
        obs = self._parse(pose_with_covariance_from_msg, msg, "perception/object_pose")
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
        push = self._parse(executed_push_from_path, msg, "pusher/executed")
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
        self._pub_pose.publish(pose_with_covariance_msg(x[0:3], p[0:3, 0:3], stamp, world,
                                                        unmeasured_variance=0.0))
        self._pub_com.publish(center_of_mass_msg(x[3:5], stamp, obj))
        self._pub_state.publish(state_array_msg(x, p))
        if self._pub_tf is not None:
            self._pub_tf.publish(TFMessage(transforms=[
                transform_msg(planar_matrix(x[0:3]), stamp, world, obj)]))

    def _publish_diagnostics(self) -> None:
        level = DiagnosticStatus.WARN if self._problem else DiagnosticStatus.OK
        message = self._status() + (f"; {self._problem}" if self._problem else "")
        values = {"state": self._status(), **self._counts,
                  "last_problem": self._problem, "last_nis": f"{self._last_nis:.3f}"}
        if self._ekf is not None:
            values["symmetry_order"] = str(self._ekf.outline.symmetry_order)
            if self._ekf.initialized:
                values.update({label: f"{v:.6g}"
                               for label, v in zip(STATE_LABELS, self._ekf.state, strict=True)})
        self._diagnostics.publish(level, message, values)


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ekf_node`` (``ros2 run push_estimator ekf_node`` / ``pushbot run``)."""
    run_node(EkfNode, NODE_NAME, args)


if __name__ == "__main__":
    main()
