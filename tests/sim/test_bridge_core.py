"""The ROS-free parts of ``sim_bridge_node``: fault injection draws, the worker's job
bookkeeping and published time, and the knock / scene checks and texts (no rclpy here)."""

from __future__ import annotations

import re
import threading
from types import SimpleNamespace

import numpy as np
import pytest

from sim_bridge.commands import (
    MAX_KNOCK_SHIFT,
    check_knock,
    knocked_pose,
    scene_summary,
    unused_com_warning,
)
from sim_bridge.faults import FaultConfig, FaultInjector
from sim_bridge.worker import ARM_BUSY, Timeline, Worker

WORKSPACE = ((-0.2, 0.2), (-0.1, 0.1))


# ---- fault injection -----------------------------------------------------------------------
def _injector(**config: float) -> tuple[FaultInjector[str], list[str]]:
    events: list[str] = []
    return FaultInjector(FaultConfig(**config), events.append), events


def test_no_faults_publish_every_frame_and_draw_nothing() -> None:
    faults, events = _injector()
    assert [faults.frames(f"f{i}", float(i)) for i in range(5)] == [[f"f{i}"] for i in range(5)]
    assert not faults.refuse_push() and events == []


def test_frame_drop_follows_the_seeded_draws() -> None:
    faults, events = _injector(frame_drop=0.5, seed=7)
    draws = np.random.default_rng(7).random(50)
    published = [faults.frames(i, float(i)) for i in range(50)]
    assert published == [[] if d < 0.5 else [i] for i, d in enumerate(draws)]
    assert events == ["frames_dropped"] * int(np.sum(draws < 0.5))


def test_a_delayed_frame_follows_the_next_newer_one() -> None:
    faults, events = _injector(frame_delay=1.0)
    assert faults.frames("old", 1.0) == []  # held back
    assert faults.frames("old again", 1.0) == ["old again"]  # same time: not newer, one held
    assert faults.frames("new", 2.0) == ["new", "old"]  # late and out of order
    assert events == ["frames_delayed", "frames_reordered"]
    assert faults.frames("newer", 3.0) == []  # held again (probability 1)


def test_reset_forgets_the_held_frame_and_reseeds() -> None:
    faults, _ = _injector(frame_delay=1.0)
    assert faults.frames("old scene", 5.0) == []
    faults.reset(FaultConfig())
    assert faults.frames("new scene", 6.0) == ["new scene"]  # the old frame never follows
    refusing = FaultInjector(FaultConfig(push_refusal=0.3, seed=3))
    first = [refusing.refuse_push() for _ in range(20)]
    refusing.reset(FaultConfig(push_refusal=0.3, seed=3))
    assert [refusing.refuse_push() for _ in range(20)] == first
    assert first == list(np.random.default_rng(3).random(20) < 0.3)


# ---- worker and published time -------------------------------------------------------------
def test_one_job_at_a_time_never_queued() -> None:
    worker, release, ran = Worker(), threading.Event(), []
    try:
        busy, job = worker.start("knocking the object", lambda: (release.wait(5), ran.append(1)))
        assert busy == "" and worker.busy == "knocking the object"
        busy2, job2 = worker.start("resetting", ran.append, 2)
        assert busy2 == "busy (knocking the object)" and job2 is None
        release.set()
        job.result(5)
        assert worker.busy == "knocking the object"  # busy until the job says it finished
        worker.finish()
        assert worker.busy == "" and ran == [1]
    finally:
        worker.shutdown()


def test_pushes_are_numbered_and_a_refused_push_is_not() -> None:
    worker, seen = Worker(), []
    try:
        _, job = worker.start("push", lambda seq, x: seen.append((seq, x)), "a", push=True)
        job.result(5)
        assert worker.busy == "executing push 1"
        assert worker.start("push", seen.append, "b", push=True)[0] == "busy (executing push 1)"
        worker.finish()
        worker.start("push", lambda seq, x: seen.append((seq, x)), "c", push=True)[1].result(5)
        assert seen == [(1, "a"), (2, "c")] and worker.pushes == 2
    finally:
        worker.shutdown()


def test_a_job_that_cannot_be_submitted_leaves_the_worker_idle() -> None:
    worker = Worker()
    worker.shutdown()
    with pytest.raises(RuntimeError):
        worker.start("push", print, push=True)
    assert worker.busy == ""


def test_arm_runs_share_the_worker_but_not_with_other_jobs() -> None:
    worker, release, opened = Worker(), threading.Event(), []
    try:
        worker.start("resetting", release.wait, 5)
        assert worker.start_arm(lambda: False, lambda: opened.append(1), print) \
            == "the simulator is busy (resetting)"
        release.set()
        worker.finish()
        loop_done = threading.Event()
        assert worker.start_arm(lambda: False, lambda: opened.append(1), loop_done.wait) == ""
        assert worker.busy == ARM_BUSY and opened == [1]
        assert worker.start_arm(lambda: True, lambda: opened.append(2), print) == ""  # offered
        assert opened == [1]
        loop_done.set()
        worker.call(lambda: None).result(5)  # the run started (queue drained)
        worker.finish()
        assert worker.busy == ""
    finally:
        worker.shutdown()


def test_timeline_never_goes_back_and_continues_across_episodes() -> None:
    timeline, sent = Timeline(), []
    assert timeline.advance(timeline.at(2.5), sent.append)
    assert not timeline.advance(2.0, sent.append) and not timeline.advance(2.5, sent.append)
    timeline.new_episode(timeline.at(3.0))  # the world restarts its sim_time at 0
    assert timeline.at(0.25) == 3.25
    assert timeline.advance(timeline.at(0.25), sent.append)
    # the world rests half a second: same sim_time, later published time
    assert timeline.idle(0.5, 0.25) == timeline.at(0.25) == 3.75
    assert timeline.advance(timeline.at(0.25), sent.append)
    assert timeline.advance(timeline.at(0.5), sent.append)  # a push after the rest
    assert sent == [2.5, 3.25, 3.75, 4.0]
    with pytest.raises(ValueError, match=">= 0"):
        timeline.idle(-0.1, 0.25)


# ---- commands ------------------------------------------------------------------------------
def test_knock_checks() -> None:
    np.testing.assert_array_equal(check_knock((0.06, -0.08, 1.0)), [0.06, -0.08, 1.0])  # 0.1 m
    with pytest.raises(ValueError, match=f"larger than {MAX_KNOCK_SHIFT} m"):
        check_knock((0.08, 0.061, 0.0))
    with pytest.raises(ValueError, match="finite"):
        check_knock((np.nan, 0.0, 0.0))
    np.testing.assert_allclose(knocked_pose((0.15, 0.0, 0.5), np.array([0.05, 0.1, -0.5]),
                                            WORKSPACE), [0.2, 0.1, 0.0])
    with pytest.raises(ValueError, match="leave the workspace"):
        knocked_pose((0.15, 0.0, 0.0), np.array([0.06, 0.0, 0.0]), WORKSPACE)


def test_scene_summary_carries_the_com_pushbot_reads() -> None:
    spec = SimpleNamespace(name="rect1", mass=0.25, com=(0.0123, -0.004),
                           friction_table=0.25, friction_pusher=0.3)
    text = scene_summary(spec, (0.0, 0.01, -0.2), 320, 240, 12.3456789)
    match = re.search(r"COM \((-?[0-9.]+), (-?[0-9.]+)\) m", text)  # pushbot.runner.episode
    assert match and (float(match.group(1)), float(match.group(2))) == (0.0123, -0.004)
    first = re.search(r"first frame at ([0-9.]+) s", text)  # the runner's episode boundary
    assert first and float(first.group(1)) == 12.3456789
    assert "camera 320x240;" in text and "'rect1' (mass 0.25 kg" in text


def test_unused_com_offset_is_named() -> None:
    assert unused_com_warning({"use_com_offset": False, "com_offset": [0.0, 0.0]}) == ""
    assert unused_com_warning({"use_com_offset": True, "com_offset": [0.01, 0.0]}) == ""
    assert "use_com_offset is false" in unused_com_warning(
        {"use_com_offset": False, "com_offset": [0.01, 0.0]})
