"""Fault scenarios of the arm graph (``robot`` arm): the executor, the simulated arm and its
controller failing mid-push, and the dry run.

Like :mod:`pushbot.runner.faults` (whose :class:`~pushbot.runner.faults.Fault` they extend),
everything is real: node processes killed with SIGKILL (and started again with ``pushbot
run``) or stopped with SIGSTOP, messages through DDS. The mid-push scenarios wait for the
episode's first executed push, then for the next ``planner/push`` and :data:`INTO_PUSH` s
more (the arm is moving), and act:

- ``kill-executor``: SIGKILL ``push_executor_node``, start it again :data:`DOWN` s later;
- ``kill-arm-sim``: SIGKILL ``sim_bridge_node`` (the simulated arm, its controller, camera and
  clock), start it again :data:`DOWN` s later with the episode's scene and the object at its
  true pose of the moment (a driver restart does not move the object; the simulator's clock
  starts again near 0);
- ``arm-hang``: SIGSTOP ``sim_bridge_node`` for :data:`HANG` s, then SIGCONT (joint states,
  clock and controller stop: a hung driver);
- ``foreign-trajectory``: another client sends ``JointTrajectory`` to the controller topic for
  :data:`FOREIGN_TIME` s, every :data:`FOREIGN_PERIOD` s, to :data:`FOREIGN_POSTURE` (the tool
  tip 1.5 cm above the table in the workspace);
- ``dry-run``: ``~/enable`` false before the goal; the episode's expected end is the planner
  waiting (``robot unavailable: disabled: ...``) with no step spent, then ``~/enable`` true.

Records gain ``back_wall`` (when the process was back or the hang ended, wall s of this
process), ``recovery_s`` (from then to the next ``planner/push``), ``unavailable_s`` (wall time
the planner said ``robot unavailable``) and, for the dry run, ``executor_paths`` (planned paths
published).
"""

from __future__ import annotations

import signal
import time
from typing import Any

from pushbot.runner.faults import Fault
from pushbot.runner.protocol import bridge_scene_params
from pushbot.runner.scenario import Episode, FaultTarget

__all__ = ["ARM_SCENARIOS", "DOWN", "FOREIGN_POSTURE", "HANG", "INTO_PUSH", "DriverHang",
           "DryRun", "ForeignTrajectory", "KillLater", "MidPush", "make_arm_fault"]

#: Wall seconds into the push (after it was sent) at which a mid-push fault acts.
INTO_PUSH = 1.0
#: Wall seconds a killed process stays down before it is started again.
DOWN = 3.0
#: Wall seconds the simulator is stopped in ``arm-hang``.
HANG = 6.0
#: ``foreign-trajectory``: how long and how often another client commands the arm, wall s ...
FOREIGN_TIME, FOREIGN_PERIOD = 5.0, 0.2
#: ... and where to (the seven Panda joints, rad): the tool tip at (0.10, -0.15, 0.015) m in
#: ``world``, vertical (inverse kinematics of push_executor with the simulated base pose).
FOREIGN_POSTURE = (-0.199, 0.788, -0.05, -1.973, 0.095, 2.759, 0.785)
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))


def _pushes_after_first_execution(runner: FaultTarget, episode: Episode) -> float | None:
    """Wall time of the first ``planner/push`` after the episode's first executed push."""
    executed = runner.rec.executed[episode.n_exec:]
    if not executed:
        return None
    return next((t for t, _ in runner.rec.pushes[episode.n_push:] if t > executed[0][0]), None)


class MidPush(Fault):
    """Acts :data:`INTO_PUSH` s into the push after the episode's first executed one; the
    subclass's :meth:`act` returns True once the fault is over (then ``back_wall`` is set)."""

    def __init__(self) -> None:
        super().__init__()
        self.back: float | None = None
        self._episode: Episode | None = None

    def poll(self, runner: FaultTarget, episode: Episode) -> None:
        self._episode = episode
        if self.back is not None:
            return
        if not self.injected:
            sent = _pushes_after_first_execution(runner, episode)
            if sent is None or time.monotonic() < sent + INTO_PUSH:
                return
            self._mark(runner)
            episode.notes["injected_after_pushes"] = len(runner.rec.executed) - episode.n_exec
        if self.act(runner, episode):
            self.back = time.monotonic()
            episode.notes["back_wall"] = self.back

    def act(self, runner: FaultTarget, episode: Episode) -> bool:
        """Inject or continue the fault (called on every spin once injected); True when over."""
        raise NotImplementedError

    def accepts_end(self, runner: FaultTarget, index: int) -> bool:
        return self.back is not None and index >= self._status_at_injection

    def record(self, runner: FaultTarget, episode: Episode) -> dict[str, Any]:
        out = super().record(runner, episode)
        if self.back is not None:
            following = [t for t, _ in runner.rec.pushes[episode.n_push:] if t >= self.back]
            out["recovery_s"] = (following[0] - self.back) if following else None
        out["unavailable_s"] = unavailable_seconds(runner.rec.status[episode.n_status:])
        return out


def unavailable_seconds(statuses: list[dict[str, str]]) -> float:
    """Wall seconds the planner said ``robot unavailable`` over ``statuses`` (as received,
    with their ``_wall`` arrival times)."""
    total, since = 0.0, None
    for s in statuses:
        wall = float(s.get("_wall", "nan"))
        if s.get("state") == "unavailable":
            since = wall if since is None else since
        elif since is not None:
            total, since = total + wall - since, None
    if since is not None:
        total += time.monotonic() - since
    return total


class KillLater(MidPush):
    """SIGKILL ``node`` mid-push and start it again :data:`DOWN` s later."""

    def __init__(self, node: str, name: str) -> None:
        super().__init__()
        self.node, self.name = node, name
        self._killed: float | None = None

    def act(self, runner: FaultTarget, episode: Episode) -> bool:
        if self._killed is None:
            self._extra = self.restart_args(runner, episode)
            runner.nodes.kill(self.node)
            self._killed = time.monotonic()
            return False
        if time.monotonic() < self._killed + DOWN:
            return False
        if self.node == "sim_bridge_node":  # its clock starts again near 0
            episode.notes["clock_restart"] = (time.monotonic(), len(runner.rec.true),
                                              len(runner.rec.est))
        runner.nodes.restart(self.node, self._extra)
        return True

    def restart_args(self, runner: FaultTarget, episode: Episode) -> list[str]:
        """``name:=value`` start-up parameters of the restarted node: for the simulator the
        episode's scene with the object at its true pose now."""
        if self.node != "sim_bridge_node":
            return []
        params = bridge_scene_params(episode.trial)
        if runner.rec.true:
            x, y, theta = (float(v) for v in runner.rec.true[-1][1])
            params.update({"initial_pose.x": x, "initial_pose.y": y, "initial_pose.theta": theta})
        return [f"{name}:={_param_text(value)}" for name, value in params.items()]


def _param_text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(repr(float(v)) for v in value) + "]"
    return str(value)


class DriverHang(MidPush):
    """SIGSTOP ``sim_bridge_node`` mid-push for :data:`HANG` s, then SIGCONT."""

    name = "arm-hang"

    def __init__(self) -> None:
        super().__init__()
        self._stopped: float | None = None

    def act(self, runner: FaultTarget, episode: Episode) -> bool:
        if self._stopped is None:
            runner.nodes.signal("sim_bridge_node", signal.SIGSTOP)
            self._stopped = time.monotonic()
            return False
        if time.monotonic() < self._stopped + HANG:
            return False
        runner.nodes.signal("sim_bridge_node", signal.SIGCONT)
        return True

    def after_episode(self, runner: FaultTarget) -> None:
        if self._stopped is not None and self.back is None:  # never leave it stopped
            runner.nodes.signal("sim_bridge_node", signal.SIGCONT)


class ForeignTrajectory(MidPush):
    """Another client commands the arm for :data:`FOREIGN_TIME` s mid-push."""

    name = "foreign-trajectory"

    def __init__(self) -> None:
        super().__init__()
        self._start: float | None = None
        self._last = -float("inf")

    def act(self, runner: FaultTarget, episode: Episode) -> bool:
        now = time.monotonic()
        self._start = now if self._start is None else self._start
        if now >= self._start + FOREIGN_TIME:
            return True
        if now >= self._last + FOREIGN_PERIOD:
            runner.foreign_trajectory(list(ARM_JOINTS), list(FOREIGN_POSTURE), 1.0)
            self._last = now
        return False


class DryRun(Fault):
    """The executor disabled (``~/enable`` false) for the episode: it must end waiting for the
    robot (``robot unavailable: disabled: ...``) with no step spent."""

    name = "dry-run"
    end_states = ("reached", "failed", "unavailable")

    def before_goal(self, runner: FaultTarget) -> None:
        self._paths = runner.rec.executor_paths
        runner.executor_enable(False)
        self.injected = True

    def accepts_end(self, runner: FaultTarget, index: int) -> bool:
        status = runner.rec.status[index]
        return status.get("state") != "unavailable" or \
            status.get("robot_unavailable", "").startswith("disabled:")

    def after_episode(self, runner: FaultTarget) -> None:
        runner.reset("planner_node")  # drop the goal first: enabled, it would push at once
        runner.executor_enable(True)

    def record(self, runner: FaultTarget, episode: Episode) -> dict[str, Any]:
        out = super().record(runner, episode)
        out["executor_paths"] = runner.rec.executor_paths - self._paths
        out["unavailable_s"] = unavailable_seconds(runner.rec.status[episode.n_status:])
        return out


#: name -> factory of the arm graph's scenarios (``benchmarks/bench_faults.py --robot arm``).
ARM_SCENARIOS = {
    "kill-executor": lambda: KillLater("push_executor_node", "kill-executor"),
    "kill-arm-sim": lambda: KillLater("sim_bridge_node", "kill-arm-sim"),
    "arm-hang": DriverHang,
    "foreign-trajectory": ForeignTrajectory,
    "dry-run": DryRun,
}


def make_arm_fault(name: str) -> Fault:
    """A fresh fault of arm scenario ``name`` (:data:`ARM_SCENARIOS`); ``ValueError`` if
    unknown."""
    try:
        return ARM_SCENARIOS[name]()
    except KeyError:
        raise ValueError(f"unknown arm fault scenario {name!r}; known: "
                         f"{', '.join(ARM_SCENARIOS)}") from None
