"""push_executor_node's parameters: the :class:`~push_ros.node.ParamSpec` table (every
parameter's default, description, bounds) and the typed, validated :class:`ExecutorParams`.

Kept beside the node module so that the node stays thin; the table is the one place the
parameter documentation is generated from (docs/INTERFACES.md and
``pushbot_bringup/config/push_executor.yaml``, by :mod:`push_ros.interfaces`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import ParameterType

from push_core.rollout import PUSHER_RADIUS
from push_executor.kinematics import DEFAULT_ACCELERATION, DEFAULT_JERK, ToolSpec
from push_executor.motion_types import PANDA_PARK, PANDA_READY, PANDA_SIM_BASE_POSE, MotionConfig
from push_executor.state_check import StateCheckConfig
from push_ros.node import ParamSpec

__all__ = ["NODE_NAME", "PARAMETERS", "YAML_HEADER", "ExecutorParams"]

_STRINGS = ParameterType.PARAMETER_STRING_ARRAY
#: The motion's defaults (one place: MotionConfig's).
_M = MotionConfig()

PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("world_frame", "world", "Frame of planner/push, pusher/executed and "
              "executor/path.", read_only=True),
    ParamSpec("controller_topic", "/joint_trajectory_controller/joint_trajectory",
              "JointTrajectory command topic of the arm's controller.", read_only=True),
    ParamSpec("robot_description_file", "", "URDF file of the arm; empty: subscribe "
              "/robot_description (std_msgs/String, transient local).", read_only=True),
    ParamSpec("base_frame", "panda_link0", "URDF link of the arm's base.", read_only=True),
    ParamSpec("base_pose", list(PANDA_SIM_BASE_POSE), "Pose of base_frame in world: x, y, z "
              "(m), yaw (rad); the default is the simulated Panda's (on a 0.15 m pedestal).",
              read_only=True),
    ParamSpec("tool.flange_link", "panda_link8", "URDF link carrying the pusher rod (along its "
              "+z axis).", read_only=True),
    ParamSpec("tool.flange_offset", 0.0, "Flange origin to the rod's upper end along the "
              "flange z axis, m.", (-1.0, 1.0), read_only=True),
    ParamSpec("tool.length", 0.20, "Rod length, m; the tool tip is its lower end on its axis.",
              (1e-3, 2.0), read_only=True),
    ParamSpec("tool.radius", PUSHER_RADIUS, "Rod radius, m (should equal the planner's "
              "pusher_radius).", (0.0, 0.2), read_only=True),
    ParamSpec("joints", None, "Joints commanded, in this order; unset: the chain's joints "
              "base_frame -> tool.flange_link (the set must equal the chain's).",
              read_only=True, type=_STRINGS),
    ParamSpec("approach_height", _M.approach_height, "Tip height of the transit (the lift "
              "ends 2.5 cm higher, the lowest of the clear poses), m above the table; above the "
              "tallest object.", (0.0, 2.0), read_only=True),
    ParamSpec("push_height", _M.push_height, "Tip height while pushing, m above the table.",
              (0.0, 1.0), read_only=True),
    ParamSpec("push_speed", _M.push_speed, "Tip speed along the push line, m/s.", (1e-4, 1.0),
              read_only=True),
    ParamSpec("cartesian_speed", _M.cartesian_speed, "Tip speed of descend, retreat and "
              "lift (and of the blends from the transit into the descend and from the lift on), "
              "m/s.", (1e-4, 1.0), read_only=True),
    ParamSpec("cartesian_acceleration", _M.cartesian_acceleration, "Tip acceleration limit "
              "of the Cartesian speed profiles, m/s^2.", (1e-3, 10.0), read_only=True),
    ParamSpec("cartesian_jerk", _M.cartesian_jerk, "Tip jerk limit of the Cartesian speed "
              "profiles, m/s^3.", (1e-2, 1000.0), read_only=True),
    ParamSpec("retreat", _M.retreat, "Distance moved back along the push line after the push, m.",
              (0.0, 0.5), read_only=True),
    ParamSpec("park_positions", list(PANDA_PARK), "Park posture (chain order), rad; the "
              "default folds a Panda back over its base, out of the camera's view.",
              read_only=True),
    ParamSpec("reference_positions", list(PANDA_READY), "Posture the inverse kinematics' "
              "redundancy is pulled toward (chain order), rad.", read_only=True),
    ParamSpec("workspace.x_min", -0.25, "Workspace rectangle in world: every push point and "
              "every tip position of the low stages inside, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.x_max", 0.25, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.y_min", -0.3, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("workspace.y_max", 0.3, "See workspace.x_min, m.", (-10.0, 10.0), read_only=True),
    ParamSpec("min_tool_height", _M.min_tool_height, "Lowest tip height anywhere, m above "
              "the table.", (0.0, 1.0), read_only=True),
    ParamSpec("limit_margin", _M.limit_margin, "Margin inside the URDF joint position limits, rad.",
              (0.0, 1.0), read_only=True),
    ParamSpec("speed_margin", _M.speed_margin, "Fraction of the joint velocity, acceleration "
              "and jerk limits a trajectory may use.", (0.01, 1.0), read_only=True),
    ParamSpec("acceleration_limits", [DEFAULT_ACCELERATION], "Joint acceleration limits, "
              "rad/s^2: one value for every joint or one per chain joint (the default: the "
              "Panda's lowest).", read_only=True),
    ParamSpec("jerk_limits", [DEFAULT_JERK], "Joint jerk limits, rad/s^3: one value for every "
              "joint or one per chain joint.", read_only=True),
    ParamSpec("min_manipulability", _M.min_manipulability, "Smallest manipulability of the "
              "tip task Jacobian on the Cartesian stages (singularity distance).", (0.0, 10.0),
              read_only=True),
    ParamSpec("ik_tolerance", _M.ik_tolerance, "Largest inverse kinematics residual, m and rad.",
              (1e-9, 0.01), read_only=True),
    ParamSpec("waypoint_period", _M.waypoint_period, "Longest time between two trajectory "
              "points, s.", (1e-3, 1.0), read_only=True),
    ParamSpec("max_push_length", _M.max_push_length, "Longest approach -> end distance, m.",
              (1e-3, 2.0), read_only=True),
    ParamSpec("tracking_tolerance", 0.05, "Largest joint deviation from the plan while moving "
              "before the arm is stopped, rad.", (1e-4, 3.0), read_only=True),
    ParamSpec("start_delay", 0.05, "The trajectory's header stamp is the node's clock plus "
              "this: the controller holds the arm until then, so the motion starts when the "
              "tracking expects it whatever the delivery latency (below this), s.",
              (0.0, 5.0), read_only=True),
    ParamSpec("tracking_window", 0.3, "Plan time either side of a joint state's time the "
              "tracking check may match (controller start delay and joint-state latency), s.",
              (0.0, 10.0), read_only=True),
    ParamSpec("state_timeout", 1.0, "Stop when no joint state arrives, or (once moving) their "
              "stamps stop advancing, for this long, s of the steady clock.", (0.05, 60.0),
              read_only=True),
    ParamSpec("start_timeout", 5.0, "Stop when the motion has not started this long after the "
              "trajectory was sent, s of the controller's time (the joint-state stamps), or "
              "when the stamps stand still this long (steady clock).", (0.1, 600.0),
              read_only=True),
    ParamSpec("state_margin", 0.05, "A measured joint outside its URDF position limits by "
              "more than this refuses every push (kind state) until the joint state is "
              "plausible again, rad (m for prismatic joints).", (0.0, 1.0), read_only=True),
    ParamSpec("max_state_age", 2.0, "A push is refused (kind state) when the newest joint "
              "state is stamped more than this before the node's clock, s.", (0.01, 3600.0),
              read_only=True),
    ParamSpec("max_trajectory_duration", 120.0, "Longest trajectory the executor sends; a "
              "longer plan, or a posture from which a joint-space stage could take longer, is "
              "refused before anything is published, s.", (1.0, 3600.0), read_only=True),
    ParamSpec("max_trajectory_points", 20000, "Most points of a trajectory the executor "
              "sends; a plan with more is refused.", (2, 1_000_000), read_only=True),
    ParamSpec("max_future_stamp", 10.0, "Joint states stamped more than this ahead of the "
              "node's clock are refused, s.", (0.0, 3600.0), read_only=True),
    ParamSpec("start_enabled", False, "Start enabled (moving the arm); false: dry run until "
              "~/enable.", read_only=True),
    ParamSpec("clear.enabled", True, "End each push at a clear pose near the work, out of the "
              "object's silhouette in the camera image (false: park after every push).",
              read_only=True),
    ParamSpec("clear.margin", 0.02, "Growth of the object's region (where it may lie after "
              "the push) before its silhouette is taken, m.", (0.0, 0.5), read_only=True),
    ParamSpec("clear.turn", 0.35, "Largest rotation of the object during a push either way "
              "the region allows for, rad.", (0.0, 3.2), read_only=True),
    ParamSpec("clear.object_height", 0.03, "Height of the object's region above the table "
              "(its silhouette is the image of that prism), m.", (0.0, 1.0), read_only=True),
    ParamSpec("clear.distance", 0.05, "Distance of the outer ring of candidate clear poses "
              "beyond the region's radius (the inner ring: half of it), m.", (0.0, 1.0),
              read_only=True),
    ParamSpec("clear.rise", 0.1, "Height of the upper ring of candidate clear poses above "
              "approach_height, m.", (0.0, 1.0), read_only=True),
    ParamSpec("clear.scale", 0.25, "Image resolution of the silhouette check, a fraction of "
              "the camera's.", (0.05, 1.0), read_only=True),
)


@dataclass(frozen=True)
class ExecutorParams:
    """The node's parameters, typed and validated (:data:`PARAMETERS`)."""

    values: dict[str, Any]
    tool: ToolSpec
    motion: MotionConfig
    checks: StateCheckConfig
    #: The ``clear.*`` parameters without the prefix.
    clear: dict[str, Any]

    @classmethod
    def from_values(cls, v: dict[str, Any]) -> ExecutorParams:
        """Build from ``{name: value}``; ``ValueError`` naming the parameter."""
        try:
            tool = ToolSpec(str(v["tool.flange_link"]), float(v["tool.flange_offset"]),
                            float(v["tool.length"]), float(v["tool.radius"]))
            names = ("approach_height", "push_height", "push_speed", "cartesian_speed",
                     "cartesian_acceleration", "cartesian_jerk", "retreat", "min_tool_height",
                     "limit_margin", "speed_margin", "min_manipulability", "waypoint_period",
                     "max_push_length", "ik_tolerance")
            motion = MotionConfig(
                **{n: float(v[n]) for n in names},
                park_positions=tuple(float(x) for x in v["park_positions"]),
                reference_positions=tuple(float(x) for x in v["reference_positions"]),
                workspace=tuple(float(v[f"workspace.{k}"]) for k in ("x_min", "x_max", "y_min",
                                                                     "y_max")))
            checks = StateCheckConfig(
                state_margin=float(v["state_margin"]), state_timeout=float(v["state_timeout"]),
                max_state_age=float(v["max_state_age"]),
                max_duration=float(v["max_trajectory_duration"]),
                max_points=int(v["max_trajectory_points"]))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"parameter {exc}") from None
        if len(v["base_pose"]) != 4 or not all(math.isfinite(x) for x in v["base_pose"]):
            raise ValueError("parameter base_pose: expected 4 finite values x, y, z, yaw")
        for name in ("tracking_tolerance", "state_timeout", "start_timeout"):
            if not v[name] > 0:
                raise ValueError(f"parameter {name}: must be > 0")
        clear = {k.removeprefix("clear."): v[k] for k in v if k.startswith("clear.")}
        return cls(values=dict(v), tool=tool, motion=motion, checks=checks, clear=clear)


#: The node's name: the top-level key of its parameter file.
NODE_NAME = "push_executor_node"
#: Comment at the top of the bundled parameter file (pushbot_bringup/config/push_executor.yaml).
YAML_HEADER = """
Parameters of push_executor_node (package push_executor): planner/push -> a joint trajectory of
a ros2_control arm (docs/ROBOT.md, docs/design/arm.md; the table is also in
docs/INTERFACES.md). The defaults describe the simulated Panda; on your arm set at least
controller_topic, base_frame, base_pose, tool.*, park_positions, the limits and the workspace
(docs/ROBOT.md).
The launch file sets use_sim_time and start_enabled (true in simulation, false on a robot: a dry run
until
~/enable)."""
