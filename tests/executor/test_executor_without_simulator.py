"""push_executor_node starts on a machine without the simulator.

The pattern of tests/ros/test_without_simulator.py (its ``no_simulator`` fixture, reused: a
``sitecustomize.py`` on ``PYTHONPATH`` makes ``import pybullet`` and ``import sim_bridge`` raise
ImportError): the node runs as a real process (its console script), loads the Panda URDF from
a file, logs its ready line and answers ``~/enable`` from a test client over DDS.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from pushbot.ros2cli.discovery import call_until_answered

from .test_kinematics import panda_urdf

pytestmark = [pytest.mark.ros, pytest.mark.graph]  # starts node processes

_spec = importlib.util.spec_from_file_location(
    "_without_simulator", Path(__file__).resolve().parents[1] / "ros" /
    "test_without_simulator.py")
_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_module)
no_simulator = _module.no_simulator  # the fixture


def test_push_executor_starts_without_pybullet_and_sim_bridge(
        no_simulator: dict[str, str], processes: Any, ros_context: Any,
        wait_for: Callable[..., bool], tmp_path: Path) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_srvs.srv import SetBool


    urdf = tmp_path / "panda.urdf"
    urdf.write_text(panda_urdf())
    proc = processes.start([str(Path(sys.executable).parent / "push_executor_node"),
                            "--ros-args", "-p", f"robot_description_file:={urdf}"],
                           env=no_simulator)
    client = Node("executor_no_simulator_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    try:
        assert wait_for(lambda: proc.poll() is not None
                        or "push executor ready" in processes.output(proc), timeout=60.0), \
            processes.output(proc)[-3000:]
        assert proc.poll() is None, processes.output(proc)[-3000:]
        log = processes.output(proc)
        assert "ImportError" not in log and "Traceback" not in log, log[-3000:]
        enable = client.create_client(SetBool, "/push_executor_node/enable")
        assert enable.wait_for_service(timeout_sec=30.0)
        future = call_until_answered(enable, SetBool.Request(data=True), executor,
                                     time.monotonic() + 30.0)
        assert future is not None, "/push_executor_node/enable: no answer in 30 s"
        assert future.result().success and future.result().message == "enabled"
        # The simulator really was unimportable in that process's environment.
        check = processes.start([sys.executable, "-c", "import pybullet"], env=no_simulator)
        assert check.wait(timeout=60) != 0
        assert "no simulator on this machine" in processes.output(check)
    finally:
        executor.shutdown()
        client.destroy_node()
