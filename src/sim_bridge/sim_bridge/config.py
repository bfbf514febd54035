"""The definition of a simulated scene, :class:`WorldConfig`, and its validation rules.

ROS-free. :class:`sim_bridge.world.PushWorld` builds a scene from it, and the modules that build
and step the scene (:mod:`sim_bridge.scene`, :mod:`sim_bridge.physics`) read it; it sits below
all of them, so none of them imports the world facade. Frames and units: the
:mod:`sim_bridge.world` module docstring.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.geometry import check_quaternion
from sim_bridge.arm_robot import DEFAULT_BASE_POSE, DEFAULT_PARK
from sim_bridge.camera import CameraConfig

__all__ = ["SUPPORT_CELL_RANGE", "WorldConfig", "check_support_cell", "finite_vector"]

#: Accepted ``WorldConfig.support_cell`` sizes (m) other than 0 (pieces kept whole).
SUPPORT_CELL_RANGE = (0.005, 0.05)


def check_support_cell(cell: object) -> float:
    """``WorldConfig.support_cell`` as a float: 0 or in :data:`SUPPORT_CELL_RANGE` (m);
    ``ValueError`` naming it otherwise (a bool, not a number, out of range)."""
    low, high = SUPPORT_CELL_RANGE
    number = not isinstance(cell, bool) and isinstance(cell, int | float | np.number)
    if not (number and (cell == 0 or low <= cell <= high)):
        raise ValueError(f"support_cell must be 0 or in [{low}, {high}] m (0: the pieces "
                         f"whole), got {cell!r}")
    return float(cell)


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
    look : str
        ``"default"`` (the training appearance: plain, or random with ``randomize_appearance``)
        or ``"site"``: a look the segmentation network never saw, drawn from ``seed``
        (textured table, metallic object, coloured light, strong shadows;
        :mod:`sim_bridge.site_look`); ``randomize_appearance`` is then ignored.
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
    robot : str
        ``"pusher"`` (the free cylinder driven by
        :meth:`~sim_bridge.world.PushWorld.execute_push`) or ``"arm"`` (a Panda with the pusher
        rod, driven by joint trajectories through :meth:`~sim_bridge.world.PushWorld.run_arm`;
        :mod:`sim_bridge.arm_robot`).
    arm_base_pose : (4,) tuple
        Arm mode: (x, y, z, yaw) of the arm's base in ``world``, m and rad.
    arm_park : (7,) tuple
        Arm mode: joint positions after a reset, rad.
    support_cell : float
        0 (default): the object's collision is its convex pieces, each resting on 3-4 of its
        corners (bullet's contact manifold); > 0: the pieces cut into grid cells of this size,
        m, in :data:`SUPPORT_CELL_RANGE`, so the table supports the whole footprint
        (:func:`sim_bridge.scene.support_cells`).
    camera_pose : (7,) tuple or None
        The camera's optical frame in ``world`` (x, y, z, qx, qy, qz, qw; m, unit
        quaternion), replacing ``camera``'s look-at viewpoint; None keeps it.
    calibration_board : bool
        Arm mode: the ChArUco calibration board on the tool
        (:mod:`sim_bridge.calibration_board`).
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
    look: str = "default"
    randomize_camera: bool = False
    workspace: tuple[tuple[float, float], tuple[float, float]] = ((-0.25, 0.25), (-0.3, 0.3))
    max_push_length: float = 0.2
    time_step: float = 1.0 / 240.0
    solver_iterations: int = 10
    settle_timeout: float = 2.0
    robot: str = "pusher"
    arm_base_pose: tuple[float, float, float, float] = DEFAULT_BASE_POSE
    arm_park: tuple[float, ...] = DEFAULT_PARK
    support_cell: float = 0.0
    camera_pose: tuple[float, ...] | None = None
    calibration_board: bool = False

    def __post_init__(self) -> None:
        if self.look not in ("default", "site"):
            raise ValueError(f"look: expected 'default' or 'site', got {self.look!r}")
        if self.robot not in ("pusher", "arm"):
            raise ValueError(f"robot: expected 'pusher' or 'arm', got {self.robot!r}")
        for name, size in (("arm_base_pose", 4), ("arm_park", 7)):
            value = finite_vector(name, getattr(self, name), size)
            object.__setattr__(self, name, tuple(float(v) for v in value))
        pose = finite_vector("object_pose", self.object_pose, 3)
        object.__setattr__(self, "object_pose", tuple(float(v) for v in pose))
        if self.com_offset is not None:
            com = finite_vector("com_offset", self.com_offset, 2)
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
        object.__setattr__(self, "support_cell", check_support_cell(self.support_cell))
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
        if self.camera_pose is not None:
            pose = finite_vector("camera_pose", self.camera_pose, 7)
            pose[3:] = check_quaternion(pose[3:])
            object.__setattr__(self, "camera_pose", tuple(float(v) for v in pose))
        if self.calibration_board and self.robot != "arm":
            raise ValueError("calibration_board: the board is carried by the arm (robot 'arm')")
        if not isinstance(self.object, str | Path):
            raise ValueError(f"object: expected a library name or a path, got {self.object!r}")


def finite_vector(name: str, value: ArrayLike, size: int) -> NDArray[np.float64]:
    """``value`` as a (size,) float64 array; ``ValueError`` naming ``name`` unless it holds
    exactly ``size`` finite numbers."""
    try:
        out = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {size} numbers, got {value!r}") from None
    if out.shape != (size,) or not np.all(np.isfinite(out)):
        raise ValueError(f"{name}: expected {size} finite numbers, got {value!r}")
    return out
