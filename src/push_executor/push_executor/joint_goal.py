"""A joint-space goal: the arm to one given posture, planned and checked like a park.

ROS-free. A goal (``executor/joint_goal``, docs/INTERFACES.md) names a posture of the chain;
:func:`plan_joint_goal` plans the motion to it from the arm's state: the clear stage first when
the arm rests low over the workspace (as before a park), then one time-optimal, jerk-limited
joint-space stage (ruckig, :func:`push_executor.timing.joint_move`) to the goal, at rest there.
The checks are a park's: the goal within the joint limits less ``limit_margin``, the tool tip
and the flange above ``min_tool_height`` everywhere (and the tip at ``approach_height`` over the
workspace), joint speeds, accelerations and jerks within the limits times ``speed_margin``;
the node adds the state checks before planning, the plan's bounds and the dry-run rule (a
disabled executor plans the goal, publishes its path and moves nothing).

Goals are how a tool pose that is not the pushing task's (the rod pointing down) is reached: a
calibration points the board on the tool at the camera. :func:`pose_ik` is the 6-D inverse
kinematics that turns such a flange pose into the goal's posture (damped least squares on
pinocchio's frame Jacobian, the redundancy pulled toward a reference posture); the caller
sends the posture, and the executor checks the motion.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from push_executor.kinematics import ArmKinematics
from push_executor.motion import _as_start, _lead_in, _plan, _Planner
from push_executor.motion_checks import Stage
from push_executor.motion_types import MotionConfig, MotionPlan, MotionState, PushRefused

__all__ = ["GOAL", "PoseIkResult", "goal_positions", "plan_joint_goal", "pose_ik"]

#: Name of the joint-space stage to a goal.
GOAL = "goal"
#: :func:`pose_ik` gives up on a seed whose error did not fall below this fraction of what it
#: was this many iterations before (converging damped least squares shrinks it far faster).
STALL_RATIO, STALL_ITERATIONS = 0.5, 50


def goal_positions(names: Sequence[str], positions: Sequence[float],
                   chain: Sequence[str]) -> NDArray[np.float64]:
    """The goal's positions in chain order; ``PushRefused`` (kind ``invalid``) unless every
    chain joint is named once with a finite position (other joints, e.g. fingers, ignored)."""
    names, positions = list(names)[:64], list(positions)[:64]
    if len(names) != len(positions):
        raise PushRefused("invalid", "input", f"joint goal: {len(names)} names, "
                          f"{len(positions)} positions")
    missing = [j for j in chain if names.count(j) != 1]
    if missing:
        raise PushRefused("invalid", "input", f"joint goal: joints {missing} not named once")
    q = np.array([float(positions[names.index(j)]) for j in chain])
    if not np.all(np.isfinite(q)):
        raise PushRefused("invalid", "input", "joint goal: non-finite positions")
    return q


def plan_joint_goal(arm: ArmKinematics, config: MotionConfig, goal: ArrayLike,
                    start: ArrayLike | MotionState, lead_in: MotionPlan | None = None,
                    lead_from: float = 0.0) -> MotionPlan:
    """Plan and check the motion to the posture ``goal`` (module docstring).

    Parameters
    ----------
    arm : ArmKinematics
    config : MotionConfig
    goal : (n,) array_like
        Chain joint positions, rad (m for prismatic joints).
    start, lead_in, lead_from
        As :func:`push_executor.motion.plan_push`.

    Returns
    -------
    MotionPlan
        A plan without a contact segment (``is_push`` false), its last stage :data:`GOAL`.

    Raises
    ------
    PushRefused
        ``invalid`` (the goal's shape), ``joint_limits``, ``tool_height``, ``speed`` or the
        clear stage's kinds.
    """
    planner = _Planner(arm, config)
    state = _as_start(arm, start)
    q_goal = np.asarray(goal, dtype=float).ravel()
    if q_goal.shape != (arm.n_joints,) or not np.all(np.isfinite(q_goal)):
        raise PushRefused("invalid", "input", f"joint goal: expected {arm.n_joints} finite "
                          "positions")
    flange = arm.tool.flange_link

    def to_goal(begin: MotionState) -> list[Stage]:
        stage = planner.joint_stage(GOAL, begin, q_goal)
        planner.check_stage(stage, begin.q, planner.clearance_floor(stage))
        low = [i for i, q in enumerate(stage.q)
               if arm.frame_position(q, flange)[2] < config.min_tool_height]
        if low:
            raise PushRefused("tool_height", GOAL, f"the flange {flange} below "
                              f"min_tool_height {config.min_tool_height} m at t = "
                              f"{stage.times[low[0]]:.2f} s")
        return [stage]

    stages = planner.begin(state, to_goal)
    nan = np.full((2, 3), math.nan)
    return _plan(arm, config, stages, _lead_in(arm, lead_in, lead_from, state),
                 (math.nan, math.nan), nan, GOAL)


class PoseIkResult:
    """Outcome of :func:`pose_ik`: the posture ``q`` (n,), within the hard limits; the flange's
    position error (m) and rotation error (rad) from the target."""

    def __init__(self, q: NDArray[np.float64], position_error: float,
                 rotation_error: float) -> None:
        self.q, self.position_error, self.rotation_error = q, position_error, rotation_error

    def within(self, tolerance: float) -> bool:
        """Whether both errors are below ``tolerance`` (m and rad)."""
        return self.position_error <= tolerance and self.rotation_error <= tolerance


def pose_ik(arm: ArmKinematics, target: ArrayLike, seeds: Sequence[ArrayLike],
            reference: ArrayLike, *, tolerance: float = 1e-7, max_iterations: int = 300,
            damping: float = 1e-6, posture_gain: float = 0.1, margin: float = 0.0
            ) -> PoseIkResult:
    """Joint positions putting the flange at the pose ``target``.

    Damped least squares on the 6-D error ``log6(current^-1 target)`` in the flange frame, the
    redundancy pulled toward ``reference`` in the task's null space, the joints clipped to
    their limits less ``margin`` each step; tried from each seed in turn (a stalled one given
    up, :data:`STALL_RATIO`), the first converged result (else the best) returned: check its
    errors.

    Parameters
    ----------
    arm : ArmKinematics
    target : (4, 4) array_like
        ``T_world_flange`` (``arm.tool.flange_link``), m.
    seeds : sequence of (n,) array_like
        Start postures.
    reference : (n,) array_like
        Posture the redundancy is pulled toward.
    tolerance : float
        Convergence: position (m) and rotation (rad) errors below it.
    max_iterations : int
        Per seed.
    damping : float
        Of the least squares.
    posture_gain : float
        Fraction of the posture error corrected per iteration (null space).
    margin : float
        Kept from the joint limits, rad.

    Returns
    -------
    PoseIkResult
    """
    model, data = arm.model, arm.model.createData()
    frame = model.getFrameId(arm.tool.flange_link)
    goal = pin.SE3(np.linalg.inv(arm.world_model) @ np.asarray(target, dtype=float))
    lower, upper = arm.lower + margin, arm.upper - margin
    ref = arm.check_q(reference, "reference")
    eye6, eye = np.eye(6), np.eye(arm.n_joints)
    best: PoseIkResult | None = None
    for seed in seeds:
        q = np.clip(arm.check_q(seed, "seed"), lower, upper)
        checkpoint = math.inf
        for it in range(max_iterations):
            pin.framesForwardKinematics(model, data, q)
            error = pin.log6(data.oMf[frame].actInv(goal)).vector
            if np.max(np.abs(error)) < tolerance:
                break
            if it % STALL_ITERATIONS == 0:  # stalled (out of reach, at a limit): next seed
                norm = float(np.linalg.norm(error))
                if norm > STALL_RATIO * checkpoint:
                    break
                checkpoint = norm
            j = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.LOCAL)
            jjt = j @ j.T
            step = j.T @ np.linalg.solve(jjt + damping * eye6, error)
            null = eye - j.T @ np.linalg.solve(jjt + 1e-12 * eye6, j)
            q = np.clip(q + step + null @ (posture_gain * (ref - q)), lower, upper)
        pin.framesForwardKinematics(model, data, q)
        error = pin.log6(data.oMf[frame].actInv(goal)).vector
        result = PoseIkResult(q, float(np.linalg.norm(error[:3])),
                              float(np.linalg.norm(error[3:])))
        if result.within(10 * tolerance):
            return result
        if best is None or (result.position_error + result.rotation_error
                            < best.position_error + best.rotation_error):
            best = result
    if best is None:
        raise ValueError("pose_ik: no seed")
    return best
