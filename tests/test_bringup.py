"""The bringup package: pushbot.launch.py and its decision function, for sim true and false.

``launch`` and ``launch_ros`` are not installable here, so the decision (which nodes, which
parameters, which remappings) is the plain function ``pushbot_bringup.graph.graph_nodes``,
tested directly, and the launch file itself is run against small stand-ins of the four
``launch`` names it uses, which record what it builds. That colcon installs the launch and
config files into share/pushbot_bringup is checked in tests/test_packaging.py.
"""

from __future__ import annotations

import ast
import importlib.util
import sys
import types
from pathlib import Path
from typing import Any

import pytest
import yaml

from push_ros.dds import PROFILE_ENV
from pushbot_bringup import graph
from pushbot_bringup.graph import NodeLaunch, graph_nodes, parameter_file, parse_bool

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"
BRINGUP = SRC / "pushbot_bringup"
LAUNCH_FILE = BRINGUP / "launch" / "pushbot.launch.py"
CONFIG_DIR = BRINGUP / "config"
REALSENSE = {
    "camera/color/image_raw": "/camera/camera/color/image_raw",
    "camera/aligned_depth_to_color/image_raw": "/camera/camera/aligned_depth_to_color/image_raw",
    "camera/color/camera_info": "/camera/camera/color/camera_info",
}


def _console_scripts() -> set[tuple[str, str]]:
    """(package, script) of every setup.py entry point under src/, read with ast."""
    found = set()
    for setup_py in SRC.glob("*/setup.py"):
        for node in ast.walk(ast.parse(setup_py.read_text())):
            if isinstance(node, ast.keyword) and node.arg == "entry_points":
                scripts = ast.literal_eval(node.value).get("console_scripts", [])
                found |= {(setup_py.parent.name, s.split("=")[0].strip()) for s in scripts}
    return found


def _overrides(node: NodeLaunch) -> dict[str, object]:
    """The merged dict parameters of a node (they come after its file)."""
    merged: dict[str, object] = {}
    for entry in node.parameters:
        if isinstance(entry, dict):
            merged.update(entry)
    return merged


def _files(node: NodeLaunch) -> list[str]:
    return [entry for entry in node.parameters if isinstance(entry, str)]


# ------------------------------------------------------------------------- the decision
def test_sim_true_starts_the_bridge_and_puts_everyone_else_on_sim_time() -> None:
    nodes = graph_nodes(True, object_name="rect1")
    assert [(n.package, n.executable) for n in nodes] == [
        ("sim_bridge", "sim_bridge_node"), ("push_perception", "segmentation_node"),
        ("push_estimator", "ekf_node"), ("push_planner", "planner_node")]
    for node in nodes:
        expected = node.package != "sim_bridge"  # the clock source does not wait for /clock
        assert _overrides(node)["use_sim_time"] is expected, node.package
        assert node.remappings == (), node.package  # the bridge publishes the default names
        assert node.name == node.executable
        # the file first, then the explicit values, which win
        assert isinstance(node.parameters[0], str) and isinstance(node.parameters[-1], dict)
    assert _overrides(nodes[0])["object"] == "rect1"
    assert _overrides(nodes[0])["robot"] == "pusher"
    assert all("object" not in _overrides(n) for n in nodes[1:])


def test_robot_arm_in_simulation_adds_the_executor_enabled_and_the_bridge_s_arm() -> None:
    nodes = graph_nodes(True, robot="arm")
    assert [n.executable for n in nodes] == ["sim_bridge_node", "segmentation_node", "ekf_node",
                                             "planner_node", "push_executor_node"]
    assert _overrides(nodes[0]) == {"use_sim_time": False, "robot": "arm",
                                    "arm.real_time_factor": 1.0}
    assert _overrides(nodes[-1]) == {"use_sim_time": True, "start_enabled": True}
    assert _overrides(nodes[1]) == {"use_sim_time": True, "robot_filter.enabled": True}


@pytest.mark.parametrize("sim, robot, match", [
    (False, "pusher", "robot:=pusher needs sim:=true"),
    (True, "gripper", "robot:=gripper: expected one of pusher, arm")])
def test_robot_argument_refusals(sim: bool, robot: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        graph_nodes(sim, robot=robot)


def test_sim_true_without_object_keeps_the_bridge_file_s_object() -> None:
    bridge = graph_nodes(True)[0]
    assert "object" not in _overrides(bridge)
    assert _files(bridge) == [str(CONFIG_DIR / "sim_bridge.yaml")]


def test_sim_false_starts_no_simulator_uses_wall_time_and_realsense_topics() -> None:
    nodes = graph_nodes(False)
    assert [n.package for n in nodes] == ["push_perception", "push_estimator", "push_planner",
                                          "push_executor"]
    assert _overrides(nodes[0]) == {"use_sim_time": False, "robot_filter.enabled": True}
    for node in nodes[1:3]:
        assert _overrides(node) == {"use_sim_time": False}, node.package
    # the arm executor: wall time, and a dry run until ~/enable
    assert _overrides(nodes[3]) == {"use_sim_time": False, "start_enabled": False}
    perception, estimator, planner, executor = nodes
    assert executor.remappings == ()
    assert dict(perception.remappings) == REALSENSE
    assert estimator.remappings == () and planner.remappings == ()


def test_sim_false_refuses_an_object() -> None:
    with pytest.raises(ValueError, match="object:=butter needs sim:=true"):
        graph_nodes(False, object_name="butter")


def test_remapped_topics_are_the_ones_perception_subscribes_to() -> None:
    source = (SRC / "push_perception" / "push_perception" / "segmentation_node.py").read_text()
    for topic in REALSENSE:
        assert f'"{topic}"' in source or f"'{topic}'" in source, topic


@pytest.mark.parametrize("sim, robot", [(True, "pusher"), (True, "arm"), (False, "arm")])
def test_only_existing_executables_and_parameter_files(sim: bool, robot: str) -> None:
    scripts = _console_scripts()
    for node in graph_nodes(sim, robot=robot):
        assert (node.package, node.executable) in scripts, node
        files = _files(node)
        assert files == [str(CONFIG_DIR / f"{node.package}.yaml")], node.package
        # the file is keyed by the node's name, so --params-file reaches it
        assert list(yaml.safe_load(Path(files[0]).read_text())) == [node.name]


def test_config_dir_overrides_per_package(tmp_path: Path) -> None:
    mine = tmp_path / "push_planner.yaml"
    mine.write_text("planner_node:\n  ros__parameters:\n    k: 3\n")
    nodes = {n.package: n for n in graph_nodes(True, config_dir=str(tmp_path))}
    assert _files(nodes["push_planner"]) == [str(mine)]
    assert _files(nodes["push_estimator"]) == [str(CONFIG_DIR / "push_estimator.yaml")]
    assert parameter_file("no_such_package", str(tmp_path)) is None


@pytest.mark.parametrize("text, value", [("true", True), ("True", True), ("1", True),
                                         ("false", False), ("FALSE", False), ("0", False)])
def test_parse_bool(text: str, value: bool) -> None:
    assert parse_bool("sim", text) is value


def test_parse_bool_refuses_anything_else() -> None:
    with pytest.raises(ValueError, match="launch argument sim: expected true or false, got 'yes'"):
        parse_bool("sim", "yes")


def test_dds_profile_unless_the_environment_names_one() -> None:
    assert graph.dds_environment({PROFILE_ENV: "/my/profile.xml"}) == {}
    env = graph.dds_environment({})
    assert Path(env[PROFILE_ENV]).name == "fastdds.xml"
    assert Path(env[PROFILE_ENV]).is_file()


# -------------------------------------------------------------------- the launch file
class _Recorder:
    """Stands in for a launch class: keeps its positional and keyword arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


class _LaunchConfiguration(_Recorder):
    def perform(self, context: Any) -> str:
        return context.launch_configurations[self.args[0]]


class _Context:
    def __init__(self, **configurations: str) -> None:
        self.launch_configurations = configurations


@pytest.fixture
def launch_module(monkeypatch: pytest.MonkeyPatch) -> types.ModuleType:
    """pushbot.launch.py loaded against stand-ins for launch / launch_ros."""
    stand_ins = {
        "launch": {"LaunchContext": _Context, "LaunchDescription": _Recorder},
        "launch.actions": {"DeclareLaunchArgument": _Recorder, "OpaqueFunction": _Recorder},
        "launch.substitutions": {"LaunchConfiguration": _LaunchConfiguration},
        "launch_ros": {},
        "launch_ros.actions": {"Node": _Recorder},
    }
    for name, attrs in stand_ins.items():
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location("pushbot_launch_under_test", LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_launch_file_imports_only_launch_and_the_bringup_package() -> None:
    tree = ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))
    modules = {alias.name.split(".")[0] for node in ast.walk(tree)
               if isinstance(node, ast.Import) for alias in node.names}
    modules |= {node.module.split(".")[0] for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom) and node.module}
    assert modules == {"__future__", "os", "sys", "launch", "launch_ros", "pushbot_bringup"}
    names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert "generate_launch_description" in names


def test_launch_arguments_and_defaults(launch_module: types.ModuleType) -> None:
    description = launch_module.generate_launch_description()
    actions = description.args[0]
    declared = {a.args[0]: a.kwargs["default_value"] for a in actions
                if "default_value" in a.kwargs}
    assert declared == {"sim": "true", "object": "", "robot": "", "config_dir": str(CONFIG_DIR)}
    assert all(a.kwargs.get("description") for a in actions[:-1])
    assert actions[-1].kwargs["function"] is launch_module._nodes


@pytest.mark.parametrize("sim, robot", [("true", ""), ("false", ""), ("true", "arm")])
def test_launch_file_builds_the_nodes_graph_nodes_decides(
        launch_module: types.ModuleType, sim: str, robot: str) -> None:
    context = _Context(sim=sim, object="", robot=robot, config_dir=str(CONFIG_DIR))
    actions = launch_module._nodes(context)
    expected = graph_nodes(sim == "true", config_dir=str(CONFIG_DIR), robot=robot)
    assert len(actions) == len(expected)
    for action, node in zip(actions, expected, strict=True):
        kw = action.kwargs
        assert (kw["package"], kw["executable"], kw["name"]) == (
            node.package, node.executable, node.name)
        assert kw["parameters"] == list(node.parameters)
        assert kw["remappings"] == list(node.remappings)
        assert PROFILE_ENV in kw["additional_env"] or graph.dds_environment() == {}


def test_launch_file_passes_object_and_refuses_bad_sim(launch_module: types.ModuleType) -> None:
    actions = launch_module._nodes(_Context(sim="true", object="hex", robot="", config_dir=""))
    bridge = actions[0].kwargs
    assert bridge["executable"] == "sim_bridge_node"
    assert bridge["parameters"][-1] == {"use_sim_time": False, "object": "hex", "robot": "pusher"}
    with pytest.raises(ValueError, match="launch argument sim"):
        launch_module._nodes(_Context(sim="maybe", object="", robot="", config_dir=""))
