"""Acceptance test of the planner in closed loop with pybullet physics.

In-process, no ROS: ground-truth state (``pushbot.experiments.planner_loop``), the ``ana``
planner with one sampled contact point (k = 1), the translation task with 10 cm: the goal must
be reached (0.75 cm, 5 deg) within 30 pushes in at least 95 % of 20 seeded trials per object.
Trial i starts at the workspace centre with orientation ``2 pi i / 20`` and a goal 10 cm away in a
direction drawn from ``default_rng([i, 6])``; the planner's seed is i. Every push the planner
sends must be accepted by the world (valid geometry, inside the workspace).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.planner import Planner, PlannerConfig
from pushbot.experiments.planner_loop import run_episode, translation_goal
from sim_bridge.world import PushWorld, WorldConfig

pytestmark = pytest.mark.slow

TRIALS = 20
MAX_STEPS = 30
MIN_SUCCESS = 0.95


@pytest.mark.parametrize("obj", ["rect1", "butter"])
def test_translation_task_ana_k1(obj: str) -> None:
    results = []
    with PushWorld(WorldConfig(object=obj)) as world:
        for i in range(TRIALS):
            world.set_object_pose([0.0, 0.0, 2.0 * math.pi * i / TRIALS])
            direction = np.random.default_rng([i, 6]).uniform(0.0, 2.0 * math.pi)
            goal = translation_goal(world.object_pose(), 0.10, direction)
            planner = Planner(PlannerConfig(method="ana", k=1, seed=i))
            results.append(run_episode(world, planner, goal, max_steps=MAX_STEPS))
    success = np.mean([r.success for r in results])
    steps = [r.steps for r in results if r.success]
    summary = (f"{obj}: success {success:.2f}, steps {np.mean(steps):.1f} +- {np.std(steps):.1f}"
               f", refused {sum(r.refused for r in results)}")
    print(summary)
    assert success >= MIN_SUCCESS, summary
    assert all(r.refused == 0 for r in results), summary
    assert all(r.steps <= MAX_STEPS for r in results)
    for r in results:  # success means the last pose is within the tolerances
        if r.success:
            assert r.final_error_xy <= 0.0075 and r.final_error_theta <= math.radians(5.0)
