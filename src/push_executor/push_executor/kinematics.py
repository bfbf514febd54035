"""The arm's kinematics: a serial chain from a URDF, a vertical rod as its tool, FK and IK.

ROS-free (no rclpy, no message types, no simulator): URDF text in, numpy out. The rigid-body
maths is pinocchio's (``pin``: URDF parsing, forward kinematics, frame Jacobians); this module
only chooses the chain, adds the tool and solves the pushing task.

Frames (REP 103: metres, radians, right-handed, z up):

- ``world``: the table frame of the pipeline (table surface z = 0).
- ``base``: the URDF link ``base_frame``; its pose in ``world`` is ``base_pose`` = (x, y, z,
  yaw) (a robot standing upright on or beside the table).
- the flange: the URDF link ``ToolSpec.flange_link``; the tool is a rod along the flange's +z
  axis, starting ``flange_offset`` from the flange origin, ``length`` long, of radius
  ``radius``. The **tool tip** is the rod's far end on its axis; the **tool axis** is the
  flange's +z axis (pointing from the flange to the tip).

The chain is every movable joint on the path from ``base_frame`` to the flange link; all other
joints of the model (a gripper's fingers, a second arm) are locked at their neutral position
(``pinocchio.buildReducedModel``) and ignored. Only 1-DOF joints (revolute, prismatic) may be
in the chain.

The pushing task (:meth:`ArmKinematics.solve_ik`) is 5-dimensional: tip position (3) and the
tool axis pointing straight down, ``-z`` of ``world`` (2); the rotation about the vertical tool
axis (yaw) is free, the remaining redundancy (two degrees of freedom on a 7-joint arm) is
spent on a bias toward a reference posture in the null space of the task.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from push_core.robot_view import MAX_URDF_CHARS, base_transform

__all__ = ["DEFAULT_ACCELERATION", "DEFAULT_JERK", "ArmKinematics", "IkResult", "ToolSpec"]

#: Default joint acceleration (rad/s^2) and jerk (rad/s^3) limits: the Franka Panda's lowest
#: (its joint 2: 7.5 rad/s^2; 3750 rad/s^3 in its datasheet, here far less: the acceleration
#: ramps up in 15 ms).
DEFAULT_ACCELERATION, DEFAULT_JERK = 7.5, 500.0
#: Unit vector of the tool axis' target direction in ``world``: straight down.
DOWN = np.array([0.0, 0.0, -1.0])


@dataclass(frozen=True)
class ToolSpec:
    """The pusher rod on the flange.

    Attributes
    ----------
    flange_link : str
        URDF link carrying the rod.
    flange_offset : float
        Distance from the flange origin to the rod's upper end along the flange z axis, m.
    length : float
        Rod length, m (> 0).
    radius : float
        Rod radius, m (>= 0).
    """

    flange_link: str = "panda_link8"
    flange_offset: float = 0.0
    length: float = 0.20
    radius: float = 0.01

    def __post_init__(self) -> None:
        for name in ("flange_offset", "length", "radius"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"tool.{name}: must be finite, got {getattr(self, name)!r}")
        if not 0.0 < self.length <= 5.0:
            raise ValueError(f"tool.length: must be in (0, 5] m, got {self.length!r}")
        if not 0.0 <= self.radius <= 1.0:
            raise ValueError(f"tool.radius: must be in [0, 1] m, got {self.radius!r}")
        if not self.flange_link:
            raise ValueError("tool.flange_link: empty")

    @property
    def tip_distance(self) -> float:
        """Distance of the tip from the flange origin along the flange z axis, m."""
        return self.flange_offset + self.length


def _per_joint(values: float | ArrayLike, n: int, what: str) -> NDArray[np.float64]:
    """One positive limit per joint from one value for all or one each; ``ValueError``."""
    arr = np.asarray(values, dtype=float).ravel()
    if arr.size not in (1, n) or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{what}: expected 1 or {n} positive values, got "
                         f"{arr.tolist()[:16]}")
    return np.broadcast_to(arr, (n,)).copy()


@dataclass(frozen=True)
class IkResult:
    """Outcome of :meth:`ArmKinematics.solve_ik`.

    Attributes
    ----------
    q : (n,) ndarray
        Joint positions of the chain (rad or m), within the hard limits.
    position_error : float
        Distance of the tip from the target, m.
    axis_error : float
        Angle between the tool axis and straight down, rad.
    iterations : int
    """

    q: NDArray[np.float64]
    position_error: float
    axis_error: float
    iterations: int


class ArmKinematics:
    """The chain ``base_frame`` -> ``tool.flange_link`` of a URDF, with the rod as its tool.

    Parameters
    ----------
    urdf : str
        URDF XML text (as ``/robot_description`` carries it).
    base_frame : str
        URDF link that is the robot's base.
    tool : ToolSpec
    base_pose : (4,) array_like
        (x, y, z, yaw) of ``base_frame`` in ``world``, m and rad.
    acceleration_limits : float or (n,) array_like
        Joint acceleration limits, rad/s^2 (m/s^2 for prismatic joints); one value for all.
    jerk_limits : float or (n,) array_like
        Joint jerk limits, rad/s^3 (m/s^3); one value for all.

    Raises
    ------
    ValueError
        Unparsable or too long URDF, a link that is not there, a flange not below the base, a
        chain joint that is not 1-DOF, a joint without finite position and velocity limits, bad
        acceleration or jerk limits.

    Attributes
    ----------
    joint_names : tuple of str
        The chain's joints, base to flange.
    lower, upper, velocity_limits, acceleration_limits, jerk_limits : (n,) ndarray
        Limits from the URDF (position: rad or m; velocity: rad/s or m/s) and the parameters.
    """

    def __init__(self, urdf: str, base_frame: str, tool: ToolSpec,
                 base_pose: ArrayLike = (0.0, 0.0, 0.0, 0.0),
                 acceleration_limits: float | ArrayLike = DEFAULT_ACCELERATION,
                 jerk_limits: float | ArrayLike = DEFAULT_JERK) -> None:
        if not isinstance(urdf, str) or not urdf.strip():
            raise ValueError("robot description: empty")
        if len(urdf) > MAX_URDF_CHARS:
            raise ValueError(f"robot description: {len(urdf)} characters, more than "
                             f"{MAX_URDF_CHARS}")
        try:
            full = pin.buildModelFromXML(urdf)
        except (ValueError, RuntimeError) as exc:
            raise ValueError(f"robot description: not a valid URDF ({exc})") from None
        self.tool = tool
        self._world_base = base_transform(base_pose)
        chain = self._chain(full, base_frame, tool.flange_link)
        locked = [j for j in range(1, full.njoints) if j not in chain]
        model = (pin.buildReducedModel(full, locked, pin.neutral(full)) if locked else full)
        self.model = model
        self.data = model.createData()
        self.joint_names = tuple(model.names[j] for j in range(1, model.njoints))
        if model.nq != len(self.joint_names) or model.nv != model.nq:
            raise ValueError("robot description: the chain has a joint with more than one "
                             "degree of freedom (only revolute and prismatic joints)")
        self.lower = np.array(model.lowerPositionLimit, dtype=float)
        self.upper = np.array(model.upperPositionLimit, dtype=float)
        self.velocity_limits = np.array(model.velocityLimit, dtype=float)
        n = len(self.joint_names)
        bad = [name for name, lo, hi, v in zip(self.joint_names, self.lower, self.upper,
                                               self.velocity_limits, strict=True)
               if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi and 0 < v < 1e3)]
        if bad:
            raise ValueError(f"robot description: joints {bad} have no finite position limits "
                             "or velocity limit in the URDF")
        self.acceleration_limits = _per_joint(acceleration_limits, n, "acceleration limits")
        self.jerk_limits = _per_joint(jerk_limits, n, "jerk limits")
        self._base_id = model.getFrameId(base_frame)
        flange_id = model.getFrameId(tool.flange_link)
        flange = model.frames[flange_id]
        tip = flange.placement * pin.SE3(np.eye(3), np.array([0.0, 0.0, tool.tip_distance]))
        self._tip_id = model.addFrame(pin.Frame("push_executor_tool_tip", flange.parentJoint,
                                                flange_id, tip, pin.FrameType.OP_FRAME))
        self.data = model.createData()
        # world <- model origin: world <- base (parameter) times base <- model (constant: the
        # base frame hangs below no chain joint).
        pin.framesForwardKinematics(model, self.data, pin.neutral(model))
        self._world_model = self._world_base @ np.linalg.inv(
            self.data.oMf[self._base_id].homogeneous)
        self._rotation = self._world_model[:3, :3]

    @staticmethod
    def _chain(model: pin.Model, base_frame: str, flange_link: str) -> list[int]:
        """Joint ids of ``model`` from ``base_frame`` down to ``flange_link``."""
        for name in (base_frame, flange_link):
            if not model.existFrame(name):
                raise ValueError(f"robot description: no link {name!r}")
        base_joint = model.frames[model.getFrameId(base_frame)].parentJoint
        joint = model.frames[model.getFrameId(flange_link)].parentJoint
        chain: list[int] = []
        while joint != base_joint:
            if joint == 0:
                raise ValueError(f"robot description: {flange_link!r} is not below "
                                 f"{base_frame!r}")
            chain.append(joint)
            joint = model.parents[joint]
        if not chain:
            raise ValueError(f"robot description: no movable joint between {base_frame!r} and "
                             f"{flange_link!r}")
        return chain[::-1]

    @property
    def n_joints(self) -> int:
        """Number of chain joints."""
        return len(self.joint_names)

    def check_q(self, q: ArrayLike, name: str = "q") -> NDArray[np.float64]:
        """``q`` as a finite (n,) array; ``ValueError`` naming ``name`` otherwise."""
        arr = np.asarray(q, dtype=float)
        if arr.shape != (self.n_joints,) or not np.all(np.isfinite(arr)):
            raise ValueError(f"{name}: expected {self.n_joints} finite joint values, got shape "
                             f"{arr.shape}")
        return arr

    # ---- forward kinematics ------------------------------------------------------------------
    def _update(self, q: NDArray[np.float64]) -> None:
        pin.framesForwardKinematics(self.model, self.data, q)

    def tip_pose(self, q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Tool tip position and tool axis in ``world``.

        Parameters
        ----------
        q : (n,) array_like
            Chain joint positions.

        Returns
        -------
        position : (3,) ndarray
            Tip, m, ``world``.
        axis : (3,) ndarray
            Unit tool axis (flange z, from flange to tip), ``world``.
        """
        self._update(self.check_q(q))
        frame = self.data.oMf[self._tip_id]
        position = self._rotation @ frame.translation + self._world_model[:3, 3]
        return position, self._rotation @ frame.rotation[:, 2]

    def tip_positions(self, qs: ArrayLike) -> NDArray[np.float64]:
        """(N, 3) tip positions in ``world`` of (N, n) postures, m."""
        qs = np.asarray(qs, dtype=float).reshape(-1, self.n_joints)
        return np.array([self.tip_pose(q)[0] for q in qs]).reshape(-1, 3)

    def frame_position(self, q: ArrayLike, frame: str) -> NDArray[np.float64]:
        """Origin of a URDF link or frame of the reduced model in ``world``, m."""
        self._update(self.check_q(q))
        t = self.data.oMf[self.model.getFrameId(frame)].translation
        return self._rotation @ t + self._world_model[:3, 3]

    def frame_pose(self, q: ArrayLike, frame: str) -> NDArray[np.float64]:
        """Pose (4, 4) of a URDF link or frame of the reduced model in ``world``, m."""
        self._update(self.check_q(q))
        return self._world_model @ self.data.oMf[self.model.getFrameId(frame)].homogeneous

    @property
    def world_model(self) -> NDArray[np.float64]:
        """``T_world_model`` (4, 4): the pinocchio model's origin in ``world``, m."""
        return self._world_model.copy()

    def task_jacobian(self, q: ArrayLike) -> NDArray[np.float64]:
        """(5, n) Jacobian of the pushing task in ``world``: tip velocity (3 rows) and the
        tool axis' angular velocity about world x and y (2 rows)."""
        return self._tip_and_jacobian(self.check_q(q))[2]

    def _tip_and_jacobian(self, q: NDArray[np.float64]
                          ) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                     NDArray[np.float64]]:
        """Tip position, tool axis and task Jacobian in ``world`` (one FK pass)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        frame = self.data.oMf[self._tip_id]
        j = pin.getFrameJacobian(self.model, self.data, self._tip_id,
                                 pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        position = self._rotation @ frame.translation + self._world_model[:3, 3]
        axis = self._rotation @ frame.rotation[:, 2]
        return position, axis, np.vstack([self._rotation @ j[:3],
                                          (self._rotation @ j[3:])[:2]])

    def manipulability(self, q: ArrayLike) -> float:
        """Yoshikawa's manipulability ``sqrt(det(J J^T))`` of :meth:`task_jacobian` (0 at a
        singular posture; units mixed m and rad, compare with a threshold for one arm)."""
        j = self.task_jacobian(q)
        return float(math.sqrt(max(np.linalg.det(j @ j.T), 0.0)))

    # ---- inverse kinematics ------------------------------------------------------------------
    def solve_ik(self, target: ArrayLike, seed: ArrayLike, reference: ArrayLike | None = None,
                 *, tolerance: float = 1e-9, posture_tolerance: float = 1e-5,
                 max_iterations: int = 200, damping: float = 1e-6, posture_gain: float = 0.2
                 ) -> IkResult:
        """Joint positions putting the tip at ``target`` with the tool axis straight down.

        Closed-loop inverse kinematics with damped least squares on the 5-row task Jacobian,
        plus a bias toward ``reference`` projected into the task's null space. Joints are kept
        within their hard limits (clipped each step). The result is returned whether or not it
        converged: check its errors.

        Parameters
        ----------
        target : (3,) array_like
            Tip position in ``world``, m.
        seed : (n,) array_like
            Start posture (the previous waypoint's solution along a path).
        reference : (n,) array_like, optional
            Posture the redundancy is pulled toward (default: ``seed``).
        tolerance : float
            Stop when the position error (m) and the axis error (rad) are both below it ...
        posture_tolerance : float
            ... and the largest joint step is below this, rad.
        max_iterations : int
        damping : float
            Damping of the least squares, squared units of the task.
        posture_gain : float
            Fraction of the posture error corrected per iteration (null space).

        Returns
        -------
        IkResult
        """
        target = np.asarray(target, dtype=float).reshape(3)
        q = np.clip(self.check_q(seed, "seed"), self.lower, self.upper)
        ref = q.copy() if reference is None else self.check_q(reference, "reference")
        eye, eye5 = np.eye(self.n_joints), np.eye(5)
        it = 0
        for it in range(1, max_iterations + 1):  # noqa: B007 - the count is reported
            position, axis, j = self._tip_and_jacobian(q)
            # Axis error: axis x down, whose world z component is always 0.
            error = np.array([*(target - position), -axis[1], axis[0]])
            jjt = j @ j.T
            step = j.T @ np.linalg.solve(jjt + damping * eye5, error)
            null = eye - j.T @ np.linalg.solve(jjt + 1e-12 * eye5, j)
            posture = null @ (posture_gain * (ref - q))
            q = np.clip(q + step + posture, self.lower, self.upper)
            if (np.max(np.abs(error)) < tolerance
                    and np.max(np.abs(step + posture)) < posture_tolerance):
                break
        position, axis = self.tip_pose(q)
        return IkResult(q=q, position_error=float(np.linalg.norm(target - position)),
                        axis_error=float(math.acos(min(1.0, max(-1.0, axis @ DOWN)))),
                        iterations=it)
