"""Fixtures of the push_core tests: the 10 cm square outline the planner tests push."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from push_core.planner import Outline, prepare_outline

#: Half side of the square, metres.
A = 0.05


def _square_outline(step: float = 0.005) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step`` along each face of the square, including the face centres (so a
    push through the COM exists), counter-clockwise from the bottom face; outward normals."""
    t = np.arange(-A + step, A - step / 2, step)
    t = t[np.abs(t) < A - 1e-12]
    faces = [  # (points, normal), counter-clockwise: bottom, right, top, left
        (np.stack([t, np.full_like(t, -A)], 1), (0.0, -1.0)),
        (np.stack([np.full_like(t, A), t], 1), (1.0, 0.0)),
        (np.stack([-t, np.full_like(t, A)], 1), (0.0, 1.0)),
        (np.stack([np.full_like(t, -A), -t], 1), (-1.0, 0.0)),
    ]
    points = np.concatenate([p for p, _ in faces])
    normals = np.concatenate([np.tile(n, (len(p), 1)) for p, n in faces])
    return points, normals


@pytest.fixture(scope="session")
def square_outline() -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    """``square_outline(step=0.005)``: the square's (points, normals), object frame."""
    return _square_outline


@pytest.fixture(scope="module")
def square() -> Outline:
    """The square as the planner's :class:`~push_core.planner.Outline`."""
    return prepare_outline(*_square_outline())
