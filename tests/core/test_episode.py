"""push_core.episode: the one set of closed-loop rules (stale estimates, stop, lost pushes)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_core.episode import ORIENTATION_IGNORED, EpisodeEngine
from push_core.objects import load_object
from push_core.planner import AVOID_RADIUS, Planner, PlannerConfig, prepare_outline

SPEC = load_object("rect1")
STATE0 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, SPEC.limit_surface_guess(), 0.3])


def engine(max_steps: int = 30) -> EpisodeEngine:
    e = EpisodeEngine(Planner(PlannerConfig(k=1, seed=3)), max_steps)
    e.set_outline(prepare_outline(*SPEC.outline(0.002)))
    return e


def state_at(x: float, y: float = 0.0, theta: float = 0.0) -> np.ndarray:
    s = STATE0.copy()
    s[:3] = (x, y, theta)
    return s


def test_one_plan_per_usable_estimate_and_the_stale_rule() -> None:
    e = engine()
    assert e.step().action == "wait"  # no goal, no estimate
    e.new_goal([0.1, 0.0, 0.0])
    assert e.step().action == "wait"  # no estimate
    e.estimate(10.0, state_at(0.0))
    first = e.step()
    assert first.action == "push" and e.steps == 1 and e.in_flight
    assert e.step().action == "wait"  # used once; a push is in flight
    e.estimate(11.0, state_at(0.0))  # while the push is in flight
    assert e.counts["ignored_busy"] == 1 and e.step().action == "wait"
    e.push_executed(12.0)
    assert e.step().action == "wait"  # the newest estimate (11 s) predates the push's end
    e.estimate(11.5, state_at(0.0))
    assert e.counts["ignored_stale"] == 1
    e.estimate(13.0, state_at(0.03))
    assert e.step().action == "push" and e.steps == 2
    e.push_executed(14.0)
    e.estimate(13.0, state_at(0.03))  # an old one again
    assert e.counts["ignored_stale"] == 2 and e.step().action == "wait"
    assert e.counts["planned"] == 2


def test_stop_rule_and_max_steps() -> None:
    e = engine(max_steps=1)
    e.new_goal([0.1, 0.0, 0.0])
    e.estimate(1.0, state_at(0.0))
    assert e.step().action == "push"
    e.push_executed(2.0)
    e.estimate(3.0, state_at(0.05))
    out = e.step()
    assert out.action == "failed" and out.reason == "max steps" and e.finished
    # a new goal is a new episode: the same (newest) estimate is re-opened, and at the goal
    e.new_goal([0.05, 0.0, 0.0])
    assert e.steps == 0 and e.step().action == "reached" and e.phase == "reached"
    # within the region by the point estimate, not with 2 mm standard deviation
    e.new_goal([0.055, 0.0, 0.0])
    e.estimate(4.0, state_at(0.05), np.diag([4e-6, 4e-6, 1e-6, 0, 0, 0, 0]))
    assert e.step().action == "push"


def test_a_lost_push_is_a_step_its_region_is_avoided_and_the_estimate_reopened() -> None:
    e = engine()
    e.new_goal([0.1, 0.0, 0.0])
    e.estimate(1.0, state_at(0.0))
    a = e.step().plan
    e.push_lost()
    b = e.step().plan  # the same estimate, planned again without waiting for a new one
    assert b is not None and e.steps == 2 and e.counts["lost"] == 1
    pts = e.outline.points
    assert np.linalg.norm(pts[b.index] - pts[a.index]) > AVOID_RADIUS
    e.push_executed(2.0)  # executed: the avoid list is cleared
    assert e._avoid == []


def test_a_push_lost_while_the_robot_may_move_waits_for_a_newer_estimate() -> None:
    # A "busy" / "fault" / "cancelled" refusal: planning again from the same estimate would
    # send a push while the robot still moves (a tight loop of busy refusals otherwise).
    e = engine()
    e.new_goal([0.1, 0.0, 0.0])
    e.estimate(1.0, state_at(0.0))
    assert e.step().action == "push"
    e.push_lost(wait_for_estimate=True)
    assert e.steps == 1 and e.counts["lost"] == 1 and not e.in_flight
    assert e.step().action == "wait"  # not from the estimate of 1 s again
    e.estimate(2.0, state_at(0.01))
    assert e.step().action == "push" and e.steps == 2


def test_bad_events_name_themselves() -> None:
    e = engine()
    with pytest.raises(ValueError, match="goal"):
        e.new_goal([0.0, math.nan, 0.0])
    with pytest.raises(ValueError, match="estimate"):
        e.estimate(1.0, [0.0] * 6)
    with pytest.raises(ValueError, match="max_steps"):
        EpisodeEngine(Planner(), 0)


def reached_engine(after_goal: str = "resume", max_steps: int = 30) -> EpisodeEngine:
    e = EpisodeEngine(Planner(PlannerConfig(k=1, seed=3)), max_steps, after_goal=after_goal)
    e.set_outline(prepare_outline(*SPEC.outline(0.002)))
    e.new_goal([0.1, 0.0, 0.0])
    e.estimate(1.0, state_at(0.0))
    assert e.step().action == "push"
    e.push_executed(2.0)
    e.estimate(3.0, state_at(0.099))
    assert e.step().action == "reached" and e.phase == "reached" and e.steps == 1
    return e


def test_after_the_goal_the_point_estimate_is_watched_and_pushing_resumes() -> None:
    e = reached_engine()
    # Uncertain but the point estimate inside the region: still reached, nothing planned.
    e.estimate(4.0, state_at(0.095), np.diag([1e-4, 1e-4, 1e-4, 0, 0, 0, 0]))
    assert e.step().action == "wait" and e.phase == "reached" and e.counts["left"] == 0
    # An injected push (not ours) knocks the object 3 cm off: reported, and pushing resumes
    # from that estimate within the same max_steps.
    e.push_executed(5.0)
    e.estimate(4.5, state_at(0.07))  # predates the injected push: stale
    assert e.step().action == "wait" and e.phase == "reached"
    e.estimate(6.0, state_at(0.07))
    step = e.step()
    assert step.action == "push" and step.resumed and "30.0 mm" in step.reason
    assert e.phase == "pushing" and e.steps == 2 and e.counts["left"] == 1
    e.push_executed(7.0)
    e.estimate(8.0, state_at(0.1))
    assert e.step().action == "reached"


def test_after_the_goal_report_only_and_max_steps_still_bound_a_resumed_episode() -> None:
    e = reached_engine("report")
    e.estimate(4.0, state_at(0.05))
    step = e.step()
    assert step.action == "left" and e.phase == "left" and "50.0 mm" in step.reason
    e.estimate(5.0, state_at(0.05))
    assert e.step().action == "wait" and e.steps == 1 and not e.in_flight  # never pushed for
    e.estimate(6.0, state_at(0.1))  # put back: reached again
    assert e.step().action == "reached" and e.counts["left"] == 1
    # resume, but the episode's one step is used: it fails after max steps
    e = reached_engine(max_steps=1)
    e.estimate(4.0, state_at(0.05))
    step = e.step()
    assert step.action == "failed" and step.reason == "max steps" and step.resumed
    with pytest.raises(ValueError, match="after_goal"):
        EpisodeEngine(Planner(), 3, after_goal="ignore")


def test_status_text_says_the_phase_and_what_is_missing() -> None:
    e = EpisodeEngine(Planner(PlannerConfig(k=1, seed=3)), max_steps=1)
    assert e.status_text() == "waiting for goal, outline, estimate"
    e.set_outline(prepare_outline(*SPEC.outline(0.002)))
    e.new_goal([0.1, 0.0, 0.0])
    assert e.status_text() == "waiting for estimate" and e.orientation_matters
    e.estimate(1.0, state_at(0.0))
    assert e.status_text() == "waiting"
    assert e.step().action == "push" and e.status_text() == "pushing step 1"
    e.push_executed(2.0)
    e.estimate(3.0, state_at(0.05))
    assert e.step().action == "failed" and e.status_text() == "failed after max steps"
    e.new_goal([0.05, 0.0, 0.0])
    assert e.step().action == "reached" and e.status_text() == "goal reached"
    # a disc: reached whatever the orientation, and the text says why
    e.set_outline(prepare_outline(*load_object("ellip1").outline(0.002)))
    e.new_goal([0.05, 0.0, 1.0])
    assert e.step().action == "reached" and not e.orientation_matters
    assert e.status_text() == f"goal reached ({ORIENTATION_IGNORED})"


def test_status_text_of_a_report_only_left_goal_and_of_no_feasible_push() -> None:
    e = reached_engine(after_goal="report")
    e.estimate(20.0, state_at(0.0))
    assert e.step().action == "left" and e.status_text() == "goal left"
    e.phase, e.failure = "failed", "no feasible push"
    assert e.status_text() == "failed: no feasible push"


def test_precedes_episode_window() -> None:
    from push_core.episode import PREVIOUS_EPISODE_WINDOW, precedes_episode

    assert precedes_episode(10.0, 10.0) and precedes_episode(9.5, 10.0)  # in flight at reset
    assert precedes_episode(10.0 - PREVIOUS_EPISODE_WINDOW, 10.0)
    assert not precedes_episode(10.5, 10.0)  # the camera's next frame
    assert not precedes_episode(0.1, 10.0)  # a restarted clock (simulator restarted)
    assert not precedes_episode(1.0, -float("inf"))  # no boundary before the first reset
