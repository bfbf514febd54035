"""The checks of every stage before anything moves (ROS-free; docs/design/arm.md, "Checks
before anything moves"): inverse kinematics residual, the workspace rectangle, joint limits with
``limit_margin``, the tool height (the clearance of the joint-space stages), manipulability,
joint speeds, accelerations and jerks within ``speed_margin`` times the limits, and the push's
input points. Each failed check raises :class:`push_executor.motion_types.PushRefused` with its
kind and stage. :class:`StageChecks` is the base of :mod:`push_executor.motion`'s planner;
:class:`Stage` is one stage's samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from push_executor.kinematics import ArmKinematics
from push_executor.motion_types import CLEAR, PARK, MotionConfig, MotionState, PushRefused

__all__ = ["CLEARANCE_MARGIN", "CONTACT_OFF_LINE", "LIMIT_SLACK", "TRANSIT_SLACK", "Stage",
           "StageChecks"]

#: The joint-space stages may dip this far below their clearance height, m (a motion from
#: rest at that height starts with a dip of a few millimetres).
TRANSIT_SLACK = 5e-3
#: Band around the workspace where the joint-space stages keep the approach height, m.
CLEARANCE_MARGIN = 0.05
#: Largest distance of the contact point from the approach -> end segment, m.
CONTACT_OFF_LINE = 1e-3
#: Relative slack of the speed, acceleration and jerk checks (sampling round-off).
LIMIT_SLACK = 1e-6


@dataclass
class Stage:
    """One stage's samples: times from its start (s), joint positions, velocities and
    accelerations (K, n) and the tool tip (K, 3) in ``world``."""

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


class StageChecks:
    """The checks of one motion's stages (module docstring), with the limits they use."""

    def __init__(self, arm: ArmKinematics, config: MotionConfig) -> None:
        self.arm, self.cfg = arm, config
        config.check_chain(arm.joint_names)
        self.vmax = arm.velocity_limits * config.speed_margin
        self.amax = arm.acceleration_limits * config.speed_margin
        self.jmax = arm.jerk_limits * config.speed_margin
        self.lower = arm.lower + config.limit_margin
        self.upper = arm.upper - config.limit_margin

    # ---- checks ------------------------------------------------------------------------------
    def check_ik(self, stage: str, position_error: float, axis_error: float,
                 target: NDArray[np.float64]) -> None:
        if not (position_error <= self.cfg.ik_tolerance and axis_error <= self.cfg.ik_tolerance):
            raise PushRefused("ik", stage, f"no inverse kinematics solution for the tip at "
                              f"({target[0]:.3f}, {target[1]:.3f}, {target[2]:.3f}) m: residual "
                              f"{position_error * 1e3:.3f} mm, tool axis {axis_error:.2e} rad "
                              "off vertical (out of reach?)")

    def check_workspace(self, stage: Stage) -> None:
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

    def clearance_floor(self, stage: Stage) -> NDArray[np.float64]:
        """Per sample of a joint-space stage: the approach height (less the slack) over the
        workspace and its margin, ``min_tool_height`` elsewhere."""
        cfg = self.cfg
        return np.where(self.over_workspace(stage.tip[:, :2]),
                        max(cfg.approach_height - TRANSIT_SLACK, cfg.min_tool_height),
                        cfg.min_tool_height)

    def check_stage(self, stage: Stage, q_start: NDArray[np.float64],
                    min_height: float | NDArray[np.float64]) -> None:
        """Joint limits, tool height (per sample or one value), speeds, accelerations, jerks."""
        arm, margin = self.arm, self.cfg.limit_margin
        lower, upper = self.lower, self.upper
        if stage.name in (CLEAR, "transit", "withdraw", PARK):  # may start outside, not further
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
