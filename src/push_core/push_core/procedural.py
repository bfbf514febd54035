"""Procedural flat objects: object specification dicts for shape classes and random shapes.

ROS-free. Every generator returns the dict of an object specification file (format in
``docs/design/objects.md``), valid for
:func:`push_core.objects.object_from_dict`; write it as YAML or JSON to get a spec file that
every pushbot tool accepts as an object.

Frames and units: SI (metres, kg/m^3). The parametric generators centre their polygons on the
area centroid, so a spec's ``com_offset`` is directly in the object frame. Thickness and
density default to the MIT pushing objects' 13 mm stainless-steel plates.

Shape classes (:func:`shape_classes`, :func:`benchmark_objects`): discs, ellipses, regular
polygons, rectangles, L, U and T shapes, crosses, other non-convex polygons (stars, blobs,
random radial polygons) and ``com_edge``: convex shapes whose COM lies 80-90 % of the way from
the area centroid to the outline. The U shapes (and thin-armed L shapes) have their area centroid
outside the footprint; the object library accepts them because the COM only has to lie inside
the convex hull.

Random shapes: :func:`random_simple_polygon` (the any-shape tests and benchmarks) and
:func:`training_shape` (the perception and affordance training data,
``pushbot.experiments.perception_data.random_shape``). ``training_shape`` is frozen: it keeps
the acceptance rule of the object library when the data were generated (area centroid inside
the outline) and its random draws, so the committed training data stay reproducible.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_core.geometry import closest_point_on_polyline
from push_core.objects import object_from_dict
from push_core.shapes import Ellipse, Polygon

__all__ = [
    "DEFAULT_DENSITY",
    "DEFAULT_THICKNESS",
    "MIN_WIDTH",
    "RANDOM_KINDS",
    "SHAPE_CLASSES",
    "TRAINING_KINDS",
    "benchmark_objects",
    "centroid_inside_outline",
    "convex_hull",
    "cross",
    "disc",
    "ellipse",
    "hull_width",
    "l_shape",
    "object_dict",
    "random_simple_polygon",
    "rectangle",
    "regular_polygon",
    "shape_classes",
    "t_shape",
    "training_shape",
    "u_shape",
    "with_com_toward_edge",
]

#: Plate thickness of the MIT pushing objects, m.
DEFAULT_THICKNESS = 0.013
#: Stainless steel (the MIT objects: 7790-7950 kg/m^3 from their listed masses), kg/m^3.
DEFAULT_DENSITY = 7900.0
#: Shape families of :func:`training_shape` (the perception training data).
TRAINING_KINDS = ("convex", "ellipse", "star", "blob", "ell")
#: Shape families of :func:`random_simple_polygon`.
RANDOM_KINDS = ("convex", "ellipse", "star", "blob", "ell", "radial", "u", "cross")
#: The benchmark's shape classes, in table order.
SHAPE_CLASSES = ("disc", "ellipse", "polygon", "rectangle", "l_shape", "u_shape", "t_shape",
                 "cross", "nonconvex", "com_edge")
#: Narrowest accepted random shape (width of its convex hull in the thinnest direction), m:
#: the training family ``convex`` also draws needles 1.5 mm wide, which are no pushable flat
#: object (the pusher is 9.6 mm across).
MIN_WIDTH = 0.015
#: Decimals kept in generated coordinates (0.1 micrometre): readable spec files.
_DECIMALS = 7


# --------------------------------------------------------------------------------------------
# Spec dicts
# --------------------------------------------------------------------------------------------
def object_dict(shape: dict[str, Any], *, name: str | None = None,
                thickness: float = DEFAULT_THICKNESS, density: float = DEFAULT_DENSITY,
                com_offset: Any = None) -> dict[str, Any]:
    """An object specification dict around a ``shape`` mapping, validated.

    Parameters
    ----------
    shape : dict
        ``{"type": "polygon", "vertices": [[x, y], ...]}`` (counter-clockwise, m) or
        ``{"type": "ellipse", "semi_axes": [a, b]}`` (m).
    name : str, optional
        The spec's ``name`` field.
    thickness : float
        m, > 0.
    density : float
        kg/m^3, > 0 (the mass follows from the area).
    com_offset : (2,) array_like, optional
        Centre of mass relative to the vertices' origin, m; None: the area centroid.

    Returns
    -------
    dict

    Raises
    ------
    ValueError
        The spec is invalid (the message names the field).
    """
    spec: dict[str, Any] = {}
    if name is not None:
        spec["name"] = str(name)
    spec.update(shape=shape, thickness=float(thickness), density=float(density))
    if com_offset is not None:
        spec["com_offset"] = [round(float(v), _DECIMALS) for v in np.ravel(com_offset)]
    object_from_dict(spec, name=name or "object")
    return spec


def _polygon_dict(vertices: NDArray[np.float64], field: str, **kwargs: Any) -> dict[str, Any]:
    """Spec dict of a polygon re-centred on its area centroid (validated with ``field``)."""
    poly = Polygon(vertices, field=field)
    centred = np.round(poly.vertices - poly.centroid, _DECIMALS)
    return object_dict({"type": "polygon", "vertices": centred.tolist()}, **kwargs)


def _check_positive(**values: float) -> None:
    for key, value in values.items():
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{key}: must be > 0, got {value}")


# --------------------------------------------------------------------------------------------
# Parametric shapes
# --------------------------------------------------------------------------------------------
def disc(radius: float, **kwargs: Any) -> dict[str, Any]:
    """A disc (an ellipse with equal semi-axes) of ``radius`` m. ``kwargs``: :func:`object_dict`.
    """
    _check_positive(radius=radius)
    return object_dict({"type": "ellipse", "semi_axes": [float(radius)] * 2}, **kwargs)


def ellipse(a: float, b: float, **kwargs: Any) -> dict[str, Any]:
    """An ellipse with semi-axes ``a`` along x and ``b`` along y, m."""
    _check_positive(a=a, b=b)
    return object_dict({"type": "ellipse", "semi_axes": [float(a), float(b)]}, **kwargs)


def regular_polygon(n_sides: int, circumradius: float, **kwargs: Any) -> dict[str, Any]:
    """A regular polygon with ``n_sides`` >= 3 vertices on a circle of ``circumradius`` m,
    the first vertex on +x."""
    if isinstance(n_sides, bool) or int(n_sides) != n_sides or n_sides < 3:
        raise ValueError(f"n_sides: expected an integer >= 3, got {n_sides!r}")
    _check_positive(circumradius=circumradius)
    phi = 2 * np.pi * np.arange(int(n_sides)) / int(n_sides)
    return _polygon_dict(circumradius * np.stack([np.cos(phi), np.sin(phi)], axis=1),
                         "n_sides", **kwargs)


def rectangle(length: float, width: float, **kwargs: Any) -> dict[str, Any]:
    """A ``length`` (along x) by ``width`` (along y) rectangle, m."""
    _check_positive(length=length, width=width)
    x, y = length / 2, width / 2
    return _polygon_dict(np.array([[x, -y], [x, y], [-x, y], [-x, -y]]), "length", **kwargs)


def l_shape(length: float, width: float, bar_width: float, leg_width: float | None = None,
            **kwargs: Any) -> dict[str, Any]:
    """An L: a bar ``length`` x ``bar_width`` along x and a leg ``leg_width`` wide up to
    ``width`` along y at its -x end (m; ``leg_width`` defaults to ``bar_width``). Thin arms put
    the area centroid outside the footprint (about ``bar_width < 0.3 * min(length, width)``).
    """
    leg_width = bar_width if leg_width is None else leg_width
    _check_positive(length=length, width=width, bar_width=bar_width, leg_width=leg_width)
    if bar_width >= width or leg_width >= length:
        raise ValueError(f"bar_width, leg_width: must be < width and < length, got "
                         f"{bar_width}, {leg_width} for {length} x {width}")
    pts = np.array([[0, 0], [length, 0], [length, bar_width], [leg_width, bar_width],
                    [leg_width, width], [0, width]], dtype=float)
    return _polygon_dict(pts, "bar_width", **kwargs)


def u_shape(width: float, height: float, arm_width: float, base_width: float | None = None,
            **kwargs: Any) -> dict[str, Any]:
    """A U open towards +y: ``width`` (x) by ``height`` (y) overall, two arms ``arm_width``
    wide, the base ``base_width`` high (m; defaults to ``arm_width``). The area centroid lies
    in the gap (outside the footprint) unless the base is heavy."""
    base_width = arm_width if base_width is None else base_width
    _check_positive(width=width, height=height, arm_width=arm_width, base_width=base_width)
    if 2 * arm_width >= width or base_width >= height:
        raise ValueError(f"arm_width, base_width: need 2 arm_width < width and base_width < "
                         f"height, got {arm_width}, {base_width} for {width} x {height}")
    w, h, a, b = width, height, arm_width, base_width
    pts = np.array([[0, 0], [w, 0], [w, h], [w - a, h], [w - a, b], [a, b], [a, h], [0, h]],
                   dtype=float)
    return _polygon_dict(pts, "arm_width", **kwargs)


def t_shape(width: float, height: float, bar_width: float, stem_width: float | None = None,
            **kwargs: Any) -> dict[str, Any]:
    """A T: a bar ``width`` x ``bar_width`` at the top (+y) on a centred stem ``stem_width``
    wide, ``height`` overall (m; ``stem_width`` defaults to ``bar_width``)."""
    stem_width = bar_width if stem_width is None else stem_width
    _check_positive(width=width, height=height, bar_width=bar_width, stem_width=stem_width)
    if stem_width >= width or bar_width >= height:
        raise ValueError(f"bar_width, stem_width: need stem_width < width and bar_width < "
                         f"height, got {bar_width}, {stem_width} for {width} x {height}")
    a, b, top = (width - stem_width) / 2, (width + stem_width) / 2, height - bar_width
    pts = np.array([[a, 0], [b, 0], [b, top], [width, top], [width, height], [0, height],
                    [0, top], [a, top]], dtype=float)
    return _polygon_dict(pts, "bar_width", **kwargs)


def cross(span: float, arm_width: float, span_y: float | None = None,
          arm_width_y: float | None = None, **kwargs: Any) -> dict[str, Any]:
    """A plus-shaped cross: an arm ``span`` long (x) and ``arm_width`` wide, crossed at its
    centre by one ``span_y`` long (y) and ``arm_width_y`` wide (m; default: the same)."""
    span_y = span if span_y is None else span_y
    arm_width_y = arm_width if arm_width_y is None else arm_width_y
    _check_positive(span=span, arm_width=arm_width, span_y=span_y, arm_width_y=arm_width_y)
    if arm_width_y >= span or arm_width >= span_y:
        raise ValueError(f"arm_width, arm_width_y: each arm must be narrower than the other's "
                         f"span, got {arm_width}, {arm_width_y} for {span} x {span_y}")
    x, y, p, q = span / 2, span_y / 2, arm_width_y / 2, arm_width / 2
    pts = np.array([[p, -q], [x, -q], [x, q], [p, q], [p, y], [-p, y], [-p, q], [-x, q],
                    [-x, -q], [-p, -q], [-p, -y], [p, -y]], dtype=float)
    return _polygon_dict(pts, "arm_width", **kwargs)


def with_com_toward_edge(spec: dict[str, Any], fraction: float,
                         angle: float) -> dict[str, Any]:
    """A copy of ``spec`` whose COM lies ``fraction`` of the way from the area centroid to the
    outline, in the direction ``angle`` (radians, object frame).

    Parameters
    ----------
    spec : dict
        An object specification dict whose area centroid lies inside its outline.
    fraction : float
        In [0, 1).
    angle : float
        Direction of the COM from the centroid, radians.

    Returns
    -------
    dict
        With ``com_offset`` set (relative to the vertices' own origin, as the format says).
    """
    if not (np.isfinite(fraction) and 0 <= fraction < 1):
        raise ValueError(f"fraction: must be in [0, 1), got {fraction}")
    obj = object_from_dict(spec)
    direction = np.array([math.cos(angle), math.sin(angle)])
    if isinstance(obj.shape, Ellipse):
        reach = 1.0 / math.hypot(direction[0] / obj.shape.a, direction[1] / obj.shape.b)
    else:
        if not centroid_inside_outline(obj.shape.vertices):
            raise ValueError("spec: the area centroid lies outside the outline, there is no "
                             "edge to move the COM towards")
        reach = _ray_exit(obj.shape.vertices, direction)
    com = fraction * reach * direction - obj.source_origin  # back to the vertices' frame
    return {**spec, "com_offset": [round(float(v), _DECIMALS) for v in com]}


def _ray_exit(vertices: NDArray[np.float64], direction: NDArray[np.float64]) -> float:
    """Distance from the origin (inside the polygon) along ``direction`` to the first edge."""
    a = vertices
    e = np.roll(vertices, -1, axis=0) - a
    den = direction[0] * e[:, 1] - direction[1] * e[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a[:, 0] * e[:, 1] - a[:, 1] * e[:, 0]) / den  # along the ray
        s = (a[:, 0] * direction[1] - a[:, 1] * direction[0]) / den  # along the edge
    hit = (np.abs(den) > 1e-15) & (t > 0) & (s >= 0) & (s <= 1)
    return float(np.min(t[hit]))


# --------------------------------------------------------------------------------------------
# Random shapes
# --------------------------------------------------------------------------------------------
def training_shape(rng: np.random.Generator, kind: str | None = None) -> dict[str, Any]:
    """A random object specification of the perception/affordance training data.

    Frozen (module docstring): ``pushbot.experiments.perception_data.random_shape`` is this
    function, and the committed training sets were drawn with it. A candidate is accepted when
    the object library accepts it *and* its area centroid lies inside its outline (the
    library's rule then), so the draws are the same as before the library accepted L/U shapes.

    Parameters
    ----------
    rng : numpy.random.Generator
    kind : {"convex", "ellipse", "star", "blob", "ell"}, optional
        Shape family; drawn uniformly when None. ``star``: star-shaped polygon with 5-12
        vertices, every other one pulled inward (non-convex); ``blob``: 72-vertex smooth
        outline from a random radial Fourier series (waists like butter's); ``ell``: L- or
        T-shaped polygon.

    Returns
    -------
    dict
        ``{"shape": ..., "thickness": ..., "density": ...}``, metres and kg/m^3, 5-18 cm
        across, 5-25 mm thick (validated; retried until valid).
    """
    kind = str(rng.choice(TRAINING_KINDS)) if kind is None else kind
    if kind not in TRAINING_KINDS:
        raise ValueError(f"kind: expected one of {TRAINING_KINDS}, got {kind!r}")
    thickness = float(rng.uniform(0.005, 0.025))
    density = float(rng.uniform(1000.0, 8000.0))
    for _ in range(100):
        size = float(rng.uniform(0.05, 0.18))  # overall extent, m
        if kind == "ellipse":
            a = size / 2
            shape: dict[str, Any] = {"type": "ellipse",
                                     "semi_axes": [a, a * float(rng.uniform(0.45, 1.0))]}
        else:
            shape = {"type": "polygon", "vertices": _random_polygon(rng, kind, size).tolist()}
        spec = {"shape": shape, "thickness": thickness, "density": density}
        try:
            object_from_dict(spec, name="candidate")
        except ValueError:
            continue
        if kind != "ellipse" and not centroid_inside_outline(np.array(shape["vertices"])):
            continue
        return spec
    raise RuntimeError(f"could not draw a valid {kind} shape in 100 tries")  # pragma: no cover


def random_simple_polygon(rng: np.random.Generator, kind: str | None = None, *,
                          size_range: tuple[float, float] = (0.05, 0.18),
                          thickness: float = DEFAULT_THICKNESS,
                          density: float = DEFAULT_DENSITY) -> dict[str, Any]:
    """A random simple polygon (convex or not) or ellipse as an object specification dict.

    Parameters
    ----------
    rng : numpy.random.Generator
    kind : str, optional
        One of :data:`RANDOM_KINDS`, drawn uniformly when None: the :func:`training_shape`
        families (``ell``: L or T), ``radial`` (4-14 vertices at sorted random angles and
        random radii 0.3-1: any mix of convex and reflex corners), ``u`` and ``cross`` (random
        proportions; a U's centroid is usually outside its footprint). ``ellipse`` has
        semi-axis ratio 0.45-1 and is an exact disc one time in five. Polygons narrower than
        :data:`MIN_WIDTH` (:func:`hull_width`) are drawn again.
    size_range : (float, float)
        Overall extent (largest side of the bounding box), m.
    thickness, density : float
        m and kg/m^3.

    Returns
    -------
    dict
        A valid object specification (retried until :func:`object_from_dict` accepts it).
    """
    kind = str(rng.choice(RANDOM_KINDS)) if kind is None else kind
    if kind not in RANDOM_KINDS:
        raise ValueError(f"kind: expected one of {RANDOM_KINDS}, got {kind!r}")
    lo, hi = size_range
    if not (0 < lo <= hi):
        raise ValueError(f"size_range: expected 0 < low <= high, got {size_range}")
    for _ in range(100):
        size = float(rng.uniform(lo, hi))
        if kind == "ellipse":
            ratio = 1.0 if rng.random() < 0.2 else float(rng.uniform(0.45, 1.0))
            shape: dict[str, Any] = {"type": "ellipse",
                                     "semi_axes": [size / 2, size / 2 * ratio]}
        else:
            pts = _random_polygon(rng, kind, size)
            if hull_width(pts) < MIN_WIDTH:
                continue
            shape = {"type": "polygon", "vertices": np.round(pts, _DECIMALS).tolist()}
        try:
            return object_dict(shape, thickness=thickness, density=density)
        except ValueError:
            continue
    raise RuntimeError(f"could not draw a valid {kind} shape in 100 tries")  # pragma: no cover


def _random_polygon(rng: np.random.Generator, kind: str, size: float) -> NDArray[np.float64]:
    """Vertices (counter-clockwise) of a random polygon of family ``kind``, ``size`` m across.
    The families of :data:`TRAINING_KINDS` keep their draws (see :func:`training_shape`)."""
    if kind == "convex":
        n = int(rng.integers(3, 9))
        angles = np.sort(rng.uniform(0, 2 * np.pi, n))
        pts = np.stack([np.cos(angles), np.sin(angles)], axis=1) * rng.uniform(0.6, 1.0, (n, 1))
        pts *= np.array([1.0, rng.uniform(0.5, 1.0)])
        hull = convex_hull(pts)
        return _scaled(hull, size)
    if kind == "star":
        n = int(rng.integers(5, 13))
        # Evenly spread angles with a little jitter: neighbours stay apart (no slivers).
        angles = np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(-0.3, 0.3, n) / n
        radii = rng.uniform(0.75, 1.0, n)
        radii[1::2] = rng.uniform(0.35, 0.75, n // 2)  # every other vertex inward: reflex
        return _scaled(np.stack([np.cos(angles), np.sin(angles)], axis=1) * radii[:, None], size)
    if kind == "blob":
        phi = np.linspace(0, 2 * np.pi, 72, endpoint=False)
        r = np.ones_like(phi)
        for k in range(2, 5):
            r += rng.uniform(0.0, 0.22 / (k - 1)) * np.cos(k * phi + rng.uniform(0, 2 * np.pi))
        pts = np.stack([np.cos(phi), np.sin(phi)], axis=1) * r[:, None]
        pts *= np.array([1.0, rng.uniform(0.55, 1.0)])
        return _scaled(pts, size)
    if kind == "radial":
        n = int(rng.integers(4, 15))
        # Sorted angles at least a quarter of the mean spacing apart: simple, no slivers.
        gaps = rng.uniform(0.25, 1.0, n)
        angles = np.cumsum(gaps) / gaps.sum() * 2 * np.pi + rng.uniform(0, 2 * np.pi)
        radii = rng.uniform(0.3, 1.0, n)
        return _scaled(np.stack([np.cos(angles), np.sin(angles)], axis=1) * radii[:, None], size)
    if kind == "u":
        arm, base = rng.uniform(0.15, 0.35), rng.uniform(0.15, 0.45)
        pts = np.array([[0, 0], [1, 0], [1, 1], [1 - arm, 1], [1 - arm, base], [arm, base],
                        [arm, 1], [0, 1]], dtype=float)
        pts[:, 1] *= rng.uniform(0.6, 1.3)
        return _scaled(pts - pts.mean(axis=0), size)
    if kind == "cross":
        p, q = rng.uniform(0.1, 0.25), rng.uniform(0.1, 0.25)  # half arm widths
        c = rng.uniform(-0.2, 0.2, 2)  # where the arms cross
        pts = np.array([[p, -q], [1, -q], [1, q], [p, q], [p, 1], [-p, 1], [-p, q], [-1, q],
                        [-1, -q], [-p, -q], [-p, -1], [p, -1]], dtype=float)
        pts[np.abs(pts[:, 0]) < 1, 0] += c[0]
        pts[np.abs(pts[:, 1]) < 1, 1] += c[1]
        pts[:, 1] *= rng.uniform(0.6, 1.0)
        return _scaled(pts, size)
    if kind != "ell":
        raise ValueError(f"kind: unknown polygon family {kind!r}")
    # L or T shape from a bar and a stem, counter-clockwise.
    w1, w2 = rng.uniform(0.25, 0.45), rng.uniform(0.25, 0.45)
    if rng.random() < 0.5:  # L
        pts = np.array([[0, 0], [1, 0], [1, w1], [w2, w1], [w2, 1], [0, 1]], dtype=float)
    else:  # T
        a, b = 0.5 - w2 / 2, 0.5 + w2 / 2
        pts = np.array([[a, 0], [b, 0], [b, 1 - w1], [1, 1 - w1], [1, 1], [0, 1], [0, 1 - w1],
                        [a, 1 - w1]], dtype=float)
    pts[:, 1] *= rng.uniform(0.6, 1.2)
    return _scaled(pts - pts.mean(axis=0), size)


def _scaled(pts: NDArray[np.float64], size: float) -> NDArray[np.float64]:
    extent = float(np.max(np.ptp(pts, axis=0)))
    return pts * (size / extent)


def convex_hull(pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """Counter-clockwise convex hull (Andrew's monotone chain) of points (N, 2), starting at
    the lexicographically smallest point; collinear points are dropped."""
    order = np.lexsort((pts[:, 1], pts[:, 0]))
    p = pts[order]

    def half(points: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        out: list[NDArray[np.float64]] = []
        for q in points:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (q[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (q[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(q)
        return out

    lower, upper = half(p), half(p[::-1])
    return np.array(lower[:-1] + upper[:-1])


def hull_width(pts: NDArray[np.float64]) -> float:
    """Width of the convex hull of points (N, 2) in its thinnest direction, m (the smallest
    gap between two parallel lines enclosing the points: attained across one hull edge)."""
    hull = convex_hull(np.asarray(pts, dtype=float))
    edges = np.roll(hull, -1, axis=0) - hull
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    # Hull edge e: every vertex lies on its inner side; the deepest one sets the width.
    depth = np.einsum("ekd,ed->ek", hull[None, :, :] - hull[:, None, :], normals)
    return float(np.min(np.max(-depth, axis=1)))


def centroid_inside_outline(vertices: NDArray[np.float64]) -> bool:
    """Whether the area centroid of a simple counter-clockwise polygon (P, 2) lies strictly
    inside it (false for most U shapes and thin-armed L shapes)."""
    poly = Polygon(vertices)
    return bool(closest_point_on_polyline(poly.vertices, poly.centroid)[2] < 0.0)


# --------------------------------------------------------------------------------------------
# The benchmark set
# --------------------------------------------------------------------------------------------
def shape_classes() -> tuple[str, ...]:
    """The benchmark's shape classes (:data:`SHAPE_CLASSES`), in table order."""
    return SHAPE_CLASSES


def _area_matched(aspect: float, area: float, longest: float) -> tuple[float, float]:
    """(length, width) of a rectangle of ``aspect`` and ``area``, shrunk to ``longest``."""
    width = math.sqrt(area / aspect)
    length = aspect * width
    if length > longest:
        length, width = longest, longest / aspect
    return length, width


def benchmark_objects(seed: int = 0) -> dict[str, list[dict[str, Any]]]:
    """The shape-class benchmark set: class -> object specification dicts (with ``name``).

    Sizes follow the MIT pushing objects (9-16 cm across, 80-130 cm^2, 13 mm steel) and stay
    within 18 cm. Random members (``nonconvex``, the COM directions of ``com_edge``) are drawn
    from ``numpy.random.default_rng([seed, class index])``, so each class is reproducible on
    its own.

    Parameters
    ----------
    seed : int
        >= 0.

    Returns
    -------
    dict
        ``{class: [spec, ...]}`` for every class of :func:`shape_classes`, 2-4 specs each;
        names are unique over the whole set.
    """
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"seed: expected an integer >= 0, got {seed!r}")
    rng = {c: np.random.default_rng([int(seed), i]) for i, c in enumerate(SHAPE_CLASSES)}
    area = 0.01  # m^2, about the MIT objects' 80-130 cm^2
    out: dict[str, list[dict[str, Any]]] = {c: [] for c in SHAPE_CLASSES}
    out["disc"] = [disc(r / 1000, name=f"disc_r{r}") for r in (35, 50, 65)]
    for ratio in (1.3, 1.7, 2.2):
        b = math.sqrt(area / (math.pi * ratio))
        out["ellipse"].append(ellipse(ratio * b, b, name=f"ellipse_ar{round(ratio * 10)}"))
    for n in (3, 5, 6, 8):  # circumradius for an area of 90 cm^2
        radius = math.sqrt(2 * 0.009 / (n * math.sin(2 * math.pi / n)))
        out["polygon"].append(regular_polygon(n, radius, name=f"polygon_n{n}"))
    for aspect in (1.5, 3.0, 6.0):
        length, width = _area_matched(aspect, area, 0.18)
        out["rectangle"].append(rectangle(length, width, name=f"rect_ar{round(aspect * 10)}"))
    out["l_shape"] = [l_shape(0.12, 0.12, 0.04, name="l_12x12_w40"),  # centroid outside
                      l_shape(0.15, 0.10, 0.025, name="l_15x10_w25"),  # centroid outside
                      l_shape(0.16, 0.08, 0.035, 0.05, name="l_16x8_w35")]  # inside
    out["u_shape"] = [u_shape(0.12, 0.10, 0.03, name="u_12x10_w30"),  # all: centroid outside
                      u_shape(0.15, 0.09, 0.025, 0.03, name="u_15x9_w25"),
                      u_shape(0.10, 0.12, 0.025, name="u_10x12_w25")]
    out["t_shape"] = [t_shape(0.12, 0.10, 0.035, 0.035, name="t_12x10_w35"),
                      t_shape(0.15, 0.12, 0.03, 0.04, name="t_15x12_w30"),
                      t_shape(0.10, 0.14, 0.04, 0.03, name="t_10x14_w40")]
    out["cross"] = [cross(0.13, 0.04, name="cross_13_w40"),
                    cross(0.15, 0.03, 0.11, 0.045, name="cross_15x11_w30")]
    r = rng["nonconvex"]
    for i, kind in enumerate(("star", "blob", "radial", "radial")):
        for _ in range(100):  # these families are non-convex nearly always
            spec = random_simple_polygon(r, kind, size_range=(0.10, 0.16))
            if not object_from_dict(spec).shape.is_convex:
                break
        else:  # pragma: no cover
            raise RuntimeError(f"no non-convex {kind} shape in 100 draws")
        out["nonconvex"].append({"name": f"nonconvex_{kind}{i}", **spec})
    r = rng["com_edge"]
    for name, base, fraction in (
            ("com_edge_rect", rectangle(0.12, 0.08), 0.85),
            ("com_edge_tri", regular_polygon(3, 0.075), 0.8),
            ("com_edge_ellipse", ellipse(0.07, 0.045), 0.9)):
        out["com_edge"].append({"name": name, **with_com_toward_edge(
            base, fraction, float(r.uniform(0, 2 * np.pi)))})
    return out
