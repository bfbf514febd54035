"""One checked joint trajectory per push: transit, descend, push, retreat, lift, withdraw.

ROS-free: points in ``world`` (m), joint positions (rad or m), times in seconds from the
trajectory's start. :func:`plan_push` turns a planned push (approach, contact and end point of
the pusher axis on the table, ``planner/push``) and the arm's current state into one
:class:`MotionPlan`, or raises :class:`PushRefused` naming the refusal class (``kind``), the
stage and the reason -- before anything moves. :func:`plan_park` is the motion to the park
posture alone (the end of an episode, after ``~/cancel``, on disable).

Stages (:data:`push_executor.motion_types.STAGES`; docs/design/cycle.md):

0. ``clear`` (only when the arm starts at rest low over the workspace, e.g. after a stop in
   the middle of a push): straight up to ``approach_height`` + :data:`CLEAR_EXTRA`.
1. ``transit``: joint space to the tip above the approach point at ``approach_height``,
   time-optimal and jerk-limited (:func:`push_executor.timing.joint_move`) from the current
   state (at rest, or moving when the push chains from the previous motion), arriving with the
   descend's initial velocity (blended); over the workspace (and :data:`CLEARANCE_MARGIN`
   around it) the tip stays at ``approach_height`` or higher (:data:`TRANSIT_SLACK`), else
   the transit ends at rest.
2. ``descend``: straight down to ``push_height``, from ``cartesian_speed`` to rest.
3. ``push``: the straight Cartesian line approach -> contact -> end, rest to rest, cruising at
   ``push_speed`` (the model's quasi-static pushing); the contact segment is the part contact
   -> end (:attr:`MotionPlan.contact_start`, :attr:`MotionPlan.contact_end`).
4. ``retreat``: back along the line by ``retreat``, rest to rest.
5. ``lift``: straight up to ``approach_height`` + :data:`LIFT_EXTRA`, from rest to
   ``cartesian_speed`` (blended into the next stage; to rest when that would not move).
6. ``withdraw``: joint space to a *clear pose* near the work, where the arm leaves the object's
   silhouette in the camera image free (the first of ``view``'s candidates that passes every
   check; :mod:`push_executor.clearance`), and the trajectory ends there. Without a ``view``
   (no camera or no object estimate yet), or when no candidate passes, the stage is ``park``:
   to ``park_positions``, out of the camera's view.

Cartesian stages follow a jerk-limited speed profile along their line
(:func:`push_executor.timing.line_profile`: ``cartesian_speed``, ``cartesian_acceleration``,
``cartesian_jerk``), sampled every ``waypoint_period`` seconds (or a little less); each sample
is solved by :meth:`push_executor.kinematics.ArmKinematics.solve_ik` seeded with the previous
one (tool axis straight down, yaw free, redundancy pulled toward ``reference_positions``);
joint velocities and accelerations follow from the solutions by the chain rule (``dq/ds`` and
``d2q/ds2`` as finite differences over the path parameter, times the profile's speed and
acceleration). Joint-space stages are ruckig's, within ``speed_margin`` times the URDF's
velocity limits and the ``acceleration_limits`` and ``jerk_limits``.

Checks, stage by stage, the first failure refusing the push with its ``kind`` (``invalid``,
``workspace``, ``ik``, ``joint_limits``, ``tool_height``, ``singular``, ``speed``; what each
checks: docs/design/arm.md#checks-before-anything-moves). Candidate clear poses are checked the
same way (IK, joint limits, the withdraw stage's checks); a failing candidate is skipped.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from push_executor.kinematics import ArmKinematics
from push_executor.motion_checks import TRANSIT_SLACK, Stage, StageChecks
from push_executor.motion_types import (
    CLEAR,
    PARK,
    MotionConfig,
    MotionPlan,
    MotionState,
    PushRefused,
    StageSpan,
    View,
    chain_point,
)
from push_executor.timing import blend_speed, joint_move, line_profile

__all__ = ["CLEAR", "MotionConfig", "MotionPlan", "MotionState", "PushRefused", "StageSpan",
           "View", "chain_point", "plan_park", "plan_push"]

#: The lift ends this far above the approach height (a transit from rest there dips by up to
#: 1.6 cm on its way; measured on the graph), m.
LIFT_EXTRA = 0.025
#: The clear stage lifts this much above the approach height (the transit then comes down to
#: it instead of crossing at it), m.
CLEAR_EXTRA = 0.05
#: The clear stage goes straight up when the tool axis is within this of vertical (rad) and
#: the line's first sample within this of the measured posture (rad; the controller takes the
#: step within the trajectory's first point); else it moves in joint space.
CLEAR_TILT = CLEAR_START_MATCH = 1e-3
#: Inverse kinematics along the Cartesian stages: the redundancy fully pulled toward the
#: reference each iteration and converged to this joint step (rad), so that the solutions form
#: a smooth path whose finite differences give the joint accelerations and jerks (the solver's
#: default gain 0.2 and step 1e-5 rad left 1e-5 rad of noise: 1e3 rad/s^3 of spurious jerk).
LINE_POSTURE_GAIN, LINE_POSTURE_STEP = 1.0, 1e-8
#: Scales of the Cartesian acceleration, jerk and speed a line stage is tried with, in turn.
RAMP_SCALES = (1.0, 0.5, 0.25)
#: Spacing of the inverse kinematics solutions along a Cartesian stage, m: the samples between
#: them lie on a cubic spline through them (checked against the line by forward kinematics).
LINE_KNOT = 0.005


class _Planner(StageChecks):
    """Builds and checks the stages of one motion (see :func:`plan_push`)."""

    def __init__(self, arm: ArmKinematics, config: MotionConfig) -> None:
        super().__init__(arm, config)
        self.reference = np.array(config.reference_positions, dtype=float)

    # ---- stages ------------------------------------------------------------------------------
    def joint_stage(self, name: str, start: MotionState, q_b: NDArray[np.float64],
                    qd_b: NDArray[np.float64] | None = None,
                    qdd_b: NDArray[np.float64] | None = None) -> Stage:
        """Time-optimal joint motion from ``start`` to ``q_b`` (at rest unless given)."""
        zero = np.zeros_like(q_b)
        target = (q_b, zero if qd_b is None else qd_b, zero if qdd_b is None else qdd_b)
        # May start outside the margin (a measured posture), never goes further out.
        lower = np.minimum(self.lower, start.q, out=None)
        upper = np.maximum(self.upper, start.q)
        bad = (q_b < lower - 1e-9) | (q_b > upper + 1e-9)
        if np.any(bad):
            j = int(np.argmax(bad))
            raise PushRefused("joint_limits", name, f"{self.arm.joint_names[j]} target "
                              f"{q_b[j]:.4f} outside [{lower[j]:.4f}, {upper[j]:.4f}] (URDF "
                              f"limits with margin {self.cfg.limit_margin})")
        try:
            times, q, qd, qdd = joint_move((start.q, start.qd, start.qdd), target, self.vmax,
                                           self.amax, self.jmax, lower, upper,
                                           self.cfg.waypoint_period)
        except ValueError as exc:
            kind = "joint_limits" if "Positional" in str(exc) else "speed"
            raise PushRefused(kind, name, f"no joint trajectory within the limits: {exc}"
                              ) from None
        return Stage(name, times, q, qd, qdd, self.arm.tip_positions(q))

    def line_stage(self, name: str, q_a: NDArray[np.float64], p_a: NDArray[np.float64],
                   p_b: NDArray[np.float64], speed: float, v0: float = 0.0, v1: float = 0.0,
                   reference: NDArray[np.float64] | None = None,
                   min_height: float | None = None) -> Stage:
        """The tip on the straight line ``p_a`` -> ``p_b`` (jerk-limited speed profile from
        ``v0`` to ``v1``), IK per sample seeded from ``q_a`` (redundancy pulled toward
        ``reference``, default ``reference_positions``), checked (tip above ``min_height``,
        default ``min_tool_height``; the workspace, except for the clear stage's vertical line
        from where the tip already is). A profile whose joint speeds, accelerations or jerks
        exceed the limits is tried again with the Cartesian acceleration, jerk and speed (not
        the push's) scaled by :data:`RAMP_SCALES` (the blend speeds lowered to fit); the last
        failure refuses."""
        cfg = self.cfg
        length = float(np.linalg.norm(p_b - p_a))
        u = (p_b - p_a) / length if length > 0 else np.zeros(3)
        path = self.line_path(name, q_a, p_a, u, length, reference)
        failure = None
        for scale in RAMP_SCALES:
            acc, jerk = cfg.cartesian_acceleration * scale, cfg.cartesian_jerk * scale
            top = speed if name == "push" else max(speed * scale, cfg.push_speed)
            ends = [min(v, top, blend_speed(length, v, acc, jerk)) if v > 0 else 0.0
                    for v in (v0, v1)]
            try:
                times, s, sd, sdd = line_profile(length, *ends, top, acc, jerk,
                                                 cfg.waypoint_period)
            except ValueError as exc:
                raise PushRefused("speed", name, f"no speed profile along the line: {exc}"
                                  ) from None
            if path is None or len(times) < 2:  # no motion
                q = np.repeat(q_a[None], len(times), axis=0)
                qd, qdd = np.zeros_like(q), np.zeros_like(q)
            else:
                q, q_s, q_ss = path(s), path(s, 1), path(s, 2)
                qd = q_s * sd[:, None]
                qdd = q_s * sdd[:, None] + q_ss * (sd**2)[:, None]
            stage = Stage(name, times, q, qd, qdd, self.check_line(name, q, p_a + s[:, None] * u))
            if name != CLEAR:
                self.check_workspace(stage)
            try:
                self.check_stage(stage, q_a, cfg.min_tool_height if min_height is None
                                 else min_height)
            except PushRefused as refusal:
                if refusal.kind != "speed":
                    raise
                failure = refusal
                continue
            return stage
        assert failure is not None
        raise failure

    def line_path(self, name: str, q_a: NDArray[np.float64], p_a: NDArray[np.float64],
                  u: NDArray[np.float64], length: float,
                  reference: NDArray[np.float64] | None = None) -> CubicSpline | None:
        """The joint path along the line as a cubic spline over the path parameter (m) through
        IK solutions every :data:`LINE_KNOT` (each seeded with the path extrapolated from the
        two before), their manipulability checked; None for a line of length 0."""
        if length <= 0.0:
            return None
        knots = np.linspace(0.0, length, max(4, int(math.ceil(length / LINE_KNOT)) + 1))
        q = np.empty((len(knots), self.arm.n_joints))
        for i, s in enumerate(knots):
            target = p_a + s * u
            seed = q_a if i == 0 else q[0] if i == 1 else 2.0 * q[i - 1] - q[i - 2]
            result = self.arm.solve_ik(target, seed,
                                       self.reference if reference is None else reference,
                                       posture_gain=LINE_POSTURE_GAIN,
                                       posture_tolerance=LINE_POSTURE_STEP)
            self.check_ik(name, result.position_error, result.axis_error, target)
            q[i] = result.q
        self.check_singular(name, q, knots)
        return CubicSpline(knots, q, axis=0)

    def check_line(self, name: str, q: NDArray[np.float64], targets: NDArray[np.float64]
                   ) -> NDArray[np.float64]:
        """The tips (N, 3) of the interpolated postures ``q``, each within ``ik_tolerance`` of
        its target on the line and the tool axis vertical (else ``ik``)."""
        tips = np.empty((len(q), 3))
        for i, posture in enumerate(q):
            tips[i], axis = self.arm.tip_pose(posture)
            self.check_ik(name, float(np.linalg.norm(tips[i] - targets[i])),
                          float(math.acos(min(1.0, max(-1.0, -axis[2])))), targets[i])
        return tips

    def blend(self, p_a: NDArray[np.float64], p_b: NDArray[np.float64]) -> float:
        """Speed at which a joint-space stage may join the line ``p_a`` -> ``p_b``, m/s."""
        cfg = self.cfg
        return blend_speed(float(np.linalg.norm(p_b - p_a)), cfg.cartesian_speed,
                           cfg.cartesian_acceleration, cfg.cartesian_jerk)

    def ik_point(self, stage: str, target: NDArray[np.float64],
                 seed: NDArray[np.float64] | None = None,
                 reference: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        result = self.arm.solve_ik(target, self.reference if seed is None else seed,
                                   self.reference if reference is None else reference,
                                   posture_gain=LINE_POSTURE_GAIN,
                                   posture_tolerance=LINE_POSTURE_STEP)
        self.check_ik(stage, result.position_error, result.axis_error, target)
        return result.q

    # ---- composite pieces --------------------------------------------------------------------
    def start_stages(self, start: MotionState, rise: bool = False) -> list[Stage]:
        """The clear stage when the arm rests low over the workspace (its band), or
        (``rise``) rests anywhere below the clear height (else nothing): up to
        :data:`CLEAR_EXTRA` above the approach height, never lower than the tip starts.

        A vertical tool (:data:`CLEAR_TILT`) goes straight up, its redundancy kept near the
        start posture (the stage's first sample within :data:`CLEAR_START_MATCH` of the
        measured posture); a tilted tool (or one whose straight line would not start at its
        posture, or leaves the reach) moves in joint space to the vertical posture above its
        tip, checked to stay at or above the tip's start height."""
        cfg = self.cfg
        tip0, axis0 = self.arm.tip_pose(start.q)
        high = cfg.approach_height + CLEAR_EXTRA - 1e-6 if rise \
            else cfg.approach_height - TRANSIT_SLACK
        if not (start.resting and tip0[2] < high
                and (rise or self.over_workspace(tip0[None, :2])[0])):
            return []
        top = np.array([tip0[0], tip0[1], cfg.approach_height + CLEAR_EXTRA])
        floor = min(cfg.min_tool_height, float(tip0[2]))  # it may start below: it rises
        if float(-axis0[2]) >= math.cos(CLEAR_TILT):
            try:
                stage = self.line_stage(CLEAR, start.q, tip0, top, cfg.cartesian_speed,
                                        reference=start.q, min_height=floor)
            except PushRefused as refusal:
                if refusal.kind != "ik":
                    raise
            else:
                if np.max(np.abs(stage.q[0] - start.q)) <= CLEAR_START_MATCH:
                    return [stage]
        q_top = self.ik_point(CLEAR, top, seed=start.q, reference=start.q)
        stage = self.joint_stage(CLEAR, start, q_top)
        self.check_stage(stage, start.q, floor)
        return [stage]

    def approach(self, start: MotionState, above: NDArray[np.float64],
                 low: NDArray[np.float64]) -> list[Stage]:
        """Transit (blended into the descend when its clearance allows) and descend."""
        cfg = self.cfg
        q_above = self.ik_point("transit", above)
        failure: PushRefused | None = None
        blend = self.blend(above, low)
        for v0 in ((blend, 0.0) if blend > 0 else (0.0,)):
            descend = self.line_stage("descend", q_above, above, low, cfg.cartesian_speed,
                                      v0=v0)
            try:
                transit = self.joint_stage("transit", start, q_above, descend.qd[0],
                                           descend.qdd[0])
                self.check_stage(transit, start.q, self.clearance_floor(transit))
            except PushRefused as refusal:
                failure = refusal  # the blended transit dips or overshoots: end it at rest
                continue
            return [transit, descend]
        assert failure is not None
        raise failure

    def begin(self, start: MotionState, then: Callable[[MotionState], list[Stage]]
              ) -> list[Stage]:
        """The start stages and ``then(state)``: should a joint-space motion from rest dip
        below its clearance (it starts at the approach height, e.g. at a clear pose), the arm
        first rises straight up (:data:`CLEAR_EXTRA` above the approach height) and tries
        again."""
        stages = self.start_stages(start)
        try:
            return stages + then(stages[-1].end if stages else start)
        except PushRefused as refusal:
            rise = self.start_stages(start, rise=True)
            if refusal.kind != "tool_height" or stages or not rise:
                raise
            return rise + then(rise[-1].end)

    def leave(self, lift_from: Stage, view: View | None) -> list[Stage]:
        """Lift and withdraw to the first clear pose that passes every check (or park)."""
        cfg = self.cfg
        back, q_back = lift_from.tip[-1], lift_from.q[-1]
        top = np.array([back[0], back[1], cfg.approach_height + LIFT_EXTRA])
        lifts: dict[bool, Stage] = {}

        def lift(blended: bool) -> Stage:  # the lift is the same for every candidate
            if blended not in lifts:
                lifts[blended] = self.line_stage("lift", q_back, back, top,
                                                 cfg.cartesian_speed,
                                                 v1=self.blend(back, top) if blended else 0.0)
            return lifts[blended]

        for tip in (view.candidates(top) if view is not None else ()):
            tip = np.asarray(tip, dtype=float)
            if float(np.linalg.norm(tip - top)) < 1e-6:  # the lift ends at the clear pose
                if view.covered(lift(False).q[-1]) == 0:
                    return [lift(False)]
                continue
            try:
                q_clear = self.ik_point("withdraw", tip, seed=q_back)
            except PushRefused:
                continue
            if np.any(q_clear < self.lower) or np.any(q_clear > self.upper) \
                    or view.covered(q_clear) > 0:
                continue
            start = lift(True)
            try:
                withdraw = self.joint_stage("withdraw", start.end, q_clear)
                self.check_stage(withdraw, start.q[-1], self.clearance_floor(withdraw))
            except PushRefused:
                continue
            return [start, withdraw]
        park = self.joint_stage(PARK, lift(True).end, np.array(cfg.park_positions,
                                                                 dtype=float))
        self.check_stage(park, lift(True).q[-1], self.clearance_floor(park))
        return [lift(True), park]


def _as_start(arm: ArmKinematics, start: ArrayLike | MotionState) -> MotionState:
    state = start if isinstance(start, MotionState) else MotionState.at_rest(
        np.asarray(start, dtype=float).ravel())
    for name in ("q", "qd", "qdd"):
        value = np.asarray(getattr(state, name), dtype=float)
        if value.shape != (arm.n_joints,) or not np.all(np.isfinite(value)):
            raise PushRefused("invalid", "input", f"start state: expected {arm.n_joints} "
                              f"finite joint {'positions' if name == 'q' else name}")
    return state


def _assemble(arm: ArmKinematics, cfg: MotionConfig, stages: list[Stage],
              lead_in: Stage | None) -> tuple[dict[str, NDArray[np.float64]],
                                               tuple[StageSpan, ...], dict[str, float]]:
    """Concatenate the stages: the first point (the start state) at ``start_delay`` (after a
    lead-in, if any), each later stage without its first sample (the previous stage's last).
    Returns the arrays, the spans and each stage's start time by name (the last such)."""
    parts = ([lead_in] if lead_in is not None else []) + stages
    arrays: dict[str, list[NDArray[np.float64]]] = {k: [] for k in ("t", "q", "qd", "qdd",
                                                                      "tip")}
    spans, starts = [], {}
    t = cfg.start_delay
    for k, stage in enumerate(parts):
        keep = slice(0 if k == 0 else 1, None)
        arrays["t"].append(t + stage.times[keep])
        for key, values in (("q", stage.q), ("qd", stage.qd), ("qdd", stage.qdd),
                            ("tip", stage.tip)):
            arrays[key].append(values[keep])
        spans.append(StageSpan(stage.name, t, t + float(stage.times[-1])))
        starts[stage.name] = t
        t += float(stage.times[-1])
    out = {k: np.concatenate(v) for k, v in arrays.items()}
    out["qd"][-1] = 0.0
    out["qdd"][-1] = 0.0
    return out, tuple(spans), starts


def _plan(arm: ArmKinematics, cfg: MotionConfig, stages: list[Stage], lead_in: Stage | None,
          contact: tuple[float, float], line: NDArray[np.float64], chain_name: str
          ) -> MotionPlan:
    out, spans, starts = _assemble(arm, cfg, stages, lead_in)
    chain_from = next((s.t_end for s in reversed(spans) if s.name == chain_name),
                      spans[-1].t_start)
    if math.isfinite(contact[0]):
        contact = (contact[0] + starts["push"], contact[1] + starts["push"])
    return MotionPlan(joint_names=arm.joint_names, times=out["t"], positions=out["q"],
                      velocities=out["qd"], accelerations=out["qdd"], tip=out["tip"],
                      stages=spans, contact_start=contact[0], contact_end=contact[1],
                      line=line, chain_from=float(chain_from))


def plan_push(arm: ArmKinematics, config: MotionConfig, approach: ArrayLike,
              contact: ArrayLike, end: ArrayLike, start: ArrayLike | MotionState,
              view: View | None = None, lead_in: MotionPlan | None = None,
              lead_from: float = 0.0) -> MotionPlan:
    """Plan and check the whole motion of one push (module docstring).

    Parameters
    ----------
    arm : ArmKinematics
    config : MotionConfig
    approach, contact, end : (2,) array_like
        Pusher axis points on the table in ``world`` (``planner/push``), m.
    start : (n,) array_like or MotionState
        Measured chain joint positions (the arm at rest) or the state the motion starts from
        (chained: the previous plan's state at its ``chain_from`` or later).
    view : View, optional
        The camera and the object, for the clear pose; None: the motion ends parked.
    lead_in, lead_from : MotionPlan, float, optional
        Chaining: the previous plan, whose points from its time ``lead_from`` up to the state
        ``start`` (taken at ``max(lead_from, lead_in.chain_from)``) lead the new trajectory in.

    Returns
    -------
    MotionPlan

    Raises
    ------
    PushRefused
        The first failed check (kind, stage, reason).
    ValueError
        ``park_positions`` / ``reference_positions`` do not fit the chain.
    """
    planner = _Planner(arm, config)
    cfg = config
    points = []
    for label, p in (("approach", approach), ("contact", contact), ("end", end)):
        arr = np.asarray(p, dtype=float).ravel()
        if arr.shape != (2,) or not np.all(np.isfinite(arr)):
            raise PushRefused("invalid", "input", f"{label} point must be 2 finite values")
        points.append(arr)
    a2, c2, e2 = points
    state = _as_start(arm, start)
    contact_along = planner.check_input(a2, c2, e2)

    def lifted(p: NDArray[np.float64], z: float) -> NDArray[np.float64]:
        return np.array([p[0], p[1], z])

    above, low = lifted(a2, cfg.approach_height), lifted(a2, cfg.push_height)
    end3 = lifted(e2, cfg.push_height)
    u = (end3 - low) / np.linalg.norm(end3 - low)
    back = end3 - cfg.retreat * u

    stages = planner.begin(state, lambda begin: planner.approach(begin, above, low))
    for name, p_b, speed in (("push", end3, cfg.push_speed),
                             ("retreat", back, cfg.cartesian_speed)):
        prev = stages[-1]
        stages.append(planner.line_stage(name, prev.q[-1], prev.tip[-1], p_b, speed))
    push = stages[-2]
    push_s = np.linalg.norm(push.tip - push.tip[0], axis=1)
    contact_times = (float(np.interp(contact_along, push_s, push.times)),
                     float(push.times[-1]))
    stages += planner.leave(stages[-1], view)
    return _plan(arm, cfg, stages, _lead_in(arm, lead_in, lead_from, state), contact_times,
                 np.array([lifted(c2, cfg.push_height), end3]), "lift")


def plan_park(arm: ArmKinematics, config: MotionConfig, start: ArrayLike | MotionState,
              lead_in: MotionPlan | None = None, lead_from: float = 0.0) -> MotionPlan:
    """The motion to ``park_positions`` alone (a clear stage first when the arm rests low
    over the workspace); arguments and checks as :func:`plan_push`."""
    planner = _Planner(arm, config)
    state = _as_start(arm, start)
    def park(begin: MotionState) -> list[Stage]:
        stage = planner.joint_stage(PARK, begin, np.array(config.park_positions, dtype=float))
        planner.check_stage(stage, begin.q, planner.clearance_floor(stage))
        return [stage]

    stages = planner.begin(state, park)
    nan = np.full((2, 3), math.nan)
    return _plan(arm, config, stages, _lead_in(arm, lead_in, lead_from, state),
                 (math.nan, math.nan), nan, CLEAR)


def _lead_in(arm: ArmKinematics, previous: MotionPlan | None, first: float,
             state: MotionState) -> Stage | None:
    """The previous plan's points from ``first`` to the chain point, as a stage from 0."""
    if previous is None:
        return None
    until = chain_point(previous, first)
    first = min(first, until)
    inside = (previous.times > first + 1e-9) & (previous.times < until - 1e-9)
    times = np.concatenate([[first], previous.times[inside], [until]]) if until > first \
        else np.array([first])
    states = [previous.state_at(float(t)) for t in times[:-1]] + [state]
    q = np.array([s.q for s in states])
    return Stage(previous.stage_at(until), times - first, q, np.array([s.qd for s in states]),
                  np.array([s.qdd for s in states]), arm.tip_positions(q))
