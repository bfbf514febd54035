"""The measured state before a push is planned, bounds on the plan, and whether the executor
can take a push at all (ROS-free).

Times: ``steady`` values are a monotonic clock of the executor's machine, s; ``clock`` values
the node's clock (simulated time in simulation), s; joint positions in rad (m for prismatic
joints), in the chain's order (``joint_names`` of :class:`push_executor.kinematics.ArmKinematics`).

A joint state whose chain posture is not finite or outside the limits by more than
``state_margin`` (:func:`nonfinite_joints`, :func:`posture_problem`) is not taken as the
measured posture: the node keeps the last plausible one in its
:class:`push_executor.tracking.MeasuredArm` (which a stop then holds), records the problem
there (``problem``) and, while a push runs, does not feed it to the tracking (implausible
states alone stop the arm as stale ones do).

Before :func:`push_executor.motion.plan_push` runs, :func:`check_before_planning` refuses

- ``no_state``: no joint state yet, or none for ``state_timeout`` s (steady clock);
- ``state``: the newest joint state has a non-finite position of a chain joint (the posture
  is unknown; the last finite one is not used), the posture is outside the URDF position
  limits by more than ``state_margin`` (a glitched encoder: the transit from 100 rad would
  take a minute, from -1e6 rad its samples would not fit in memory), the joint state is
  stamped more than ``max_state_age`` s before the node's clock (a driver re-sending an old
  state), or the worst-case joint-space stage from this posture (:func:`joint_stage_bound`)
  would last longer than ``max_duration``.

An arm still moving is not refused here: the node defers a push until the arm is held, and a
push during its own motion chains from the running plan (docs/design/cycle.md).

With the posture within the limits every joint-space stage is bounded by the joint ranges and
the velocity, acceleration and jerk limits, the Cartesian stages by the workspace and the
speeds, so planning is bounded in time and memory for every finite input. :func:`check_plan`
then refuses (kind ``plan``) a plan longer than ``max_duration`` s or with more than
``max_points`` points before anything is published.

A refusal at the ``clear`` stage, or a ``tool_height`` refusal of the ``transit`` from a tool
tip lower than the approach height, is a posture the executor cannot leave (re-planning
another push starts from the same posture): :class:`StuckPosture` turns it into kind
``state`` and keeps the executor unavailable until the measured posture has changed.

:func:`unavailable` is the executor's readiness in one rule (``executor/status``'s
``ready``): the first of ``no_model``, ``disabled``, ``no_state``, ``state`` (the checks
above, a posture it cannot leave), ``settling`` (no motion of its own runs and the arm is not
held: stopping after a hold, or moved by another client), ``no_controller`` that holds, or
None (ready).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_executor.kinematics import ArmKinematics
from push_executor.motion_types import CLEAR, MotionConfig, MotionPlan, PushRefused
from push_executor.tracking import MeasuredArm

__all__ = ["STUCK_MOVE", "StateCheckConfig", "StuckPosture", "check_before_planning",
           "check_plan", "check_posture", "joint_move_bound", "joint_stage_bound",
           "nonfinite_joints", "posture_problem", "unavailable"]

#: A posture the executor could not leave counts as changed once a joint moved this far, rad.
STUCK_MOVE = 0.01


@dataclass(frozen=True)
class StateCheckConfig:
    """Thresholds of the state checks and the plan bounds (module docstring).

    Attributes
    ----------
    state_margin : float
        How far (rad, m for prismatic joints) a measured joint may be outside its URDF limits.
    state_timeout : float
        Longest time without a joint state before a push is refused ``no_state``, s (steady).
    max_state_age : float
        Largest age of the newest joint state's stamp against the node's clock, s.
    max_duration : float
        Longest trajectory, s (``time_from_start`` of its last point).
    max_points : int
        Most points of a trajectory.
    """

    state_margin: float = 0.05
    state_timeout: float = 1.0
    max_state_age: float = 2.0
    max_duration: float = 120.0
    max_points: int = 20_000

    def __post_init__(self) -> None:
        for name in ("state_margin", "state_timeout", "max_state_age", "max_duration"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
        for name in ("state_timeout", "max_duration"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name}: must be > 0, got {getattr(self, name)!r}")
        if isinstance(self.max_points, bool) or int(self.max_points) != self.max_points \
                or self.max_points < 2:
            raise ValueError(f"max_points: must be an integer >= 2, got {self.max_points!r}")


def nonfinite_joints(chain: Sequence[str], names: Sequence[str], positions: ArrayLike) -> str:
    """Which chain joints of a joint state have a non-finite position (``""``: none, or the
    message does not map the chain's joints one to one: a malformed message, not a posture).

    Parameters
    ----------
    chain : sequence of str
        The chain's joint names.
    names : sequence of str
        The joint state's names.
    positions : array_like
        The joint state's positions, same length as ``names``.
    """
    values = np.asarray(positions, dtype=float).ravel()
    if len(values) != len(names) or len(set(names)) != len(names):
        return ""
    index = {name: i for i, name in enumerate(names)}
    if any(j not in index for j in chain):
        return ""
    bad = [f"{j} = {values[index[j]]}" for j in chain if not math.isfinite(values[index[j]])]
    return f"non-finite joint position ({', '.join(bad)})" if bad else ""


def posture_problem(arm: ArmKinematics, q: ArrayLike, margin: float) -> str:
    """Why ``q`` is not a posture the arm can be in (``""``: it can): not finite, or outside
    the URDF limits widened by ``margin``; the first joint outside is named with its value
    and limits."""
    arr = np.asarray(q, dtype=float).ravel()
    if arr.shape != (arm.n_joints,):
        return f"measured posture: {arr.size} values for the {arm.n_joints} chain joints"
    lower, upper = arm.lower - margin, arm.upper + margin
    bad = ~np.isfinite(arr) | (arr < lower) | (arr > upper)
    if not np.any(bad):
        return ""
    j = int(np.argmax(bad))
    return (f"measured {arm.joint_names[j]} = {arr[j]:.6g} is outside its URDF limits "
            f"[{arm.lower[j]:.4f}, {arm.upper[j]:.4f}] by more than state_margin {margin} (a "
            "faulty encoder or joint state?)")


def check_posture(arm: ArmKinematics, q: ArrayLike, margin: float) -> None:
    """``PushRefused`` (kind ``state``) naming :func:`posture_problem`'s joint, if any."""
    problem = posture_problem(arm, q, margin)
    if problem:
        raise PushRefused("state", "", f"{problem}: not planned")


def joint_move_bound(span: ArrayLike, velocity: ArrayLike, acceleration: ArrayLike,
                     jerk: ArrayLike, moving: bool = True) -> float:
    """An upper bound on the duration of a time-optimal jerk-limited joint motion
    (:func:`push_executor.timing.joint_move`, ruckig) over ``span`` per joint, from and to
    any state within the limits (``moving`` False: from rest to rest), s.

    Per joint, with ``V``, ``A``, ``J`` its limits: the rest-to-rest profile that reaches the
    velocity limit ramps up and down in ``V / A + A / J`` and cruises the rest, so no
    rest-to-rest motion over ``d`` takes longer than ``d / V + V / A + A / J`` (when ``A`` is
    not reached, ``2 sqrt(V / J)`` is smaller). A moving start or end (at most ``V``, ``A``)
    first brakes to rest (or accelerates from rest) in at most ``t_b = V / A + 3 A / J`` over
    at most ``(V + A^2 / 2J) t_b``, counted at both ends; ruckig's time-synchronised motion
    lasts as long as its slowest joint's, so the bound is the largest over the joints.

    Parameters
    ----------
    span : (n,) array_like
        Largest distance each joint travels between start and end, rad (m).
    velocity, acceleration, jerk : (n,) array_like
        The limits used (already times ``speed_margin``), > 0.
    moving : bool
        Whether the start or the end state may move.
    """
    d, v, a, j = (np.asarray(x, dtype=float) for x in (span, velocity, acceleration, jerk))
    brake = v / a + 3.0 * a / j if moving else np.zeros_like(v)
    brake_distance = (v + a * a / (2.0 * j)) * brake
    return float(np.max(2.0 * brake + (d + 2.0 * brake_distance) / v + v / a + a / j))


def joint_stage_bound(arm: ArmKinematics, q: ArrayLike, motion: MotionConfig) -> float:
    """Longest joint-space stage (:func:`joint_move_bound` at ``speed_margin`` times the
    limits) from ``q`` to any posture within the URDF limits, or from there to
    ``park_positions``, s.

    Parameters
    ----------
    arm : ArmKinematics
    q : (n,) array_like
        Start posture (finite; within the limits plus the state margin).
    motion : MotionConfig
        ``speed_margin`` and ``park_positions``.
    """
    start = np.asarray(q, dtype=float).ravel()
    park = np.asarray(motion.park_positions, dtype=float)
    # The transit ends within the limits (the inverse kinematics clips to them), the withdraw
    # and park stages go from within them to within them or to the park posture.
    span = np.maximum.reduce([np.abs(arm.upper - start), np.abs(start - arm.lower),
                              arm.upper - arm.lower, np.abs(arm.upper - park),
                              np.abs(park - arm.lower)])
    m = motion.speed_margin
    return joint_move_bound(span, arm.velocity_limits * m, arm.acceleration_limits * m,
                            arm.jerk_limits * m)


def check_before_planning(arm: ArmKinematics, measured: MeasuredArm,
                          config: StateCheckConfig, motion: MotionConfig, steady: float,
                          clock: float | None) -> NDArray[np.float64]:
    """The measured posture to plan from, or ``PushRefused`` (module docstring).

    Parameters
    ----------
    arm : ArmKinematics
    measured : MeasuredArm
        The newest plausible posture, its stamp and arrival, and the newest state's problem.
    config : StateCheckConfig
    motion : MotionConfig
    steady : float
        Now, s (steady clock).
    clock : float or None
        The node's clock now, s; None while a simulated clock has not started (no age check).

    Returns
    -------
    (n,) ndarray
        ``measured.q``.

    Raises
    ------
    PushRefused
        Kind ``no_state`` or ``state``.
    """
    if measured.problem:  # the robot's newest word on its posture: not one it can be in
        raise PushRefused("state", "", f"the newest joint state is unusable: "
                          f"{measured.problem}; not planned")
    if measured.q is None or steady - measured.steady > config.state_timeout:
        raise PushRefused("no_state", "", f"no joint state for {config.state_timeout} s "
                          "(state_timeout)" if measured.q is not None else "no joint state yet")
    check_posture(arm, measured.q, config.state_margin)
    if clock is not None and clock - measured.stamp > config.max_state_age:
        raise PushRefused("state", "", f"the newest joint state is stamped "
                          f"{clock - measured.stamp:.3f} s before the node's clock (more than "
                          f"max_state_age {config.max_state_age} s): a stale state, or "
                          "clocks not synchronised")
    bound = joint_stage_bound(arm, measured.q, motion)
    if bound > config.max_duration:
        raise PushRefused("state", "", f"a joint-space stage from the measured posture could "
                          f"take up to {bound:.1f} s, more than max_trajectory_duration "
                          f"{config.max_duration} s (the joint limits x speed_margin)")
    return measured.q


def check_plan(plan: MotionPlan, config: StateCheckConfig) -> None:
    """``PushRefused`` (kind ``plan``) when ``plan`` lasts longer than ``max_duration`` or has
    more than ``max_points`` points."""
    n = len(plan.times)
    if not (plan.duration <= config.max_duration and n <= config.max_points):
        raise PushRefused("plan", "", f"the planned trajectory lasts {plan.duration:.2f} s with "
                          f"{n} points; the limits are max_trajectory_duration "
                          f"{config.max_duration} s and max_trajectory_points "
                          f"{config.max_points}")


class StuckPosture:
    """A posture the executor could not leave (module docstring), until the arm moved."""

    def __init__(self) -> None:
        self.q: NDArray[np.float64] | None = None
        self.reason = ""

    def classify(self, refusal: PushRefused, arm: ArmKinematics, q: ArrayLike | None,
                 motion: MotionConfig) -> PushRefused:
        """``refusal`` itself, or kind ``state`` when it says the measured posture ``q`` (None:
        none yet) cannot be left; that posture is then remembered."""
        if q is None or refusal.kind in ("state", "no_state"):
            return refusal
        tip_height = float(arm.tip_pose(q)[0][2])
        low = tip_height < motion.approach_height
        if not (refusal.stage == CLEAR or (refusal.stage == "transit" and low
                                           and refusal.kind == "tool_height")):
            return refusal
        self.q = np.array(q, dtype=float)
        self.reason = (f"the arm cannot leave its posture (tool tip {tip_height:.3f} m above "
                       f"the table; {refusal.kind} at {refusal.stage}: {refusal.reason}); "
                       "move it clear of the table (above approach_height, e.g. to the park "
                       "posture) with the robot's own tools")
        return PushRefused("state", refusal.stage, self.reason)

    def holds(self, q: ArrayLike | None) -> bool:
        """Whether the remembered posture is still the measured one (``q``); forgets it once
        a joint moved more than :data:`STUCK_MOVE`."""
        if self.q is None:
            return False
        if q is not None and np.max(np.abs(np.asarray(q, dtype=float) - self.q)) > STUCK_MOVE:
            self.q, self.reason = None, ""
            return False
        return True


def unavailable(*, model: bool, enabled: bool, arm: ArmKinematics | None,
                measured: MeasuredArm, stuck: StuckPosture, config: StateCheckConfig,
                motion: MotionConfig, controller: bool, moving: bool, steady: float,
                clock: float | None) -> tuple[str, str] | None:
    """Why the executor cannot take a push now: ``(kind, reason)``, or None when it can.

    One rule for ``executor/status`` and the ``available`` value of a refusal (module
    docstring); a push arriving while it is None is planned (and may still be refused for its
    own geometry). ``moving``: a motion of the executor's own runs (a push then chains, and
    the arm is not expected to be held).
    """
    if not model or arm is None:
        return "no_model", "no robot description yet"
    if not enabled:
        return "disabled", "executor disabled (dry run): plans, moves nothing; ~/enable true"
    try:
        check_before_planning(arm, measured, config, motion, steady, clock)
    except PushRefused as refusal:
        return refusal.kind, refusal.reason
    if clock is None:
        return "no_state", "the node's clock has not started (no /clock yet)"
    if stuck.holds(measured.q):
        return "state", stuck.reason
    if not moving and not measured.held(steady):
        return "settling", ("the arm is moving without a trajectory of this executor (stopping "
                            "after a hold, or commanded by another client): a push starts once "
                            "it is held")
    if not controller:
        return "no_controller", "no controller subscribes the trajectory topic"
    return None
