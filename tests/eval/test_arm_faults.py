"""The arm fault scenarios' bookkeeping (pushbot.runner.arm_faults), without a graph: which
scenarios exist, how long the planner said it waited for the robot, the restarted simulator's
start-up parameters. The scenarios themselves run through the real graph in
``benchmarks/bench_faults.py --robot arm``."""

from __future__ import annotations

import time

import pytest

from pushbot.runner.arm_faults import (
    ARM_SCENARIOS,
    DryRun,
    KillLater,
    make_arm_fault,
    unavailable_seconds,
)
from pushbot.runner.protocol import Trial


def test_every_scenario_is_made_fresh_and_unknown_ones_are_named() -> None:
    for name in ARM_SCENARIOS:
        a, b = make_arm_fault(name), make_arm_fault(name)
        assert a is not b and a.name == name and not a.injected
    assert DryRun.end_states == ("reached", "failed", "unavailable")
    with pytest.raises(ValueError, match="unknown arm fault scenario 'kill-arm'"):
        make_arm_fault("kill-arm")


def test_unavailable_seconds_sums_the_waits() -> None:
    statuses = [{"state": "pushing", "_wall": "10.0"}, {"state": "unavailable", "_wall": "11.0"},
                {"state": "unavailable", "_wall": "12.5"}, {"state": "waiting", "_wall": "14.0"},
                {"state": "unavailable", "_wall": "20.0"}, {"state": "pushing", "_wall": "20.5"}]
    assert unavailable_seconds(statuses) == pytest.approx(3.5)
    still = [{"state": "unavailable", "_wall": f"{time.monotonic() - 2.0:.6f}"}]
    assert unavailable_seconds(still) >= 2.0  # still waiting: up to now


class _Recorded:
    true = [(5.0, (0.01, -0.02, 0.3))]


class _Runner:
    rec = _Recorded()


def test_the_restarted_simulator_gets_the_scene_and_the_true_pose() -> None:
    trial = Trial(object="butter", task="mixed", method="ana", k=3, state="filter",
                  com="random", index=2, seed=0)

    class _Episode:
        pass

    episode = _Episode()
    episode.trial = trial
    args = KillLater("sim_bridge_node", "kill-arm-sim").restart_args(_Runner(), episode)
    values = dict(a.split(":=", 1) for a in args)
    assert values["object"] == "butter" and values["randomize"] in ("true", "false")
    assert float(values["initial_pose.x"]) == pytest.approx(0.01)
    assert float(values["initial_pose.theta"]) == pytest.approx(0.3)
    assert values["com_offset"].startswith("[") and values["seed"].isdigit()
    assert KillLater("push_executor_node", "kill-executor").restart_args(_Runner(), episode) \
        == []


def test_a_restarted_clock_forgets_the_stamped_records() -> None:
    import numpy as np

    from pushbot.runner.client import Recorded

    rec = Recorded()
    rec.true.append((500.0, np.zeros(3)))
    rec.est.append((500.0, np.zeros(3)))
    rec.executed.append((1.0, 490.0, 495.0))
    rec.outline_stamps.append(400.0)
    rec.status.append({"state": "reached"})
    rec.pushes.append((1.0, np.zeros((3, 2))))
    rec.forget_stamps()
    assert not (rec.true or rec.est or rec.executed or rec.outline_stamps)
    assert rec.status and rec.pushes  # matched by arrival, not by stamp: kept
