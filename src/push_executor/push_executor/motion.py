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
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from push_executor.kinematics import ArmKinematics
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

#: The joint-space stages may dip this far below their clearance height, m (a motion from
#: rest at that height starts with a dip of a few millimetres).
TRANSIT_SLACK = 5e-3
#: The lift ends this far above the approach height (a transit from rest there dips by up to
#: 1.6 cm on its way; measured on the graph), m.
LIFT_EXTRA = 0.025
#: The clear stage lifts this much above the approach height (the transit then comes down to
#: it instead of crossing at it), m.
CLEAR_EXTRA = 0.05
#: Band around the workspace where the joint-space stages keep the approach height, m.
CLEARANCE_MARGIN = 0.05
#: Largest distance of the contact point from the approach -> end segment, m.
CONTACT_OFF_LINE = 1e-3
#: Relative slack of the speed, acceleration and jerk checks (sampling round-off).
LIMIT_SLACK = 1e-6
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


@dataclass
class _Stage:
    name: str
    times: NDArray[np.float64]  # from the stage's start, s
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    qdd: NDArray[np.float64]
    tip: NDArray[np.float64]

    @property
    def end(self) -> MotionState:
        return MotionState(self.q[-1].copy(), self.qd[-1].copy(), self.qdd[-1].copy())

    @property
    def start(self) -> MotionState:
        return MotionState(self.q[0].copy(), self.qd[0].copy(), self.qdd[0].copy())


class _Planner:
    """Builds and checks the stages of one motion (see :func:`plan_push`)."""

    def __init__(self, arm: ArmKinematics, config: MotionConfig) -> None:
        self.arm, self.cfg = arm, config
        config.check_chain(arm.joint_names)
        self.reference = np.array(config.reference_positions, dtype=float)
        self.vmax = arm.velocity_limits * config.speed_margin
        self.amax = arm.acceleration_limits * config.speed_margin
        self.jmax = arm.jerk_limits * config.speed_margin
        self.lower = arm.lower + config.limit_margin
        self.upper = arm.upper - config.limit_margin

    # ---- stages ------------------------------------------------------------------------------
    def joint_stage(self, name: str, start: MotionState, q_b: NDArray[np.float64],
                    qd_b: NDArray[np.float64] | None = None,
                    qdd_b: NDArray[np.float64] | None = None) -> _Stage:
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
        return _Stage(name, times, q, qd, qdd, self.arm.tip_positions(q))

    def line_stage(self, name: str, q_a: NDArray[np.float64], p_a: NDArray[np.float64],
                   p_b: NDArray[np.float64], speed: float, v0: float = 0.0, v1: float = 0.0
                   ) -> _Stage:
        """The tip on the straight line ``p_a`` -> ``p_b`` (jerk-limited speed profile from
        ``v0`` to ``v1``), IK per sample seeded from ``q_a``, checked (``min_tool_height``).
        A profile whose joint speeds, accelerations or jerks exceed the limits is tried again
        with the Cartesian acceleration, jerk and speed (not the push's) scaled by
        :data:`RAMP_SCALES` (the blend speeds lowered to fit); the last failure refuses."""
        cfg = self.cfg
        length = float(np.linalg.norm(p_b - p_a))
        u = (p_b - p_a) / length if length > 0 else np.zeros(3)
        path = self.line_path(name, q_a, p_a, u, length)
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
            stage = _Stage(name, times, q, qd, qdd, self.check_line(name, q, p_a + s[:, None] * u))
            self.check_workspace(stage)
            try:
                self.check_stage(stage, q_a, cfg.min_tool_height)
            except PushRefused as refusal:
                if refusal.kind != "speed":
                    raise
                failure = refusal
                continue
            return stage
        assert failure is not None
        raise failure

    def line_path(self, name: str, q_a: NDArray[np.float64], p_a: NDArray[np.float64],
                  u: NDArray[np.float64], length: float) -> CubicSpline | None:
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
            result = self.arm.solve_ik(target, seed, self.reference,
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
                 seed: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        result = self.arm.solve_ik(target, self.reference if seed is None else seed,
                                   self.reference, posture_gain=LINE_POSTURE_GAIN,
                                   posture_tolerance=LINE_POSTURE_STEP)
        self.check_ik(stage, result.position_error, result.axis_error, target)
        return result.q

    # ---- checks ------------------------------------------------------------------------------
    def check_ik(self, stage: str, position_error: float, axis_error: float,
                 target: NDArray[np.float64]) -> None:
        if not (position_error <= self.cfg.ik_tolerance and axis_error <= self.cfg.ik_tolerance):
            raise PushRefused("ik", stage, f"no inverse kinematics solution for the tip at "
                              f"({target[0]:.3f}, {target[1]:.3f}, {target[2]:.3f}) m: residual "
                              f"{position_error * 1e3:.3f} mm, tool axis {axis_error:.2e} rad "
                              "off vertical (out of reach?)")

    def check_workspace(self, stage: _Stage) -> None:
        x_min, x_max, y_min, y_max = self.cfg.workspace
        xy = stage.tip[:, :2]
        out = (xy[:, 0] < x_min - 1e-9) | (xy[:, 0] > x_max + 1e-9) | \
            (xy[:, 1] < y_min - 1e-9) | (xy[:, 1] > y_max + 1e-9)
        if np.any(out):
            x, y = xy[np.argmax(out)]
            raise PushRefused("workspace", stage.name, f"tip at ({x:.3f}, {y:.3f}) m leaves the "
                              f"workspace x [{x_min}, {x_max}], y [{y_min}, {y_max}] m")

    def check_singular(self, name: str, q: NDArray[np.float64], along: NDArray[np.float64]
                       ) -> None:
        """Manipulability of postures ``q`` at ``along`` m of a line's length."""
        m = np.array([self.arm.manipulability(posture) for posture in q])
        if np.min(m) < self.cfg.min_manipulability:
            i = int(np.argmin(m))
            raise PushRefused("singular", name, f"manipulability {m[i]:.4f} < "
                              f"{self.cfg.min_manipulability} {1e3 * along[i]:.0f} mm along "
                              "the line (near a singular posture)")

    def over_workspace(self, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Which (N, 2) points lie within CLEARANCE_MARGIN of the workspace rectangle."""
        x_min, x_max, y_min, y_max = self.cfg.workspace
        m = CLEARANCE_MARGIN
        return ((xy[:, 0] >= x_min - m) & (xy[:, 0] <= x_max + m)
                & (xy[:, 1] >= y_min - m) & (xy[:, 1] <= y_max + m))

    def clearance_floor(self, stage: _Stage) -> NDArray[np.float64]:
        """Per sample of a joint-space stage: the approach height (less the slack) over the
        workspace and its margin, ``min_tool_height`` elsewhere."""
        cfg = self.cfg
        return np.where(self.over_workspace(stage.tip[:, :2]),
                        max(cfg.approach_height - TRANSIT_SLACK, cfg.min_tool_height),
                        cfg.min_tool_height)

    def check_stage(self, stage: _Stage, q_start: NDArray[np.float64],
                    min_height: float | NDArray[np.float64]) -> None:
        """Joint limits, tool height (per sample or one value), speeds, accelerations, jerks."""
        arm, margin = self.arm, self.cfg.limit_margin
        lower, upper = self.lower, self.upper
        if stage.name in ("transit", "withdraw", PARK):  # may start outside, never go further
            lower, upper = np.minimum(lower, q_start), np.maximum(upper, q_start)
        bad = (stage.q < lower - 1e-9) | (stage.q > upper + 1e-9)
        if np.any(bad):
            i, j = np.argwhere(bad)[0]
            raise PushRefused("joint_limits", stage.name, f"{arm.joint_names[j]} at "
                              f"{stage.q[i, j]:.4f} outside [{lower[j]:.4f}, {upper[j]:.4f}] "
                              f"(URDF limits with margin {margin})")
        z = stage.tip[:, 2]
        floor = np.broadcast_to(min_height, z.shape)
        low = z < floor - self.cfg.ik_tolerance  # the tip is only known to the IK's accuracy
        if np.any(low):
            i = int(np.argmax(low))
            raise PushRefused("tool_height", stage.name, f"tip at ({stage.tip[i, 0]:.3f}, "
                              f"{stage.tip[i, 1]:.3f}, {z[i]:.4f}) m, below {floor[i]:.4f} m "
                              f"at t = {stage.times[i]:.2f} s")
        self.check_limits(stage.name, stage.times, stage.qd, stage.qdd)

    def check_limits(self, name: str, times: NDArray[np.float64], qd: NDArray[np.float64],
                     qdd: NDArray[np.float64]) -> None:
        """Speeds, accelerations (the samples' and the velocities' finite differences) and
        jerks (the accelerations' finite differences) within the limits x speed_margin."""
        names = self.arm.joint_names
        checks = [("", "/s", "velocity", qd, self.vmax, times)]
        if len(times) > 1:
            dt = np.diff(times)[:, None]
            checks += [(" accelerates at", "/s^2", "acceleration", qdd, self.amax, times),
                       (" accelerates at", "/s^2", "acceleration", np.diff(qd, axis=0) / dt,
                        self.amax, times[1:]),
                       (" jerks at", "/s^3", "jerk", np.diff(qdd, axis=0) / dt, self.jmax,
                        times[1:])]
        for verb, unit, what, values, limit, at in checks:
            ratio = np.abs(values) / limit
            if np.max(ratio) > 1.0 + LIMIT_SLACK:
                i, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
                raise PushRefused("speed", name, f"{names[j]}{verb or ' at'} "
                                  f"{values[i, j]:.3f} {unit}, limit {limit[j]:.3f} {unit} "
                                  f"({what} limit x speed_margin) at t = {at[i]:.2f} s")

    def check_input(self, approach: NDArray[np.float64], contact: NDArray[np.float64],
                    end: NDArray[np.float64]) -> float:
        """Finite points in the workspace, a straight push; returns approach -> contact."""
        x_min, x_max, y_min, y_max = self.cfg.workspace
        for label, p in (("approach", approach), ("contact", contact), ("end", end)):
            if not (x_min <= p[0] <= x_max and y_min <= p[1] <= y_max):
                raise PushRefused("workspace", "input", f"{label} point ({p[0]:.3f}, "
                                  f"{p[1]:.3f}) m outside the workspace x [{x_min}, {x_max}], "
                                  f"y [{y_min}, {y_max}] m")
        length = float(np.linalg.norm(end - approach))
        if not length <= self.cfg.max_push_length:
            raise PushRefused("invalid", "input", f"push {length:.3f} m long, more than "
                              f"max_push_length {self.cfg.max_push_length} m")
        if length < 1e-4:
            raise PushRefused("invalid", "input", "approach and end point coincide")
        u = (end - approach) / length
        along = float((contact - approach) @ u)
        off = float(np.linalg.norm(contact - approach - along * u))
        if off > CONTACT_OFF_LINE or not -1e-9 <= along <= length + 1e-9:
            raise PushRefused("invalid", "input", "the contact point is not on the approach -> "
                              f"end segment ({off * 1e3:.1f} mm off)")
        return along

    # ---- composite pieces --------------------------------------------------------------------
    def start_stages(self, start: MotionState, rise: bool = False) -> list[_Stage]:
        """The clear stage when the arm rests low over the workspace, or (``rise``) rests
        anywhere below the clear height (else nothing)."""
        cfg = self.cfg
        tip0 = self.arm.tip_pose(start.q)[0]
        high = cfg.approach_height + CLEAR_EXTRA - 1e-6 if rise \
            else cfg.approach_height - TRANSIT_SLACK
        if not (start.resting and self.over_workspace(tip0[None, :2])[0] and tip0[2] < high):
            return []
        top = np.array([tip0[0], tip0[1], cfg.approach_height + CLEAR_EXTRA])
        return [self.line_stage(CLEAR, start.q, tip0, top, cfg.cartesian_speed)]

    def approach(self, start: MotionState, above: NDArray[np.float64],
                 low: NDArray[np.float64]) -> list[_Stage]:
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

    def begin(self, start: MotionState, then: Callable[[MotionState], list[_Stage]]
              ) -> list[_Stage]:
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

    def leave(self, lift_from: _Stage, view: View | None) -> list[_Stage]:
        """Lift and withdraw to the first clear pose that passes every check (or park)."""
        cfg = self.cfg
        back, q_back = lift_from.tip[-1], lift_from.q[-1]
        top = np.array([back[0], back[1], cfg.approach_height + LIFT_EXTRA])
        lifts: dict[bool, _Stage] = {}

        def lift(blended: bool) -> _Stage:  # the lift is the same for every candidate
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


def _assemble(arm: ArmKinematics, cfg: MotionConfig, stages: list[_Stage],
              lead_in: _Stage | None) -> tuple[dict[str, NDArray[np.float64]],
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


def _plan(arm: ArmKinematics, cfg: MotionConfig, stages: list[_Stage], lead_in: _Stage | None,
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
    def park(begin: MotionState) -> list[_Stage]:
        stage = planner.joint_stage(PARK, begin, np.array(config.park_positions, dtype=float))
        planner.check_stage(stage, begin.q, planner.clearance_floor(stage))
        return [stage]

    stages = planner.begin(state, park)
    nan = np.full((2, 3), math.nan)
    return _plan(arm, config, stages, _lead_in(arm, lead_in, lead_from, state),
                 (math.nan, math.nan), nan, CLEAR)


def _lead_in(arm: ArmKinematics, previous: MotionPlan | None, first: float,
             state: MotionState) -> _Stage | None:
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
    return _Stage(previous.stage_at(until), times - first, q, np.array([s.qd for s in states]),
                  np.array([s.qdd for s in states]), arm.tip_positions(q))
