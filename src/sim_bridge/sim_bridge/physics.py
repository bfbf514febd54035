"""Physics of the pybullet world: stepping, the pusher drive, push execution and settling.

ROS-free; :class:`sim_bridge.world.PushWorld` is the entry point (this module moves its
bodies, built by :mod:`sim_bridge.scene`). Points in ``world``, metres; times in seconds of
simulated time.

- The pusher is held by a force-limited fixed constraint to the world whose pivot is moved
  every physics step (``changeConstraint(jointChildPivot=..., maxForce=PUSHER_MAX_FORCE)``),
  like a stiff, position-controlled robot finger: every contact with the object is resolved
  by the solver, the pusher is never teleported through the object.
- Time: fixed step ``WorldConfig.time_step`` (default 1/240 s), ``solver_iterations`` (default
  10) sequential-impulse iterations; ``sim_time`` is ``steps * time_step``. The settings are
  justified by the convergence study in docs/results/bench_sim.md (against a
  1/960 s, 100-iteration reference the defaults deviate about as much as moving the push
  sideways by 0.1 mm does at fixed settings: the contact dynamics are that sensitive).

Push execution (:meth:`Physics.execute_push` after :func:`check_push`)
-----------------------------------------------------------------------
1. Validate (``ValueError`` with a message naming the argument, nothing is moved): finite
   (2,) points inside ``workspace``; push length ``|end - contact|`` in
   ``[MIN_PUSH_LENGTH, max_push_length]``; ``|contact - approach| <= MAX_APPROACH_DISTANCE``;
   ``contact`` within ``COLLINEAR_TOLERANCE`` of the line approach -> end; ``approach``
   outside the object's current outline by at least ``pusher_radius + APPROACH_MARGIN``.
2. Travel: the pusher is parked high above the robot side of the table (out of the camera's
   view). It is moved in the air, above the object's top plus ``LIFT_CLEARANCE``, to above
   the approach point. This air transfer is a teleport (instantaneous in simulated time);
   nothing can be in the way up there.
3. Lower physically at ``LIFT_SPEED`` to 2 mm above the table at the approach point.
4. Push: the pivot moves on the straight line approach -> end at ``push_speed`` (20 mm/s).
   ``pusher_start`` / ``t_start`` and ``pusher_end`` / ``t_end`` are the pusher's *measured*
   position and the sim time when this motion starts and ends (the pusher lags the pivot
   slightly under load).
5. Retract: back off 1 mm along the push direction at ``RETRACT_SPEED``, lift at
   ``LIFT_SPEED``, park (air teleport).
6. Settle: step until the object is at rest (speed below ``REST_SPEED`` and ``REST_ANGULAR``
   for ``REST_STEPS`` consecutive steps) or ``settle_timeout`` has passed.

``execute_push(..., on_step=f)`` calls ``f()`` after every physics step of steps 3-6 (the
world's monitor renders from it, :class:`sim_bridge.rendering.MonitorConfig`); the callback
must only read the scene (render, query poses): the motion is then exactly the one without it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pybullet as p
from numpy.typing import ArrayLike, NDArray
from pybullet_utils.bullet_client import BulletClient

from push_core.geometry import closest_point_on_polyline
from sim_bridge.config import WorldConfig
from sim_bridge.scene import (
    PUSHER_LENGTH,
    PUSHER_MAX_FORCE,
    Scene,
    park_position,
    yaw_quaternion,
)

__all__ = [
    "APPROACH_MARGIN",
    "BACK_OFF",
    "COLLINEAR_TOLERANCE",
    "LIFT_CLEARANCE",
    "LIFT_SPEED",
    "MAX_APPROACH_DISTANCE",
    "MIN_PUSH_LENGTH",
    "PUSHER_GAP",
    "REST_ANGULAR",
    "REST_SPEED",
    "REST_STEPS",
    "RETRACT_SPEED",
    "Physics",
    "PushRefused",
    "PushResult",
    "check_push",
]

#: Shortest accepted push ``|end - contact|``, metres.
MIN_PUSH_LENGTH = 1e-3
#: Longest accepted distance from the approach point to the contact point, metres.
MAX_APPROACH_DISTANCE = 0.1
#: Largest distance of the contact point from the line approach -> end, metres.
COLLINEAR_TOLERANCE = 2e-3
#: Extra clearance beyond the pusher radius between the approach point and the outline, m.
APPROACH_MARGIN = 5e-4

#: Pusher motion.
PUSHER_GAP = 0.002  # bottom of the pusher above the table while pushing, m
LIFT_SPEED = 0.5  # m/s, lowering and lifting
RETRACT_SPEED = 0.1  # m/s, backing off after the push
LIFT_CLEARANCE = 0.01  # m above the object's top while travelling
BACK_OFF = 1e-3  # m, retreat along -push direction before lifting

#: Rest detection after a push.
REST_SPEED = 5e-4  # m/s
REST_ANGULAR = 5e-3  # rad/s
REST_STEPS = 5


class PushRefused(ValueError):
    """A push :func:`check_push` refuses; ``kind`` is the ``pusher/refused`` class:
    ``workspace`` (a point outside the workspace) or ``invalid`` (anything else)."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.kind = kind


@dataclass(frozen=True)
class PushResult:
    """Outcome of :meth:`PushWorld.execute_push`. Points in ``world``, metres; times in s.

    Attributes
    ----------
    pusher_start, pusher_end : (2,) ndarray
        Measured pusher axis position when the straight push motion started and ended.
    t_start, t_end : float
        ``sim_time`` at those two instants.
    pose_before, pose_after : (3,) ndarray
        Object pose ``(x, y, theta)`` before the push and after it has settled.
    touched : bool
        Whether the pusher made contact with the object during the push.
    settled : bool
        Whether the object came to rest within ``settle_timeout`` (addition).
    t_done : float
        ``sim_time`` when the pusher was retracted and the object had settled (addition).
    approach, contact, end : (2,) ndarray
        The commanded points (addition).
    """

    pusher_start: NDArray[np.float64]
    pusher_end: NDArray[np.float64]
    t_start: float
    t_end: float
    pose_before: NDArray[np.float64]
    pose_after: NDArray[np.float64]
    touched: bool
    settled: bool = True
    t_done: float = 0.0
    approach: NDArray[np.float64] = field(default_factory=lambda: np.full(2, np.nan))
    contact: NDArray[np.float64] = field(default_factory=lambda: np.full(2, np.nan))
    end: NDArray[np.float64] = field(default_factory=lambda: np.full(2, np.nan))


def check_push(cfg: WorldConfig, outline: Callable[[], NDArray[np.float64]],
               approach: ArrayLike, contact: ArrayLike,
               end: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    """Validate a push (rules in the module docstring) without moving anything.

    Parameters
    ----------
    cfg : WorldConfig
        ``workspace``, ``max_push_length`` and ``pusher_radius`` are used.
    outline : callable
        Returns the object's current outline (P, 2) in ``world`` (called last, only when the
        cheaper checks pass).
    approach, contact, end : (2,) array_like

    Returns
    -------
    approach, contact, end : (3 x) (2,) float64 ndarray

    Raises
    ------
    ValueError
        Naming the offending argument.
    """
    pts = []
    for name, value in (("approach", approach), ("contact", contact), ("end", end)):
        try:
            pt = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected a point (x, y) in metres, got {value!r}") \
                from None
        if pt.shape != (2,):
            raise ValueError(f"{name}: expected a point (x, y) of shape (2,), got shape "
                             f"{pt.shape}")
        if not np.all(np.isfinite(pt)):
            raise ValueError(f"{name}: must be finite, got {pt.tolist()}")
        (x0, x1), (y0, y1) = cfg.workspace
        if not (x0 <= pt[0] <= x1 and y0 <= pt[1] <= y1):
            raise PushRefused("workspace", f"{name}: ({pt[0]:.4f}, {pt[1]:.4f}) m is outside "
                              f"the workspace x in [{x0}, {x1}], y in [{y0}, {y1}] m")
        pts.append(pt)
    a, c, e = pts
    length = float(np.linalg.norm(e - c))
    if length < MIN_PUSH_LENGTH:
        raise ValueError(f"push too short: |end - contact| = {1e3 * length:.3f} mm < "
                         f"{1e3 * MIN_PUSH_LENGTH:.0f} mm")
    if length > cfg.max_push_length:
        raise ValueError(f"push too long: |end - contact| = {length:.4f} m > "
                         f"max_push_length = {cfg.max_push_length} m")
    gap = float(np.linalg.norm(c - a))
    if gap > MAX_APPROACH_DISTANCE:
        raise ValueError(f"approach: {gap:.4f} m from the contact point, at most "
                         f"{MAX_APPROACH_DISTANCE} m allowed")
    stroke = e - a
    off_line = abs(stroke[0] * (c - a)[1] - stroke[1] * (c - a)[0]) / np.linalg.norm(stroke)
    if off_line > COLLINEAR_TOLERANCE:
        raise ValueError(f"contact: {1e3 * off_line:.1f} mm off the straight line approach "
                         f"-> end (tolerance {1e3 * COLLINEAR_TOLERANCE:.0f} mm); the pusher "
                         "moves on that line")
    _, _, dist, _ = closest_point_on_polyline(outline(), a)
    need = cfg.pusher_radius + APPROACH_MARGIN
    if dist < 0:
        raise ValueError(f"approach: ({a[0]:.4f}, {a[1]:.4f}) m is inside the object; the "
                         "pusher must be lowered outside it")
    if dist < need:
        raise ValueError(f"approach: ({a[0]:.4f}, {a[1]:.4f}) m is {1e3 * float(dist):.2f} "
                         f"mm from the object's outline; it must be at least "
                         f"{1e3 * need:.1f} mm (pusher radius + {1e3 * APPROACH_MARGIN} mm) "
                         "away so the pusher can be lowered without touching the object")
    return a, c, e


class Physics:
    """Steps one scene and drives its pusher; counts the physics steps (``sim_time``).

    Parameters
    ----------
    client : BulletClient
    scene : Scene
        The bodies, freshly built (pusher parked).
    cfg : WorldConfig
        ``time_step``, ``settle_timeout`` and ``push_speed`` are used.
    """

    def __init__(self, client: BulletClient, scene: Scene, cfg: WorldConfig) -> None:
        self._client = client
        self._scene = scene
        self._cfg = cfg
        self.steps = 0
        self._target = park_position()
        self._on_step: Callable[[], None] | None = None  # set only while execute_push runs

    @property
    def sim_time(self) -> float:
        """Simulated time since the scene was built, s."""
        return self.steps * self._cfg.time_step

    # ---------------------------------------------------------------------- state
    def object_frame(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Position (3,) of the object frame in ``world`` and its rotation matrix (3, 3)."""
        com, quat = self._client.getBasePositionAndOrientation(self._scene.object)
        rot = np.array(self._client.getMatrixFromQuaternion(quat)).reshape(3, 3)
        return np.asarray(com) - rot @ self._scene.inertial_offset, rot

    def object_pose(self) -> NDArray[np.float64]:
        """``(x, y, theta)`` of the object frame in ``world`` (theta in (-pi, pi])."""
        pos, rot = self.object_frame()
        return np.array([pos[0], pos[1], np.arctan2(rot[1, 0], rot[0, 0])])

    def pusher_position(self) -> NDArray[np.float64]:
        """Measured (x, y) of the pusher axis in ``world``, m."""
        pos, _ = self._client.getBasePositionAndOrientation(self._scene.pusher)
        return np.array(pos[:2])

    def place_object(self, pose: NDArray[np.float64], margin: float) -> None:
        """Put the object frame at ``(x, y, theta)``, ``margin`` above the table, at rest."""
        quat = yaw_quaternion(pose[2])
        rot = np.array(self._client.getMatrixFromQuaternion(quat)).reshape(3, 3)
        com = np.array([pose[0], pose[1], margin]) + rot @ self._scene.inertial_offset
        self._client.resetBasePositionAndOrientation(self._scene.object, com.tolist(), quat)
        self._client.resetBaseVelocity(self._scene.object, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])

    # --------------------------------------------------------------------- motion
    def step(self, n: int) -> None:
        """Run ``n`` physics steps."""
        for _ in range(n):
            self._client.stepSimulation()
        self.steps += n

    def teleport_pusher(self, target: NDArray[np.float64]) -> None:
        """Move the pusher instantly; only ever called with both ends above everything (or
        by the world's ``place_pusher``, whose caller checks for overlap)."""
        c = self._client
        c.resetBasePositionAndOrientation(self._scene.pusher, target.tolist(),
                                          [0.0, 0.0, 0.0, 1.0])
        c.resetBaseVelocity(self._scene.pusher, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        c.changeConstraint(self._scene.drive, target.tolist(), maxForce=PUSHER_MAX_FORCE)
        self._target = target.copy()

    def move_pusher(self, target: NDArray[np.float64], speed: float,
                    watch_contact: bool = False) -> bool:
        """Move the constraint pivot in a straight line to ``target`` at ``speed``, stepping
        the physics; returns whether the pusher touched the object (if ``watch_contact``)."""
        cid = self._client._client  # direct pybullet calls: this loop runs every physics step
        drive, pusher, body = self._scene.drive, self._scene.pusher, self._scene.object
        dt = self._cfg.time_step
        start = self._target
        n = max(1, int(np.ceil(np.linalg.norm(target - start) / (speed * dt) - 1e-9)))
        touched = False
        for i in range(1, n + 1):
            pivot = (start + (target - start) * (i / n)).tolist()
            p.changeConstraint(drive, pivot, maxForce=PUSHER_MAX_FORCE, physicsClientId=cid)
            p.stepSimulation(physicsClientId=cid)
            self.steps += 1
            if self._on_step is not None:
                self._on_step()
            if watch_contact and not touched:
                touched = any(pt[9] > 0.0 for pt in p.getContactPoints(
                    pusher, body, physicsClientId=cid))
        self._target = target.copy()
        return touched

    def settle(self) -> bool:
        """Step until the object rests (module docstring) or ``settle_timeout`` has passed;
        returns whether it came to rest."""
        c = self._client
        calm = 0
        for _ in range(int(np.ceil(self._cfg.settle_timeout / self._cfg.time_step))):
            lin, ang = c.getBaseVelocity(self._scene.object)
            if np.linalg.norm(lin) < REST_SPEED and np.linalg.norm(ang) < REST_ANGULAR:
                calm += 1
                if calm >= REST_STEPS:
                    return True
            else:
                calm = 0
            self.step(1)
            if self._on_step is not None:
                self._on_step()
        return False

    def clear_height(self, thickness: float) -> float:
        """Height of the pusher's centre when its bottom is clear above the object, m."""
        top = self._client.getAABB(self._scene.object)[1][2]
        return max(top, thickness) + LIFT_CLEARANCE + PUSHER_LENGTH / 2.0

    def execute_push(self, a: NDArray[np.float64], c: NDArray[np.float64],
                     e: NDArray[np.float64], thickness: float,
                     on_step: Callable[[], None] | None = None) -> PushResult:
        """Steps 2-6 of the module docstring for a push already validated by
        :func:`check_push`; ``thickness`` is the object's, m. ``on_step`` is called after
        every physics step of steps 3-6 (read-only observers, module docstring)."""
        self._on_step = on_step
        try:
            return self._execute_push(a, c, e, thickness)
        finally:
            self._on_step = None

    def _execute_push(self, a: NDArray[np.float64], c: NDArray[np.float64],
                      e: NDArray[np.float64], thickness: float) -> PushResult:
        pose_before = self.object_pose()
        z_push = PUSHER_GAP + PUSHER_LENGTH / 2.0
        z_clear = self.clear_height(thickness)
        self.teleport_pusher(np.array([a[0], a[1], z_clear]))
        self.move_pusher(np.array([a[0], a[1], z_push]), LIFT_SPEED)
        start, t_start = self.pusher_position(), self.sim_time
        touched = self.move_pusher(np.array([e[0], e[1], z_push]), self._cfg.push_speed,
                                   watch_contact=True)
        finish, t_end = self.pusher_position(), self.sim_time
        back = e - BACK_OFF * (e - a) / np.linalg.norm(e - a)
        self.move_pusher(np.array([back[0], back[1], z_push]), RETRACT_SPEED)
        self.move_pusher(np.array([back[0], back[1], z_clear]), LIFT_SPEED)
        self.teleport_pusher(park_position())
        settled = self.settle()
        return PushResult(pusher_start=start, pusher_end=finish, t_start=t_start, t_end=t_end,
                          pose_before=pose_before, pose_after=self.object_pose(),
                          touched=touched, settled=settled, t_done=self.sim_time,
                          approach=a, contact=c, end=e)
