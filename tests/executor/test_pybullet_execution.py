"""A planned push executed on pybullet's position-controlled Panda stays on the commanded line.

No rclpy. The trajectory of :func:`push_executor.motion.plan_push` is followed the way a
joint_trajectory_controller does it (cubic Hermite between the points, positions + velocities
as targets of pybullet's joint position control at 240 Hz); the measured tool tip (pybullet's
panda_link8 + the rod) must stay within 1 mm of the commanded contact line during contact (the
arm's acceptance figure) and :class:`push_executor.tracking.Execution` must report the
run ``done`` with the same contact-line error from the measured joints.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from push_executor.kinematics import ArmKinematics, ToolSpec
from push_executor.motion import MotionConfig, plan_push
from push_executor.motion_types import PANDA_PARK
from push_executor.tracking import Execution, expected_positions, segment_distance

from .test_kinematics import BASE_POSE, panda_urdf

p = pytest.importorskip("pybullet")
pybullet_data = pytest.importorskip("pybullet_data")

DT = 1.0 / 240.0


def test_executed_push_stays_on_the_line() -> None:
    arm = ArmKinematics(panda_urdf(), "panda_link0", ToolSpec(), BASE_POSE)
    contact, end = np.array([-0.05, 0.1]), np.array([0.0, 0.08])
    approach = contact - 0.005 * (end - contact) / np.linalg.norm(end - contact)
    plan = plan_push(arm, MotionConfig(), approach, contact, end, np.array(PANDA_PARK))
    client = p.connect(p.DIRECT)
    try:
        robot = p.loadURDF(os.path.join(pybullet_data.getDataPath(), "franka_panda",
                                        "panda.urdf"), basePosition=BASE_POSE[:3],
                           useFixedBase=True, physicsClientId=client)
        index = {p.getJointInfo(robot, i, physicsClientId=client)[1].decode(): i
                 for i in range(p.getNumJoints(robot, physicsClientId=client))}
        joints = [index[n] for n in arm.joint_names]
        for j, q in zip(joints, PANDA_PARK, strict=True):
            p.resetJointState(robot, j, q, physicsClientId=client)
        run = Execution(plan, t0=0.0, steady=0.0, last_stamp=0.0, tracking_tolerance=0.05,
                        state_timeout=1.0, start_timeout=5.0)
        off_line, event, t, executed = [], None, 0.0, None
        while (event is None or event.kind == "executed") and t < plan.duration + 2.0:
            t += DT
            target = expected_positions(plan, t)
            velocity = (expected_positions(plan, t + 1e-4) - target) / 1e-4
            p.setJointMotorControlArray(robot, joints, p.POSITION_CONTROL,
                                        targetPositions=target.tolist(),
                                        targetVelocities=velocity.tolist(),
                                        forces=[500.0] * len(joints),
                                        physicsClientId=client)
            p.stepSimulation(physicsClientId=client)
            q = np.array([s[0] for s in p.getJointStates(robot, joints,
                                                          physicsClientId=client)])
            if plan.contact_start <= t <= plan.contact_end:
                off_line.append(segment_distance(arm.tip_pose(q)[0][None], *plan.line)[0])
            event = run.on_state(t, q, t)
            if event is not None and event.kind == "executed":
                executed = t
    finally:
        p.disconnect(client)
    assert event is not None and event.kind == "done", event
    # The contact segment was reported as soon as it had ended, while the arm went on.
    assert executed is not None and plan.contact_end <= executed < plan.contact_end + 2 * DT
    segment = run.contact_segment(arm)
    print(f"tip off the commanded line during contact: max {max(off_line) * 1e3:.4f} mm "
          f"({len(off_line)} steps at 240 Hz); Execution's figure {segment.line_error * 1e3:.4f}"
          " mm")
    assert max(off_line) < 1e-3
    assert segment.line_error == pytest.approx(max(off_line), abs=1e-4)
    np.testing.assert_allclose(segment.start[:2], (-0.05, 0.1), atol=1e-3)
    np.testing.assert_allclose(segment.end[:2], (0.0, 0.08), atol=1e-3)
