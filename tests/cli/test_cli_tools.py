"""The operator CLI's pieces without a node graph: help text, the message YAML codec, argument
checks (exit 2 and one line), ``pushbot up``'s node arguments, ``param dump``'s nesting, and
``topic pub`` reaching an in-process subscriber over DDS (the session's domain).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from pushbot import cli
from pushbot.ros2cli import param
from pushbot.ros2cli.messages import MessageFieldError, fill_message, message_from_yaml
from pushbot.runner import run, up

MARKUP = re.compile(r"``|:[a-z]+:`")


def pushbot(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).parent / "pushbot"
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ), stdin=subprocess.DEVNULL)


def _parsers(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser]]:
    """Every parser below ``parser`` (subcommands at any depth) with its prog."""
    found = [(parser.prog, parser)]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in dict.fromkeys(action.choices.values()):
                found += _parsers(child)
    return found


# --- help -----------------------------------------------------------------------------------

def test_no_help_text_shows_restructuredtext_markup() -> None:
    parsers = _parsers(cli.build_parser())
    assert len(parsers) > 30  # every subcommand and target, not just the top level
    for prog, parser in parsers:
        text = parser.format_help()
        assert not MARKUP.search(text), f"{prog} --help shows markup: " \
            f"{MARKUP.search(text).group(0)!r} in\n{text}"


def test_plain_help_unmarks_roles_and_literals() -> None:
    doc = ("Uses :mod:`push_ros.dds` and :func:`~push_core.planner.plan`, "
           ":class:`Trial <pushbot.runner.protocol.Trial>`; run ``pushbot demo``."
           "\n\n- a list\n")
    assert cli.plain_help(doc) == ("Uses push_ros.dds and plan, Trial; run pushbot demo.\n\n"
                                   "- a list")


def test_demo_help_puts_its_own_options_before_the_doctors() -> None:
    text = cli.build_parser()._subparsers._group_actions[0].choices["demo"].format_help()
    usage = text.split("\n\n")[0]
    assert usage.index("--object") < usage.index("--timeout")
    body = text[text.index("\noptions:"):]
    assert body.index("--skip-doctor") < body.index("doctor options") < body.index("--count")


#: Prints the modules loaded after ``cli.main(argv + ['--help'])`` in a fresh interpreter
#: (stdout: the help, then one JSON line: the ``pushbot`` modules and the heavy packages).
_LOADED = """
import json, sys
from pushbot import cli
try:
    cli.main(sys.argv[1:] + ['--help'])
except SystemExit:
    pass
print(json.dumps([sorted(m for m in sys.modules if m.split('.')[0] == 'pushbot'),
                  sorted({'numpy', 'rclpy', 'torch', 'push_core'} & set(sys.modules))]))
"""


def _help_and_modules(*argv: str) -> tuple[str, set[str], set[str]]:
    result = subprocess.run([sys.executable, "-c", _LOADED, *argv], capture_output=True,
                            text=True, timeout=120, env=dict(os.environ, COLUMNS="100"))
    assert result.returncode == 0, result.stderr
    text, _, last = result.stdout.rstrip("\n").rpartition("\n")
    pushbot_modules, heavy = json.loads(last)
    return " ".join(text.split()), set(pushbot_modules), set(heavy)


def _command_modules() -> dict[str, str]:
    """command (``'eval push'`` for a target) -> its module, from the CLI's tables."""
    modules = {name: entry[0] for name, entry in cli.COMMANDS.items()}
    for group, (_, targets) in cli.TARGETS.items():
        modules |= {f"{group} {target}": entry[0] for target, entry in targets.items()}
    return modules


def test_command_modules_are_named_after_their_commands() -> None:
    for name, (module, _, _, _) in cli.COMMANDS.items():
        assert re.fullmatch(rf"pushbot\.(ros2cli|runner|experiments|viz)\.{name}", module), name


def test_top_level_help_lists_every_command_and_imports_none() -> None:
    text, loaded, heavy = _help_and_modules()
    assert loaded == {"pushbot", "pushbot.cli"}
    assert not heavy  # not even numpy: the DDS profile (push_ros) is applied after parsing
    for name, (_, _, summary, _) in cli.COMMANDS.items():
        assert f"{name} {summary}" in text
    for group, (summary, _) in cli.TARGETS.items():
        assert f"{group} {summary}" in text


@pytest.mark.parametrize("command", ["topic", "node", "eval push", "data perception", "eval"])
def test_a_commands_help_imports_only_its_own_module(command: str) -> None:
    text, loaded, _ = _help_and_modules(*command.split())
    expected = {m for c, m in _command_modules().items() if c == command}
    assert loaded & set(_command_modules().values()) == expected
    assert text.startswith(f"usage: pushbot {command}")
    if command == "eval":  # a group: its targets with their one-line help, none imported
        for target, (_, summary) in cli.TARGETS["eval"][1].items():
            assert f"{target} {summary}" in text


@pytest.mark.parametrize(("argv", "selected"), [
    ([], set()),
    (["--help"], set()),
    (["topic", "echo", "/a", "--once"], {"topic"}),
    (["--version", "up"], {"up"}),
    (["eval", "--help"], {"eval"}),
    (["eval", "push", "--objects", "rect1"], {"eval", "eval push"}),
    (["run", "planner_node", "--ros-args", "-p", "k:=3"], {"run"}),
])
def test_selected_commands_is_the_first_word_and_a_groups_target(argv: list[str],
                                                                  selected: set[str]) -> None:
    assert cli.selected_commands(argv) == selected


# --- the message codec ----------------------------------------------------------------------

def test_message_from_yaml_sets_nested_fields_and_keeps_defaults() -> None:
    from geometry_msgs.msg import PoseStamped
    from std_msgs.msg import Float64MultiArray

    msg = message_from_yaml(
        PoseStamped, "{header: {frame_id: world, stamp: {sec: 3}}, pose: {position: {x: 0.05, "
                     "y: -1}, orientation: {z: 0.5, w: 0.8660254}}}")
    assert msg.header.frame_id == "world" and msg.header.stamp.sec == 3
    assert (msg.pose.position.x, msg.pose.position.y, msg.pose.position.z) == (0.05, -1.0, 0.0)
    assert isinstance(msg.pose.position.y, float)
    assert msg.pose.orientation.w == pytest.approx(0.8660254)
    array = message_from_yaml(Float64MultiArray,
                              "{data: [1, 2.5], layout: {dim: [{label: state, size: 2}]}}")
    assert list(array.data) == [1.0, 2.5]
    assert (array.layout.dim[0].label, array.layout.dim[0].size) == ("state", 2)
    assert message_from_yaml(PoseStamped, "") == PoseStamped()


@pytest.mark.parametrize("text, error", [
    ("{header: {frame_idx: world}}",
     "std_msgs/msg/Header has no field 'header.frame_idx' (its fields: stamp, frame_id)"),
    ("{pose: {position: {x: abc}}}", "field 'pose.position.x' (double) cannot take str 'abc'"),
    ("{pose: {position: {x: true}}}", "field 'pose.position.x' (double) cannot take bool True"),
    ("{header: {stamp: {sec: 2147483648}}}",
     "field 'header.stamp.sec' (int32): 2147483648 is out of range [-2147483648, 2147483647]"),
    ("{header: {stamp: {nanosec: -1}}}",
     "field 'header.stamp.nanosec' (uint32): -1 is out of range [0, 4294967295]"),
    ("{pose: 3}", "field 'pose' (geometry_msgs/msg/Pose) takes a mapping of fields, got int 3"),
    ("[1, 2]", "the message (geometry_msgs/msg/PoseStamped) takes a mapping of fields, got "
               "list [1, 2]"),
    ("{pose: [", "the values are not valid YAML (expected the node content, but found "
                 "'<stream end>')"),
])
def test_message_from_yaml_names_the_bad_field(text: str, error: str) -> None:
    from geometry_msgs.msg import PoseStamped

    with pytest.raises(MessageFieldError) as info:
        message_from_yaml(PoseStamped, text)
    assert str(info.value) == error


def test_fill_message_checks_arrays_element_by_element() -> None:
    from std_msgs.msg import Float32MultiArray, String, UInt8MultiArray

    msg = UInt8MultiArray()
    fill_message(msg, {"data": [0, 255]})
    assert list(msg.data) == [0, 255]
    with pytest.raises(MessageFieldError, match=r"field 'data\[1\]' \(uint8\): 256 is out"):
        fill_message(msg, {"data": [0, 256]})
    with pytest.raises(MessageFieldError, match=r"field 'data' \(sequence<uint8>\) takes a list"):
        fill_message(msg, {"data": 7})
    with pytest.raises(MessageFieldError, match="float32 range"):
        fill_message(Float32MultiArray(), {"data": [1e39]})
    text = String()
    fill_message(text, {"data": 12})  # YAML reads an unquoted 12 as a number
    assert text.data == "12"


# --- bad input: exit 2, one line, before any ROS work ---------------------------------------

@pytest.mark.parametrize("argv, message", [
    (["topic", "pub", "goal_pose", "geometry_msgs/msg/PoseStamped", "{pose: {postion: {}}}",
      "--once"], "pushbot topic pub: geometry_msgs/msg/Pose has no field 'pose.postion'"),
    (["topic", "pub", "x", "geometry_msgs/msg/NoSuchType", "--once"],
     "pushbot topic pub: cannot decode 'geometry_msgs/msg/NoSuchType'"),
    (["topic", "pub", "x", "std_msgs/String", "--times", "0"],
     "pushbot topic pub: --times must be >= 1"),
    (["service", "call", "/x/reset", "std_srvs/srv/Trigger", "{force: true}"],
     "pushbot service call: std_srvs/srv/Trigger_Request has no field 'force'"),
    (["service", "call", "/x/reset", "std_msgs/msg/String"],
     "pushbot service call: 'std_msgs/msg/String' is not a service type"),
    (["goal", "nan", "0", "0"], "pushbot goal: X, Y and YAW must be finite numbers"),
    (["goal", "0", "0", "0", "--frame", " "], "pushbot goal: --frame must not be empty"),
    (["goal", "0", "0", "0", "--linger", "-1"], "pushbot goal: --linger must be >= 0"),
    (["up", "--no-sim", "--object", "rect1"], "pushbot up: launch argument object:=rect1 needs "
                                               "sim:=true"),
    (["up", "--params-dir", "/no/such/dir"], "pushbot up: --params-dir /no/such/dir: no such "
                                              "directory"),
    (["param", "get", "node/", "x"], "pushbot param get: invalid node name 'node/'"),
    (["run", "planner_node", "--ros-args", "--params-file", "/no/such.yaml"],
     "pushbot run: --params-file /no/such.yaml: no such file"),
])
def test_bad_input_exits_2_with_one_line(argv: list[str], message: str) -> None:
    result = pushbot(*argv)
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.startswith(message), result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr


def test_missing_params_file_only_looks_inside_ros_args(tmp_path: Path) -> None:
    present = tmp_path / "p.yaml"
    present.write_text("{}")
    assert run.missing_params_file(["--ros-args", "--params-file", str(present)]) is None
    assert run.missing_params_file(["--params-file", "gone.yaml"]) is None  # a node option
    assert run.missing_params_file(["--ros-args", "-p", "a:=1", "--params-file", "gone.yaml"]) \
        == "gone.yaml"


# --- pushbot up's arguments: what the launch file starts ------------------------------------

def test_up_passes_the_launch_files_parameters_and_remappings() -> None:
    from pushbot_bringup.graph import DEFAULT_CONFIG_DIR, graph_nodes

    sim = up.ros_arguments(True, "rect1")
    assert list(sim) == [n.name for n in graph_nodes(True)]
    assert sim["sim_bridge_node"] == [
        "--params-file", str(Path(DEFAULT_CONFIG_DIR) / "sim_bridge.yaml"),
        "-p", "use_sim_time:=false", "-p", "object:='rect1'", "-p", "robot:='pusher'"]
    assert sim["planner_node"] == ["--params-file", str(Path(DEFAULT_CONFIG_DIR) /
                                                        "push_planner.yaml"),
                                   "-p", "use_sim_time:=true"]
    real = up.ros_arguments(False)
    assert list(real) == ["segmentation_node", "ekf_node", "planner_node", "push_executor_node"]
    assert real["push_executor_node"][-2:] == ["-p", "start_enabled:=false"]  # a dry run
    arm = up.ros_arguments(True, robot="arm")
    assert "robot:='arm'" in arm["sim_bridge_node"]
    assert arm["push_executor_node"][-2:] == ["-p", "start_enabled:=true"]
    assert "-p" in real["ekf_node"] and "use_sim_time:=false" in real["ekf_node"]
    remaps = [real["segmentation_node"][i + 1] for i, a in enumerate(real["segmentation_node"])
              if a == "-r"]
    assert remaps == [f"{a}:={b}" for a, b in graph_nodes(False)[0].remappings]


def test_up_overrides_parameter_files_from_params_dir(tmp_path: Path) -> None:
    (tmp_path / "push_planner.yaml").write_text("planner_node:\n  ros__parameters: {k: 1}\n")
    args = up.ros_arguments(True, config_dir=str(tmp_path))
    assert args["planner_node"][:2] == ["--params-file", str(tmp_path / "push_planner.yaml")]
    assert "config/push_estimator.yaml" in args["ekf_node"][1]


def test_up_says_which_params_dir_files_it_reads(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "push_planner.yaml").write_text("planner_node:\n  ros__parameters: {k: 1}\n")
    (tmp_path / "my_planner.yaml").write_text("planner_node:\n  ros__parameters: {k: 1}\n")
    (tmp_path / "notes.txt").write_text("not a parameter file")
    up._report_params_dir(tmp_path, True, "")
    out, err = capsys.readouterr()
    assert f"--params-dir {tmp_path}: using push_planner.yaml" in out
    assert "warning" in err and "my_planner.yaml not read" in err
    assert "notes.txt" not in err and "sim_bridge.yaml, " in err  # the names it would read


def test_log_follower_prefixes_complete_lines(tmp_path: Path) -> None:
    import io

    out = io.StringIO()
    follower = up.LogFollower(tmp_path, ["a_node", "b_node"], out)
    (tmp_path / "a_node.log").write_text("one\ntw")
    follower.poll()
    assert out.getvalue() == "[a_node] one\n"
    with open(tmp_path / "a_node.log", "a") as log:
        log.write("o\nthree")
    follower.finish()
    assert out.getvalue() == "[a_node] one\n[a_node] two\n[a_node] three\n"


# --- param dump ------------------------------------------------------------------------------

def test_param_nest_writes_dotted_names_as_a_parameter_file_does() -> None:
    nested = param.nest({"k": 3, "goal_tolerance.xy": 0.0075, "goal_tolerance.theta": 0.1,
                         "a": 1, "a.b": 2})
    assert nested == {"k": 3, "goal_tolerance": {"xy": 0.0075, "theta": 0.1}, "a": 1, "a.b": 2}


def test_param_value_reads_yaml_like_ros2_param_set() -> None:
    from rcl_interfaces.msg import ParameterType

    value = param.parameter_value("3", ParameterType.PARAMETER_DOUBLE)
    assert (value.type, value.double_value) == (ParameterType.PARAMETER_DOUBLE, 3.0)
    value = param.parameter_value("3", ParameterType.PARAMETER_INTEGER)
    assert (value.type, value.integer_value) == (ParameterType.PARAMETER_INTEGER, 3)
    value = param.parameter_value("[1, 2]", ParameterType.PARAMETER_DOUBLE_ARRAY)
    assert list(value.double_array_value) == [1.0, 2.0]
    assert param.parameter_value("butter", ParameterType.PARAMETER_STRING).string_value \
        == "butter"


# --- topic pub over DDS -----------------------------------------------------------------------

@pytest.mark.ros
def test_topic_pub_reaches_a_subscriber_with_the_field_values(ros_context: Any,
                                                              wait_for: Any) -> None:
    from geometry_msgs.msg import PoseStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    node = Node("pub_test_subscriber", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    received: list[PoseStamped] = []
    topic = f"/pub_test_{os.getpid()}"
    # A volatile, reliable subscriber like planner_node's goal_pose.
    node.create_subscription(PoseStamped, topic, received.append,
                             QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    exe = Path(sys.executable).parent / "pushbot"
    proc = subprocess.Popen(
        [str(exe), "topic", "pub", topic, "geometry_msgs/PoseStamped",
         "{header: {frame_id: world}, pose: {position: {x: 0.05, y: -0.02}, "
         "orientation: {z: 0.25881905, w: 0.96592583}}}", "--times", "3", "--rate", "20"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL)
    try:
        # pub waits for this subscription before its first message: all three arrive.
        assert wait_for(lambda: len(received) >= 3, timeout=30, executor=executor)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        executor.shutdown()
        node.destroy_node()
    assert proc.returncode == 0, err
    assert out.count("publishing #") == 3
    msg = received[0]
    assert msg.header.frame_id == "world"
    assert (msg.pose.position.x, msg.pose.position.y) == (0.05, -0.02)
    assert 2 * math.atan2(msg.pose.orientation.z, msg.pose.orientation.w) == pytest.approx(
        math.radians(30), abs=1e-6)
    assert out.startswith("publisher: beginning loop\n")


@pytest.mark.ros
def test_goal_without_a_planner_exits_1_with_one_line() -> None:
    result = pushbot("goal", "0.03", "0", "0", "--wait", "--timeout", "2")
    assert result.returncode == 1
    assert result.stderr.startswith("pushbot goal: no planner_node: nothing subscribes to "
                                    "goal_pose"), result.stderr
    assert result.stderr.count("\n") == 1


@pytest.mark.graph
def test_goal_wait_timing_out_says_the_goal_stays_and_how_to_drop_it(processes: Any) -> None:
    # A planner alone: it takes the goal but never gets an estimate, so --wait times out.
    planner = processes.node("planner_node")
    result = pushbot("goal", "0.03", "0", "0", "--wait", "--timeout", "10")
    assert planner.poll() is None, processes.output(planner)
    assert result.returncode == 1
    assert result.stdout.startswith("goal sent: x 0.03 m"), result.stdout
    assert "pushbot goal: timed out after 10 s" in result.stderr, result.stderr
    assert ("the goal stays with planner_node" in result.stderr
            and "pushbot service call /planner_node/reset" in result.stderr)
    assert result.stderr.count("\n") == 1


def test_a_closed_stdout_ends_quietly_with_141() -> None:
    # The reader is gone before pushbot writes (what `| head` leads to): no traceback.
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        result = subprocess.run([str(Path(sys.executable).parent / "pushbot"), "run", "--list"],
                                stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=60,
                                stdin=subprocess.DEVNULL)
    finally:
        os.close(write_end)
    assert result.returncode == cli.EXIT_BROKEN_PIPE
    assert result.stderr == ""


# --- what ros2 prints -----------------------------------------------------------------------

def test_byte_fields_print_as_ros2_prints_them() -> None:
    from diagnostic_msgs.msg import DiagnosticStatus
    from std_msgs.msg import ByteMultiArray, UInt8MultiArray

    from pushbot.ros2cli.messages import message_to_dict, to_yaml

    status = DiagnosticStatus(level=DiagnosticStatus.ERROR, name="n")
    assert message_to_dict(status)["level"] == "\x02"
    assert 'level: "\\x02"' in to_yaml(message_to_dict(status)).splitlines()
    assert to_yaml(message_to_dict(DiagnosticStatus())).splitlines()[0] == 'level: "\\0"'
    assert message_to_dict(ByteMultiArray(data=[b"a", b"\x01"]))["data"] == ["a", "\x01"]
    assert message_to_dict(UInt8MultiArray(data=[0, 7, 255]))["data"] == [0, 7, 255]


def test_parameter_types_and_values_print_as_ros2_param_does() -> None:
    from rcl_interfaces.msg import ParameterType, ParameterValue

    assert param.type_name(ParameterType.PARAMETER_DOUBLE_ARRAY) == "double array"
    assert param.type_name(ParameterType.PARAMETER_INTEGER) == "integer"
    assert param.type_name(ParameterType.PARAMETER_BOOL) == "boolean"
    assert param.type_name(ParameterType.PARAMETER_NOT_SET) == "not set"
    T = ParameterType  # noqa: N806 - rcl_interfaces' name
    cases = [
        (ParameterValue(type=T.PARAMETER_DOUBLE, double_value=0.25), "Double value is: 0.25"),
        (ParameterValue(type=T.PARAMETER_INTEGER, integer_value=7), "Integer value is: 7"),
        (ParameterValue(type=T.PARAMETER_BOOL, bool_value=False), "Boolean value is: False"),
        (ParameterValue(type=T.PARAMETER_STRING, string_value="rect1"),
         "String value is: rect1"),
        (ParameterValue(type=T.PARAMETER_DOUBLE_ARRAY, double_array_value=[0.0, 1.5]),
         "Double values are: [0.0, 1.5]"),
        (ParameterValue(type=T.PARAMETER_INTEGER_ARRAY, integer_array_value=[1, 2]),
         "Integer values are: [1, 2]"),
        (ParameterValue(type=T.PARAMETER_STRING_ARRAY, string_array_value=["a", "b"]),
         "String values are: ['a', 'b']"),
        (ParameterValue(), "Parameter not set."),
    ]
    for value, line in cases:
        assert param.value_line(value) == line
    assert param.value_line(cases[4][0], hide_type=True) == "[0.0, 1.5]"


def test_topic_echo_accepts_once() -> None:
    parser = cli.build_parser()
    assert parser.parse_args(["topic", "echo", "/x", "--once"]).count == 1
    assert parser.parse_args(["topic", "echo", "/x"]).count is None
    result = pushbot("topic", "echo", "/x", "--once", "--count", "3")
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "not allowed with argument" in result.stderr


def test_service_call_prints_the_response_as_ros2_does(ros_context: Any) -> None:
    import threading

    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_srvs.srv import Trigger

    def on_call(_request: Any, response: Any) -> Any:
        response.success, response.message = True, "it's done"
        return response

    node = Node("service_test_server", context=ros_context)
    name = f"/service_test_{os.getpid()}/reset"
    node.create_service(Trigger, name, on_call)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        plain = pushbot("service", "call", name, "std_srvs/srv/Trigger")
        as_yaml = pushbot("service", "call", name, "std_srvs/srv/Trigger", "--yaml")
    finally:
        executor.shutdown()
        thread.join(timeout=10)
        node.destroy_node()
    assert plain.returncode == 0, plain.stderr
    assert plain.stdout == (
        'requester: making request: std_srvs.srv.Trigger_Request()\n\n'
        'response:\n'
        'std_srvs.srv.Trigger_Response(success=True, message="it\'s done")\n\n')
    assert as_yaml.returncode == 0, as_yaml.stderr
    assert yaml.safe_load(as_yaml.stdout.split("response:")[1]) == {
        "success": True, "message": "it's done"}


@pytest.mark.ros
def test_an_unanswered_request_is_sent_again(ros_context: Any) -> None:
    # A request sent before any server exists is lost (nobody reads it), as a response is
    # when the server has not matched the client yet. The server here appears 1 s after the
    # first request: only a request sent again is answered.
    import time

    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_srvs.srv import Trigger

    from pushbot.ros2cli.discovery import call_until_answered

    node = Node("resend_test", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    served: list[Any] = []

    def answer(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = True, "answered"
        return response

    def start_server() -> None:
        timer.cancel()
        served.append(node.create_service(Trigger, "resend_test_service", answer))

    try:
        client = node.create_client(Trigger, "resend_test_service")
        timer = node.create_timer(1.0, start_server)
        started = time.monotonic()
        future = call_until_answered(client, Trigger.Request(), executor,
                                     started + 30.0, resend_after=0.5)
        assert future is not None and future.result().message == "answered"
        assert served and time.monotonic() - started >= 1.0
        node.destroy_service(served[0])
        started = time.monotonic()
        assert call_until_answered(client, Trigger.Request(), executor, started + 1.2,
                                   resend_after=0.5) is None
        assert time.monotonic() - started >= 1.2  # it waited out its deadline, then gave up
    finally:
        executor.shutdown()
        node.destroy_node()
