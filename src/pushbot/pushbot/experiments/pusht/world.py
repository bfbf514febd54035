"""The Push-T env as push_core sees it: the T, the frames and the agent's controller.

The env is gym-pusht's ``gym_pusht/PushT-v0`` (:mod:`pushbot.experiments.pusht.adapter` plans
in it). Units and frames (checked against gym-pusht 0.1.8, ``envs/pusht.py``):

- **Scale**: one env unit (a pixel of the 512 x 512 render) is taken as 1 mm
  (:data:`METRES_PER_UNIT`), so the T is 120 mm wide and 120 mm tall, the pusher radius 15 mm,
  push lengths of 1-5 cm are 10-50 units.
- **Axes**: push_core's ``world`` is the pymunk frame scaled: x to the right of the image, y
  *down* the image (pygame draws pymunk coordinates unflipped, ``positive_y_is_up = False``),
  angles from x towards y (clockwise on the screen). This is a right-handed frame whose z
  points into the screen; push_core's planar maths needs nothing else.
- **Block reference point**: the env reports ``block.position``/``block.angle``, the pose of
  the pymunk *body* frame: the midpoint of the top edge of the T's bar, y along the stem. The
  T is two boxes in that frame, the bar ``[-60, 60] x [0, 30]`` and the stem
  ``[-15, 15] x [30, 120]``; their union is the outline given to
  :meth:`push_core.pushable.PushObject.from_polygon`, whose ``object`` frame origin is the
  area centroid, ``(0, 40.71)`` in the body frame (:meth:`PushObject.to_object_pose`).
- **Centre of gravity**: pymunk's, ``center_of_gravity = (0, 45)`` in the body frame (the mean of
  the two boxes' centroids, not area-weighted): the COM the planner uses, 4.29 mm from the area
  centroid along the stem. The env sets the block angle about this point at reset.
- **Dynamics**: ``space.damping = 0`` zeroes every velocity at each 10 ms physics step, and the
  contact is frictionless (the T's and the agent's shapes keep pymunk's default friction 0;
  ``body.friction = 1`` in the env sets no shape friction). A frictionless impulsive push on a
  body that keeps no velocity moves it as the ellipsoidal limit-surface model with ``m = 0``
  and ``l = sqrt(I / M)`` (the radius of gyration about the COM; the impulse gives
  ``v = J / M``, ``omega = (r x J) / I``), read from the env's body (``M = 1``, ``I = 3000``:
  the env adds the bar's moment twice, so ``l = 54.8`` mm, not the uniform-pressure guess).
- **Agent**: a kinematic disc (radius 15) driven by PD control towards the action (``k_p =
  100``, ``k_v = 20``, 10 physics steps of 10 ms per control step). The agent is kinematic, so
  its motion depends only on the actions: :class:`AgentModel` replicates the controller and
  picks each action so that the disc follows the planned path (two-step deadbeat on position
  and velocity), tracking its velocity from the actions it sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.pushable import Pusher, PushObject

__all__ = ["ENV_ID", "METRES_PER_UNIT", "MISSING", "AgentModel", "PushTFrames", "make_tee",
           "tee_body", "timed_path"]

#: Metres per env unit (one pixel of the 512 x 512 render is taken as 1 mm).
METRES_PER_UNIT = 1e-3
#: Message of a missing optional dependency.
MISSING = "Push-T needs gym-pusht and its dependencies (pip install 'pushbot[pusht]'): "
#: The env id.
ENV_ID = "gym_pusht/PushT-v0"


# ------------------------------------------------------------------------------ the env's T
def tee_body(env: object) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float,
                                      float, float]:
    """The block as the env built it: outline (body frame, env units), centre of gravity,
    mass, moment of inertia, pusher-block friction and the agent's radius.

    Read from the env's pymunk objects (``env.unwrapped``): the two boxes' union (shapely,
    a gym-pusht dependency), ``block.center_of_gravity``, ``block.mass``, ``block.moment``,
    the product of the shapes' friction coefficients (pymunk's default combine rule).
    """
    try:  # gym-pusht's dependency: an optional extra (pushbot[pusht]), no rosdep key
        import shapely.geometry as sg
        from shapely.geometry.polygon import orient
        from shapely.ops import unary_union
    except ImportError as exc:
        raise ImportError(MISSING + str(exc)) from exc

    u = env.unwrapped
    boxes = [sg.Polygon([tuple(v) for v in s.get_vertices()]) for s in u.block.shapes]
    ring = np.array(orient(unary_union(boxes), 1.0).exterior.coords)[:-1]  # CCW
    keep = _corners(ring)
    agent_shape = next(iter(u.agent.shapes))
    friction = float(agent_shape.friction) * float(next(iter(u.block.shapes)).friction)
    cog = np.array(tuple(u.block.center_of_gravity), dtype=np.float64)
    return (ring[keep], cog, float(u.block.mass), float(u.block.moment), friction,
            float(agent_shape.radius))


def _corners(ring: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Vertices of a closed ring that are real corners (not collinear)."""
    prev, nxt = np.roll(ring, 1, axis=0), np.roll(ring, -1, axis=0)
    cross = (ring - prev)[:, 0] * (nxt - ring)[:, 1] - (ring - prev)[:, 1] * (nxt - ring)[:, 0]
    return np.abs(cross) > 1e-9


@dataclass(frozen=True)
class PushTFrames:
    """Conversions between the env (units, body frame of the T) and push_core (metres,
    object frame); see the module docstring."""

    obj: PushObject
    scale: float = METRES_PER_UNIT

    def to_world(self, points: ArrayLike) -> NDArray[np.float64]:
        """Env points (..., 2) -> world metres."""
        return np.asarray(points, dtype=np.float64) * self.scale

    def to_env(self, points: ArrayLike) -> NDArray[np.float64]:
        """World metres (..., 2) -> env units."""
        return np.asarray(points, dtype=np.float64) / self.scale

    def object_pose(self, body_pose: ArrayLike) -> NDArray[np.float64]:
        """The env's block pose ``(x, y, angle)`` (body frame, units) -> object frame (m)."""
        b = np.asarray(body_pose, dtype=np.float64)
        return self.obj.to_object_pose([b[0] * self.scale, b[1] * self.scale, b[2]])

    def body_pose(self, pose: ArrayLike) -> NDArray[np.float64]:
        """Inverse of :meth:`object_pose`."""
        s = self.obj.to_source_pose(pose)
        return np.array([s[0] / self.scale, s[1] / self.scale, s[2]])


def make_tee(env: object) -> tuple[PushObject, Pusher, PushTFrames]:
    """The T, the pusher and the frames of an env, through the public library API."""
    ring, cog, mass, moment, friction, radius = tee_body(env)
    s = METRES_PER_UNIT
    obj = PushObject.from_polygon(ring * s, com=cog * s, friction=friction,
                                  limit_surface=math.sqrt(moment / mass) * s)
    return obj, Pusher(radius=radius * s), PushTFrames(obj)


# ------------------------------------------------------------------------------ the agent
class AgentModel:
    """The env's PD control of its kinematic disc, per axis (exact: the disc is kinematic).

    One control step holds the action ``a`` for ``n`` physics steps of ``dt``:
    ``v += (k_p (a - x) - k_v v) dt; x += v dt``. Linear, so ``(x, v)`` after a step is
    ``A (x, v) + B a``; :meth:`action` solves the two-step deadbeat for a desired position
    after one step and position and velocity after two.
    """

    def __init__(self, k_p: float = 100.0, k_v: float = 20.0, dt: float = 0.01,
                 n: int = 10, low: float = 0.0, high: float = 512.0) -> None:
        m = np.array([[1.0 - k_p * dt * dt, dt * (1.0 - k_v * dt)], [-k_p * dt, 1.0 - k_v * dt]])
        b = np.array([k_p * dt * dt, k_p * dt])
        a_mat, b_vec = np.eye(2), np.zeros(2)
        for _ in range(n):
            a_mat, b_vec = m @ a_mat, m @ b_vec + b
        self.A, self.B = a_mat, b_vec
        self.low, self.high = low, high
        # [a0, a1] -> (x2, v2): A B a0 + B a1
        self._solve = np.linalg.inv(np.column_stack([self.A @ self.B, self.B]))
        self.x = np.zeros(2)
        self.v = np.zeros(2)

    @classmethod
    def of_env(cls, env: object) -> AgentModel:
        u = env.unwrapped
        n = int(1 / (u.dt * u.control_hz))
        return cls(u.k_p, u.k_v, u.dt, n, float(u.action_space.low[0]),
                   float(u.action_space.high[0]))

    def reset(self, position: ArrayLike) -> None:
        self.x = np.asarray(position, dtype=np.float64).copy()
        self.v = np.zeros(2)

    def action(self, p2: ArrayLike, v2: ArrayLike) -> NDArray[np.float64]:
        """Action (2,) towards position ``p2`` and velocity ``v2`` (units/s) two steps ahead,
        clipped to the action space."""
        target = np.stack([np.asarray(p2, float), np.asarray(v2, float)])  # (2 [x,v], 2 axes)
        free = self.A @ (self.A @ np.stack([self.x, self.v]))
        a = (self._solve @ (target - free))[0]
        return np.clip(a, self.low, self.high)

    def step(self, action: ArrayLike, observed: ArrayLike | None = None) -> None:
        """Advance the model by one control step with ``action``; ``observed`` (the env's
        agent position) replaces the predicted position."""
        s = self.A @ np.stack([self.x, self.v]) + np.outer(self.B, np.asarray(action, float))
        self.x, self.v = s[0], s[1]
        if observed is not None:
            self.x = np.asarray(observed, dtype=np.float64).copy()


def timed_path(waypoints: NDArray[np.float64], speeds: NDArray[np.float64]
               ) -> NDArray[np.float64]:
    """Positions (K, 2) at successive control steps along a polyline: every waypoint, and
    segment ``i`` split into equal parts of at most ``speeds[i]`` units (per control step)."""
    out = [waypoints[0]]
    for i in range(len(waypoints) - 1):
        a, b = waypoints[i], waypoints[i + 1]
        n = int(math.ceil(float(np.linalg.norm(b - a)) / speeds[i] - 1e-9))
        out.extend(a + (b - a) * (j / n) for j in range(1, n + 1))
    return np.array(out)
