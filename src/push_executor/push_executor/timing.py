"""Time-optimal, jerk-limited time parametrisation with ruckig (ROS-free).

Two kinds of motion between two states, each sampled every ``period`` seconds or a little
less (``n = ceil(T / period)`` equal steps, so the last sample is the end state exactly):

- :func:`joint_move`: all joints from a current state (positions, velocities, accelerations) to
  a target state, time-synchronised, within per-joint velocity, acceleration and jerk limits
  and position bounds (ruckig's online trajectory generation, a 7th-order polynomial profile
  per phase: time-optimal under those limits from *any* current state, which is what lets a
  push chain from a moving arm);
- :func:`line_profile`: a path parameter ``s`` from 0 to a length, with a start and an end
  speed, within a speed, an acceleration and a jerk limit (ruckig on one degree of freedom);
  the Cartesian stages put the tool tip at ``a + s (b - a) / |b - a|``.

Units follow the inputs (rad or m; per s, s^2, s^3). ``ValueError`` carries ruckig's reason
when no trajectory exists (a target velocity above the limit, a start outside the position
bounds that cannot be brought back in time, non-finite input).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

__all__ = ["Samples", "blend_speed", "joint_move", "line_profile", "sample_times"]

#: (times (K,), positions (K, n), velocities (K, n), accelerations (K, n)) from 0, s.
Samples = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                NDArray[np.float64]]


def sample_times(duration: float, period: float) -> NDArray[np.float64]:
    """``0 ... duration`` in ``ceil(duration / period)`` equal steps (one sample for 0)."""
    if not duration > 0.0:
        return np.zeros(1)
    n = max(1, int(math.ceil(duration / period - 1e-9)))
    return np.linspace(0.0, duration, n + 1)


def _calculate(inp: InputParameter, dofs: int) -> Trajectory:
    trajectory = Trajectory(dofs)
    try:
        result = Ruckig(dofs).calculate(inp, trajectory)
    except RuckigError as exc:
        reason = str(exc).replace("[ruckig] ", "").strip().splitlines()
        raise ValueError(reason[0] if reason else "ruckig found no trajectory") from None
    if result not in (Result.Working, Result.Finished):
        raise ValueError(f"no time-optimal trajectory ({result.name})")
    return trajectory


def _sample(trajectory: Trajectory, period: float, dofs: int) -> Samples:
    times = sample_times(float(trajectory.duration), period)
    out = np.empty((3, len(times), dofs))
    for i, t in enumerate(times):
        out[:, i] = trajectory.at_time(float(t))
    return times, out[0], out[1], out[2]


def joint_move(start: tuple[ArrayLike, ArrayLike, ArrayLike],
               target: tuple[ArrayLike, ArrayLike, ArrayLike], velocity: ArrayLike,
               acceleration: ArrayLike, jerk: ArrayLike, lower: ArrayLike, upper: ArrayLike,
               period: float) -> Samples:
    """The time-optimal joint motion from ``start`` to ``target`` (module docstring).

    Parameters
    ----------
    start, target : (q, qd, qdd), each (n,) array_like
        Positions, velocities and accelerations at the start and at the end.
    velocity, acceleration, jerk : (n,) array_like
        Limits (> 0) per joint.
    lower, upper : (n,) array_like
        Position bounds the motion stays within (the start and the target must lie inside).
    period : float
        Largest sample spacing, s.

    Returns
    -------
    Samples
        From time 0 (the start state) to the duration (the target state).

    Raises
    ------
    ValueError
        No such trajectory (ruckig's reason).
    """
    q0 = np.asarray(start[0], dtype=float)
    n = len(q0)
    inp = InputParameter(n)
    inp.current_position, inp.current_velocity, inp.current_acceleration = (
        np.asarray(v, dtype=float).tolist() for v in start)
    inp.target_position, inp.target_velocity, inp.target_acceleration = (
        np.asarray(v, dtype=float).tolist() for v in target)
    inp.max_velocity = np.asarray(velocity, dtype=float).tolist()
    inp.max_acceleration = np.asarray(acceleration, dtype=float).tolist()
    inp.max_jerk = np.asarray(jerk, dtype=float).tolist()
    inp.min_position = np.asarray(lower, dtype=float).tolist()
    inp.max_position = np.asarray(upper, dtype=float).tolist()
    return _sample(_calculate(inp, n), period, n)


def line_profile(length: float, v0: float, v1: float, speed: float, acceleration: float,
                 jerk: float, period: float) -> tuple[NDArray[np.float64], ...]:
    """Path parameter ``s`` over a straight line of ``length`` (module docstring).

    Parameters
    ----------
    length : float
        m (>= 0).
    v0, v1 : float
        Speed along the line at the start and at the end, m/s (0 <= v <= ``speed``); the
        acceleration is zero at both ends.
    speed, acceleration, jerk : float
        Limits, m/s, m/s^2, m/s^3.
    period : float
        Sample spacing, s.

    Returns
    -------
    times, s, sd, sdd : (K,) ndarray
        s, m, m/s, m/s^2.
    """
    inp = InputParameter(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [v0], [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [length], [v1], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [speed], [acceleration], [jerk]
    # The speed never reverses: the tip only moves forward along the line.
    inp.min_velocity = [0.0]
    times, s, sd, sdd = _sample(_calculate(inp, 1), period, 1)
    return times, np.clip(s[:, 0], 0.0, length), np.maximum(sd[:, 0], 0.0), sdd[:, 0]


def stopping_distance(speed: float, acceleration: float, jerk: float) -> float:
    """Shortest distance (m) to stop from ``speed`` (m/s) at zero acceleration within the
    acceleration and jerk limits (the time-optimal jerk-limited braking)."""
    if speed <= acceleration**2 / jerk:  # the acceleration limit is not reached
        return speed * math.sqrt(speed / jerk)
    return speed**2 / (2.0 * acceleration) + speed * acceleration / (2.0 * jerk)


def blend_speed(length: float, speed: float, acceleration: float, jerk: float) -> float:
    """The largest speed <= ``speed`` at which a line of ``length`` (m) can start (or end)
    and still stop (or start) at rest at its other end: :func:`stopping_distance` within 90 %
    of ``length`` (the margin keeps ruckig's solution away from the boundary case)."""
    if stopping_distance(speed, acceleration, jerk) <= 0.9 * length:
        return speed
    lo, hi = 0.0, speed
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stopping_distance(mid, acceleration, jerk) <= 0.9 * length \
            else (lo, mid)
    return lo
