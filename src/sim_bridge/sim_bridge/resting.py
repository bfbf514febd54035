"""Time and camera frames while the simulated world rests (no job runs), ROS-free.

A real robot's clock and camera do not stop when nothing moves. While no job steps the world,
``sim_bridge_node`` lets its published time pass as wall time does (:meth:`Rest.elapsed`,
at most :data:`MAX_IDLE_STEP` s per tick, into :meth:`sim_bridge.worker.Timeline.idle`) and
streams still frames of the resting scene (:meth:`sim_bridge.world.PushWorld.still_frame`).
:meth:`Rest.run` runs such an action only while the worker is idle and holds :attr:`Rest.lock`
meanwhile; a job's results go out under the same lock, so no resting frame or time step comes
between a job's end and its results.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from sim_bridge.worker import Worker

__all__ = ["MAX_IDLE_STEP", "Rest"]

#: Longest step of resting time per tick, s: a stalled executor does not make time jump.
MAX_IDLE_STEP = 0.1


class Rest:
    """The resting world's guard and clock (module docstring).

    Parameters
    ----------
    worker : Worker
        Whose ``busy`` says whether a job runs.
    now : callable
        A monotonic clock, s (default :func:`time.monotonic`).
    """

    def __init__(self, worker: Worker, now: Callable[[], float] = time.monotonic) -> None:
        self.lock = threading.Lock()
        self._worker, self._now = worker, now
        self._tick = now()

    def elapsed(self) -> float:
        """Wall time since the previous call, s, at most :data:`MAX_IDLE_STEP`."""
        now = self._now()
        elapsed, self._tick = now - self._tick, now
        return min(max(elapsed, 0.0), MAX_IDLE_STEP)

    def run(self, action: Callable[[], object]) -> bool:
        """Run ``action()`` under :attr:`lock` if no job runs (and none holds the lock, i.e.
        no job's results are going out); whether it ran."""
        if self._worker.busy or not self.lock.acquire(blocking=False):
            return False
        try:
            if self._worker.busy:
                return False
            action()
            return True
        finally:
            self.lock.release()
