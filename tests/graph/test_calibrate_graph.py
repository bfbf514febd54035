"""``pushbot calibrate`` against the real arm graph: the command's process, its joint goals to
push_executor_node over DDS, the simulated Panda carrying the rendered ChArUco board, frames
from the camera placed away from the default viewpoint (``camera.use_pose``); no mocks.

- the executor disabled (a dry run): the command is refused as ``robot`` in one line, exit
  status 3, and writes nothing;
- enabled: exit status 0, the extrinsics YAML within 2 mm / 0.2 deg of the placed camera's
  truth (the acceptance figures over 20 placements are RESULTS ``calibrate``), and the
  ``static_transform_publisher`` line printed with the same pose.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pushbot.runner.calibrate import read_extrinsics
from pushbot.runner.episode import GraphRunner

pytestmark = [pytest.mark.ros, pytest.mark.graph, pytest.mark.slow]

#: The placed camera (world, m; its optical frame's quaternion x, y, z, w): 3.5 cm from the
#: default viewpoint, turned by about 2 deg.
TRUTH_POSITION = np.array([0.515, 0.025, 0.64])
TRUTH_ROTATION = (Rotation.from_quat([-0.6743797232066279, -0.6743797232066278,
                                      0.2126311099715939, 0.2126311099715939])
                  * Rotation.from_euler("xy", [1.5, -1.0], degrees=True))
#: Generated views after the first: the fewest the command accepts with margin (6 reachable
#: poses in all), to keep the test short.
POSES = 5


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[GraphRunner]:
    pose = ",".join(f"{v:.12g}" for v in (*TRUTH_POSITION, *TRUTH_ROTATION.as_quat()))
    sim_args = ["calibration.board:=true", "camera.use_pose:=true", f"camera.pose:=[{pose}]"]
    with GraphRunner(log_dir=tmp_path_factory.mktemp("calibrate_graph_logs"), robot="arm",
                     node_args={"sim_bridge_node": sim_args}) as runner:
        yield runner


def _calibrate(out: Path) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).parent / "pushbot"
    return subprocess.run([str(exe), "calibrate", "--poses", str(POSES), "--out", str(out)],
                          capture_output=True, text=True, timeout=300, env=dict(os.environ),
                          stdin=subprocess.DEVNULL)


def test_calibrate_is_refused_while_the_executor_is_disabled(graph: GraphRunner,
                                                            tmp_path: Path) -> None:
    out = tmp_path / "extrinsics.yaml"
    graph.executor_enable(False)
    try:
        result = _calibrate(out)
    finally:
        graph.executor_enable(True)
    assert result.returncode == 3, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pushbot calibrate: refused (robot): "), lines
    assert "disabled" in lines[0] and f"nothing written to {out}" in lines[0]
    assert not out.exists()


def test_calibrate_finds_the_placed_camera(graph: GraphRunner, tmp_path: Path) -> None:
    out = tmp_path / "extrinsics.yaml"
    result = _calibrate(out)
    assert result.returncode == 0, result.stdout + result.stderr
    t, frame_id, child_frame_id = read_extrinsics(out)
    assert (frame_id, child_frame_id) == ("world", "camera_color_optical_frame")
    position = t[:3, 3]
    rotation = Rotation.from_matrix(t[:3, :3])
    error_mm = 1e3 * float(np.linalg.norm(position - TRUTH_POSITION))
    error_deg = float(np.degrees((rotation.inv() * TRUTH_ROTATION).magnitude()))
    assert error_mm <= 2.0 and error_deg <= 0.2, (error_mm, error_deg, result.stdout)
    line = next(s for s in result.stdout.splitlines() if "static_transform_publisher" in s)
    printed = [float(line.split(f"--{k} ")[1].split()[0]) for k in ("x", "y", "z")]
    assert np.allclose(printed, position, atol=1e-5)
    assert "--frame-id world --child-frame-id camera_color_optical_frame" in line
