"""Every package under src/ is a real ament_python package and the workspace builds with colcon.

Expected names (packages, node executables) are derived from the files themselves (package.xml,
setup.py console_scripts), never from a second hard-coded list.
"""

from __future__ import annotations

import ast
import configparser
import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"
ROS_WS = REPO / "ros_ws"
BRINGUP = "pushbot_bringup"
#: The parameter files and the launch file, installed to share/pushbot_bringup/{config,launch}.
CONFIG_DIR = SRC / BRINGUP / "config"
LAUNCH_DIR = SRC / BRINGUP / "launch"
PACKAGES = sorted(p.name for p in SRC.iterdir() if p.is_dir() and not p.name.startswith("."))
CORE = "push_core"

# Top-level modules that mean "ROS": the client library, its C layers, generated interface
# packages, launch and the ament index.
ROS_MODULE = re.compile(
    r"^(rclpy|rcl\w*|rmw\w*|rosidl\w*|launch\w*|ament_index_python|tf2\w*|builtin_interfaces"
    r"|\w+_msgs|\w+_srvs|\w+_actions|\w+_interfaces)$"
)


def setup_py_info(package: str) -> tuple[str, list[str]]:
    """(name passed to setup(), console script names) read from setup.py with ast."""
    tree = ast.parse((SRC / package / "setup.py").read_text())
    constants = {
        target.id: node.value.value
        for node in tree.body if isinstance(node, ast.Assign)
        and isinstance(node.value, ast.Constant)
        for target in node.targets if isinstance(target, ast.Name)
    }
    calls = [node for node in ast.walk(tree) if isinstance(node, ast.Call)
             and getattr(node.func, "id", None) == "setup"]
    assert len(calls) == 1, f"{package}/setup.py: expected one setup() call"
    kwargs = {kw.arg: kw.value for kw in calls[0].keywords}
    name_node = kwargs["name"]
    name = constants[name_node.id] if isinstance(name_node, ast.Name) else name_node.value
    scripts = []
    if "entry_points" in kwargs:
        entry_points = ast.literal_eval(kwargs["entry_points"])
        scripts = [spec.split("=")[0].strip() for spec in entry_points.get("console_scripts", [])]
    return name, scripts


def console_scripts() -> dict[str, list[str]]:
    """Package -> its console scripts, for every package that has any."""
    return {p: scripts for p in PACKAGES if (scripts := setup_py_info(p)[1])}


def test_the_packages_are_there() -> None:
    assert CORE in PACKAGES and "pushbot" in PACKAGES
    assert (ROS_WS / "src").resolve() == SRC.resolve(), "ros_ws/src must link to ../src"


@pytest.mark.parametrize("package", PACKAGES)
def test_package_xml_format_3_ament_python(package: str) -> None:
    root = ET.parse(SRC / package / "package.xml").getroot()
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == package
    assert root.findtext("export/build_type") == "ament_python"
    for tag in ("version", "description", "maintainer", "license"):
        assert (root.findtext(tag) or "").strip(), f"{package}/package.xml: empty <{tag}>"


@pytest.mark.parametrize("package", PACKAGES)
def test_setup_files_and_resource_marker_agree(package: str) -> None:
    name, _ = setup_py_info(package)
    assert name == package, f"setup.py name {name!r} != directory {package!r}"
    cfg = configparser.ConfigParser()
    cfg.read(SRC / package / "setup.cfg")
    assert cfg.get("develop", "script_dir") == f"$base/lib/{package}"
    assert cfg.get("install", "install_scripts") == f"$base/lib/{package}"
    assert (SRC / package / "resource" / package).is_file()
    assert (SRC / package / package / "__init__.py").is_file()


def _ros_imports(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            modules = [node.module]
        else:
            continue
        found += [f"{path.relative_to(REPO)}:{node.lineno} imports {m}"
                  for m in modules if ROS_MODULE.match(m.split(".")[0])]
    return found


#: Third-party top-level modules -> the rosdep keys that provide them (any one suffices). Keys
#: checked against ros/rosdistro rosdep/{base,python}.yaml: torch has the system key
#: python3-torch and the pip key python3-pytorch-pip; pybullet and filterpy only pip keys.
ROSDEP_KEYS = {
    "numpy": {"python3-numpy"},
    "scipy": {"python3-scipy"},
    "yaml": {"python3-yaml"},
    "matplotlib": {"python3-matplotlib"},
    "torch": {"python3-torch", "python3-pytorch-pip"},
    "cv2": {"python3-opencv"},
    "PIL": {"python3-pil"},
    "tqdm": {"python3-tqdm"},
    "pybullet": {"python3-pybullet-pip"},
    "pybullet_data": {"python3-pybullet-pip"},  # ships inside the pybullet wheel
    "pybullet_utils": {"python3-pybullet-pip"},
    "filterpy": {"python3-filterpy-pip"},
    # pip `pin`; rosdep: the ROS package `pinocchio` (released into Jazzy) ships the bindings.
    "pinocchio": {"pinocchio"},
    # pip `ruckig`; no rosdep Python key: the Jazzy ROS package `ruckig` (the same library).
    "ruckig": {"ruckig"},
}


def _required_imports(path: Path) -> set[str]:
    """Top-level modules ``path`` imports unconditionally: not inside ``try`` blocks that catch
    ImportError (optional features) nor under ``if TYPE_CHECKING``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    optional: set[int] = set()
    for node in ast.walk(tree):
        guarded = []
        if isinstance(node, ast.Try) and any(
                isinstance(h.type, ast.Name) and h.type.id in ("ImportError", "ModuleNotFoundError")
                or isinstance(h.type, ast.Tuple) and any(
                    getattr(e, "id", None) in ("ImportError", "ModuleNotFoundError")
                    for e in h.type.elts)
                for h in node.handlers):
            guarded = node.body
        elif isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            guarded = node.body
        optional |= {id(n) for stmt in guarded for n in ast.walk(stmt)}
    found = set()
    for node in ast.walk(tree):
        if id(node) in optional:
            continue
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
    return found


def _declared_dependencies(package: str) -> set[str]:
    root = ET.parse(SRC / package / "package.xml").getroot()
    return {(e.text or "").strip() for tag in ("depend", "exec_depend") for e in root.iter(tag)}


@pytest.mark.parametrize("package", PACKAGES)
def test_package_xml_covers_every_third_party_import(package: str) -> None:
    # The package's modules (and a bringup's launch files); workspace packages (first party)
    # and the standard library are not rosdep's business here.
    sources = sorted((SRC / package / package).rglob("*.py"))
    sources += sorted((SRC / package / "launch").glob("*.py"))
    imports = set().union(*(_required_imports(path) for path in sources))
    third_party = imports - set(sys.stdlib_module_names) - set(PACKAGES) - {"__future__"}
    declared = _declared_dependencies(package)
    missing, unknown = [], []
    for module in sorted(third_party):
        if ROS_MODULE.match(module):  # a ROS package: its rosdep key is its name
            keys = {module}
        elif module in ROSDEP_KEYS:
            keys = ROSDEP_KEYS[module]
        else:
            unknown.append(module)
            continue
        if not keys & declared:
            missing.append(f"{module} (one of {sorted(keys)})")
    assert not unknown, f"{package}: no rosdep key known for {unknown}; add it to ROSDEP_KEYS"
    assert not missing, f"{package}/package.xml: no exec_depend for {missing}"


def test_push_core_sources_never_import_ros() -> None:
    sources = sorted((SRC / CORE).rglob("*.py"))
    assert sources
    offenders = [hit for path in sources for hit in _ros_imports(path)]
    assert not offenders, offenders


def test_push_core_import_loads_no_ros_module() -> None:
    # Import the package and every submodule in a fresh interpreter, then look at sys.modules.
    code = (
        'import importlib, json, pkgutil, re, sys\n'
        f'pattern = re.compile({ROS_MODULE.pattern!r})\n'
        f'import {CORE}\n'
        f'for info in pkgutil.walk_packages({CORE}.__path__, "{CORE}."):\n'
        '    importlib.import_module(info.name)\n'
        'print(json.dumps(sorted(m for m in sys.modules if pattern.match(m.split(".")[0]))))\n'
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    loaded = json.loads(result.stdout.strip().splitlines()[-1])
    assert "rclpy" not in loaded and loaded == [], f"push_core pulled in ROS modules: {loaded}"


@pytest.mark.slow
def test_colcon_build_installs_every_node(tmp_path: Path) -> None:
    colcon = Path(sys.executable).parent / "colcon"
    assert colcon.exists(), "colcon is not in the venv: run make venv"
    before = {p for p in (ROS_WS / "build", ROS_WS / "install", ROS_WS / "log") if p.exists()}
    before |= {p for p in SRC.glob("*/build") if p.exists()}
    result = subprocess.run(
        [str(colcon), "--log-base", str(tmp_path / "log"), "build",
         "--build-base", str(tmp_path / "build"), "--install-base", str(tmp_path / "install"),
         "--event-handlers", "console_direct-", "console_cohesion-"],
        cwd=ROS_WS, capture_output=True, text=True, timeout=600,
        env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
    )
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-4000:]
    install = tmp_path / "install"
    # `ros2 launch pushbot_bringup pushbot.launch.py` needs the launch file and its
    # parameter files in the package's share directory.
    share = install / BRINGUP / "share" / BRINGUP
    launch_files = sorted(p.name for p in LAUNCH_DIR.glob("*.launch.py"))
    assert "pushbot.launch.py" in launch_files
    for name in launch_files:
        assert (share / "launch" / name).is_file(), f"share/{BRINGUP}/launch/{name} missing"
    for config in CONFIGS:
        installed = share / "config" / config.name
        assert installed.is_file(), f"share/{BRINGUP}/config/{config.name} missing"
        assert installed.read_text() == config.read_text()
    for package in PACKAGES:
        marker = install / package / "share" / "ament_index" / "resource_index" / "packages"
        assert (marker / package).is_file(), f"{package}: ament index marker not installed"
        assert (install / package / "share" / package / "package.xml").is_file()
    expected = console_scripts()
    assert set(expected) >= {"sim_bridge", "push_perception", "push_estimator", "push_planner"}
    for package, scripts in expected.items():
        for script in scripts:
            executable = install / package / "lib" / package / script
            assert executable.is_file(), f"{executable.relative_to(tmp_path)} missing"
            assert os.access(executable, os.X_OK), f"{executable} is not executable"
    # The build went to tmp_path only: no build/install/log trees appeared in the repo.
    after = {p for p in (ROS_WS / "build", ROS_WS / "install", ROS_WS / "log") if p.exists()}
    after |= {p for p in SRC.glob("*/build") if p.exists()}
    assert after <= before, f"colcon wrote into the repository: {sorted(after - before)}"


CONFIGS = sorted(CONFIG_DIR.glob("*.yaml"))


@pytest.mark.parametrize("path", CONFIGS, ids=[p.name for p in CONFIGS])
def test_parameter_yaml_has_the_ros_parameters_shape(path: Path) -> None:
    from rclpy.parameter import parameter_dict_from_yaml_file

    data = yaml.safe_load(path.read_text())
    assert isinstance(data, dict) and data, f"{path.name}: expected <node_name>: mapping"
    for node_name, body in data.items():
        assert isinstance(node_name, str) and node_name
        assert isinstance(body, dict) and list(body) == ["ros__parameters"], (
            f"{path.name}: {node_name} must hold exactly ros__parameters")
        assert isinstance(body["ros__parameters"], dict)
        # The parser rclpy itself uses for --params-file must accept it.
        parsed = parameter_dict_from_yaml_file(str(path), target_nodes=[node_name])
        assert set(parsed) == _flat_names(body["ros__parameters"])


def _flat_names(params: dict, prefix: str = "") -> set[str]:
    """Parameter names as ROS sees them: nested mappings become dotted names."""
    names = set()
    for key, value in params.items():
        if isinstance(value, dict):
            names |= _flat_names(value, f"{prefix}{key}.")
        else:
            names.add(f"{prefix}{key}")
    return names


CLOCK_SOURCE = "sim_bridge"  # publishes /clock, so it alone runs on its own clock


def test_every_node_package_has_a_parameter_yaml() -> None:
    names = {p.stem for p in CONFIGS}
    nodes = {pkg for pkg in console_scripts() if pkg != "pushbot"}
    assert nodes, "no node packages found"
    missing = nodes - names
    assert not missing, f"no {CONFIG_DIR.relative_to(REPO)}/<pkg>.yaml for {sorted(missing)}"
    # The clock source never waits for /clock; the launch file sets use_sim_time of the others
    # from sim:=true|false (after the file, so it wins).
    data = yaml.safe_load((CONFIG_DIR / f"{CLOCK_SOURCE}.yaml").read_text())
    for body in data.values():
        assert body["ros__parameters"].get("use_sim_time", False) is False


def test_nothing_refers_to_the_old_workspace_config_and_launch_dirs() -> None:
    # The files moved from ros_ws/{config,launch} to src/pushbot_bringup/{config,launch}.
    old = re.compile(r"ros_ws/(config|launch)\b")
    texts = [REPO / "README.md", ROS_WS / "README.md", *CONFIGS, *LAUNCH_DIR.glob("*.py")]
    offenders = [str(p.relative_to(REPO)) for p in texts if old.search(p.read_text())]
    assert not offenders, offenders
    assert not (ROS_WS / "config").exists() and not (ROS_WS / "launch").exists()
