"""Fixtures of the perception tests: synthetic top-down frames and rendered pybullet frames."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from push_core.geometry import object_to_world
from sim_bridge.camera import project

#: Synthetic camera: 640 x 480, f = 600 px, 0.6 m above the table looking straight down.
K_DOWN = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])
T_DOWN = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.6],
                   [0.0, 0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class SyntheticFrame:
    """A flat polygon seen from straight above: exact mask and depth."""

    mask: np.ndarray
    depth: np.ndarray
    camera_matrix: np.ndarray
    T_world_camera: np.ndarray  # noqa: N815 - the world's name


def synthetic_frame(polygon: np.ndarray, pose: np.ndarray, thickness: float = 0.013,
                    size: tuple[int, int] = (640, 480)) -> SyntheticFrame:
    """Render ``polygon`` (object frame, (P, 2), m) at ``pose`` (x, y, theta) analytically.

    The top face at z = thickness projects to a similar polygon (the image plane is parallel
    to the table); it is filled with 1/16 px precision. Depth: 0.6 m - thickness on the
    object, 0.6 m on the table.
    """
    w, h = size
    corners = np.column_stack([object_to_world(pose, polygon),
                               np.full(len(polygon), thickness)])
    uv = project(corners, K_DOWN, T_DOWN)
    mask = np.zeros((h, w), dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(uv * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    depth = np.full((h, w), 0.6, dtype=np.float32)
    depth[mask > 0] = 0.6 - thickness
    return SyntheticFrame(mask > 0, depth, K_DOWN.copy(), T_DOWN.copy())


@pytest.fixture
def make_frame() -> Callable[..., SyntheticFrame]:
    """``make_frame(polygon, pose, thickness=0.013)`` -> :class:`SyntheticFrame`."""
    return synthetic_frame


@pytest.fixture(scope="module")
def world_factory() -> Iterator[Callable[..., object]]:
    """``world_factory(**WorldConfig kwargs)`` -> a PushWorld, closed after the module."""
    from sim_bridge.world import PushWorld, WorldConfig

    worlds: list[PushWorld] = []

    def make(**kwargs: object) -> PushWorld:
        world = PushWorld(WorldConfig(**kwargs))
        worlds.append(world)
        return world

    yield make
    for world in worlds:
        world.close()
