"""One checked joint trajectory per push: transit, descend, push, retreat, lift, park.

ROS-free: points in ``world`` (m), joint positions (rad or m), times in seconds from the
trajectory's start. :func:`plan_push` turns a planned push (approach, contact and end point of
the pusher axis on the table, ``planner/push``) and the measured joint positions into one
:class:`MotionPlan`, or raises :class:`PushRefused` naming the refusal class (``kind``), the
stage and the reason -- before anything moves.

Stages (:data:`STAGES`), each starting and ending at rest:

0. ``clear`` (only when the measured tip is low over the workspace, e.g. after a stop in the
   middle of a push): straight up to ``approach_height`` + :data:`CLEAR_EXTRA`.
1. ``transit``: joint space (quintic time scaling) to the tip above the approach point at
   ``approach_height``; wherever the tip is over the workspace (or within
   :data:`CLEARANCE_MARGIN` of it) it stays at ``approach_height`` or higher (1 mm slack), so
   it passes above the object.
2. ``descend``: straight down to ``push_height``.
3. ``push``: the straight Cartesian line approach -> contact -> end at ``push_speed``
   (trapezoidal speed profile, ``cartesian_acceleration``); the contact segment is the part
   contact -> end (:attr:`MotionPlan.contact_start`, :attr:`MotionPlan.contact_end`).
4. ``retreat``: back along the line by ``retreat``.
5. ``lift``: straight up to ``approach_height``.
6. ``park``: joint space to ``park_positions``.

Cartesian stages are sampled every ``waypoint_period`` seconds, each sample solved by
:meth:`push_executor.kinematics.ArmKinematics.solve_ik` seeded with the previous one (tool axis
straight down, yaw free, redundancy pulled toward ``reference_positions``); joint velocities are
central differences of the solutions (zero at every stage's ends). Joint-space stages are
sampled at the same period with their analytic velocities.

Checks, stage by stage, the first failure refusing the push (``kind``):
``invalid`` (non-finite or malformed points, a push longer than ``max_push_length``, a contact
point off the approach -> end line), ``workspace`` (the push's points, and every tip position of
the Cartesian stages, inside the workspace rectangle), ``ik`` (residual above
``ik_tolerance``), ``joint_limits`` (within the URDF limits shrunk by ``limit_margin``; the
transit may start outside them, but never goes further out), ``tool_height`` (tip above
``min_tool_height`` everywhere, and the transit's clearance above), ``singular``
(manipulability of the task Jacobian at least ``min_manipulability`` on the Cartesian stages),
``speed`` (joint speeds and accelerations within ``speed_margin`` times the limits).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_executor.kinematics import ArmKinematics

__all__ = ["CLEAR", "PANDA_PARK", "PANDA_READY", "PANDA_SIM_BASE_POSE", "STAGES", "MotionConfig",
           "MotionPlan", "PushRefused", "StageSpan", "plan_push", "quintic_segment"]

STAGES = ("transit", "descend", "push", "retreat", "lift", "park")
#: The optional first stage (a start low over the workspace).
CLEAR = "clear"
#: Franka Panda park posture: folded back over its base, out of a camera looking down on the
#: workspace (every link origin and the tip at x <= -0.48 m, z >= 0.33 m, with the base at
#: x = -0.55 m; the tool tilted 29 degrees), rad.
PANDA_PARK = (0.0, -1.2, 0.0, -2.9, 0.0, 1.75, 0.785)
#: Base pose (x, y, z m, yaw rad) of the simulated Panda in ``world`` (sim_bridge's
#: ``arm.base_pose``; tests/executor/test_sim_defaults.py keeps the two equal).
PANDA_SIM_BASE_POSE = (-0.47, 0.0, 0.15, 0.0)
#: Franka Panda "ready" posture, the default redundancy reference of the inverse kinematics.
PANDA_READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
#: Shortest joint-space stage, s.
MIN_JOINT_STAGE = 0.2
#: The transit may dip this far below its clearance height, m.
TRANSIT_SLACK = 1e-3
#: The clear stage lifts this much above the approach height (the transit then comes down to
#: it instead of crossing at it), m.
CLEAR_EXTRA = 0.05
#: Band around the workspace where the transit keeps the approach height, m.
CLEARANCE_MARGIN = 0.05
#: Largest distance of the contact point from the approach -> end segment, m.
CONTACT_OFF_LINE = 1e-3


class PushRefused(Exception):  # noqa: N818 - a refusal, not an error of the code
    """A push that will not be executed: ``kind`` (refusal class), ``stage``, ``reason``."""

    def __init__(self, kind: str, stage: str, reason: str) -> None:
        super().__init__(f"{kind} at {stage}: {reason}")
        self.kind, self.stage, self.reason = kind, stage, reason


@dataclass(frozen=True)
class MotionConfig:
    """Heights, speeds, postures and check thresholds of a push motion (module docstring).

    Attributes
    ----------
    approach_height, push_height, min_tool_height : float
        Tip heights above the table (world z), m.
    push_speed : float
        Tip speed along the push line, m/s.
    cartesian_speed : float
        Tip speed of descend, retreat and lift, m/s.
    cartesian_acceleration : float
        Tip acceleration of the Cartesian stages' speed ramps, m/s^2.
    retreat : float
        Distance moved back along the line after the push, m.
    park_positions, reference_positions : tuple of float
        Chain joint positions: the park posture; the inverse kinematics' redundancy reference
        (and seed of the transit target).
    workspace : (x_min, x_max, y_min, y_max)
        Rectangle in ``world`` the tip stays in while low, m.
    limit_margin : float
        Joint position margin inside the URDF limits, rad (m for prismatic joints).
    speed_margin : float
        Fraction (0, 1] of the velocity and acceleration limits a trajectory may use.
    min_manipulability : float
        Smallest manipulability of the task Jacobian on the Cartesian stages.
    waypoint_period : float
        Time between two trajectory points, s.
    max_push_length : float
        Longest approach -> end distance, m.
    ik_tolerance : float
        Largest inverse kinematics residual: tip position (m) and tool axis angle (rad).
    start_delay : float
        ``time_from_start`` of the first point (the measured posture), s (> 0: the controller
        interpolates from its own state to it instead of jumping).
    """

    approach_height: float = 0.10
    push_height: float = 0.01
    push_speed: float = 0.02
    cartesian_speed: float = 0.05
    cartesian_acceleration: float = 0.2
    retreat: float = 0.02
    park_positions: tuple[float, ...] = PANDA_PARK
    reference_positions: tuple[float, ...] = PANDA_READY
    workspace: tuple[float, float, float, float] = (-0.25, 0.25, -0.3, 0.3)
    min_tool_height: float = 0.003
    limit_margin: float = 0.05
    speed_margin: float = 0.5
    min_manipulability: float = 0.005
    waypoint_period: float = 0.01
    max_push_length: float = 0.3
    ik_tolerance: float = 1e-5
    start_delay: float = 0.05

    def __post_init__(self) -> None:
        positive = ("approach_height", "push_speed", "cartesian_speed", "cartesian_acceleration",
                    "speed_margin", "waypoint_period", "max_push_length", "ik_tolerance",
                    "start_delay")
        for name in (*positive, "push_height", "min_tool_height", "retreat", "limit_margin",
                     "min_manipulability"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
            if name in positive and value <= 0:
                raise ValueError(f"{name}: must be > 0, got {value!r}")
        if self.speed_margin > 1.0:
            raise ValueError(f"speed_margin: must be in (0, 1], got {self.speed_margin!r}")
        if not self.min_tool_height <= self.push_height < self.approach_height:
            raise ValueError("heights: need min_tool_height <= push_height < approach_height, "
                             f"got {self.min_tool_height}, {self.push_height}, "
                             f"{self.approach_height}")
        x_min, x_max, y_min, y_max = self.workspace
        if not (x_min < x_max and y_min < y_max):
            raise ValueError(f"workspace: need x_min < x_max and y_min < y_max, got "
                             f"{self.workspace}")
        for name in ("park_positions", "reference_positions"):
            values = getattr(self, name)
            if not values or not all(math.isfinite(v) for v in values):
                raise ValueError(f"{name}: must be a non-empty list of finite values")


    def check_chain(self, joint_names: tuple[str, ...]) -> None:
        """``ValueError`` unless the postures have one value per chain joint."""
        for name in ("park_positions", "reference_positions"):
            if len(getattr(self, name)) != len(joint_names):
                raise ValueError(f"{name}: {len(getattr(self, name))} values, the chain "
                                 f"{list(joint_names)} has {len(joint_names)} joints")


@dataclass(frozen=True)
class StageSpan:
    """One stage of a plan: name and its time span from the trajectory's start, s."""

    name: str
    t_start: float
    t_end: float


@dataclass(frozen=True)
class MotionPlan:
    """A checked push motion.

    Attributes
    ----------
    joint_names : tuple of str
    times : (N,) ndarray
        ``time_from_start`` of each point, s, strictly increasing, ``times[0] > 0``.
    positions, velocities : (N, n) ndarray
        Joint positions and velocities; ``positions[0]`` is the measured posture, velocities
        are zero at the first and the last point.
    tip : (N, 3) ndarray
        Planned tip positions in ``world``, m.
    stages : tuple of StageSpan
    contact_start, contact_end : float
        Times at which the tip passes the contact point and reaches the end point, s.
    line : (2, 3) ndarray
        The commanded contact line: contact point and end point at push height, ``world``, m.
    """

    joint_names: tuple[str, ...]
    times: NDArray[np.float64]
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    tip: NDArray[np.float64]
    stages: tuple[StageSpan, ...]
    contact_start: float
    contact_end: float
    line: NDArray[np.float64] = field(repr=False)

    @property
    def duration(self) -> float:
        """``time_from_start`` of the last point, s."""
        return float(self.times[-1])

    def stage_at(self, t: float) -> str:
        """Name of the stage running at time ``t`` (the last one after the end)."""
        for span in self.stages:
            if t <= span.t_end:
                return span.name
        return self.stages[-1].name


@dataclass
class _Stage:
    name: str
    times: NDArray[np.float64]  # from the stage's start, s
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    tip: NDArray[np.float64]


def quintic_segment(q_a: NDArray[np.float64], q_b: NDArray[np.float64],
                    velocity_limits: NDArray[np.float64],
                    acceleration_limits: NDArray[np.float64], period: float
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Rest-to-rest joint motion with the quintic time scaling 10 s^3 - 15 s^4 + 6 s^5.

    The duration is the shortest multiple of ``period`` (at least :data:`MIN_JOINT_STAGE`)
    whose peak speed (1.875 |dq| / T) and peak acceleration (5.7735 |dq| / T^2) stay within the
    given limits for every joint.

    Returns
    -------
    times : (K,) ndarray
        0 ... T, s.
    q, qd : (K, n) ndarray
        Positions and velocities.
    """
    dq = q_b - q_a
    duration = max(MIN_JOINT_STAGE, float(np.max(1.875 * np.abs(dq) / velocity_limits)),
                   float(np.max(np.sqrt(5.7735 * np.abs(dq) / acceleration_limits))))
    k = int(math.ceil(duration / period - 1e-9))
    times = np.arange(k + 1) * period
    s = times / times[-1]
    pos = 10 * s**3 - 15 * s**4 + 6 * s**5
    vel = (30 * s**2 - 60 * s**3 + 30 * s**4) / times[-1]
    return times, q_a + pos[:, None] * dq, vel[:, None] * dq


def _trapezoid(length: float, speed: float, acceleration: float, period: float
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Times (from 0, about ``period`` apart) and distances of a rest-to-rest line."""
    peak = min(speed, math.sqrt(length * acceleration))
    t_ramp = peak / acceleration
    t_cruise = (length - peak * t_ramp) / peak if peak > 0 else 0.0
    total = 2 * t_ramp + t_cruise
    k = max(int(math.ceil(total / period - 1e-9)), 1)
    t = np.linspace(0.0, total, k + 1)
    up = np.minimum(t, t_ramp)
    down = np.clip(t - t_ramp - t_cruise, 0.0, t_ramp)
    s = 0.5 * acceleration * up**2 + peak * np.clip(t - t_ramp, 0.0, t_cruise) \
        + peak * down - 0.5 * acceleration * down**2
    return t, np.minimum(s, length)


class _Planner:
    """Builds and checks the stages of one push (see :func:`plan_push`)."""

    def __init__(self, arm: ArmKinematics, config: MotionConfig) -> None:
        self.arm, self.cfg = arm, config
        config.check_chain(arm.joint_names)
        self.reference = np.array(config.reference_positions, dtype=float)
        self.vmax = arm.velocity_limits * config.speed_margin
        self.amax = arm.acceleration_limits * config.speed_margin

    # ---- stages ------------------------------------------------------------------------------
    def joint_stage(self, name: str, q_a: NDArray[np.float64], q_b: NDArray[np.float64]
                    ) -> _Stage:
        times, q, qd = quintic_segment(q_a, q_b, self.vmax, self.amax, self.cfg.waypoint_period)
        return _Stage(name, times, q, qd, self.arm.tip_positions(q))

    def line_stage(self, name: str, q_a: NDArray[np.float64], p_a: NDArray[np.float64],
                   p_b: NDArray[np.float64], speed: float) -> _Stage:
        cfg = self.cfg
        length = float(np.linalg.norm(p_b - p_a))
        times, s = _trapezoid(length, speed, cfg.cartesian_acceleration, cfg.waypoint_period)
        u = (p_b - p_a) / length if length > 0 else np.zeros(3)
        targets = p_a + s[:, None] * u
        q = np.empty((len(times), self.arm.n_joints))
        seed = q_a
        for i, target in enumerate(targets):
            result = self.arm.solve_ik(target, seed, self.reference)
            self.check_ik(name, result.position_error, result.axis_error, target)
            q[i] = seed = result.q
        qd = np.gradient(q, times, axis=0) if len(times) > 1 else np.zeros_like(q)
        qd[0] = qd[-1] = 0.0
        stage = _Stage(name, times, q, qd, self.arm.tip_positions(q))
        self.check_workspace(stage)
        self.check_singular(stage)
        return stage

    def ik_point(self, stage: str, target: NDArray[np.float64]) -> NDArray[np.float64]:
        result = self.arm.solve_ik(target, self.reference, self.reference)
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

    def check_singular(self, stage: _Stage) -> None:
        m = np.array([self.arm.manipulability(q) for q in stage.q])
        if np.min(m) < self.cfg.min_manipulability:
            i = int(np.argmin(m))
            raise PushRefused("singular", stage.name, f"manipulability {m[i]:.4f} < "
                              f"{self.cfg.min_manipulability} at t = {stage.times[i]:.2f} s "
                              "(near a singular posture)")

    def over_workspace(self, xy: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Which (N, 2) points lie within CLEARANCE_MARGIN of the workspace rectangle."""
        x_min, x_max, y_min, y_max = self.cfg.workspace
        m = CLEARANCE_MARGIN
        return ((xy[:, 0] >= x_min - m) & (xy[:, 0] <= x_max + m)
                & (xy[:, 1] >= y_min - m) & (xy[:, 1] <= y_max + m))

    def check_stage(self, stage: _Stage, q_start: NDArray[np.float64],
                    min_height: float | NDArray[np.float64]) -> None:
        """Joint limits, tool height (per sample or one value), speeds and accelerations."""
        arm, margin = self.arm, self.cfg.limit_margin
        lower, upper = arm.lower + margin, arm.upper - margin
        if stage.name == "transit":  # may start outside the margin, never go further out
            lower, upper = np.minimum(lower, q_start), np.maximum(upper, q_start)
        bad = (stage.q < lower - 1e-9) | (stage.q > upper + 1e-9)
        if np.any(bad):
            i, j = np.argwhere(bad)[0]
            raise PushRefused("joint_limits", stage.name, f"{arm.joint_names[j]} at "
                              f"{stage.q[i, j]:.4f} outside [{lower[j]:.4f}, {upper[j]:.4f}] "
                              f"(URDF limits with margin {margin})")
        z = stage.tip[:, 2]
        floor = np.broadcast_to(min_height, z.shape)
        if np.any(z < floor - 1e-9):
            i = int(np.argmax(z < floor - 1e-9))
            raise PushRefused("tool_height", stage.name, f"tip at ({stage.tip[i, 0]:.3f}, "
                              f"{stage.tip[i, 1]:.3f}, {z[i]:.4f}) m, below {floor[i]:.4f} m "
                              f"at t = {stage.times[i]:.2f} s")
        ratio = np.abs(stage.qd) / self.vmax
        if np.max(ratio) > 1.0 + 1e-6:
            i, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
            raise PushRefused("speed", stage.name, f"{arm.joint_names[j]} at "
                              f"{stage.qd[i, j]:.3f} /s, limit {self.vmax[j]:.3f} /s "
                              f"(velocity limit x speed_margin)")
        if len(stage.times) > 1:
            qdd = np.diff(stage.qd, axis=0) / np.diff(stage.times)[:, None]
            ratio = np.abs(qdd) / self.amax
            if np.max(ratio) > 1.0 + 1e-6:
                i, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
                raise PushRefused("speed", stage.name, f"{arm.joint_names[j]} accelerates at "
                                  f"{qdd[i, j]:.2f} /s^2, limit {self.amax[j]:.2f} /s^2 "
                                  "(acceleration limit x speed_margin)")

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


def plan_push(arm: ArmKinematics, config: MotionConfig, approach: ArrayLike,
              contact: ArrayLike, end: ArrayLike, q_measured: ArrayLike) -> MotionPlan:
    """Plan and check the whole motion of one push (module docstring).

    Parameters
    ----------
    arm : ArmKinematics
    config : MotionConfig
    approach, contact, end : (2,) array_like
        Pusher axis points on the table in ``world`` (``planner/push``), m.
    q_measured : (n,) array_like
        Measured chain joint positions (the trajectory's first point).

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
    q0 = np.asarray(q_measured, dtype=float).ravel()
    if q0.shape != (arm.n_joints,) or not np.all(np.isfinite(q0)):
        raise PushRefused("invalid", "input", f"measured state: expected {arm.n_joints} finite "
                          "joint positions")
    contact_along = planner.check_input(a2, c2, e2)

    def lifted(p: NDArray[np.float64], z: float) -> NDArray[np.float64]:
        return np.array([p[0], p[1], z])

    above, low = lifted(a2, cfg.approach_height), lifted(a2, cfg.push_height)
    end3 = lifted(e2, cfg.push_height)
    u = (end3 - low) / np.linalg.norm(end3 - low)
    back = end3 - cfg.retreat * u
    park = np.array(cfg.park_positions, dtype=float)

    stages: list[_Stage] = []
    tip0 = arm.tip_pose(q0)[0]
    if planner.over_workspace(tip0[None, :2])[0] and \
            tip0[2] < cfg.approach_height - TRANSIT_SLACK:
        clear = planner.line_stage("clear", q0, tip0, lifted(tip0, cfg.approach_height
                                                              + CLEAR_EXTRA),
                                   cfg.cartesian_speed)
        planner.check_stage(clear, q0, cfg.min_tool_height)
        stages.append(clear)
    q_start = stages[-1].q[-1] if stages else q0
    q_above = planner.ik_point("transit", above)
    transit = planner.joint_stage("transit", q_start, q_above)
    # Over the workspace (and CLEARANCE_MARGIN around it) the tip stays at the approach height.
    floor = np.where(planner.over_workspace(transit.tip[:, :2]),
                     cfg.approach_height - TRANSIT_SLACK, cfg.min_tool_height)
    planner.check_stage(transit, q_start, np.maximum(floor, cfg.min_tool_height))
    stages.append(transit)
    for name, p_b, speed in (("descend", low, cfg.cartesian_speed),
                             ("push", end3, cfg.push_speed),
                             ("retreat", back, cfg.cartesian_speed),
                             ("lift", lifted(back, cfg.approach_height), cfg.cartesian_speed)):
        prev = stages[-1]
        stage = planner.line_stage(name, prev.q[-1], prev.tip[-1], p_b, speed)
        planner.check_stage(stage, prev.q[-1], cfg.min_tool_height)
        stages.append(stage)
    park_stage = planner.joint_stage("park", stages[-1].q[-1], park)
    planner.check_stage(park_stage, stages[-1].q[-1], cfg.min_tool_height)
    stages.append(park_stage)

    # Concatenate: the first point (the measured posture) at start_delay, each later stage
    # without its first sample (the previous stage's last).
    times, qs, qds, tips, spans = [], [], [], [], []
    t = cfg.start_delay
    push_times = push_s = None
    for k, stage in enumerate(stages):
        keep = slice(0 if k == 0 else 1, None)
        times.append(t + stage.times[keep])
        qs.append(stage.q[keep])
        qds.append(stage.qd[keep])
        tips.append(stage.tip[keep])
        spans.append(StageSpan(stage.name, t, t + float(stage.times[-1])))
        if stage.name == "push":
            push_times = t + stage.times
            push_s = np.linalg.norm(stage.tip - stage.tip[0], axis=1)
        t += float(stage.times[-1])
    assert push_times is not None and push_s is not None
    # The planned tip passes the contact point / the end point (distance along the push).
    contact_start = float(np.interp(contact_along, push_s, push_times))
    velocities = np.concatenate(qds)
    velocities[0] = velocities[-1] = 0.0
    return MotionPlan(joint_names=arm.joint_names, times=np.concatenate(times),
                      positions=np.concatenate(qs), velocities=velocities,
                      tip=np.concatenate(tips), stages=tuple(spans),
                      contact_start=contact_start, contact_end=float(push_times[-1]),
                      line=np.array([lifted(c2, cfg.push_height), end3]))
