"""The planner's validated inputs: the outline it plans on and a plausible state, ROS-free.

:func:`prepare_outline` turns measured outline points and normals into an :class:`Outline`
(once per shape): validated, decimated to :data:`MAX_OUTLINE_POINTS`, with the simplified
polyline of the contact search. :func:`check_state` refuses an implausible ``(x, y, theta, c_x,
c_y, l, m)``. Both bound the planner's work and memory on any input; neither binds on a normal
one (the library's outlines have at most ~260 points at the perception's 2 mm spacing), so
normal results are unchanged to the bit.

Frames and units: outline points, normals and the COM in the object frame (origin = area
centroid), metres; the pose in ``world``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import check_polyline, check_vector
from push_core.shapes import Polygon
from push_core.symmetry import has_continuous_symmetry

__all__ = ["MAX_COM_RADII", "MAX_FRICTION", "MAX_L_RADII", "MAX_OUTLINE_POINTS", "Outline",
           "check_state", "prepare_outline"]

#: :func:`prepare_outline` decimates an outline of more points to this many (every
#: ``N / MAX_OUTLINE_POINTS``-th point, normals with them): its simple-polygon check is
#: O(N^2) in memory (~80 MB at this size), every later step O(N) or O(N P).
MAX_OUTLINE_POINTS = 1000
#: Plausible state (:func:`check_state`): ``0 < l <= MAX_L_RADII * r`` and
#: ``|c| <= MAX_COM_RADII * r`` with ``r`` the outline's radius (its largest distance from the
#: object frame origin; the estimator keeps ``l <= r`` and ``c`` in the convex hull), and
#: ``0 <= m <= MAX_FRICTION``.
MAX_L_RADII = 4.0
MAX_COM_RADII = 2.0
MAX_FRICTION = 10.0


@dataclass(frozen=True, eq=False)
class Outline:
    """A validated outline for planning (build it with :func:`prepare_outline`, once per shape).

    Attributes
    ----------
    points : numpy.ndarray, shape (N, 2)
        Candidate contact points, counter-clockwise, object frame (metres).
    normals : numpy.ndarray, shape (N, 2)
        Outward unit normals at ``points``.
    polyline : numpy.ndarray, shape (P, 2)
        Closed counter-clockwise polyline for contact search in rollouts and approach checks:
        ``points`` simplified by Douglas-Peucker (``P <= N``).
    orientation_matters : bool
        False for a continuously symmetric outline (a disc,
        :func:`push_core.symmetry.has_continuous_symmetry`): its orientation cannot be
        observed, so the planner scores and stops on the goal position alone.
    source_points : int
        Points of the outline as given (more than ``len(points)`` when it was decimated to
        :data:`MAX_OUTLINE_POINTS`); 0 = not recorded.
    """

    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    polyline: NDArray[np.float64]
    orientation_matters: bool = True
    source_points: int = 0

    @property
    def radius(self) -> float:
        """Largest distance of an outline point from the object frame origin, metres."""
        return float(np.max(np.hypot(self.points[:, 0], self.points[:, 1])))


def prepare_outline(points: ArrayLike, normals_out: ArrayLike,
                    simplify_tolerance: float = 5e-4,
                    max_points: int = MAX_OUTLINE_POINTS) -> Outline:
    """Validate an outline and build the simplified polyline used for contact search.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Outline points, counter-clockwise, object frame (metres), ``N >= 3``, finite, with a
        positive enclosed area.
    normals_out : array_like, shape (N, 2)
        Outward normals at ``points``, finite and non-zero; normalised here.
    simplify_tolerance : float
        Douglas-Peucker tolerance of the contact polyline, metres (>= 0; 0 keeps ``points``).
        Measured outlines that do not form a simple polygon are used unsimplified.
    max_points : int
        An outline of more points is decimated to this many (every ``N / max_points``-th
        point from point 0, with its normal; bounded work and memory, see
        :data:`MAX_OUTLINE_POINTS`); ``Outline.source_points`` keeps ``N``.

    Returns
    -------
    Outline

    Raises
    ------
    ValueError
        Naming ``points`` or ``normals_out``.
    """
    p = np.array(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3:
        raise ValueError(f"points must have shape (N, 2) with N >= 3, got shape {p.shape}")
    n = np.array(normals_out, dtype=np.float64)
    if n.shape != p.shape:
        raise ValueError(f"normals_out must have the shape of points {p.shape}, got {n.shape}")
    source_points = len(p)
    if isinstance(max_points, bool) or int(max_points) != max_points or max_points < 3:
        raise ValueError(f"max_points must be an integer >= 3, got {max_points!r}")
    if len(p) > max_points:
        keep = np.linspace(0, len(p), int(max_points), endpoint=False).astype(np.intp)
        p, n = p[keep], n[keep]
    check_polyline(p, "points")
    norm = np.hypot(n[:, 0], n[:, 1])
    if not np.all(np.isfinite(norm)) or np.any(norm <= 1e-12):
        raise ValueError("normals_out must be finite and non-zero")
    if not simplify_tolerance >= 0.0:
        raise ValueError(f"simplify_tolerance must be >= 0, got {simplify_tolerance}")
    polyline = p
    if simplify_tolerance > 0.0:
        try:
            polyline = np.array(Polygon(p).simplified(simplify_tolerance).vertices)
        except ValueError:  # not a simple polygon (noisy measured outline): use it as it is
            polyline = p
    for a in (p, n, polyline):
        a.setflags(write=False)
    n = n / norm[:, None]
    n.setflags(write=False)
    return Outline(points=p, normals=n, polyline=polyline,
                   orientation_matters=not has_continuous_symmetry(p),
                   source_points=source_points)


def check_state(state: ArrayLike, outline: Outline | None = None) -> NDArray[np.float64]:
    """A plausible planner state ``(x, y, theta, c_x, c_y, l, m)``, (7,), or ``ValueError``.

    Finite; ``l > 0`` and ``m`` in ``[0, MAX_FRICTION]``; with ``outline``, also
    ``l <= MAX_L_RADII * r`` and ``|c| <= MAX_COM_RADII * r`` (``r = outline.radius``: the COM
    of a rigid object lies inside its outline, and the estimator keeps ``l <= r``). The message
    starts with ``state``.
    """
    s = check_vector(state, 7, "state")
    com, l, m = s[3:5], float(s[5]), float(s[6])  # noqa: E741
    if not l > 0.0 or not 0.0 <= m <= MAX_FRICTION:
        raise ValueError(f"state: l must be > 0 and m in [0, {MAX_FRICTION}], got l = {l}, "
                         f"m = {m}")
    if outline is not None:
        r = outline.radius
        if l > MAX_L_RADII * r:
            raise ValueError(f"state: l = {l:.6g} m is more than {MAX_L_RADII:g} times the "
                             f"outline's radius {r:.6g} m")
        if math.hypot(com[0], com[1]) > MAX_COM_RADII * r:
            raise ValueError(f"state: the COM ({com[0]:.6g}, {com[1]:.6g}) m is more than "
                             f"{MAX_COM_RADII:g} outline radii ({r:.6g} m) from the object "
                             f"frame origin")
    return s
