"""A joint trajectory follower with the rules of ros2_control's joint_trajectory_controller.

ROS-free (no rclpy, no message types, no pybullet): the simulator's arm mode
(:mod:`sim_bridge.arm_robot`, :mod:`sim_bridge.arm_ros`) converts a
``trajectory_msgs/JointTrajectory`` into a :class:`TrajectoryCommand` (float seconds), checks it
with :func:`check_trajectory` and hands the accepted :class:`Trajectory` to a
:class:`TrajectoryFollower`, which the physics loop samples every step.

Acceptance (the Jazzy controller's ``validate_trajectory_msg`` with its defaults,
``allow_partial_joints_goal`` and ``allow_nonzero_velocity_at_trajectory_end`` false; source:
upstream ros2_controllers jazzy, ``joint_trajectory_controller``; docs/ROBOT.md); each
rejection raises :class:`TrajectoryRejected` with a ``kind``:

- ``joints``: the joint names do not cover all controller joints exactly once (order is free:
  the trajectory is re-sorted into the controller's order; unknown or repeated names are
  rejected);
- ``empty``: no points;
- ``time``: ``time_from_start`` not strictly increasing (or negative);
- ``size``: positions of the wrong size, or velocities / accelerations neither empty nor of
  the joints' size;
- ``final_velocity``: a non-zero velocity at the last point;
- ``past``: a non-zero ``stamp`` whose trajectory ends (stamp + last ``time_from_start``)
  before ``now``. Upstream sums the points' ``time_from_start``; the end of a trajectory is its
  last point's, which is what this checks;
- additions, for bounded CPU and no NaN in the physics: ``finite`` (a non-finite number) and
  ``duration`` (the trajectory would end more than ``max_duration`` s after ``now``).

A stamp of 0 means "start when received". Sampling (:meth:`Trajectory.sample`): from the
receipt to the first point the follower interpolates from the state at receipt (a first point
with ``time_from_start`` 0 jumps; a stamp in the future stretches this segment, as the Jazzy
controller's ``Trajectory::sample`` does: a moving arm goes on from its state, an arm at rest
with the first point at its posture stays put);
positions only: linear interpolation of positions (velocity = the segment's slope); positions
and velocities: cubic Hermite; accelerations are checked for size but not used (the controller
would interpolate quintically). After the last point the last positions are held with zero
velocity. A new accepted trajectory replaces the running one (:meth:`TrajectoryFollower.offer`).

Units: radians, rad/s, seconds (of simulated time).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Trajectory",
    "TrajectoryCommand",
    "TrajectoryFollower",
    "TrajectoryRejected",
    "check_trajectory",
    "hermite",
]

#: Largest |velocity| at the last point still taken as zero, rad/s (the controller compares
#: with 0.0 exactly; a float round trip must not reject a zero).
ZERO_VELOCITY = 1e-9


class TrajectoryRejected(ValueError):
    """A trajectory the controller rejects; ``kind`` names the rule (module docstring)."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.kind = kind


@dataclass(frozen=True)
class TrajectoryCommand:
    """A ``JointTrajectory`` as plain numbers, as received (not yet checked).

    Attributes
    ----------
    joint_names : sequence of str
    stamp : float
        Header stamp, s of the sim clock; 0 = start when received.
    times : sequence of float
        ``time_from_start`` of each point, s.
    positions, velocities, accelerations : sequence of sequences of float
        Per point (velocities and accelerations may be empty per point), rad, rad/s, rad/s^2.
    """

    joint_names: Sequence[str]
    stamp: float
    times: Sequence[float]
    positions: Sequence[Sequence[float]]
    velocities: Sequence[Sequence[float]]
    accelerations: Sequence[Sequence[float]] = ()


@dataclass(frozen=True)
class Trajectory:
    """An accepted trajectory in the controller's joint order.

    Attributes
    ----------
    stamp : float
        Start time, s of the sim clock; 0 = when the follower picks it up.
    times : (N,) ndarray
        ``time_from_start`` of the points, strictly increasing, s.
    positions : (N, J) ndarray
        rad.
    velocities : (N, J) ndarray or None
        rad/s; None = positions only (linear interpolation).
    """

    stamp: float
    times: NDArray[np.float64]
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64] | None

    def sample(self, t: float, start: float, q0: ArrayLike, v0: ArrayLike,
               received: float | None = None
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Desired positions and velocities at time ``t``.

        Parameters
        ----------
        t : float
            Sample time, s.
        start : float
            Time of ``time_from_start`` = 0, s.
        q0, v0 : (J,) array_like
            The state at receipt (rad, rad/s): the segment before the first point starts there.
        received : float, optional
            When the trajectory was received, s (default ``start``): the segment to the first
            point starts then, as the controller's does (a stamp in the future does not stop a
            moving arm: it goes on from its state at receipt to the first point); before it
            the state at receipt is held.

        Returns
        -------
        q, v : (J,) ndarray
        """
        q0 = np.asarray(q0, dtype=float)
        v0 = np.asarray(v0, dtype=float)
        s = t - start
        times, pos, vel = self.times, self.positions, self.velocities
        begin = 0.0 if received is None else min(float(received) - start, float(times[0]))
        if s < begin:  # before the receipt: the state then
            return q0.copy(), np.zeros_like(q0)
        if s >= times[-1]:
            return pos[-1].copy(), np.zeros(pos.shape[1])
        i = int(np.searchsorted(times, s, side="right"))  # times[i-1] <= s < times[i]
        if i == 0:
            ta, qa, va = begin, q0, v0
        else:
            ta, qa = float(times[i - 1]), pos[i - 1]
            va = None if vel is None else vel[i - 1]
        tb, qb = float(times[i]), pos[i]
        if vel is None:
            slope = (qb - qa) / (tb - ta)
            return qa + slope * (s - ta), slope
        return hermite(s - ta, tb - ta, qa, va, qb, vel[i])


def hermite(s: float, h: float, qa: ArrayLike, va: ArrayLike, qb: ArrayLike, vb: ArrayLike
            ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cubic Hermite segment from ``(qa, va)`` at 0 to ``(qb, vb)`` at ``h``, sampled at ``s``.

    Returns
    -------
    q, v : ndarray
        Position and its time derivative at ``s`` (units of ``qa`` and per second).
    """
    qa, va, qb, vb = (np.asarray(a, dtype=float) for a in (qa, va, qb, vb))
    u = s / h
    h00, h10, h01, h11 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, \
        u**3 - u**2
    d00, d10, d01, d11 = 6 * u**2 - 6 * u, 3 * u**2 - 4 * u + 1, -6 * u**2 + 6 * u, 3 * u**2 - 2 * u
    q = h00 * qa + h10 * h * va + h01 * qb + h11 * h * vb
    v = (d00 * qa + d01 * qb) / h + d10 * va + d11 * vb
    return q, v


def check_trajectory(cmd: TrajectoryCommand, joints: Sequence[str], now: float,
                     max_duration: float = 600.0) -> Trajectory:
    """Accept ``cmd`` for a controller of ``joints`` at time ``now``, or raise.

    Parameters
    ----------
    cmd : TrajectoryCommand
    joints : sequence of str
        The controller's joints, in its order.
    now : float
        Current time of the sim clock, s.
    max_duration : float
        Longest accepted time from ``now`` to the trajectory's end, s.

    Returns
    -------
    Trajectory
        In the order of ``joints``.

    Raises
    ------
    TrajectoryRejected
        With the rule's ``kind`` and a reason naming the offending point or joint.
    """
    names = [str(n) for n in cmd.joint_names]
    if len(names) != len(joints) or set(names) != set(joints):
        missing = [j for j in joints if j not in names]
        extra = [n for n in names if n not in joints]
        raise TrajectoryRejected(
            "joints", f"joint names must cover the controller's {len(joints)} joints exactly "
            f"once (missing {missing[:8]}, unknown {[e[:64] for e in extra[:8]]}, "
            f"{len(names)} names given)")
    n = len(cmd.times)
    if n == 0 or len(cmd.positions) == 0:
        raise TrajectoryRejected("empty", "empty trajectory: no points")
    if len(cmd.positions) != n or len(cmd.velocities) not in (0, n) \
            or len(cmd.accelerations) not in (0, n):
        raise TrajectoryRejected("size", "inconsistent number of points")
    times = np.array(cmd.times, dtype=float)
    if not np.all(np.isfinite(times)) or not np.isfinite(cmd.stamp):
        raise TrajectoryRejected("finite", "non-finite time_from_start or stamp")
    if times[0] < 0.0 or np.any(np.diff(times) <= 0.0):
        raise TrajectoryRejected("time", "time_from_start must be >= 0 and strictly increasing "
                                         "between points")
    order = [names.index(j) for j in joints]
    size = len(joints)
    pos = np.empty((n, size))
    vel = None if all(len(v) == 0 for v in cmd.velocities) else np.empty((n, size))
    for i in range(n):
        if len(cmd.positions[i]) != size:
            raise TrajectoryRejected("size", f"point {i}: {len(cmd.positions[i])} positions "
                                             f"for {size} joints")
        pos[i] = np.asarray(cmd.positions[i], dtype=float)[order]
        v = cmd.velocities[i] if cmd.velocities else ()
        if len(v) != (0 if vel is None else size):
            raise TrajectoryRejected("size", f"point {i}: {len(v)} velocities for {size} "
                                             "joints (all points or none must have them)")
        if vel is not None:
            vel[i] = np.asarray(v, dtype=float)[order]
        a = cmd.accelerations[i] if cmd.accelerations else ()
        if len(a) not in (0, size):
            raise TrajectoryRejected("size", f"point {i}: {len(a)} accelerations for {size} "
                                             "joints")
    if not np.all(np.isfinite(pos)) or (vel is not None and not np.all(np.isfinite(vel))):
        raise TrajectoryRejected("finite", "non-finite position or velocity")
    if vel is not None and np.any(np.abs(vel[-1]) > ZERO_VELOCITY):
        raise TrajectoryRejected("final_velocity", "non-zero velocity at the last point")
    end = (cmd.stamp if cmd.stamp != 0.0 else now) + float(times[-1])
    if cmd.stamp != 0.0 and end < now:
        raise TrajectoryRejected("past", f"non-zero stamp {cmd.stamp:.6f} s whose trajectory "
                                         f"ends {now - end:.6f} s in the past")
    if end - now > max_duration:
        raise TrajectoryRejected("duration", f"the trajectory ends {end - now:.3f} s from now, "
                                             f"more than {max_duration} s")
    return Trajectory(stamp=float(cmd.stamp), times=times, positions=pos, velocities=vel)


class TrajectoryFollower:
    """The running trajectory of one controller; thread-safe.

    :meth:`offer` (any thread) queues an accepted trajectory; the physics loop calls
    :meth:`target` every step, which picks up the newest offered trajectory (replacing the
    running one, starting from the measured state) and samples it.

    Parameters
    ----------
    joints : sequence of str
        The controller's joints, in order.
    """

    def __init__(self, joints: Sequence[str]) -> None:
        self.joints = tuple(joints)
        self._lock = threading.Lock()
        self._pending: Trajectory | None = None
        self._current: Trajectory | None = None
        self._start = self._received = 0.0
        self._q0 = np.zeros(len(self.joints))
        self._v0 = np.zeros(len(self.joints))
        self._hold: NDArray[np.float64] | None = None
        self.running = False

    def offer(self, trajectory: Trajectory) -> bool:
        """Queue ``trajectory``; return whether a running loop will pick it up (False: the
        caller starts a loop, :meth:`open`)."""
        with self._lock:
            self._pending = trajectory
            return self.running

    def open(self) -> None:
        """Mark the physics loop as running (it will pick up offered trajectories)."""
        with self._lock:
            self.running = True

    def close_if_done(self, t: float) -> bool:
        """If nothing is pending and the current trajectory has ended at ``t``: mark the loop
        as stopped and return True (an :meth:`offer` after this returns False)."""
        with self._lock:
            if self._pending is None and t >= self.end_time:
                self.running = False
                return True
            return False

    @property
    def end_time(self) -> float:
        """When the current trajectory ends, s (-inf without one)."""
        if self._current is None:
            return -np.inf
        return self._start + float(self._current.times[-1])

    def hold(self, q: ArrayLike) -> None:
        """Forget any trajectory and hold positions ``q`` (a reset, or a failed physics loop:
        the loop counts as stopped)."""
        with self._lock:
            self._pending = self._current = None
            self.running = False
            self._hold = np.asarray(q, dtype=float).copy()

    def target(self, t: float, q: ArrayLike, v: ArrayLike
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Desired positions and velocities at ``t`` given the measured state ``(q, v)``.

        A pending trajectory starts now (stamp 0) or at its stamp, from ``(q, v)``.
        Without any trajectory the positions last held are kept (``q`` if none).
        """
        with self._lock:
            if self._pending is not None:
                self._current, self._pending = self._pending, None
                self._start = self._current.stamp if self._current.stamp != 0.0 else t
                self._received = t
                self._q0 = np.asarray(q, dtype=float).copy()
                self._v0 = np.asarray(v, dtype=float).copy()
            current = self._current
        if current is None:
            if self._hold is None:
                self._hold = np.asarray(q, dtype=float).copy()
            return self._hold.copy(), np.zeros(len(self.joints))
        return current.sample(t, self._start, self._q0, self._v0, self._received)
