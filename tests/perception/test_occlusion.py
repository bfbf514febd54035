"""The pose from the visible part when the robot hides some of the object (in-process, seeded).

Synthetic top-down frames check the geometry exactly; rendered frames of the simulated Panda
over tri1 check the whole path (the robot's pixels from its URDF and joint state, the frame
cleared of them, the CNN, the fit) against the simulator's ground truth.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

from push_perception.model import Segmenter
from push_perception.occlusion import hidden_share, visible_match
from push_perception.perception_config import PerceptionError
from push_perception.robot_filter import RobotFilter, RobotFilterConfig
from push_perception.tracker import EpisodeTracker

from .conftest import K_DOWN, T_DOWN

#: A lopsided pentagon (object frame, m), about 10 x 7 cm.
LOPSIDED = np.array([[0.05, -0.02], [0.03, 0.035], [-0.02, 0.04], [-0.05, 0.0],
                     [-0.01, -0.035]])
#: The scene of the rendered tests: tri1's reference pose, its later pose, and tool tips that
#: make the arm hide a share of it there (the true shares are checked in the tests).
REFERENCE_POSE = (0.0, 0.05, 0.3)
LATER_POSE = (0.01, 0.06, 0.45)
TIPS = {"little": (0.12, 0.094, 0.072), "some": (0.182, 0.002, 0.095),
        "much": (0.191, -0.002, 0.048)}
TIP_ON_REFERENCE = (0.153, 0.114, 0.06)


def test_hidden_share_of_a_square_half_under_the_robot() -> None:
    # A 4 x 4 cm square 13 mm thick seen from 0.6 m straight down; the robot covers x > 0.
    square = np.array([[-0.02, -0.02], [0.02, -0.02], [0.02, 0.02], [-0.02, 0.02]])
    robot = np.zeros((480, 640), dtype=bool)
    robot[:, 320:] = True  # u >= 320 <=> x >= (320 - 319.5) / 600 * depth > 0
    share, pixels = hidden_share(square, 0.013, robot, K_DOWN, T_DOWN)
    assert share == pytest.approx(0.5, abs=0.02)
    side = 0.04 * 600 / (0.6 - 0.013)  # the top face, px (pixel centres inside it)
    assert (side - 1) ** 2 <= pixels <= (side + 1) ** 2
    assert hidden_share(square + [0.1, 0.0], 0.013, robot, K_DOWN, T_DOWN)[0] == 1.0
    assert hidden_share(square - [0.1, 0.0], 0.013, robot, K_DOWN, T_DOWN)[0] == 0.0


@pytest.mark.parametrize("band", [(325, 340), (345, 370)])
def test_a_band_across_the_object_leaves_the_pose(make_frame: Callable[..., Any],
                                                  band: tuple[int, int]) -> None:
    # The rod (15 px) or a link (25 px) across the object's top face (u 284-387 px): the
    # visible part falls in two pieces; the fit to the reference still finds the pose.
    tracker = EpisodeTracker()
    first = make_frame(LOPSIDED, np.array([0.0, 0.0, 0.0]))
    m0 = tracker.update(first.mask, first.depth, first.camera_matrix, first.T_world_camera,
                        robot=np.zeros_like(first.mask))
    assert m0.occluded_share == 0.0
    pose = np.array([0.012, -0.008, 0.35])
    frame = make_frame(LOPSIDED, pose)
    robot = np.zeros_like(frame.mask)
    robot[:, band[0]:band[1]] = True
    depth = frame.depth.copy()
    depth[robot] = 0.4  # the robot, 20 cm above the table
    meas = tracker.update(frame.mask, depth, frame.camera_matrix, frame.T_world_camera,
                          robot=robot)
    # The object frame's origin is the footprint centroid: where the pose puts it.
    c, s = np.cos(pose[2]), np.sin(pose[2])
    expected = np.array([[c, -s], [s, c]]) @ m0.pose[:2] + pose[:2]
    # Within what the tracker achieves on these frames without a robot (test_core).
    assert np.linalg.norm(meas.pose[:2] - expected) < 1e-3
    assert abs(meas.pose[2] - pose[2]) < np.radians(1.0)
    assert 0.05 < meas.occluded_share < 0.3


def test_visible_match_is_the_iou_of_the_predicted_visible_part() -> None:
    sil = np.zeros((10, 10), dtype=bool)
    sil[2:8, 2:8] = True  # 36 px predicted
    robot = np.zeros_like(sil)
    robot[:, 5:] = True  # hides 18 of them
    mask = np.zeros_like(sil)
    mask[2:8, 2:5] = True  # the 18 seen
    assert visible_match(sil, robot, mask) == 1.0
    mask[2:8, 1] = True  # 6 more pixels that the prediction does not hold
    assert visible_match(sil, robot, mask) == pytest.approx(18 / 24)


def test_a_visible_part_unlike_the_outline_gives_no_pose(make_frame: Callable[..., Any]) -> None:
    # Another object under the robot than the episode's: no pose fits what is seen.
    tracker = EpisodeTracker()
    first = make_frame(LOPSIDED, np.array([0.0, 0.0, 0.0]))
    tracker.update(first.mask, first.depth, first.camera_matrix, first.T_world_camera,
                   robot=np.zeros_like(first.mask))
    disc = 0.03 * np.column_stack([np.cos(np.linspace(0, 2 * np.pi, 60, endpoint=False)),
                                   np.sin(np.linspace(0, 2 * np.pi, 60, endpoint=False))])
    frame = make_frame(disc, np.array([0.005, 0.0, 0.0]))
    robot = np.zeros_like(frame.mask)
    robot[:, 330:345] = True
    with pytest.raises(PerceptionError, match="matches the episode.s outline poorly"):
        tracker.update(frame.mask, frame.depth, frame.camera_matrix, frame.T_world_camera,
                       robot=robot)


@pytest.fixture(scope="module")
def arm_scene(world_factory: Callable[..., Any]) -> Iterator[dict[str, Any]]:
    """Rendered frames of tri1 with the arm parked and posed over it, with joint states."""
    world = world_factory(robot="arm", object="tri1", object_pose=REFERENCE_POSE)
    arm = world.arm

    def shot(tip: tuple[float, float, float] | None) -> tuple[Any, Any, float]:
        arm.set_positions(world.config.arm_park if tip is None else arm.inverse_kinematics(tip))
        frame = world.render()
        return frame, arm.state(), float(np.count_nonzero(frame.mask))

    scene: dict[str, Any] = {"reference": shot(None), "touching": shot(TIP_ON_REFERENCE)}
    world.set_object_pose(LATER_POSE)
    scene["clear"] = shot(None)
    for name, tip in TIPS.items():
        scene[name] = shot(tip)
    scene["filter"] = RobotFilter(RobotFilterConfig(base_pose=world.config.arm_base_pose))
    assert scene["filter"].set_model(world.robot_description)
    yield scene


@pytest.fixture(scope="module")
def segmenter() -> Segmenter:
    return Segmenter.load()


def measure(scene: dict[str, Any], tracker: EpisodeTracker, segmenter: Segmenter,
            name: str) -> Any:
    """Measure one shot as segmentation_node does with robot_filter.enabled."""
    frame, state, _ = scene[name]
    filt = scene["filter"]
    filt.joints.clear()  # the shots share one stamp (the world did not step between them)
    filt.joints.add(frame.stamp, state.names, state.positions)
    robot = filt.pixels(frame.stamp, frame.camera_matrix, frame.T_world_camera, frame.depth)
    return tracker.measure_frame(segmenter, frame, robot.mask, robot.cover)


def cover(scene: dict[str, Any], name: str) -> float:
    return 1.0 - scene[name][2] / scene["clear"][2]


def test_partial_cover_gives_the_pose(arm_scene: dict[str, Any], segmenter: Segmenter) -> None:
    tracker = EpisodeTracker()
    m0 = measure(arm_scene, tracker, segmenter, "reference")
    truth = np.subtract(LATER_POSE, REFERENCE_POSE)
    for name in ("little", "some"):
        assert 0.05 < cover(arm_scene, name) < 0.25, name  # the scene is what it claims
        meas = measure(arm_scene, tracker, segmenter, name)
        est = meas.pose - m0.pose
        assert np.linalg.norm(est[:2] - truth[:2]) < 1e-3, name
        assert abs(est[2] - truth[2]) < np.radians(0.5), name
        assert abs(meas.occluded_share - cover(arm_scene, name)) < 0.1, name


def test_too_much_cover_is_refused_and_changes_nothing(arm_scene: dict[str, Any],
                                                       segmenter: Segmenter) -> None:
    tracker = EpisodeTracker()
    m0 = measure(arm_scene, tracker, segmenter, "reference")
    assert cover(arm_scene, "much") > 0.4
    with pytest.raises(PerceptionError, match="the robot hides") as info:
        measure(arm_scene, tracker, segmenter, "much")
    assert info.value.kind == "occluded" and info.value.occluded_share > 0.3
    meas = measure(arm_scene, tracker, segmenter, "clear")  # as if the refusal never happened
    truth = np.subtract(LATER_POSE, REFERENCE_POSE)
    assert np.linalg.norm(meas.pose[:2] - m0.pose[:2] - truth[:2]) < 1e-3
    assert meas.occluded_share == 0.0


def test_the_episodes_outline_comes_from_a_clear_frame(arm_scene: dict[str, Any],
                                                       segmenter: Segmenter) -> None:
    tracker = EpisodeTracker()
    assert cover(arm_scene, "touching") >= 0.0  # on the reference pose: see the fixture
    with pytest.raises(PerceptionError, match="waiting for a clear frame") as info:
        measure(arm_scene, tracker, segmenter, "touching")
    assert info.value.kind == "occluded" and tracker.outline is None
    assert measure(arm_scene, tracker, segmenter, "reference").is_reference
