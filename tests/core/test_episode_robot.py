"""push_core.episode rules 9 and 10: an unavailable robot pauses the episode (no step spent,
resumed from a fresh estimate, failed after ``robot_timeout``); a restarted clock forgets the
old clock's stamps."""

from __future__ import annotations

import numpy as np
import pytest

from push_core.episode import EpisodeEngine
from push_core.objects import load_object
from push_core.planner import Planner, PlannerConfig, prepare_outline

SPEC = load_object("rect1")
STATE0 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, SPEC.limit_surface_guess(), 0.3])


def engine(robot_timeout: float = 60.0) -> EpisodeEngine:
    e = EpisodeEngine(Planner(PlannerConfig(k=1, seed=3)), 30, robot_timeout=robot_timeout)
    e.set_outline(prepare_outline(*SPEC.outline(0.002)))
    e.new_goal([0.1, 0.0, 0.0])
    return e


def test_an_unavailable_robot_spends_no_step_and_resumes_from_a_fresh_estimate() -> None:
    e = engine()
    e.estimate(1.0, STATE0)
    assert e.step().action == "push" and e.steps == 1
    e.robot_unavailable("disabled: executor disabled (dry run)", now=100.0)
    assert e.phase == "unavailable" and e.steps == 0 and not e.in_flight
    assert e.status_text() == "robot unavailable: disabled: executor disabled (dry run)"
    assert e.step().action == "wait"  # nothing planned while waiting ...
    e.estimate(2.0, STATE0)
    assert e.step().action == "wait" and e.steps == 0  # ... whatever arrives
    assert not e.finished and e.robot_waited(now=159.0) is None
    assert e.robot_available(fresh_after=5.0)
    assert e.phase == "waiting" and e.unavailable == ""
    assert e.step().action == "wait"  # the estimate of 2 s predates the robot's return
    e.estimate(4.5, STATE0)
    assert e.counts["ignored_stale"] == 1 and e.step().action == "wait"
    e.estimate(5.5, STATE0)
    step = e.step()
    assert step.action == "push" and e.steps == 1 and e.counts["lost"] == 0
    assert not e.robot_available(6.0)  # not waiting: nothing changes
    assert e.counts["robot_unavailable"] == 1


def test_a_push_the_robot_had_started_counts_as_lost() -> None:
    e = engine()
    e.estimate(1.0, STATE0)
    e.step()
    e.robot_unavailable("no_state: no joint state for 1.0 s", now=0.0, moved=True)
    assert e.steps == 1 and e.counts["lost"] == 1 and e.phase == "unavailable"
    e.robot_available(2.0)
    assert e.phase == "pushing"  # the episode had a step: back to pushing


def test_the_wait_times_out_with_its_reason() -> None:
    e = engine(robot_timeout=30.0)
    e.estimate(1.0, STATE0)
    e.step()
    e.robot_unavailable("no_controller: no controller subscribes", now=10.0)
    e.robot_unavailable("no_controller: no controller subscribes", now=20.0)  # same wait
    assert e.robot_waited(now=40.0) is None
    step = e.robot_waited(now=40.5)
    assert step is not None and step.action == "failed" and e.finished
    assert e.failure == "robot unavailable" and "30 s" in step.reason
    assert e.status_text().startswith("failed: robot unavailable for 30 s")
    assert e.status_text().endswith("no_controller: no controller subscribes")
    assert e.step().action == "wait"


def test_an_executed_push_restarts_the_wait_clock() -> None:
    e = engine(robot_timeout=30.0)
    e.estimate(1.0, STATE0)
    e.step()
    e.robot_unavailable("no_state: x", now=0.0)
    e.robot_available(1.5)
    e.estimate(2.0, STATE0)
    e.step()
    e.push_executed(3.0)
    e.estimate(4.0, STATE0)
    e.step()
    e.robot_unavailable("no_state: x", now=100.0)
    assert e.robot_waited(now=125.0) is None  # timed from 100 s, not from 0 s


def test_a_new_goal_while_waiting_is_a_new_episode() -> None:
    e = engine()
    e.estimate(1.0, STATE0)
    e.step()
    e.robot_unavailable("disabled: dry run", now=0.0)
    e.new_goal([0.05, 0.0, 0.0])
    assert e.phase == "waiting" and e.unavailable == "" and e.step().action == "push"


def test_a_restarted_clock_forgets_the_old_stamps() -> None:
    e = engine()
    e.estimate(500.0, STATE0)
    e.step()
    e.push_executed(510.0)
    e.estimate(3.0, STATE0)  # the restarted simulator's clock: before the last push's end
    assert e.step().action == "wait"
    e.clock_restarted()
    assert e.last_push_end == -np.inf and e.latest is None
    e.estimate(4.0, STATE0)
    assert e.step().action == "push" and e.counts["clock_restarts"] == 1


def test_robot_timeout_is_validated() -> None:
    with pytest.raises(ValueError, match="robot_timeout"):
        EpisodeEngine(Planner(), 3, robot_timeout=0.0)
