"""Rotational symmetry of an outline: when the orientation of an object can be seen at all.

ROS-free, numpy. One rule, used by the perception (is the orientation observable?), the
estimator (fuse the orientation or not), the planner (does the goal orientation matter?) and the
scoring of episodes (is the orientation error counted?), so they always agree
(docs/design/symmetry.md):

**Continuous symmetry.** An outline is *continuously symmetric* (a disc, a cylinder lying on its
base, or a regular polygon with so many sides that a camera cannot tell its facets) when
rotating it about its area centroid by each of ``TEST_ANGLES_DEG`` (every 7.5 degrees up to
180) moves its points by at most ``CONTINUOUS_SYMMETRY_TOLERANCE`` root-mean-square from the
outline. The appearance of a uniformly coloured flat object then cannot show its orientation:
perception reports the orientation as not observed (variance ``UNOBSERVED_VARIANCE``), the
estimator fuses only the position, the planner plans for the goal position alone, and an
episode succeeds on the position tolerance alone. The tolerance (1 mm) is above the perceived
outline's own error (median 0.6 mm) and below what a visible corner gives: a hexagon of 6 cm
radius moves 3 mm RMS when turned by 30 degrees, an ellipse with semi-axes 52.5 and 54 mm 1 mm.

**k-fold symmetry** (:func:`symmetry_order_of_polygon`): the orientation is observable modulo
``2 pi / k`` (hex: k = 6); the estimator takes its innovation modulo that period.

A variance at or above ``UNOBSERVED_THRESHOLD`` (pi^2: a standard deviation of more than half a
turn carries no information) marks an orientation as not observed (:func:`orientation_observed`),
the convention of ``geometry_msgs/PoseWithCovariance`` for the unmeasured z, roll and pitch
(1e6).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import check_polyline, closest_point_on_polyline
from push_core.shapes import Polygon, polygon_signed_area

__all__ = [
    "CONTINUOUS_SYMMETRY_TOLERANCE",
    "MAX_SYMMETRY_ORDER",
    "TEST_ANGLES_DEG",
    "UNOBSERVED_THRESHOLD",
    "UNOBSERVED_VARIANCE",
    "has_continuous_symmetry",
    "orientation_observed",
    "rotation_mismatch",
    "symmetry_order_of_polygon",
]

#: RMS distance (m) a rotated outline may have from itself and still count as symmetric.
CONTINUOUS_SYMMETRY_TOLERANCE = 1e-3
#: Rotations tested for continuous symmetry, degrees (every 7.5 up to 180).
TEST_ANGLES_DEG = tuple(7.5 * k for k in range(1, 25))
#: Variance (rad^2) reported for an orientation that cannot be observed.
UNOBSERVED_VARIANCE = 1e6
#: Variances at or above this (rad^2) mean "not observed".
UNOBSERVED_THRESHOLD = math.pi**2
#: Largest rotational symmetry order :func:`symmetry_order_of_polygon` reports.
MAX_SYMMETRY_ORDER = 12
#: Vertices :func:`symmetry_order_of_polygon` rotates first, before all of them.
SYMMETRY_PROBE_VERTICES = 16
#: Outlines are decimated to at most this many points for the symmetry test (bounded cost).
_MAX_POINTS = 256


def orientation_observed(yaw_variance: float) -> bool:
    """Whether a reported orientation variance (rad^2) carries information.

    ``False`` for variances ``>= UNOBSERVED_THRESHOLD`` (pi^2) and for non-finite ones.
    """
    v = float(yaw_variance)
    return bool(math.isfinite(v) and v < UNOBSERVED_THRESHOLD)


def _centred(points: ArrayLike) -> NDArray[np.float64]:
    """The outline (decimated to ``_MAX_POINTS``) about its area centroid, counter-clockwise."""
    p = check_polyline(points, "points")
    if len(p) > _MAX_POINTS:
        p = p[np.linspace(0, len(p), _MAX_POINTS, endpoint=False).astype(np.intp)]
    if polygon_signed_area(p) < 0.0:
        p = p[::-1]
    x, y = p[:, 0], p[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = 0.5 * float(cross.sum())
    if abs(area) <= 1e-12:
        raise ValueError("points: the outline encloses no area")
    centroid = np.array([np.sum((x + xn) * cross), np.sum((y + yn) * cross)]) / (6.0 * area)
    return p - centroid


def rotation_mismatch(points: ArrayLike, angles: ArrayLike) -> NDArray[np.float64]:
    """RMS distance (m) of the outline rotated about its area centroid from the outline.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Closed outline (polygon vertices or sampled outline points), metres, any orientation.
    angles : array_like, shape (A,)
        Rotations, radians.

    Returns
    -------
    numpy.ndarray, shape (A,)
        For each angle, ``sqrt(mean_i d(R p_i, outline)^2)``.
    """
    p = _centred(points)
    a = np.atleast_1d(np.asarray(angles, dtype=np.float64))
    c, s = np.cos(a)[:, None], np.sin(a)[:, None]
    rotated = np.stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]], axis=-1)
    dist = closest_point_on_polyline(p, rotated)[2]  # (A, N)
    return np.sqrt(np.mean(dist**2, axis=1))


def has_continuous_symmetry(points: ArrayLike,
                            tolerance: float = CONTINUOUS_SYMMETRY_TOLERANCE) -> bool:
    """Whether the outline looks the same at every orientation (module docstring).

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Closed outline, metres (a shape's polygon, an ellipse's polyline or a perceived
        outline).
    tolerance : float
        Largest RMS mismatch (m) over ``TEST_ANGLES_DEG``.

    Raises
    ------
    ValueError
        Naming ``points`` (not an outline) or ``tolerance`` (not > 0).
    """
    if not tolerance > 0.0:
        raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
    angles = np.radians(np.array(TEST_ANGLES_DEG))
    # An outline without the symmetry already fails at the first test angle: it alone is
    # checked first (the same answer at a twenty-fourth of the cost for most outlines).
    return all(float(np.max(rotation_mismatch(points, batch))) <= tolerance
               for batch in (angles[:1], angles[1:]))


def symmetry_order_of_polygon(vertices: ArrayLike, tolerance: float = 1e-3,
                              max_order: int = MAX_SYMMETRY_ORDER) -> int:
    """Rotational symmetry order of a polygon about its frame's origin.

    Parameters
    ----------
    vertices : array_like, shape (P, 2)
        Closed counter-clockwise polygon, metres, in a frame whose origin is the area centroid
        (the object frame).
    tolerance : float
        Largest distance (m) of a rotated vertex from the outline (and back) for the rotation
        to count as a symmetry.
    max_order : int
        Largest order tested (a disc reports ``max_order``).

    Returns
    -------
    int
        The largest k in ``[1, max_order]`` such that rotating by ``2 pi / k`` maps the outline
        onto itself; 1 if there is none.
    """
    v = Polygon(vertices, field="vertices").vertices
    if not tolerance > 0.0:
        raise ValueError(f"tolerance must be > 0, got {tolerance!r}")
    # A few vertices rotated first: their largest distance is at most that of all vertices, so
    # a rotation they already refute is refuted (the same answer; most k are refuted there).
    probe = np.arange(0, len(v), max(1, len(v) // SYMMETRY_PROBE_VERTICES))
    for k in range(int(max_order), 1, -1):
        c, s = math.cos(2.0 * math.pi / k), math.sin(2.0 * math.pi / k)
        rotated = v @ np.array([[c, s], [-s, c]])  # rows R(2 pi / k) v_i
        if np.abs(closest_point_on_polyline(v, rotated[probe])[2]).max() > tolerance:
            continue
        there = np.abs(closest_point_on_polyline(v, rotated)[2]).max()
        back = np.abs(closest_point_on_polyline(rotated, v)[2]).max()
        if max(there, back) <= tolerance:
            return k
    return 1
