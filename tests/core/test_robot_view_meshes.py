"""Shapes to triangles: mesh files, closure and winding, primitives that contain the true shape."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest

from push_core.robot_view.meshes import (
    MAX_MESH_BYTES,
    box_triangles,
    capsule_triangles,
    closed_and_outward,
    cylinder_triangles,
    mesh_triangles,
    read_mesh,
    sphere_triangles,
)


def volume(tri: np.ndarray) -> float:
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6


def as_mesh(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return tri.reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3)


@pytest.mark.parametrize(("tri", "true_volume", "radius"), [
    (box_triangles([0.1, 0.2, 0.3]), 0.1 * 0.2 * 0.3, None),
    (cylinder_triangles(0.05, 0.2), math.pi * 0.05**2 * 0.2, 0.05),
    (sphere_triangles(0.05), 4 / 3 * math.pi * 0.05**3, 0.05),
    (capsule_triangles(0.05, 0.2), math.pi * 0.05**2 * 0.2 + 4 / 3 * math.pi * 0.05**3, 0.05),
])
def test_primitives_are_closed_outward_and_contain_the_shape(tri: np.ndarray, true_volume: float,
                                                             radius: float | None) -> None:
    closed, flip = closed_and_outward(*as_mesh(tri))
    assert closed and not flip
    assert true_volume <= volume(tri) <= 1.06 * true_volume
    if radius is not None:  # every face plane lies at least the radius from the axis / centre
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        keep = np.linalg.norm(normal, axis=1) > 1e-12
        n = normal[keep] / np.linalg.norm(normal[keep], axis=1, keepdims=True)
        side = np.abs(n[:, 2]) < 1e-9  # faces of the mantle: their distance from the z axis
        dist = np.einsum("ij,ij->i", n, tri[keep, 0])
        assert np.all(dist[side] >= radius * (1 - 1e-9))


def test_an_open_or_inward_mesh_is_recognised() -> None:
    tri = box_triangles([1.0, 1.0, 1.0])
    assert closed_and_outward(*as_mesh(tri[:-1])) == (False, False)
    assert closed_and_outward(*as_mesh(tri[:, ::-1])) == (True, True)
    out, closed = mesh_triangles(*as_mesh(tri[:, ::-1]))
    assert closed and volume(out) == pytest.approx(1.0)
    mirrored, closed = mesh_triangles(*as_mesh(tri), scale=[-2.0, 1.0, 1.0])
    assert closed and volume(mirrored) == pytest.approx(2.0)


def test_obj_with_quads_groups_and_negative_indices(tmp_path: Path) -> None:
    path = tmp_path / "part.obj"
    path.write_text("# a unit square and a triangle in two groups\n"
                    "o first\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\n"
                    "f 1//1 2//1 3//1 4//1\n"
                    "g second\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf -3/1 -2/2 -1/3\n")
    vertices, faces = read_mesh(str(path))
    assert vertices.shape == (7, 3)
    assert faces.tolist() == [[0, 1, 2], [0, 2, 3], [4, 5, 6]]


def test_binary_and_ascii_stl(tmp_path: Path) -> None:
    tri = box_triangles([0.1, 0.2, 0.3]).astype(np.float32)
    binary = tmp_path / "box.STL"
    with binary.open("wb") as f:
        f.write(b"\0" * 80 + struct.pack("<I", len(tri)))
        for t in tri:
            f.write(struct.pack("<3f", 0, 0, 0) + t.tobytes() + b"\0\0")
    ascii_path = tmp_path / "box.stl"
    ascii_path.write_text("solid box\n" + "".join(
        "facet normal 0 0 0\nouter loop\n" + "".join(f"vertex {x} {y} {z}\n" for x, y, z in t)
        + "endloop\nendfacet\n" for t in tri.tolist()) + "endsolid box\n")
    for path in (binary, ascii_path):
        out, closed = mesh_triangles(*read_mesh(str(path)))
        assert closed
        assert np.allclose(out, tri, atol=1e-7)


def test_bad_mesh_files_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="not supported"):
        read_mesh(str(tmp_path / "arm.dae"))
    with pytest.raises(ValueError, match="No such file"):
        read_mesh(str(tmp_path / "missing.obj"))
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="malformed"):
        read_mesh(str(bad))
    empty = tmp_path / "empty.obj"
    empty.write_text("v 0 0 0\n")
    with pytest.raises(ValueError, match="no triangle"):
        read_mesh(str(empty))
    assert MAX_MESH_BYTES >= 1 << 20
