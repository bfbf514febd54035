"""What planner_node knows about whatever executes its pushes (ROS-free decisions).

:class:`RobotLink` turns the executor's answers into episode-engine events (rule 9 of
:mod:`push_core.episode`, the robot's availability):

- a refusal of the push in flight that says the robot is not available
  (:func:`push_ros.refusal.robot_unavailable`) pauses the episode
  (:meth:`push_core.episode.EpisodeEngine.robot_unavailable`): no step is spent while waiting;
- an ``executor/status`` that says ``ready`` while the episode waits resumes it from the newest
  estimate stamped after the wait began (the planner's clock at the refusal; any estimate of a
  clock restarted meanwhile): a frame of the world as the wait left it. Not "after the ready":
  a simulator publishes a frame only when the world comes to rest, and a restarted one its
  first frame before the executor is ready again, so the episode never resumed;
- an ``executor/status`` of another executor *session* (a restarted process) while a push is in
  flight means that push is gone with the old process: the caller counts it lost at once
  instead of waiting out ``push_timeout``.

Times: ``now`` is the node's steady clock (s; the ``robot_timeout``), ``stamp_now`` its ROS clock
(s; the estimates' clock, simulated time in simulation).
"""

from __future__ import annotations

import math

from push_core.episode import EpisodeEngine
from push_ros.refusal import MOVING_KINDS, Readiness, Refusal, robot_unavailable

__all__ = ["REPLANNING", "RESTARTED", "RESUMED", "RobotLink", "ignored_refusal_text",
           "refusal_note", "timeout_note"]

#: :meth:`RobotLink.status`'s events, in the words the planner logs.
RESTARTED = ("the executor restarted during the push (a new session on executor/status): the "
             "push is gone with the old process; planning again")
#: What the planner does after any other refusal of its push.
REPLANNING = "counted as a step, planning again"
RESUMED = ("the robot is ready again: resuming the episode from the newest estimate since the "
           "wait began")


def refusal_note(step: int, refusal: Refusal) -> str:
    """The status note of the push in flight refused."""
    return (f"push of step {step} refused by {refusal.who} ({refusal.kind}): "
            f"{refusal.reason}")[:500]


def ignored_refusal_text(refusal: Refusal) -> str:
    """The log line of a refusal that names no push in flight."""
    return (f"ignored a refusal of push {refusal.push_stamp} by {refusal.who!r}: not the push "
            "in flight")


def timeout_note(step: int, push_timeout: float) -> str:
    """The status note of a push not reported within ``push_timeout`` s."""
    return (f"push of step {step} not reported on pusher/executed within {push_timeout} s; "
            "counted as a step; its contact region is avoided until a push is executed")


class RobotLink:
    """The executor as planner_node sees it (module docstring)."""

    def __init__(self) -> None:
        #: The newest executor session seen on ``executor/status`` ("" before the first).
        self.session = ""
        #: Whether that status said ``ready`` (None: never said).
        self.ready: bool | None = None
        self._push_session = ""
        #: When the wait began (s, the estimates' clock; -inf: any estimate is fresh).
        self.wait_stamp = -math.inf

    def push_sent(self) -> None:
        """A push went out: it is the current session's (a later session has not seen it)."""
        self._push_session = self.session

    def refused(self, engine: EpisodeEngine, refusal: Refusal, now: float,
                stamp_now: float | None = None) -> str:
        """The push in flight was refused: pause the episode if the refusal says the robot
        is not available and return the status note, else ``""`` (the caller re-plans).
        ``stamp_now``: the estimates' clock now (None: not started)."""
        if not robot_unavailable(refusal):
            return ""
        if engine.phase != "unavailable":  # the wait begins
            self.wait_stamp = -math.inf if stamp_now is None else float(stamp_now)
        reason = f"{refusal.kind}: {refusal.reason}"
        engine.robot_unavailable(reason, now, moved=refusal.kind in MOVING_KINDS)
        return (f"the robot ({refusal.who}) cannot take a push; waiting for it to say it is "
                "ready on executor/status, no step spent")

    def status(self, engine: EpisodeEngine, readiness: Readiness) -> str:
        """An ``executor/status`` arrived. Returns :data:`RESTARTED` (the push in flight was
        given to an executor process that is gone: count it lost), :data:`RESUMED` (the episode
        was waiting and the robot is ready: plan from the newest estimate since the wait began)
        or ``""``."""
        if readiness.ready is None:
            return ""
        self.session = readiness.session or self.session
        self.ready = readiness.ready
        if engine.in_flight and readiness.session:
            if not self._push_session:  # sent before any status: the first executor heard of
                self._push_session = readiness.session
            elif readiness.session != self._push_session:
                return RESTARTED
        if readiness.ready and engine.robot_available(self.wait_stamp):
            return RESUMED
        return ""

    def clock_restarted(self) -> None:
        """The estimates' clock jumped back: every estimate of the new one is after the wait."""
        self.wait_stamp = -math.inf
