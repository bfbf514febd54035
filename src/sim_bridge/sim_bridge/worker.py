"""The worker of ``sim_bridge_node``: one thread for every pybullet call, one job at a time,
never queued, and the published time (``epoch + sim_time``, monotonic). ROS-free.

A job (a push, a knock, a reset, a run of arm trajectories) is started only while the worker is
idle; a request arriving meanwhile is answered with the reason (:meth:`Worker.start` returns
it). The worker is never left busy: a job that cannot be submitted releases it at once, and
every job ends with :meth:`Worker.finish`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

__all__ = ["ARM_BUSY", "Timeline", "Worker"]

#: The worker's state while the arm follows trajectories.
ARM_BUSY = "following joint trajectories"


class Worker:
    """One job at a time in one thread (thread-safe).

    Parameters
    ----------
    name : str
        Thread name prefix.
    """

    def __init__(self, name: str = "sim_bridge_world") -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix=name)
        self._lock = threading.Lock()
        self._busy = ""  # "" = idle, else what the worker does
        self._arm_queued = 0  # arm runs submitted and not started yet
        self.pushes = 0  # pushes handed to the worker

    @property
    def busy(self) -> str:
        """What the worker does ("" = idle)."""
        return self._busy

    def call(self, job: Callable[..., Any], *args: Any) -> Future:
        """Run ``job`` in the worker thread without claiming it (building, closing)."""
        return self._pool.submit(job, *args)

    def start(self, what: str, job: Callable[..., Any], *args: Any,
              push: bool = False) -> tuple[str, Future | None]:
        """Claim the idle worker for ``job(*args)``; ``("", future)``, or ``(reason, None)``
        when busy (nothing is queued). A ``push`` is numbered from 1, called as
        ``job(number, *args)`` and described as ``executing push <number>``."""
        with self._lock:
            if self._busy:
                return f"busy ({self._busy})", None
            if push:
                self.pushes += 1
                args = (self.pushes, *args)
                what = f"executing push {self.pushes}"
            self._busy = what
        return "", self._submit(job, *args)

    def start_arm(self, offer: Callable[[], bool], open_: Callable[[], None],
                  job: Callable[[], Any]) -> str:
        """Hand a trajectory to a running arm loop (``offer()`` true) or start one (``open_()``,
        then ``job`` in the worker); the reason when the worker does something else."""
        with self._lock:
            if self._busy and self._busy != ARM_BUSY:
                return f"the simulator is busy ({self._busy})"
            if offer():
                return ""
            open_()
            self._busy, self._arm_queued = ARM_BUSY, self._arm_queued + 1
        self._submit(self._arm_job, job)
        return ""

    def _arm_job(self, job: Callable[[], Any]) -> Any:
        with self._lock:
            self._arm_queued -= 1
        return job()

    def _submit(self, job: Callable[..., Any], *args: Any) -> Future:
        try:
            return self._pool.submit(job, *args)
        except BaseException:  # never left busy without a job that ends it
            self.finish()
            raise

    def finish(self) -> None:
        """The running job ended: idle (or back to the arm loop a submitted run starts)."""
        with self._lock:
            self._busy = ARM_BUSY if self._arm_queued else ""

    def shutdown(self, last: Callable[[], Any] | None = None) -> None:
        """Run ``last`` after a running job, then stop the thread."""
        if last is not None:
            self._pool.submit(last)
        self._pool.shutdown(wait=True)


class Timeline:
    """Published time = ``epoch + sim_time``, never going backwards (thread-safe).

    The world restarts its ``sim_time`` at 0 on every reset; :meth:`new_episode` moves the
    epoch so that the new episode continues where the old one stopped.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.epoch = 0.0
        self.last = -1.0  # newest published time, s (-1: none yet)

    def at(self, sim_time: float) -> float:
        """The published time of a world ``sim_time``, s."""
        return self.epoch + float(sim_time)

    def new_episode(self, time_before: float) -> None:
        """The world restarted its sim_time: continue at ``time_before`` (s)."""
        self.epoch = float(time_before)

    def advance(self, time: float, publish: Callable[[float], Any]) -> bool:
        """``publish(time)`` if ``time`` is later than the newest published time."""
        with self._lock:
            if time <= self.last:
                return False
            self.last = float(time)
            publish(self.last)
        return True

    def idle(self, seconds: float, sim_time: float) -> float:
        """Time passes while the world rests (no physics step): later published times move
        ``seconds`` (s, >= 0) further on; the world's own ``sim_time`` (s) is unchanged.
        Returns the published time of ``sim_time`` now."""
        if not seconds >= 0.0:
            raise ValueError(f"idle time must be >= 0 s, got {seconds!r}")
        with self._lock:
            self.epoch += float(seconds)
            return self.epoch + float(sim_time)
