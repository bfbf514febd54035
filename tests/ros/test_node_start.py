"""The node runtime on the user's path (push_ros.node): ROS that cannot start is one line and
exit status 2, not a traceback; parameters a node does not declare (``-p kk:=3``, a misspelt
name in a ``--params-file``) are warned about with the closest declared name."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from push_ros.node import ParamSpec, declare_config, ros_start_error, unknown_parameters

pytestmark = pytest.mark.ros

SPECS = (ParamSpec("k", 3, "Points."), ParamSpec("max_steps", 30, "Pushes."),
         ParamSpec("goal_tolerance.xy", 0.0075, "m."))


def test_unknown_parameters_name_the_closest_known_one() -> None:
    names = [s.name for s in SPECS]
    assert unknown_parameters(["kk", "k", "use_sim_time", "max_step", "goal_tolerance.yx"],
                              names) == [
        "unknown parameter 'goal_tolerance.yx' ignored (did you mean 'goal_tolerance.xy'?)",
        "unknown parameter 'kk' ignored (did you mean 'k'?)",
        "unknown parameter 'max_step' ignored (did you mean 'max_steps'?)"]
    far = unknown_parameters(["zzzzzz"], names)
    assert len(far) == 1 and "not a parameter of this node; its parameters: " in far[0]


def test_a_params_file_and_command_line_typo_are_warned_about(tmp_path: Path,
                                                              capfd: Any) -> None:
    """Through rcl's own argument and parameter-file parsing (a real context)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    params = tmp_path / "node.yaml"
    params.write_text("typo_node:\n  ros__parameters:\n    max_step: 5\n    k: 2\n")
    context = Context()
    rclpy.init(args=["--ros-args", "--params-file", str(params), "-p", "kk:=3"],
               context=context)
    try:
        node = Node("typo_node", context=context)
        values = declare_config(node, SPECS, dict)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    assert values["k"] == 2 and values["max_steps"] == 30  # the typo changed nothing
    err = capfd.readouterr().err
    assert "unknown parameter 'kk' ignored (did you mean 'k'?)" in err
    assert "unknown parameter 'max_step' ignored (did you mean 'max_steps'?)" in err


def test_security_enforce_without_a_keystore_is_one_line_and_exit_2() -> None:
    exe = Path(sys.executable).parent / "pushbot"
    env = {k: v for k, v in os.environ.items() if not k.startswith("ROS_SECURITY_")}
    env.update(ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY="Enforce")
    result = subprocess.run([str(exe), "run", "planner_node"], capture_output=True, text=True,
                            timeout=120, env=env, stdin=subprocess.DEVNULL)
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("planner_node: cannot start ROS: failed to initialize rcl")
    assert "ROS_SECURITY_ENABLE=true, ROS_SECURITY_STRATEGY=Enforce" in lines[0]
    assert "docs/SECURITY.md" in lines[0]


def test_ros_start_error_without_security_points_at_doctor(monkeypatch: Any) -> None:
    monkeypatch.delenv("ROS_SECURITY_ENABLE", raising=False)
    text = ros_start_error(RuntimeError("failed to initialize rcl: bad domain\nmore"))
    assert text.startswith("cannot start ROS: failed to initialize rcl: bad domain (")
    assert "pushbot doctor" in text and "\n" not in text
