"""The shapes of a URDF's links: ``<collision>`` (or ``<visual>``) elements as posed triangles.

ROS-free (numpy, the standard library's XML parser). Each element gives its link, its
``<origin>`` in the link frame (``xyz`` m, ``rpy`` rad: fixed-axis roll, pitch, yaw, so
``R = Rz(yaw) Ry(pitch) Rx(roll)``) and one ``<geometry>``: ``box size``, ``cylinder radius
length`` (about z), ``sphere radius``, ``capsule radius length`` or ``mesh filename scale``
(:mod:`push_core.robot_view.meshes`). Mesh file names (:func:`resolve_mesh_path`): absolute
paths and ``file://`` URLs as they are, ``package://<pkg>/<path>`` as ``<dir>/<pkg>/<path>``
and a relative path as ``<dir>/<path>``, for each ``dir`` of ``package_dirs`` in turn.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from push_core.robot_view.meshes import (
    box_triangles,
    capsule_triangles,
    cylinder_triangles,
    mesh_triangles,
    read_mesh,
    sphere_triangles,
)

__all__ = ["LinkShape", "link_shapes", "origin_matrix", "resolve_mesh_path"]

#: Characters of a name or path quoted in an error message.
_QUOTE = 200


@dataclass(frozen=True)
class LinkShape:
    """One shape of a link.

    Attributes
    ----------
    link : str
        The link's name.
    triangles : (T, 3, 3) float64
        Vertices in the link frame, metres.
    closed : bool
        The triangles form a closed surface wound outward.
    source : str
        What it is: the mesh file or the primitive's type.
    """

    link: str
    triangles: NDArray[np.float64]
    closed: bool
    source: str


def origin_matrix(xyz: Sequence[float], rpy: Sequence[float]) -> NDArray[np.float64]:
    """``parent <- child`` (4, 4) of a URDF ``<origin xyz rpy>`` (m, rad)."""
    roll, pitch, yaw = (float(a) for a in rpy)
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    t = np.eye(4)
    t[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    t[:3, 3] = [float(v) for v in xyz]
    return t


def resolve_mesh_path(filename: str, package_dirs: Sequence[str]) -> str:
    """The file a URDF mesh ``filename`` names (module docstring).

    Raises
    ------
    ValueError
        No such file.
    """
    name = filename.strip()
    if name.startswith("file://"):
        name = name[len("file://"):]
    if name.startswith("package://"):
        rest = name[len("package://"):]
        candidates = [os.path.join(d, rest) for d in package_dirs]
    elif os.path.isabs(name):
        candidates = [name]
    else:
        candidates = [os.path.join(d, name) for d in package_dirs]
    for path in candidates:
        if os.path.isfile(path):
            return path
    where = f" in {[str(d)[:_QUOTE] for d in package_dirs][:8]}" if not os.path.isabs(name) \
        else ""
    raise ValueError(f"mesh {filename[:_QUOTE]!r} not found{where}")


def link_shapes(urdf: str, kind: str = "collision", package_dirs: Sequence[str] = ()
                ) -> list[LinkShape]:
    """Every ``<collision>`` (``kind="collision"``) or ``<visual>`` shape of a URDF, posed in
    its link frame.

    Raises
    ------
    ValueError
        Not XML, a geometry of an unknown type or with missing or bad attributes (the link is
        named), a mesh that cannot be found or read.
    """
    if kind not in ("collision", "visual"):
        raise ValueError(f"kind must be 'collision' or 'visual', got {kind!r}")
    try:
        root = ET.fromstring(urdf)
    except ET.ParseError as exc:
        raise ValueError(f"robot description: not XML ({exc})") from None
    shapes = []
    for link in root.findall("link"):
        name = link.get("name", "")
        for element in link.findall(kind):
            try:
                shapes.append(_shape(name, element, package_dirs))
            except ValueError as exc:
                raise ValueError(f"link {name[:_QUOTE]!r}: {kind}: {exc}") from None
    return shapes


def _numbers(element: ET.Element, attribute: str, count: int, default: str | None = None
             ) -> list[float]:
    text = element.get(attribute, default)
    if text is None:
        raise ValueError(f"<{element.tag}> has no {attribute}")
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"<{element.tag} {attribute}={text[:_QUOTE]!r}>: expected {count} "
                         "finite numbers")
    return values


def _shape(link: str, element: ET.Element, package_dirs: Sequence[str]) -> LinkShape:
    origin = element.find("origin")
    pose = (origin_matrix(_numbers(origin, "xyz", 3, "0 0 0"), _numbers(origin, "rpy", 3, "0 0 0"))
            if origin is not None else np.eye(4))
    geometry = element.find("geometry")
    shape = None if geometry is None or len(geometry) == 0 else geometry[0]
    if shape is None:
        raise ValueError("no <geometry>")
    closed = True
    if shape.tag == "box":
        size = _numbers(shape, "size", 3)
        tri = box_triangles(size)
    elif shape.tag in ("cylinder", "capsule"):
        radius, length = _numbers(shape, "radius", 1)[0], _numbers(shape, "length", 1)[0]
        size = [radius, length]
        tri = (cylinder_triangles if shape.tag == "cylinder" else capsule_triangles)(radius,
                                                                                    length)
    elif shape.tag == "sphere":
        size = _numbers(shape, "radius", 1)
        tri = sphere_triangles(size[0])
    elif shape.tag == "mesh":
        filename = shape.get("filename")
        if not filename:
            raise ValueError("<mesh> has no filename")
        path = resolve_mesh_path(filename, package_dirs)
        vertices, faces = read_mesh(path)
        tri, closed = mesh_triangles(vertices, faces, _numbers(shape, "scale", 3, "1 1 1"))
        return LinkShape(link, tri @ pose[:3, :3].T + pose[:3, 3], closed, path)
    else:
        raise ValueError(f"unknown geometry <{shape.tag[:_QUOTE]}> (box, cylinder, sphere, "
                         "capsule, mesh)")
    if any(v < 0 for v in size):
        raise ValueError(f"<{shape.tag}> with a negative size")
    return LinkShape(link, tri @ pose[:3, :3].T + pose[:3, 3], closed, shape.tag)
