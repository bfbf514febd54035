"""Triangles of a robot's shapes: OBJ and STL meshes read from file, primitives tessellated.

ROS-free (numpy). Each shape becomes ``(T, 3, 3)`` triangles in the shape's own frame plus a
flag saying whether they form a closed surface wound outward (then the rasteriser may skip the
faces turned away from the camera).

- **Meshes** (:func:`read_mesh`): Wavefront OBJ (``v`` and ``f`` records; polygons split into
  fans; every object and group of the file) and STL (binary or ASCII), at most
  ``MAX_MESH_BYTES``. Read here rather than through pinocchio's loader (``coal`` with assimp):
  that loader returned wrong triangles for an OBJ file holding several meshes (the Panda's
  ``link6.obj`` in ``pybullet_data``: the triangles' total area 3.7 times the file's).
  :func:`mesh_triangles` applies the URDF's ``scale`` and checks closure: every edge is shared
  by exactly two triangles that traverse it in opposite directions; wound outward when the
  enclosed signed volume is positive (a closed mesh of negative volume is flipped).
- **Primitives** (URDF ``box``, ``cylinder``, ``sphere`` and the ``capsule`` some URDFs use):
  tessellated with ``SEGMENTS`` segments around the axis and the vertices pushed out so that
  the polyhedron *contains* the true shape (a self-filter must not under-cover the robot).
"""

from __future__ import annotations

import math
import os
import struct

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["MAX_MESH_BYTES", "SEGMENTS", "box_triangles", "capsule_triangles",
           "closed_and_outward", "cylinder_triangles", "mesh_triangles", "read_mesh",
           "sphere_triangles"]

#: Largest mesh file read, bytes.
MAX_MESH_BYTES = 64 * 1024 * 1024
#: Segments around the axis of a tessellated cylinder, sphere or capsule.
SEGMENTS = 24
#: Rings from pole to pole of a tessellated sphere (and of a capsule's two caps together).
RINGS = 12


def read_mesh(path: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices and triangles of an OBJ or STL file (format by extension, case-insensitive).

    Returns
    -------
    vertices : (V, 3) float64
        In the file's units (URDF: metres).
    faces : (F, 3) int64
        Indices into ``vertices``.

    Raises
    ------
    ValueError
        Missing or unreadable file, a file larger than ``MAX_MESH_BYTES``, another format,
        a malformed record, or no triangle.
    """
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".obj", ".stl"):
        raise ValueError(f"mesh {path!r}: format {ext or '(none)'} not supported (OBJ, STL)")
    try:
        size = os.path.getsize(path)
        if size > MAX_MESH_BYTES:
            raise ValueError(f"mesh {path!r}: {size} bytes, more than {MAX_MESH_BYTES}")
        with open(path, "rb") as f:
            data = f.read()
    except OSError as exc:
        raise ValueError(f"mesh {path!r}: {exc.strerror or exc}") from None
    try:
        vertices, faces = _read_obj(data) if ext == ".obj" else _read_stl(data)
    except (ValueError, IndexError, struct.error) as exc:
        raise ValueError(f"mesh {path!r}: malformed ({exc})") from None
    if len(faces) == 0:
        raise ValueError(f"mesh {path!r}: no triangle")
    if not np.all(np.isfinite(vertices)):
        raise ValueError(f"mesh {path!r}: non-finite vertex")
    return vertices, faces


def _read_obj(data: bytes) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    vertices: list[list[float]] = []
    faces: list[list[int]] = []
    for line in data.decode("utf-8", errors="replace").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            vertices.append([float(x) for x in parts[1:4]])
            if len(vertices[-1]) != 3:
                raise ValueError("a vertex without three coordinates")
        elif parts[0] == "f":
            # "f 1 2 3", "f 1/1 2/2 3/3", "f 1//1 ..."; negative indices count from the end
            idx = [int(p.split("/")[0]) for p in parts[1:]]
            idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
            if len(idx) < 3 or min(idx) < 0 or max(idx) >= len(vertices):
                raise ValueError("a face with fewer than three or unknown vertices")
            faces += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
    return (np.array(vertices, dtype=np.float64).reshape(-1, 3),
            np.array(faces, dtype=np.int64).reshape(-1, 3))


def _read_stl(data: bytes) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    if len(data) >= 84:
        (count,) = struct.unpack_from("<I", data, 80)
        if len(data) == 84 + 50 * count:  # binary: normal, 3 vertices, attribute per facet
            rec = np.frombuffer(data, dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)),
                                                      ("a", "<u2")]), count=count, offset=84)
            tri = rec["v"].astype(np.float64)
            return tri.reshape(-1, 3), np.arange(3 * count, dtype=np.int64).reshape(-1, 3)
    text = data.decode("utf-8", errors="replace").split()
    coords = [text[i + 1:i + 4] for i, word in enumerate(text) if word == "vertex"]
    vertices = np.array(coords, dtype=np.float64).reshape(-1, 3)
    if len(vertices) % 3:
        raise ValueError("ASCII STL with a vertex count not a multiple of three")
    return vertices, np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)


def mesh_triangles(vertices: ArrayLike, faces: ArrayLike, scale: ArrayLike = (1.0, 1.0, 1.0)
                   ) -> tuple[NDArray[np.float64], bool]:
    """Triangles of a mesh scaled per axis, wound outward when closed.

    Parameters
    ----------
    vertices : (V, 3) array_like
    faces : (F, 3) int array_like
    scale : (3,) array_like
        The URDF's ``scale`` (a negative product mirrors the mesh: its winding is reversed).

    Returns
    -------
    triangles : (F, 3, 3) float64
    closed : bool
        Whether the triangles form a closed surface wound outward.
    """
    s = np.asarray(scale, dtype=np.float64)
    v = np.asarray(vertices, dtype=np.float64) * s
    f = np.asarray(faces, dtype=np.int64)
    if np.prod(s) < 0:
        f = f[:, ::-1]
    closed, flip = closed_and_outward(v, f)
    return v[f[:, ::-1] if flip else f], closed


def closed_and_outward(vertices: NDArray[np.float64], faces: NDArray[np.int64]
                       ) -> tuple[bool, bool]:
    """Whether a triangle mesh is closed and consistently wound, and whether it must be
    flipped to wind outward.

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (F, 3) int
        Indices into ``vertices``; identical vertices are merged first.

    Returns
    -------
    closed : bool
        Every directed edge appears once and its reverse once.
    flip : bool
        The mesh is closed and its signed volume is negative (wound inward).
    """
    _, canon = np.unique(vertices, axis=0, return_inverse=True)
    f = canon.reshape(-1)[faces]
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    if len(edges) == 0 or np.any(edges[:, 0] == edges[:, 1]):
        return False, False
    directed, counts = np.unique(edges, axis=0, return_counts=True)
    if np.any(counts != 1):
        return False, False
    reverse = np.unique(edges[:, ::-1], axis=0)
    if len(reverse) != len(directed) or np.any(reverse != directed):
        return False, False
    tri = vertices[faces]
    volume = float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6
    return True, volume < 0.0


def box_triangles(size: ArrayLike) -> NDArray[np.float64]:
    """A box of side lengths ``size`` (3,) m centred on the origin, outward."""
    half = 0.5 * np.asarray(size, dtype=np.float64)
    corners = np.array([[sx, sy, sz] for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)],
                       dtype=np.float64) * half
    # Faces as corner indices, counter-clockwise seen from outside.
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return corners[np.array(faces)]


def cylinder_triangles(radius: float, length: float) -> NDArray[np.float64]:
    """A cylinder about the z axis, centred on the origin (the URDF's), containing the true
    one, outward."""
    h = 0.5 * length
    bottom, top = _ring(radius, -h), _ring(radius, h)
    return np.concatenate([_band(bottom, top), _fan(np.array([0.0, 0.0, h]), top, True),
                           _fan(np.array([0.0, 0.0, -h]), bottom, False)])


def sphere_triangles(radius: float) -> NDArray[np.float64]:
    """A sphere centred on the origin, containing the true one, outward."""
    return _round(radius, 0.0)


def capsule_triangles(radius: float, length: float) -> NDArray[np.float64]:
    """A capsule about the z axis (a cylinder of ``length`` between two hemispheres), centred
    on the origin, containing the true one, outward."""
    return _round(radius, 0.5 * length)


def _round(radius: float, half: float) -> NDArray[np.float64]:
    """A sphere of ``radius`` cut at its equator, the halves moved apart along z by
    ``2 half`` (the equator ring in both: the cylinder between them)."""
    grow = 1.0 / math.cos(math.pi / (2 * RINGS))  # the polyhedron contains the sphere
    polar = np.arange(1, RINGS) * (math.pi / RINGS)  # from +z
    eq = math.pi / 2
    lower = [*(t for t in polar[::-1] if t > eq + 1e-9), eq]  # bottom to top
    upper = [eq, *(t for t in polar[::-1] if t < eq - 1e-9)]
    angles = [(t, -half) for t in lower] + [(t, half) for t in upper[half == 0.0:]]
    rings = [_ring(grow * radius * math.sin(t), grow * radius * math.cos(t) + dz)
             for t, dz in angles]
    bottom = np.array([0.0, 0.0, -half - grow * radius])
    top = np.array([0.0, 0.0, half + grow * radius])
    parts = [_fan(bottom, rings[0], False), _fan(top, rings[-1], True)]
    parts += [_band(a, b) for a, b in zip(rings[:-1], rings[1:], strict=True)]
    return np.concatenate(parts)


def _ring(radius: float, z: float) -> NDArray[np.float64]:
    """A counter-clockwise ring about +z whose polygon contains the circle of ``radius``."""
    a = np.arange(SEGMENTS) * (2 * math.pi / SEGMENTS)
    r = radius / math.cos(math.pi / SEGMENTS)
    return np.stack([r * np.cos(a), r * np.sin(a), np.full(SEGMENTS, z)], axis=1)


def _band(lower: NDArray[np.float64], upper: NDArray[np.float64]) -> NDArray[np.float64]:
    """Triangles between two counter-clockwise rings of one size, ``upper`` above: outward."""
    a, b = lower, upper
    a1, b1 = np.roll(a, -1, axis=0), np.roll(b, -1, axis=0)
    return np.concatenate([np.stack([a, a1, b1], axis=1), np.stack([a, b1, b], axis=1)])


def _fan(centre: NDArray[np.float64], ring: NDArray[np.float64], up: bool
         ) -> NDArray[np.float64]:
    """A cap from ``centre`` to a counter-clockwise ring; ``up``: its face looks along +z."""
    r1 = np.roll(ring, -1, axis=0)
    c = np.broadcast_to(centre, ring.shape)
    return np.stack([c, ring, r1] if up else [c, r1, ring], axis=1)
