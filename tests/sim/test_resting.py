"""sim_bridge.resting: the resting world's clock steps and guard (no ROS, no pybullet)."""

from __future__ import annotations

import threading

from sim_bridge.resting import MAX_IDLE_STEP, Rest
from sim_bridge.worker import Worker


def test_elapsed_is_wall_time_capped_per_tick() -> None:
    now = [10.0]
    rest = Rest(Worker(), now=lambda: now[0])
    try:
        now[0] = 10.02
        assert abs(rest.elapsed() - 0.02) < 1e-12
        now[0] = 15.0  # a stalled executor: at most MAX_IDLE_STEP of resting time
        assert rest.elapsed() == MAX_IDLE_STEP
        assert rest.elapsed() == 0.0  # no time passed since
    finally:
        rest._worker.shutdown()


def test_run_only_while_no_job_runs_and_no_results_go_out() -> None:
    worker = Worker()
    rest, ran = Rest(worker), []
    try:
        assert rest.run(lambda: ran.append(1)) and ran == [1]
        with rest.lock:  # a job's results are going out
            assert not rest.run(lambda: ran.append(2))
        release = threading.Event()
        reason, future = worker.start("a test job", release.wait)  # a job runs
        assert reason == ""
        assert not rest.run(lambda: ran.append(3))
        release.set()
        future.result(5)
        worker.finish()
        assert rest.run(lambda: ran.append(4)) and ran == [1, 4]
    finally:
        worker.shutdown()
