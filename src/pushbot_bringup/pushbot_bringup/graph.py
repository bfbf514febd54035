"""Which nodes ``pushbot.launch.py`` starts, with which parameters and remappings.

ROS-free and ``launch``-free (``launch`` and ``launch_ros`` are not on PyPI), so the decision is
a plain function, :func:`graph_nodes`, that the launch file turns into ``launch_ros`` ``Node``
actions one to one and that the tests call directly.

``sim`` true (the default): ``sim_bridge_node`` runs the pybullet world and publishes
``/clock``; every other node gets ``use_sim_time: true``, the bridge itself ``false`` (it is
the clock source). ``object`` goes to the bridge's ``object`` parameter.

``robot`` says what executes the planner's pushes: ``pusher`` (the simulator's free-floating
finger, only with ``sim``) or ``arm`` (``push_executor_node`` turns each push into a joint
trajectory of a ros2_control arm; with ``sim`` the bridge simulates a Franka Panda behind that
interface, ``robot: arm``, and the executor starts enabled; without ``sim`` the executor starts
disabled, a dry run, until ``~/enable``; ``segmentation_node`` gets ``robot_filter.enabled``,
so the arm's own pixels are never taken for the object). The default is ``pusher`` in
simulation and ``arm`` on a robot (docs/ROBOT.md).

``sim`` false (a real robot): no ``sim_bridge_node``, ``use_sim_time: false`` for every node,
and perception's camera inputs are remapped to the topics of the Intel RealSense ROS 2 wrapper
(``realsense2_camera``, ``ros2 launch realsense2_camera rs_launch.py align_depth.enable:=true``):
its topics are ``/<camera_namespace>/<camera_name>/<stream>/...`` with both defaults
``camera`` (realsense-ros README, ros2-development branch, the ``camera_namespace`` and
``camera_name`` parameters; "Apply camera name in topics",
https://github.com/IntelRealSense/realsense-ros/issues/2866 and its pull request 2857). Its
aligned depth is ``16UC1`` millimetres, which ``push_perception`` decodes.
``push_executor_node`` takes ``planner/push`` and publishes ``pusher/executed`` in place of the
bridge; the camera extrinsics (``camera/color/extrinsics``, or tf where available) come from
the robot's calibration.

Parameter files: ``<config_dir>/<package>.yaml`` when it exists, else the file of the same
name in the default directory (``share/pushbot_bringup/config`` once installed,
``src/pushbot_bringup/config`` in the source tree). The explicit ``use_sim_time`` (and
``object``) come after the file, so they win over it.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "CLOCK_SOURCE",
    "unused_parameter_files",
    "DEFAULT_CONFIG_DIR",
    "EXECUTOR",
    "PIPELINE",
    "ROBOTS",
    "REALSENSE_TOPICS",
    "SIMULATOR",
    "NodeLaunch",
    "dds_environment",
    "graph_nodes",
    "parameter_file",
    "parse_bool",
]

#: (package, executable) of the simulator: the only node that publishes /clock.
SIMULATOR = ("sim_bridge", "sim_bridge_node")
CLOCK_SOURCE = SIMULATOR[0]
#: (package, executable) of the arm's push executor (``robot`` arm).
EXECUTOR = ("push_executor", "push_executor_node")
#: What executes the pushes: the simulator's finger or an arm through push_executor_node.
ROBOTS = ("pusher", "arm")
#: (package, executable) of the nodes that run in simulation and on the robot alike.
PIPELINE = (
    ("push_perception", "segmentation_node"),
    ("push_estimator", "ekf_node"),
    ("push_planner", "planner_node"),
)
#: segmentation_node's camera inputs -> the realsense2_camera defaults (sim:=false).
REALSENSE_TOPICS = (
    ("camera/color/image_raw", "/camera/camera/color/image_raw"),
    ("camera/aligned_depth_to_color/image_raw",
     "/camera/camera/aligned_depth_to_color/image_raw"),
    ("camera/color/camera_info", "/camera/camera/color/camera_info"),
)
#: The camera node's package: perception is the node that reads the camera.
CAMERA_CONSUMER = "push_perception"
#: ``<this package>/config``: next to ``launch/`` both in the source tree and installed (the
#: launch file passes its own ``../config``; this is the source-tree fallback).
DEFAULT_CONFIG_DIR = str(Path(__file__).resolve().parents[1] / "config")


@dataclass(frozen=True)
class NodeLaunch:
    """One node of the graph, as ``launch_ros.actions.Node`` takes it.

    Attributes
    ----------
    package, executable : str
        ``ros2 run <package> <executable>``; the node keeps its executable's name.
    parameters : tuple
        Parameter file paths and dicts, in order (later entries win).
    remappings : tuple of (str, str)
        ``(from, to)`` topic remappings.
    """

    package: str
    executable: str
    parameters: tuple[str | dict[str, object], ...] = ()
    remappings: tuple[tuple[str, str], ...] = ()

    @property
    def name(self) -> str:
        """Node name: the executable's (the YAMLs are keyed by it)."""
        return self.executable


def parse_bool(name: str, text: str | bool) -> bool:
    """A launch argument ``true``/``false`` (any case, also ``1``/``0``) as a bool.

    Raises
    ------
    ValueError
        Anything else, naming the argument.
    """
    if isinstance(text, bool):
        return text
    value = str(text).strip().lower()
    if value in ("true", "1"):
        return True
    if value in ("false", "0"):
        return False
    raise ValueError(f"launch argument {name}: expected true or false, got {text!r}")


def parameter_file(package: str, config_dir: str | os.PathLike[str] | None,
                   default_dir: str | os.PathLike[str] = DEFAULT_CONFIG_DIR) -> str | None:
    """``<config_dir>/<package>.yaml`` if it exists, else ``<default_dir>/<package>.yaml``,
    else None (the node runs on its declared defaults)."""
    for directory in (config_dir, default_dir):
        if directory:
            candidate = Path(directory) / f"{package}.yaml"
            if candidate.is_file():
                return os.path.normpath(candidate)
    return None


def unused_parameter_files(config_dir: str | os.PathLike[str],
                           launches: list[NodeLaunch]) -> list[str]:
    """The YAML files of ``config_dir`` that no node of ``launches`` reads (a parameter file
    is read only as ``<package>.yaml``), sorted by name: a user's ``my_planner.yaml`` there is
    otherwise ignored without a word."""
    packages = {launch.package for launch in launches}
    return sorted(f.name for f in Path(config_dir).iterdir()
                  if f.suffix in (".yaml", ".yml") and f.is_file()
                  and not (f.suffix == ".yaml" and f.stem in packages))


def graph_nodes(sim: bool, object_name: str = "", config_dir: str | None = None,
                default_config_dir: str = DEFAULT_CONFIG_DIR, robot: str = ""
                ) -> list[NodeLaunch]:
    """The nodes to start, with their parameters and remappings.

    Parameters
    ----------
    sim : bool
        True: the simulator and simulated time; False: a real robot with a RealSense camera.
    object_name : str
        Object library name or spec path for the simulator ("" = its parameter file's).
    config_dir : str, optional
        Directory of override parameter files ``<package>.yaml``.
    default_config_dir : str
        Where the bundled parameter files are.
    robot : str
        ``pusher``, ``arm`` or ``""`` (``pusher`` with ``sim``, ``arm`` without).

    Returns
    -------
    list of NodeLaunch
        The simulator first (when ``sim``), then perception, estimator, planner, then the
        executor (``robot`` arm).

    Raises
    ------
    ValueError
        ``object_name`` given with ``sim`` false (there is no simulator to take it), an unknown
        ``robot``, or ``pusher`` without ``sim`` (the finger exists only in the simulator).
    """
    robot = robot or ("pusher" if sim else "arm")
    if robot not in ROBOTS:
        raise ValueError(f"launch argument robot:={robot}: expected one of {', '.join(ROBOTS)}")
    if robot == "pusher" and not sim:
        raise ValueError("launch argument robot:=pusher needs sim:=true (the free pusher exists "
                         "only in the simulator; a robot pushes with robot:=arm)")
    if object_name and not sim:
        raise ValueError(f"launch argument object:={object_name} needs sim:=true (the object "
                         "is a simulator parameter; on the robot it is whatever is on the table)")
    nodes = []
    executors = (EXECUTOR,) if robot == "arm" else ()
    for package, executable in ((SIMULATOR,) if sim else ()) + PIPELINE + executors:
        parameters: list[str | dict[str, object]] = []
        path = parameter_file(package, config_dir, default_config_dir)
        if path is not None:
            parameters.append(path)
        overrides: dict[str, object] = {"use_sim_time": sim and package != CLOCK_SOURCE}
        if package == CLOCK_SOURCE and object_name:
            overrides["object"] = object_name
        if package == CLOCK_SOURCE:
            overrides["robot"] = robot
            if robot == "arm":  # the simulated arm moves in real time, as a real one
                overrides["arm.real_time_factor"] = 1.0
        if package == EXECUTOR[0]:
            overrides["start_enabled"] = sim  # a robot starts as a dry run until ~/enable
        if package == CAMERA_CONSUMER and robot == "arm":  # the arm may be in the view
            overrides["robot_filter.enabled"] = True
        parameters.append(overrides)
        remappings = REALSENSE_TOPICS if (not sim and package == CAMERA_CONSUMER) else ()
        nodes.append(NodeLaunch(package, executable, tuple(parameters), remappings))
    return nodes


def dds_environment(environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The DDS variables every node gets: :func:`push_ros.dds.dds_environment`, the one rule
    for the launch file, ``pushbot`` and every node's ``main()`` (docs/design/dds.md);
    ``push_ros`` is installed wherever a node is, so a robot install without
    ``pushbot`` gets the same profile. {} when the environment already names a profile.
    """
    from push_ros.dds import dds_environment as rule

    return rule(environ)
