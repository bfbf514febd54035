"""The simulator's arm: a Franka Panda with the pusher rod as its tool, position-controlled.

ROS-free; :class:`sim_bridge.world.PushWorld` builds it in arm mode (``WorldConfig.robot =
"arm"``) and :mod:`sim_bridge.arm_ros` publishes its state.

Model (:func:`arm_urdf`): ``franka_panda/panda.urdf`` of ``pybullet_data`` (Apache-2.0, the
licence file sits next to it) with the hand and fingers removed and the pusher rod as the tool:
a fixed link ``pusher_rod`` (cylinder of radius ``pusher_radius`` and length ``ROD_LENGTH``,
its top on the flange ``panda_link8``, its axis along the flange z) and a fixed frame
``pusher_tip`` at the rod's lower end. Mesh paths are made absolute, so the URDF string loads
from any file and is what ``/robot_description`` carries.

Frames: the arm's base ``panda_link0`` stands at ``base_pose`` = (x, y, z, yaw) in ``world``
(m, rad); a pedestal under it (z > 0) is neither modelled nor drawn (drawn, it showed at the
image's top edge and cost perception accuracy: bench_arm_perception). The tip is on the rod
axis at its lower end; with the rod vertical the flange is ``ROD_LENGTH`` above the tip.

Contacts: the rod collides with the object (its friction is the scene's pusher friction; the
object's is 1, bullet multiplies); the arm's links and the rod do not collide with the table
(the tool is kept above it; a tip commanded below the table goes through it rather than
wrecking the physics), and the links do not collide with the object: they stay high above it.

Control: ``POSITION_CONTROL`` of the 7 joints with ``targetVelocities`` as feed-forward,
position gain ``POSITION_GAIN``, velocity gain ``VELOCITY_GAIN``, forces limited to the URDF's
efforts.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pybullet as p
import pybullet_data
from numpy.typing import ArrayLike, NDArray
from pybullet_utils.bullet_client import BulletClient

__all__ = [
    "ARM_JOINTS",
    "DEFAULT_BASE_POSE",
    "DEFAULT_PARK",
    "ROD_LENGTH",
    "ArmRobot",
    "JointState",
    "arm_urdf",
]

#: The seven controlled joints, in the controller's order.
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
#: Length of the pusher rod on the flange, m.
ROD_LENGTH = 0.20
#: Pose (x, y, z, yaw) of ``panda_link0`` in ``world`` (m, rad): behind the workspace on a
#: 0.15 m pedestal (on the bare table no base pose reaches the whole workspace with the rod
#: vertical; docs/results/bench_arm_reach.md).
DEFAULT_BASE_POSE = (-0.47, 0.0, 0.15, 0.0)
#: Park posture (rad): the arm folded back over its base, rod pointing down, out of the
#: camera's view (the parked arm covers < 1 % of the image; bench_arm_perception).
DEFAULT_PARK = (0.0, -1.2, 0.0, -2.9, 0.0, 1.75, 0.785)
#: Joint position controller gains (pybullet's POSITION_CONTROL).
POSITION_GAIN = 0.3
VELOCITY_GAIN = 1.0

_ROD_RGB = "0.15 0.15 0.17"


def arm_urdf(pusher_radius: float) -> str:
    """The URDF of the Panda with the pusher rod (module docstring), mesh paths absolute.

    Parameters
    ----------
    pusher_radius : float
        Radius of the rod, m.
    """
    folder = f"{pybullet_data.getDataPath()}/franka_panda"
    with open(f"{folder}/panda.urdf", encoding="utf-8") as f:
        text = f.read()
    cut = text.index('<joint name="panda_hand_joint"')
    text = text[:cut].replace("package://meshes/", f"{folder}/meshes/")
    text = re.sub(r'<robot name="[^"]*"', '<robot name="panda_pusher"', text, count=1)
    r, half = f"{pusher_radius:.6g}", f"{ROD_LENGTH / 2:.6g}"
    rod = f"""  <link name="pusher_rod">
    <inertial>
      <origin rpy="0 0 0" xyz="0 0 {half}"/>
      <mass value="0.05"/>
      <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-6"/>
    </inertial>
    <visual>
      <origin rpy="0 0 0" xyz="0 0 {half}"/>
      <geometry><cylinder radius="{r}" length="{ROD_LENGTH:.6g}"/></geometry>
      <material name="rod"><color rgba="{_ROD_RGB} 1"/></material>
    </visual>
    <collision>
      <origin rpy="0 0 0" xyz="0 0 {half}"/>
      <geometry><cylinder radius="{r}" length="{ROD_LENGTH:.6g}"/></geometry>
    </collision>
  </link>
  <joint name="pusher_rod_joint" type="fixed">
    <parent link="panda_link8"/>
    <child link="pusher_rod"/>
    <origin rpy="0 0 0" xyz="0 0 0"/>
  </joint>
  <link name="pusher_tip">
    <inertial>
      <mass value="0.001"/>
      <inertia ixx="1e-9" ixy="0" ixz="0" iyy="1e-9" iyz="0" izz="1e-9"/>
    </inertial>
  </link>
  <joint name="pusher_tip_joint" type="fixed">
    <parent link="pusher_rod"/>
    <child link="pusher_tip"/>
    <origin rpy="0 0 0" xyz="0 0 {ROD_LENGTH:.6g}"/>
  </joint>
</robot>
"""
    return text + rod


@dataclass(frozen=True)
class JointState:
    """Measured state of the controlled joints (order ``ARM_JOINTS``): rad, rad/s, N m."""

    names: tuple[str, ...]
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    efforts: NDArray[np.float64]


class ArmRobot:
    """The arm in one pybullet client (module docstring).

    Parameters
    ----------
    client : BulletClient
    urdf_path : str
        A file holding :func:`arm_urdf`'s text.
    base_pose : (4,) array_like
        (x, y, z, yaw) of the base in ``world``, m and rad.
    park : (7,) array_like
        Initial joint positions, rad.
    friction : float
        Lateral friction of the rod (the scene's pusher friction).
    table, obj : int
        Body ids of the table and the object (collision filtering).
    """

    def __init__(self, client: BulletClient, urdf_path: str, base_pose: ArrayLike,
                 park: ArrayLike, friction: float, table: int, obj: int) -> None:
        x, y, z, yaw = (float(v) for v in np.asarray(base_pose, dtype=float))
        self._c = client
        self.body = client.loadURDF(urdf_path, [x, y, z], p.getQuaternionFromEuler([0, 0, yaw]),
                                    useFixedBase=True, flags=p.URDF_USE_INERTIA_FROM_FILE)
        names = {client.getJointInfo(self.body, j)[1].decode(): j
                 for j in range(client.getNumJoints(self.body))}
        self.joints = [names[n] for n in ARM_JOINTS]
        self.rod = names["pusher_rod_joint"]
        self.tip = names["pusher_tip_joint"]
        self.max_force = [client.getJointInfo(self.body, j)[10] for j in self.joints]
        self.limits = np.array([client.getJointInfo(self.body, j)[8:10] for j in self.joints])
        for link in range(-1, client.getNumJoints(self.body)):
            client.setCollisionFilterPair(self.body, table, link, -1, 0)
            if link != self.rod:
                client.setCollisionFilterPair(self.body, obj, link, -1, 0)
            client.changeDynamics(self.body, link, linearDamping=0.0, angularDamping=0.0)
        client.changeDynamics(self.body, self.rod, lateralFriction=friction,
                              spinningFriction=0.0, rollingFriction=0.0, restitution=0.0)
        self.set_positions(park)

    def set_positions(self, q: ArrayLike) -> None:
        """Teleport the joints to ``q`` (rad) at rest and hold them there."""
        q = np.asarray(q, dtype=float)
        for j, qj in zip(self.joints, q, strict=True):
            self._c.resetJointState(self.body, j, float(qj), 0.0)
        self.command(q, np.zeros(len(q)))

    def command(self, q: ArrayLike, v: ArrayLike) -> None:
        """Position targets ``q`` (rad) with velocity feed-forward ``v`` (rad/s)."""
        self._c.setJointMotorControlArray(
            self.body, self.joints, p.POSITION_CONTROL, targetPositions=list(map(float, q)),
            targetVelocities=list(map(float, v)), forces=self.max_force,
            positionGains=[POSITION_GAIN] * len(self.joints),
            velocityGains=[VELOCITY_GAIN] * len(self.joints))

    def state(self) -> JointState:
        """The measured joint state."""
        states = self._c.getJointStates(self.body, self.joints)
        return JointState(names=ARM_JOINTS,
                          positions=np.array([s[0] for s in states]),
                          velocities=np.array([s[1] for s in states]),
                          efforts=np.array([s[3] for s in states]))

    def tip_position(self) -> NDArray[np.float64]:
        """The tool tip (lower end of the rod on its axis) in ``world``, (3,) m."""
        link = self._c.getLinkState(self.body, self.tip, computeForwardKinematics=True)
        return np.array(link[4])

    def rod_axis(self) -> NDArray[np.float64]:
        """Unit vector along the rod from its top to the tip, in ``world``."""
        quat = self._c.getLinkState(self.body, self.tip, computeForwardKinematics=True)[5]
        return np.array(self._c.getMatrixFromQuaternion(quat)).reshape(3, 3)[:, 2]

    def inverse_kinematics(self, tip: Sequence[float], rest: ArrayLike | None = None
                           ) -> NDArray[np.float64]:
        """Joint positions (rad) putting the tip at ``tip`` with the rod vertical (pointing
        down), pybullet's damped least squares; for tests and benchmarks only (the robot side
        plans with its own kinematics). Not checked: compare :meth:`tip_position` after
        :meth:`set_positions`."""
        down = p.getQuaternionFromEuler([np.pi, 0.0, 0.0])
        lower, upper = self.limits[:, 0], self.limits[:, 1]
        rest = (lower + upper) / 2 if rest is None else np.asarray(rest, dtype=float)
        q = self._c.calculateInverseKinematics(
            self.body, self.tip, list(tip), down, lowerLimits=list(lower),
            upperLimits=list(upper), jointRanges=list(upper - lower), restPoses=list(rest),
            maxNumIterations=200, residualThreshold=1e-6)
        return np.array(q[:len(self.joints)])
