"""The runtime nodes start on a machine without the simulator.

``segmentation_node``, ``ekf_node`` and ``planner_node`` run as real processes (``pushbot run
<node>``) in an environment where ``import pybullet`` and ``import sim_bridge`` raise
ImportError, as on a robot without the simulator: a directory on ``PYTHONPATH`` holds a
``sitecustomize.py`` whose meta-path finder refuses those names (and their submodules) before
any other finder sees them. Each node must log its ready line and answer its ``~/reset``
service from a test client. No ROS or DDS mocks: the processes talk DDS on the session's own
domain (tests/conftest.py).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from pushbot.ros2cli.discovery import call_until_answered

pytestmark = [pytest.mark.ros, pytest.mark.graph]  # starts node processes

BLOCKED = ("pybullet", "sim_bridge")
SITECUSTOMIZE = f'''
"""Test stub: the simulator is not installed (tests/ros/test_without_simulator.py)."""
import sys

BLOCKED = {BLOCKED!r}


class _NoSimulator:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"{{name}} is blocked: no simulator on this machine")
        return None


sys.meta_path.insert(0, _NoSimulator())
'''
#: node -> (the line it logs when ready, its reset service).
NODES = {
    "segmentation_node": ("segmentation node ready", "/segmentation_node/reset"),
    "ekf_node": ("ekf_node ready", "/ekf_node/reset"),
    "planner_node": ("planner ready", "/planner_node/reset"),
}
TIMEOUT = 90.0  # s: torch and the CNN weights load in the segmentation node


@pytest.fixture
def no_simulator(tmp_path: Path) -> dict[str, str]:
    """Environment additions that make pybullet and sim_bridge unimportable."""
    stub = tmp_path / "no_simulator"
    stub.mkdir()
    (stub / "sitecustomize.py").write_text(SITECUSTOMIZE)
    path = os.pathsep.join(p for p in (str(stub), os.environ.get("PYTHONPATH", "")) if p)
    return {"PYTHONPATH": path}


def test_the_blocker_blocks(no_simulator: dict[str, str], processes: Any) -> None:
    for name in BLOCKED:
        result = subprocess.run([sys.executable, "-c", f"import {name}"], capture_output=True,
                                text=True, env={**os.environ, **no_simulator}, timeout=60)
        assert result.returncode != 0 and "ImportError" in result.stderr, (name, result)
    # ... also inside a node process started like the others: the bridge cannot start.
    bridge = processes.node("sim_bridge_node", env=no_simulator)
    assert bridge.wait(timeout=60) != 0
    assert "no simulator on this machine" in processes.output(bridge)


def test_runtime_nodes_start_without_pybullet_and_sim_bridge(
        no_simulator: dict[str, str], processes: Any, ros_context: Any,
        wait_for: Callable[..., bool]) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_srvs.srv import Trigger

    procs = {name: processes.node(name, env=no_simulator) for name in NODES}
    client = Node("no_simulator_test_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client)
    try:
        deadline = time.monotonic() + TIMEOUT
        for name, (ready, service) in NODES.items():
            proc = procs[name]

            def up(proc: Any = proc, ready: str = ready) -> bool:
                return proc.poll() is not None or ready in processes.output(proc)

            assert wait_for(up, timeout=max(deadline - time.monotonic(), 1.0)), (
                f"{name} did not log {ready!r}:\n{processes.output(proc)[-3000:]}")
            assert proc.poll() is None, (
                f"{name} exited with {proc.returncode}:\n{processes.output(proc)[-3000:]}")
            log = processes.output(proc)
            assert "ImportError" not in log and "Traceback" not in log, log[-3000:]

            reset = client.create_client(Trigger, service)
            assert reset.wait_for_service(timeout_sec=30.0), f"{service} not offered"
            future = call_until_answered(reset, Trigger.Request(), executor,
                                         time.monotonic() + 30.0)
            assert future is not None, f"{service}: no answer"
            assert future.result().success, (service, future.result().message)
    finally:
        executor.shutdown()
        client.destroy_node()
