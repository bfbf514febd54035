"""``ekf_node``'s parameters: the declared table and the typed, validated configuration.

:data:`PARAMETERS` is the one declaration of every parameter (name, default, description with
unit, bounds, read-only), node-only parameters first; :data:`_FIELDS` maps the others to the
:class:`~push_core.estimator.EKFConfig` field they set. :meth:`EkfNodeParams.from_values` builds
the frozen configuration and raises ``ValueError`` naming the parameter;
:func:`check_parameter_set` is the rule for a set at run time (also: the current outline must
still build a filter) and :func:`changed_values` names what an episode start applies.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from push_core.estimator import EKFConfig, PushEKF
from push_core.estimator.replay import FILTER_ERRORS
from push_ros.frames import OBJECT_FRAME, WORLD_FRAME
from push_ros.interfaces import SIM_TIME
from push_ros.node import ParamSpec

__all__ = ["NODE_NAME", "PARAMETERS", "YAML_EXTRA", "YAML_HEADER", "YAML_NOTES",
           "EkfNodeParams", "changed_values", "check_parameter_set"]

_DEFAULTS = EKFConfig()
#: The parameter table (node-only parameters first); :data:`_FIELDS` maps the others to the
#: :class:`EKFConfig` field they set.
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("world_frame", WORLD_FRAME, "Frame of observations, pushes and the estimated pose.",
              read_only=True),
    ParamSpec("object_frame", OBJECT_FRAME, "Frame of the outline and the COM.", read_only=True),
    ParamSpec("publish_tf", True, "Publish world -> object on /tf (only where tf2_msgs is "
              "importable: a full ROS install; the pip install has no tf2_msgs wheel).",
              read_only=True),
    ParamSpec("diagnostics_period", 1.0, "Period of the regular /diagnostics message, s of wall "
              "time (also sent on every event).", (0.1, 60.0), read_only=True),
    ParamSpec("max_future_stamp", 10.0, "Inputs stamped more than this ahead of the node's "
              "clock are dropped, s (not applied while use_sim_time has no /clock yet, the clock "
              "reading 0; ~/reset clears every 'last applied' time).",
              (0.0, 3600.0)),
    ParamSpec("max_push_length", 1.0, "Longest pusher travel of one pusher/executed, m; a "
              "longer push is dropped before any model step (the planner's pushes are 2-4 cm).",
              (1e-3, 10.0)),
    ParamSpec("observation.use_message_covariance", True, "Use the covariance of "
              "perception/object_pose (x, y, yaw) when it is symmetric positive definite; "
              "otherwise (or when false) the sigmas below."),
    ParamSpec("observation.position_sigma", _DEFAULTS.position_sigma,
              "Observation noise of x and y (standard deviation), m.", (1e-5, 0.1)),
    ParamSpec("observation.angle_sigma", _DEFAULTS.angle_sigma,
              "Observation noise of theta (standard deviation), rad (0.0262 rad = 1.5 deg).",
              (1e-5, 1.0)),
    ParamSpec("symmetry_order", 0, "Rotational symmetry order of the object's outline: 1 = "
              "none, k = looks the same after a rotation by 2 pi / k (rect: 2 or 4, hex: 6), 0 = "
              "detect it from the outline. The observed orientation is taken modulo 2 pi / k, "
              "closest to the prediction, so theta stays continuous.", (0, 64)),
    ParamSpec("symmetry_tolerance", _DEFAULTS.symmetry_tolerance,
              "Largest outline mismatch of a symmetry when detecting it, m (2 mm: perceived "
              "outlines deviate from the true one by up to about 1.5 mm).", (1e-5, 0.02)),
    ParamSpec("pusher_radius", _DEFAULTS.pusher_radius, "Radius of the pusher, m.",
              (0.0, 0.05)),
    ParamSpec("substep", _DEFAULTS.substep, "Longest model step along a push, m; longer pushes "
              "are integrated in substeps (1 cm: 0.5 mm / 0.4 deg median discretisation error on "
              "2-4 cm pushes).", (1e-4, 0.2)),
    ParamSpec("max_substeps", _DEFAULTS.max_substeps, "Most model steps of one push (a longer "
              "push is integrated in this many equal, longer steps: bounded work per push; 1000 "
              "never binds with the defaults, 1 m / 1 cm = 100).", (1, 100000)),
    ParamSpec("contact_tol", _DEFAULTS.contact_tol, "Contact test tolerance, m.", (0.0, 0.01)),
    ParamSpec("outline_tolerance", _DEFAULTS.outline_tolerance,
              "Douglas-Peucker tolerance of the contact outline, m.", (1e-5, 0.01)),
    ParamSpec("iterations", _DEFAULTS.iterations, "Linearisations of a push per observation "
              "(1 = plain EKF; 2 = re-linearise once at the smoothed pre-push state, an iterated "
              "EKF: butter's COM error 10.6 -> 6.5 mm on the pybullet benchmark, consistent NEES, "
              "twice the cost of an update).", (1, 10)),
    ParamSpec("initial.com_prior_fraction", _DEFAULTS.com_prior_fraction,
              "COM prior covariance = fraction^2 x the outline area's second moment (1 = "
              "anywhere in the object).", (1e-3, 10.0)),
    ParamSpec("initial.l_sigma_fraction", _DEFAULTS.l_sigma_fraction,
              "Initial standard deviation of l as a fraction of l_0 (l starts at l_0, the "
              "uniform-pressure value of the outline: the mean distance of its area from its "
              "centroid).", (1e-3, 10.0)),
    ParamSpec("initial.m", _DEFAULTS.m_init, "Initial pusher-object friction coefficient "
              "(between steel on steel and the simulator's 0.15-0.5).",
              (0.01, 5.0)),
    ParamSpec("initial.m_sigma", _DEFAULTS.m_sigma, "Initial standard deviation of m.",
              (1e-4, 5.0)),
    ParamSpec("limits.l_min_fraction", _DEFAULTS.l_min_fraction,
              "Lower clip of l as a fraction of l_0 (upper clip: outline radius).",
              (1e-3, 0.99)),
    ParamSpec("limits.m_min", _DEFAULTS.m_range[0], "Lower clip of m (m_min < initial.m <= "
              "m_max).", (1e-3, 5.0)),
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
              "of the Mahalanobis gate (0.9999: squared distance 21.1): a farther observation "
              "re-initialises the pose (object knocked by hand) and keeps c, l, m; reported on "
              "/diagnostics. 1 disables gating.", (1e-6, 1.0)),
    ParamSpec("relearn.enabled", _DEFAULTS.relearn, "Re-learn c, l, m when pushes contradict "
              "their predictions (gate failure or windowed NIS test) instead of keeping them."),
    ParamSpec("relearn.window", _DEFAULTS.relearn_window, "Observations after pushes in the "
              "windowed NIS test of relearn.", (1, 64)),
    ParamSpec("relearn.probability", _DEFAULTS.relearn_probability, "Chi-square probability "
              "of the windowed NIS test (3 x window dof).", (1e-6, 0.999999)),
)

#: The node's name: the top-level key of its parameter file.
NODE_NAME = "ekf_node"
#: Written before the table in the parameter file (ROS declares it).
YAML_EXTRA = (SIM_TIME,)
#: Comment at the top of the bundled parameter file (pushbot_bringup/config/push_estimator.yaml).
YAML_HEADER = """
Parameters of push_estimator's ekf_node: the EKF over the object pose, centre of mass (COM),
limit-surface parameter l and pusher-object friction m (docs/design/estimator.md; the
table is also in docs/INTERFACES.md).
Load with: pushbot run ekf_node --ros-args --params-file \\
  src/pushbot_bringup/config/push_estimator.yaml
(or ros2 run / ros2 launch on a full ROS install: `ros2 launch pushbot_bringup pushbot.launch.py`
loads it from share/pushbot_bringup/config and sets use_sim_time from sim:=true|false).

State x = (x, y, theta, c_x, c_y, l, m): object frame pose in world (m, rad; theta
continuous), COM in the object frame (m), l (m), m (dimensionless). Every value below is the
default; units SI. Ranges are enforced at start-up (a bad value stops the node with a clear
message). The filter is push_core.estimator.PushEKF; its docstring explains the model.
Set at run time (ros2 param set), a value outside its range, an invalid combination or one
the current outline cannot build a filter with is refused with the reason; a valid one is
accepted and takes effect at the next episode start (~/reset or a new outline), which
re-reads every parameter. The read-only ones cannot be set at run time."""
#: Comment paragraphs before a parameter in the parameter file.
YAML_NOTES = {
    "world_frame": "Frames and reporting.",
    "max_future_stamp": "Input bounds: bad input is dropped with a reason and a /diagnostics "
                        "counter (the rules per field: docs/INTERFACES.md, topic table).",
    "pusher_radius": "Process model: the analytical pushing model driven by pusher/executed.",
    "initial.com_prior_fraction": "Initial state: l starts at l_0, computed from the outline.",
    "process_noise.position_min": "Process noise per push, standard deviations: a constant "
                                  "part plus a part per metre of pusher travel in contact (the "
                                  "model's error grows with the motion), and a random walk of "
                                  "the slowly varying parameters. Tuned on the pybullet "
                                  "benchmark (docs/results/eval_estimator.md).",
}
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
    "relearn.enabled": "relearn",
    "relearn.window": "relearn_window",
    "relearn.probability": "relearn_probability",
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




def changed_values(values: Mapping[str, Any], applied: Mapping[str, Any]) -> str:
    """``"name=value, ..."`` of the parameters whose value differs from ``applied`` (the values
    of the last episode start); "" if none."""
    return ", ".join(f"{name}={value!r}" for name, value in values.items()
                     if value != applied.get(name, value))


def check_parameter_set(current: Mapping[str, Any], changed: Mapping[str, Any],
                        outline: np.ndarray | None, normals: np.ndarray | None) -> str:
    """Why a parameter set is refused ("" if it is accepted); never raises.

    Parameters
    ----------
    current : mapping
        Every parameter's current value.
    changed : mapping
        The values being set (names of other nodes' parameters, e.g. ``use_sim_time``, are
        ignored).
    outline, normals : (N, 2) arrays or None
        The current outline (``object`` frame, m) and its unit normals: a set that the outline
        cannot build a filter with is refused too.
    """
    changed = {name: value for name, value in changed.items() if name in _PARAMETER_NAMES}
    if not changed:
        return ""
    try:
        params = EkfNodeParams.from_values({**current, **changed})
        if outline is not None:
            try:
                PushEKF(outline, normals, params.config)
            except FILTER_ERRORS as exc:
                return f"the current outline does not build a filter with these values: {exc}"
    except (ValueError, TypeError) as exc:
        return str(exc)
    except Exception as exc:  # noqa: BLE001 - a parameter callback must not raise
        return f"{type(exc).__name__}: {exc}"[:500]
    return ""
