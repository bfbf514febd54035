"""Object library, object specification files and shape geometry (push_core.objects/shapes)."""

import json

import numpy as np
import pytest

from push_core.objects import TEST_OBJECTS, load_object, object_from_dict
from push_core.objects import library_names as names
from push_core.shapes import Ellipse, Polygon, polygon_signed_area

SQUARE = [[0.05, 0.05], [-0.05, 0.05], [-0.05, -0.05], [0.05, -0.05]]


def _spec(**over):
    base = {"shape": {"type": "polygon", "vertices": SQUARE}, "thickness": 0.013, "mass": 0.5}
    base.update(over)
    return base


# --- library ---------------------------------------------------------------------------------


def test_library_has_the_mit_objects_and_the_held_out_ones():
    lib = names()
    assert {"rect1", "rect2", "rect3", "tri1", "tri2", "tri3", "ellip1", "ellip2", "ellip3",
            "hex", "butter"} == set(lib)
    assert set(TEST_OBJECTS) <= set(lib)


@pytest.mark.parametrize("name", ["rect1", "rect2", "rect3", "tri1", "tri2", "tri3", "ellip1",
                                  "ellip2", "ellip3", "butter"])
def test_uniform_density_inertia_matches_the_dataset_measurement(name):
    # The dataset lists measured moments of inertia about the vertical axis through the
    # centroid; uniform steel plates of the listed mass and outline must agree within 1 %.
    raw = json.loads(
        (__import__("importlib.resources").resources.files("push_core") / "data"
         / "mit_push_objects.json").read_text()
    )["objects"][name]
    spec = load_object(name)
    assert spec.moment_of_inertia == pytest.approx(raw["moment_of_inertia_kgm2"], rel=0.01)


def test_library_shapes_are_centred_on_their_area_centroid():
    for name in names():
        spec = load_object(name)
        np.testing.assert_allclose(spec.shape.centroid, 0.0, atol=1e-12)
        np.testing.assert_allclose(spec.com, 0.0, atol=1e-12)


def test_tri1_source_origin_matches_the_dataset_centroid():
    # The dataset gives tri1's centre of area (0.00303333, 0.00306333) in its own frame; our
    # object frame sits there, so the dataset origin is at minus that vector (to 0.05 mm:
    # the dataset rounds its vertices).
    spec = load_object("tri1")
    np.testing.assert_allclose(spec.source_origin, [-0.00303333, -0.00306333], atol=5e-5)


def test_rect1_area_and_outline_by_hand():
    spec = load_object("rect1")
    assert spec.area == pytest.approx(0.09 * 0.09)
    pts, nrm = spec.outline(spacing=0.01)
    # 9 cm edges at 1 cm spacing: 9 points per edge at the sub-interval centres.
    assert len(pts) == 36
    # Vertex order is (0.045, 0.045) -> (-0.045, 0.045): the first edge is the top edge, so
    # its first point is 0.5 cm from the first vertex along -x, with outward normal +y.
    np.testing.assert_allclose(pts[0], [0.04, 0.045])
    np.testing.assert_allclose(nrm[0], [0.0, 1.0])
    np.testing.assert_allclose(nrm[9], [-1.0, 0.0])  # second edge: the -x side


def test_limit_surface_guess_of_a_disc_is_two_thirds_of_the_radius():
    # l = mean distance of the area from the COM = integral r * 2 pi r dr / (pi R^2) = 2R/3.
    spec = load_object("ellip1")  # a disc, R = 52.5 mm
    assert spec.limit_surface_guess() == pytest.approx(2 * 0.0525 / 3, rel=0.01)


def test_limit_surface_guess_of_a_square_by_hand():
    # Mean distance from the centre of a square of side s: s * (sqrt(2) + asinh(1)) / 6
    # = 0.382598 s.
    spec = load_object("rect1")
    assert spec.limit_surface_guess(n=200000) == pytest.approx(0.382598 * 0.09, rel=0.005)


def test_com_offset_moves_inertia_by_the_parallel_axis_theorem():
    spec = load_object("rect1")
    moved = spec.replace(com=np.array([0.01, -0.02]))
    assert moved.moment_of_inertia == pytest.approx(
        spec.moment_of_inertia + spec.mass * (0.01**2 + 0.02**2)
    )


# --- specification files ---------------------------------------------------------------------


def test_json_and_yaml_spec_files_load_by_path(tmp_path):
    spec = _spec(name="box", com_offset=[0.01, 0.0], friction_table=0.3)
    j = tmp_path / "box.json"
    j.write_text(json.dumps(spec))
    y = tmp_path / "box.yaml"
    y.write_text(
        "shape:\n  type: polygon\n  vertices: [[0.05, 0.05], [-0.05, 0.05], [-0.05, -0.05], "
        "[0.05, -0.05]]\nthickness: 0.013\nmass: 0.5\ncom_offset: [0.01, 0.0]\n"
        "friction_table: 0.3\n"
    )
    a, b = load_object(j), load_object(str(y))
    assert a.name == "box" and b.name == "box"  # name field, and file stem
    for s in (a, b):
        assert s.mass == 0.5 and s.friction_table == 0.3 and s.friction_pusher == 0.25
        np.testing.assert_allclose(s.com, [0.01, 0.0])


def test_offset_polygon_is_recentred_and_com_follows(tmp_path):
    verts = (np.array(SQUARE) + [0.2, 0.1]).tolist()
    s = object_from_dict(_spec(shape={"type": "polygon", "vertices": verts},
                               com_offset=[0.21, 0.1]))
    np.testing.assert_allclose(s.shape.centroid, 0.0, atol=1e-12)
    np.testing.assert_allclose(s.com, [0.01, 0.0], atol=1e-12)
    np.testing.assert_allclose(s.source_origin, [-0.2, -0.1], atol=1e-12)


def test_density_gives_mass():
    s = object_from_dict({"shape": {"type": "ellipse", "semi_axes": [0.05, 0.03]},
                          "thickness": 0.01, "density": 1000.0})
    assert s.mass == pytest.approx(1000.0 * np.pi * 0.05 * 0.03 * 0.01)


@pytest.mark.parametrize(
    "change, field",
    [
        ({"shape": None}, "shape"),
        ({"thickness": None}, "thickness"),
        ({"thickness": 0.0}, "thickness"),
        ({"thickness": -1.0}, "thickness"),
        ({"mass": 0.0}, "mass"),
        ({"mass": "heavy"}, "mass"),
        ({"density": 100.0}, "mass"),  # both mass and density
        ({"friction_table": -0.1}, "friction_table"),
        ({"friction_pusher": float("nan")}, "friction_pusher"),
        ({"com_offset": [0.2, 0.0]}, "com_offset"),
        ({"com_offset": [0.0]}, "com_offset"),
        ({"colour": "red"}, "colour"),
        ({"shape": {"type": "blob"}}, "shape.type"),
        ({"shape": {"vertices": SQUARE}}, "shape.type"),
        ({"shape": {"type": "polygon"}}, "shape.vertices"),
        ({"shape": {"type": "polygon", "vertices": SQUARE[::-1]}}, "shape.vertices"),
        ({"shape": {"type": "polygon", "vertices": SQUARE[:2]}}, "shape.vertices"),
        ({"shape": {"type": "ellipse", "semi_axes": [0.05, -0.01]}}, "shape.semi_axes"),
        ({"shape": {"type": "ellipse"}}, "shape.semi_axes"),
    ],
)
def test_bad_specs_raise_value_error_naming_the_field(change, field):
    spec = _spec()
    spec.update(change)
    if change.get("shape", 1) is None:
        del spec["shape"]
    if change.get("thickness", 1) is None:
        del spec["thickness"]
    with pytest.raises(ValueError, match=rf"^{field}:"):
        object_from_dict(spec)


def test_missing_mass_and_density_names_mass():
    spec = _spec()
    del spec["mass"]
    with pytest.raises(ValueError, match=r"^mass: give exactly one"):
        object_from_dict(spec)


def test_clockwise_and_self_intersecting_polygons_say_so():
    with pytest.raises(ValueError, match="clockwise"):
        Polygon(SQUARE[::-1], field="shape.vertices")
    bowtie = [[0.05, 0.05], [-0.05, -0.05], [-0.05, 0.05], [0.05, -0.05]]
    with pytest.raises(ValueError, match=r"^shape.vertices: polygon is self-intersecting"):
        Polygon(bowtie, field="shape.vertices")
    # A vertex touching a non-adjacent edge is not simple either.
    touching = [[0, 0], [2, 0], [2, 2], [1, 0], [0, 2]]
    with pytest.raises(ValueError, match="self-intersecting"):
        Polygon(touching)


def test_unknown_name_and_bad_files_raise_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="unknown object 'cube'.*rect1"):
        load_object("cube")
    with pytest.raises(ValueError, match="does not exist"):
        load_object(tmp_path / "missing.yaml")
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(ValueError, match="cannot parse"):
        load_object(broken)
    listy = tmp_path / "list.yaml"
    listy.write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match="must be a mapping"):
        load_object(listy)


# --- shapes ----------------------------------------------------------------------------------


def _on_polygon_boundary(points, vertices):
    a = vertices
    b = np.roll(vertices, -1, axis=0)
    d = b - a
    t = np.clip(np.einsum("pkd,kd->pk", points[:, None] - a, d) / np.sum(d * d, 1), 0, 1)
    closest = a + t[..., None] * d
    return np.min(np.linalg.norm(points[:, None] - closest, axis=2), axis=1)


def _inside_even_odd(points, vertices):
    from matplotlib.path import Path

    return Path(vertices).contains_points(points)


@pytest.mark.parametrize("name", ["rect1", "tri1", "hex", "butter", "ellip2"])
def test_outline_points_lie_on_the_boundary_with_outward_unit_normals(name):
    spec = load_object(name)
    pts, nrm = spec.outline(spacing=0.002)
    poly = spec.shape.polyline()
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-9)
    # Ellipse points are exact on the ellipse, its polyline is a fine chordal approximation.
    assert np.max(_on_polygon_boundary(pts, poly)) < (1e-9 if name != "ellip2" else 5e-6)
    assert not np.any(_inside_even_odd(pts + 5e-4 * nrm, poly))
    assert np.all(_inside_even_odd(pts - 5e-4 * nrm, poly))
    assert polygon_signed_area(pts) > 0  # ordered counter-clockwise
    gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    assert np.median(gaps) == pytest.approx(0.002, rel=0.25)


def test_ellipse_outline_normals_by_hand():
    e = Ellipse(0.05, 0.03)
    pts, nrm = e.outline(0.001)
    # On x^2/a^2 + y^2/b^2 = 1 the outward normal is parallel to (x/a^2, y/b^2).
    np.testing.assert_allclose((pts[:, 0] / 0.05) ** 2 + (pts[:, 1] / 0.03) ** 2, 1.0, atol=1e-12)
    g = np.stack([pts[:, 0] / 0.05**2, pts[:, 1] / 0.03**2], axis=1)
    np.testing.assert_allclose(g[:, 0] * nrm[:, 1] - g[:, 1] * nrm[:, 0], 0.0, atol=1e-9)
    from scipy.integrate import quad

    exact, _ = quad(lambda t: np.hypot(0.05 * np.sin(t), 0.03 * np.cos(t)), 0, 2 * np.pi)
    assert e.perimeter == pytest.approx(exact, rel=1e-8)


@pytest.mark.parametrize("name", ["rect1", "tri1", "hex", "butter"])
def test_convex_pieces_are_convex_ccw_and_cover_the_area(name):
    spec = load_object(name)
    pieces = spec.shape.convex_pieces()
    total = 0.0
    for piece in pieces:
        p = Polygon(piece)  # validates CCW and simple
        assert p.is_convex
        total += p.area
    assert total == pytest.approx(spec.area, rel=2e-3)


def test_butter_is_decomposed_not_hulled():
    from scipy.spatial import ConvexHull

    spec = load_object("butter")
    pieces = spec.shape.convex_pieces()
    assert len(pieces) > 1
    hull_area = ConvexHull(spec.shape.vertices).volume
    assert hull_area > 1.05 * spec.area  # the waist: the hull would fill it in
    # A point in the waist region (inside the hull, outside the outline) is in no piece.
    rng = np.random.default_rng(0)
    cand = rng.uniform(spec.shape.vertices.min(0), spec.shape.vertices.max(0), size=(4000, 2))
    hull = ConvexHull(spec.shape.vertices)
    in_hull = np.all(cand @ hull.equations[:, :2].T + hull.equations[:, 2] <= 0, axis=1)
    in_shape = _inside_even_odd(cand, spec.shape.vertices)
    waist = cand[in_hull & ~in_shape]
    assert len(waist) > 50
    in_any = np.zeros(len(waist), dtype=bool)
    for piece in pieces:
        in_any |= _inside_even_odd(waist, piece)
    # Simplification tolerance is 0.3 mm, so only points within that of the edge may differ.
    dist = _on_polygon_boundary(waist[in_any], spec.shape.vertices)
    assert np.all(dist < 3e-4)


def test_simplified_polygon_stays_within_tolerance():
    spec = load_object("butter")
    simple = spec.shape.simplified(3e-4)
    assert len(simple.vertices) < len(spec.shape.vertices) / 4
    assert np.max(_on_polygon_boundary(spec.shape.vertices, simple.vertices)) <= 3e-4 + 1e-12


# --- non-convex shapes: the COM rule is the convex hull --------------------------------------

#: A U, 10 cm x 8 cm, arms and base 2 cm wide, counter-clockwise; its area centroid lies in the
#: gap between the arms (outside the footprint).
U_SHAPE = [[-0.05, -0.04], [0.05, -0.04], [0.05, 0.04], [0.03, 0.04], [0.03, -0.02],
           [-0.03, -0.02], [-0.03, 0.04], [-0.05, 0.04]]


def test_u_shape_with_the_centroid_outside_the_footprint_loads(tmp_path):
    path = tmp_path / "u.yaml"
    path.write_text("shape:\n  type: polygon\n  vertices: " + json.dumps(U_SHAPE)
                    + "\nthickness: 0.013\ndensity: 7850\n")
    spec = load_object(path)
    np.testing.assert_allclose(spec.com, 0.0, atol=1e-12)  # default COM = area centroid
    # The centroid (the object frame origin) really is outside the outline: in the gap.
    assert not _inside_even_odd(np.zeros((1, 2)), spec.shape.vertices)[0]
    # Area 0.1 * 0.08 - 0.06 * 0.06 = 0.0044 m^2; centroid y by hand from the base (0.002 m^2
    # at y = -0.03) and the two arms (0.0024 m^2 at y = 0.01): -0.000036 / 0.0044 = -8.18 mm.
    assert spec.area == pytest.approx(0.0044)
    np.testing.assert_allclose(spec.source_origin, [0.0, 0.0036 / 0.44], atol=1e-12)
    assert spec.mass == pytest.approx(7850 * 0.0044 * 0.013)
    # Inertia: exact polygon formula vs uniform area samples (ear-clipped triangles).
    rng = np.random.default_rng(3)
    from push_core.objects import _sample_area

    pts = _sample_area(spec.shape, 200000, rng)
    assert np.all(_inside_even_odd(pts, spec.shape.vertices))
    assert spec.moment_of_inertia == pytest.approx(
        spec.mass * np.mean(np.sum(pts**2, axis=1)), rel=0.01)
    # l = mean distance of the area from the COM (here the centroid in the gap).
    assert spec.limit_surface_guess() == pytest.approx(
        np.mean(np.linalg.norm(pts, axis=1)), rel=0.01)
    # A COM anywhere in the hull is accepted, e.g. near the top of the gap.
    moved = spec.replace(com=np.array([0.0, 0.04]))
    np.testing.assert_allclose(moved.com, [0.0, 0.04])


@pytest.mark.parametrize("com", [[0.0, 0.052], [0.06, 0.0], [0.051, 0.045]])
def test_com_outside_the_convex_hull_is_refused(com):
    spec = {"shape": {"type": "polygon", "vertices": U_SHAPE}, "thickness": 0.013,
            "mass": 0.3}
    # com_offset is relative to the vertices' own origin; the centroid is at (0, -0.00818).
    spec["com_offset"] = com
    with pytest.raises(ValueError, match=r"^com_offset: .* outside the convex hull"):
        object_from_dict(spec)
    with pytest.raises(ValueError, match=r"^com_offset:"):
        load_object("rect1").replace(com=np.array([0.0451, 0.0]))


def test_com_on_the_hull_boundary_is_refused_just_inside_accepted():
    spec = load_object("rect1")  # 9 cm square
    with pytest.raises(ValueError, match=r"^com_offset:"):
        spec.replace(com=np.array([0.045, 0.01]))
    assert spec.replace(com=np.array([0.0449, 0.01])).com[0] == pytest.approx(0.0449)
