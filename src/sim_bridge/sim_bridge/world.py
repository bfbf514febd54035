"""The in-process pybullet world of the sim bridge: table, one flat object, pusher, camera.

ROS-free. The sim bridge node, the perception data generator and the evaluation run it in
their own process (pybullet DIRECT mode through ``pybullet_utils.bullet_client``, so several
worlds can live in one process). API contract: ``docs/ARCHITECTURE.md``, section
"sim_bridge internals: the in-process world".

Frames and units
----------------
SI throughout (metres, radians, seconds, kilograms, newtons).

- ``world``: the table frame. Origin on the table surface (z = 0) at the workspace centre,
  x away from the robot, y to its left, z up.
- ``object``: origin at the area centroid of the object's outline *on the table surface*
  (the bottom face), axes of the object library entry. The object occupies
  ``0 <= z <= thickness``. The centre of mass sits at ``(c_x, c_y, thickness / 2)`` in this
  frame, ``c = ObjectSpec.com``; it enters pybullet through the base inertial frame
  (``baseInertialFramePosition``), so collision and visual shapes stay in the object frame.
  ``object_pose()`` is ``(x, y, theta)`` of this frame in ``world``. Note that pybullet's
  ``getBasePositionAndOrientation`` reports the *inertial* (COM) frame; this module converts.
- ``pusher``: on the pusher axis at table height; ``pusher_position()`` is its (x, y).
- ``camera_color_optical_frame``: REP 103 optical frame (z forward, x right, y down), see
  :mod:`sim_bridge.camera`. ``T_world_camera`` maps optical-frame points to ``world``.

Quaternions are (x, y, z, w), the order of both pybullet and ROS messages.

Physics model
-------------
- Table: an infinite static plane (collision) drawn as a 1.5 m x 1.5 m slab.
- Object: a compound of convex prisms, one per piece of
  ``shape.convex_pieces(tolerance=COLLISION_TOLERANCE)`` (a true convex decomposition of the
  outline simplified to within 0.5 mm, so non-convex outlines such as butter keep their
  concavities), with a collision margin of 0.1 mm (pybullet's default 1 mm inflates the
  outline by 1 mm). Visual: a mesh of the true outline (top face triangulated, side walls;
  within 0.02 mm), so images show the exact outline. Mass from the spec; inertia diagonal
  ``(I_xx, I_yy, I_zz)`` about the COM with ``I_zz = ObjectSpec.moment_of_inertia`` and the
  tilt inertias of the uniform plate.
  Linear/angular damping 0, restitution 0, spinning and rolling friction 0. The object has a
  friction anchor (``changeDynamics(frictionAnchor=1)``): without it a resting rect1 creeps
  on the table by about 0.3 deg and 0.2 mm in 8 s with nothing touching it (bullet's support
  contacts switch between two and four corners); with it the creep is below 0.03 mm.
- Friction: bullet combines the lateral friction coefficients of two touching bodies by
  multiplying them. The object's coefficient is therefore 1.0, the table's is
  ``friction_table`` and the pusher's is ``friction_pusher``, so the object-table pair sees
  ``friction_table`` and the pusher-object pair ``friction_pusher``. The pusher never touches
  the table (collisions between them are disabled; it hovers 2 mm above it).
- Pusher: a dynamic vertical cylinder (radius ``pusher_radius``, 60 mm long, 0.1 kg) held by
  a force-limited fixed constraint to the world whose pivot is moved every physics step
  (``changeConstraint(jointChildPivot=..., maxForce=PUSHER_MAX_FORCE)``), like a stiff,
  position-controlled robot finger: every contact with the object is resolved by the solver,
  the pusher is never teleported through the object.
- Time: fixed step ``WorldConfig.time_step`` (default 1/240 s), ``solver_iterations`` (default
  10) sequential-impulse iterations; ``sim_time`` is ``steps * time_step``. The settings are
  justified in docs/RESULTS.md (section bench_sim) by a convergence study: against a
  1/960 s, 100-iteration reference, final poses differ by about 1 mm / 1 deg (median), the
  same as moving the push sideways by 0.1 mm does at fixed settings (the contact dynamics are
  that sensitive), while 1/120 s is clearly worse and 20 iterations are no better but slower.

Push execution (``execute_push(approach, contact, end)``)
---------------------------------------------------------
1. Validate (``ValueError`` with a message naming the argument, nothing is moved): finite
   (2,) points inside ``workspace``; push length ``|end - contact|`` in
   ``[MIN_PUSH_LENGTH, max_push_length]``; ``|contact - approach| <= MAX_APPROACH_DISTANCE``;
   ``contact`` within ``COLLINEAR_TOLERANCE`` of the line approach -> end; ``approach``
   outside the object's current outline by at least ``pusher_radius + APPROACH_MARGIN``.
2. Travel: the pusher is parked high above the robot side of the table (out of the camera's
   view). It is moved in the air, above the object's top plus ``LIFT_CLEARANCE``, to above
   the approach point. This air transfer is a teleport (instantaneous in simulated time);
   nothing can be in the way up there.
3. Lower physically at ``LIFT_SPEED`` to 2 mm above the table at the approach point.
4. Push: the pivot moves on the straight line approach -> end at ``push_speed`` (20 mm/s).
   ``pusher_start`` / ``t_start`` and ``pusher_end`` / ``t_end`` are the pusher's *measured*
   position and the sim time when this motion starts and ends (the pusher lags the pivot by
   a fraction of a millimetre under load).
5. Retract: back off 1 mm along the push direction at ``RETRACT_SPEED``, lift at
   ``LIFT_SPEED``, park (air teleport).
6. Settle: step until the object is at rest (speed below ``REST_SPEED`` and ``REST_ANGULAR``
   for ``REST_STEPS`` consecutive steps) or ``settle_timeout`` has passed.

Randomisation (``WorldConfig.randomize``; explicit overrides always win)
------------------------------------------------------------------------
Drawn from independent streams of ``numpy.random.SeedSequence(seed)`` (physics, appearance,
camera, sensor noise), so switching one kind of randomisation on does not change the others:

- mass: the spec's mass times a log-uniform factor in ``MASS_FACTOR_RANGE`` = [0.5, 2];
- COM: uniform over the object's outline shrunk by ``COM_SHRINK`` = 30 % about the area
  centroid (scaled by 0.7);
- friction_table uniform in ``FRICTION_TABLE_RANGE`` = [0.15, 0.4];
- friction_pusher uniform in ``FRICTION_PUSHER_RANGE`` = [0.15, 0.5].

``randomize_appearance``: table and object colour (HSV; the object's brightness differs
from the table's by at least 0.1), light direction (azimuth uniform, elevation 30-90 deg),
light colour (each channel in [0.8, 1]), ambient/diffuse/specular coefficients, shadows on or
off, and Gaussian colour noise (sigma 2 grey levels) per frame. ``randomize_camera``: the
camera pose jitters by ``CameraConfig.jitter_position`` / ``jitter_angle_deg`` (standard
deviations); ``T_world_camera`` reports the jittered (true) pose. ``depth_noise``:
RealSense-like depth noise and dropouts (:func:`sim_bridge.camera.add_depth_noise`), fresh
per frame. ``reset`` with the same config reproduces everything exactly.
"""

from __future__ import annotations

import colorsys
import contextlib
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pybullet as p
from numpy.typing import ArrayLike, NDArray
from pybullet_utils.bullet_client import BulletClient

from push_core.geometry import closest_point_on_polyline, object_to_world
from push_core.objects import ObjectSpec, load_object
from push_core.shapes import Ellipse, Polygon
from sim_bridge.camera import (
    CameraConfig,
    add_depth_noise,
    depth_from_zbuffer,
    intrinsics,
    jittered,
    look_at_pose,
    opengl_projection,
    opengl_view,
)

__all__ = [
    "APPROACH_MARGIN",
    "COM_SHRINK",
    "FRICTION_PUSHER_RANGE",
    "FRICTION_TABLE_RANGE",
    "MASS_FACTOR_RANGE",
    "MIN_PUSH_LENGTH",
    "CameraConfig",
    "Frame",
    "PushResult",
    "PushWorld",
    "WorldConfig",
    "push_points",
    "quiet_stdout",
]

#: Randomisation ranges (see the module docstring).
MASS_FACTOR_RANGE = (0.5, 2.0)
COM_SHRINK = 0.3
FRICTION_TABLE_RANGE = (0.15, 0.4)
FRICTION_PUSHER_RANGE = (0.15, 0.5)

#: Shortest accepted push ``|end - contact|``, metres.
MIN_PUSH_LENGTH = 1e-3
#: Longest accepted distance from the approach point to the contact point, metres.
MAX_APPROACH_DISTANCE = 0.1
#: Largest distance of the contact point from the line approach -> end, metres.
COLLINEAR_TOLERANCE = 2e-3
#: Extra clearance beyond the pusher radius between the approach point and the outline, m.
APPROACH_MARGIN = 5e-4

#: Pusher geometry and drive.
PUSHER_LENGTH = 0.06
PUSHER_MASS = 0.1
PUSHER_GAP = 0.002  # bottom of the pusher above the table while pushing, m
PUSHER_MAX_FORCE = 100.0  # N, force limit of the driving constraint
PUSHER_PARK = (-0.45, 0.0, 0.30)  # parked pusher: axis x, y and bottom height, m
LIFT_SPEED = 0.5  # m/s, lowering and lifting
RETRACT_SPEED = 0.1  # m/s, backing off after the push
LIFT_CLEARANCE = 0.01  # m above the object's top while travelling
BACK_OFF = 1e-3  # m, retreat along -push direction before lifting

#: Rest detection after a push.
REST_SPEED = 5e-4  # m/s
REST_ANGULAR = 5e-3  # rad/s
REST_STEPS = 5

#: Largest deviation of the collision outline from the true outline (Douglas-Peucker tolerance
#: passed to ``Polygon.convex_pieces``), m. push_core's default, 0.3 mm, cuts butter into 14
#: pieces (9 of them slivers along the concave waist); 0.5 mm gives 8 pieces and makes butter's
#: physics about 30 % faster, which keeps push + frame under 150 ms on the shared 2-core
#: machine. Convex polygons and ellipses are not simplified.
COLLISION_TOLERANCE = 5e-4
#: Largest deviation of the visual mesh's outline from the true outline, m.
VISUAL_TOLERANCE = 2e-5
#: Collision margin of the object's convex pieces, m (pybullet's default is 1 mm).
OBJECT_MARGIN = 1e-4
#: Steps run after building the scene so that resting contacts are established.
INITIAL_SETTLE_STEPS = 24

_TABLE_HALF_SIZE = 0.75
_DEFAULT_TABLE_RGB = (0.78, 0.74, 0.66)
_DEFAULT_OBJECT_RGB = (0.50, 0.52, 0.56)
_PUSHER_RGB = (0.15, 0.15, 0.17)



@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """Send file descriptor 1 to /dev/null for the block (pybullet's C code prints
    ``argv[0]=`` when a client connects; C-level prints bypass ``sys.stdout``). For callers that
    build worlds while writing their own output (evaluations with progress bars)."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)

@dataclass(frozen=True)
class WorldConfig:
    """Everything that defines a scene; ``PushWorld(cfg)`` builds it, ``reset(cfg)`` rebuilds.

    Attributes
    ----------
    object : str or Path
        Object library name or object specification file (``push_core.objects.load_object``).
    object_pose : (3,) tuple
        Initial ``(x, y, theta)`` of the object frame in ``world`` (m, m, rad); (x, y) must be
        inside ``workspace``.
    com_offset : (2,) tuple or None
        COM in the object frame (m); None keeps the spec's (or a randomised) COM.
    mass, friction_table, friction_pusher : float or None
        Overrides (kg, Coulomb coefficients); None keeps the spec's (or randomised) value.
    randomize : bool
        Randomise mass, COM and frictions from ``seed`` (ranges in the module docstring).
    seed : int
        Seed of every random draw of the world (>= 0).
    pusher_radius : float
        Radius of the cylindrical pusher, m.
    push_speed : float
        Speed of the straight push, m/s (quasi-static: keep it below about 0.05).
    camera : CameraConfig
        Intrinsics and viewpoint.
    depth_noise : bool
        RealSense-like depth noise and dropouts.
    randomize_appearance : bool
        Random colours, lighting and colour noise (perception training).
    randomize_camera : bool
        Random jitter of the camera pose (perception training).
    workspace : ((xmin, xmax), (ymin, ymax))
        Reachable rectangle of the pusher in ``world``, m.
    max_push_length : float
        Longest accepted push ``|end - contact|``, m.
    time_step : float
        Physics time step, s.
    solver_iterations : int
        Constraint solver iterations per step.
    settle_timeout : float
        Longest time to wait for the object to come to rest after a push, s.
    """

    object: str | Path = "rect1"
    object_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    com_offset: tuple[float, float] | None = None
    mass: float | None = None
    friction_table: float | None = None
    friction_pusher: float | None = None
    randomize: bool = False
    seed: int = 0
    pusher_radius: float = 0.0048
    push_speed: float = 0.02
    camera: CameraConfig = field(default_factory=CameraConfig)
    depth_noise: bool = False
    randomize_appearance: bool = False
    randomize_camera: bool = False
    workspace: tuple[tuple[float, float], tuple[float, float]] = ((-0.25, 0.25), (-0.3, 0.3))
    max_push_length: float = 0.2
    time_step: float = 1.0 / 240.0
    solver_iterations: int = 10
    settle_timeout: float = 2.0

    def __post_init__(self) -> None:
        pose = _finite_vector("object_pose", self.object_pose, 3)
        object.__setattr__(self, "object_pose", tuple(float(v) for v in pose))
        if self.com_offset is not None:
            com = _finite_vector("com_offset", self.com_offset, 2)
            object.__setattr__(self, "com_offset", tuple(float(v) for v in com))
        for name, low in (("mass", None), ("friction_table", 0.0), ("friction_pusher", 0.0)):
            value = getattr(self, name)
            if value is None:
                continue
            ok = np.isfinite(value) and (value > 0 if low is None else value >= low)
            if isinstance(value, bool) or not ok:
                rule = "> 0" if low is None else ">= 0"
                raise ValueError(f"{name}: must be a finite number {rule} or None, got {value!r}")
            object.__setattr__(self, name, float(value))
        if isinstance(self.seed, bool) or int(self.seed) != self.seed or self.seed < 0:
            raise ValueError(f"seed: expected an integer >= 0, got {self.seed!r}")
        object.__setattr__(self, "seed", int(self.seed))
        for name, low, high in (("pusher_radius", 1e-4, 0.05), ("push_speed", 1e-4, 0.5),
                                ("max_push_length", 2e-3, 1.0), ("time_step", 1e-4, 0.02),
                                ("settle_timeout", 0.0, 60.0)):
            value = getattr(self, name)
            if not (np.isfinite(value) and low <= value <= high):
                raise ValueError(f"{name}: must be in [{low}, {high}], got {value!r}")
            object.__setattr__(self, name, float(value))
        iters = self.solver_iterations
        if isinstance(iters, bool) or int(iters) != iters or not 1 <= iters <= 1000:
            raise ValueError(f"solver_iterations: expected an integer in [1, 1000], got {iters!r}")
        object.__setattr__(self, "solver_iterations", int(iters))
        try:
            ws = np.array(self.workspace, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"workspace: expected ((xmin, xmax), (ymin, ymax)), got "
                             f"{self.workspace!r}") from None
        if ws.shape != (2, 2) or not np.all(np.isfinite(ws)) or np.any(ws[:, 1] <= ws[:, 0]):
            raise ValueError(f"workspace: expected ((xmin, xmax), (ymin, ymax)) with min < max, "
                             f"got {self.workspace!r}")
        object.__setattr__(self, "workspace", tuple(tuple(float(v) for v in r) for r in ws))
        if not (ws[0, 0] <= pose[0] <= ws[0, 1] and ws[1, 0] <= pose[1] <= ws[1, 1]):
            raise ValueError(f"object_pose: position ({pose[0]:.3f}, {pose[1]:.3f}) m is outside "
                             f"the workspace {self.workspace}")
        if not isinstance(self.camera, CameraConfig):
            raise ValueError(f"camera: expected a CameraConfig, got {type(self.camera).__name__}")
        if not isinstance(self.object, str | Path):
            raise ValueError(f"object: expected a library name or a path, got {self.object!r}")


@dataclass(frozen=True)
class PushResult:
    """Outcome of :meth:`PushWorld.execute_push`. Points in ``world``, metres; times in s.

    Attributes
    ----------
    pusher_start, pusher_end : (2,) ndarray
        Measured pusher axis position when the straight push motion started and ended.
    t_start, t_end : float
        ``sim_time`` at those two instants.
    pose_before, pose_after : (3,) ndarray
        Object pose ``(x, y, theta)`` before the push and after it has settled.
    touched : bool
        Whether the pusher made contact with the object during the push.
    settled : bool
        Whether the object came to rest within ``settle_timeout`` (addition).
    t_done : float
        ``sim_time`` when the pusher was retracted and the object had settled (addition).
    approach, contact, end : (2,) ndarray
        The commanded points (addition).
    """

    pusher_start: NDArray[np.float64]
    pusher_end: NDArray[np.float64]
    t_start: float
    t_end: float
    pose_before: NDArray[np.float64]
    pose_after: NDArray[np.float64]
    touched: bool
    settled: bool = True
    t_done: float = 0.0
    approach: NDArray[np.float64] = field(default_factory=lambda: np.full(2, np.nan))
    contact: NDArray[np.float64] = field(default_factory=lambda: np.full(2, np.nan))
    end: NDArray[np.float64] = field(default_factory=lambda: np.full(2, np.nan))


@dataclass(frozen=True)
class Frame:
    """One RGB-D camera frame; all images in ``camera_color_optical_frame``.

    Attributes
    ----------
    rgb : (H, W, 3) uint8
    depth : (H, W) float32
        z-depth along the optical axis in metres; NaN where there is no return.
    mask : (H, W) bool
        Pixels that show the object.
    stamp : float
        ``sim_time`` of the frame, s.
    camera_matrix : (3, 3) ndarray
        K (addition).
    T_world_camera : (4, 4) ndarray
        world <- optical frame at the time of the frame (addition).
    object_pose : (3,) ndarray
        Ground-truth object pose at the time of the frame (addition).
    """

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    mask: NDArray[np.bool_]
    stamp: float
    camera_matrix: NDArray[np.float64] = field(default_factory=lambda: np.eye(3))
    T_world_camera: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))  # noqa: N815
    object_pose: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))


@dataclass(frozen=True)
class _Appearance:
    table_rgb: tuple[float, float, float] = _DEFAULT_TABLE_RGB
    object_rgb: tuple[float, float, float] = _DEFAULT_OBJECT_RGB
    light_direction: tuple[float, float, float] = (0.5, 0.3, 1.0)
    light_color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    ambient: float = 0.5
    diffuse: float = 0.55
    specular: float = 0.1
    shadow: bool = False
    rgb_noise: float = 0.0  # grey levels (sigma)


class PushWorld:
    """A pybullet world with one flat object, a cylindrical pusher and an RGB-D camera.

    Parameters
    ----------
    config : WorldConfig, optional
        Scene definition (default: rect1 at the origin).

    Raises
    ------
    ValueError
        Unknown object, invalid overrides (e.g. a COM outside the outline).

    Notes
    -----
    Not thread-safe: one pybullet client per world, so calls on one world must not overlap
    (the node serialises pushes, renders and resets). Different worlds are independent.
    """

    def __init__(self, config: WorldConfig | None = None) -> None:
        self._client: BulletClient | None = None
        self._config = WorldConfig() if config is None else config
        self.reset(self._config)

    # ------------------------------------------------------------------ scene
    def reset(self, config: WorldConfig | None = None) -> None:
        """Rebuild the scene from ``config`` (default: the current one); ``sim_time`` restarts
        (at 0.1 s: the new scene settles for ``INITIAL_SETTLE_STEPS`` steps).

        The same config (including the seed) reproduces the same world and the same push
        results exactly. On ``ValueError`` the previous scene is kept.
        """
        cfg = self._config if config is None else config
        if not isinstance(cfg, WorldConfig):
            raise ValueError(f"config: expected a WorldConfig, got {type(cfg).__name__}")
        streams = np.random.SeedSequence(cfg.seed).spawn(4)
        rng_phys, rng_look, rng_cam, rng_noise = (np.random.default_rng(s) for s in streams)
        spec = _simulated_spec(cfg, rng_phys)
        look = _random_appearance(rng_look) if cfg.randomize_appearance else _Appearance()
        t_cam = look_at_pose(cfg.camera)
        if cfg.randomize_camera:
            t_cam = jittered(t_cam, cfg.camera, rng_cam)

        if self._client is None:
            self._client = BulletClient(connection_mode=p.DIRECT)
        else:
            self._client.resetSimulation()
        self._config = cfg
        self._spec = spec
        self._look = look
        self._rng_noise = rng_noise
        self._k = intrinsics(cfg.camera)
        self._t_world_camera = t_cam
        self._view = opengl_view(t_cam)
        self._projection = opengl_projection(self._k, cfg.camera.width, cfg.camera.height,
                                             cfg.camera.near, cfg.camera.far)
        self._steps = 0
        self._build()

    def _build(self) -> None:
        c, cfg, spec = self._client, self._config, self._spec
        c.setPhysicsEngineParameter(fixedTimeStep=cfg.time_step,
                                    numSolverIterations=cfg.solver_iterations, numSubSteps=0,
                                    deterministicOverlappingPairs=1, enableFileCaching=0)
        c.setGravity(0.0, 0.0, -9.81)

        plane = c.createCollisionShape(p.GEOM_PLANE)
        slab = c.createVisualShape(p.GEOM_BOX, halfExtents=[_TABLE_HALF_SIZE] * 2 + [0.01],
                                   visualFramePosition=[0.0, 0.0, -0.01],
                                   rgbaColor=[*self._look.table_rgb, 1.0],
                                   specularColor=[0.05, 0.05, 0.05])
        self._table = c.createMultiBody(0.0, plane, slab, [0.0, 0.0, 0.0])
        c.changeDynamics(self._table, -1, lateralFriction=spec.friction_table,
                         spinningFriction=0.0, rollingFriction=0.0, restitution=0.0)

        self._object = self._create_object()

        radius = cfg.pusher_radius
        col = c.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=PUSHER_LENGTH)
        vis = c.createVisualShape(p.GEOM_CYLINDER, radius=radius, length=PUSHER_LENGTH,
                                  rgbaColor=[*_PUSHER_RGB, 1.0])
        park = self._park_position()
        self._pusher = c.createMultiBody(PUSHER_MASS, col, vis, park.tolist())
        c.changeDynamics(self._pusher, -1, lateralFriction=spec.friction_pusher,
                         spinningFriction=0.0, rollingFriction=0.0, restitution=0.0,
                         linearDamping=0.0, angularDamping=0.0)
        c.setCollisionFilterPair(self._pusher, self._table, -1, -1, 0)
        self._drive = c.createConstraint(self._pusher, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0],
                                         [0, 0, 0], park.tolist())
        self._target = park.copy()
        c.changeConstraint(self._drive, park.tolist(), maxForce=PUSHER_MAX_FORCE)
        self._step(INITIAL_SETTLE_STEPS)

    def _create_object(self) -> int:
        c, spec = self._client, self._spec
        t = spec.thickness
        tmp = Path(tempfile.mkdtemp(prefix="pushbot_sim_"))
        try:
            obj_file = tmp / "collision.obj"
            obj_text, (verts, normals, indices) = _object_geometry(spec.shape, t)
            obj_file.write_text(obj_text)
            col = c.createCollisionShape(p.GEOM_MESH, fileName=str(obj_file))
            vis = c.createVisualShape(p.GEOM_MESH, vertices=verts, normals=normals,
                                      indices=indices, rgbaColor=[*self._look.object_rgb, 1.0],
                                      specularColor=[0.4, 0.4, 0.4])
            x, y, theta = self._config.object_pose
            body = c.createMultiBody(
                spec.mass, col, vis, [x, y, OBJECT_MARGIN], _yaw_quaternion(theta),
                baseInertialFramePosition=[float(spec.com[0]), float(spec.com[1]), t / 2.0])
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        if body < 0:
            raise RuntimeError("pybullet could not create the object body")
        self._inertial_offset = np.array([spec.com[0], spec.com[1], t / 2.0])
        c.changeDynamics(body, -1, lateralFriction=1.0, spinningFriction=0.0,
                         rollingFriction=0.0, restitution=0.0, linearDamping=0.0,
                         angularDamping=0.0, collisionMargin=OBJECT_MARGIN, frictionAnchor=1,
                         localInertiaDiagonal=_inertia_diagonal(spec).tolist())
        return body

    def close(self) -> None:
        """Disconnect from pybullet; the world cannot be used afterwards."""
        if self._client is not None:
            self._client.disconnect()
            self._client = None

    def __enter__(self) -> PushWorld:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -------------------------------------------------------------- properties
    @property
    def config(self) -> WorldConfig:
        """The configuration the current scene was built from."""
        return self._config

    @property
    def object_spec(self) -> ObjectSpec:
        """The object actually simulated (after overrides and randomisation)."""
        return self._spec

    @property
    def sim_time(self) -> float:
        """Simulated time since the last reset, s (grows with every physics step)."""
        return self._steps * self._config.time_step

    @property
    def camera_matrix(self) -> NDArray[np.float64]:
        """Camera matrix K (3, 3), pixels (OpenCV convention)."""
        return self._k.copy()

    @property
    def T_world_camera(self) -> NDArray[np.float64]:  # noqa: N802 - the contract's name
        """world <- camera_color_optical_frame (4, 4) homogeneous transform."""
        return self._t_world_camera.copy()

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) of the rendered images, pixels (addition)."""
        return self._config.camera.width, self._config.camera.height

    @property
    def workspace(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((xmin, xmax), (ymin, ymax)) reachable region of the pusher in ``world``, m."""
        return self._config.workspace

    # ------------------------------------------------------------------ state
    def object_pose(self) -> NDArray[np.float64]:
        """Ground-truth ``(x, y, theta)`` of the object frame in ``world`` (theta in (-pi, pi])."""
        pos, rot = self._object_frame()
        return np.array([pos[0], pos[1], np.arctan2(rot[1, 0], rot[0, 0])])

    def object_pose_3d(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Object frame position (3,) and quaternion (4,) = (x, y, z, w) in ``world`` (addition).

        The position is on the bottom face (z about 0); tilt is kept in the quaternion.
        """
        pos, _ = self._object_frame()
        _, quat = self._client.getBasePositionAndOrientation(self._object)
        return pos, np.array(quat)

    def object_outline(self) -> NDArray[np.float64]:
        """The object's outline polyline (P, 2) at its current pose in ``world`` (addition)."""
        return object_to_world(self.object_pose(), self._spec.polyline())

    def pusher_position(self) -> NDArray[np.float64]:
        """Measured (x, y) of the pusher axis in ``world``, m (the parked pose between pushes)."""
        pos, _ = self._client.getBasePositionAndOrientation(self._pusher)
        return np.array(pos[:2])

    def set_object_pose(self, pose: ArrayLike) -> None:
        """Teleport the object to ``(x, y, theta)`` at rest (addition; data generation, tests).

        Not a physical motion: use it only while the pusher is parked (between pushes). The
        object is placed on the table at rest and ``INITIAL_SETTLE_STEPS`` physics steps are
        run so that its resting contacts form.
        """
        pose = _finite_vector("pose", pose, 3)
        self._place_object(pose)
        self._step(INITIAL_SETTLE_STEPS)

    def place_pusher(self, xy: ArrayLike, lift: float = 0.0) -> None:
        """Teleport the pusher to stand at ``xy`` (world, m), its bottom ``PUSHER_GAP + lift``
        above the table (addition; data generation, tests).

        Not a physical motion and no physics step is run: the caller must make sure the pusher
        does not overlap the object (``ValueError`` if it would, with 0.3 mm of margin), and
        park it again (:meth:`park_pusher`) before the object moves.
        """
        xy = _finite_vector("xy", xy, 2)
        if not np.isfinite(lift) or lift < 0.0:
            raise ValueError(f"lift must be finite and >= 0, got {lift}")
        _, _, dist, _ = closest_point_on_polyline(self.object_outline(), xy)
        if dist <= self._config.pusher_radius + 3e-4:  # signed: negative inside
            raise ValueError(f"pusher at {xy.tolist()} would overlap the object")
        self._teleport_pusher(np.array([xy[0], xy[1], PUSHER_GAP + PUSHER_LENGTH / 2.0 + lift]))

    def park_pusher(self) -> None:
        """Teleport the pusher back to its parked position, out of view (addition)."""
        self._teleport_pusher(self._park_position())

    def _place_object(self, pose: NDArray[np.float64]) -> None:
        quat = _yaw_quaternion(pose[2])
        rot = np.array(self._client.getMatrixFromQuaternion(quat)).reshape(3, 3)
        com = np.array([pose[0], pose[1], OBJECT_MARGIN]) + rot @ self._inertial_offset
        self._client.resetBasePositionAndOrientation(self._object, com.tolist(), quat)
        self._client.resetBaseVelocity(self._object, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])

    def _object_frame(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        com, quat = self._client.getBasePositionAndOrientation(self._object)
        rot = np.array(self._client.getMatrixFromQuaternion(quat)).reshape(3, 3)
        return np.asarray(com) - rot @ self._inertial_offset, rot

    # ------------------------------------------------------------------ push
    def execute_push(self, approach: ArrayLike, contact: ArrayLike,
                     end: ArrayLike) -> PushResult:
        """Execute one straight push approach -> end (through contact) and let the object settle.

        Parameters
        ----------
        approach, contact, end : (2,) array_like
            Points in ``world``, metres: where the pusher is lowered (clear of the object),
            where it is expected to meet the object, and where the push ends.

        Returns
        -------
        PushResult

        Raises
        ------
        ValueError
            Non-finite or malformed points, points outside the workspace, a push shorter than
            1 mm or longer than ``max_push_length``, an approach point farther than 10 cm from
            the contact point, a contact point off the line approach -> end, or an approach
            point inside the object or closer than ``pusher_radius + 0.5 mm`` to its outline.
            Nothing has moved when it is raised.
        """
        a, c, e = self.check_push(approach, contact, end)
        pose_before = self.object_pose()
        z_push = PUSHER_GAP + PUSHER_LENGTH / 2.0
        z_clear = self._clear_height()
        self._teleport_pusher(np.array([a[0], a[1], z_clear]))
        self._move_pusher(np.array([a[0], a[1], z_push]), LIFT_SPEED)
        start, t_start = self.pusher_position(), self.sim_time
        touched = self._move_pusher(np.array([e[0], e[1], z_push]), self._config.push_speed,
                                    watch_contact=True)
        finish, t_end = self.pusher_position(), self.sim_time
        back = e - BACK_OFF * (e - a) / np.linalg.norm(e - a)
        self._move_pusher(np.array([back[0], back[1], z_push]), RETRACT_SPEED)
        self._move_pusher(np.array([back[0], back[1], z_clear]), LIFT_SPEED)
        self._teleport_pusher(self._park_position())
        settled = self._settle()
        return PushResult(pusher_start=start, pusher_end=finish, t_start=t_start, t_end=t_end,
                          pose_before=pose_before, pose_after=self.object_pose(),
                          touched=touched, settled=settled, t_done=self.sim_time,
                          approach=a, contact=c, end=e)

    def check_push(self, approach: ArrayLike, contact: ArrayLike,
                   end: ArrayLike) -> tuple[NDArray[np.float64], ...]:
        """Validate a push against the current scene without moving anything (addition).

        Returns
        -------
        approach, contact, end : (3 x) (2,) float64 ndarray

        Raises
        ------
        ValueError
            Exactly the errors of :meth:`execute_push`.
        """
        cfg = self._config
        pts = []
        for name, value in (("approach", approach), ("contact", contact), ("end", end)):
            try:
                pt = np.array(value, dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"{name}: expected a point (x, y) in metres, got {value!r}") \
                    from None
            if pt.shape != (2,):
                raise ValueError(f"{name}: expected a point (x, y) of shape (2,), got shape "
                                 f"{pt.shape}")
            if not np.all(np.isfinite(pt)):
                raise ValueError(f"{name}: must be finite, got {pt.tolist()}")
            (x0, x1), (y0, y1) = cfg.workspace
            if not (x0 <= pt[0] <= x1 and y0 <= pt[1] <= y1):
                raise ValueError(f"{name}: ({pt[0]:.4f}, {pt[1]:.4f}) m is outside the "
                                 f"workspace x in [{x0}, {x1}], y in [{y0}, {y1}] m")
            pts.append(pt)
        a, c, e = pts
        length = float(np.linalg.norm(e - c))
        if length < MIN_PUSH_LENGTH:
            raise ValueError(f"push too short: |end - contact| = {1e3 * length:.3f} mm < "
                             f"{1e3 * MIN_PUSH_LENGTH:.0f} mm")
        if length > cfg.max_push_length:
            raise ValueError(f"push too long: |end - contact| = {length:.4f} m > "
                             f"max_push_length = {cfg.max_push_length} m")
        gap = float(np.linalg.norm(c - a))
        if gap > MAX_APPROACH_DISTANCE:
            raise ValueError(f"approach: {gap:.4f} m from the contact point, at most "
                             f"{MAX_APPROACH_DISTANCE} m allowed")
        stroke = e - a
        off_line = abs(stroke[0] * (c - a)[1] - stroke[1] * (c - a)[0]) / np.linalg.norm(stroke)
        if off_line > COLLINEAR_TOLERANCE:
            raise ValueError(f"contact: {1e3 * off_line:.1f} mm off the straight line approach "
                             f"-> end (tolerance {1e3 * COLLINEAR_TOLERANCE:.0f} mm); the pusher "
                             "moves on that line")
        _, _, dist, _ = closest_point_on_polyline(self.object_outline(), a)
        need = cfg.pusher_radius + APPROACH_MARGIN
        if dist < 0:
            raise ValueError(f"approach: ({a[0]:.4f}, {a[1]:.4f}) m is inside the object; the "
                             "pusher must be lowered outside it")
        if dist < need:
            raise ValueError(f"approach: ({a[0]:.4f}, {a[1]:.4f}) m is {1e3 * float(dist):.2f} "
                             f"mm from the object's outline; it must be at least "
                             f"{1e3 * need:.1f} mm (pusher radius + {1e3 * APPROACH_MARGIN} mm) "
                             "away so the pusher can be lowered without touching the object")
        return a, c, e

    def _clear_height(self) -> float:
        """Height of the pusher's centre when its bottom is clear above the object, m."""
        top = self._client.getAABB(self._object)[1][2]
        return max(top, self._spec.thickness) + LIFT_CLEARANCE + PUSHER_LENGTH / 2.0

    def _park_position(self) -> NDArray[np.float64]:
        x, y, bottom = PUSHER_PARK
        return np.array([x, y, bottom + PUSHER_LENGTH / 2.0])

    def _teleport_pusher(self, target: NDArray[np.float64]) -> None:
        """Move the pusher instantly; only ever called with both ends above everything."""
        c = self._client
        c.resetBasePositionAndOrientation(self._pusher, target.tolist(), [0.0, 0.0, 0.0, 1.0])
        c.resetBaseVelocity(self._pusher, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        c.changeConstraint(self._drive, target.tolist(), maxForce=PUSHER_MAX_FORCE)
        self._target = target.copy()

    def _move_pusher(self, target: NDArray[np.float64], speed: float,
                     watch_contact: bool = False) -> bool:
        """Move the constraint pivot in a straight line to ``target`` at ``speed``, stepping
        the physics; returns whether the pusher touched the object (if ``watch_contact``)."""
        cid = self._client._client  # direct pybullet calls: this loop runs every physics step
        dt = self._config.time_step
        start = self._target
        n = max(1, int(np.ceil(np.linalg.norm(target - start) / (speed * dt) - 1e-9)))
        touched = False
        for i in range(1, n + 1):
            pivot = (start + (target - start) * (i / n)).tolist()
            p.changeConstraint(self._drive, pivot, maxForce=PUSHER_MAX_FORCE,
                               physicsClientId=cid)
            p.stepSimulation(physicsClientId=cid)
            self._steps += 1
            if watch_contact and not touched:
                touched = any(pt[9] > 0.0 for pt in p.getContactPoints(
                    self._pusher, self._object, physicsClientId=cid))
        self._target = target.copy()
        return touched

    def _settle(self) -> bool:
        c = self._client
        calm = 0
        for _ in range(int(np.ceil(self._config.settle_timeout / self._config.time_step))):
            lin, ang = c.getBaseVelocity(self._object)
            if np.linalg.norm(lin) < REST_SPEED and np.linalg.norm(ang) < REST_ANGULAR:
                calm += 1
                if calm >= REST_STEPS:
                    return True
            else:
                calm = 0
            self._step(1)
        return False

    def _step(self, n: int) -> None:
        for _ in range(n):
            self._client.stepSimulation()
        self._steps += n

    # ---------------------------------------------------------------- camera
    def render(self) -> Frame:
        """Render one RGB-D frame with pybullet's TinyRenderer (CPU).

        Returns
        -------
        Frame
            rgb (H, W, 3) uint8; depth (H, W) float32 z-depth in metres with NaN where no
            surface is hit (and where ``depth_noise`` drops pixels); mask (H, W) bool of the
            object's pixels; stamp = ``sim_time``.
        """
        cfg, look = self._config, self._look
        w, h = cfg.camera.width, cfg.camera.height
        _, _, rgba, zbuf, seg = self._client.getCameraImage(
            w, h, viewMatrix=self._view, projectionMatrix=self._projection,
            renderer=p.ER_TINY_RENDERER, lightDirection=list(look.light_direction),
            lightColor=list(look.light_color), lightDistance=2.0, shadow=int(look.shadow),
            lightAmbientCoeff=look.ambient, lightDiffuseCoeff=look.diffuse,
            lightSpecularCoeff=look.specular)
        rgb = np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3]
        seg = np.asarray(seg).reshape(h, w)
        depth = depth_from_zbuffer(np.asarray(zbuf).reshape(h, w), cfg.camera.near,
                                   cfg.camera.far)
        depth[seg < 0] = np.nan
        if cfg.depth_noise:
            depth = add_depth_noise(depth, self._rng_noise)
        if look.rgb_noise > 0:
            noisy = rgb + look.rgb_noise * self._rng_noise.standard_normal(rgb.shape)
            rgb = np.clip(np.round(noisy), 0, 255).astype(np.uint8)
        else:
            rgb = np.ascontiguousarray(rgb)
        return Frame(rgb=rgb, depth=depth, mask=seg == self._object, stamp=self.sim_time,
                     camera_matrix=self.camera_matrix, T_world_camera=self.T_world_camera,
                     object_pose=self.object_pose())


# ---------------------------------------------------------------- helpers
_LIBRARY_CACHE: dict[str, ObjectSpec] = {}
_GEOMETRY_CACHE: dict[tuple[int, float], tuple[object, str, tuple]] = {}


def _load_object(name_or_path: str | Path) -> ObjectSpec:
    """``load_object`` with library objects cached (validating butter's 637-vertex outline
    takes about 0.1 s); specification files are read every time, they may have changed."""
    key = str(name_or_path)
    if key in _LIBRARY_CACHE:
        return _LIBRARY_CACHE[key]
    spec = load_object(name_or_path)
    if spec.source == f"library:{key}":
        _LIBRARY_CACHE[key] = spec
    return spec


def _object_geometry(shape: Polygon | Ellipse, thickness: float) -> tuple[str, tuple]:
    """Collision OBJ text and visual mesh of a shape, cached per shape object (randomised
    specs share their library shape), at most 32 entries."""
    key = (id(shape), thickness)
    hit = _GEOMETRY_CACHE.get(key)
    if hit is not None and hit[0] is shape:
        return hit[1], hit[2]
    pieces = (shape.convex_pieces() if isinstance(shape, Ellipse)
              else shape.convex_pieces(tolerance=COLLISION_TOLERANCE))
    geometry = (_prisms_obj(pieces, thickness), _extruded_mesh(shape, thickness))
    if len(_GEOMETRY_CACHE) >= 32:
        _GEOMETRY_CACHE.pop(next(iter(_GEOMETRY_CACHE)))
    _GEOMETRY_CACHE[key] = (shape, *geometry)
    return geometry


def push_points(pose: ArrayLike, point: ArrayLike, normal: ArrayLike, angle: float,
                length: float, pusher_radius: float = 0.0048,
                gap: float = 0.01) -> tuple[NDArray[np.float64], ...]:
    """World points ``(approach, contact, end)`` of the pusher axis for a push at an outline
    point (addition; used by the benchmarks and handy for data generation).

    Parameters
    ----------
    pose : (3,) array_like
        Object pose ``(x, y, theta)`` in ``world``.
    point, normal : (2,) array_like
        Outline point and its *outward* unit normal in the object frame.
    angle : float
        Push direction relative to the inward normal ``-normal``, radians (counter-clockwise).
    length : float
        Push length ``|end - contact|``, metres.
    pusher_radius : float
        The pusher axis touches a flat face at ``point + pusher_radius * normal``: that is the
        returned contact point.
    gap : float
        Distance of the approach point before the contact point along the push, metres.

    Returns
    -------
    approach, contact, end : (2,) float64 ndarrays in ``world``, collinear.
    """
    pose = _finite_vector("pose", pose, 3)
    n = _finite_vector("normal", normal, 2)
    n = n / np.linalg.norm(n)
    c, s = np.cos(angle), np.sin(angle)
    direction = -np.array([c * n[0] - s * n[1], s * n[0] + c * n[1]])
    contact = _finite_vector("point", point, 2) + pusher_radius * n
    local = np.stack([contact - gap * direction, contact, contact + length * direction])
    approach_w, contact_w, end_w = object_to_world(pose, local)
    return approach_w, contact_w, end_w


def _finite_vector(name: str, value: ArrayLike, size: int) -> NDArray[np.float64]:
    try:
        out = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {size} numbers, got {value!r}") from None
    if out.shape != (size,) or not np.all(np.isfinite(out)):
        raise ValueError(f"{name}: expected {size} finite numbers, got {value!r}")
    return out


def _yaw_quaternion(theta: float) -> list[float]:
    """Quaternion (x, y, z, w) of a rotation by ``theta`` about z."""
    return [0.0, 0.0, float(np.sin(theta / 2.0)), float(np.cos(theta / 2.0))]


def _simulated_spec(cfg: WorldConfig, rng: np.random.Generator) -> ObjectSpec:
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


def _random_appearance(rng: np.random.Generator) -> _Appearance:
    table = colorsys.hsv_to_rgb(rng.random(), rng.uniform(0.0, 0.5), rng.uniform(0.3, 0.95))
    while True:
        obj = colorsys.hsv_to_rgb(rng.random(), rng.uniform(0.0, 0.6), rng.uniform(0.2, 0.9))
        if abs(max(obj) - max(table)) >= 0.1:
            break
    az, el = rng.uniform(0.0, 2 * np.pi), np.radians(rng.uniform(30.0, 90.0))
    direction = (np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el))
    return _Appearance(
        table_rgb=tuple(float(v) for v in table), object_rgb=tuple(float(v) for v in obj),
        light_direction=tuple(float(v) for v in direction),
        light_color=tuple(float(v) for v in rng.uniform(0.8, 1.0, 3)),
        ambient=float(rng.uniform(0.3, 0.7)), diffuse=float(rng.uniform(0.3, 0.7)),
        specular=float(rng.uniform(0.0, 0.5)), shadow=bool(rng.random() < 0.5),
        rgb_noise=2.0)


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

    Dense measured outlines are simplified to within ``VISUAL_TOLERANCE`` (0.02 mm, 1/65 of a
    pixel at the default viewpoint): butter's 637 vertices become 100, which makes its frame
    about 10 ms cheaper to render and its scene faster to build.

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
