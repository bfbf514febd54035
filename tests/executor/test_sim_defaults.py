"""The executor's defaults describe the simulated Panda: the same base pose, park posture and
tool as sim_bridge's arm mode (the simulated graph starts the executor on its defaults)."""

from __future__ import annotations

import numpy as np

from push_executor.parameters import PARAMETERS
from sim_bridge.arm_robot import DEFAULT_BASE_POSE, DEFAULT_PARK, ROD_LENGTH
from sim_bridge.params import PARAMETERS as SIM_PARAMETERS


def test_executor_defaults_are_the_simulated_arm_s() -> None:
    executor = {p.name: p.default for p in PARAMETERS}
    sim = {p.name: p.default for p in SIM_PARAMETERS}
    np.testing.assert_allclose(executor["base_pose"], DEFAULT_BASE_POSE)
    np.testing.assert_allclose(executor["park_positions"], DEFAULT_PARK)
    np.testing.assert_allclose(sim["arm.base_pose"], DEFAULT_BASE_POSE)
    assert executor["tool.length"] == ROD_LENGTH
    assert executor["tool.flange_offset"] == 0.0
    assert executor["tool.radius"] == sim["pusher_radius"]
    assert executor["controller_topic"] == sim["arm.controller_topic"]

