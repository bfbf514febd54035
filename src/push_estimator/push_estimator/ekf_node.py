"""``ekf_node``: EKF over the object pose, centre of mass, limit surface and friction.

Role: feeds :class:`push_core.estimator.PushEKF` the perceived poses and the executed pushes in
stamp order through :class:`push_core.estimator.replay.ReplayHistory` (a late push is inserted and
the later observations re-filtered), builds the filter from ``perception/outline`` (a different
outline starts an episode) and publishes the estimate latched, stamped with the observation's
stamp. Input rules: :mod:`push_estimator.inputs`; parameters: :mod:`push_estimator.config`.

Invariants: a refused input never changes the filter (a failed or non-finite update restores
its snapshot); no exception leaves a callback; health, refusals and counters are
:class:`push_ros.health.NodeHealth`'s (``/diagnostics``); every message goes through a
:mod:`push_ros` codec; it never imports the simulator.

Topics, services and parameters: docs/INTERFACES.md (generated parameter table); the filter and
the rules: docs/design/estimator.md and docs/design/node-runtime.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable
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

from push_core.estimator import STATE_LABELS, PushEKF
from push_core.estimator.replay import FILTER_ERRORS, Rejected, ReplayHistory
from push_core.geometry import NonFiniteError
from push_estimator import inputs
from push_estimator.config import (
    NODE_NAME,
    PARAMETERS,
    EkfNodeParams,
    changed_values,
    check_parameter_set,
)
from push_ros.health import NodeHealth
from push_ros.node import declare_config, on_clock_jump_back, parameter_values, run_node
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
from push_ros.stamps import check_not_ahead, clock_seconds, seconds_from_stamp, stamp_from_seconds
from push_ros.state import state_array_msg
from push_ros.tf import tf_publisher

__all__ = ["EkfNode", "EkfNodeParams", "main"]

#: Seconds between repeated log lines of one kind (the counters count every event).
LOG_THROTTLE_S = 2.0
#: An outline of more points is decimated to at most this many (every k-th point): the
#: filter's polygon checks grow quadratically (1000 points: about 1 s and 0.2 GB to build).
#: A perceived outline (2 mm spacing) has a few hundred points.
OUTLINE_WORKING_POINTS = 1000
#: The node's own counters; refusals are ``refused_<kind>`` (NodeHealth).
_COUNTERS = ("observations", "pushes", "replayed", "gated", "relearned", "resets", "outlines",
             "decimated_outlines", "replaced_covariance",
             *(f"refused_{k}" for k in ("outline", "nan", "invalid", "out_of_range", "future",
                                        "duplicate", "out_of_order", "before_init",
                                        "before_outline", "filter_error")))


class EkfNode(Node):
    """ROS wrapper of :class:`push_core.estimator.PushEKF`; see the module docstring.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        At construction, if a parameter is invalid.
    """

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.health = NodeHealth(self, "estimator", "push_estimator", _COUNTERS, LOG_THROTTLE_S,
                                 on_error=self._on_callback_error)
        self.params = declare_config(self, PARAMETERS, EkfNodeParams.from_values)
        self._applied_values = parameter_values(self, PARAMETERS)
        # Runs before declare_config's check (rclpy calls the last added first) and does it
        # too: a set is refused when the current outline would not build a filter with it.
        self.add_on_set_parameters_callback(self._check_parameters)

        self._ekf: PushEKF | None = None
        self._outline: np.ndarray | None = None
        self._normals: np.ndarray | None = None
        self._replay = ReplayHistory(None)  # the applied inputs of the episode (late pushes)
        self._inputs = inputs.EpisodeInputs()  # last observation, episode boundary
        self._episode_start = -math.inf  # stamp of the observation that initialised the filter
        self._last_nis = math.nan
        self._problem = ""  # the most recent problem, "" after a good input

        self._pub_pose = self.create_publisher(PoseWithCovarianceStamped,
                                               "estimator/object_pose", LATCHED_QOS)
        self._pub_com = self.create_publisher(PointStamped, "estimator/center_of_mass",
                                              LATCHED_QOS)
        self._pub_state = self.create_publisher(Float64MultiArray, "estimator/state",
                                                LATCHED_QOS)
        self._pub_outline = self.create_publisher(PointCloud2, "estimator/outline", LATCHED_QOS)
        self._tf = tf_publisher(self, self.params.publish_tf)
        guard = self.health.guard
        self.create_subscription(PointCloud2, "perception/outline", guard(self._on_outline),
                                 LATCHED_QOS)
        self.create_subscription(PoseWithCovarianceStamped, "perception/object_pose",
                                 guard(self._on_observation), RELIABLE_QOS)
        self.create_subscription(Path, "pusher/executed", guard(self._on_push), RELIABLE_QOS)
        self.create_service(Trigger, "~/reset", guard(self._on_reset))
        self._jump = on_clock_jump_back(self, guard(self._on_clock_restart))
        self.create_timer(self.params.diagnostics_period, guard(self._publish_diagnostics),
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"ekf_node ready (use_sim_time={self.get_parameter('use_sim_time').value}, "
            f"iterations={self.params.config.iterations}); waiting for perception/outline")

    # ---- state ---------------------------------------------------------------------------
    def _status(self) -> str:
        if self._ekf is None:
            return "waiting for outline"
        return "tracking" if self._ekf.initialized else "waiting for first observation"

    def _on_callback_error(self, name: str, message: str) -> None:
        """An exception reached the guard (counted and logged by it): report it."""
        self._problem = f"{name} failed: {message}"
        self._publish_diagnostics()

    def _refuse(self, what: str, kind: str, reason: str, error: bool = False) -> None:
        """Count (``refused_<kind>``), log (throttled) and report a refused input."""
        self._problem = self.health.refuse(what, reason, kind, error)
        self._publish_diagnostics()

    def _duplicate(self) -> None:
        """A refused duplicate: counted, not logged (the perception re-publishes while idle)."""
        self.health.count("refused")
        self.health.count("refused_duplicate")

    def _parse(self, parse: Callable[[Any, str], Any], msg: Any, topic: str) -> Any:
        """``parse(msg, world_frame)``, or None after refusing a bad message."""
        try:
            return parse(msg, self.params.world_frame)
        except NonFiniteError as exc:
            self._refuse(topic, "nan", str(exc))
        except ValueError as exc:
            self._refuse(topic, "invalid", str(exc))
        return None

    def _check_time(self, stamp: float, what: str = "stamped") -> None:
        """The stamp rules of the module docstring (future, before the episode)."""
        try:
            check_not_ahead(stamp, clock_seconds(self.get_clock()),
                            self.params.max_future_stamp, what)
        except ValueError as exc:
            raise Rejected("future", str(exc)) from None
        inputs.check_stamp_order(stamp, self._episode_start, what)

    def _new_episode(self) -> None:
        self._replay.clear(self._ekf)
        self._inputs.last = -math.inf
        self._episode_start = -math.inf

    def _on_clock_restart(self, delta: float) -> None:
        """The clock jumped back (a restarted simulator): the object did not move, its stamps
        did; the filter is kept, the stamp order and episode boundary start again."""
        self._new_episode()
        self._inputs.boundary = -math.inf

    def _read_parameters(self) -> tuple[EkfNodeParams, str]:
        """The current parameter values, built, and those changed since the last episode."""
        values = parameter_values(self, PARAMETERS)
        return EkfNodeParams.from_values(values), changed_values(values, self._applied_values)

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
        """On-set (:func:`push_estimator.config.check_parameter_set`); never raises."""
        reason = check_parameter_set(parameter_values(self, PARAMETERS),
                                     {p.name: p.value for p in parameters}, self._outline,
                                     self._normals)
        return SetParametersResult(successful=not reason, reason=reason)

    # ---- callbacks -----------------------------------------------------------------------
    def _on_outline(self, msg: PointCloud2) -> None:
        topic = "perception/outline"
        try:
            points, normals = outline_from_cloud(msg, self.params.object_frame,
                                                 inputs.MAX_OUTLINE_CLOUD_POINTS)
            inputs.check_outline_extent(points)
            reference = seconds_from_stamp(msg.header.stamp)  # the episode's first frame
        except ValueError as exc:  # NonFiniteError included
            self._refuse(topic, "outline", str(exc), error=True)
            return
        n_received = len(points)
        points, normals = decimate_outline(points, normals, OUTLINE_WORKING_POINTS)
        if inputs.same_outline(self._outline, points):
            return  # the same latched outline again
        try:
            params, changed = self._read_parameters()
            ekf = PushEKF(points, normals, params.config)
        except FILTER_ERRORS as exc:
            self._refuse(topic, "outline", str(exc), error=True)
            return
        if len(points) < n_received:
            self.health.count("decimated_outlines")
        replaced = self._ekf is not None
        self.params = params  # a new episode: the parameters set since the last one apply
        self._applied_values = parameter_values(self, PARAMETERS)
        if changed:
            self.get_logger().info(f"parameters applied with the new outline: {changed}")
        self._ekf = ekf
        self._outline, self._normals = points, normals
        self._new_episode()
        self._inputs.new_outline(reference)  # perception's new episode starts at its frame
        self._pub_outline.publish(msg)  # the episode's reference, latched (module docstring)
        self.health.count("outlines")
        self._problem = ""
        self.get_logger().info(inputs.outline_summary(ekf.outline, len(points), n_received,
                                                      replaced))
        self._publish_diagnostics()

    def _on_observation(self, msg: PoseWithCovarianceStamped) -> None:
        topic = "perception/object_pose"
        if self._ekf is None:
            self._refuse(topic, "before_outline", "no outline yet (waiting for "
                         "perception/outline)")
            return
        obs = self._parse(pose_with_covariance_from_msg, msg, topic)
        if obs is None:
            return
        try:
            inputs.check_position(obs.pose[:2])
            if self._inputs.old(obs.stamp):  # a repeat, or taken before ~/reset: no log
                self._duplicate()
                return
            self._check_time(obs.stamp)
            self._replay.check_order(obs.stamp)
            cov = obs.covariance if self.params.use_message_covariance else None
            if cov is not None and not inputs.usable_covariance(cov):
                self.health.count("replaced_covariance")
                cov = None
            result = self._replay.observe(obs.stamp, obs.pose, cov)
        except Rejected as rejected:
            self._refuse(topic, rejected.kind, str(rejected))
            return
        self._last_nis = result.nis
        self._inputs.last = obs.stamp
        self.health.count("gated", int(result.reinitialized))
        relearned = bool(getattr(result, "relearned", False))
        self.health.count("relearned", int(relearned))
        self.health.count("observations")
        if result.initialized:
            self._episode_start = obs.stamp
        self._problem = inputs.observation_problem(obs.stamp, result, relearned,
                                                   self._ekf.config.gate_threshold)
        if self._problem:
            self.get_logger().warning(self._problem)
        elif result.initialized:
            self.get_logger().info(f"initialised from the observation at {obs.stamp:.3f} s")
        self._publish_estimate(obs.stamp)
        self._publish_diagnostics()

    def _on_push(self, msg: Path) -> None:
        topic = "pusher/executed"
        if self._ekf is None or not self._ekf.initialized:
            self._refuse(topic, "before_init", "the filter is not initialised yet (needs the "
                         "outline and a first observation)")
            return
        push = self._parse(executed_push_from_path, msg, topic)
        if push is None:
            return
        try:
            inputs.check_position((*push.start, *push.end))
            inputs.check_push_length(push.start, push.end, self.params.max_push_length)
            if self._replay.has_push(push.t_start, push.t_end):
                self._duplicate()
                return
            self._check_time(push.t_end, "ending")
            self._check_time(push.t_start, "starting")
            done = self._replay.insert_push(push.t_start, push.t_end, push.start, push.end)
        except Rejected as rejected:
            self._refuse(topic, rejected.kind, str(rejected))
            return
        self.health.count("pushes")
        self.health.count("gated", done.gated_change)
        self._problem = ""
        pred = done.prediction
        if pred.touched:
            contact = f"contact over {1e3 * pred.contact_length:.1f} mm"
        else:
            contact = "no contact"
        report = (f"push {push.t_start:.3f} -> {push.t_end:.3f} s: {contact}, "
                  f"{pred.n_substeps} substeps")
        if done.replayed:
            report += f"; arrived after {done.replayed} later input(s), re-filtered"
        self.get_logger().info(report)
        if done.replayed:
            self._last_nis = done.nis
            self.health.count("replayed")
            if done.still_gated:
                self._problem = ("after re-filtering a late pusher/executed, an observation "
                                 "still fails the gate")
            self._publish_estimate(self._inputs.last)
        self._publish_diagnostics()

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        try:
            applied = self._apply_parameters()
        except FILTER_ERRORS as exc:  # refused at set time; kept as a second line
            applied = None
            self._problem = f"~/reset: the parameters set were not applied ({exc})"
        self.health.count("resets")
        after = self._inputs.reset()  # inputs.EpisodeInputs: which observations are old
        self._new_episode()
        if applied is not None:
            self._problem = ""
        if self._ekf is not None:
            self._ekf.reset()
            response.message = f"new episode{after}: waiting for the first observation"
        else:
            response.message = f"new episode{after}: waiting for perception/outline"
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
        if self._tf is not None:
            self._tf.publish(transform_msg(planar_matrix(x[0:3]), stamp, world, obj))

    def _publish_diagnostics(self) -> None:
        level = DiagnosticStatus.WARN if self._problem else DiagnosticStatus.OK
        message = self._status() + (f"; {self._problem}" if self._problem else "")
        values = {"state": self._status(), "last_problem": self._problem,
                  "last_nis": f"{self._last_nis:.3f}"}
        if self._ekf is not None:
            values["symmetry_order"] = str(self._ekf.outline.symmetry_order)
            if self._ekf.initialized:
                values.update({label: f"{v:.6g}"
                               for label, v in zip(STATE_LABELS, self._ekf.state, strict=True)})
        self.health.publish(level, message, values)


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ekf_node`` (``ros2 run push_estimator ekf_node`` / ``pushbot run``)."""
    run_node(EkfNode, NODE_NAME, args)


if __name__ == "__main__":
    main()
