"""Launch the pushbot node graph: sim_bridge, perception, estimator and planner.

For a full ROS 2 Jazzy install (``launch`` and ``launch_ros`` are not on PyPI, so the pip
install cannot run this file; there, start the nodes with ``pushbot run <node>``):

    cd ros_ws && colcon build && source install/setup.bash
    ros2 launch launch/pushbot.launch.py            # or: use_sim_time:=false config_dir:=...

Each node gets its commented parameter file ``<package>.yaml``, taken from ``config_dir``
(default: ``ros_ws/config`` next to this file; a package may also install it to
``share/<package>/config``, which is used when ``config_dir`` has none), and ``use_sim_time``
(default true: sim_bridge publishes ``/clock``). sim_bridge itself, the clock source, keeps
the ``use_sim_time`` of its own parameter file (false).

Every node also gets the project's Fast DDS profile (``FASTRTPS_DEFAULT_PROFILES_FILE``, unless
it is already set in the environment): 32 MB shared-memory segments and 4 MB UDP buffers, without
which most 640 x 480 camera images never reach segmentation_node in another process
(docs/ARCHITECTURE.md, "DDS profile"). It is the ``pushbot`` package's
``pushbot/data/fastdds.xml``, found through the installed package or next to this workspace.
"""

from __future__ import annotations

import os

from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

# (package, executable): the console_scripts of each package's setup.py.
NODES = (
    ('sim_bridge', 'sim_bridge_node'),
    ('push_perception', 'segmentation_node'),
    ('push_estimator', 'ekf_node'),
    ('push_planner', 'planner_node'),
)
CLOCK_SOURCE = 'sim_bridge'  # publishes /clock; keeps use_sim_time from its own file (false)
DEFAULT_CONFIG_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'config')
PROFILE_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'
SOURCE_PROFILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'src',
                              'pushbot', 'pushbot', 'data', 'fastdds.xml')


def _dds_environment() -> dict[str, str]:
    """``{FASTRTPS_DEFAULT_PROFILES_FILE: <the bundled profile>}`` unless already set."""
    if os.environ.get(PROFILE_ENV):
        return {}
    try:
        from pushbot.dds import profile_path

        path = str(profile_path())
    except ImportError:
        path = os.path.normpath(SOURCE_PROFILE)
    return {PROFILE_ENV: path} if os.path.isfile(path) else {}


def _parameter_file(package: str, config_dir: str) -> str | None:
    """``<config_dir>/<package>.yaml``, else ``share/<package>/config/<package>.yaml``."""
    candidate = os.path.join(config_dir, f'{package}.yaml')
    if os.path.isfile(candidate):
        return os.path.normpath(candidate)
    try:
        from ament_index_python.packages import get_package_share_directory

        installed = os.path.join(
            get_package_share_directory(package), 'config', f'{package}.yaml')
    except (ImportError, LookupError):
        return None
    return installed if os.path.isfile(installed) else None


def _nodes(context: LaunchContext, *args: object, **kwargs: object) -> list[Node]:
    """One Node action per entry of NODES, resolved once the launch arguments are known."""
    config_dir = LaunchConfiguration('config_dir').perform(context)
    use_sim_time = LaunchConfiguration('use_sim_time').perform(context).lower() == 'true'
    actions = []
    env = _dds_environment()
    for package, executable in NODES:
        parameters: list = []
        path = _parameter_file(package, config_dir)
        if path is not None:
            parameters.append(path)
        if package != CLOCK_SOURCE:
            parameters.append({'use_sim_time': use_sim_time})  # last wins over the file
        actions.append(Node(
            package=package,
            executable=executable,
            name=executable,
            output='screen',
            emulate_tty=True,
            parameters=parameters,
            additional_env=env,
        ))
    return actions


def generate_launch_description() -> LaunchDescription:
    """The four pushbot nodes with their parameter files (and use_sim_time but the bridge)."""
    return LaunchDescription([
        DeclareLaunchArgument(
            'use_sim_time', default_value='true',
            description='nodes other than sim_bridge use its /clock (false only with real '
                        'hardware)'),
        DeclareLaunchArgument(
            'config_dir', default_value=os.path.normpath(DEFAULT_CONFIG_DIR),
            description='directory holding <package>.yaml parameter files'),
        OpaqueFunction(function=_nodes),
    ])
