"""Launch the pushbot node graph: in simulation, or on a real robot with a RealSense camera.

For a full ROS 2 Jazzy install (``launch`` and ``launch_ros`` are not on PyPI, so the pip
install cannot run this file; there, start the nodes with ``pushbot run <node>``):

    cd ros_ws && colcon build && source install/setup.bash
    ros2 launch pushbot_bringup pushbot.launch.py                      # simulation, butter
    ros2 launch pushbot_bringup pushbot.launch.py sim:=true object:=rect1
    ros2 launch pushbot_bringup pushbot.launch.py robot:=arm           # simulated Panda arm
    ros2 launch pushbot_bringup pushbot.launch.py sim:=false           # an arm + realsense2_camera
    ros2 launch pushbot_bringup pushbot.launch.py config_dir:=/path/to/my/config

Arguments:

- ``sim`` (default ``true``): start ``sim_bridge_node`` and run every other node on its
  ``/clock`` (``use_sim_time: true``; the bridge, the clock source, ``false``). ``false``: no
  simulator, ``use_sim_time: false`` everywhere, and segmentation_node reads the RealSense ROS 2
  wrapper's default topics (``/camera/camera/color/image_raw``,
  ``/camera/camera/aligned_depth_to_color/image_raw``, ``/camera/camera/color/camera_info``).
- ``object`` (default ``""``: the bridge's parameter file): object library name or spec file
  for the simulator; only with ``sim:=true``.
- ``robot`` (default ``""``: ``pusher`` with ``sim:=true``, ``arm`` with ``sim:=false``): what
  executes the planner's pushes. ``pusher``: the simulator's free finger. ``arm``:
  ``push_executor_node`` sends each push as a joint trajectory to a ros2_control arm's
  ``joint_trajectory_controller`` (with ``sim:=true`` the simulated Panda, enabled; with
  ``sim:=false`` your arm, starting as a dry run until ``~/enable``; docs/ROBOT.md).
- ``config_dir`` (default: this package's ``config``): a directory whose ``<package>.yaml``
  files replace the bundled ones (packages without a file there keep the bundled one).

Which nodes, parameters and remappings is decided by :func:`pushbot_bringup.graph.graph_nodes`
(a plain function, tested without ``launch``); this file only turns its answer into ``Node``
actions. Every node also gets the project's DDS environment
(:func:`pushbot_bringup.graph.dds_environment`, the same rule as ``pushbot``): the Fast DDS
profile (``FASTRTPS_DEFAULT_PROFILES_FILE`` unless already set), without which most 640 x 480
camera images never reach segmentation_node in another process, and which binds UDP to
127.0.0.1 only, with ``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT`` unless a range is set: a
closed graph. ``PUSHBOT_DDS_NETWORK=1`` (or ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``) in the
environment of ``ros2 launch`` opens it to the network, without DDS-Security (README,
"Security"; docs/design/dds.md). Under SROS2 Enforce each ``Node`` would also
need ``ros_arguments=['--enclave', '/pushbot/<executable>']`` (not passed today).
"""

from __future__ import annotations

import os
import sys

from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

try:
    from pushbot_bringup.graph import dds_environment, graph_nodes, parse_bool
except ImportError:  # started from the source tree without a build: the package is next door
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    from pushbot_bringup.graph import dds_environment, graph_nodes, parse_bool

#: Installed: share/pushbot_bringup/config; source tree: src/pushbot_bringup/config.
DEFAULT_CONFIG_DIR = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "config"))


def _nodes(context: LaunchContext, *args: object, **kwargs: object) -> list[Node]:
    """The Node actions of :func:`graph_nodes`, once the launch arguments are known."""
    sim = parse_bool("sim", LaunchConfiguration("sim").perform(context))
    nodes = graph_nodes(
        sim,
        object_name=LaunchConfiguration("object").perform(context),
        config_dir=LaunchConfiguration("config_dir").perform(context) or None,
        default_config_dir=DEFAULT_CONFIG_DIR,
        robot=LaunchConfiguration("robot").perform(context),
    )
    env = dds_environment()
    return [
        Node(
            package=node.package,
            executable=node.executable,
            name=node.name,
            output="screen",
            emulate_tty=True,
            parameters=list(node.parameters),
            remappings=list(node.remappings),
            additional_env=env,
        )
        for node in nodes
    ]


def generate_launch_description() -> LaunchDescription:
    """The pushbot graph: [sim_bridge,] perception, estimator, planner [, push executor]."""
    return LaunchDescription([
        DeclareLaunchArgument(
            "sim", default_value="true",
            description="true: start sim_bridge_node and use its /clock; false: a real robot "
                        "(no simulator, wall time, RealSense topics)"),
        DeclareLaunchArgument(
            "object", default_value="",
            description="object library name or spec file for the simulator (sim:=true); "
                        "empty = the one in sim_bridge.yaml"),
        DeclareLaunchArgument(
            "robot", default_value="",
            description="pusher (the simulated finger) or arm (push_executor_node and a "
                        "ros2_control arm; simulated with sim:=true); empty = pusher with "
                        "sim:=true, arm with sim:=false"),
        DeclareLaunchArgument(
            "config_dir", default_value=DEFAULT_CONFIG_DIR,
            description="directory holding <package>.yaml parameter files that replace the "
                        "bundled ones"),
        OpaqueFunction(function=_nodes),
    ])
