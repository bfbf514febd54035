"""The self-filter's rules without ROS: joint states by stamp, refusals, the robot's pixels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_perception.inputs import InputError
from push_perception.robot_filter import (
    JOINT_HISTORY,
    JointStateBuffer,
    RobotFilter,
    RobotFilterConfig,
    clear_robot,
)

from .conftest import K_DOWN, T_DOWN

#: A 10 cm cube on a slide along world x, 0.3 m above the table (camera 0.6 m above it).
SLIDE = """<robot name="slide"><link name="base"/>
  <joint name="x" type="prismatic"><parent link="base"/><child link="cube"/>
    <origin xyz="0 0 0.3"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <link name="cube"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>
  </link></robot>"""
CFG = RobotFilterConfig(base_pose=(0.0, 0.0, 0.0, 0.0), dilate_px=0, depth_margin=0.01,
                        joint_state_tolerance=0.05)
TABLE = np.full((480, 640), 0.6, dtype=np.float32)  # the depth of the bare table


def test_joint_states_are_interpolated_or_the_nearest_within_the_tolerance() -> None:
    buf = JointStateBuffer()
    buf.add(1.00, ["a", "b"], [0.0, 1.0])
    buf.add(1.04, ["a", "b"], [0.4, 1.0])
    names, q, used = buf.at(1.01, 0.05)
    assert names == ("a", "b") and np.allclose(q, [0.1, 1.0]) and used == 1.01
    names, q, used = buf.at(1.08, 0.05)  # after the last one: the nearest
    assert np.allclose(q, [0.4, 1.0]) and used == 1.04
    buf.add(0.98, ["a", "b"], [-0.2, 1.0])  # out of order: kept in stamp order
    assert np.allclose(buf.at(0.99, 0.05)[1], [-0.1, 1.0])
    with pytest.raises(InputError, match="0.060 s from the frame") as info:
        buf.at(1.10, 0.05)
    assert info.value.kind == "stale_joint_state"
    with pytest.raises(InputError) as info:
        JointStateBuffer().at(1.0, 0.05)
    assert info.value.kind == "no_joint_state"


def test_a_robot_at_rest_keeps_its_last_state_longer() -> None:
    buf = JointStateBuffer()
    buf.add(1.0, ["a"], [0.5], velocities=[0.001])  # at rest
    assert buf.at(1.5, 0.05, still_tolerance=2.0)[1:] == (pytest.approx([0.5]), 1.0)
    with pytest.raises(InputError):
        buf.at(3.5, 0.05, still_tolerance=2.0)  # older than the still tolerance
    buf.add(2.0, ["a"], [0.5004], velocities=[0.0])  # later, at rest where it was
    assert buf.at(1.5, 0.05, still_tolerance=2.0)[2] == 1.0
    buf.add(2.5, ["a"], [0.9], velocities=[0.0])  # later, elsewhere: it moved in between
    with pytest.raises(InputError):
        buf.at(2.3, 0.05, still_tolerance=2.0)
    moving, unknown = JointStateBuffer(), JointStateBuffer()
    moving.add(1.0, ["a"], [0.5], velocities=[0.2])
    unknown.add(1.0, ["a"], [0.5])  # no velocities: rest is not known
    for b in (moving, unknown):
        with pytest.raises(InputError) as info:
            b.at(1.5, 0.05, still_tolerance=2.0)
        assert info.value.kind == "stale_joint_state"


def test_the_joint_history_is_bounded_and_bad_states_are_refused() -> None:
    buf = JointStateBuffer()
    for i in range(JOINT_HISTORY + 10):
        buf.add(float(i), ["a"], [float(i)])
    assert len(buf) == JOINT_HISTORY
    with pytest.raises(InputError):
        buf.at(0.0, 0.5)  # dropped
    with pytest.raises(ValueError, match="not finite"):
        buf.add(math.nan, ["a"], [0.0])
    with pytest.raises(ValueError, match="1 names but 2 positions"):
        buf.add(1.0, ["a"], [0.0, 1.0])


def test_a_restarted_clock_replaces_the_joint_history() -> None:
    """A restarted simulator's stamps start near 0: a full history of the old clock must not
    keep them out (they were inserted first and dropped as the oldest, and every frame of the
    new clock was refused for 220 s of stamps to the nearest joint state); a state a little
    older than the newest is kept."""
    buf = JointStateBuffer()
    for i in range(JOINT_HISTORY):
        buf.add(200.0 + 0.01 * i, ["a"], [1.0])
    buf.add(209.0, ["a"], [1.0])  # 1 s older than the newest: late, kept
    assert len(buf) == JOINT_HISTORY
    buf.add(0.6, ["a"], [2.0])
    assert len(buf) == 1
    names, q, at = buf.at(0.6, 0.05)
    assert names == ("a",) and q[0] == 2.0 and at == 0.6


def test_no_model_no_state_or_a_stale_state_refuses_the_frame() -> None:
    filt = RobotFilter(CFG)
    with pytest.raises(InputError) as info:
        filt.pixels(1.0, K_DOWN, T_DOWN, TABLE)
    assert info.value.kind == "no_robot_model"
    assert not filt.set_model("<robot name='broken'><link></robot>")
    assert "robot description" in filt.model_error
    with pytest.raises(InputError, match="robot description"):
        filt.pixels(1.0, K_DOWN, T_DOWN, TABLE)
    assert filt.set_model(SLIDE) and filt.robot is not None
    with pytest.raises(InputError) as info:
        filt.pixels(1.0, K_DOWN, T_DOWN, TABLE)
    assert info.value.kind == "no_joint_state"
    filt.joints.add(0.5, ["x"], [0.0])
    with pytest.raises(InputError) as info:
        filt.pixels(1.0, K_DOWN, T_DOWN, TABLE)
    assert info.value.kind == "stale_joint_state"
    filt.joints.add(1.0, ["y"], [0.0])  # a state without the model's joint
    with pytest.raises(InputError) as info:
        filt.pixels(1.0, K_DOWN, T_DOWN, TABLE)
    assert info.value.kind == "robot_pose"


def test_the_robot_pixels_leave_out_what_is_measured_in_front_of_it() -> None:
    filt = RobotFilter(CFG)
    assert filt.set_model(SLIDE)
    filt.joints.add(1.0, ["x"], [0.1])
    # The cube spans x in [0.05, 0.15] m, 0.25-0.35 m from the camera: its near side wall
    # (x = 0.05) starts at u = 319.5 + 600 * 0.05 / 0.35 = 405.2, its top face at 439.5; row
    # 240 sees it to the image's edge. On the wall at u = 420 the depth is 30 / (420 - 319.5).
    seen = TABLE.copy()
    seen[:, 500:520] = 0.1  # something 10 cm from the lens, in front of the cube
    robot = filt.pixels(1.0, K_DOWN, T_DOWN, seen)
    cols = np.nonzero(robot.cover[240])[0]
    assert cols.min() == 406 and cols.max() == 639
    assert robot.depth[240, 420] == pytest.approx(30 / (420 - 319.5), rel=1e-5)
    assert not robot.mask[240, 500:520].any() and robot.mask[240, 480]
    assert robot.depth[240, 480] == pytest.approx(0.25)
    assert robot.joint_stamp == 1.0
    grown = RobotFilter(RobotFilterConfig(base_pose=(0.0, 0.0, 0.0, 0.0), dilate_px=3))
    assert grown.set_model(SLIDE)
    grown.joints.add(1.0, ["x"], [0.1])
    wide = grown.pixels(1.0, K_DOWN, T_DOWN, TABLE)
    assert np.nonzero(wide.mask[240])[0].min() == 403
    plain = filt.pixels(1.0, K_DOWN, T_DOWN, TABLE)
    assert np.array_equal(wide.cover, plain.cover)  # the cover has no margin
    assert np.all(wide.mask[plain.mask]) and wide.mask.sum() > plain.mask.sum()


def test_clear_robot_makes_the_robot_neutral() -> None:
    rng = np.random.default_rng(0)
    rgb = np.full((48, 64, 3), (200, 180, 150), dtype=np.uint8)
    rgb[:, 40:] = rng.integers(0, 255, (48, 24, 3))  # the robot's pixels, any colour
    depth = np.full((48, 64), 0.6, dtype=np.float32)
    robot = np.zeros((48, 64), dtype=bool)
    robot[:, 40:] = True
    out_rgb, out_depth = clear_robot(rgb, depth, robot)
    assert np.all(out_rgb[robot] == (200, 180, 150)) and np.all(np.isnan(out_depth[robot]))
    assert np.array_equal(out_rgb[~robot], rgb[~robot]) and np.all(out_depth[~robot] == 0.6)
    assert not np.isnan(depth).any()  # the inputs are unchanged


def test_bad_settings_are_refused() -> None:
    for kwargs, match in [({"dilate_px": -1}, "dilate_px"), ({"depth_margin": 1.0}, "depth"),
                          ({"joint_state_tolerance": 0.0}, "tolerance"),
                          ({"still_tolerance": -1.0}, "still_tolerance"),
                          ({"base_pose": (0.0, 0.0, 0.0)}, "base_pose")]:
        with pytest.raises(ValueError, match=match):
            RobotFilterConfig(**kwargs)
