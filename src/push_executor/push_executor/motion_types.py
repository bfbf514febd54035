"""The vocabulary of a push motion: its configuration, a joint state, the checked plan and
the refusal.

ROS-free. :mod:`push_executor.motion` builds a :class:`MotionPlan` from a planned push
(stages and checks: its docstring and docs/design/cycle.md); :mod:`push_executor.tracking`
follows one and :mod:`push_executor.messages` turns it into the controller's message.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: The stages of a push, in order (:mod:`push_executor.motion`).
STAGES = ("transit", "descend", "push", "retreat", "lift", "withdraw")
#: The optional first stage (a start low over the workspace).
CLEAR = "clear"
#: The last stage when the arm parks instead of withdrawing to a clear pose.
PARK = "park"
#: Franka Panda park posture: folded back over its base, out of a camera looking down on the
#: workspace (every link origin and the tip at x <= -0.48 m, z >= 0.33 m, with the base at
#: x = -0.55 m; the tool tilted 29 degrees), rad.
PANDA_PARK = (0.0, -1.2, 0.0, -2.9, 0.0, 1.75, 0.785)
#: Base pose (x, y, z m, yaw rad) of the simulated Panda in ``world`` (sim_bridge's
#: ``arm.base_pose``; tests/executor/test_sim_defaults.py keeps the two equal).
PANDA_SIM_BASE_POSE = (-0.47, 0.0, 0.15, 0.0)
#: Franka Panda "ready" posture, the default redundancy reference of the inverse kinematics.
PANDA_READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
#: A start state slower than this (rad/s) counts as at rest (the clear stage may start there).
AT_REST = 1e-6


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
        Tip speed of descend, retreat and lift (and the blend speed into and out of them), m/s.
    cartesian_acceleration, cartesian_jerk : float
        Tip acceleration (m/s^2) and jerk (m/s^3) limits of the Cartesian stages' profiles.
    retreat : float
        Distance moved back along the line after the push, m.
    park_positions, reference_positions : tuple of float
        Chain joint positions: the park posture; the inverse kinematics' redundancy reference
        (and seed of the transit target and of the clear poses).
    workspace : (x_min, x_max, y_min, y_max)
        Rectangle in ``world`` the tip stays in while low, m.
    limit_margin : float
        Joint position margin inside the URDF limits, rad (m for prismatic joints).
    speed_margin : float
        Fraction (0, 1] of the velocity, acceleration and jerk limits a trajectory may use.
    min_manipulability : float
        Smallest manipulability of the task Jacobian on the Cartesian stages.
    waypoint_period : float
        Largest time between two trajectory points, s.
    max_push_length : float
        Longest approach -> end distance, m.
    ik_tolerance : float
        Largest inverse kinematics residual: tip position (m) and tool axis angle (rad).
    start_delay : float
        ``time_from_start`` of the first point (the start state), s (> 0: the controller
        interpolates from its own state to it instead of jumping).
    """

    approach_height: float = 0.06
    push_height: float = 0.01
    push_speed: float = 0.02
    cartesian_speed: float = 0.35
    cartesian_acceleration: float = 1.5
    cartesian_jerk: float = 30.0
    retreat: float = 0.01
    park_positions: tuple[float, ...] = PANDA_PARK
    reference_positions: tuple[float, ...] = PANDA_READY
    workspace: tuple[float, float, float, float] = (-0.25, 0.25, -0.3, 0.3)
    min_tool_height: float = 0.003
    limit_margin: float = 0.05
    speed_margin: float = 0.75
    min_manipulability: float = 0.005
    waypoint_period: float = 0.01
    max_push_length: float = 0.3
    ik_tolerance: float = 1e-5
    start_delay: float = 0.05

    def __post_init__(self) -> None:
        positive = ("approach_height", "push_speed", "cartesian_speed", "cartesian_acceleration",
                    "cartesian_jerk", "speed_margin", "waypoint_period", "max_push_length",
                    "ik_tolerance", "start_delay")
        for name in (*positive, "push_height", "min_tool_height", "retreat", "limit_margin",
                     "min_manipulability"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
            if name in positive and value <= 0:
                raise ValueError(f"{name}: must be > 0, got {value!r}")
        if self.speed_margin > 1.0:
            raise ValueError(f"speed_margin: must be in (0, 1], got {self.speed_margin!r}")
        if self.push_speed > self.cartesian_speed:
            raise ValueError(f"push_speed: must not exceed cartesian_speed "
                             f"({self.cartesian_speed}), got {self.push_speed!r}")
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
class MotionState:
    """Chain joint positions, velocities and accelerations at one instant (rad, /s, /s^2)."""

    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    qdd: NDArray[np.float64]

    @classmethod
    def at_rest(cls, q: ArrayLike) -> MotionState:
        """The arm standing still at ``q``."""
        q = np.asarray(q, dtype=float).ravel()
        return cls(q, np.zeros_like(q), np.zeros_like(q))

    @property
    def resting(self) -> bool:
        """Whether the arm stands still."""
        return bool(np.max(np.abs(self.qd), initial=0.0) < AT_REST)


class View(Protocol):
    """What the withdraw stage needs to know of the camera and the object
    (:class:`push_executor.clearance.ClearView`)."""

    def candidates(self, tip: NDArray[np.float64]) -> Sequence[NDArray[np.float64]]:
        """Tool tip positions (x, y, z; ``world``, m) for the clear pose, the preferred first,
        given the tip at the end of the lift."""

    def covered(self, q: NDArray[np.float64]) -> int:
        """Pixels of the object's (dilated) image silhouette the arm covers at posture ``q``."""


@dataclass(frozen=True)
class StageSpan:
    """One stage of a plan: name and its time span from the trajectory's start, s."""

    name: str
    t_start: float
    t_end: float


@dataclass(frozen=True)
class MotionPlan:
    """A checked motion.

    Attributes
    ----------
    joint_names : tuple of str
    times : (N,) ndarray
        ``time_from_start`` of each point, s, strictly increasing, ``times[0] > 0``.
    positions, velocities, accelerations : (N, n) ndarray
        Joint positions, velocities and accelerations; ``positions[0]`` is the start state;
        the last point is at rest.
    tip : (N, 3) ndarray
        Planned tip positions in ``world``, m.
    stages : tuple of StageSpan
    contact_start, contact_end : float
        Times at which the tip passes the contact point and reaches the end point, s (NaN for
        a park motion).
    line : (2, 3) ndarray
        The commanded contact line: contact point and end point at push height, ``world``, m
        (NaN for a park motion).
    chain_from : float
        Earliest plan time from which a following motion may chain, s: the end of the lift
        (the tip is back up at the approach height, clear of the object); for a park motion
        the end of its clear stage (the start of the park stage without one).
    """

    joint_names: tuple[str, ...]
    times: NDArray[np.float64]
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    accelerations: NDArray[np.float64]
    tip: NDArray[np.float64]
    stages: tuple[StageSpan, ...]
    contact_start: float
    contact_end: float
    line: NDArray[np.float64] = field(repr=False)
    chain_from: float = 0.0

    @property
    def duration(self) -> float:
        """``time_from_start`` of the last point, s."""
        return float(self.times[-1])

    @property
    def is_push(self) -> bool:
        """Whether the plan has a contact segment (a push, not a park)."""
        return math.isfinite(self.contact_end)

    @property
    def final(self) -> str:
        """Name of the last stage (``withdraw`` or ``park``)."""
        return self.stages[-1].name

    def stage_at(self, t: float) -> str:
        """Name of the stage running at time ``t`` (the last one after the end)."""
        for span in self.stages:
            if t <= span.t_end:
                return span.name
        return self.stages[-1].name

    def positions_at(self, times: ArrayLike) -> NDArray[np.float64]:
        """Planned positions (T, n) at plan times (T,) (the positions of :meth:`state_at`)."""
        grid = self.times
        t = np.minimum(np.maximum(np.asarray(times, dtype=float).ravel(), grid[0]), grid[-1])
        if len(grid) == 1:
            return np.repeat(self.positions[:1], len(t), axis=0)
        i = np.minimum(np.maximum(np.searchsorted(grid, t) - 1, 0), len(grid) - 2)
        h = (grid[i + 1] - grid[i])[:, None]
        u = (t - grid[i])[:, None] / h
        u2 = u * u
        u3 = u2 * u
        q, v = self.positions, self.velocities
        return ((2 * u3 - 3 * u2 + 1) * q[i] + (u3 - 2 * u2 + u) * h * v[i]
                + (3 * u2 - 2 * u3) * q[i + 1] + (u3 - u2) * h * v[i + 1])

    def state_at(self, t: float) -> MotionState:
        """The planned state at plan time ``t`` (cubic Hermite positions and velocities
        between the points, as the controller interpolates them; accelerations linear; the
        first point before it, the last one after the end)."""
        times = self.times
        if t <= times[0]:
            return MotionState(self.positions[0].copy(), self.velocities[0].copy(),
                               self.accelerations[0].copy())
        if t >= times[-1]:
            return MotionState.at_rest(self.positions[-1])
        i = int(np.searchsorted(times, t)) - 1
        h = times[i + 1] - times[i]
        u = (t - times[i]) / h
        q0, q1, v0, v1 = (self.positions[i], self.positions[i + 1], self.velocities[i],
                          self.velocities[i + 1])
        q = self.positions_at([t])[0]
        v = ((6 * u**2 - 6 * u) * q0 + (-6 * u**2 + 6 * u) * q1) / h \
            + (3 * u**2 - 4 * u + 1) * v0 + (3 * u**2 - 2 * u) * v1
        a = (1 - u) * self.accelerations[i] + u * self.accelerations[i + 1]
        return MotionState(q, v, a)


def chain_point(previous: MotionPlan, first: float) -> float:
    """Plan time of ``previous`` where a following motion whose first point is at
    ``previous``'s time ``first`` takes over: ``first`` or, before its ``chain_from``, that."""
    return min(max(first, previous.chain_from), previous.duration)
