"""The z-buffer rasteriser against hand-derived projections (push_core.robot_view.raster)."""

from __future__ import annotations

import numpy as np
import pytest

from push_core.robot_view.raster import check_camera, rasterize

#: 100 x 80 image, f = 100 px, principal point at the image centre.
K = np.array([[100.0, 0.0, 49.5], [0.0, 100.0, 39.5], [0.0, 0.0, 1.0]])
W, H = 100, 80


def square(x0: float, x1: float, y0: float, y1: float, z: float) -> np.ndarray:
    """Two triangles of the rectangle [x0, x1] x [y0, y1] at depth z, facing the camera."""
    a, b, c, d = (x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)
    # Counter-clockwise seen from the camera (at the origin, looking along +z, y down):
    # the right-handed normal points back at the camera.
    return np.array([[a, d, c], [a, c, b]], dtype=float)


def test_a_square_facing_the_camera_covers_the_pixels_whose_centres_it_holds() -> None:
    # x in [-0.1, 0.1] m at z = 1 m: u = 100 x + 49.5 in [39.5, 59.5] -> columns 40..59;
    # y in [-0.05, 0.15]: v = 100 y + 39.5 in [34.5, 54.5] -> rows 35..54.
    mask, depth = rasterize(square(-0.1, 0.1, -0.05, 0.15, 1.0), K, W, H)
    expected = np.zeros((H, W), dtype=bool)
    expected[35:55, 40:60] = True
    assert np.array_equal(mask, expected)
    assert np.all(depth[mask] == np.float32(1.0))
    assert np.all(np.isnan(depth[~mask]))


def test_depth_is_perspective_correct_on_a_tilted_plane() -> None:
    # The plane z = 1 + 0.5 x: the ray through pixel u hits it at z = 1 / (1 - 0.5 (u - cx) / fx).
    corners = np.array([[-0.3, -0.3], [0.3, -0.3], [0.3, 0.3], [-0.3, 0.3]])
    pts = np.column_stack([corners, 1.0 + 0.5 * corners[:, 0]])
    tri = np.array([[pts[0], pts[3], pts[2]], [pts[0], pts[2], pts[1]]])
    mask, depth = rasterize(tri, K, W, H)
    v, u = np.nonzero(mask)
    assert len(u) > 1000
    expected = 1.0 / (1.0 - 0.5 * (u - K[0, 2]) / K[0, 0])
    assert np.max(np.abs(depth[v, u] - expected)) < 1e-6


def test_the_nearest_surface_wins_whatever_the_drawing_order() -> None:
    near = square(-0.1, 0.1, -0.1, 0.1, 1.0)
    far = square(-0.4, 0.1, -0.4, 0.1, 2.0)  # u = 50 x + 49.5: columns 30..54, rows 20..44
    for tri in (np.concatenate([near, far]), np.concatenate([far, near])):
        mask, depth = rasterize(tri, K, W, H)
        assert depth[40, 50] == np.float32(1.0)  # both cover it
        assert depth[25, 35] == np.float32(2.0)  # only the far one (the near one: 40..59)


def test_a_plane_reaching_behind_the_camera_is_clipped_at_the_near_plane() -> None:
    # The floor y = 0.5 (below the camera; y is down) from z = -1 (behind) to z = 10, x in
    # [-5, 5]: pixel row v sees it at z = 0.5 fy / (v - cy), drawn where near <= z <= 10.
    p = [(-5.0, 0.5, -1.0), (5.0, 0.5, -1.0), (5.0, 0.5, 10.0), (-5.0, 0.5, 10.0)]
    tri = np.array([[p[0], p[1], p[2]], [p[0], p[2], p[3]]])
    mask, depth = rasterize(tri, K, W, H, near=0.05)
    rows = np.arange(H)
    with np.errstate(divide="ignore"):
        z = np.where(rows > K[1, 2], 0.5 * K[1, 1] / (rows - K[1, 2]), np.inf)
    expected_rows = (z >= 0.05) & (z <= 10.0)
    assert np.array_equal(mask[:, 50], expected_rows)
    assert np.allclose(depth[expected_rows, 50], z[expected_rows], rtol=1e-6)


def test_culling_skips_only_the_flagged_faces_turned_away() -> None:
    front = square(-0.1, 0.1, -0.1, 0.1, 1.0)
    back = front[:, ::-1]  # the same triangles wound the other way: facing away
    assert rasterize(back, K, W, H, cull=[True, True])[0].sum() == 0
    assert np.array_equal(rasterize(back, K, W, H, cull=[False, False])[0],
                          rasterize(front, K, W, H, cull=[True, True])[0])


def test_a_closed_box_looks_the_same_with_and_without_culling() -> None:
    from push_core.robot_view.meshes import box_triangles

    rng = np.random.default_rng(3)
    for _ in range(5):
        tri = box_triangles(rng.uniform(0.05, 0.3, 3))
        angle = rng.uniform(-np.pi, np.pi)
        c, s = np.cos(angle), np.sin(angle)
        rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ np.array(
            [[1, 0, 0], [0, c, -s], [0, s, c]])
        tri = tri @ rot.T + [rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), 1.5]
        m0, d0 = rasterize(tri, K, W, H)
        m1, d1 = rasterize(tri, K, W, H, cull=np.ones(len(tri), bool))
        assert m0.sum() > 100
        assert np.array_equal(m0, m1)
        assert np.allclose(d0[m0], d1[m1], atol=1e-6)


def test_bands_of_a_large_triangle_give_the_same_image(monkeypatch: pytest.MonkeyPatch) -> None:
    import push_core.robot_view.raster as raster

    tri = square(-0.4, 0.4, -0.3, 0.3, 1.0)
    whole = rasterize(tri, K, W, H)
    monkeypatch.setattr(raster, "CHUNK_PIXELS", 37)  # bands of one row, chunks of one band
    banded = rasterize(tri, K, W, H)
    assert np.array_equal(whole[0], banded[0])
    assert np.array_equal(whole[1][whole[0]], banded[1][banded[0]])


def test_work_is_bounded() -> None:
    wall = square(-10, 10, -10, 10, 0.5)
    many = np.repeat(wall, 40, axis=0)  # 80 triangles each covering the whole image
    with pytest.raises(ValueError, match="images' worth of pixels"):
        rasterize(many, K, W, H, max_work=64)
    assert rasterize(many, K, W, H, max_work=100)[0].all()


def test_bad_input_is_a_clear_error() -> None:
    tri = square(-0.1, 0.1, -0.1, 0.1, 1.0)
    with pytest.raises(ValueError, match=r"\(T, 3, 3\)"):
        rasterize(tri[:, :2], K, W, H)
    with pytest.raises(ValueError, match="non-finite"):
        rasterize(np.where(tri == tri[0, 0, 0], np.nan, tri), K, W, H)
    with pytest.raises(ValueError, match="pinhole K"):
        rasterize(tri, np.eye(3) * [[1], [1], [0]], W, H)
    with pytest.raises(ValueError, match="width"):
        check_camera(K, 0, H)
    with pytest.raises(ValueError, match="near"):
        rasterize(tri, K, W, H, near=0.0)
    with pytest.raises(ValueError, match="cull"):
        rasterize(tri, K, W, H, cull=[True])
    assert not rasterize(np.zeros((0, 3, 3)), K, W, H)[0].any()


def test_fill_polygon_takes_the_pixel_centres_inside_even_a_concave_polygon() -> None:
    from push_core.robot_view.raster import fill_polygon

    # A U: the outer square 10..30 x 10..30 without the notch 15..25 x 10..22 (u, v).
    u_shape = np.array([[10.0, 10.0], [15.0, 10.0], [15.0, 22.0], [25.0, 22.0], [25.0, 10.0],
                        [30.0, 10.0], [30.0, 30.0], [10.0, 30.0]])
    mask = fill_polygon(u_shape, 40, 40)
    vv, uu = np.mgrid[:40, :40]
    outer = (uu >= 10) & (uu <= 30) & (vv >= 10) & (vv < 30)
    notch = (uu > 15) & (uu < 25) & (vv < 22)
    inside = outer & ~notch
    # Pixel centres on an edge may go either way; all the others must agree.
    edge = ((uu == 10) | (uu == 30) | (uu == 15) | (uu == 25) | (vv == 10) | (vv == 22)
            | (vv == 30))
    assert np.array_equal(mask[~edge], inside[~edge])
    assert np.array_equal(fill_polygon(u_shape[::-1], 40, 40), mask)  # orientation free
    with pytest.raises(ValueError, match="K >= 3"):
        fill_polygon(u_shape[:2], 40, 40)


def test_prism_silhouette_of_a_box_seen_from_above() -> None:
    from push_core.robot_view.raster import prism_silhouette

    # Camera 1 m above the table looking straight down (x right, y down in the image =
    # world -y): a 0.2 x 0.1 m plate 0.1 m high at the origin, top face 0.9 m from the lens.
    t_cam_world = np.array([[1.0, 0, 0, 0], [0, -1.0, 0, 0], [0, 0, -1.0, 1.0], [0, 0, 0, 1]])
    plate = np.array([[-0.1, -0.05], [0.1, -0.05], [0.1, 0.05], [-0.1, 0.05]])
    sil = prism_silhouette(plate, 0.1, K, t_cam_world, W, H)
    u = 49.5 + 100 * np.array([-0.1, 0.1]) / 0.9  # the top face: 38.4 .. 60.6
    v = 39.5 + 100 * np.array([-0.05, 0.05]) / 0.9
    expected = np.zeros((H, W), dtype=bool)
    expected[int(np.ceil(v[0])):int(np.floor(v[1])) + 1,
             int(np.ceil(u[0])):int(np.floor(u[1])) + 1] = True
    assert np.array_equal(sil, expected)  # from straight above the top face is the silhouette
    tilted = np.array([[1.0, 0, 0, 0], [0, -0.8, 0.6, 0], [0, -0.6, -0.8, 1.0], [0, 0, 0, 1]])
    side = prism_silhouette(plate, 0.1, K, tilted, W, H)
    assert side.sum() > sil.sum()  # seen at an angle: a side wall shows too
