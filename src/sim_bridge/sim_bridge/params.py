"""The parameters of ``sim_bridge_node``: declarations, the typed set and its checks.

ROS-free apart from the :class:`push_ros.node.ParamSpec` table (declared by the node with
:func:`push_ros.node.declare_config`); docs/INTERFACES.md and
``pushbot_bringup/config/sim_bridge.yaml`` are generated from it (:mod:`push_ros.interfaces`).
"""

from __future__ import annotations

import functools
import math
import os
import stat
from dataclasses import dataclass
from typing import Any

import numpy as np

from push_core.geometry import quaternion_from_matrix
from push_core.objects import library_names, load_object
from push_ros.node import ParamSpec
from sim_bridge.arm_robot import DEFAULT_BASE_POSE, DEFAULT_PARK
from sim_bridge.camera import look_at_pose
from sim_bridge.camera_profiles import profile
from sim_bridge.config import SUPPORT_CELL_RANGE
from sim_bridge.faults import FaultConfig
from sim_bridge.world import CameraConfig, MonitorConfig, WorldConfig

__all__ = ["NODE_NAME", "PARAMETERS", "YAML_EXTRA", "YAML_HEADER", "YAML_NOTES", "FaultConfig",
           "SimBridgeParams", "check_object_parameter"]

#: (x, y, z, qx, qy, qz, qw) of the default viewpoint's optical frame in world.
_DEFAULT_VIEW = look_at_pose(CameraConfig())
DEFAULT_CAMERA_POSE = tuple(float(v) for v in np.concatenate(
    [_DEFAULT_VIEW[:3, 3], quaternion_from_matrix(_DEFAULT_VIEW[:3, :3])]))
#: Suffixes of the object specification files the ``object`` parameter accepts.
SPEC_SUFFIXES = (".json", ".yaml", ".yml")
#: Largest object specification file the ``object`` parameter reads, bytes (a spec is < 10 kB).
MAX_SPEC_BYTES = 1 << 20


# --------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------
_UNSET_OR_NEGATIVE = "negative = the object spec's value"
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("object", "butter", "Object library name (the MIT pushing dataset objects, e.g. "
              "butter, rect1, tri1, ellip1, hex) or a path to a .json/.yaml/.yml object "
              "specification file of at most 1 MiB (docs/design/objects.md); nothing else is "
              "read, and errors never quote the file."),
    ParamSpec("initial_pose.x", 0.0, "Initial x of the object frame (area centroid) in world, "
              "m; must lie in the workspace.", (-1.0, 1.0)),
    ParamSpec("initial_pose.y", 0.0, "Initial y of the object frame in world, m; must lie in "
              "the workspace.", (-1.0, 1.0)),
    ParamSpec("initial_pose.theta", 0.0, "Initial yaw of the object frame in world, rad.",
              (-math.pi, math.pi)),
    ParamSpec("use_com_offset", False, "Build the object with its centre of mass at "
              "com_offset; false: the object spec's COM (random from the seed with randomize)."),
    ParamSpec("com_offset", [0.0, 0.0], "Centre of mass (x, y) in the object frame, m; used "
              "only with use_com_offset true.", constraints="2 finite values"),
    ParamSpec("mass", -1.0, "Object mass, kg; > 0 to override (0 is an error).", (-1.0, 100.0),
              constraints=_UNSET_OR_NEGATIVE),
    ParamSpec("friction_table", -1.0, "Object-table Coulomb friction coefficient, >= 0 to "
              "override (spec default 0.25).",
              (-1.0, 10.0), constraints=_UNSET_OR_NEGATIVE),
    ParamSpec("friction_pusher", -1.0, "Pusher-object Coulomb friction coefficient, >= 0 to "
              "override (spec default 0.25).",
              (-1.0, 10.0), constraints=_UNSET_OR_NEGATIVE),
    ParamSpec("seed", 0, "Seed of the randomisation (physics and appearance).", (0, 2**31 - 1)),
    ParamSpec("randomize", False, "Randomise mass, COM and frictions from the seed."),
    ParamSpec("image_width", 640, "Camera image width, px (D415-like colour stream, depth "
              "aligned to colour; the focal length scales with the size).", (32, 1920)),
    ParamSpec("image_height", 480, "Camera image height, px.", (24, 1080)),
    ParamSpec("camera.profile", "default", "How the camera publishes: default (640 x 480, "
              "rgb8, 32FC1 m, ideal pinhole, aligned depth), d415, d435, orbbec or zed (the "
              "driver's resolution, encodings, distortion and depth noise; orbbec publishes "
              "depth in its own frame on camera/depth/image_raw with camera/depth/camera_info). "
              "A profile other than default sets the image size (image_width and image_height "
              "are ignored) and always adds its own depth noise (docs/design/cameras.md).",
              read_only=True, constraints="default, d415, d435, orbbec or zed"),
    ParamSpec("camera.use_pose", False, "Place the camera at camera.pose instead of the default "
              "viewpoint (the published extrinsics are that pose: the truth a calibration is "
              "measured against).", read_only=True),
    ParamSpec("camera.pose", list(DEFAULT_CAMERA_POSE), "The camera's optical frame in world: "
              "x, y, z (m), qx, qy, qz, qw (a unit quaternion); used only with camera.use_pose. "
              "The default is the default viewpoint's.", read_only=True,
              constraints="7 finite values, unit quaternion"),
    ParamSpec("calibration.board", False, "Arm mode: a ChArUco calibration board on the tool, "
              "for pushbot calibrate (sim_bridge.calibration_board, "
              "docs/design/calibration.md).", read_only=True),
    ParamSpec("depth_noise", False, "Add D415-like depth noise, quantisation and dropouts "
              "(NaN)."),
    ParamSpec("randomize_appearance", False, "Randomise lighting, table and object colours "
              "from the seed."),
    ParamSpec("appearance.look", "default", "default (the training appearance; random with "
              "randomize_appearance) or site: a look the segmentation network never saw, drawn "
              "from the seed (textured table, metallic or camouflaged object, coloured light, "
              "strong shadows; docs/design/site-adaptation.md).",
              constraints="default or site"),
    ParamSpec("randomize_camera", False, "Jitter the camera pose from the seed (the published "
              "extrinsics are the true, jittered pose)."),
    ParamSpec("idle_frame_rate", 2.0, "Rate of camera frames while the world rests, Hz (wall "
              "time): still frames (fresh sensor noise) of the resting scene with its object "
              "pose, at the current time (the clock runs while the world rests), as a streaming "
              "camera.", (0.1, 30.0), read_only=True),
    ParamSpec("clock_rate", 50.0, "Rate of /clock messages while the physics runs, Hz (wall "
              "time): during a push and its settling.", (1.0, 1000.0), read_only=True),
    ParamSpec("idle_clock_rate", 10.0, "Rate of /clock messages while the world rests, Hz "
              "(wall time; time still passes as wall time does): every node on sim time "
              "handles each message, so a resting graph costs less CPU at a lower rate.",
              (1.0, 1000.0), read_only=True),
    ParamSpec("push_speed", 0.02, "Pusher speed along the push, m/s (the planner's push_speed "
              "should be equal).", (0.001, 0.2)),
    ParamSpec("pusher_radius", 0.0048, "Radius of the cylindrical pusher, m.", (0.001, 0.05)),
    ParamSpec("support_cell", 0.0, "0: the object's convex collision pieces rest on 3-4 of "
              "their corners (bullet's contact manifold); > 0 "
              f"({1e3 * SUPPORT_CELL_RANGE[0]:g}-{1e3 * SUPPORT_CELL_RANGE[1]:g} mm): the "
              "pieces are cut into grid cells of this size, m, so the table supports the whole "
              "footprint (sim_bridge.scene.support_cells).", (0.0, SUPPORT_CELL_RANGE[1])),
    ParamSpec("faults.frame_drop", 0.0, "Fault injection: probability that a camera frame "
              "publication (colour, depth, camera_info together) is dropped.", (0.0, 0.9)),
    ParamSpec("faults.frame_delay", 0.0, "Fault injection: probability that a camera frame "
              "publication is held back and published right after the next newer frame "
              "(delayed and reordered).", (0.0, 0.9)),
    ParamSpec("faults.push_refusal", 0.0, "Fault injection: probability that a valid push is "
              "refused (as a robot refuses a command).", (0.0, 1.0)),
    ParamSpec("faults.seed", 0, "Seed of the fault injection draws (re-seeded on ~/reset).",
              (0, 2**31 - 1)),
    ParamSpec("monitor.rate", 0.0, "Monitor stream (sim/monitor/*): frames per second of sim "
              "time rendered while a push executes (rounded to whole 1/240 s physics steps); "
              "0 = off. pushbot demo uses 10 Hz.", (0.0, 60.0)),
    ParamSpec("monitor.width", 320, "Monitor image width, px.", (32, 1920)),
    ParamSpec("monitor.height", 240, "Monitor image height, px.", (24, 1080)),
    ParamSpec("robot", "pusher", "What pushes: 'pusher' (a free cylinder executing "
              "planner/push) or 'arm' (a Franka Panda with the pusher rod following joint "
              "trajectories on arm.controller_topic with the Jazzy joint_trajectory_controller's "
              "acceptance rules; it publishes /joint_states, /robot_description and "
              "sim/tool_tip and ignores planner/push).", read_only=True,
              constraints="pusher or arm"),
    ParamSpec("arm.base_pose", list(DEFAULT_BASE_POSE), "Arm mode: x, y, z (m) and yaw (rad) "
              "of the arm's base panda_link0 in world, read on start-up and ~/reset; on a "
              "0.15 m pedestal the whole workspace is reachable with the rod vertical "
              "(bench_arm_reach).", constraints="4 finite values"),
    ParamSpec("arm.park_positions", list(DEFAULT_PARK), "Arm mode: the 7 joint positions "
              "after a reset (out of the camera's view), rad.", constraints="7 finite values"),
    ParamSpec("arm.controller_topic", "/joint_trajectory_controller/joint_trajectory",
              "Arm mode: the trajectory_msgs/JointTrajectory command topic.", read_only=True),
    ParamSpec("arm.joint_state_rate", 100.0, "Arm mode: /joint_states rate while a "
              "trajectory runs, Hz of sim time.", (1.0, 240.0), read_only=True),
    ParamSpec("arm.max_duration", 600.0, "Arm mode: longest accepted trajectory (from now to "
              "its end), s of sim time.", (1.0, 3600.0), read_only=True),
    ParamSpec("arm.real_time_factor", 0.0, "Arm mode: sim time runs at most this many times "
              "faster than wall time while the arm moves (1 = like a real robot, for timing "
              "the executor's reactions); 0 = as fast as the CPU allows. The launch file "
              "(robot:=arm) sets 1; evaluations use 5.", (0.0, 1000.0)),
)

#: The node's name: the top-level key of its parameter file.
NODE_NAME = "sim_bridge_node"
#: Written before the table in the parameter file (ROS declares it): the bridge is the clock.
YAML_EXTRA = (ParamSpec("use_sim_time", False, "The bridge is the /clock source: it publishes "
                        "simulated time and must not wait for it. Keep false (its timers use "
                        "the steady clock anyway; true only earns a warning)."),)
#: Comment at the top of the bundled parameter file (pushbot_bringup/config/sim_bridge.yaml).
YAML_HEADER = """
Parameters of sim_bridge_node (package sim_bridge): the pybullet table, object, pusher and
RGB-D camera (the table is also in docs/INTERFACES.md). Values below are the defaults. Units SI
(REP 103): metres, radians, seconds, kg.

  pushbot run sim_bridge_node --ros-args --params-file src/pushbot_bringup/config/sim_bridge.yaml
  ros2 run sim_bridge sim_bridge_node --ros-args --params-file \\
      $(ros2 pkg prefix pushbot_bringup)/share/pushbot_bringup/config/sim_bridge.yaml
  (`ros2 launch pushbot_bringup pushbot.launch.py` loads this file, with object:=... on top)

All scene parameters are read at start-up and again by the ~/reset service
(std_srvs/srv/Trigger), so `ros2 param set` (or a test's set_parameters) followed by
~/reset rebuilds the scene with the new values. A bad value stops start-up with a clear
message and a non-zero exit (a refused reset keeps the previous scene).
Doubles must be written with a decimal point (0.0, not 0): ROS rejects an integer for a
double parameter."""
#: Comment paragraphs before a parameter in the parameter file.
YAML_NOTES = {
    "mass": "Physical overrides; a negative value (default -1.0) keeps the object spec's value.",
    "seed": "Randomisation (perception training, robustness tests); everything derives from the "
            "seed.",
    "faults.frame_drop": "Fault injection (fault scenarios, benchmarks/bench_faults.py); all off "
                         "by default, read on start-up and ~/reset, draws re-seeded from "
                         "faults.seed on every reset. A camera frame publication includes idle "
                         "re-publications; ground truth (sim/object_pose) is never dropped; a "
                         "refused push is reported on pusher/refused. The object can also be "
                         "displaced on sim/knock (docs/INTERFACES.md).",
    "monitor.rate": "Monitor stream: a visualisation of the simulator, not an input of the "
                    "pipeline (docs/INTERFACES.md, sim/monitor/*). Its cost: "
                    "docs/results/record.md.",
    "robot": "Arm mode: docs/design/arm.md.",
}


@dataclass(frozen=True)
class SimBridgeParams:
    """The node's parameters, typed; sentinels already turned into None (= spec default).

    Attributes
    ----------
    object : str
        Library name or spec-file path.
    initial_pose : tuple of 3 float
        x, y (m) and theta (rad) of the object frame in ``world``.
    com_offset : tuple of 2 float or None
        COM in the object frame, m; None = the spec's.
    mass, friction_table, friction_pusher : float or None
        kg and Coulomb coefficients; None = the spec's.
    seed : int
    randomize, depth_noise, randomize_appearance, randomize_camera : bool
    image_width, image_height : int
        px.
    camera_profile : str
        ``camera.profile`` (:mod:`sim_bridge.camera_profiles`).
    look : str
        ``appearance.look``: ``default`` or ``site`` (``WorldConfig.look``).
    idle_frame_rate, clock_rate, idle_clock_rate : float
        Hz of wall time.
    push_speed : float
        m/s.
    pusher_radius : float
        m.
    support_cell : float
        m; 0 = the collision pieces whole (``WorldConfig.support_cell``).
    faults : FaultConfig
        Fault injection (all off by default).
    monitor : MonitorConfig or None
        The monitor stream; None = off (``monitor.rate`` 0).
    robot : str
        ``pusher`` or ``arm``.
    arm_base_pose, arm_park : tuple of float
        Arm mode: base (x, y, z m, yaw rad) in ``world``; 7 park joint positions, rad.
    arm_controller_topic : str
    arm_joint_state_rate : float
        Hz of sim time.
    arm_max_duration : float
        s of sim time.
    arm_real_time_factor : float
        Largest sim time / wall time ratio while the arm moves; 0 = unpaced.
    camera_pose : tuple of 7 float or None
        ``camera.pose`` when ``camera.use_pose``, else None (the default viewpoint).
    calibration_board : bool
        ``calibration.board``.
    """

    object: str
    initial_pose: tuple[float, float, float]
    com_offset: tuple[float, float] | None
    mass: float | None
    friction_table: float | None
    friction_pusher: float | None
    seed: int
    randomize: bool
    image_width: int
    image_height: int
    depth_noise: bool
    randomize_appearance: bool
    randomize_camera: bool
    idle_frame_rate: float
    clock_rate: float
    idle_clock_rate: float
    push_speed: float
    pusher_radius: float
    support_cell: float = 0.0
    camera_profile: str = "default"
    look: str = "default"
    faults: FaultConfig = FaultConfig()
    monitor: MonitorConfig | None = None
    robot: str = "pusher"
    arm_base_pose: tuple[float, ...] = DEFAULT_BASE_POSE
    arm_park: tuple[float, ...] = DEFAULT_PARK
    arm_controller_topic: str = "/joint_trajectory_controller/joint_trajectory"
    arm_joint_state_rate: float = 100.0
    arm_max_duration: float = 600.0
    arm_real_time_factor: float = 0.0
    camera_pose: tuple[float, ...] | None = None
    calibration_board: bool = False

    @classmethod
    def from_values(cls, values: dict[str, Any]) -> SimBridgeParams:
        """Build from ``{parameter name: value}`` and check what the descriptors cannot.

        Raises
        ------
        ValueError
            Naming the parameter: an unknown object, a COM offset that is not 2 finite values,
            a zero mass.
        """
        name = str(values["object"]).strip()
        if not name:
            raise ValueError("parameter 'object' is empty; give a library name or a spec path")
        check_object_parameter(name)
        try:
            if name in library_names():
                _check_library_object(name)
            else:
                load_object(name)
        except (ValueError, OSError) as exc:  # load_object's messages never quote a file
            raise ValueError(f"parameter 'object' = {name[:200]!r}: {exc}") from None
        com_arr = np.asarray(values["com_offset"], dtype=float).reshape(-1)
        if com_arr.shape != (2,) or not np.all(np.isfinite(com_arr)):
            raise ValueError(f"parameter 'com_offset' must be 2 finite values (x, y in metres, "
                             f"object frame), got {list(com_arr)[:10]}")
        com_offset = ((float(com_arr[0]), float(com_arr[1]))
                      if values["use_com_offset"] else None)
        robot = str(values.get("robot", "pusher"))
        if robot not in ("pusher", "arm"):
            raise ValueError(f"parameter 'robot' must be 'pusher' or 'arm', got {robot[:40]!r}")
        arm = {}
        for key, size in (("arm.base_pose", 4), ("arm.park_positions", 7)):
            arr = np.asarray(values.get(key, ()), dtype=float).reshape(-1)
            if arr.shape != (size,) or not np.all(np.isfinite(arr)):
                raise ValueError(f"parameter {key!r} must be {size} finite values, got "
                                 f"{list(arr)[:10]}")
            arm[key] = tuple(float(v) for v in arr)
        if values["mass"] == 0.0:
            raise ValueError("parameter 'mass' must be > 0 kg, or negative for the spec's mass")
        return cls(
            object=name,
            initial_pose=(
                float(values["initial_pose.x"]),
                float(values["initial_pose.y"]),
                float(values["initial_pose.theta"]),
            ),
            com_offset=com_offset,
            mass=_spec_default_if_negative(values["mass"]),
            friction_table=_spec_default_if_negative(values["friction_table"]),
            friction_pusher=_spec_default_if_negative(values["friction_pusher"]),
            seed=int(values["seed"]),
            randomize=bool(values["randomize"]),
            image_width=int(values["image_width"]),
            image_height=int(values["image_height"]),
            depth_noise=bool(values["depth_noise"]),
            camera_profile=profile(str(values.get("camera.profile", "default"))).name,
            randomize_appearance=bool(values["randomize_appearance"]),
            randomize_camera=bool(values["randomize_camera"]),
            look=_look(values.get("appearance.look", "default")),
            idle_frame_rate=float(values["idle_frame_rate"]),
            clock_rate=float(values["clock_rate"]),
            idle_clock_rate=float(values["idle_clock_rate"]),
            push_speed=float(values["push_speed"]),
            pusher_radius=float(values["pusher_radius"]),
            support_cell=float(values.get("support_cell", 0.0)),
            faults=FaultConfig(frame_drop=float(values["faults.frame_drop"]),
                               frame_delay=float(values["faults.frame_delay"]),
                               push_refusal=float(values["faults.push_refusal"]),
                               seed=int(values["faults.seed"])),
            monitor=(MonitorConfig(rate=float(values["monitor.rate"]),
                                   width=int(values["monitor.width"]),
                                   height=int(values["monitor.height"]))
                     if values["monitor.rate"] > 0.0 else None),
            robot=robot,
            arm_base_pose=arm["arm.base_pose"],
            arm_park=arm["arm.park_positions"],
            arm_controller_topic=str(values.get("arm.controller_topic",
                                                cls.arm_controller_topic)),
            arm_joint_state_rate=float(values.get("arm.joint_state_rate", 100.0)),
            arm_max_duration=float(values.get("arm.max_duration", 600.0)),
            arm_real_time_factor=float(values.get("arm.real_time_factor", 0.0)),
            camera_pose=(tuple(float(v) for v in values["camera.pose"])
                         if values.get("camera.use_pose", False) else None),
            calibration_board=bool(values.get("calibration.board", False)),
        )

    def world_config(self) -> WorldConfig:
        """The :class:`~sim_bridge.world.WorldConfig` these parameters describe.

        Raises
        ------
        ValueError
            If the world rejects a value.
        """
        return WorldConfig(
            object=self.object,
            object_pose=self.initial_pose,
            com_offset=self.com_offset,
            mass=self.mass,
            friction_table=self.friction_table,
            friction_pusher=self.friction_pusher,
            randomize=self.randomize,
            seed=self.seed,
            pusher_radius=self.pusher_radius,
            support_cell=self.support_cell,
            push_speed=self.push_speed,
            camera=(CameraConfig(width=self.image_width, height=self.image_height)
                    if self.camera_profile == "default"
                    else profile(self.camera_profile).camera_config()),
            depth_noise=self.depth_noise and self.camera_profile == "default",
            randomize_appearance=self.randomize_appearance,
            randomize_camera=self.randomize_camera,
            look=self.look,
            robot=self.robot,
            arm_base_pose=self.arm_base_pose,
            arm_park=self.arm_park,
            camera_pose=self.camera_pose,
            calibration_board=self.calibration_board,
        )

    def _camera_text(self) -> str:
        if self.camera_profile == "default":
            return f"{self.image_width}x{self.image_height}"
        prof = profile(self.camera_profile)
        return f"{prof.name} profile {prof.width}x{prof.height}"

    def summary(self) -> str:
        """One line naming what these parameters build."""
        x, y, theta = self.initial_pose
        return (
            f"object {self.object!r} at (x={x:.4f} m, y={y:.4f} m, theta={theta:.4f} rad), "
            f"camera {self._camera_text()}, seed {self.seed}"
            f"{', randomized' if self.randomize else ''}"
        )


@functools.cache
def _check_library_object(name: str) -> None:
    """``load_object`` of a bundled library entry, once (up to 0.2 s each: every parameter set
    re-validates the whole table)."""
    load_object(name)


def check_object_parameter(name: str) -> None:
    """Accept a library name or a readable object specification file; nothing else.

    A file must end in ``.json``, ``.yaml`` or ``.yml``, be a regular file and hold at most
    ``MAX_SPEC_BYTES``; it is then parsed as a specification by ``load_object``, whose errors
    name the schema field and never quote the file. Raises ``ValueError`` otherwise.
    """
    if name in library_names():
        return
    shown = f"{name[:200]!r}"
    if not name.lower().endswith(SPEC_SUFFIXES):
        raise ValueError(f"parameter 'object' = {shown}: unknown object {shown}; library "
                         f"objects are {', '.join(library_names())}, or give the path of an "
                         f"object specification file ({', '.join(SPEC_SUFFIXES)})")
    try:
        info = os.stat(name)
    except (OSError, ValueError):
        raise ValueError(f"parameter 'object' = {shown}: no such object specification "
                         "file") from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"parameter 'object' = {shown}: not a regular file")
    if info.st_size > MAX_SPEC_BYTES:
        raise ValueError(f"parameter 'object' = {shown}: {info.st_size} bytes, larger than "
                         f"an object specification file may be ({MAX_SPEC_BYTES} bytes)")


def _look(value: object) -> str:
    look = str(value)
    if look not in ("default", "site"):
        raise ValueError(f"parameter 'appearance.look' must be 'default' or 'site', got "
                         f"{look[:40]!r}")
    return look


def _spec_default_if_negative(value: float) -> float | None:
    return None if value < 0.0 else float(value)
