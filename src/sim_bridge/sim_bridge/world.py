"""The in-process pybullet world of the sim bridge: table, one flat object, pusher, camera.

ROS-free. The sim bridge node, the perception data generator and the evaluation run it in
their own process (pybullet DIRECT mode through ``pybullet_utils.bullet_client``, so several
worlds can live in one process). API contract: ``docs/design/sim-world.md``.

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

Structure
---------
This module is the facade: :class:`PushWorld` and the scene definition :class:`WorldConfig`
(:mod:`sim_bridge.config`), whose methods delegate to

- :mod:`sim_bridge.scene`: the pybullet scene builder (table, pusher, the object as convex
  pieces with its visual mesh, masses, inertias, frictions) and the randomisation of the
  simulated object (mass, COM, frictions);
- :mod:`sim_bridge.physics`: stepping, the pusher drive, push validation and execution,
  settling; :class:`PushResult`;
- :mod:`sim_bridge.rendering`: appearance, camera view, RGB-D frames; :class:`Frame`.

Every public name of these (``PushResult``, ``Frame``, ``MIN_PUSH_LENGTH``, the randomisation
ranges, ...) is importable from here as before. Speed and the choice of the physics settings:
docs/results/bench_sim.md.

Randomisation (``WorldConfig.randomize``; explicit overrides always win)
------------------------------------------------------------------------
Drawn from independent streams of ``numpy.random.SeedSequence(seed)`` (physics, appearance,
camera, sensor noise), so switching one kind of randomisation on does not change the others:
mass, COM and frictions (:mod:`sim_bridge.scene`, ``randomize``); colours, lighting and colour
noise (:mod:`sim_bridge.rendering`, ``randomize_appearance``; or the unseen site look of
:mod:`sim_bridge.site_look`, ``look``); the camera pose jitters by
``CameraConfig.jitter_position`` / ``jitter_angle_deg`` (standard deviations; ``randomize_camera``;
``T_world_camera`` reports the jittered, true pose); depth noise and dropouts (``depth_noise``),
fresh per frame. ``reset`` with the same config reproduces everything exactly.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import replace

import numpy as np
import pybullet as p
from numpy.typing import ArrayLike, NDArray
from pybullet_utils.bullet_client import BulletClient

from push_core.calibration import BoardSpec
from push_core.geometry import closest_point_on_polyline, object_to_world
from push_core.objects import ObjectSpec
from sim_bridge.arm import TrajectoryFollower
from sim_bridge.arm_motion import ArmRun, run_arm
from sim_bridge.arm_robot import ArmRobot, JointState, arm_urdf
from sim_bridge.calibration_board import add_board, camera_pose_matrix, texture_board
from sim_bridge.camera import CameraConfig, jittered, look_at_pose
from sim_bridge.config import WorldConfig, finite_vector
from sim_bridge.physics import (
    APPROACH_MARGIN,
    BACK_OFF,
    COLLINEAR_TOLERANCE,
    LIFT_CLEARANCE,
    LIFT_SPEED,
    MAX_APPROACH_DISTANCE,
    MIN_PUSH_LENGTH,
    PUSHER_GAP,
    REST_ANGULAR,
    REST_SPEED,
    REST_STEPS,
    RETRACT_SPEED,
    Physics,
    PushResult,
    check_push,
)
from sim_bridge.rendering import (
    Appearance,
    Frame,
    MonitorConfig,
    camera_view,
    monitor_view,
    random_appearance,
    render,
    still_frame,
)
from sim_bridge.scene import (
    COLLISION_TOLERANCE,
    COM_SHRINK,
    FRICTION_PUSHER_RANGE,
    FRICTION_TABLE_RANGE,
    INITIAL_SETTLE_STEPS,
    MASS_FACTOR_RANGE,
    OBJECT_MARGIN,
    PUSHER_LENGTH,
    PUSHER_MASS,
    PUSHER_MAX_FORCE,
    PUSHER_PARK,
    VISUAL_TOLERANCE,
    build_scene,
    park_position,
    simulated_spec,
)
from sim_bridge.site_look import site_appearance

__all__ = [
    "APPROACH_MARGIN",
    "BACK_OFF",
    "COLLINEAR_TOLERANCE",
    "COLLISION_TOLERANCE",
    "COM_SHRINK",
    "FRICTION_PUSHER_RANGE",
    "FRICTION_TABLE_RANGE",
    "INITIAL_SETTLE_STEPS",
    "LIFT_CLEARANCE",
    "LIFT_SPEED",
    "MASS_FACTOR_RANGE",
    "MAX_APPROACH_DISTANCE",
    "MIN_PUSH_LENGTH",
    "OBJECT_MARGIN",
    "PUSHER_GAP",
    "PUSHER_LENGTH",
    "PUSHER_MASS",
    "PUSHER_MAX_FORCE",
    "PUSHER_PARK",
    "REST_ANGULAR",
    "REST_SPEED",
    "REST_STEPS",
    "RETRACT_SPEED",
    "VISUAL_TOLERANCE",
    "CameraConfig",
    "Frame",
    "MonitorConfig",
    "PushResult",
    "PushWorld",
    "WorldConfig",
    "push_points",
    "quiet_stdout",
]


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
        # A fifth stream for the frames of a resting scene (still_frame): spawn(5)'s first four
        # children are spawn(4)'s, so worlds and push frames are those without it.
        streams = np.random.SeedSequence(cfg.seed).spawn(5)
        rng_phys, rng_look, rng_cam, rng_noise, rng_still = (
            np.random.default_rng(s) for s in streams)
        spec = simulated_spec(cfg, rng_phys)
        if cfg.look == "site":
            look = site_appearance(rng_look)
        else:
            look = random_appearance(rng_look) if cfg.randomize_appearance else Appearance()
        t_cam = (look_at_pose(cfg.camera) if cfg.camera_pose is None
                 else camera_pose_matrix(cfg.camera_pose))
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
        self._rng_still = rng_still
        self._view = camera_view(cfg.camera, t_cam)
        scene = build_scene(self._client, cfg, spec, look)
        self._scene = scene
        self._object = scene.object  # pybullet body id (tests read the COM frame through it)
        self._physics = Physics(self._client, scene, cfg)
        self._arm: ArmRobot | None = None
        self._urdf = ""
        if cfg.robot == "arm":
            self._urdf = arm_urdf(cfg.pusher_radius)
            if cfg.calibration_board:
                self._urdf = add_board(self._urdf, BoardSpec())
            with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
                f.write(self._urdf)
            try:
                self._arm = ArmRobot(self._client, f.name, cfg.arm_base_pose, cfg.arm_park,
                                     spec.friction_pusher, scene.table, scene.object)
            finally:
                os.unlink(f.name)
            if cfg.calibration_board:
                texture_board(self._client, self._arm.body, BoardSpec())
        self._physics.step(INITIAL_SETTLE_STEPS)

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
        return self._physics.sim_time

    @property
    def camera_matrix(self) -> NDArray[np.float64]:
        """Camera matrix K (3, 3), pixels (OpenCV convention)."""
        return self._view.camera_matrix.copy()

    @property
    def T_world_camera(self) -> NDArray[np.float64]:  # noqa: N802 - the contract's name
        """world <- camera_color_optical_frame (4, 4) homogeneous transform."""
        return self._view.T_world_camera.copy()

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
        return self._physics.object_pose()

    def object_pose_3d(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Object frame position (3,) and quaternion (4,) = (x, y, z, w) in ``world`` (addition).

        The position is on the bottom face (z about 0); tilt is kept in the quaternion.
        """
        pos, _ = self._physics.object_frame()
        _, quat = self._client.getBasePositionAndOrientation(self._object)
        return pos, np.array(quat)

    def object_outline(self) -> NDArray[np.float64]:
        """The object's outline polyline (P, 2) at its current pose in ``world`` (addition)."""
        return object_to_world(self.object_pose(), self._spec.polyline())

    def support_contacts(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The object's contacts with the table now: points ``(K, 2)`` in ``world`` (m, on
        the object) and their normal forces ``(K,)`` (N) (addition: a diagnostic of how the
        simulator supports the object, docs/results/eval_push_support.md)."""
        points = self._client.getContactPoints(bodyA=self._object, bodyB=self._scene.table)
        xy = np.array([c[5][:2] for c in points], dtype=np.float64).reshape(-1, 2)
        return xy, np.array([c[9] for c in points], dtype=np.float64)

    def pusher_position(self) -> NDArray[np.float64]:
        """Measured (x, y) of the pusher axis in ``world``, m (the parked pose between pushes;
        in arm mode the tool tip's)."""
        if self._arm is not None:
            return self._arm.tip_position()[:2]
        return self._physics.pusher_position()

    # ------------------------------------------------------------------ arm mode
    @property
    def arm(self) -> ArmRobot | None:
        """The arm (arm mode) or None (pusher mode)."""
        return self._arm

    @property
    def robot_description(self) -> str:
        """The URDF the arm was loaded from (arm mode; "" in pusher mode)."""
        return self._urdf

    def arm_state(self) -> JointState:
        """Measured joint state of the arm (``ValueError`` in pusher mode)."""
        return self._require_arm().state()

    def run_arm(self, follower: TrajectoryFollower, sample_every: int = 1,
                on_sample: Callable[[float, JointState], None] | None = None,
                monitor: MonitorConfig | None = None,
                on_frame: Callable[[Frame], None] | None = None,
                real_time_factor: float = 0.0) -> ArmRun:
        """Step the physics while the arm follows ``follower``'s trajectories, until they
        have ended, the arm is still and the object has settled
        (:func:`sim_bridge.arm_motion.run_arm`; ``monitor`` / ``on_frame`` as in
        :meth:`execute_push`). ``real_time_factor`` > 0: sim time advances at most that many
        times faster than wall time (the steps wait), as a real arm's controller runs."""
        arm = self._require_arm()
        on_step = None
        if monitor is not None and on_frame is not None:
            on_step = self._monitor_hook(monitor, on_frame)
        if real_time_factor > 0.0:
            on_step = self._pacer(real_time_factor, on_step)
        return run_arm(self._physics, arm, follower, self._object,
                       self._config.settle_timeout, sample_every, on_sample, on_step)

    def _pacer(self, factor: float, inner: Callable[[], None] | None) -> Callable[[], None]:
        """A per-step hook that sleeps while sim time is ahead of ``factor`` x wall time."""
        wall0, sim0 = time.monotonic(), self.sim_time

        def on_step() -> None:
            if inner is not None:
                inner()
            ahead = (self.sim_time - sim0) / factor - (time.monotonic() - wall0)
            if ahead > 1e-3:
                time.sleep(ahead)

        return on_step

    def _require_arm(self) -> ArmRobot:
        if self._arm is None:
            raise ValueError("the world has no arm (robot = 'pusher')")
        return self._arm

    def set_object_pose(self, pose: ArrayLike) -> None:
        """Teleport the object to ``(x, y, theta)`` at rest (addition; data generation, tests).

        Not a physical motion: use it only while the pusher is parked (between pushes). The
        object is placed on the table at rest and ``INITIAL_SETTLE_STEPS`` physics steps are
        run so that its resting contacts form.
        """
        pose = finite_vector("pose", pose, 3)
        self._physics.place_object(pose, OBJECT_MARGIN)
        self._physics.step(INITIAL_SETTLE_STEPS)

    def place_pusher(self, xy: ArrayLike, lift: float = 0.0) -> None:
        """Teleport the pusher to stand at ``xy`` (world, m), its bottom ``PUSHER_GAP + lift``
        above the table (addition; data generation, tests).

        Not a physical motion and no physics step is run: the caller must make sure the pusher
        does not overlap the object (``ValueError`` if it would, with 0.3 mm of margin), and
        park it again (:meth:`park_pusher`) before the object moves.
        """
        xy = finite_vector("xy", xy, 2)
        if not np.isfinite(lift) or lift < 0.0:
            raise ValueError(f"lift must be finite and >= 0, got {lift}")
        _, _, dist, _ = closest_point_on_polyline(self.object_outline(), xy)
        if dist <= self._config.pusher_radius + 3e-4:  # signed: negative inside
            raise ValueError(f"pusher at {xy.tolist()} would overlap the object")
        self._physics.teleport_pusher(
            np.array([xy[0], xy[1], PUSHER_GAP + PUSHER_LENGTH / 2.0 + lift]))

    def park_pusher(self) -> None:
        """Teleport the pusher back to its parked position, out of view (addition)."""
        self._physics.teleport_pusher(park_position())

    # ------------------------------------------------------------------ push
    def execute_push(self, approach: ArrayLike, contact: ArrayLike, end: ArrayLike,
                     monitor: MonitorConfig | None = None,
                     on_frame: Callable[[Frame], None] | None = None) -> PushResult:
        """Execute one straight push approach -> end (through contact) and let the object settle.

        The motion (travel, lowering, the push, retract, settle) is described in
        :mod:`sim_bridge.physics`.

        Parameters
        ----------
        approach, contact, end : (2,) array_like
            Points in ``world``, metres: where the pusher is lowered (clear of the object),
            where it is expected to meet the object, and where the push ends.
        monitor : MonitorConfig, optional
            With ``on_frame``: render a monitor frame (:func:`sim_bridge.rendering.monitor_view`,
            no noise) every ``monitor.every(time_step)`` physics steps from the start of the
            push, while the pusher is lowered, pushes, retracts and the object settles, and
            hand it to ``on_frame`` at once (stamp = ``sim_time`` of the render, in
            ``(t0, t_done]`` with ``t0`` the ``sim_time`` when the push was called). Reading
            only: the push result and every later frame are bit-identical to a push without
            the monitor.
        on_frame : callable, optional
            Receives each monitor :class:`Frame` (rgb (h, w, 3) uint8, depth, mask, stamp,
            the monitor's K; same ``T_world_camera``), in the caller's thread, in time order.
            It must not raise: an exception propagates out of the physics loop and leaves the
            push unfinished (the pusher down), like any other exception there.

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
        if self._arm is not None:
            raise ValueError("arm mode: the arm executes joint trajectories, not pushes")
        a, c, e = self.check_push(approach, contact, end)
        on_step = None
        if monitor is not None and on_frame is not None:
            on_step = self._monitor_hook(monitor, on_frame)
        return self._physics.execute_push(a, c, e, self._spec.thickness, on_step)

    def _monitor_hook(self, monitor: MonitorConfig,
                      on_frame: Callable[[Frame], None]) -> Callable[[], None]:
        """The per-step callback of :meth:`execute_push` that renders the monitor frames."""
        cfg, physics = self._config, self._physics
        camera, view = monitor_view(cfg.camera, self._view, monitor)
        look = replace(self._look, rgb_noise=0.0)
        unused = np.random.default_rng(0)  # no noise is drawn: the world's stream is untouched
        every, first = monitor.every(cfg.time_step), physics.steps

        def on_step() -> None:
            if (physics.steps - first) % every == 0:
                on_frame(render(self._client, camera, view, look, self._object, False, unused,
                                physics.sim_time, physics.object_pose))

        return on_step

    def check_push(self, approach: ArrayLike, contact: ArrayLike,
                   end: ArrayLike) -> tuple[NDArray[np.float64], ...]:
        """Validate a push against the current scene without moving anything (addition):
        :func:`sim_bridge.physics.check_push`; the points as (2,) float64 arrays, or exactly
        the ``ValueError`` of :meth:`execute_push`."""
        return check_push(self._config, self.object_outline, approach, contact, end)

    # ---------------------------------------------------------------- camera
    def still_frame(self, frame: Frame) -> Frame:
        """Another camera frame of the resting scene: ``frame``'s clean images with fresh
        sensor noise from the world's own still-frame stream (never the push frames' stream,
        so push results and push frames are unchanged by how many still frames were made).

        No pybullet call: safe from another thread while no job steps the world.
        """
        cfg = self._config
        return still_frame(frame, cfg.depth_noise, self._look.rgb_noise, self._rng_still)

    def render(self) -> Frame:
        """Render one RGB-D frame with pybullet's TinyRenderer (CPU).

        Returns
        -------
        Frame
            rgb (H, W, 3) uint8; depth (H, W) float32 z-depth in metres with NaN where no
            surface is hit (and where ``depth_noise`` drops pixels); mask (H, W) bool of the
            object's pixels; stamp = ``sim_time``.
        """
        cfg = self._config
        return render(self._client, cfg.camera, self._view, self._look, self._object,
                      cfg.depth_noise, self._rng_noise, self.sim_time, self.object_pose)

    def arm_mask(self) -> NDArray[np.bool_]:
        """The arm's pixels in the camera image, (H, W) bool: the renderer's segmentation
        buffer, the ground truth of a robot self-filter (arm mode; ``ValueError`` in pusher
        mode; addition). Draws no sensor noise: later frames are unchanged."""
        arm = self._require_arm()
        cam = self._config.camera
        seg = self._client.getCameraImage(cam.width, cam.height, viewMatrix=self._view.view,
                                          projectionMatrix=self._view.projection,
                                          renderer=p.ER_TINY_RENDERER)[4]
        return np.asarray(seg).reshape(cam.height, cam.width) == arm.body


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
    pose = finite_vector("pose", pose, 3)
    n = finite_vector("normal", normal, 2)
    n = n / np.linalg.norm(n)
    c, s = np.cos(angle), np.sin(angle)
    direction = -np.array([c * n[0] - s * n[1], s * n[0] + c * n[1]])
    contact = finite_vector("point", point, 2) + pusher_radius * n
    local = np.stack([contact - gap * direction, contact, contact + length * direction])
    approach_w, contact_w, end_w = object_to_world(pose, local)
    return approach_w, contact_w, end_w
