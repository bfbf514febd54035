"""Procedural shapes (push_core.procedural): parametric classes, random polygons, the benchmark set.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from push_core.objects import load_object, object_from_dict
from push_core.procedural import (
    MIN_WIDTH,
    RANDOM_KINDS,
    SHAPE_CLASSES,
    benchmark_objects,
    centroid_inside_outline,
    convex_hull,
    cross,
    disc,
    ellipse,
    hull_width,
    l_shape,
    random_simple_polygon,
    rectangle,
    regular_polygon,
    shape_classes,
    t_shape,
    training_shape,
    u_shape,
    with_com_toward_edge,
)
from push_core.shapes import Ellipse

OBJECTS_DIR = Path(__file__).resolve().parents[2] / "benchmarks" / "objects"


def _inside(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    from matplotlib.path import Path as MplPath

    return MplPath(vertices).contains_points(points)


# --- parametric shapes -----------------------------------------------------------------------
@pytest.mark.parametrize("spec, area", [
    (disc(0.05), math.pi * 0.05**2),
    (ellipse(0.06, 0.04), math.pi * 0.06 * 0.04),
    (regular_polygon(6, 0.05), 1.5 * math.sqrt(3) * 0.05**2),
    (rectangle(0.12, 0.05), 0.12 * 0.05),
    (l_shape(0.10, 0.08, 0.02), 0.10 * 0.02 + 0.02 * 0.06),
    (u_shape(0.10, 0.08, 0.02, 0.03), 0.10 * 0.08 - 0.06 * 0.05),
    (t_shape(0.10, 0.08, 0.02, 0.03), 0.10 * 0.02 + 0.03 * 0.06),
    (cross(0.12, 0.03, 0.10, 0.04), 0.12 * 0.03 + 0.10 * 0.04 - 0.03 * 0.04),
])
def test_parametric_shapes_have_their_area_and_are_centred(spec, area):
    obj = object_from_dict(spec)
    assert obj.area == pytest.approx(area, rel=1e-6)
    assert obj.thickness == 0.013 and obj.mass == pytest.approx(7900.0 * area * 0.013, rel=1e-6)
    np.testing.assert_allclose(obj.source_origin, 0.0, atol=1e-7)  # vertices about the centroid
    np.testing.assert_allclose(obj.com, 0.0, atol=1e-7)


def test_u_centroid_is_outside_the_footprint_t_and_cross_inside():
    u = object_from_dict(u_shape(0.12, 0.10, 0.03))
    assert not u.shape.is_convex and not centroid_inside_outline(u.shape.vertices)
    # By hand: base 0.12 x 0.03 at y = 0.015, arms 2 x 0.03 x 0.07 at y = 0.065 (source frame).
    cy = (0.0036 * 0.015 + 0.0042 * 0.065) / 0.0078
    np.testing.assert_allclose(u.shape.vertices.min(axis=0), [-0.06, -cy], atol=1e-7)
    assert not centroid_inside_outline(object_from_dict(l_shape(0.15, 0.10, 0.025))
                                       .shape.vertices)
    for spec in (t_shape(0.12, 0.10, 0.035), cross(0.13, 0.04)):
        assert centroid_inside_outline(object_from_dict(spec).shape.vertices)


def test_regular_polygon_vertices_on_the_circle():
    obj = object_from_dict(regular_polygon(5, 0.06))
    np.testing.assert_allclose(np.linalg.norm(obj.shape.vertices, axis=1), 0.06, atol=1e-7)
    assert obj.shape.is_convex and len(obj.shape.vertices) == 5


@pytest.mark.parametrize("call, field", [
    (lambda: disc(0.0), "radius"),
    (lambda: ellipse(0.05, -1.0), "b"),
    (lambda: regular_polygon(2, 0.05), "n_sides"),
    (lambda: regular_polygon(4.5, 0.05), "n_sides"),
    (lambda: rectangle(float("nan"), 0.05), "length"),
    (lambda: l_shape(0.1, 0.08, 0.09), "bar_width"),
    (lambda: u_shape(0.1, 0.08, 0.05), "arm_width"),
    (lambda: t_shape(0.1, 0.08, 0.02, 0.1), "bar_width"),
    (lambda: cross(0.1, 0.12), "arm_width"),
    (lambda: with_com_toward_edge(rectangle(0.1, 0.05), 1.0, 0.0), "fraction"),
    (lambda: with_com_toward_edge(u_shape(0.1, 0.08, 0.02), 0.5, 0.0), "spec"),
])
def test_bad_parameters_raise_naming_them(call, field):
    with pytest.raises(ValueError, match=rf"^{field}"):
        call()


def test_com_toward_edge_by_hand():
    spec = with_com_toward_edge(rectangle(0.12, 0.08), 0.85, 0.0)
    np.testing.assert_allclose(object_from_dict(spec).com, [0.85 * 0.06, 0.0], atol=1e-7)
    # 45 deg in a 12 x 8 cm rectangle: the ray leaves through the top edge at y = 4 cm.
    spec = with_com_toward_edge(rectangle(0.12, 0.08), 0.5, math.pi / 4)
    np.testing.assert_allclose(object_from_dict(spec).com, [0.02, 0.02], atol=1e-7)
    spec = with_com_toward_edge(ellipse(0.07, 0.045), 0.9, math.pi / 2)
    np.testing.assert_allclose(object_from_dict(spec).com, [0.0, 0.9 * 0.045], atol=1e-7)
    # com_offset is in the vertices' frame: an off-centre source polygon keeps its offset.
    shifted = {**rectangle(0.12, 0.08)}
    shifted["shape"] = {"type": "polygon",
                        "vertices": (np.array(shifted["shape"]["vertices"]) + 0.3).tolist()}
    spec = with_com_toward_edge(shifted, 0.5, 0.0)
    np.testing.assert_allclose(spec["com_offset"], [0.33, 0.3], atol=1e-7)
    np.testing.assert_allclose(object_from_dict(spec).com, [0.03, 0.0], atol=1e-7)


def test_hull_width_by_hand():
    assert hull_width(np.array([[0, 0], [0.1, 0], [0.1, 0.04], [0, 0.04]])) == \
        pytest.approx(0.04)
    assert hull_width(np.array([[0, 0], [1, 0], [0.5, 0.5], [0.5, 0.1]])) == pytest.approx(0.5)
    # An equilateral triangle of side 1: its height.
    tri = np.array([[0, 0], [1, 0], [0.5, math.sqrt(3) / 2]])
    assert hull_width(tri) == pytest.approx(math.sqrt(3) / 2)


def test_convex_hull_is_ccw_and_drops_inner_and_collinear_points():
    pts = np.array([[0, 0], [1, 0], [2, 0], [2, 2], [0, 2], [1, 1], [0.5, 1.5]], dtype=float)
    np.testing.assert_array_equal(convex_hull(pts), [[0, 0], [2, 0], [2, 2], [0, 2]])


# --- random shapes ---------------------------------------------------------------------------
def test_random_simple_polygons_are_valid_sized_and_cover_every_kind():
    rng = np.random.default_rng(11)
    seen: dict[str, list] = {k: [] for k in RANDOM_KINDS}
    for i in range(len(RANDOM_KINDS) * 25):
        kind = RANDOM_KINDS[i % len(RANDOM_KINDS)]
        obj = object_from_dict(random_simple_polygon(rng, kind))
        extent = np.ptp(obj.polyline(), axis=0).max()
        assert 0.05 - 1e-6 <= extent <= 0.18 + 1e-6
        assert obj.thickness == 0.013
        assert isinstance(obj.shape, Ellipse) or hull_width(obj.shape.vertices) >= MIN_WIDTH
        seen[kind].append(obj)
    for kind in ("star", "ell", "u", "cross", "radial"):
        assert sum(not o.shape.is_convex for o in seen[kind]) >= 15, kind
    assert all(o.shape.is_convex for o in seen["convex"] + seen["ellipse"])
    discs = [o for o in seen["ellipse"] if o.shape.a == o.shape.b]
    assert 1 <= len(discs) <= 15
    # Most U shapes have their centroid outside the footprint.
    assert sum(not centroid_inside_outline(o.shape.vertices) for o in seen["u"]) >= 15
    # Drawn kind, same seed: the same shapes.
    a = random_simple_polygon(np.random.default_rng(5), size_range=(0.08, 0.1))
    b = random_simple_polygon(np.random.default_rng(5), size_range=(0.08, 0.1))
    assert a == b
    with pytest.raises(ValueError, match="^kind"):
        random_simple_polygon(rng, "torus")
    with pytest.raises(ValueError, match="^size_range"):
        random_simple_polygon(rng, "convex", size_range=(0.1, 0.05))


def _digest(shapes: list) -> str:
    def rnd(x):
        if isinstance(x, float):
            return round(x, 9)
        if isinstance(x, list):
            return [rnd(v) for v in x]
        if isinstance(x, dict):
            return {k: rnd(v) for k, v in x.items()}
        return x

    return hashlib.sha256(json.dumps(rnd(shapes), sort_keys=True).encode()).hexdigest()[:16]


def test_training_shapes_keep_the_draws_of_the_generated_training_data():
    # Digest computed with pushbot.experiments.perception_data.random_shape (then
    # push_perception.data) as it was when the segmentation and affordance training data were
    # generated (before the object library accepted centroids outside the footprint). Seed 3 draws
    # an L shape whose centroid is outside: the old rule rejected it, and so must training_shape.
    rng = np.random.default_rng(3)
    kinds = (None, "convex", "ellipse", "star", "blob", "ell", None, "ell", "ell")
    shapes = [training_shape(rng, k) for k in kinds] + [float(rng.random())]
    assert _digest(shapes) == "a01a39cf8ccd5eb6"


# --- the benchmark set -----------------------------------------------------------------------
def test_benchmark_set_has_every_class_unique_names_and_mit_like_sizes():
    bench = benchmark_objects(0)
    assert tuple(bench) == shape_classes() == SHAPE_CLASSES
    names = [s["name"] for specs in bench.values() for s in specs]
    assert len(names) == len(set(names))
    for cls, specs in bench.items():
        assert 2 <= len(specs) <= 4, cls
        for spec in specs:
            obj = object_from_dict(spec)
            extent = np.ptp(obj.polyline(), axis=0).max()
            assert 0.05 <= extent <= 0.18 + 1e-9, spec["name"]
            assert 0.003 <= obj.area <= 0.014, spec["name"]
    for spec in bench["u_shape"]:
        assert not centroid_inside_outline(object_from_dict(spec).shape.vertices)
    for spec in bench["nonconvex"] + bench["l_shape"] + bench["t_shape"] + bench["cross"]:
        assert not object_from_dict(spec).shape.is_convex
    assert benchmark_objects(0) == bench and benchmark_objects(1) != bench


def test_com_edge_objects_have_the_com_80_to_90_percent_to_the_outline():
    for spec in benchmark_objects(0)["com_edge"]:
        obj = object_from_dict(spec)
        com = obj.com
        d = com / np.linalg.norm(com)
        if isinstance(obj.shape, Ellipse):
            reach = 1.0 / math.hypot(d[0] / obj.shape.a, d[1] / obj.shape.b)
        else:  # march along the ray to the outline
            s = np.linspace(0, 0.2, 200001)
            inside = _inside(s[:, None] * d, obj.shape.vertices)
            reach = s[np.argmin(inside)]
        assert 0.8 - 1e-3 <= np.linalg.norm(com) / reach <= 0.9 + 1e-3, spec["name"]


def test_committed_benchmark_spec_files_are_the_generated_set():
    bench = benchmark_objects(0)
    files = sorted(OBJECTS_DIR.glob("*/*.yaml"))
    assert len(files) == sum(len(v) for v in bench.values())
    for path in files:
        spec = next(s for s in bench[path.parent.name] if s["name"] == path.stem)
        assert yaml.safe_load(path.read_text()) == spec
        load_object(path)  # and every tool can load it
