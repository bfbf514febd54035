"""push_core as a library: describe your own object and pusher in a few lines.

For a user outside this repository with their own pusher and simulator (or robot)::

    from push_core.pushable import Pusher, PushObject
    obj = PushObject.from_polygon(vertices, com=(0.0, 0.01))   # no mass, no thickness
    pusher = Pusher(radius=0.015)                               # the one place for the radius
    planner = pusher.planner(workspace=((0.0, 0.5), (0.0, 0.5)), obstacles=[wall])
    plan = planner.plan(obj.outline, obj.state(obj.to_object_pose(pose)), goal,
                        pusher=pusher_xy)                       # a pusher that cannot lift
    way_in = planner.transit(obj.outline, obj.to_object_pose(pose), pusher_xy, plan.approach)

- :class:`PushObject`: a shape from just a polygon (either orientation: clockwise input is
  re-oriented and says so in ``notes`` and a ``UserWarning``) or an ellipse, and a COM; no mass
  or thickness (the planner and estimator do not need them). It is re-centred on its area
  centroid, the ``object`` frame of push_core; :meth:`PushObject.to_object_pose` and
  :meth:`PushObject.to_source_pose` convert poses of the frame the vertices were given in.
  Defaults: the limit-surface parameter ``l`` is the uniform-pressure guess from the shape
  (:func:`push_core.objects.limit_surface_guess`) and the pusher-object friction is
  :data:`push_core.objects.DEFAULT_FRICTION_PUSHER` (0.25); both can be given (``friction=0``
  for a frictionless world).
- :class:`Pusher`: the pusher's radius, shared by the planner (:meth:`Pusher.planner`), the
  rollout (through the planner config) and the estimator (:meth:`Pusher.estimator`).

Frames and units: SI by default (metres, radians), but nothing here depends on the unit as long
as every length (vertices, COM, poses, radius, workspace) uses the same one; the planner's
scores and defaults (tolerances, push lengths, substep) are in metres, so a user working in
other units passes them explicitly.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.estimator.config import EKFConfig
from push_core.estimator.ekf import PushEKF
from push_core.geometry import object_to_world, world_to_object, wrap_angle
from push_core.objects import DEFAULT_FRICTION_PUSHER, limit_surface_guess
from push_core.planner import Outline, Planner, PlannerConfig, prepare_outline
from push_core.rollout import PUSHER_RADIUS
from push_core.shapes import Ellipse, Polygon, Shape, polygon_signed_area
from push_core.transit import ccw_polygon

__all__ = ["PushObject", "Pusher"]


@dataclass(frozen=True, eq=False)
class PushObject:
    """A flat object for planning and estimation (build it with :meth:`from_polygon` or
    :meth:`from_ellipse`).

    Attributes
    ----------
    shape : Polygon | Ellipse
        Outline in the object frame (area centroid at the origin).
    com : numpy.ndarray, shape (2,)
        Centre of mass in the object frame.
    origin : numpy.ndarray, shape (2,)
        The input vertices' origin expressed in the object frame.
    limit_surface : float
        Limit-surface parameter ``l`` (same length unit).
    friction : float
        Pusher-object Coulomb coefficient, >= 0.
    outline : Outline
        The planner's outline (points every ``spacing`` with outward normals).
    notes : tuple of str
        What was changed in the input (e.g. a clockwise polygon re-oriented).
    """

    shape: Shape
    com: NDArray[np.float64]
    origin: NDArray[np.float64]
    limit_surface: float
    friction: float
    outline: Outline
    notes: tuple[str, ...] = field(default=())

    @classmethod
    def from_polygon(cls, vertices: ArrayLike, com: ArrayLike | None = None,
                     friction: float = DEFAULT_FRICTION_PUSHER,
                     limit_surface: float | None = None, spacing: float = 0.002
                     ) -> PushObject:
        """An object from its outline polygon.

        Parameters
        ----------
        vertices : array_like, shape (P, 2)
            A simple polygon about any origin, either orientation (clockwise is reversed,
            noted in ``notes`` and warned about).
        com : array_like, shape (2,), optional
            Centre of mass in the vertices' frame; default the area centroid (uniform density).
        friction : float
            Pusher-object friction coefficient (default 0.25; 0 = frictionless contact).
        limit_surface : float, optional
            ``l``; default the uniform-pressure guess from the shape about ``com``.
        spacing : float
            Spacing of the planner's outline points (length unit of ``vertices``).

        Raises
        ------
        ValueError
            Naming ``vertices``, ``com``, ``friction``, ``limit_surface`` or ``spacing``.
        """
        notes = []
        v = ccw_polygon(vertices, "vertices")
        if polygon_signed_area(np.asarray(vertices, dtype=np.float64)) < 0.0:
            notes.append("vertices were clockwise: re-oriented counter-clockwise (same polygon)")
            warnings.warn(f"PushObject.from_polygon: {notes[-1]}", UserWarning, stacklevel=2)
        source = Polygon(v, field="vertices")
        centroid = source.centroid
        shape = source.translated(-centroid)
        return cls._build(shape, centroid, com, friction, limit_surface, spacing, notes)

    @classmethod
    def from_ellipse(cls, a: float, b: float, com: ArrayLike | None = None,
                     friction: float = DEFAULT_FRICTION_PUSHER,
                     limit_surface: float | None = None, spacing: float = 0.002
                     ) -> PushObject:
        """An ellipse with semi-axes ``a`` (along x) and ``b`` centred at the origin; the other
        parameters as in :meth:`from_polygon`."""
        shape = Ellipse(a, b)
        return cls._build(shape, np.zeros(2), com, friction, limit_surface, spacing, [])

    @classmethod
    def _build(cls, shape: Shape, centroid: NDArray[np.float64], com: ArrayLike | None,
               friction: float, limit_surface: float | None, spacing: float,
               notes: list[str]) -> PushObject:
        c = np.zeros(2) if com is None else _finite("com", com, 2) - centroid
        f = float(friction)
        if not (math.isfinite(f) and f >= 0.0):
            raise ValueError(f"friction: must be finite and >= 0, got {friction!r}")
        if not (isinstance(spacing, int | float) and math.isfinite(spacing) and spacing > 0.0):
            raise ValueError(f"spacing: must be finite and > 0, got {spacing!r}")
        if limit_surface is None:
            ls = limit_surface_guess(shape, c)
        else:
            ls = float(limit_surface)
            if not (math.isfinite(ls) and ls > 0.0):
                raise ValueError(f"limit_surface: must be finite and > 0, got {limit_surface!r}")
        points, normals = shape.outline(spacing)
        outline = prepare_outline(points, normals)
        c.setflags(write=False)
        origin = -np.asarray(centroid, dtype=np.float64)
        origin.setflags(write=False)
        return cls(shape=shape, com=c, origin=origin, limit_surface=ls, friction=f,
                   outline=outline, notes=tuple(notes))

    def state(self, pose: ArrayLike) -> NDArray[np.float64]:
        """The planner/estimator state ``(x, y, theta, c_x, c_y, l, m)`` (7,) at an object-frame
        pose (3,)."""
        p = _finite("pose", pose, 3)
        return np.array([p[0], p[1], p[2], self.com[0], self.com[1], self.limit_surface,
                         self.friction])

    def to_object_pose(self, source_pose: ArrayLike) -> NDArray[np.float64]:
        """Pose (3,) of the object frame from the pose of the frame the vertices were given
        in (same rotation; the origin moves by the centroid)."""
        p = _finite("source_pose", source_pose, 3)
        xy = object_to_world(p, -self.origin)
        return np.array([xy[0], xy[1], p[2]])

    def to_source_pose(self, pose: ArrayLike) -> NDArray[np.float64]:
        """Inverse of :meth:`to_object_pose`."""
        p = _finite("pose", pose, 3)
        xy = object_to_world(p, self.origin)
        return np.array([xy[0], xy[1], p[2]])

    def world_polygon(self, pose: ArrayLike) -> NDArray[np.float64]:
        """The outline polyline (P, 2) placed at an object-frame pose, world frame."""
        return object_to_world(_finite("pose", pose, 3), self.outline.polyline)

    def pose_error(self, pose: ArrayLike, goal: ArrayLike) -> tuple[float, float]:
        """Distance (length unit) and absolute wrapped angle (rad) between two poses."""
        a, b = _finite("pose", pose, 3), _finite("goal", goal, 3)
        return float(np.hypot(*(b[:2] - a[:2]))), abs(float(wrap_angle(b[2] - a[2])))

    def in_object_frame(self, pose: ArrayLike, points: ArrayLike) -> NDArray[np.float64]:
        """World points (..., 2) in the object frame at ``pose``."""
        return world_to_object(_finite("pose", pose, 3), points)


@dataclass(frozen=True)
class Pusher:
    """A disc pusher: the one place for its radius (planner, rollouts, estimator).

    Attributes
    ----------
    radius : float
        Pusher radius (length unit of the objects), >= 0; default the source setup's 4.8 mm.
    """

    radius: float = PUSHER_RADIUS

    def __post_init__(self) -> None:
        r = self.radius
        if isinstance(r, bool) or not isinstance(r, int | float) or not math.isfinite(r) \
                or r < 0.0:
            raise ValueError(f"radius: must be a finite number >= 0, got {r!r}")
        object.__setattr__(self, "radius", float(r))

    def planner_config(self, **options: object) -> PlannerConfig:
        """A :class:`PlannerConfig` with this pusher's radius and ``options`` (any other field,
        e.g. ``workspace``, ``obstacles``, ``travel_weight``)."""
        if "pusher_radius" in options:
            raise ValueError("pusher_radius: set it once, in Pusher(radius=...)")
        return PlannerConfig(pusher_radius=self.radius, **options)

    def planner(self, **options: object) -> Planner:
        """A :class:`Planner` for :meth:`planner_config` ``(**options)``."""
        return Planner(self.planner_config(**options))

    def estimator(self, obj: PushObject, **options: object) -> PushEKF:
        """A :class:`push_core.estimator.PushEKF` for ``obj`` with this pusher's radius; the
        object's COM, ``l`` and friction are taken as known (``EKFConfig.known_com`` etc.)
        unless ``options`` say otherwise."""
        if "pusher_radius" in options:
            raise ValueError("pusher_radius: set it once, in Pusher(radius=...)")
        options.setdefault("known_com", tuple(float(v) for v in obj.com))
        options.setdefault("known_l", obj.limit_surface)
        options.setdefault("known_m", obj.friction)
        config = EKFConfig(pusher_radius=self.radius, **options)
        return PushEKF(obj.outline.points, obj.outline.normals, config)


def _finite(name: str, value: ArrayLike, size: int) -> NDArray[np.float64]:
    try:
        v = np.array(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {size} numbers, got {value!r}") from None
    if v.shape != (size,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: expected {size} finite numbers, got {value!r}")
    return v
