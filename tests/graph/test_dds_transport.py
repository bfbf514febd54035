"""Camera images cross process boundaries with the bundled Fast DDS profile (push_ros.dds).

A 640 x 480 frame is 0.9 MB (rgb8) + 1.2 MB (32FC1 depth). With Fast DDS's default transports
(512 KB shared-memory segments, 208 KB UDP socket buffers) about half of the depth images never
reached another process; the bundled profile declares 32 MB shared-memory segments and 4 MB
UDP buffers (docs/design/dds.md). These tests run sim_bridge_node as its own
process and count what arrives here, and check that shared-memory segments left behind by a
killed process do not break discovery or delivery for the next one, and that a node started by
its own console script (as ``ros2 run`` starts it, without ``pushbot`` setting the profile) gets
the same profile from its ``main()``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image

from push_ros.dds import PROFILE_ENV, profile_path
from pushbot.ros2cli.discovery import cli_node, spin_until

if TYPE_CHECKING:  # the fixtures come from tests/conftest.py
    from conftest import ProcessManager

pytestmark = [pytest.mark.ros, pytest.mark.graph, pytest.mark.slow]

RATE = 5.0  # Hz of repeated frames while the bridge is idle
WINDOW = 6.0  # s of counting
STARTUP_TIMEOUT = 90.0  # s; pybullet scene + discovery on a loaded 2-core machine
DEPTH = "camera/aligned_depth_to_color/image_raw"


def _count_depth_frames(bridge_alive: Callable[[], bool]) -> tuple[int, float]:
    """(depth images received in WINDOW seconds after the first one, measured seconds)."""
    stamps: list[float] = []
    with cli_node("dds_transport") as (node, executor):
        node.create_subscription(Image, DEPTH, lambda m: stamps.append(time.monotonic()),
                                 qos_profile_sensor_data)
        assert spin_until(executor, lambda: bridge_alive() and bool(stamps),
                          time.monotonic() + STARTUP_TIMEOUT), "no depth image arrived"
        start = stamps[-1]
        spin_until(executor, lambda: not bridge_alive(), start + WINDOW)
        assert bridge_alive(), "the bridge exited while frames were counted"
        received = [t for t in stamps if start < t <= start + WINDOW]
    return len(received), WINDOW


def _start_bridge(processes: ProcessManager) -> subprocess.Popen:
    return processes.node("sim_bridge_node", "--ros-args", "-p", f"idle_frame_rate:={RATE}")


def test_session_uses_the_bundled_profile() -> None:
    assert os.environ[PROFILE_ENV] == str(profile_path())
    text = profile_path().read_text()
    assert "<segment_size>33554432</segment_size>" in text
    assert "<receiveBufferSize>4194304</receiveBufferSize>" in text
    assert "<address>127.0.0.1</address>" in text  # loopback only (test_closed_graph.py)


def test_full_size_frames_reach_another_process(processes: ProcessManager) -> None:
    bridge = _start_bridge(processes)
    count, seconds = _count_depth_frames(lambda: bridge.poll() is None)
    # The bridge re-publishes at RATE; allow one frame of timer jitter at each end.
    assert count >= RATE * seconds - 2, (count, processes.output(bridge)[-2000:])


def test_segments_of_a_killed_process_do_not_break_the_next(processes: ProcessManager) -> None:
    first = _start_bridge(processes)
    count, _ = _count_depth_frames(lambda: first.poll() is None)
    assert count > 0
    first.send_signal(signal.SIGKILL)  # leaves its /dev/shm segments and port files behind
    first.wait(timeout=30)
    second = _start_bridge(processes)
    count, seconds = _count_depth_frames(lambda: second.poll() is None)
    assert count >= RATE * seconds - 2, (count, processes.output(second)[-2000:])


def test_a_node_started_by_its_console_script_gets_the_profile(
        processes: ProcessManager) -> None:
    # Without FASTRTPS_DEFAULT_PROFILES_FILE, under UDPv4 only (the tests' and a multi-host
    # setting): before, a second process received 0 colour and 0 depth frames in 30 s.
    env = {PROFILE_ENV: "", "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}  # "" = not set
    script = str(Path(sys.executable).parent / "sim_bridge_node")  # the console script itself
    bridge = processes.start([script, "--ros-args", "-p",
                              f"idle_frame_rate:={RATE}"], env=env)
    count, seconds = _count_depth_frames(lambda: bridge.poll() is None)
    assert count >= RATE * seconds - 2, (count, processes.output(bridge)[-2000:])
    log = processes.output(bridge)
    assert f"DDS: bundled profile {profile_path()} (loopback only)" in log, log[-2000:]
    assert "FASTDDS_BUILTIN_TRANSPORTS=UDPv4 has no effect under it" in log
