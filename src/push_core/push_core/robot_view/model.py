"""The robot's geometry posed by its joints: link poses, posed triangles, the rendered robot.

ROS-free. pinocchio (``pin``) parses the URDF's kinematics and computes the forward kinematics;
:mod:`push_core.robot_view.urdf` reads the links' shapes as triangles and
:mod:`push_core.robot_view.raster` draws them. See :mod:`push_core.robot_view` for the frames.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from push_core.robot_view.raster import MAX_WORK, check_camera, rasterize
from push_core.robot_view.urdf import LinkShape, link_shapes

__all__ = ["MAX_DILATE_PX", "MAX_TRIANGLES", "MAX_URDF_CHARS", "SIM_PANDA_BASE_POSE",
           "RobotGeometry", "RobotImage",
           "base_transform", "check_rigid_transform", "dilate", "joint_positions"]

#: Pose (x, y, z, yaw) of the simulated Panda's base ``panda_link0`` in ``world`` (m, rad):
#: behind the workspace on a 0.15 m pedestal (on the bare table no base pose reaches the whole
#: workspace with the rod vertical; docs/RESULTS.md, section bench_arm_reach). The default of
#: every node's base pose parameter.
SIM_PANDA_BASE_POSE = (-0.47, 0.0, 0.15, 0.0)
#: Longest URDF text accepted, characters (a 10 MB string is refused before parsing).
MAX_URDF_CHARS = 4_000_000
#: Most triangles of a robot's geometry (bounded work per rendered frame).
MAX_TRIANGLES = 200_000
#: Largest dilation of the rendered mask, pixels.
MAX_DILATE_PX = 50
#: Most joint names in one joint state.
MAX_JOINT_NAMES = 1000


def base_transform(base_pose: ArrayLike) -> NDArray[np.float64]:
    """4 x 4 homogeneous transform ``world <- base`` of ``base_pose`` = (x, y, z, yaw).

    Parameters
    ----------
    base_pose : (4,) array_like
        Position of the base link's origin in ``world`` (m) and its rotation about the world z
        axis (rad): a robot standing upright on or beside the table.

    Raises
    ------
    ValueError
        Not 4 finite values.
    """
    pose = np.asarray(base_pose, dtype=float)
    if pose.shape != (4,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"base_pose: expected 4 finite values (x, y, z, yaw), got {pose!r}")
    c, s = math.cos(pose[3]), math.sin(pose[3])
    t = np.eye(4)
    t[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    t[:3, 3] = pose[:3]
    return t


def check_rigid_transform(transform: ArrayLike, name: str) -> NDArray[np.float64]:
    """``transform`` as a float64 (4, 4) rigid transform, or raise ``ValueError`` naming it."""
    t = np.asarray(transform, dtype=np.float64)
    if t.shape != (4, 4) or not np.all(np.isfinite(t)) \
            or not np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-6) \
            or not np.allclose(t[3], (0.0, 0.0, 0.0, 1.0)) or np.linalg.det(t[:3, :3]) < 0:
        raise ValueError(f"{name} must be a finite (4, 4) rigid transform")
    return t


def joint_positions(chain: Sequence[str], names: Sequence[str], positions: ArrayLike
                    ) -> NDArray[np.float64]:
    """The positions of the joints ``chain`` out of a joint state (any order, extras ignored).

    Parameters
    ----------
    chain : sequence of str
        The joints wanted, in the order returned.
    names : sequence of str
        The joint state's names.
    positions : (len(names),) array_like
        Their positions, rad or m.

    Raises
    ------
    ValueError
        ``names`` and ``positions`` differ in length, a name repeats, a joint of ``chain`` is
        missing, or one of their positions is not finite.
    """
    values = np.asarray(positions, dtype=float).ravel()
    if len(names) != len(values):
        raise ValueError(f"{len(names)} names but {len(values)} positions")
    index: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in index:
            raise ValueError(f"joint {name[:64]!r} appears twice")
        index[name] = i
    missing = [j for j in chain if j not in index]
    if missing:
        raise ValueError(f"joints {missing[:16]} missing")
    q = values[[index[j] for j in chain]]
    if not np.all(np.isfinite(q)):
        raise ValueError("non-finite joint position")
    return q


class RobotImage(NamedTuple):
    """The robot as a camera sees it (:meth:`RobotGeometry.render`).

    Attributes
    ----------
    mask : (H, W) bool
        Pixels showing the robot (dilated by ``dilate_px``).
    depth : (H, W) float32
        Optical z of the robot's nearest surface, metres; NaN where ``mask`` is False (in the
        dilated ring: the nearest robot depth within ``dilate_px``).
    """

    mask: NDArray[np.bool_]
    depth: NDArray[np.float32]


class RobotGeometry:
    """A robot's geometry from its URDF, posed by joint positions; see :mod:`push_core.robot_view`.

    Build it with :meth:`from_urdf`.

    Attributes
    ----------
    joint_names : tuple of str
        The movable joints (1-DOF: revolute, continuous, prismatic), in the model's order.
    link_names : tuple of str
        Every link of the URDF.
    triangle_count : int
        Triangles of the geometry.
    base_link : str
        The link placed at ``base_pose``.
    base_pose : (4,) ndarray
        (x, y, z, yaw) of ``base_link`` in ``world``, m and rad.
    """

    def __init__(self, model: pin.Model, shapes: Sequence[LinkShape], base_pose: ArrayLike,
                 base_link: str) -> None:
        self._model = model
        self._data = model.createData()
        self.base_link = base_link
        self.base_pose = np.asarray(base_pose, dtype=float).copy()
        names, slots = [], []
        for j in range(1, model.njoints):
            joint = model.joints[j]
            if joint.nv != 1 or joint.nq not in (1, 2):
                raise ValueError(f"robot description: joint {model.names[j]!r} has "
                                 f"{joint.nv} degrees of freedom (only revolute, continuous "
                                 "and prismatic joints)")
            names.append(model.names[j])
            slots.append((joint.idx_q, joint.nq))
        self.joint_names = tuple(names)
        self._slots = tuple(slots)
        frames = {f.name: i for i, f in enumerate(model.frames) if f.type == pin.FrameType.BODY}
        self.link_names = tuple(frames)
        if base_link not in frames:
            raise ValueError(f"robot description: no link {base_link!r}")
        base = model.frames[frames[base_link]]
        if base.parentJoint != 0:
            raise ValueError(f"robot description: base link {base_link!r} moves with joint "
                             f"{model.names[base.parentJoint]!r}; it must be fixed to the root")
        self._world_model = base_transform(base_pose) @ np.linalg.inv(base.placement.homogeneous)
        # Shapes in their link's frame; posed by the link frames (one pinocchio frame each).
        self._links = tuple(sorted({s.link for s in shapes}))
        self._link_frames = [frames[name] for name in self._links]
        order = {name: i for i, name in enumerate(self._links)}
        self.triangle_count = sum(len(s.triangles) for s in shapes)
        if self.triangle_count > MAX_TRIANGLES:
            raise ValueError(f"robot description: {self.triangle_count} triangles, more than "
                             f"{MAX_TRIANGLES}")
        empty = np.zeros((0, 3, 3))
        self._tri = np.concatenate([empty, *(s.triangles for s in shapes)])
        self._owner = np.concatenate([np.zeros(0, dtype=np.int64),
                                      *(np.full(len(s.triangles), order[s.link]) for s in shapes)])
        self._cull = np.concatenate([np.zeros(0, dtype=bool),
                                     *(np.full(len(s.triangles), s.closed) for s in shapes)])

    @classmethod
    def from_urdf(cls, urdf: str, package_dirs: Sequence[str] = (),
                  base_pose: ArrayLike = (0.0, 0.0, 0.0, 0.0), base_link: str | None = None,
                  kind: str = "collision") -> RobotGeometry:
        """Load a robot from URDF text.

        Parameters
        ----------
        urdf : str
            URDF XML (as ``/robot_description`` carries it).
        package_dirs : sequence of str
            Folders searched for mesh files: ``package://<pkg>/<path>`` is looked up as
            ``<dir>/<pkg>/<path>``, a relative path as ``<dir>/<path>`` (pass the URDF file's
            folder for paths relative to it); absolute paths and ``file://`` URLs are read as
            they are.
        base_pose : (4,) array_like
            (x, y, z, yaw) of ``base_link`` in ``world``, m and rad.
        base_link : str, optional
            The link at ``base_pose``; default the URDF's root link. It must be fixed to the
            root (no joint between them).
        kind : {"collision", "visual"}
            Which geometry of the links: the collision geometry (a self-filter's choice: it
            is usually a little larger than the visual one) or the visual one.

        Raises
        ------
        ValueError
            Empty, too long or unparsable URDF, a mesh that cannot be found or read, an
            unsupported joint or shape type, too many triangles, a bad base link or pose.
        """
        if not isinstance(urdf, str) or not urdf.strip():
            raise ValueError("robot description: empty")
        if len(urdf) > MAX_URDF_CHARS:
            raise ValueError(f"robot description: {len(urdf)} characters, more than "
                             f"{MAX_URDF_CHARS}")
        base_transform(base_pose)  # the pose is checked before the (slower) parsing
        try:
            model = pin.buildModelFromXML(urdf)
        except (ValueError, RuntimeError) as exc:
            raise ValueError(f"robot description: not a valid URDF ({exc})") from None
        shapes = link_shapes(urdf, kind, [str(d) for d in package_dirs])
        links = {f.name for f in model.frames if f.type == pin.FrameType.BODY}
        unknown = sorted({s.link for s in shapes} - links)
        if unknown:
            raise ValueError(f"robot description: shapes of unknown links {unknown[:8]}")
        root = next(f.name for f in model.frames if f.type == pin.FrameType.BODY)
        return cls(model, shapes, base_pose, root if base_link is None else base_link)

    # ---- kinematics ----------------------------------------------------------------------------
    def configuration(self, joint_names: Sequence[str], positions: ArrayLike
                      ) -> NDArray[np.float64]:
        """pinocchio's configuration vector for joint positions given by name.

        Parameters
        ----------
        joint_names : sequence of str
            Names of a joint state; every name of :attr:`joint_names` must be among them
            (others are ignored).
        positions : (len(joint_names),) array_like
            rad (revolute, continuous) or m (prismatic).

        Raises
        ------
        ValueError
            As :func:`joint_positions`, or more than ``MAX_JOINT_NAMES`` names.
        """
        if len(joint_names) > MAX_JOINT_NAMES:
            raise ValueError(f"{len(joint_names)} joint names (at most {MAX_JOINT_NAMES})")
        values = joint_positions(self.joint_names, list(joint_names), positions)
        q = pin.neutral(self._model)
        for (start, nq), value in zip(self._slots, values, strict=True):
            if nq == 1:
                q[start] = value
            else:  # continuous joint: (cos, sin)
                q[start:start + 2] = (math.cos(value), math.sin(value))
        return q

    def _shape_link_poses(self, joint_names: Sequence[str], positions: ArrayLike
                          ) -> NDArray[np.float64]:
        """``world <- link`` (L, 4, 4) of the links that have shapes."""
        q = self.configuration(joint_names, positions)
        pin.forwardKinematics(self._model, self._data, q)
        out = np.empty((len(self._link_frames), 4, 4))
        for i, frame in enumerate(self._link_frames):
            out[i] = self._world_model @ pin.updateFramePlacement(self._model, self._data,
                                                                  frame).homogeneous
        return out

    def link_poses(self, joint_names: Sequence[str], positions: ArrayLike
                   ) -> dict[str, NDArray[np.float64]]:
        """Pose of every link in ``world``.

        Parameters
        ----------
        joint_names, positions
            As :meth:`configuration`.

        Returns
        -------
        dict of str to (4, 4) ndarray
            ``{link: T_world_link}``, metres.
        """
        pin.framesForwardKinematics(self._model, self._data,
                                    self.configuration(joint_names, positions))
        return {f.name: self._world_model @ self._data.oMf[i].homogeneous
                for i, f in enumerate(self._model.frames) if f.type == pin.FrameType.BODY}

    def triangles(self, joint_names: Sequence[str], positions: ArrayLike,
                  t_frame_world: ArrayLike | None = None
                  ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """The geometry's triangles posed by the joints.

        Parameters
        ----------
        joint_names, positions
            As :meth:`configuration`.
        t_frame_world : (4, 4) array_like, optional
            ``frame <- world``: the triangles are returned in that frame (default ``world``).

        Returns
        -------
        triangles : (T, 3, 3) float64
            Vertices, metres.
        closed : (T,) bool
            Triangles of a closed, outward-wound surface (:mod:`push_core.robot_view.meshes`).
        """
        poses = self._shape_link_poses(joint_names, positions)
        if t_frame_world is not None:
            poses = check_rigid_transform(t_frame_world, "t_frame_world") @ poses
        rot, shift = poses[self._owner, :3, :3], poses[self._owner, :3, 3]
        return np.einsum("tij,tvj->tvi", rot, self._tri) + shift[:, None, :], self._cull

    # ---- rendering -----------------------------------------------------------------------------
    def render(self, camera_matrix: ArrayLike, t_world_camera: ArrayLike, width: int,
               height: int, joint_names: Sequence[str], positions: ArrayLike,
               dilate_px: int = 0, near: float = 0.01, max_work: float = MAX_WORK
               ) -> RobotImage:
        """The robot's mask and depth in a camera image.

        Parameters
        ----------
        camera_matrix : (3, 3) array_like
            K, pixels.
        t_world_camera : (4, 4) array_like
            ``world <- camera optical frame``.
        width, height : int
            Image size, pixels.
        joint_names, positions
            As :meth:`configuration`.
        dilate_px : int
            Grow the mask by a disc of this radius, pixels, in [0, ``MAX_DILATE_PX``] (a
            margin for calibration and joint-state errors).
        near : float
            Near clipping plane, m.
        max_work : float
            Bound of the rasteriser's work (:func:`push_core.robot_view.raster.rasterize`).

        Returns
        -------
        RobotImage

        Raises
        ------
        ValueError
            Bad camera, transform, size, joints or ``dilate_px``; too much work (the robot on
            the lens).
        """
        k = check_camera(camera_matrix, width, height)
        t = check_rigid_transform(t_world_camera, "t_world_camera")
        if isinstance(dilate_px, bool) or int(dilate_px) != dilate_px \
                or not 0 <= dilate_px <= MAX_DILATE_PX:
            raise ValueError(f"dilate_px must be an integer in [0, {MAX_DILATE_PX}], got "
                             f"{dilate_px!r}")
        camera_world = np.linalg.inv(t)
        tri, cull = self.triangles(joint_names, positions, camera_world)
        mask, depth = rasterize(tri, k, width, height, near=near, cull=cull, max_work=max_work)
        if dilate_px > 0 and mask.any():
            mask, depth = dilate(mask, depth, int(dilate_px))
        return RobotImage(mask, depth)


def dilate(mask: NDArray[np.bool_], depth: NDArray[np.float32], radius: int
           ) -> tuple[NDArray[np.bool_], NDArray[np.float32]]:
    """Grow a mask by a disc of ``radius`` pixels; the new pixels get the nearest (smallest)
    depth of the mask within the disc. Works on the mask's bounding box only."""
    rows, cols = np.nonzero(np.any(mask, axis=1))[0], np.nonzero(np.any(mask, axis=0))[0]
    r0, r1 = max(rows[0] - radius, 0), min(rows[-1] + radius + 1, mask.shape[0])
    c0, c1 = max(cols[0] - radius, 0), min(cols[-1] + radius + 1, mask.shape[1])
    yy, xx = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    disc = xx * xx + yy * yy <= radius * radius
    crop = mask[r0:r1, c0:c1]
    grown = ndimage.binary_dilation(crop, structure=disc)
    near = ndimage.minimum_filter(np.where(crop, depth[r0:r1, c0:c1], np.inf), footprint=disc,
                                  mode="constant", cval=np.inf)
    out_mask = mask.copy()
    out_mask[r0:r1, c0:c1] = grown
    out_depth = depth.copy()
    ring = grown & ~crop
    out_depth[r0:r1, c0:c1][ring] = near[ring]
    return out_mask, out_depth
