"""docs/INTERFACES.md and the bundled parameter files say what the nodes declare.

- The parameter tables of docs/INTERFACES.md and the parameter files
  ``src/pushbot_bringup/config/*.yaml`` are generated from the nodes' ``PARAMETERS`` tables
  (:mod:`push_ros.interfaces`) and current; every node has a table and a file.
- The topic table is written by hand: every topic each node creates (started in-process in every
  mode, endpoints listed with rclpy) is a row whose publisher / subscriber column names that
  node, and every row is created by some node (the tf topics only where ``tf2_msgs`` exists);
  every service a node offers (besides rclpy's parameter services) is in the Services paragraph
  with the node's name.
"""

from __future__ import annotations

import importlib.util
import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from push_ros.interfaces import (
    generated,
    markdown_regions,
    parameter_markdown,
    regenerate_yaml,
    type_name,
    yaml_source,
)
from push_ros.node import ParamSpec

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "INTERFACES.md"
CONFIG = REPO / "src" / "pushbot_bringup" / "config"
#: node name -> (table module, bundled parameter file, label in the topic table's columns)
NODES = {
    "sim_bridge_node": ("sim_bridge.params", "sim_bridge.yaml", "sim_bridge"),
    "segmentation_node": ("push_perception.config", "push_perception.yaml", "perception"),
    "ekf_node": ("push_estimator.config", "push_estimator.yaml", "estimator"),
    "planner_node": ("push_planner.config", "push_planner.yaml", "planner"),
    "push_executor_node": ("push_executor.parameters", "push_executor.yaml", "push_executor"),
}
REGENERATE = ".venv/bin/python -m push_ros.interfaces docs/INTERFACES.md " \
             "src/pushbot_bringup/config/*.yaml"


# --------------------------------------------------------------------------------------------
# The generator
# --------------------------------------------------------------------------------------------
def test_type_names_follow_the_default_or_the_declared_type() -> None:
    from rcl_interfaces.msg import ParameterType

    assert type_name(ParamSpec("a", True, "")) == "bool"
    assert type_name(ParamSpec("a", 3, "")) == "integer"
    assert type_name(ParamSpec("a", 0.5, "")) == "double"
    assert type_name(ParamSpec("a", "x", "")) == "string"
    assert type_name(ParamSpec("a", [1.0, 2.0], "")) == "double[]"
    assert type_name(ParamSpec("a", None, "")) == "double[]"
    assert type_name(ParamSpec("a", None, "", type=ParameterType.PARAMETER_STRING_ARRAY)) \
        == "string[]"
    with pytest.raises(ValueError, match="'a'.*empty list"):
        type_name(ParamSpec("a", [], ""))
    with pytest.raises(ValueError, match="'a'"):
        type_name(ParamSpec("a", {"x": 1}, ""))


def test_markdown_table_rows_hold_type_default_and_the_documented_limits() -> None:
    specs = (ParamSpec("k", 3, "Points per step.", (1, 1000)),
             ParamSpec("method", "ana", "ana | lrn.", read_only=True),
             ParamSpec("tol.theta", math.radians(5.0), "Tolerance, rad."),
             ParamSpec("pose", [0.0, -0.5], "x, y, m.", constraints="2 finite values"),
             ParamSpec("joints", None, "Joint names."))
    assert parameter_markdown(specs).splitlines() == [
        "| parameter | type | default | description |",
        "| --- | --- | --- | --- |",
        "| `k` | integer | `3` | Points per step. Range [1, 1000]. |",
        '| `method` | string | `"ana"` | ana \\| lrn. Read-only. |',
        "| `tol.theta` | double | `0.0872665` | Tolerance, rad. |",
        "| `pose` | double[] | `[0.0, -0.5]` | x, y, m. Constraint: 2 finite values. |",
        "| `joints` | double[] | (unset) | Joint names. |",
    ]


def test_regions_name_their_node_and_module() -> None:
    text = ("a\n<!-- BEGIN parameters n1 m.one -->\nold\n<!-- END parameters n1 -->\n"
            "<!-- BEGIN parameters n2 m.two -->\n<!-- END parameters n2 -->\n")
    assert markdown_regions(text) == [("n1", "m.one"), ("n2", "m.two")]
    assert yaml_source("# Generated from push_planner.config by x\n") == "push_planner.config"
    assert yaml_source("# Parameters of planner_node\n") is None


# --------------------------------------------------------------------------------------------
# The generated documents are current
# --------------------------------------------------------------------------------------------
def test_every_node_has_a_current_parameter_table_in_interfaces_md() -> None:
    text = DOC.read_text(encoding="utf-8")
    assert dict(markdown_regions(text)) == {node: spec[0] for node, spec in NODES.items()}
    assert generated(DOC) == text, f"docs/INTERFACES.md is stale: {REGENERATE}"


def test_every_node_file_is_listed() -> None:
    """A new ``*_node.py`` needs a row in NODES (and so a table and a parameter file)."""
    files = {p.stem for p in (REPO / "src").glob("*/*/*_node.py")}
    assert files == {"sim_bridge_node", "segmentation_node", "ekf_node", "planner_node",
                     "push_executor_node"}


@pytest.mark.parametrize("node", sorted(NODES))
def test_parameter_file_is_generated_from_the_table(node: str) -> None:
    module, name, _ = NODES[node]
    path = CONFIG / name
    text = path.read_text(encoding="utf-8")
    assert yaml_source(text) == module
    assert text == regenerate_yaml(module), f"{path} is stale: {REGENERATE}"
    params = yaml.safe_load(text)[node]["ros__parameters"]
    flat = {f"{k}.{kk}": vv for k, v in params.items() if isinstance(v, dict)
            for kk, vv in v.items()}
    flat.update({k: v for k, v in params.items() if not isinstance(v, dict)})
    table = importlib.import_module(module).PARAMETERS
    assert {s.name for s in table if s.default is not None} <= set(flat)
    for spec in table:
        if spec.default is not None:
            value = flat[spec.name]
            assert value == spec.default and type(value) is type(spec.default), spec.name


# --------------------------------------------------------------------------------------------
# The topic table
# --------------------------------------------------------------------------------------------
def topic_rows() -> dict[str, tuple[str, str]]:
    """``{absolute topic: (publisher column, subscriber column)}`` of docs/INTERFACES.md."""
    rows: dict[str, tuple[str, str]] = {}
    section = DOC.read_text(encoding="utf-8").split("## Topics and services", 1)[1]
    for line in section.split("\n## ", 1)[0].splitlines():
        match = re.match(r"\| `([^`]+)` \|", line)
        if match:
            cells = [c.strip() for c in line.strip("|").split(" | ")]
            name = match[1] if match[1].startswith("/") else "/" + match[1]
            rows[name] = (cells[2], cells[3])
    return rows


#: Topics every rclpy node creates, not part of the contract.
ROS_INTERNAL = {"/rosout", "/parameter_events"}


def _node_endpoints(context: Any) -> Iterator[tuple[str, Any]]:
    """(label, node) for every node in every mode that creates other endpoints."""
    from rclpy.parameter import Parameter

    from push_estimator.ekf_node import EkfNode
    from push_executor.push_executor_node import PushExecutorNode
    from push_perception.segmentation_node import SegmentationNode
    from push_planner.planner_node import PlannerNode
    from sim_bridge.sim_bridge_node import SimBridgeNode

    yield "sim_bridge", SimBridgeNode(
        context=context,
        parameter_overrides=[Parameter("monitor.rate", value=10.0),
                             Parameter("image_width", value=64),
                             Parameter("image_height", value=48)])
    yield "sim_bridge", SimBridgeNode(
        context=context,
        parameter_overrides=[Parameter("robot", value="arm"), Parameter("image_width", value=64),
                             Parameter("image_height", value=48)])
    yield "perception", SegmentationNode(context=context)
    yield "perception", SegmentationNode(
        context=context, parameter_overrides=[Parameter("robot_filter.enabled", value=True)])
    sim_time = [Parameter("use_sim_time", value=True)]
    yield "estimator", EkfNode(context=context, parameter_overrides=sim_time)
    yield "planner", PlannerNode(context=context, parameter_overrides=sim_time)
    yield "push_executor", PushExecutorNode(context=context)


@pytest.mark.ros
@pytest.mark.slow
def test_topic_table_and_services_list_exactly_the_nodes_endpoints(ros_context: Any) -> None:
    rows = topic_rows()
    services = DOC.read_text(encoding="utf-8").split("Services:", 1)[1].split("\n\n", 1)[0]
    created: set[str] = set()
    problems: list[str] = []
    for label, node in _node_endpoints(ros_context):
        try:
            ends = [(p.topic_name, 0) for p in node.publishers] + \
                   [(s.topic_name, 1) for s in node.subscriptions]
            for topic, column in ends:
                if topic in ROS_INTERNAL:
                    continue
                created.add(topic)
                if topic not in rows:
                    problems.append(f"{label}: {topic} has no row")
                elif not re.search(rf"\b{label}\b|\ball nodes\b|\bevery node\b",
                                   rows[topic][column]):
                    problems.append(f"{label}: {topic} ({('publisher', 'subscriber')[column]})"
                                    f" column does not name it: {rows[topic][column]!r}")
            for service in node.services:
                leaf = service.srv_name.rsplit("/", 1)[1]
                if not re.search(r"parameter|type_description", leaf) and not (
                        f"`~/{leaf}`" in services and f"`{node.get_name()}`" in services):
                    problems.append(f"{label}: service ~/{leaf} of {node.get_name()} is not "
                                    "in the Services paragraph")
        finally:
            node.destroy_node()
    tf_available = importlib.util.find_spec("tf2_msgs") is not None
    absent = set(rows) - created - (set() if tf_available else {"/tf", "/tf_static"})
    problems += [f"{topic}: row of a topic no node creates" for topic in sorted(absent)]
    assert not problems, "\n".join(problems)
