"""A URDF's link shapes: origins, primitives, mesh paths (push_core.robot_view.urdf)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from push_core.robot_view.urdf import link_shapes, origin_matrix, resolve_mesh_path


def test_origin_rpy_is_fixed_axis_roll_pitch_yaw() -> None:
    t = origin_matrix([1.0, 2.0, 3.0], [0.0, 0.0, math.pi / 2])
    assert np.allclose(t[:3, :3] @ [1, 0, 0], [0, 1, 0])  # yaw: x -> y
    assert np.allclose(t[:3, 3], [1, 2, 3])
    roll, pitch, yaw = 0.3, -0.4, 1.1
    rx = np.array([[1, 0, 0], [0, math.cos(roll), -math.sin(roll)],
                   [0, math.sin(roll), math.cos(roll)]])
    ry = np.array([[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0],
                   [-math.sin(pitch), 0, math.cos(pitch)]])
    rz = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0],
                   [0, 0, 1]])
    assert np.allclose(origin_matrix([0, 0, 0], [roll, pitch, yaw])[:3, :3], rz @ ry @ rx)


def test_mesh_paths_absolute_file_package_and_relative(tmp_path: Path) -> None:
    mesh = tmp_path / "share" / "my_robot" / "meshes" / "link.stl"
    mesh.parent.mkdir(parents=True)
    mesh.write_bytes(b"")
    share = str(tmp_path / "share")
    assert resolve_mesh_path(str(mesh), []) == str(mesh)
    assert resolve_mesh_path(f"file://{mesh}", []) == str(mesh)
    assert resolve_mesh_path("package://my_robot/meshes/link.stl", ["/nowhere", share]) \
        == str(mesh)
    assert resolve_mesh_path("meshes/link.stl", [str(mesh.parents[1])]) == str(mesh)
    with pytest.raises(ValueError, match="not found in"):
        resolve_mesh_path("package://other/meshes/link.stl", [share])


def urdf(geometry: str, origin: str = "") -> str:
    return (f'<robot name="r"><link name="base"><collision>{origin}<geometry>{geometry}'
            '</geometry></collision><visual><geometry><sphere radius="1"/></geometry></visual>'
            "</link></robot>")


def test_primitives_are_posed_by_their_origin() -> None:
    (shape,) = link_shapes(urdf('<box size="0.2 0.4 0.6"/>',
                                '<origin xyz="1 0 0" rpy="0 0 1.5707963267948966"/>'))
    lo, hi = shape.triangles.reshape(-1, 3).min(axis=0), shape.triangles.reshape(-1, 3).max(axis=0)
    assert np.allclose(lo, [0.8, -0.1, -0.3]) and np.allclose(hi, [1.2, 0.1, 0.3])
    assert shape.closed and shape.source == "box" and shape.link == "base"
    (visual,) = link_shapes(urdf('<box size="1 1 1"/>'), kind="visual")
    assert visual.source == "sphere"


def test_a_mesh_is_read_and_scaled(tmp_path: Path) -> None:
    obj = tmp_path / "tet.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    (shape,) = link_shapes(urdf('<mesh filename="tet.obj" scale="2 2 2"/>'),
                           package_dirs=[str(tmp_path)])
    assert shape.closed and shape.source == str(obj)
    assert np.allclose(shape.triangles.reshape(-1, 3).max(axis=0), [2, 2, 2])


@pytest.mark.parametrize(("geometry", "match"), [
    ('<box size="1 2"/>', "expected 3 finite numbers"),
    ('<cylinder radius="0.1"/>', "no length"),
    ('<sphere radius="nan"/>', "finite"),
    ('<cone radius="1" length="1"/>', "unknown geometry"),
    ('<mesh filename="missing.stl"/>', "not found"),
    ("", "no <geometry>"),
    ('<sphere radius="-1"/>', "negative"),
])
def test_bad_shapes_name_their_link(geometry: str, match: str) -> None:
    with pytest.raises(ValueError, match=f"link 'base'.*{match}"):
        link_shapes(urdf(geometry))


def test_not_xml() -> None:
    with pytest.raises(ValueError, match="not XML"):
        link_shapes("<robot")
    with pytest.raises(ValueError, match="kind"):
        link_shapes(urdf('<box size="1 1 1"/>'), kind="inertial")
