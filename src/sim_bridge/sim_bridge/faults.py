"""Fault injection of ``sim_bridge_node``: which camera frames are dropped, held back or
reordered and which pushes are refused (docs/design/faults.md). ROS-free: the node
passes its frames (any object) and publishes what :meth:`FaultInjector.frames` returns."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

__all__ = ["FaultConfig", "FaultInjector"]

T = TypeVar("T")


@dataclass(frozen=True)
class FaultConfig:
    """Fault injection of the bridge (docs/design/faults.md); all off by default.

    Attributes
    ----------
    frame_drop : float
        Probability in [0, 0.9] that one publication of a camera frame (colour, depth and
        camera_info together) is dropped; ``sim/object_pose`` (ground truth) is never dropped.
    frame_delay : float
        Probability in [0, 0.9] that one publication of a camera frame is held back and
        published right after the next publication of a *newer* frame (so it arrives late and
        out of order; the idle re-publications of its own frame still go out meanwhile).
    push_refusal : float
        Probability in [0, 1] that a valid push is refused (``pushes_refused_fault``).
    seed : int
        Seed of the draws, re-seeded on every ``~/reset``. Which publications are hit also
        depends on how many idle re-publications happen, i.e. on wall time.
    """

    frame_drop: float = 0.0
    frame_delay: float = 0.0
    push_refusal: float = 0.0
    seed: int = 0


class FaultInjector(Generic[T]):
    """The draws of one :class:`FaultConfig` (thread-safe; one held-back frame at most).

    Parameters
    ----------
    config : FaultConfig
    count : callable, optional
        ``count(event)`` for ``frames_dropped``, ``frames_delayed`` and ``frames_reordered``.
    """

    def __init__(self, config: FaultConfig,
                 count: Callable[[str], object] | None = None) -> None:
        self._lock = threading.Lock()
        self._count = count or (lambda event: None)
        self.reset(config)

    def reset(self, config: FaultConfig) -> None:
        """A new scene: new config, draws re-seeded, a held frame of the old scene forgotten."""
        with self._lock:
            self.config = config
            self._rng = np.random.default_rng(config.seed)
            self._held: tuple[float, T] | None = None

    def refuse_push(self) -> bool:
        """Whether the next valid push is refused (probability ``push_refusal``)."""
        if self.config.push_refusal <= 0.0:
            return False
        with self._lock:
            return bool(self._rng.random() < self.config.push_refusal)

    def frames(self, frame: T, time: float) -> list[T]:
        """The frames to publish now for one publication of ``frame`` (stamped ``time``, s),
        in order: none (dropped or held back), ``frame``, and a held-back older frame right
        after it once ``frame`` is newer (delayed and reordered)."""
        cfg = self.config
        if cfg.frame_drop <= 0.0 and cfg.frame_delay <= 0.0 and self._held is None:
            return [frame]
        events = []
        with self._lock:
            out = [frame]
            if cfg.frame_drop > 0.0 and self._rng.random() < cfg.frame_drop:
                out = []
                events.append("frames_dropped")
            if (out and self._held is None and cfg.frame_delay > 0.0
                    and self._rng.random() < cfg.frame_delay):
                self._held, out = (time, frame), []
                events.append("frames_delayed")
            elif self._held is not None and self._held[0] < time:
                out.append(self._held[1])  # an older frame right after a newer one
                self._held = None
                events.append("frames_reordered")
        for event in events:
            self._count(event)
        return out
