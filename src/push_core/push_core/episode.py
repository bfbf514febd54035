"""The episode engine: one goal, pushed for until it is reached, ROS-free.

One set of rules for every closed loop: ``planner_node`` (events from DDS), the in-process
evaluation (``pushbot.experiments.inprocess``) and the ground-truth planner loop all drive an
:class:`EpisodeEngine`, so graph and in-process runs make the same decisions by construction.
The caller reports events (a new goal, an outline, an estimate, a push executed or lost) and
asks :meth:`EpisodeEngine.step` what to do; the engine never blocks, never reads a clock and
never talks to a simulator. Times are float seconds of whatever clock stamps the estimates and
pushes (simulated time in the pipeline).

Rules (docs/design/episode-engine.md):

1. **Stale-estimate rule.** An estimate is *usable* when it is

   a. newer than every estimate already used for this goal (a re-sent or older one is
      ``ignored_duplicate``),
   b. not older than the end of the last executed push (``stamp >= last_push_end``, else
      ``ignored_stale``: it predates the push's effect), and
   c. received while no push is in flight (``ignored_busy``; the newest estimate is kept and
      used as soon as the push is reported, if it is still usable then).

   Only the newest estimate is ever used; :meth:`EpisodeEngine.step` uses it at most once.
2. **Goal check** on a usable estimate, before planning: the stop rule of
   :func:`push_core.planner.goal_reached` (the estimate inside the goal region shrunk by its
   uncertainty, the orientation ignored for a continuously symmetric outline) ->
   ``reached``; ``max_steps`` pushes already sent -> ``failed`` (``max steps``).
3. **Plan** (``Planner.plan`` with the avoid list) -> a push to execute (``pushing``, in
   flight); :class:`push_core.planner.NoFeasiblePush` -> ``failed`` (``no feasible push``); a
   plan that raises ``ValueError`` (an estimate it cannot use) leaves the episode as it is
   and is reported as refused.
4. **Executed push** (:meth:`EpisodeEngine.push_executed`): not in flight any more, its end
   time is the new ``last_push_end``, the avoid list is cleared (the object may have moved).
5. **Lost push** (:meth:`EpisodeEngine.push_lost`: the robot refused it, or it was not
   reported in time): it counts as a step; its outline point joins the avoid list
   (``Planner.plan(avoid=...)``, until a push is executed or a new outline arrives) and the
   newest estimate becomes usable again (nothing moved, so it is not stale).
6. A new goal starts a new episode (step 0) and re-opens the newest estimate once (the same
   pose, a new question). A new outline clears the avoid list.
7. **Watching after the goal**. Once ``reached``, every further usable estimate
   (rule 1) is checked against the goal region by the *point* estimate (the stop rule without
   the covariance, :meth:`Planner.reached` with ``covariance=None``): entering needs the
   confident rule, leaving needs the point estimate outside the full region, so uncertainty
   noise alone never re-opens a reached goal. If the object left the region (knocked, an
   injected push, drift) it is counted (``left``) and, by ``after_goal``:

   - ``resume`` (default): the episode goes on from this estimate within the same
     ``max_steps`` (the steps so far count): rule 2-3 as usual, the step says ``resumed``;
   - ``report``: the phase becomes ``left`` and the step is ``left``; no push is planned. A
     later estimate that satisfies the stop rule again gives ``reached``.

   The in-process loops end at the first ``reached``, so this changes nothing for them.
8. **Contradicted pushes** (only with ``PlannerConfig.avoid_contradicted``). The first
   usable estimate after an executed push is compared with the push's predicted pose
   (``PushPlan.predicted_pose``): the push *contradicted its prediction* when the estimate is
   more than ``CONTRADICTION_MISS`` (eq. 5.1 units) from the prediction and the score to the
   goal improved by less than ``CONTRADICTION_GAIN`` of the predicted improvement (a
   depth-noise stall seen in evaluation: predicted 163 -> 108 mm, observed a 3.6 mm move, 27
   times). Its outline
   point joins a second avoid list (the ``MAX_CONTRADICTED`` newest; kept until a new goal or
   outline, unlike refused pushes the object did move), counted as ``contradicted`` and said
   by :meth:`EpisodeEngine.status_text` until the next push is planned: the same push is not
   planned again, the planner tries another contact region (with the estimator's
   ``EKFConfig.relearn`` the model is re-learnt from the same observation).
9. **A robot that is not available pauses the episode** (:meth:`EpisodeEngine.robot_unavailable`:
   the robot refused a push for a reason no other push avoids: disabled for a dry run, no joint
   states, no controller, an impossible measured posture). The push in flight is given back
   (not a step; a push the robot had started counts as lost), the phase becomes
   ``unavailable`` (:meth:`EpisodeEngine.status_text`: ``robot unavailable: <kind>: <reason>``)
   and nothing is planned, so no step is spent while waiting. :meth:`EpisodeEngine.robot_available`
   (the robot says it is ready) resumes the episode from an estimate stamped after the given
   time (``planner_node``: when the wait began; the world may have changed meanwhile);
   :meth:`EpisodeEngine.robot_waited` fails the episode (``robot unavailable``) once the robot
   has been unavailable for ``robot_timeout`` s without an executed push since. These times
   are the caller's clock (``now``), not the estimates' stamps.
10. **A restarted clock** (:meth:`EpisodeEngine.clock_restarted`: the time source jumped back,
    e.g. a restarted simulator starting near 0): the stamps of the old clock mean nothing any
    more; the end of the last push, the used and the fresh-frame stamps are forgotten and so is
    the newest estimate (the next one is of the new clock).

Scoring (:func:`end_score`, :func:`true_errors`, re-exported from
:mod:`push_core.episode_record` with the record's other helpers): success from the *true* end
pose against the true goal, the orientation modulo the object's k-fold symmetry and not counted
for a continuously symmetric outline (:mod:`push_core.symmetry`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.episode_record import (
    check_goal_offset,
    end_score,
    min_pushes,
    new_record,
    robot_times,
    true_errors,
)
from push_core.geometry import wrap_angle
from push_core.planner import NoFeasiblePush, Outline, Planner, PushPlan, motion_score

__all__ = [
    "AFTER_GOAL",
    "COUNTERS",
    "ORIENTATION_IGNORED",
    "PREVIOUS_EPISODE_WINDOW",
    "EpisodeEngine",
    "Step",
    "check_goal_offset",
    "contradiction",
    "end_score",
    "min_pushes",
    "new_record",
    "precedes_episode",
    "robot_times",
    "true_errors",
]

#: Counters an :class:`EpisodeEngine` keeps (``planner_node`` reports them in its status).
COUNTERS = ("estimates", "planned", "ignored_stale", "ignored_duplicate", "ignored_busy",
            "lost", "left", "contradicted", "robot_unavailable", "clock_restarts")
#: Rule 8: an executed push contradicts its prediction when the observed pose is more than this
#: (eq. 5.1 score units, mm + lambda deg) from the predicted one ...
CONTRADICTION_MISS = 10.0
#: ... and it gained less than this fraction of the score gain it was predicted to make.
CONTRADICTION_GAIN = 0.5
#: Rule 8: contact regions of at most this many contradicted pushes are avoided (the newest).
MAX_CONTRADICTED = 8
#: What the engine does when the object leaves the goal region after ``reached`` (rule 7).
AFTER_GOAL = ("resume", "report")
#: Said by :meth:`EpisodeEngine.status_text` when the outline is continuously symmetric.
ORIENTATION_IGNORED = "orientation ignored: rotationally symmetric outline"


#: How long before an episode boundary an input still counts as the old episode's, s: frames
#: in flight at a ``~/reset`` (a camera streaming at >= 1 Hz, delivery well under a second).
#: An input older than that comes from a restarted clock (a restarted simulator starts near 0)
#: and is not skipped.
PREVIOUS_EPISODE_WINDOW = 2.0


def precedes_episode(stamp: float, boundary: float) -> bool:
    """Whether an input stamped ``stamp`` (s) belongs to the episode before ``boundary`` (s;
    ``push_ros.stamps.episode_boundary``): at or before it, by at most
    :data:`PREVIOUS_EPISODE_WINDOW`."""
    return boundary - PREVIOUS_EPISODE_WINDOW <= stamp <= boundary


@dataclass(frozen=True)
class Step:
    """What :meth:`EpisodeEngine.step` decided.

    Attributes
    ----------
    action : str
        ``"push"`` (execute ``plan``), ``"reached"``, ``"failed"`` (``reason`` says why),
        ``"refused"`` (the estimate could not be planned for: ``reason``), ``"left"`` (the
        object left the reached goal region; ``after_goal = "report"``) or ``"wait"`` (nothing
        to do until the next event).
    plan : PushPlan or None
        For ``"push"`` (a ``push_core.pushnet.PushNetPlan`` for that planner).
    state : numpy.ndarray or None
        The estimate the decision was made on, (7,).
    reason : str
    resumed : bool
        The object had left the reached goal region and the episode resumed with this step
        (``after_goal = "resume"``; ``reason`` says how far off it was).
    """

    action: str
    plan: PushPlan | None = None
    state: NDArray[np.float64] | None = None
    reason: str = ""
    resumed: bool = False


@dataclass
class EpisodeEngine:
    """The closed-loop rules for one goal at a time (module docstring).

    Parameters
    ----------
    planner : Planner
        Plans the pushes and owns the stop rule (its tolerances and confidence); anything with
        ``Planner``'s ``plan(outline, state, goal, avoid=...)`` and ``reached(pose, goal,
        covariance, outline)``, e.g. ``push_core.pushnet.PushNetPlanner``.
    max_steps : int
        Pushes per episode (executed or lost) before it fails.
    after_goal : str
        ``resume`` | ``report``: what happens when the object leaves the goal region after
        ``reached`` (module docstring, rule 7).
    robot_timeout : float
        Longest wait for an unavailable robot before the episode fails (rule 9), s of the
        caller's clock.

    Attributes
    ----------
    phase : str
        ``waiting`` | ``pushing`` | ``reached`` | ``left`` (after_goal ``report``) |
        ``unavailable`` (rule 9) | ``failed``.
    steps : int
        Pushes sent in this episode (a push given back by rule 9 is not one).
    failure : str
        ``max steps``, ``no feasible push`` or ``robot unavailable`` once failed.
    unavailable : str
        Why the robot is not available (``<kind>: <reason>``) while the phase is
        ``unavailable``, else empty.
    counts : dict
        The :data:`COUNTERS` (over the engine's life, not reset by a new goal).
    """

    planner: Planner | Any
    max_steps: int = 30
    after_goal: str = "resume"
    robot_timeout: float = 300.0
    phase: str = "waiting"
    steps: int = 0
    failure: str = ""
    unavailable: str = ""
    goal: NDArray[np.float64] | None = None
    outline: Outline | None = None
    last_push_end: float = -math.inf
    in_flight: bool = False
    counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(COUNTERS, 0))
    _latest: tuple[float, NDArray[np.float64], NDArray[np.float64] | None] | None = None
    _used_stamp: float = -math.inf
    _in_flight_point: NDArray[np.float64] | None = None
    _avoid: list[NDArray[np.float64]] = field(default_factory=list)
    _contradicted: list[NDArray[np.float64]] = field(default_factory=list)
    #: (pose planned from, predicted pose, outline point) of the last executed push, until its
    #: outcome is judged (rule 8).
    _outcome: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None = None
    _planned: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None = None
    last_contradiction: str = ""
    #: Rule 9: since when (caller's clock) the robot has been unavailable without an executed
    #: push; the next estimate used must be stamped after ``_fresh_after``.
    _unavailable_since: float = math.nan
    _fresh_after: float = -math.inf
    _failure_detail: str = ""

    def __post_init__(self) -> None:
        if not (callable(getattr(self.planner, "plan", None))
                and callable(getattr(self.planner, "reached", None))):
            raise ValueError(f"planner: expected a push_core.planner.Planner (or a planner "
                             f"with its plan/reached), got {type(self.planner).__name__}")
        if isinstance(self.max_steps, bool) or int(self.max_steps) != self.max_steps \
                or self.max_steps < 1:
            raise ValueError(f"max_steps: expected an integer >= 1, got {self.max_steps!r}")
        self.max_steps = int(self.max_steps)
        if self.after_goal not in AFTER_GOAL:
            raise ValueError(f"after_goal: expected one of {', '.join(AFTER_GOAL)}, got "
                             f"{self.after_goal!r}")
        if not (isinstance(self.robot_timeout, int | float) and self.robot_timeout > 0):
            raise ValueError(f"robot_timeout: expected > 0 s, got {self.robot_timeout!r}")

    # ---- events --------------------------------------------------------------------------------
    def new_goal(self, goal: ArrayLike) -> None:
        """Start an episode for ``goal`` (x, y, theta in ``world``): step 0; the newest
        estimate is usable again."""
        g = np.asarray(goal, dtype=np.float64).reshape(-1)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ValueError(f"goal: expected 3 finite numbers, got {goal!r}")
        self.goal = g
        self.phase, self.steps, self.failure, self.unavailable = "waiting", 0, "", ""
        self._unavailable_since = math.nan
        self._used_stamp = -math.inf
        self._contradicted.clear()
        self._outcome = None
        self.last_contradiction = ""

    def set_outline(self, outline: Outline) -> None:
        """The object's outline (``push_core.planner.prepare_outline``); clears the avoid
        list (points of another outline)."""
        if not isinstance(outline, Outline):
            raise ValueError(f"outline: expected an Outline, got {type(outline).__name__}")
        self.outline = outline
        self._avoid.clear()
        self._contradicted.clear()
        self._outcome = None

    def estimate(self, stamp: float, state: ArrayLike,
                 covariance: ArrayLike | None = None) -> None:
        """A new estimate: state (7,) ``(x, y, theta, c_x, c_y, l, m)`` at ``stamp`` with its
        covariance ((7, 7) or (3, 3); None = exact). Counted as stale, duplicate or busy when
        rule 1 says so; the newest one is kept either way."""
        s = np.array(state, dtype=np.float64).reshape(-1)
        if s.shape != (7,) or not np.all(np.isfinite(s)) or not math.isfinite(stamp):
            raise ValueError(f"estimate: expected a finite stamp and 7 finite state values, "
                             f"got {stamp!r}, {state!r}")
        cov = None if covariance is None else np.array(covariance, dtype=np.float64)
        self.counts["estimates"] += 1
        if self._latest is None or stamp >= self._latest[0]:
            self._latest = (float(stamp), s, cov)
        if stamp < self.last_push_end or stamp <= self._fresh_after:
            self.counts["ignored_stale"] += 1
        elif stamp <= self._used_stamp:
            self.counts["ignored_duplicate"] += 1
        elif self.in_flight:
            self.counts["ignored_busy"] += 1

    def push_executed(self, end_stamp: float) -> None:
        """The push in flight was executed; it ended at ``end_stamp``."""
        self.last_push_end = max(self.last_push_end, float(end_stamp))
        self._unavailable_since = math.nan  # progress: a later wait is timed afresh
        self.in_flight, self._in_flight_point = False, None
        self._avoid.clear()
        self._outcome, self._planned = self._planned, None

    def push_lost(self, wait_for_estimate: bool = False) -> None:
        """The push in flight was not executed (refused, or not reported in time): it stays
        counted as a step, its contact region is avoided, and the newest estimate is usable
        again, unless ``wait_for_estimate``: the robot may still be moving (it was busy with
        an earlier push, or stopped this one on the way), so the next plan waits for an
        estimate newer than the one this push was planned from."""
        if not self.in_flight:
            return
        self.in_flight = False
        self.counts["lost"] += 1
        if not wait_for_estimate:
            self._used_stamp = -math.inf
        if self._in_flight_point is not None:
            self._avoid.append(self._in_flight_point)
        self._in_flight_point = None
        self._planned = None

    def robot_unavailable(self, reason: str, now: float, moved: bool = False) -> None:
        """Rule 9: the robot cannot take any push (``reason``: ``<kind>: <reason>``). The push
        in flight is given back (``moved``: the robot had started it, it counts as lost) and
        the episode waits; ``now`` (s, the caller's clock) starts the ``robot_timeout``."""
        if self.phase in ("failed", "reached", "left") and not self.in_flight:
            return
        if self.in_flight:
            self.in_flight, self._in_flight_point, self._planned = False, None, None
            if moved:
                self.counts["lost"] += 1
            else:
                self.steps = max(0, self.steps - 1)
        self.phase, self.unavailable = "unavailable", str(reason)
        self.counts["robot_unavailable"] += 1
        if not math.isfinite(self._unavailable_since):
            self._unavailable_since = float(now)

    def robot_available(self, fresh_after: float) -> bool:
        """Rule 9: the robot is ready again; the episode resumes from an estimate stamped
        after ``fresh_after`` (s, the estimates' clock). False when it was not waiting."""
        if self.phase != "unavailable":
            return False
        self.phase = "pushing" if self.steps > 0 else "waiting"
        self.unavailable = ""
        self._fresh_after = max(self._fresh_after, float(fresh_after))
        return True

    def robot_waited(self, now: float) -> Step | None:
        """Rule 9's time-out: ``failed`` once the robot has been unavailable for more than
        ``robot_timeout`` s at ``now`` (the caller's clock), else None."""
        waited = float(now) - self._unavailable_since
        if self.phase != "unavailable" or not waited > self.robot_timeout:
            return None
        self.phase, self.failure = "failed", "robot unavailable"
        self._failure_detail = (f"robot unavailable for {waited:.0f} s (robot_timeout "
                                f"{self.robot_timeout:g} s): {self.unavailable}")
        return Step("failed", reason=self._failure_detail)

    def clock_restarted(self) -> None:
        """Rule 10: the clock of the stamps jumped back; forget every stamp of the old one."""
        self.last_push_end = self._used_stamp = self._fresh_after = -math.inf
        self._latest = None
        self.counts["clock_restarts"] += 1

    # ---- decision ------------------------------------------------------------------------------
    @property
    def finished(self) -> bool:
        """Reached or failed (a reached goal is still watched, rule 7)."""
        return self.phase in ("reached", "failed")

    @property
    def latest(self) -> tuple[float, NDArray[np.float64], NDArray[np.float64] | None] | None:
        """(stamp, state, covariance) of the newest estimate, or None."""
        return self._latest

    @property
    def orientation_matters(self) -> bool:
        """False for a continuously symmetric outline (the stop rule ignores theta)."""
        return self.outline is None or self.outline.orientation_matters

    def status_text(self) -> str:
        """The episode in words: ``waiting`` (``for goal, outline, estimate`` what is missing),
        ``pushing step n``, ``goal reached`` (with ``(ORIENTATION_IGNORED)`` for a continuously
        symmetric outline), ``goal left``, ``robot unavailable: <kind>: <reason>``, ``failed
        after max steps``, ``failed: no feasible push`` or ``failed: robot unavailable for
        ...``."""
        if self.phase == "pushing":
            return f"pushing step {self.steps}" + (f" - {self.last_contradiction}"
                                                   if self.last_contradiction else "")
        if self.phase == "reached":
            return "goal reached" + ("" if self.orientation_matters
                                     else f" ({ORIENTATION_IGNORED})")
        if self.phase == "left":
            return "goal left"
        if self.phase == "unavailable":
            return f"robot unavailable: {self.unavailable}"
        if self.phase == "failed":
            return {"max steps": "failed after max steps",
                    "robot unavailable": f"failed: {self._failure_detail}"}.get(
                        self.failure, "failed: no feasible push")
        missing = [name for name, have in (("goal", self.goal is not None),
                                           ("outline", self.outline is not None),
                                           ("estimate", self._latest is not None)) if not have]
        return "waiting" + (f" for {', '.join(missing)}" if missing else "")

    def step(self) -> Step:
        """Decide on the newest estimate if rule 1 allows it (module docstring, rules 2-3)."""
        if (self._latest is None or self.goal is None or self.outline is None
                or self.phase in ("failed", "unavailable") or self.in_flight):
            return Step("wait")
        stamp, state, cov = self._latest
        if stamp < self.last_push_end or stamp <= self._used_stamp or stamp <= self._fresh_after:
            return Step("wait")
        self._used_stamp = stamp
        self._judge_outcome(state)
        resumed, why = False, ""
        if self.phase == "reached":  # rule 7: watching the reached goal
            if self.planner.reached(state[:3], self.goal, None, self.outline):
                return Step("wait", state=state)
            self.counts["left"] += 1
            why = self._how_far(state)
            if self.after_goal == "report":
                self.phase = "left"
                return Step("left", state=state, reason=why)
            resumed = True
        if self.planner.reached(state[:3], self.goal, cov, self.outline):
            self.phase = "reached"
            return Step("reached", state=state)
        if self.phase == "left":  # after_goal report: watched, never pushed for
            return Step("wait", state=state)
        if self.steps >= self.max_steps:
            self.phase, self.failure = "failed", "max steps"
            return Step("failed", state=state, reason="max steps", resumed=resumed)
        try:
            plan = self.planner.plan(self.outline, state, self.goal,
                                     avoid=self._avoid + self._contradicted)
        except NoFeasiblePush as exc:
            self.phase, self.failure = "failed", "no feasible push"
            return Step("failed", state=state, reason=f"no feasible push: {exc}",
                        resumed=resumed)
        except ValueError as exc:
            if resumed:
                self.phase = "waiting"  # left the goal; planned again on the next estimate
            return Step("refused", state=state, reason=str(exc), resumed=resumed)
        self.steps += 1
        self.phase = "pushing"
        self.counts["planned"] += 1
        self.in_flight = True
        index = getattr(plan, "index", None)  # the pushnet baseline has no contact point
        self._in_flight_point = None if index is None else self.outline.points[index].copy()
        self._planned = None
        if self._in_flight_point is not None and self._avoids_contradicted():
            self._planned = (state[:3].copy(), np.asarray(plan.predicted_pose, dtype=np.float64),
                             self._in_flight_point)
        return Step("push", plan=plan, state=state, reason=why, resumed=resumed)

    def _avoids_contradicted(self) -> bool:
        """Rule 8 is on (``PlannerConfig.avoid_contradicted``)."""
        return bool(getattr(getattr(self.planner, "config", None), "avoid_contradicted", False))

    def _judge_outcome(self, state: NDArray[np.float64]) -> None:
        """Rule 8: did the last executed push contradict its prediction? (once per push)"""
        if self._outcome is None or self.goal is None:
            self.last_contradiction = ""
            return
        start, predicted, point = self._outcome
        self._outcome = None
        lam = getattr(self.planner.config, "lam", 0.0)
        to_go = contradiction(start, predicted, state[:3], self.goal, lam,
                              self.orientation_matters)
        if to_go is not None:
            self.counts["contradicted"] += 1
            self._contradicted.append(point)
            del self._contradicted[:-MAX_CONTRADICTED]
            self.last_contradiction = (
                f"the last push contradicted its prediction (predicted {to_go[1]:.1f} "
                f"mm to go, observed {to_go[2]:.1f} from {to_go[0]:.1f}): its "
                f"contact region is avoided")
        else:
            self.last_contradiction = ""

    def _how_far(self, state: NDArray[np.float64]) -> str:
        """How far the point estimate is off the goal (for the rule 7 report)."""
        goal = self.goal  # set: step() decides only with a goal
        dxy = math.hypot(*(goal[:2] - state[:2]))
        dth = abs(float(wrap_angle(goal[2] - state[2])))
        return (f"left the goal region: the estimate is {1e3 * dxy:.1f} mm and "
                f"{math.degrees(dth):.1f} deg off the goal")


# ------------------------------------------------------------------------------------ scoring
def contradiction(start: ArrayLike, predicted: ArrayLike, observed: ArrayLike, goal: ArrayLike,
                  lam: float, orientation_matters: bool = True
                  ) -> tuple[float, float, float] | None:
    """Rule 8's test: did a push contradict its prediction?

    The push started at ``start``, was predicted to end at ``predicted`` and was observed at
    ``observed`` (poses ``(x, y, theta)``, ``world``; ``goal`` likewise). It contradicted its
    prediction when the observation is more than ``CONTRADICTION_MISS`` from the prediction
    and it gained less than ``CONTRADICTION_GAIN`` of the predicted gain (eq. 5.1 with
    ``lam``, mm + lam deg; without the orientation when ``orientation_matters`` is False).

    Returns
    -------
    (float, float, float) or None
        Eq. (5.1) to the goal from the start, the prediction and the observation when it
        contradicted, else None.
    """
    def flat(pose: ArrayLike) -> NDArray[np.float64]:
        p = np.asarray(pose, dtype=np.float64)[:3]
        return p if orientation_matters else np.r_[p[:2], 0.0]

    weight = lam if orientation_matters else 0.0
    g = flat(goal)
    go = [float(motion_score(g - flat(p), weight)) for p in (start, predicted, observed)]
    miss = float(motion_score(flat(observed) - flat(predicted), weight))
    if miss > CONTRADICTION_MISS and go[0] - go[2] < CONTRADICTION_GAIN * (go[0] - go[1]):
        return go[0], go[1], go[2]
    return None
