"""The closed loop through the real ROS graph (pushbot.runner.episode, pushbot demo).

Real processes (sim_bridge_node, segmentation_node, ekf_node, planner_node) over DDS with
simulated time; no mocks. One graph serves the module (started once, as ``run_graph_trials``
does); every episode is set up through the nodes' parameters and ``~/reset`` services.

- one easy episode reaches the goal by ground truth, and its record is consistent;
- a second, different trial on the same graph (episode set-up and resets between trials);
- Ctrl-C (SIGINT) to ``pushbot demo`` stops every node process it started;
- faults (the repeated runs are ``benchmarks/bench_faults.py``): planner_node killed
  (SIGKILL) after the first push and started again resumes the episode from the latched goal
  and estimate and reaches the goal by ground truth; the object knocked on ``sim/knock`` after
  ``goal reached`` is seen leaving the region and pushed back to the goal;
- agreement: the same trials through the graph and in-process
  (``pushbot.experiments.inprocess.run_trial``) succeed at rates that agree within statistical error
  (95 % Wilson intervals overlap) and mostly succeed or fail together trial by trial (at least n - 3
  of n).
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from pushbot.runner.episode import GraphRunner, run_graph_trials
from pushbot.runner.faults import KillRestart, Knock
from pushbot.runner.graph_record import same_goal
from pushbot.runner.protocol import Trial, check_graph_trial

pytestmark = [pytest.mark.ros, pytest.mark.graph, pytest.mark.slow]

#: The agreement trials: the demo's task and object (random COM), ana, k = 3.
AGREEMENT_TRIALS = [Trial(object="butter", task="mixed", method="ana", k=3, state="filter",
                          com="random", index=i, seed=0) for i in range(8)]
Z95 = 1.959964


def wilson(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion."""
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def test_wilson_interval_by_hand() -> None:
    lo, hi = wilson(8, 8)
    assert hi == pytest.approx(1.0) and lo == pytest.approx(0.6756, abs=1e-4)
    lo, hi = wilson(0, 8)
    assert lo == pytest.approx(0.0, abs=1e-12) and hi == pytest.approx(0.3244, abs=1e-4)
    assert wilson(0, 8)[1] < wilson(8, 8)[0]  # disjoint: the agreement test can fail


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[GraphRunner]:
    with GraphRunner(log_dir=tmp_path_factory.mktemp("graph_logs")) as runner:
        yield runner


def test_one_episode_reaches_the_goal(graph: GraphRunner) -> None:
    trial = Trial(object="rect1", task="mixed", method="ana", k=3, state="filter",
                  com="centre", index=0, seed=0)
    rec = graph.run(trial)
    assert rec["reason"] == "goal reached" and rec["success"], rec
    tol_xy, tol_theta = trial.tolerances
    assert rec["end_error_xy"] <= tol_xy and rec["end_error_theta"] <= tol_theta
    # The record is consistent with itself and with the trial.
    assert rec["trial"] == trial.as_dict()
    assert 1 <= rec["steps"] == len(rec["pushes"]) <= trial.max_steps
    # a push the bridge refused (busy) is a step without a new pose
    assert len(rec["poses_true"]) == len(rec["poses_est"]) == rec["steps"] - rec["refused"] + 1
    pose0 = np.asarray(rec["poses_true"][0])
    np.testing.assert_allclose(pose0, [0.0, 0.0, trial.initial_yaw], atol=2e-3)
    goal_true = pose0 + trial.goal_offset()
    end = np.asarray(rec["poses_true"][-1])
    assert math.hypot(*(end[:2] - goal_true[:2])) == pytest.approx(rec["end_error_xy"])
    # The goal went out as the first estimate plus the offset (yaw in the episode frame).
    np.testing.assert_allclose(rec["goal"], np.asarray(rec["poses_est"][0]) + trial.goal_offset())
    # The first frame defines yaw 0; the first estimate may already have fused a still frame of
    # the resting object (fresh sensor noise: a small fraction of a degree), never more.
    assert abs(rec["poses_est"][0][2]) < math.radians(0.5)
    # The object moved by about the task's 10 cm, the estimate followed it.
    assert np.linalg.norm(end[:2] - pose0[:2]) > 0.08
    assert np.linalg.norm(np.asarray(rec["poses_est"][-1])[:2] - end[:2]) < 0.005
    assert rec["com_error"] is not None and rec["com_error"] < 0.03
    assert all(0.0 < v < 10_000.0 for v in rec["step_latency_ms"])
    assert len(rec["step_latency_ms"]) <= rec["steps"] - 1  # a refused push has no latency


def test_a_disc_is_pushed_to_its_goal_position_with_its_orientation_ignored(
        graph: GraphRunner) -> None:
    # ellip1 is a disc: perception reports no orientation, the EKF fuses the position, the
    # planner scores and stops on the position and says so, the record scores the position.
    trial = Trial(object="ellip1", task="mixed", method="ana", k=3, state="filter",
                  com="centre", index=3, seed=0)
    n_status = len(graph.rec.status)
    rec = graph.run(trial)
    assert rec["orientation_ignored"] is True
    assert rec["reason"] in ("goal reached", "max steps", "no feasible push"), rec["reason"]
    assert rec["success"] == (rec["end_error_xy"] <= trial.tolerances[0])
    # Only this episode's statuses (its goal): a late status of the previous episode (a resting
    # world keeps streaming frames) can arrive after n_status.
    goal = rec["goal"]
    goal_text = " ".join(f"{v:.4f}" for v in (goal[0], goal[1], math.remainder(goal[2],
                                                                             2 * math.pi)))
    mine = [s for s in graph.rec.status[n_status:] if same_goal(s.get("goal", ""), goal_text)]
    messages = [s["_message"] for s in mine]
    assert all(s.get("orientation") == "ignored" for s in mine
               if s.get("state") in ("pushing", "reached")), messages
    if rec["reason"] == "goal reached":  # the runner ended on it: it is in ``mine``
        assert ("goal reached (orientation ignored: rotationally symmetric outline)"
                in messages), messages


def test_consecutive_trials_on_one_graph(graph: GraphRunner) -> None:
    # A different object, orientation and goal right after another episode: the resets must
    # give a fresh reference frame, estimate and goal.
    trial = Trial(object="tri1", task="rotation", method="ana", k=3, state="filter",
                  com="centre", index=5, seed=0, region="medium")
    rec = graph.run(trial)
    np.testing.assert_allclose(rec["poses_true"][0], [0.0, 0.0, trial.initial_yaw], atol=2e-3)
    assert abs(rec["poses_est"][0][2]) < math.radians(0.5) and rec["steps"] >= 1  # as above
    assert rec["reason"] in ("goal reached", "max steps", "no feasible push"), rec["reason"]
    assert rec["success"] == (rec["end_error_xy"] <= trial.tolerances[0]
                              and rec["end_error_theta"] <= trial.tolerances[1])


def _param(node: str, name: str) -> str:
    """``pushbot param get`` of a running node's parameter (its stdout)."""
    exe = Path(sys.executable).parent / "pushbot"
    got = subprocess.run([str(exe), "param", "get", node, name], capture_output=True, text=True,
                         timeout=120, env=dict(os.environ), stdin=subprocess.DEVNULL)
    assert got.returncode == 0, got.stderr
    return got.stdout


def test_the_trials_planner_and_filter_variant_reach_the_nodes(graph: GraphRunner) -> None:
    # Trial.horizon / avoid_contradicted go to planner_node, relearn to ekf_node
    # before the episode (the nodes apply them at their resets), support_cell to the
    # simulator (the scene's), and the episode still runs.
    trial = Trial(object="rect1", task="rotation", method="ana", k=3, state="filter",
                  com="centre", index=2, seed=0, region="medium", horizon=2,
                  avoid_contradicted=True, relearn=True, support_cell=0.015)
    rec = graph.run(trial)
    assert rec["trial"]["horizon"] == 2 and rec["trial"]["relearn"] is True
    assert rec["reason"] in ("goal reached", "max steps", "no feasible push"), rec["reason"]
    assert _param("/planner_node", "lookahead.horizon") == "Integer value is: 2\n"
    assert _param("/planner_node", "avoid_contradicted") == "Boolean value is: True\n"
    assert _param("/ekf_node", "relearn.enabled") == "Boolean value is: True\n"
    assert _param("/sim_bridge_node", "support_cell") == "Double value is: 0.015\n"


FAULT_TRIAL = Trial(object="butter", task="mixed", method="ana", k=3, state="filter",
                    com="random", index=0, seed=0)


def _assert_reached_by_ground_truth(rec: dict) -> None:
    tol_xy, tol_theta = FAULT_TRIAL.tolerances
    assert rec["reason"] == "goal reached" and rec["success"], rec
    assert rec["end_error_xy"] <= tol_xy and rec["end_error_theta"] <= tol_theta


def test_a_killed_planner_is_restarted_and_reaches_the_goal(graph: GraphRunner) -> None:
    # A restarted planner once stalled for good in "waiting for goal, estimate": the goal and
    # the estimate were volatile. Now both are latched on the sending side and read
    # transient local, so the new process resumes the episode.
    rec = graph.run(FAULT_TRIAL, KillRestart("planner_node"))
    assert rec["fault_injected"] and rec["killed_after_pushes"] >= 1, rec
    _assert_reached_by_ground_truth(rec)
    assert rec["pushes_sent"] > rec["killed_after_pushes"]  # the episode went on


def test_a_killed_estimator_is_restarted_and_reaches_the_goal(graph: GraphRunner) -> None:
    # The restarted estimator re-reads the latched outline and takes the camera's next frame:
    # while nothing moves the simulated camera streams still frames with advancing time, so the
    # new process has an estimate without waiting for a push (before, 30 s in 2 of 3 runs).
    rec = graph.run(FAULT_TRIAL, KillRestart("ekf_node"))
    assert rec["fault_injected"] and rec["killed_after_pushes"] >= 1, rec
    assert rec["first_estimate_after_restart_s"] > 0.0
    _assert_reached_by_ground_truth(rec)


def test_an_object_knocked_after_the_goal_is_pushed_back(graph: GraphRunner) -> None:
    rec = graph.run(FAULT_TRIAL, Knock())
    assert rec["fault_injected"] and rec["left_goal"] >= 1, rec
    _assert_reached_by_ground_truth(rec)  # the goal reached again, after the knock
    assert rec["pushes_sent"] > rec["knocked_after_pushes"]


def test_trials_the_graph_cannot_run_are_refused() -> None:
    with pytest.raises(ValueError, match="state must be 'filter'"):
        check_graph_trial(Trial(object="butter", state="gt"))
    with pytest.raises(ValueError, match="Push-Net"):
        run_graph_trials([Trial(object="butter", state="filter", method="pushnet")],
                         progress=False)


def _children(pid: int) -> list[int]:
    """Direct children of ``pid`` (from /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(entry))
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _other_domain() -> int:
    """A domain id outside the sessions' 1-100 (tests/conftest.py), so the demo's graph does not
    meet this module's graph (same node names, same services)."""
    return 101 + int(os.environ["ROS_DOMAIN_ID"]) % 100


def _default_sigint() -> None:  # runs in the child before exec
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_stops_every_process(tmp_path: Path) -> None:
    exe = Path(sys.executable).parent / "pushbot"
    log = tmp_path / "demo.log"
    with open(log, "wb") as out:
        # --pause holds the graph up before the episode until the signal comes, so the signal
        # never races with the end of a short episode.
        # SIGINT at its default in the demo, as in a terminal: a test session started in the
        # background by a shell without job control (`(make test &)`) inherits SIGINT
        # ignored, and the demo then rightly ignores Ctrl-C (two failed clean-clone runs).
        demo = subprocess.Popen([str(exe), "demo", "--skip-doctor", "--pause", "600",
                                 "--out", str(tmp_path)],
                                stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                env={**os.environ, "PYTHONUNBUFFERED": "1",
                                     "ROS_DOMAIN_ID": str(_other_domain())},
                                preexec_fn=_default_sigint)
    try:
        deadline = time.monotonic() + 180.0
        while "pausing" not in log.read_text() and time.monotonic() < deadline:
            assert demo.poll() is None, log.read_text()
            time.sleep(0.05)  # polling the log file: no DDS event to wait on in this process
        assert "pausing" in log.read_text(), log.read_text()
        nodes = _children(demo.pid)
        assert len(nodes) == 4, (nodes, log.read_text())
        demo.send_signal(signal.SIGINT)  # what Ctrl-C in a terminal sends
        try:
            status = demo.wait(timeout=60)
        except subprocess.TimeoutExpired:
            demo.send_signal(signal.SIGUSR1)  # the demo prints its threads' stacks
            time.sleep(2.0)
            tails = "\n".join(f"--- {p.name}:\n{p.read_text(errors='replace')[-1500:]}"
                              for p in sorted((tmp_path / "graph_logs").glob("*.log")))
            pytest.fail(f"the demo did not exit within 60 s of SIGINT:\n{log.read_text()}\n"
                        f"{tails}")
        assert status == 130, log.read_text()
    finally:
        if demo.poll() is None:
            demo.kill()
            demo.wait()
    deadline = time.monotonic() + 10.0
    while any(_alive(p) for p in nodes) and time.monotonic() < deadline:
        time.sleep(0.1)
    survivors = [p for p in nodes if _alive(p)]
    for p in survivors:  # do not leave them behind even when the test fails
        os.kill(p, signal.SIGKILL)
    assert not survivors, log.read_text()
    assert "interrupted; every node process was stopped" in log.read_text()


def test_graph_and_in_process_success_rates_agree(graph: GraphRunner) -> None:
    from pushbot.experiments.inprocess import run_trial

    through_graph = [graph.run(t) for t in AGREEMENT_TRIALS]
    in_process = [run_trial(t) for t in AGREEMENT_TRIALS]
    n = len(AGREEMENT_TRIALS)
    s_graph = sum(r["success"] for r in through_graph)
    s_proc = sum(r["success"] for r in in_process)
    lo_g, hi_g = wilson(s_graph, n)
    lo_p, hi_p = wilson(s_proc, n)
    summary = (f"graph {s_graph}/{n} [{lo_g:.2f}, {hi_g:.2f}], in-process {s_proc}/{n} "
               f"[{lo_p:.2f}, {hi_p:.2f}]; steps graph "
               f"{[r['steps'] for r in through_graph]}, in-process "
               f"{[r['steps'] for r in in_process]}")
    assert lo_g <= hi_p and lo_p <= hi_g, summary  # the 95 % Wilson intervals overlap
    # Same scenes, goals and planner seeds: most trials end the same way (not all: graph runs are
    # not bit-reproducible, estimates differ in the 6th decimal and the closed loop amplifies it).
    same = sum(a["success"] == b["success"] for a, b in zip(through_graph, in_process,
                                                            strict=True))
    print(summary, f"; same outcome in {same}/{n}")
    assert same >= n - 3, summary
