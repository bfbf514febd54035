"""The pybullet scene of the sim bridge: table, one flat object (convex pieces), pusher.

ROS-free; :class:`sim_bridge.world.PushWorld` is the entry point (this module builds its
bodies). Frames and units: ``docs/ARCHITECTURE.md#units-frames-conventions`` and
:mod:`sim_bridge.world`; SI throughout, quaternions (x, y, z, w).

Bodies
------
- Table: an infinite static plane (collision) drawn as a 1.5 m x 1.5 m slab.
- Object: a compound of convex prisms, one per piece of
  ``shape.convex_pieces(tolerance=COLLISION_TOLERANCE)`` (a true convex decomposition of the
  outline simplified to within 0.5 mm, so non-convex outlines such as butter keep their
  concavities), with a collision margin of 0.1 mm (pybullet's default 1 mm inflates the
  outline by 1 mm). With ``WorldConfig.support_cell`` > 0 every piece is further cut into
  cells of that size (:func:`support_cells`): bullet keeps at most 4 contact points per pair of
  convex shapes, so a single convex piece rests on 3 or 4 of its corners and its friction acts
  there, not over the footprint (the resting contacts of both:
  docs/results/eval_push_support.md); cells spread the support over the footprint. 0 (default)
  keeps the pieces whole. Visual: a mesh of the true outline (top face triangulated, side walls;
  within 0.02 mm), so images show the exact outline. Mass from the spec; inertia diagonal ``(I_xx,
  I_yy, I_zz)`` about the COM with ``I_zz = ObjectSpec.moment_of_inertia`` and the tilt inertias of
  the uniform plate. The COM enters pybullet through the base inertial frame
  (``baseInertialFramePosition``), so collision and visual shapes stay in the object frame.
  Linear/angular damping 0, restitution 0, spinning and rolling friction 0. The object has a
  friction anchor (``changeDynamics(frictionAnchor=1)``): without it a resting object creeps on the
  table with nothing touching it (bullet's support contacts switch between corners).
- Friction: bullet combines the lateral friction coefficients of two touching bodies by
  multiplying them. The object's coefficient is therefore 1.0, the table's is
  ``friction_table`` and the pusher's is ``friction_pusher``, so the object-table pair sees
  ``friction_table`` and the pusher-object pair ``friction_pusher``. The pusher never touches
  the table (collisions between them are disabled; it hovers 2 mm above it).
- Pusher: a dynamic vertical cylinder (radius ``pusher_radius``, 60 mm long, 0.1 kg) held by
  a force-limited fixed constraint to the world (``Scene.drive``), parked high above the robot
  side of the table, out of the camera's view; :mod:`sim_bridge.physics` moves it.

Randomisation (``WorldConfig.randomize``; explicit overrides always win), drawn by
:func:`simulated_spec` from the world's physics stream:

- mass: the spec's mass times a log-uniform factor in ``MASS_FACTOR_RANGE`` = [0.5, 2];
- COM: uniform over the object's outline shrunk by ``COM_SHRINK`` = 30 % about the area
  centroid (scaled by 0.7);
- friction_table uniform in ``FRICTION_TABLE_RANGE`` = [0.15, 0.4];
- friction_pusher uniform in ``FRICTION_PUSHER_RANGE`` = [0.15, 0.5].
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as p
from numpy.typing import NDArray
from pybullet_utils.bullet_client import BulletClient

from push_core.geometry import closest_point_on_polyline
from push_core.objects import ObjectSpec, load_object
from push_core.shapes import Ellipse, Polygon
from sim_bridge.config import WorldConfig
from sim_bridge.rendering import Appearance
from sim_bridge.site_look import load_texture

__all__ = [
    "COLLISION_TOLERANCE",
    "COM_SHRINK",
    "FRICTION_PUSHER_RANGE",
    "FRICTION_TABLE_RANGE",
    "INITIAL_SETTLE_STEPS",
    "MASS_FACTOR_RANGE",
    "OBJECT_MARGIN",
    "PUSHER_LENGTH",
    "PUSHER_MASS",
    "PUSHER_MAX_FORCE",
    "PUSHER_PARK",
    "VISUAL_TOLERANCE",
    "Scene",
    "build_scene",
    "park_position",
    "simulated_spec",
    "support_cells",
    "yaw_quaternion",
]

#: Randomisation ranges (see the module docstring).
MASS_FACTOR_RANGE = (0.5, 2.0)
COM_SHRINK = 0.3
FRICTION_TABLE_RANGE = (0.15, 0.4)
FRICTION_PUSHER_RANGE = (0.15, 0.5)

#: Pusher geometry and drive.
PUSHER_LENGTH = 0.06
PUSHER_MASS = 0.1
PUSHER_MAX_FORCE = 100.0  # N, force limit of the driving constraint
PUSHER_PARK = (-0.45, 0.0, 0.30)  # parked pusher: axis x, y and bottom height, m

#: Largest deviation of the collision outline from the true outline (Douglas-Peucker tolerance
#: passed to ``Polygon.convex_pieces``), m. push_core's default, 0.3 mm, cuts butter into many
#: slivers along its concave waist; 0.5 mm gives about half as many pieces and makes butter's
#: physics markedly faster (push + frame timings: docs/results/bench_sim.md).
#: Convex polygons and ellipses are not simplified.
COLLISION_TOLERANCE = 5e-4
#: Largest deviation of the visual mesh's outline from the true outline, m.
VISUAL_TOLERANCE = 2e-5
#: Collision margin of the object's convex pieces, m (pybullet's default is 1 mm).
OBJECT_MARGIN = 1e-4
#: Support cells smaller than this area (m^2, a 1 mm x 1 mm sliver) are dropped.
_MIN_CELL_AREA = 1e-6
#: Steps run after building the scene so that resting contacts are established.
INITIAL_SETTLE_STEPS = 24

_TABLE_HALF_SIZE = 0.75
#: Side of the table slab's top face, m (a texture spans it once).
TABLE_SIDE = 2 * _TABLE_HALF_SIZE
_PUSHER_RGB = (0.15, 0.15, 0.17)


@dataclass(frozen=True)
class Scene:
    """The pybullet bodies of one scene.

    Attributes
    ----------
    table, object, pusher : int
        Body ids (``pusher`` -1 in arm mode: the arm's rod pushes).
    drive : int
        The pusher's fixed constraint to the world; its pivot is the commanded position
        (-1 in arm mode).
    inertial_offset : (3,) ndarray
        COM in the object frame, ``(c_x, c_y, thickness / 2)``, m (pybullet reports the COM
        frame; ``object frame = COM frame - R @ inertial_offset``).
    """

    table: int
    object: int
    pusher: int
    drive: int
    inertial_offset: NDArray[np.float64]


def park_position() -> NDArray[np.float64]:
    """Centre of the parked pusher in ``world`` (3,), m."""
    x, y, bottom = PUSHER_PARK
    return np.array([x, y, bottom + PUSHER_LENGTH / 2.0])


def build_scene(client: BulletClient, cfg: WorldConfig, spec: ObjectSpec,
                look: Appearance) -> Scene:
    """Set the physics engine up and create table, object and parked pusher in ``client``.

    No physics step is run (the world settles the new scene itself).
    """
    c = client
    c.setPhysicsEngineParameter(fixedTimeStep=cfg.time_step,
                                numSolverIterations=cfg.solver_iterations, numSubSteps=0,
                                deterministicOverlappingPairs=1, enableFileCaching=0)
    c.setGravity(0.0, 0.0, -9.81)

    plane = c.createCollisionShape(p.GEOM_PLANE)
    slab = c.createVisualShape(p.GEOM_BOX, halfExtents=[_TABLE_HALF_SIZE] * 2 + [0.01],
                               visualFramePosition=[0.0, 0.0, -0.01],
                               rgbaColor=[*look.table_rgb, 1.0],
                               specularColor=[0.05, 0.05, 0.05])
    table = c.createMultiBody(0.0, plane, slab, [0.0, 0.0, 0.0])
    texture = load_texture(c, look) if look.table_texture else -1
    if texture >= 0:  # the site look's procedural table (sim_bridge.site_look)
        c.changeVisualShape(table, -1, textureUniqueId=texture)
    c.changeDynamics(table, -1, lateralFriction=spec.friction_table,
                     spinningFriction=0.0, rollingFriction=0.0, restitution=0.0)

    body, inertial_offset = _create_object(c, cfg, spec, look, texture)

    if cfg.robot == "arm":  # the rod on the arm is the pusher (sim_bridge.arm_robot)
        return Scene(table=table, object=body, pusher=-1, drive=-1,
                     inertial_offset=inertial_offset)
    radius = cfg.pusher_radius
    col = c.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=PUSHER_LENGTH)
    vis = c.createVisualShape(p.GEOM_CYLINDER, radius=radius, length=PUSHER_LENGTH,
                              rgbaColor=[*_PUSHER_RGB, 1.0])
    park = park_position()
    pusher = c.createMultiBody(PUSHER_MASS, col, vis, park.tolist())
    c.changeDynamics(pusher, -1, lateralFriction=spec.friction_pusher,
                     spinningFriction=0.0, rollingFriction=0.0, restitution=0.0,
                     linearDamping=0.0, angularDamping=0.0)
    c.setCollisionFilterPair(pusher, table, -1, -1, 0)
    drive = c.createConstraint(pusher, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0],
                               park.tolist())
    c.changeConstraint(drive, park.tolist(), maxForce=PUSHER_MAX_FORCE)
    return Scene(table=table, object=body, pusher=pusher, drive=drive,
                 inertial_offset=inertial_offset)


def _create_object(c: BulletClient, cfg: WorldConfig, spec: ObjectSpec, look: Appearance,
                   texture: int = -1) -> tuple[int, NDArray[np.float64]]:
    """The object body at ``cfg.object_pose`` and its inertial offset (3,); with a
    ``texture`` (pybullet id) and ``look.object_textured``, the object wears the table's
    texture at the table's scale (tinted by its colour), shifted by ``look.texture_shift``."""
    t = spec.thickness
    tmp = Path(tempfile.mkdtemp(prefix="pushbot_sim_"))
    try:
        obj_file = tmp / "collision.obj"
        obj_text, (verts, normals, indices) = _object_geometry(spec.shape, t, cfg.support_cell)
        obj_file.write_text(obj_text)
        col = c.createCollisionShape(p.GEOM_MESH, fileName=str(obj_file))
        textured = texture >= 0 and look.object_textured
        uvs = {"uvs": [[x / TABLE_SIDE + 0.5 + look.texture_shift[0],
                        y / TABLE_SIDE + 0.5 + look.texture_shift[1]] for x, y, _ in verts]
               } if textured else {}
        vis = c.createVisualShape(p.GEOM_MESH, vertices=verts, normals=normals,
                                  indices=indices, rgbaColor=[*look.object_rgb, 1.0],
                                  specularColor=[look.object_specular] * 3, **uvs)
        x, y, theta = cfg.object_pose
        body = c.createMultiBody(
            spec.mass, col, vis, [x, y, OBJECT_MARGIN], yaw_quaternion(theta),
            baseInertialFramePosition=[float(spec.com[0]), float(spec.com[1]), t / 2.0])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if body < 0:
        raise RuntimeError("pybullet could not create the object body")
    if textured:
        c.changeVisualShape(body, -1, textureUniqueId=texture)
    inertial_offset = np.array([spec.com[0], spec.com[1], t / 2.0])
    c.changeDynamics(body, -1, lateralFriction=1.0, spinningFriction=0.0,
                     rollingFriction=0.0, restitution=0.0, linearDamping=0.0,
                     angularDamping=0.0, collisionMargin=OBJECT_MARGIN, frictionAnchor=1,
                     localInertiaDiagonal=_inertia_diagonal(spec).tolist())
    return body, inertial_offset


def yaw_quaternion(theta: float) -> list[float]:
    """Quaternion (x, y, z, w) of a rotation by ``theta`` about z."""
    return [0.0, 0.0, float(np.sin(theta / 2.0)), float(np.cos(theta / 2.0))]


# ------------------------------------------------------------- the simulated object
_LIBRARY_CACHE: dict[str, ObjectSpec] = {}
_GEOMETRY_CACHE: dict[tuple[int, float, float], tuple[object, str, tuple]] = {}


def _load_object(name_or_path: str | Path) -> ObjectSpec:
    """``load_object`` with library objects cached (validating a dense measured outline such
    as butter's is slow); specification files are read every time, they may have changed."""
    key = str(name_or_path)
    if key in _LIBRARY_CACHE:
        return _LIBRARY_CACHE[key]
    spec = load_object(name_or_path)
    if spec.source == f"library:{key}":
        _LIBRARY_CACHE[key] = spec
    return spec


def simulated_spec(cfg: WorldConfig, rng: np.random.Generator) -> ObjectSpec:
    """The library spec with randomisation (if enabled) and then explicit overrides applied.

    All random values are drawn in a fixed order whether or not they are used, so an override
    of one parameter does not change the others.
    """
    spec = _load_object(cfg.object)
    factor = float(np.exp(rng.uniform(*np.log(MASS_FACTOR_RANGE))))
    com = _random_com(spec, rng)
    mu_table = float(rng.uniform(*FRICTION_TABLE_RANGE))
    mu_pusher = float(rng.uniform(*FRICTION_PUSHER_RANGE))
    changes: dict[str, object] = {}
    if cfg.randomize:
        changes.update(mass=spec.mass * factor, com=com, friction_table=mu_table,
                       friction_pusher=mu_pusher)
    for name, key in (("mass", "mass"), ("com_offset", "com"),
                      ("friction_table", "friction_table"),
                      ("friction_pusher", "friction_pusher")):
        value = getattr(cfg, name)
        if value is not None:
            changes[key] = value
    return spec.replace(**changes) if changes else spec


def _random_com(spec: ObjectSpec, rng: np.random.Generator) -> NDArray[np.float64]:
    """A point uniform over the outline scaled by ``1 - COM_SHRINK`` about the area centroid."""
    outline = spec.polyline()
    scale = 1.0 - COM_SHRINK
    lo, hi = outline.min(axis=0) * scale, outline.max(axis=0) * scale
    for _ in range(1000):
        q = rng.uniform(lo, hi)
        _, _, dist, _ = closest_point_on_polyline(outline, np.stack([q / scale, q]))
        if np.all(dist < 0):
            return q
    return np.zeros(2)  # unreachable for any sensible outline


def _inertia_diagonal(spec: ObjectSpec) -> NDArray[np.float64]:
    """(I_xx, I_yy, I_zz) about the COM, kg m^2: I_zz from the spec, the tilt inertias of a
    uniform plate of the spec's outline and thickness (second moments of the polyline)."""
    v = spec.polyline() - spec.com
    w = np.roll(v, -1, axis=0)
    cr = v[:, 0] * w[:, 1] - w[:, 0] * v[:, 1]
    area = 0.5 * cr.sum()
    sxx = np.sum(cr * (v[:, 1] ** 2 + v[:, 1] * w[:, 1] + w[:, 1] ** 2)) / 12.0  # int y^2
    syy = np.sum(cr * (v[:, 0] ** 2 + v[:, 0] * w[:, 0] + w[:, 0] ** 2)) / 12.0  # int x^2
    density = spec.mass / area
    tilt = spec.mass * spec.thickness**2 / 12.0
    return np.array([density * sxx + tilt, density * syy + tilt, spec.moment_of_inertia])


# ------------------------------------------------------------------------ geometry
def _object_geometry(shape: Polygon | Ellipse, thickness: float,
                     support_cell: float = 0.0) -> tuple[str, tuple]:
    """Collision OBJ text and visual mesh of a shape, cached per shape object (randomised
    specs share their library shape) and support cell, at most 32 entries."""
    key = (id(shape), thickness, support_cell)
    hit = _GEOMETRY_CACHE.get(key)
    if hit is not None and hit[0] is shape:
        return hit[1], hit[2]
    pieces = (shape.convex_pieces() if isinstance(shape, Ellipse)
              else shape.convex_pieces(tolerance=COLLISION_TOLERANCE))
    if support_cell > 0.0:
        pieces = support_cells(pieces, support_cell)
    geometry = (_prisms_obj(pieces, thickness), _extruded_mesh(shape, thickness))
    if len(_GEOMETRY_CACHE) >= 32:
        _GEOMETRY_CACHE.pop(next(iter(_GEOMETRY_CACHE)))
    _GEOMETRY_CACHE[key] = (shape, *geometry)
    return geometry


def support_cells(pieces: list[NDArray[np.float64]], cell: float) -> list[NDArray[np.float64]]:
    """Cut convex pieces into the cells of a square grid (side ``cell`` m, aligned with the
    object frame's origin): each piece clipped to each grid square it overlaps (the clip of a
    convex polygon by a square is convex), counter-clockwise; cells under ``_MIN_CELL_AREA``
    dropped. Together they cover the pieces exactly."""
    if not cell > 0.0:
        raise ValueError(f"support cell must be > 0 m, got {cell!r}")
    cells = []
    for piece in pieces:
        poly = np.asarray(piece, dtype=np.float64)
        lo = np.floor(poly.min(axis=0) / cell).astype(int)
        hi = np.ceil(poly.max(axis=0) / cell).astype(int)
        for i in range(lo[0], hi[0]):
            for j in range(lo[1], hi[1]):
                clip = _clip_to_box(poly, (i * cell, j * cell), ((i + 1) * cell, (j + 1) * cell))
                if len(clip) >= 3 and _area(clip) >= _MIN_CELL_AREA:
                    cells.append(clip)
    return cells


def _clip_to_box(poly: NDArray[np.float64], low: tuple[float, float],
                 high: tuple[float, float]) -> NDArray[np.float64]:
    """Sutherland-Hodgman clip of a counter-clockwise polygon (K, 2) by an axis-aligned box;
    the result keeps the orientation (possibly empty, (0, 2))."""
    out = poly
    for axis, bound, keep_below in ((0, low[0], False), (0, high[0], True),
                                    (1, low[1], False), (1, high[1], True)):
        if len(out) == 0:
            break
        side = (out[:, axis] - bound) * (-1.0 if keep_below else 1.0)  # >= 0: inside
        nxt = []
        for k in range(len(out)):
            a, b = out[k], out[(k + 1) % len(out)]
            sa, sb = side[k], side[(k + 1) % len(out)]
            if sa >= 0.0:
                nxt.append(a)
            if (sa >= 0.0) != (sb >= 0.0):
                nxt.append(a + (b - a) * (sa / (sa - sb)))
        out = np.array(nxt, dtype=np.float64).reshape(-1, 2)
    if len(out):  # drop repeated vertices (a corner on the box edge)
        keep = np.linalg.norm(out - np.roll(out, -1, axis=0), axis=1) > 1e-9
        out = out[keep]
    return out


def _area(poly: NDArray[np.float64]) -> float:
    """Signed area of a polygon (K, 2), positive counter-clockwise (shoelace)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _prisms_obj(pieces: list[NDArray[np.float64]], thickness: float) -> str:
    """Wavefront OBJ text with one closed prism per convex piece (one ``o`` group each);
    pybullet turns each group into a convex hull of a compound collision shape."""
    lines = []
    base = 1
    for k, piece in enumerate(pieces):
        n = len(piece)
        lines.append(f"o piece{k}")
        for z in (0.0, thickness):
            lines += [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y in piece]
        lines.append("f " + " ".join(str(base + i) for i in reversed(range(n))))
        lines.append("f " + " ".join(str(base + n + i) for i in range(n)))
        for i in range(n):
            j = (i + 1) % n
            lines.append(f"f {base + i} {base + j} {base + n + j} {base + n + i}")
        base += 2 * n
    return "\n".join(lines) + "\n"


def _extruded_mesh(shape: Polygon | Ellipse,
                   thickness: float) -> tuple[list[list[float]], list[list[float]], list[int]]:
    """Visual mesh of the true outline: top face and side walls (the bottom is never seen).

    Dense measured outlines are simplified to within ``VISUAL_TOLERANCE`` (0.02 mm, a small
    fraction of a pixel at the default viewpoint), which makes their frames cheaper to render
    and their scenes faster to build (render timings: docs/results/bench_sim.md).

    Returns vertices (N, 3), per-vertex normals (N, 3) and triangle indices (3 T,) with
    counter-clockwise (outward) winding.
    """
    if isinstance(shape, Ellipse):
        outline = shape.polyline(max_spacing=0.003)  # chord error < 0.03 mm for a > 3 cm
        tris = np.array([[0, i, i + 1] for i in range(1, len(outline) - 1)])
    else:
        simple = shape.simplified(VISUAL_TOLERANCE)
        outline = simple.vertices
        tris = simple.triangles()
    n = len(outline)
    top = np.column_stack([outline, np.full(n, thickness)])
    verts = [top]
    normals = [np.tile([0.0, 0.0, 1.0], (n, 1))]
    indices = [tris.reshape(-1)]
    # Side walls: four vertices per edge so each wall has its own flat normal.
    a, b = outline, np.roll(outline, -1, axis=0)
    d = b - a
    nrm = np.column_stack([d[:, 1], -d[:, 0], np.zeros(n)])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    quad = np.stack([np.column_stack([a, np.zeros(n)]), np.column_stack([b, np.zeros(n)]),
                     np.column_stack([b, np.full(n, thickness)]),
                     np.column_stack([a, np.full(n, thickness)])], axis=1)  # (n, 4, 3)
    verts.append(quad.reshape(-1, 3))
    normals.append(np.repeat(nrm, 4, axis=0))
    first = n + 4 * np.arange(n)[:, None]
    indices.append((first + np.array([0, 1, 2, 0, 2, 3])).reshape(-1))
    return (np.concatenate(verts).tolist(), np.concatenate(normals).tolist(),
            np.concatenate(indices).astype(int).tolist())
