"""``ekf_node``: EKF over the object pose, centre of mass, limit surface and friction.

A thin ROS wrapper around :class:`push_core.estimator.PushEKF` (the filter, its state, noise
model, Jacobian and gating are documented there). Every message is converted by the codecs of
:mod:`push_ros` (outline: :mod:`push_ros.outline`; poses, COM, transform:
:mod:`push_ros.poses`; executed push: :mod:`push_ros.paths`; state: :mod:`push_ros.state`;
stamps: :mod:`push_ros.stamps`); QoS, parameters, logging and ``main()`` are :mod:`push_ros`'s
too. It never imports the simulator.

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
  is true and it is symmetric positive definite with eigenvalues in ``COVARIANCE_RANGE``;
  otherwise ``observation.*_sigma``.
- ``pusher/executed`` (nav_msgs/Path, ``world``; reliable): the executed push, two poses
  (start, end) each with its stamp; drives the prediction.
- ``/clock`` only with ``use_sim_time`` true. The default is false (wall time, a real
  robot); the simulation (``pushbot demo``, the graph runner, the bringup YAML) sets it.

Inputs are applied in stamp order (an observation at its stamp, a push from its start to its
end stamp). DDS does not order messages across topics (a reliable sample repaired after a lost
packet arrives late), so the post-push observation can overtake its ``pusher/executed``: the
node keeps the last ``HISTORY`` applied inputs with filter snapshots (the bounded replay
buffer), and a push that arrives after inputs it precedes is inserted and the later
observations re-applied (``replayed``; the estimate is published again).

Bad input. Every subscription, timer and service callback is wrapped by
:func:`push_ros.node.guarded`: an exception never leaves a callback (it would end the node); it
is logged with its line, counted (``callback_errors``) and reported on ``/diagnostics``, and
the filter is returned to its state before the input. A rejected input never changes the
filter's state. Every rejection has a log line (at most one per kind every
``LOG_THROTTLE_S``), the reason in ``last_problem`` and a counter on ``/diagnostics``. The
rules, per field (the README topic table and docs/ARCHITECTURE.md, "Estimator", list them too):

- every ``header.stamp`` (and each pose's stamp of a path): the :mod:`push_ros.stamps` rule
  (``sec >= 0``, ``nanosec < 1e9``, at most 2^31 s - 1 us: ``dropped_invalid``); not more than
  ``max_future_stamp`` s ahead of the node's clock (``dropped_future``); with
  ``use_sim_time`` before the first ``/clock`` (the clock reads 0) the node's clock is not
  valid and the future rule is not applied (the bridge publishes ``/clock`` before any frame;
  ``~/reset`` recovers from anything accepted then); not before the episode, i.e. the
  observation that initialised the filter (``dropped_out_of_order``, the reason says "before
  the episode");
- frames: ``header.frame_id`` (and a pose's own, which may be empty) must be the configured
  frame (``dropped_invalid``; outlines: ``rejected_outlines``);
- observation: position and orientation finite (``dropped_nan``); the quaternion unit and
  planar per :mod:`push_ros.poses` (``dropped_invalid``); ``|x|, |y| <= MAX_POSITION``
  (``dropped_out_of_range``); a covariance that is not finite, not symmetric positive
  definite or has an eigenvalue outside ``COVARIANCE_RANGE`` is replaced by the configured
  sigmas (``replaced_covariance``); the stamp of the previous observation, or of the last one
  before ``~/reset`` (the perception re-publishes while the scene is idle), is a repetition
  (``dropped_duplicate``, not logged); older than the last applied input:
  ``dropped_out_of_order``;
- push: exactly two poses (``dropped_invalid``: this caps the poses of a path), finite
  positions (``dropped_nan``), end not stamped before start (``dropped_invalid``), ``|x|, |y|
  <= MAX_POSITION`` and pusher travel at most ``max_push_length`` (``dropped_out_of_range``,
  rejected before any model step); a push seen before (``dropped_duplicate``); a push that
  cannot be placed (overlapping an observation or another push, older than the history:
  ``dropped_out_of_order``); a push before the filter is initialised (``dropped_before_init``);
  the model's loop is bounded by ``max_substeps`` (a longer push takes longer substeps);
- outline: the :mod:`push_ros.outline` reader's rules, at most ``MAX_OUTLINE_POINTS`` points
  (refused before decoding), coordinates within ``MAX_POSITION``, a valid counter-clockwise
  simple polygon with outward unit normals (``rejected_outlines``); above
  ``OUTLINE_WORKING_POINTS`` points it is decimated (every k-th point,
  :func:`push_ros.outline.decimate_outline`; ``decimated_outlines``), which bounds the contact
  polygon and the work of building the filter;
- observations before any outline: ``dropped_before_outline``;
- an input the filter cannot apply (non-finite result, singular matrix):
  ``dropped_filter_error``, the filter restored.

An observation that fails the Mahalanobis gate re-initialises the pose (``gated``, status
WARN; re-filtering updates the count).

Publications (after every applied observation, stamped with the observation's stamp; a stamp
is clamped into the representable range, so publishing never raises). The three estimate
topics are **latched** (reliable, transient local, depth 1): a subscriber that starts later
(the planner started by hand after the estimator) still gets the last estimate; subscribers
must be transient local too (``push_ros.qos.LATCHED_QOS`` or ``latched_reader_qos``) to get it,
volatile ones only get what follows:

- ``estimator/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``; latched):
  x, y, yaw and their covariance (z, roll, pitch variance 0).
- ``estimator/center_of_mass`` (geometry_msgs/PointStamped, ``object``; latched).
- ``estimator/state`` (std_msgs/Float64MultiArray; latched): dim 0 label ``state`` size 7
  (``x,y,theta,c_x,c_y,l,m``), dim 1 label ``covariance_row_major`` size 49; data = the 7
  values then the 7 x 7 covariance (:func:`push_ros.state.state_array_msg`).
- ``estimator/outline`` (sensor_msgs/PointCloud2, ``object``; latched): the
  ``perception/outline`` message the filter was built from, re-published as received (same
  stamp, points and normals) whenever a different outline is accepted. With the latched
  ``estimator/object_pose`` it is the episode's orientation reference that survives a restart
  of ``segmentation_node`` (its own latched outline dies with it): a restarted perception
  matches its first frame against it (docs/ARCHITECTURE.md, "Faults and recovery").
- ``/tf`` world -> object (tf2_msgs/TFMessage; reliable): only where ``tf2_msgs`` is
  importable (full ROS install; see the tf note in ARCHITECTURE.md) and ``publish_tf``.
- ``/diagnostics`` (diagnostic_msgs/DiagnosticArray; reliable): one status, every
  ``diagnostics_period`` seconds of wall time and on every event.

Services: ``~/reset`` (std_srvs/srv/Trigger): start a new episode (the outline is kept; the
next observation initialises the filter). It clears every "last applied" time (the replay
history, the last observation, the episode's start), so no stamp can wedge the node across
episodes, and applies the parameters set since the last episode start. An observation with the
stamp of the last one applied before the reset is a repetition of the previous episode's frame
(the perception re-publishes while the scene is idle) and is dropped (``dropped_duplicate``),
so it cannot initialise the new episode (found driving the graph, issue 7).

Parameters: declared below with descriptions and ranges, read into :class:`EkfNodeParams`
(frozen) and validated by building the filter's :class:`~push_core.estimator.EKFConfig`;
defaults, units and meaning in ``pushbot_bringup/config/push_estimator.yaml``. A bad value
fails start-up with a clear message (exit status 2). At run time a set is refused with the
reason when the configuration would be invalid or the current outline would not build a filter
with it; a valid value is accepted and **takes effect at the next episode start** (``~/reset``
or a new outline), which re-reads every parameter and rebuilds the filter when its
configuration changed. The structural ones (frames, ``publish_tf``, ``diagnostics_period``)
are read-only. Frames: ``world`` and ``object`` (parameters ``world_frame``,
``object_frame``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from push_core.estimator import STATE_LABELS, EKFConfig, PushEKF
from push_core.geometry import NonFiniteError
from push_ros.diagnostics import DiagnosticsPublisher
from push_ros.frames import OBJECT_FRAME, WORLD_FRAME
from push_ros.node import (
    ParamSpec,
    ThrottledLog,
    declare_config,
    guarded,
    parameter_values,
    run_node,
)
from push_ros.outline import decimate_outline, outline_from_cloud
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
#: Largest |x|, |y| (m) of an observation, a pusher position or an outline point: the table
#: scene spans a few metres (the perception's transforms have the same 100 m bound).
MAX_POSITION = 100.0
#: An outline cloud of more points is refused before it is decoded.
MAX_OUTLINE_POINTS = 4000
#: An outline of more points is decimated to at most this many (every k-th point): the
#: filter's polygon checks grow quadratically (1000 points: about 1 s and 0.2 GB to build).
#: A perceived outline (2 mm spacing) has a few hundred points.
OUTLINE_WORKING_POINTS = 1000
#: Eigenvalues (m^2, rad^2) of a message covariance the filter uses; outside, the configured
#: sigmas (1e-12: 1 um / 1 urad; 1e8 keeps the perception's "orientation not observed" 1e6).
COVARIANCE_RANGE = (1e-12, 1e8)

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
    ParamSpec("max_future_stamp", 10.0, "Inputs stamped more than this ahead of the node's "
              "clock are dropped, s (not applied while use_sim_time has no /clock yet).",
              (0.0, 3600.0)),
    ParamSpec("max_push_length", 1.0, "Longest pusher travel of one pusher/executed, m; a "
              "longer push is dropped before any model step.", (1e-3, 10.0)),
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
    ParamSpec("max_substeps", _DEFAULTS.max_substeps, "Most model steps of one push (a longer "
              "push is integrated in this many equal, longer steps).", (1, 100000)),
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
    "max_substeps": "max_substeps",
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
_PARAMETER_NAMES = frozenset(spec.name for spec in PARAMETERS)


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
    max_future_stamp : float
        s ahead of the node's clock.
    max_push_length : float
        m of pusher travel.
    """

    config: EKFConfig
    world_frame: str
    object_frame: str
    publish_tf: bool
    diagnostics_period: float
    use_message_covariance: bool
    max_future_stamp: float = 10.0
    max_push_length: float = 1.0

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
        limits = {}
        for name, (low, high) in (("max_future_stamp", (0.0, 3600.0)),
                                  ("max_push_length", (1e-3, 10.0))):
            value = values[name]
            if isinstance(value, bool) or not isinstance(value, int | float) or \
                    not low <= value <= high:
                raise ValueError(f"parameter {name!r} must be a number in [{low:g}, {high:g}], "
                                 f"got {value!r}")
            limits[name] = float(value)
        return cls(config=config, world_frame=str(values["world_frame"]),
                   object_frame=str(values["object_frame"]),
                   publish_tf=bool(values["publish_tf"]),
                   diagnostics_period=float(values["diagnostics_period"]),
                   use_message_covariance=bool(values["observation.use_message_covariance"]),
                   **limits)


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


#: Applied inputs kept for re-filtering a push that arrives after later inputs (the replay
#: buffer's bound: a late push re-applies at most this many inputs).
HISTORY = 32

_COUNTERS = ("observations", "pushes", "replayed", "gated", "resets", "outlines",
             "rejected_outlines", "decimated_outlines", "replaced_covariance",
             "dropped_nan", "dropped_invalid", "dropped_out_of_range", "dropped_future",
             "dropped_duplicate", "dropped_out_of_order",
             "dropped_before_init", "dropped_before_outline", "dropped_filter_error",
             "callback_errors")


class _Rejected(Exception):
    """An input the node refuses: ``counter`` and the reason."""

    def __init__(self, counter: str, reason: str) -> None:
        super().__init__(reason)
        self.counter = counter


#: What the filter may raise on an input it cannot apply (the input is dropped, the filter
#: restored): bad values, a singular matrix, an overflow.
_FILTER_ERRORS = (ValueError, ArithmeticError, np.linalg.LinAlgError, RuntimeError)


def _finite(ekf: PushEKF) -> bool:
    return bool(np.all(np.isfinite(ekf.x)) and np.all(np.isfinite(ekf.P)))


def _usable_covariance(cov: np.ndarray | None) -> bool:
    if cov is None:
        return False
    eig = np.linalg.eigvalsh(cov)
    return bool(COVARIANCE_RANGE[0] <= eig[0] and eig[-1] <= COVARIANCE_RANGE[1])


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
        self._applied_values = parameter_values(self, PARAMETERS)
        # Runs before declare_config's check (rclpy calls the last added first) and does it
        # too: a set is refused when the current outline would not build a filter with it.
        self.add_on_set_parameters_callback(self._check_parameters)

        self._ekf: PushEKF | None = None
        self._outline: np.ndarray | None = None
        self._normals: np.ndarray | None = None
        self._counts = dict.fromkeys(_COUNTERS, 0)
        self._history: list[_Applied] = []  # the last HISTORY applied inputs, in stamp order
        self._last_observation = -math.inf
        self._episode_start = -math.inf  # stamp of the observation that initialised the filter
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
        self._pub_outline = self.create_publisher(PointCloud2, "estimator/outline", LATCHED_QOS)
        self._diagnostics = DiagnosticsPublisher(self, "estimator", "push_estimator")
        self._pub_tf = None
        if TFMessage is not None and self.params.publish_tf:
            self._pub_tf = self.create_publisher(TFMessage, "/tf", RELIABLE_QOS)
        self.create_subscription(PointCloud2, "perception/outline",
                                 self._guard(self._on_outline), LATCHED_QOS)
        self.create_subscription(PoseWithCovarianceStamped, "perception/object_pose",
                                 self._guard(self._on_observation), RELIABLE_QOS)
        self.create_subscription(Path, "pusher/executed", self._guard(self._on_push),
                                 RELIABLE_QOS)
        self.create_service(Trigger, "~/reset", self._guard(self._on_reset))
        self.create_timer(self.params.diagnostics_period,
                          self._guard(self._publish_diagnostics),
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"ekf_node ready (use_sim_time={self.get_parameter('use_sim_time').value}, "
            f"iterations={self.params.config.iterations}); waiting for perception/outline")

    # ---- state ---------------------------------------------------------------------------
    @property
    def filter(self) -> PushEKF | None:
        """The current filter (None before the first outline)."""
        return self._ekf

    @property
    def counts(self) -> dict[str, int]:
        """The counters reported on /diagnostics (a copy)."""
        return dict(self._counts)

    def _status(self) -> str:
        if self._ekf is None:
            return "waiting for outline"
        return "tracking" if self._ekf.initialized else "waiting for first observation"

    def _guard(self, callback: Callable[..., Any]) -> Callable[..., Any]:
        return guarded(callback, self._log, self._on_callback_error, callback.__name__)

    def _on_callback_error(self, name: str, message: str) -> None:
        """An exception reached the guard: count and report it (the guard logged it)."""
        self._counts["callback_errors"] += 1
        self._problem = f"{name} failed: {message}"
        self._publish_diagnostics()

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

    def _clock_seconds(self) -> float | None:
        """The node's clock, s; None while it is not valid (use_sim_time, no /clock yet)."""
        clock = self.get_clock()
        ns = clock.now().nanoseconds
        if clock.ros_time_is_active and ns <= 0:
            return None
        return ns / 1e9

    def _check_time(self, stamp: float, topic: str, what: str = "stamped") -> None:
        """The stamp rules of the module docstring (future, before the episode)."""
        now = self._clock_seconds()
        if now is not None and stamp > now + self.params.max_future_stamp:
            raise _Rejected("dropped_future", f"dropped {topic} {what} {stamp:.6f} s: more "
                            f"than max_future_stamp = {self.params.max_future_stamp:g} s ahead "
                            f"of the node's clock ({now:.6f} s)")
        if stamp < self._episode_start:
            raise _Rejected("dropped_out_of_order", f"dropped {topic} {what} {stamp:.6f} s: "
                            f"before the episode (its first observation at "
                            f"{self._episode_start:.6f} s)")

    @staticmethod
    def _check_position(values: Iterable[float], topic: str) -> None:
        worst = max(abs(v) for v in values)
        if worst > MAX_POSITION:
            raise _Rejected("dropped_out_of_range", f"dropped {topic}: a coordinate of "
                            f"{worst:.6g} m, more than MAX_POSITION = {MAX_POSITION:g} m from "
                            "the origin")

    def _new_episode(self) -> None:
        self._history.clear()
        self._last_observation = -math.inf
        self._episode_start = -math.inf

    def _read_parameters(self) -> tuple[EkfNodeParams, str]:
        """The current parameter values, built, and ``"name=value, ..."`` of those that differ
        from the values applied last (raises ``ValueError``; they were checked on set)."""
        values = parameter_values(self, PARAMETERS)
        params = EkfNodeParams.from_values(values)
        changed = ", ".join(f"{name}={value!r}" for name, value in values.items()
                            if value != self._applied_values.get(name, value))
        return params, changed

    def _apply_parameters(self) -> str:
        """Episode start (``~/reset``): re-read every parameter and rebuild the filter on the
        current outline if its config changed. Returns the changed ``name=value`` list ("" if
        none); raises (nothing changed) if the filter cannot be built."""
        params, changed = self._read_parameters()
        if self._ekf is not None and params.config != self._ekf.config:
            self._ekf = PushEKF(self._outline, self._normals, params.config)
        self.params = params
        self._applied_values = parameter_values(self, PARAMETERS)
        return changed

    def _check_parameters(self, parameters: list[Any]) -> SetParametersResult:
        """On-set: refuse a value that makes the configuration invalid or that the current
        outline cannot build a filter with; never raises."""
        try:
            changed = {p.name: p.value for p in parameters if p.name in _PARAMETER_NAMES}
            if not changed:
                return SetParametersResult(successful=True)
            params = EkfNodeParams.from_values({**parameter_values(self, PARAMETERS),
                                                **changed})
            if self._outline is not None:
                try:
                    PushEKF(self._outline, self._normals, params.config)
                except _FILTER_ERRORS as exc:
                    return SetParametersResult(successful=False, reason=(
                        f"the current outline does not build a filter with these values: "
                        f"{exc}"))
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        except Exception as exc:  # noqa: BLE001 - a parameter callback must not raise
            return SetParametersResult(successful=False,
                                       reason=f"{type(exc).__name__}: {exc}"[:500])
        return SetParametersResult(successful=True)

    # ---- callbacks -----------------------------------------------------------------------
    def _on_outline(self, msg: PointCloud2) -> None:
        try:
            points, normals = outline_from_cloud(msg, self.params.object_frame,
                                                 MAX_OUTLINE_POINTS)
        except ValueError as exc:  # NonFiniteError included
            self._drop("rejected_outlines", f"rejected perception/outline: {exc}", error=True)
            return
        worst = float(np.max(np.abs(points)))
        if worst > MAX_POSITION:
            self._drop("rejected_outlines", f"rejected perception/outline: a point {worst:.6g} "
                       f"m from the object origin, more than MAX_POSITION = {MAX_POSITION:g} m",
                       error=True)
            return
        n_received = len(points)
        points, normals = decimate_outline(points, normals, OUTLINE_WORKING_POINTS)
        if (self._outline is not None and self._outline.shape == points.shape
                and np.allclose(self._outline, points, rtol=0.0, atol=SAME_OUTLINE_TOL)):
            return  # the same latched outline again
        try:
            params, changed = self._read_parameters()
            ekf = PushEKF(points, normals, params.config)
        except _FILTER_ERRORS as exc:
            self._drop("rejected_outlines", f"rejected perception/outline: {exc}", error=True)
            return
        if len(points) < n_received:
            self._counts["decimated_outlines"] += 1
        replaced = self._ekf is not None
        self.params = params  # a new episode: the parameters set since the last one apply
        self._applied_values = parameter_values(self, PARAMETERS)
        if changed:
            self.get_logger().info(f"parameters applied with the new outline: {changed}")
        self._ekf, self._outline, self._normals = ekf, points, normals
        self._new_episode()
        self._pub_outline.publish(msg)  # the episode's reference, latched (module docstring)
        self._counts["outlines"] += 1
        self._problem = ""
        o = ekf.outline
        decimated = (f" (decimated from {n_received})" if len(points) < n_received else "")
        self.get_logger().info(
            f"{'new ' if replaced else ''}outline: {len(points)} points{decimated} -> "
            f"{len(o.vertices)} contact vertices, l_0 = {1e3 * o.limit_surface:.1f} mm, "
            f"symmetry order {o.symmetry_order}{'; new episode' if replaced else ''}")
        self._publish_diagnostics()

    def _on_observation(self, msg: PoseWithCovarianceStamped) -> None:
        if self._ekf is None:
            self._drop("dropped_before_outline", "dropped perception/object_pose: no outline "
                       "yet (waiting for perception/outline)")
            return
        obs = self._parse(pose_with_covariance_from_msg, msg, "perception/object_pose")
        if obs is None:
            return
        try:
            self._check_position(obs.pose[:2], "perception/object_pose")
            if obs.stamp in (self._last_observation, self._previous_episode):
                self._counts["dropped_duplicate"] += 1  # normal while the scene is idle: no log
                return
            self._check_time(obs.stamp, "perception/object_pose")
            last = self._history[-1].key if self._history else -math.inf
            if obs.stamp < last:
                raise _Rejected("dropped_out_of_order", f"dropped perception/object_pose "
                                f"stamped {obs.stamp:.6f} s: older than the last applied input "
                                f"({last:.6f} s)")
            cov = obs.covariance if self.params.use_message_covariance else None
            if cov is not None and not _usable_covariance(cov):
                self._counts["replaced_covariance"] += 1
                cov = None
            entry = _Applied(obs.stamp, (obs.pose, cov), self._ekf.snapshot())
            result = self._apply_or_restore(entry, "perception/object_pose")
        except _Rejected as rejected:
            self._drop(rejected.counter, str(rejected))
            return
        self._last_nis = result.nis
        self._last_observation = entry.key
        self._record(entry)
        self._counts["observations"] += 1
        if result.initialized:
            self._episode_start = obs.stamp
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
        try:
            self._check_position((*push.start, *push.end), "pusher/executed")
            length = math.hypot(*(push.end - push.start))
            if length > self.params.max_push_length:
                raise _Rejected("dropped_out_of_range", f"dropped pusher/executed: the pusher "
                                f"travels {length:.6g} m, more than max_push_length = "
                                f"{self.params.max_push_length:g} m")
            if any(e.push == push_key(push) for e in self._history):
                self._counts["dropped_duplicate"] += 1
                return
            self._check_time(push.t_end, "pusher/executed", "ending")
            self._check_time(push.t_start, "pusher/executed", "starting")
            self._insert_push(push)
        except _Rejected as rejected:
            self._drop(rejected.counter, str(rejected))
            return
        self._trim_history()
        self._publish_diagnostics()

    def _insert_push(self, push: Any) -> None:
        """Place the push among the applied inputs, apply it and re-apply what follows it;
        on any failure the filter and the history are as before (raises :class:`_Rejected`)."""
        # Inputs after which this push belongs: every applied input up to its start.
        i = len(self._history)
        while i > 0 and self._history[i - 1].key > push.t_start:
            i -= 1
        later = self._history[i:]
        if later and (i == 0 or any(e.push is not None or e.key < push.t_end for e in later)):
            raise _Rejected("dropped_out_of_order", f"dropped pusher/executed "
                            f"{push.t_start:.6f} -> {push.t_end:.6f} s: it cannot be placed "
                            "among the applied inputs (before the first observation, "
                            "overlapping an observation or another push, or older than the "
                            "kept history)")
        current = self._ekf.snapshot()
        saved = [(e.before, e.after, e.gated) for e in later]
        last_nis = self._last_nis
        before = later[0].before if later else current
        entry = _Applied(push.t_end, (push.start, push.end), before, push=push_key(push))
        self._ekf.restore(before)
        try:
            pred = self._apply_or_restore(entry, "pusher/executed")
            for e in later:  # the push arrived after inputs it precedes: re-apply them
                e.before = self._ekf.snapshot()
                result = self._apply_or_restore(e, "perception/object_pose (re-filtered)")
                self._last_nis = result.nis
        except _Rejected:
            for e, (b, a, g) in zip(later, saved, strict=True):
                e.before, e.after, e.gated = b, a, g
            self._last_nis = last_nis
            self._ekf.restore(current)
            raise
        self._counts["pushes"] += 1
        self._counts["gated"] += sum(int(e.gated) - int(g)
                                     for e, (_, _, g) in zip(later, saved, strict=True))
        self._problem = ""
        contact = (f"contact over {1e3 * pred.contact_length:.1f} mm" if pred.touched
                   else "no contact")
        self.get_logger().info(f"push {push.t_start:.3f} -> {push.t_end:.3f} s: {contact}, "
                               f"{pred.n_substeps} substeps"
                               + (f"; arrived after {len(later)} later input(s), re-filtered"
                                  if later else ""))
        self._history.insert(i, entry)
        if later:
            self._counts["replayed"] += 1
            if any(e.gated for e in later):
                self._problem = ("after re-filtering a late pusher/executed, an observation "
                                 "still fails the gate")
            self._publish_estimate(self._last_observation)

    def _apply_or_restore(self, entry: _Applied, topic: str) -> Any:
        """Apply one input; if the filter raises or its result is not finite, restore the
        filter to its state before and raise :class:`_Rejected` (``dropped_filter_error``)."""
        before = self._ekf.snapshot()
        gated = entry.gated
        try:
            result = self._apply(entry)
            ok = _finite(self._ekf)
            problem = "the result is not finite"
        except _FILTER_ERRORS as exc:
            ok, problem = False, f"{type(exc).__name__}: {exc}"
        if not ok:
            self._ekf.restore(before)
            entry.gated = gated
            raise _Rejected("dropped_filter_error", f"dropped {topic}: the filter cannot apply "
                            f"it ({problem}); filter unchanged")
        return result

    def _apply(self, entry: _Applied) -> Any:
        """Apply one input to the filter; record its outcome in ``entry``."""
        if entry.push is not None:
            start, end = entry.data
            result = self._ekf.predict_push(start, end)
        else:
            pose, cov = entry.data
            result = self._ekf.update_pose(pose, cov)
            entry.gated = result.reinitialized
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
        try:
            applied = self._apply_parameters()
        except _FILTER_ERRORS as exc:  # refused at set time; kept as a second line
            applied = None
            self._problem = f"~/reset: the parameters set were not applied ({exc})"
        self._counts["resets"] += 1
        self._previous_episode = self._last_observation
        self._new_episode()
        if applied is not None:
            self._problem = ""
        if self._ekf is not None:
            self._ekf.reset()
            response.message = "new episode: waiting for the first observation"
        else:
            response.message = "new episode: waiting for perception/outline"
        if applied:
            response.message += f"; parameters applied: {applied}"
        response.success = applied is not None
        if applied is None:
            response.message += f"; {self._problem}"
        self.get_logger().info(f"~/reset: {response.message}")
        self._publish_diagnostics()
        return response

    # ---- publishing ----------------------------------------------------------------------
    def _publish_estimate(self, stamp_s: float) -> None:
        x, p = self._ekf.state, self._ekf.covariance
        stamp = stamp_from_seconds(stamp_s, clamp=True)
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
