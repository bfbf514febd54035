"""The runner offers a fault everything :class:`pushbot.runner.scenario.FaultTarget` names."""

from __future__ import annotations

import inspect

from pushbot.runner.episode import GraphRunner
from pushbot.runner.scenario import FaultTarget


def test_the_graph_runner_is_a_fault_target() -> None:
    runner = GraphRunner()  # not started: no process, no ROS context
    try:
        for name in FaultTarget.__annotations__:
            assert hasattr(runner, name), name
        for name, member in inspect.getmembers(FaultTarget, inspect.isfunction):
            if name.startswith("_"):
                continue
            ours = getattr(runner, name)
            assert callable(ours), name
            assert (list(inspect.signature(ours).parameters)
                    == list(inspect.signature(member).parameters)[1:]), name
    finally:
        runner.close()
