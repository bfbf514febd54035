"""The self-filter of ``segmentation_node``, ROS-free: the robot's pixels in a camera frame.

The robot's model (``push_core.robot_view.RobotGeometry``: the URDF's collision geometry), posed
by the joint state measured at the frame's stamp, is rendered with the frame's K and
extrinsics into a mask and a depth (grown by ``dilate_px``). A pixel is the robot's when the
model covers it and the camera did not measure something clearly in front of the model there
(a measured depth more than ``depth_margin`` nearer: the object in front of the rod, say).
Those pixels are never object pixels: :func:`clear_robot` makes them neutral for the CNN (no
depth, the table's colour) and the tracker measures the object from the rest
(:mod:`push_perception.occlusion`). The design: docs/design/arm-in-view.md.

A frame whose robot pixels cannot be computed is refused with the reason, never measured as if
no robot were there (:class:`push_perception.inputs.InputError`): ``no_robot_model`` (no robot
description yet, or it could not be loaded), ``no_joint_state`` (none received),
``stale_joint_state`` (none within ``joint_state_tolerance`` of the frame's stamp),
``robot_pose`` (the joint state does not fit the model, or the robot cannot be drawn).

Joint states (:class:`JointStateBuffer`) are kept for the last ``JOINT_HISTORY`` messages; the
frame gets the positions interpolated linearly between the states just before and after its
stamp when both are within the tolerance, else those of the nearest state within it. A robot at
rest need not be sampled that often: when the last state before the frame reports every joint
slower than ``STILL_VELOCITY`` (its velocities are given) and is at most
``still_tolerance`` old, and no later state shows the robot elsewhere, its positions are the
frame's (the simulator publishes a resting arm's state at 10 Hz of wall time; a loaded machine
stretches that).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_core.robot_view import SIM_PANDA_BASE_POSE, RobotGeometry, dilate
from push_perception.inputs import InputError

__all__ = ["JOINT_HISTORY", "JointStateBuffer", "RobotFilter", "RobotFilterConfig",
           "RobotPixels", "clear_robot", "segment"]

#: Joint states kept (2 s at 500 Hz).
JOINT_HISTORY = 1000
#: A joint state stamped this long (s) before the newest one comes from a restarted clock (a
#: restarted simulator or driver starts near 0; the rule of
#: ``push_core.episode.PREVIOUS_EPISODE_WINDOW``): the old clock's states are forgotten.
CLOCK_RESTART = 2.0
#: Most joints in one joint state.
MAX_JOINTS = 256
#: Joint speed below which a joint state shows the robot at rest, rad/s (m/s).
STILL_VELOCITY = 0.01
#: Largest difference of the positions of two states of a robot that did not move, rad (m).
STILL_POSITION = 1e-3
#: Pixels sampled per axis for the table colour (every n-th row and column).
_COLOUR_STRIDE = 8


@dataclass(frozen=True)
class RobotFilterConfig:
    """Settings of the self-filter (SI units; the node's ``robot_filter.*`` parameters).

    Attributes
    ----------
    base_pose : (4,) tuple of float
        (x, y, z, yaw) of ``base_link`` in ``world``, m and rad.
    base_link : str
        URDF link at ``base_pose``; "" = the root link.
    package_dirs : tuple of str
        Folders searched for mesh files (``push_core.robot_view.RobotGeometry.from_urdf``).
    dilate_px : int
        Margin grown around the rendered robot, pixels, [0, 20].
    depth_margin : float
        A pixel measured this much nearer than the model is not the robot, m, [0, 0.5].
    joint_state_tolerance : float
        Largest time between the frame's stamp and the joint state used, s, (0, 5].
    still_tolerance : float
        The same for the last state before the frame when it shows the robot at rest, s,
        [0, 60] (module docstring).
    """

    base_pose: tuple[float, float, float, float] = SIM_PANDA_BASE_POSE
    base_link: str = ""
    package_dirs: tuple[str, ...] = ()
    dilate_px: int = 2
    depth_margin: float = 0.01
    joint_state_tolerance: float = 0.1
    still_tolerance: float = 2.0

    def __post_init__(self) -> None:
        pose = tuple(float(v) for v in self.base_pose)
        if len(pose) != 4 or not all(math.isfinite(v) for v in pose):
            raise ValueError(f"robot_filter.base_pose: expected 4 finite values (x, y, z, yaw), "
                             f"got {list(self.base_pose)[:8]}")
        object.__setattr__(self, "base_pose", pose)
        if isinstance(self.dilate_px, bool) or int(self.dilate_px) != self.dilate_px \
                or not 0 <= self.dilate_px <= 20:
            raise ValueError(f"robot_filter.dilate_px: must be an integer in [0, 20], got "
                             f"{self.dilate_px!r}")
        if not (math.isfinite(self.depth_margin) and 0.0 <= self.depth_margin <= 0.5):
            raise ValueError(f"robot_filter.depth_margin: must be in [0, 0.5] m, got "
                             f"{self.depth_margin!r}")
        if not (math.isfinite(self.joint_state_tolerance)
                and 0.0 < self.joint_state_tolerance <= 5.0):
            raise ValueError(f"robot_filter.joint_state_tolerance: must be in (0, 5] s, got "
                             f"{self.joint_state_tolerance!r}")
        if not (math.isfinite(self.still_tolerance) and 0.0 <= self.still_tolerance <= 60.0):
            raise ValueError(f"robot_filter.still_tolerance: must be in [0, 60] s, got "
                             f"{self.still_tolerance!r}")
        object.__setattr__(self, "package_dirs", tuple(str(d) for d in self.package_dirs))


class JointStateBuffer:
    """The last ``JOINT_HISTORY`` joint states, ordered by stamp (module docstring)."""

    def __init__(self) -> None:
        self._stamps: list[float] = []
        self._states: list[tuple[tuple[str, ...], NDArray[np.float64]]] = []
        self._still: list[bool] = []

    def __len__(self) -> int:
        return len(self._stamps)

    def add(self, stamp: float, names: Sequence[str], positions: Sequence[float],
            velocities: Sequence[float] = ()) -> None:
        """Keep one joint state (``stamp`` s; the positions of ``names``, rad or m; their
        velocities, rad/s or m/s, if given: one per name, else not known).

        Raises
        ------
        ValueError
            A non-finite stamp, names and positions of different lengths, more than
            ``MAX_JOINTS`` joints.
        """
        if not math.isfinite(stamp):
            raise ValueError(f"joint state stamp {stamp!r} is not finite")
        if len(names) > MAX_JOINTS:
            raise ValueError(f"{len(names)} joints (at most {MAX_JOINTS})")
        values = np.asarray(positions, dtype=np.float64).ravel()
        if len(values) != len(names):
            raise ValueError(f"{len(names)} names but {len(values)} positions")
        speed = np.asarray(velocities, dtype=np.float64).ravel()
        still = len(speed) == len(values) > 0 and bool(np.all(np.abs(speed) <= STILL_VELOCITY))
        if self._stamps and stamp < self._stamps[-1] - CLOCK_RESTART:
            self.clear()  # a restarted clock: the old one's states would pair with no frame
        i = bisect.bisect_right(self._stamps, stamp)
        self._stamps.insert(i, float(stamp))
        self._states.insert(i, (tuple(str(n) for n in names), values))
        self._still.insert(i, still)
        if len(self._stamps) > JOINT_HISTORY:
            del self._stamps[0], self._states[0], self._still[0]

    def clear(self) -> None:
        """Forget every state."""
        self._stamps.clear()
        self._states.clear()
        self._still.clear()

    def at(self, stamp: float, tolerance: float, still_tolerance: float = 0.0
           ) -> tuple[tuple[str, ...], NDArray[np.float64], float]:
        """The joint state at ``stamp`` (s): names, positions and the time it is from.

        Interpolated between the states just before and after ``stamp`` when both are
        within ``tolerance`` s and name the same joints; otherwise the nearest state within
        ``tolerance``; otherwise the state before ``stamp`` if it shows the robot at rest, is
        at most ``still_tolerance`` s old and a later state (if any) shows it at rest at the
        same positions (module docstring).

        Raises
        ------
        InputError
            ``no_joint_state`` (none yet), ``stale_joint_state`` (none within the tolerance).
        """
        if not self._stamps:
            raise InputError("no_joint_state", "no /joint_states received yet: the robot's "
                             "pixels cannot be computed")
        i = bisect.bisect_left(self._stamps, stamp)
        before = i - 1 if i > 0 else None
        after = i if i < len(self._stamps) else None
        if before is not None and after is not None:
            t0, t1 = self._stamps[before], self._stamps[after]
            (n0, q0), (n1, q1) = self._states[before], self._states[after]
            if stamp - t0 <= tolerance and t1 - stamp <= tolerance and n0 == n1:
                s = 0.0 if t1 == t0 else (stamp - t0) / (t1 - t0)
                return n0, (1.0 - s) * q0 + s * q1, stamp
        near = min((j for j in (before, after) if j is not None),
                   key=lambda j: abs(self._stamps[j] - stamp))
        gap = abs(self._stamps[near] - stamp)
        if gap > tolerance and before is not None and self._resting(before, after) \
                and stamp - self._stamps[before] <= still_tolerance:
            names, q = self._states[before]
            return names, q, self._stamps[before]
        if gap > tolerance:
            raise InputError("stale_joint_state", f"the nearest joint state is {gap:.3f} s from "
                             f"the frame (more than {tolerance:g} s): the robot's pixels "
                             "cannot be computed")
        names, q = self._states[near]
        return names, q, self._stamps[near]

    def _resting(self, before: int, after: int | None) -> bool:
        """The state ``before`` shows the robot at rest, and so does ``after`` (if any), at
        the same positions."""
        if not self._still[before]:
            return False
        if after is None:
            return True
        (n0, q0), (n1, q1) = self._states[before], self._states[after]
        return self._still[after] and n0 == n1 and bool(np.all(np.abs(q1 - q0)
                                                                <= STILL_POSITION))


@dataclass(frozen=True)
class RobotPixels:
    """The robot in one frame.

    Attributes
    ----------
    mask : (H, W) bool
        The robot's pixels with the ``dilate_px`` margin (module docstring): removed from the
        frame.
    cover : (H, W) bool
        The same without the margin: what the robot hides of the object (the occluded share
        is counted on it).
    depth : (H, W) float32
        The model's depth, m; NaN off the rendered robot (in the margin: the nearest depth).
    joint_stamp : float
        Time of the joint state used, s.
    """

    mask: NDArray[np.bool_]
    cover: NDArray[np.bool_]
    depth: NDArray[np.float32]
    joint_stamp: float


class RobotFilter:
    """The robot's pixels of each frame from its model and its joint states.

    Parameters
    ----------
    cfg : RobotFilterConfig
    """

    def __init__(self, cfg: RobotFilterConfig) -> None:
        self.cfg = cfg
        self.joints = JointStateBuffer()
        self._robot: RobotGeometry | None = None
        self._urdf = ""
        self.model_error = ""

    @property
    def robot(self) -> RobotGeometry | None:
        """The loaded robot model (None before one loaded)."""
        return self._robot

    def set_model(self, urdf: str) -> bool:
        """Load the robot from URDF text (the same text again: nothing to do).

        Returns
        -------
        bool
            Whether it loaded; if not, :attr:`model_error` says why and the previous model
            (if any) is dropped: frames are refused until a good one arrives.
        """
        if urdf == self._urdf and self._robot is not None:
            return True
        self._urdf = urdf
        try:
            self._robot = RobotGeometry.from_urdf(
                urdf, package_dirs=self.cfg.package_dirs, base_pose=self.cfg.base_pose,
                base_link=self.cfg.base_link or None)
        except ValueError as exc:
            self._robot, self.model_error = None, str(exc)[:500]
            return False
        self.model_error = ""
        return True

    def pixels(self, stamp: float, camera_matrix: NDArray[np.float64],
               t_world_camera: NDArray[np.float64], depth: NDArray[np.floating]
               ) -> RobotPixels:
        """The robot's pixels in the frame stamped ``stamp`` (s) with depth ``depth`` (m).

        Raises
        ------
        InputError
            ``no_robot_model``, ``no_joint_state``, ``stale_joint_state``, ``robot_pose``
            (module docstring).
        """
        if self._robot is None:
            why = f" ({self.model_error})" if self.model_error else ""
            raise InputError("no_robot_model", f"no robot model yet{why}: the robot's pixels "
                             "cannot be computed (/robot_description or "
                             "robot_filter.description_file)")
        names, q, used = self.joints.at(stamp, self.cfg.joint_state_tolerance,
                                        self.cfg.still_tolerance)
        h, w = depth.shape
        try:
            core = self._robot.render(camera_matrix, t_world_camera, w, h, names, q)
        except ValueError as exc:
            raise InputError("robot_pose", f"the robot's pixels cannot be computed: "
                             f"{str(exc)[:300]}") from None
        grown = dilate(core.mask, core.depth, self.cfg.dilate_px) \
            if self.cfg.dilate_px > 0 and core.mask.any() else core
        measured = np.asarray(depth, dtype=np.float32)
        margin = np.float32(self.cfg.depth_margin)
        with np.errstate(invalid="ignore"):  # NaN: nothing measured, the robot may be there
            mask = grown[0] & ~(measured < grown[1] - margin)
            cover = core.mask & ~(measured < core.depth - margin)
        return RobotPixels(mask, cover, grown[1], used)


def clear_robot(rgb: NDArray[np.uint8], depth: NDArray[np.floating],
                robot: NDArray[np.bool_]) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
    """The frame with the robot's pixels made neutral for the segmentation: no depth (the
    CNN reads it as table level) and the median colour of the rest of the image (mostly the
    table). Copies; the inputs are unchanged."""
    out_depth = np.array(depth, dtype=np.float32)
    out_rgb = np.array(rgb, dtype=np.uint8)
    if not np.any(robot):
        return out_rgb, out_depth
    sample = ~robot[::_COLOUR_STRIDE, ::_COLOUR_STRIDE]
    colours = out_rgb[::_COLOUR_STRIDE, ::_COLOUR_STRIDE][sample]
    fill = np.median(colours, axis=0).astype(np.uint8) if len(colours) else np.zeros(3, np.uint8)
    out_rgb[robot] = fill
    out_depth[robot] = np.nan
    return out_rgb, out_depth


def segment(segmenter: Any, rgb: NDArray[np.uint8], depth: NDArray[np.floating],
            camera_matrix: NDArray[np.float64], t_world_camera: NDArray[np.float64],
            robot: NDArray[np.bool_] | None = None) -> Any:
    """Segment a frame with ``segmenter`` (a :class:`push_perception.model.Segmenter`); with
    the robot's pixels ``robot`` (H, W) they are made neutral first (:func:`clear_robot`) and
    are never object pixels. Returns the :class:`push_perception.model.Segmentation`."""
    if robot is None:
        return segmenter(rgb, depth, camera_matrix, t_world_camera)
    clean_rgb, clean_depth = clear_robot(rgb, depth, robot)
    return segmenter(clean_rgb, clean_depth, camera_matrix, t_world_camera, robot=robot)
