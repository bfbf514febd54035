"""Fault scenarios of graph episodes: what goes wrong, when, and how.

A :class:`Fault` is handed to :meth:`pushbot.runner.episode.GraphRunner.run`; the runner asks it
for extra episode parameters (the bridge's ``faults.*``, the planner's ``after_goal``), calls
:meth:`Fault.poll` on every spin of its end-of-episode wait (where it injects the fault through
the graph's public interfaces or by killing a process) and accepts an end status only when
:meth:`Fault.accepts_end` agrees. The hooks see the runner as a
:class:`pushbot.runner.scenario.FaultTarget` and the episode as a
:class:`pushbot.runner.scenario.Episode`. Everything is real: node processes killed with
SIGKILL and started again with ``pushbot run``, messages through DDS.

Scenarios (:data:`SCENARIOS`, ``benchmarks/bench_faults.py`` runs them;
docs/design/faults.md#scenarios):

- ``kill-<node>`` (:class:`KillRestart`): after the episode's first executed push, SIGKILL
  ``segmentation_node``, ``ekf_node`` or ``planner_node`` and start it again (a restarted
  planner gets the trial's episode parameters as start-up parameters, as a launch file's YAML
  would give them). The episode must still end at the goal by ground truth.
- ``frame-drop`` / ``frame-delay`` / ``push-refusal`` (:class:`BridgeFaults`): the bridge's
  seeded ``faults.frame_drop`` (20 %), ``faults.frame_delay`` (30 %: a frame held back and
  published right after the next newer one) or ``faults.push_refusal`` (20 %) for the whole episode.
- ``knock`` (:class:`Knock`): once the planner says ``goal reached``, the object is displaced on
  ``sim/knock``; the planner (``after_goal: resume`` for this episode) must see it leave the
  region, push again and reach the goal again.
- ``foreign-push`` (:class:`ForeignPush`): once the planner says ``goal reached``, another
  client sends a push on ``planner/push`` (along 0.5 rad in ``world``, from 2 cm outside the
  object's circumscribed circle to 2 cm past its origin, at the true pose); the bridge
  executes it and the planner must push the object back.
- ``second-goal`` (:class:`SecondGoal`): after the first executed push another client (a
  volatile sender, like RViz) sends a different goal; the planner takes it, says so
  (``goal_switches``) and the episode is scored against that goal.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from pushbot.runner.protocol import Trial, planner_episode_params
from pushbot.runner.scenario import Episode, FaultTarget

__all__ = ["SCENARIOS", "BridgeFaults", "Fault", "ForeignPush", "KillRestart",
           "Knock", "SecondGoal", "make_fault"]

#: The knock of the ``knock`` scenario: (dx, dy) m and dyaw rad, far outside every goal region.
KNOCK = (0.03, -0.02, 0.25)
#: The bridge's ``/diagnostics`` counters a record keeps.
BRIDGE_COUNTERS = ("frames_dropped", "frames_delayed", "frames_reordered",
                   "pushes_refused_fault", "knocks", "pushes_executed")
#: Direction (rad, world) of the push another client sends in ``foreign-push`` and how far past
#: the object's origin it ends (m): it starts 2 cm outside the circumscribed circle.
FOREIGN_PUSH_DIRECTION, FOREIGN_PUSH_PAST_CENTRE = 0.5, 0.02
#: The second goal of ``second-goal``: offset from the first goal (dx, dy m, dtheta rad).
SECOND_GOAL_SHIFT = (-0.04, 0.03, -0.2)


class Fault:
    """No fault (the base of the scenarios); see the module docstring."""

    name = "none"
    #: ``planner/status`` states that end the episode (when :meth:`accepts_end` agrees).
    end_states: tuple[str, ...] = ("reached", "failed")

    def __init__(self) -> None:
        self.injected = False
        self._status_at_injection = 0

    def bridge_params(self, trial: Trial) -> dict[str, Any]:
        """``sim_bridge_node`` parameters for this episode (``faults.*``)."""
        return {}

    def planner_params(self) -> dict[str, Any]:
        """Extra ``planner_node`` episode parameters."""
        return {}

    def before_goal(self, runner: FaultTarget) -> None:
        """Act before the episode's goal is sent (e.g. disable the executor)."""

    def poll(self, runner: FaultTarget, episode: Episode) -> None:
        """Inject the fault when its moment has come (called on every spin of the wait)."""

    def after_episode(self, runner: FaultTarget) -> None:
        """Undo what the fault left behind once the episode ended (or failed)."""

    def accepts_end(self, runner: FaultTarget, index: int) -> bool:
        """Whether the end status at ``runner.rec.status[index]`` ends the episode."""
        return True

    def _mark(self, runner: FaultTarget) -> None:
        self.injected = True
        self._status_at_injection = len(runner.rec.status)

    def record(self, runner: FaultTarget, episode: Episode) -> dict[str, Any]:
        """Fault fields of the episode record."""
        mine = runner.rec.status[episode.n_status:]
        last = mine[-1] if mine else {}
        diagnostics = runner.rec.diagnostics
        bridge = diagnostics.get("/sim_bridge_node: simulation", {})
        perception = diagnostics.get("/segmentation_node: perception", {})
        # The bridge's counters since its start (the bench reads differences), the
        # perception's since its (re)start.
        return {"fault": self.name, "fault_injected": self.injected,
                "pushes_sent": len(runner.rec.pushes) - episode.n_push,
                "goal_switches": int(last.get("goal_switches", 0)),
                "left_goal": max((int(s.get("left_goal", 0)) for s in mine), default=0),
                "bridge_counts": {k: int(bridge.get(k, 0)) for k in BRIDGE_COUNTERS},
                "perception_anchored": int(perception.get("anchored", 0)),
                **episode.notes}


def _executed(runner: FaultTarget, episode: Episode) -> int:
    return len(runner.rec.executed) - episode.n_exec


#: Longest wait for a restarted estimator's first estimate, s of wall time (process start
#: with its imports included; the camera's next frame follows within 1 / idle_frame_rate).
RESTART_ESTIMATE_TIMEOUT = 60.0


class KillRestart(Fault):
    """SIGKILL a node after ``after`` executed pushes of the episode and start it again."""

    def __init__(self, node: str, after: int = 1) -> None:
        super().__init__()
        self.node, self.after = node, int(after)
        self.name = f"kill-{node.removesuffix('_node')}"

    def poll(self, runner: FaultTarget, episode: Episode) -> None:
        if self.injected or _executed(runner, episode) < self.after:
            return
        extra: list[str] = []
        if self.node == "planner_node":
            extra = planner_start_args(episode.trial)
        elif self.node == "ekf_node":  # the episode's filter variant (Trial.relearn)
            extra = [f"relearn.enabled:={str(episode.trial.relearn).lower()}"]
        n_estimates = len(runner.rec.est)
        restarted = time.monotonic()
        runner.nodes.kill_and_restart(self.node, extra)
        self._mark(runner)
        episode.notes["killed_after_pushes"] = _executed(runner, episode)
        if self.node == "ekf_node":  # the new estimator's first estimate (the camera streams)
            runner.wait(lambda: len(runner.rec.est) > n_estimates, RESTART_ESTIMATE_TIMEOUT,
                        "the restarted ekf_node's first estimate")
            episode.notes["first_estimate_after_restart_s"] = time.monotonic() - restarted

    def accepts_end(self, runner: FaultTarget, index: int) -> bool:
        # An end status of the killed planner's predecessor cannot come after the kill; for the
        # others the episode must run on after the restart.
        return self.injected and index >= self._status_at_injection


class BridgeFaults(Fault):
    """The bridge's seeded fault injection (``faults.*``) for the whole episode."""

    def __init__(self, name: str, **faults: float) -> None:
        super().__init__()
        self.name = name
        self.faults = {f"faults.{k}": float(v) for k, v in faults.items()}
        self.injected = True

    def bridge_params(self, trial: Trial) -> dict[str, Any]:
        return {**self.faults, "faults.seed": int(trial.world_kwargs()["seed"])}


class Knock(Fault):
    """Displace the object on ``sim/knock`` once the planner reports ``goal reached``."""

    name = "knock"

    def __init__(self, delta: tuple[float, float, float] = KNOCK) -> None:
        super().__init__()
        self.delta = np.asarray(delta, dtype=float)
        self._left_before = 0

    def planner_params(self) -> dict[str, Any]:
        return {"after_goal": "resume"}

    def poll(self, runner: FaultTarget, episode: Episode) -> None:
        if self.injected:
            return
        mine = runner.rec.status[episode.n_status:]
        if any(s.get("state") == "reached" for s in mine) and runner.client_matched():
            self._left_before = max((int(s.get("left_goal", 0)) for s in mine), default=0)
            runner.knock(self.delta)
            self._mark(runner)
            episode.notes["knocked_after_pushes"] = _executed(runner, episode)

    def accepts_end(self, runner: FaultTarget, index: int) -> bool:
        # Only a "goal reached" after the planner saw the object leave (and pushed it back).
        if not self.injected or index < self._status_at_injection:
            return False
        return int(runner.rec.status[index].get("left_goal", 0)) > self._left_before


class ForeignPush(Knock):
    """Another client sends a push on ``planner/push`` once the planner reports ``goal
    reached`` (someone else moving the object a few cm out of the goal region): the bridge
    executes it like any push and the planner, watching after the goal, must see the object
    leave and push it back."""

    name = "foreign-push"

    def poll(self, runner: FaultTarget, episode: Episode) -> None:
        if self.injected:
            return
        mine = runner.rec.status[episode.n_status:]
        if not (any(s.get("state") == "reached" for s in mine) and runner.rec.true
                and runner.client_matched()):
            return
        from push_core.objects import load_object

        self._left_before = max((int(s.get("left_goal", 0)) for s in mine), default=0)
        centre = runner.rec.true[-1][1][:2]
        radius = float(np.max(np.linalg.norm(load_object(episode.trial.object).polyline(),
                                             axis=1)))
        d = np.array([math.cos(FOREIGN_PUSH_DIRECTION), math.sin(FOREIGN_PUSH_DIRECTION)])
        approach = centre - d * (radius + 0.02)
        contact = centre - d * radius
        runner.foreign_push(np.array([approach, contact,
                                      centre + d * FOREIGN_PUSH_PAST_CENTRE]))
        self._mark(runner)
        episode.notes["pushed_after_pushes"] = _executed(runner, episode)


class SecondGoal(Fault):
    """Another client sends a different goal after ``after`` executed pushes."""

    name = "second-goal"

    def __init__(self, shift: tuple[float, float, float] = SECOND_GOAL_SHIFT,
                 after: int = 1) -> None:
        super().__init__()
        self.shift, self.after = np.asarray(shift, dtype=float), int(after)

    def poll(self, runner: FaultTarget, episode: Episode) -> None:
        if self.injected or _executed(runner, episode) < self.after:
            return
        if not runner.client_matched():
            return
        first_goal = episode.goal.copy()
        episode.goal = first_goal + self.shift
        episode.offset = episode.offset + self.shift
        episode.goal_text = runner.send_goal(episode.goal, other=True)
        self._mark(runner)
        episode.notes["first_goal"] = first_goal.tolist()

    def accepts_end(self, runner: FaultTarget, index: int) -> bool:
        return self.injected and index >= self._status_at_injection


def planner_start_args(trial: Trial) -> list[str]:
    """The trial's episode parameters of ``planner_node`` as ``name:=value`` start-up
    parameters (what a restarted planner is started with)."""
    return [f"{name}:={str(value).lower() if isinstance(value, bool) else value}"
            for name, value in planner_episode_params(trial).items()]


#: name -> factory of the scenario's fault.
SCENARIOS = {
    "none": Fault,
    "kill-segmentation": lambda: KillRestart("segmentation_node"),
    "kill-ekf": lambda: KillRestart("ekf_node"),
    "kill-planner": lambda: KillRestart("planner_node"),
    "frame-drop": lambda: BridgeFaults("frame-drop", frame_drop=0.2),
    "frame-delay": lambda: BridgeFaults("frame-delay", frame_delay=0.3),
    "push-refusal": lambda: BridgeFaults("push-refusal", push_refusal=0.2),
    "knock": Knock,
    "foreign-push": ForeignPush,
    "second-goal": SecondGoal,
}


def make_fault(name: str) -> Fault:
    """A fresh fault of scenario ``name`` (:data:`SCENARIOS`); ``ValueError`` if unknown."""
    try:
        return SCENARIOS[name]()
    except KeyError:
        raise ValueError(f"unknown fault scenario {name!r}; known: "
                         f"{', '.join(SCENARIOS)}") from None
