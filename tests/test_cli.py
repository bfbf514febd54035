"""The ``pushbot`` CLI, driven as a user drives it: real processes, real DDS.

ROS isolation (domain id, localhost discovery, UDPv4) comes from ``tests/conftest.py``; the
subprocesses inherit it.
"""

from __future__ import annotations

import os
import re
import secrets
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from pushbot import cli
from pushbot.ros2cli.messages import ArraySummary, message_to_dict, to_yaml
from pushbot.runner import run

NODES = {
    "sim_bridge_node": "sim_bridge",
    "segmentation_node": "push_perception",
    "ekf_node": "push_estimator",
    "planner_node": "push_planner",
}
SUBCOMMANDS = ("doctor", "run", "up", "topic", "node", "param", "service", "goal", "demo")


def pushbot(*args: str, env: dict[str, str] | None = None,
            timeout: float = 120.0) -> subprocess.CompletedProcess:
    """Run the installed ``pushbot`` console script (the one next to this Python)."""
    exe = Path(sys.executable).parent / "pushbot"
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, **(env or {})})


# --- help -----------------------------------------------------------------------------------

def test_help_lists_subcommands() -> None:
    result = pushbot("--help")
    assert result.returncode == 0, result.stderr
    for command in SUBCOMMANDS:
        assert re.search(rf"^\s+{command}\s", result.stdout, re.MULTILINE), result.stdout


@pytest.mark.parametrize("command", [*SUBCOMMANDS, "topic list", "topic echo", "topic hz",
                                     "topic info", "topic pub", "node list", "node info",
                                     "param list", "param get", "param set", "param dump",
                                     "service list", "service call"])
def test_every_subcommand_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        cli.main([*command.split(), "--help"])
    assert exit_info.value.code == 0
    assert "usage: pushbot " + command in capsys.readouterr().out


# --- doctor ---------------------------------------------------------------------------------

@pytest.mark.ros
@pytest.mark.slow
def test_doctor_passes_with_two_process_pubsub() -> None:
    result = pushbot("doctor")
    assert result.returncode == 0, result.stdout + result.stderr
    lines = result.stdout.splitlines()
    pubsub = [line for line in lines if "pub/sub" in line]
    assert len(pubsub) == 1 and pubsub[0].startswith("OK"), result.stdout
    assert "5/5 messages" in pubsub[0]
    for label in ("rclpy", "RMW implementation", "torch", "pybullet", "OpenCV", "numpy",
                  "ROS_DOMAIN_ID", "discovery range"):
        assert any(line.startswith("OK") and label in line for line in lines), label
    assert re.search(rf'ROS_DOMAIN_ID\s+{os.environ["ROS_DOMAIN_ID"]}$', result.stdout, re.M)
    assert re.search(r"discovery range\s+LOCALHOST$", result.stdout, re.M)
    assert "rmw_fastrtps_cpp" in result.stdout
    assert re.fullmatch(r"doctor: all \d+ checks passed", lines[-1]), lines[-1]


@pytest.mark.ros
@pytest.mark.slow
def test_doctor_fails_clearly_when_messages_cannot_arrive() -> None:
    # A real failure: the probe subscriber runs on another DDS domain, so it never discovers
    # the publisher.
    result = pushbot("doctor", "--timeout", "4", env={"PUSHBOT_DOCTOR_SUB_DOMAIN_OFFSET": "1"})
    assert result.returncode == 1, result.stdout
    pubsub = next(line for line in result.stdout.splitlines() if "pub/sub" in line)
    assert pubsub.startswith("FAIL")
    assert "no message reached the subscriber within 4 s" in pubsub
    assert "check ROS_DOMAIN_ID / firewall / FASTDDS_BUILTIN_TRANSPORTS" in pubsub
    assert "Traceback" not in result.stdout + result.stderr


@pytest.mark.slow
def test_doctor_reports_a_missing_module_without_traceback() -> None:
    # sys.modules[name] = None makes `import name` fail exactly as if it were not installed.
    code = ('import sys; sys.modules["torch"] = None\n'
            'from pushbot.cli import main; sys.exit(main(["doctor", "--timeout", "30"]))')
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 1
    assert re.search(r"^FAIL\s+torch\s+torch is not installed: run make venv$", result.stdout,
                     re.M), result.stdout
    assert "Traceback" not in result.stdout + result.stderr


@pytest.mark.parametrize("value", ["-1", "nan", "inf"])
def test_demo_rejects_a_bad_pause_before_starting_anything(value: str, tmp_path: Path) -> None:
    result = pushbot("demo", "--skip-doctor", "--pause", value, "--out", str(tmp_path))
    assert result.returncode == 2
    assert "--pause must be a finite number of seconds >= 0" in result.stderr
    assert not (tmp_path / "graph_logs").exists()  # no node was started


# --- run ------------------------------------------------------------------------------------

def test_run_list_shows_the_four_nodes_with_their_packages() -> None:
    result = pushbot("run", "--list")
    assert result.returncode == 0, result.stderr
    listed = {tuple(line.split()[::-1]) for line in result.stdout.splitlines()}
    assert set(NODES.items()) <= listed, result.stdout


def test_run_unknown_node_exits_2_and_lists_known_nodes() -> None:
    result = pushbot("run", "no_such_node")
    assert result.returncode == 2
    assert "unknown node 'no_such_node'" in result.stderr
    for node, package in NODES.items():
        assert f"{node} ({package})" in result.stderr


class _StubEntryPoint:
    def __init__(self, record: list[list[str]]) -> None:
        self.record = record

    def load(self):  # noqa: ANN201
        return lambda: self.record.append(list(sys.argv))


@pytest.mark.parametrize("prefix", [["argv_node"], ["argv_pkg", "argv_node"]])
def test_run_passes_everything_after_the_node_to_its_main(
    prefix: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    record: list[list[str]] = []
    stub = run.NodeEntry("argv_node", "argv_pkg", "stub:main", _StubEntryPoint(record))
    monkeypatch.setattr(run, "discover_nodes", lambda: [stub])
    monkeypatch.setattr(sys, "argv", ["pushbot"])
    node_args = ["--ros-args", "-p", "x:=1", "-r", "a:=b", "--help"]
    assert cli.main(["run", *prefix, *node_args]) == 0
    assert record == [["argv_node", *node_args]]


# --- message formatting (no ROS graph needed) -----------------------------------------------

def test_message_to_dict_nests_and_truncates_large_arrays() -> None:
    from geometry_msgs.msg import PoseWithCovarianceStamped, Quaternion
    from nav_msgs.msg import Path as PathMsg
    from sensor_msgs.msg import Image

    image = Image(height=2, width=3, encoding="rgb8", step=9, data=bytes(range(18)))
    image.header.frame_id = "camera_color_optical_frame"
    as_dict = message_to_dict(image, max_array=16)
    assert as_dict["header"] == {"stamp": {"sec": 0, "nanosec": 0},
                                 "frame_id": "camera_color_optical_frame"}
    assert isinstance(as_dict["data"], ArraySummary)
    assert as_dict["data"].startswith("<18 x uint8, starts [0, 1, 2")
    assert message_to_dict(image, max_array=0)["data"] == list(range(18))

    pose = PoseWithCovarianceStamped()
    pose.pose.pose.orientation = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    covariance = message_to_dict(pose, max_array=36)["pose"]["covariance"]
    assert covariance == [0.0] * 36

    path = PathMsg()
    path.poses = [pose_stamped_at(1.0), pose_stamped_at(2.0)]
    text = to_yaml(message_to_dict(path))
    loaded = yaml.safe_load(text)
    assert [p["pose"]["position"]["x"] for p in loaded["poses"]] == [1.0, 2.0]


def pose_stamped_at(x: float):  # noqa: ANN201
    from geometry_msgs.msg import PoseStamped

    msg = PoseStamped()
    msg.pose.position.x = x
    return msg


@pytest.mark.parametrize("text", ["hello", "a: b", "", "42", "true", "- x", "line\nbreak",
                                  " padded", "#comment", "ok #not"])
def test_yaml_strings_round_trip(text: str) -> None:
    assert yaml.safe_load(to_yaml({"data": text})) == {"data": text}


@pytest.mark.ros
def test_compatible_qos_receives_from_best_effort_and_latched_publishers(
    ros_context: Any, wait_for: Any
) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import (
        DurabilityPolicy,
        QoSProfile,
        ReliabilityPolicy,
        qos_profile_sensor_data,
    )
    from std_msgs.msg import String

    from pushbot.ros2cli.discovery import compatible_qos

    node = Node("qos_test", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        latched = node.create_publisher(
            String, "qos_test/latched",
            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        latched.publish(String(data="published before anyone subscribed"))
        sensor = node.create_publisher(String, "qos_test/sensor", qos_profile_sensor_data)
        received: dict[str, str] = {}
        chosen = {}
        for name in ("latched", "sensor"):
            topic = f"/qos_test/{name}"
            assert wait_for(lambda t=topic: node.get_publishers_info_by_topic(t), timeout=10)
            chosen[name] = compatible_qos(node.get_publishers_info_by_topic(topic))
            node.create_subscription(String, topic,
                                     lambda msg, n=name: received.setdefault(n, msg.data),
                                     chosen[name])
        assert chosen["latched"].durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert chosen["latched"].reliability == ReliabilityPolicy.RELIABLE
        assert chosen["sensor"].reliability == ReliabilityPolicy.BEST_EFFORT
        assert chosen["sensor"].durability == DurabilityPolicy.VOLATILE
        assert wait_for(lambda: sensor.get_subscription_count() > 0, timeout=10)
        sensor.publish(String(data="live"))
        assert wait_for(lambda: len(received) == 2, timeout=10, executor=executor), received
        assert received == {"latched": "published before anyone subscribed", "sensor": "live"}
    finally:
        executor.shutdown()
        node.destroy_node()


# --- topic (a real publisher in another process) --------------------------------------------

PUBLISHER = textwrap.dedent("""
    import sys
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, qos_profile_sensor_data
    from sensor_msgs.msg import Image
    from std_msgs.msg import String

    prefix, rate = sys.argv[1], float(sys.argv[2])
    rclpy.init()
    node = Node('cli_test_publisher')
    chatter = node.create_publisher(String, prefix + '/chatter', 10)
    camera = node.create_publisher(Image, prefix + '/image', qos_profile_sensor_data)
    latched_qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    latched = node.create_publisher(String, prefix + '/latched', latched_qos)
    latched.publish(String(data='latched: once'))
    count = 0

    def tick():
        global count
        count += 1
        chatter.publish(String(data=f'hello {count}'))
        image = Image(height=48, width=64, encoding='rgb8', step=192, data=bytes(48 * 192))
        image.header.frame_id = 'camera_color_optical_frame'
        camera.publish(image)

    node.create_timer(1.0 / rate, tick)
    print('publishing', flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
""")
RATE_HZ = 10.0


@pytest.fixture(scope="module")
def publisher(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A publisher process of three topics under a unique prefix; yields the prefix."""
    script = tmp_path_factory.mktemp("publisher") / "publisher.py"
    script.write_text(PUBLISHER)
    prefix = f"/cli_test_{secrets.token_hex(4)}"
    proc = subprocess.Popen([sys.executable, str(script), prefix, str(RATE_HZ)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield prefix
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@pytest.mark.ros
@pytest.mark.graph
def test_topic_list_sees_the_other_process(publisher: str) -> None:
    result = pushbot("topic", "list", "-t")
    assert result.returncode == 0, result.stderr
    assert f"{publisher}/chatter [std_msgs/msg/String]" in result.stdout.splitlines()
    assert f"{publisher}/image [sensor_msgs/msg/Image]" in result.stdout.splitlines()


@pytest.mark.ros
@pytest.mark.graph
def test_topic_echo_prints_one_message(publisher: str) -> None:
    result = pushbot("topic", "echo", f"{publisher}/chatter", "--count", "1", "--timeout", "20")
    assert result.returncode == 0, result.stderr
    documents = result.stdout.split("---\n")
    assert documents[-1] == "" and len(documents) == 2, result.stdout
    assert re.fullmatch(r"hello \d+", yaml.safe_load(documents[0])["data"])


@pytest.mark.ros
@pytest.mark.graph
def test_topic_echo_matches_best_effort_and_summarises_image_data(publisher: str) -> None:
    # A reliable subscription would never receive from this best-effort publisher.
    result = pushbot("topic", "echo", f"{publisher}/image", "-n", "1", "--timeout", "20")
    assert result.returncode == 0, result.stderr
    image = yaml.safe_load(result.stdout.split("---\n")[0])
    assert (image["height"], image["width"], image["encoding"]) == (48, 64, "rgb8")
    assert image["header"]["frame_id"] == "camera_color_optical_frame"
    assert image["data"].startswith("<9216 x uint8, starts [0, 0")


@pytest.mark.ros
@pytest.mark.graph
def test_topic_echo_receives_latched_message(publisher: str) -> None:
    # Published once at start-up: only a transient-local subscription gets it now.
    result = pushbot("topic", "echo", f"{publisher}/latched", "-n", "1", "--timeout", "20")
    assert result.returncode == 0, result.stderr
    assert yaml.safe_load(result.stdout.split("---\n")[0]) == {"data": "latched: once"}


@pytest.mark.ros
@pytest.mark.graph
def test_topic_hz_reports_the_publisher_rate(publisher: str) -> None:
    result = pushbot("topic", "hz", f"{publisher}/chatter", "--duration", "3", "--timeout", "20")
    assert result.returncode == 0, result.stderr
    rates = [float(r) for r in re.findall(r"average rate: ([\d.]+)", result.stdout)]
    assert rates, result.stdout
    # Behaviour, not a benchmark: loose bounds around the 10 Hz timer.
    assert 0.5 * RATE_HZ < rates[-1] < 1.5 * RATE_HZ, result.stdout


@pytest.mark.ros
@pytest.mark.graph
def test_topic_info_shows_type_and_qos(publisher: str) -> None:
    result = pushbot("topic", "info", f"{publisher}/image", "--timeout", "20")
    assert result.returncode == 0, result.stderr
    assert "Type: sensor_msgs/msg/Image" in result.stdout
    assert "Publisher count: 1" in result.stdout
    assert "/cli_test_publisher" in result.stdout
    assert "reliability=BEST_EFFORT" in result.stdout


@pytest.mark.ros
def test_topic_echo_on_a_missing_topic_exits_1_clearly() -> None:
    result = pushbot("topic", "echo", "/no_such_topic_here", "--timeout", "2")
    assert result.returncode == 1
    assert "topic /no_such_topic_here did not appear within 2 s" in result.stderr
    assert "Traceback" not in result.stderr


def test_readme_lists_every_command_and_option() -> None:
    """docs/CLI.md's command reference is exactly what the parsers say (every option
    documented), and it names every option string of every command."""
    import argparse

    from pushbot.cli import build_parser
    from pushbot.cli_reference import readme_section, reference_markdown

    readme = Path(__file__).resolve().parents[1] / "docs" / "CLI.md"
    section = readme_section(readme.read_text(encoding="utf-8"))
    assert section is not None, "docs/CLI.md has no cli-reference section"
    assert section == reference_markdown(), \
        "docs/CLI.md command reference is stale: python -m pushbot.cli_reference docs/CLI.md"
    options = set()
    stack = [build_parser()]
    while stack:
        parser = stack.pop()
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                stack.extend(action.choices.values())
            else:
                options.update(o for o in action.option_strings if o.startswith("--"))
    missing = sorted(o for o in options - {"--help", "--version"} if f"`{o}" not in section
                     and f", {o}" not in section)
    assert not missing, missing
