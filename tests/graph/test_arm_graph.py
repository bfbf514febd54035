"""The arm through the real graph: push_executor_node drives the simulated Panda.

Real processes (sim_bridge_node with ``robot:=arm``, segmentation_node, ekf_node, planner_node,
push_executor_node) over DDS on simulated time; no mocks. One graph serves the module.

- one episode reaches the goal by ground truth, every push executed by the arm, the true tool
  tip within 1 mm of each commanded contact segment (``sim/tool_tip``), no park between the
  pushes (each trajectory ends at a clear pose), the robot time in the record;
- a dry run (``~/enable`` false) plans, publishes the tool path and refuses the push with kind
  ``disabled`` on ``pusher/refused``; nothing moves (sim time stands still, the joints and the
  object stay);
- ``~/cancel`` stops the arm at its acceleration limits: held (``HELD_STATES`` joint states
  slower than ``HELD``) within the stop's planned time ``stop_s`` plus ``SETTLE`` s of sim
  time after the executor's hold (the simulator paced to real time, ``arm.real_time_factor``
  1, as a real controller runs), where the stop found it; then the arm parks.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml

from pushbot.runner.episode import GraphRunner
from pushbot.runner.graph_nodes import GraphError
from pushbot.runner.protocol import Trial

pytestmark = [pytest.mark.ros, pytest.mark.graph, pytest.mark.slow]

#: A push far from the object at the origin (approach, contact, end; world, m): the executor
#: does not know the object, the arm moves all the same.
FAR_PUSH = np.array([[0.15, -0.22], [0.15, -0.20], [0.15, -0.15]])
#: Joint speed below which the arm counts as held, rad/s, and in how many consecutive joint
#: states (push_executor's ``MeasuredArm`` rule: 3 states at 100 Hz of sim time).
HELD, HELD_STATES = 0.01, 3
#: Sim time the stop may take beyond its planned deceleration, s: the hold's way to the
#: simulator and the executor's estimate of the controller's time (its newest joint state
#: carried forward: a few joint-state periods behind when the machine is loaded; real time at
#: real_time_factor 1), the joints' settling under their position control, one joint state
#: period at the protocol graphs' 50 Hz.
SETTLE = 0.1
#: The graph's executor parameters (the largest joint deviation from the plan while moving,
#: rad; the joint acceleration limit, rad/s^2), read from the file the graph starts it with.
_EXECUTOR = yaml.safe_load((Path(__file__).resolve().parents[2] / "src" / "pushbot_bringup"
                            / "config" / "push_executor.yaml").read_text()
                           )["push_executor_node"]["ros__parameters"]
TRACKING_TOLERANCE = float(_EXECUTOR["tracking_tolerance"])
ACCELERATION = max(float(a) for a in _EXECUTOR["acceleration_limits"])


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[GraphRunner]:
    with GraphRunner(log_dir=tmp_path_factory.mktemp("arm_graph_logs"), robot="arm") as runner:
        yield runner


def test_an_arm_episode_reaches_the_goal_along_the_commanded_lines(graph: GraphRunner) -> None:
    trial = Trial(object="rect1", task="mixed", method="ana", k=3, state="filter",
                  com="centre", index=0, seed=0)
    n_status = len(graph.rec.executor_status)
    rec = graph.run(trial)
    assert rec["reason"] == "goal reached" and rec["success"], rec
    # No park between pushes: every executed push's trajectory ended at a clear pose near the
    # work (its last stage the lift or a withdraw, not the park), the frame after it showing
    # the object all the same (perception measured it: the episode went on to the goal); the
    # arm parked once the episode was over.
    finals = {s["push"]: s["final"] for s in graph.rec.executor_status[n_status:]
              if s.get("push")}
    assert finals and set(finals.values()) <= {"lift", "withdraw"}, finals
    assert graph.rec.executor_status[-1]["at_park"] == "true"
    # Robot time: goal -> final stop, and one cycle per push after the first.
    assert len(rec["cycle_s"]) == rec["steps"] - 1 and all(c > 0 for c in rec["cycle_s"])
    assert rec["robot_time_s"] >= sum(rec["cycle_s"])
    executed = rec["steps"] - rec["refused"]
    assert executed >= 1
    # one contact-line figure per executed push, all within the acceptance's 1 mm
    assert len(rec["contact_line_error_mm"]) == executed, rec["contact_line_error_mm"]
    assert max(rec["contact_line_error_mm"]) <= 1.0, rec["contact_line_error_mm"]
    assert np.linalg.norm(np.asarray(rec["poses_true"][-1])[:2]
                          - np.asarray(rec["poses_true"][0])[:2]) > 0.05


def _held_joint_state(graph: GraphRunner) -> tuple[float, np.ndarray, np.ndarray]:
    """The newest joint state once the arm is held: the last two states at the same positions
    with every joint slower than ``HELD`` (after an episode the arm may still be going back
    to its park pose; on a loaded machine that takes a while in wall time)."""
    def held() -> bool:
        states = list(graph.rec.joint_states)[-2:]
        return len(states) == 2 and np.allclose(states[0][1], states[1][1], atol=1e-9) \
            and all(np.max(np.abs(v)) < HELD for _, _, v in states)
    graph.wait(held, 60.0, "the arm held on /joint_states")
    return graph.rec.joint_states[-1]


def test_a_dry_run_plans_and_refuses_and_moves_nothing(graph: GraphRunner) -> None:
    client = graph._client()
    client.executor_enable(False)
    try:
        # Disabling parks an arm that is not at its park posture (after the episode above it
        # may not be yet): the executor says "disabled" once nothing of its own runs; only then
        # is the held posture the one a dry run must leave alone.
        graph.wait(lambda: bool(graph.rec.executor_status)
                   and graph.rec.executor_status[-1].get("state") == "disabled", 60.0,
                   "executor/status state 'disabled' (the park on disabling finished)")
        stamp0, q0, _ = _held_joint_state(graph)
        true0 = graph.rec.true[-1][1].copy()
        n_refusals, n_paths = len(graph.rec.refusals), graph.rec.executor_paths
        client.publish_push(FAR_PUSH)
        graph.wait(lambda: any(r.get("kind") == "disabled"
                               for r in graph.rec.refusals[n_refusals:]),
                   30.0, "a 'disabled' refusal on pusher/refused")
        graph.wait(lambda: graph.rec.executor_paths > n_paths, 30.0, "executor/path")
        refusal = next(r for r in graph.rec.refusals[n_refusals:] if r["kind"] == "disabled")
        assert refusal["push_stamp"] == "0.000000000"  # the push's own header stamp
        # Idle joint states keep coming (10 Hz wall; the clock runs while the world rests)
        # with the arm where it was: nothing ran.
        count = len(graph.rec.joint_states)
        graph.wait(lambda: len(graph.rec.joint_states) >= count + 5, 30.0, "idle joint states")
        stamp1, q1, _ = graph.rec.joint_states[-1]
        assert stamp1 >= stamp0
        np.testing.assert_allclose(q1, q0, atol=1e-9)
        np.testing.assert_allclose(graph.rec.true[-1][1], true0, atol=1e-9)
    finally:
        client.executor_enable(True)


def test_cancel_stops_the_arm_at_its_acceleration_limits_then_parks(graph: GraphRunner) -> None:
    client = graph._client()
    graph.set_parameters("sim_bridge_node", {"arm.real_time_factor": 1.0})
    _reset_when_idle(graph)
    try:
        n_status = len(graph.rec.executor_status)
        _start_moving(graph, client)
        stops = int(graph.rec.executor_status[-1].get("stopped", "0"))
        client.executor_cancel()
        # The latency counts from the executor's hold (executor/status stop_time: the
        # controller's time when it sent the hold), not from this client's request: with the
        # simulator paced to real time, a loaded machine's service latency would count as
        # robot time.
        stopped = graph.wait(lambda: next((s for s in graph.rec.executor_status[n_status:]
                                           if s.get("state") == "stopped"
                                           and int(s.get("stopped", "0")) > stops), None),
                             30.0, "executor/status 'stopped' after ~/cancel")
        t_stop, stop_s = float(stopped["stop_time"]), float(stopped["stop_s"])
        # at most the Panda's fastest joint limit (2.61 rad/s) at the executor's default
        # acceleration limit (7.5 rad/s^2): 0.35 s
        assert 0.05 <= stop_s <= 0.35, stop_s

        def held_at() -> tuple[float, np.ndarray] | None:
            # Held: HELD_STATES consecutive joint states after the stop, every joint slower
            # than HELD, their postures within 1e-4 rad (the executor's own rule before it
            # parks; the park that follows may start right after them).
            after = [(t, q, v) for t, q, v in list(graph.rec.joint_states) if t >= t_stop]
            for i in range(len(after) - HELD_STATES + 1):
                run = after[i:i + HELD_STATES]
                qs = np.array([q for _, q, _ in run])
                if all(np.max(np.abs(v)) < HELD for _, _, v in run) \
                        and float(np.ptp(qs, axis=0).max()) <= 1e-4:
                    return run[0][0], run[0][1]
            return None

        t_held, q_held = graph.wait(held_at, 60.0, "the arm held after ~/cancel")
        trace = [(round(t - t_stop, 3), round(float(np.max(np.abs(v))), 4))
                 for t, _, v in list(graph.rec.joint_states) if t_stop - 0.05 <= t <= t_held]
        assert t_held - t_stop <= stop_s + SETTLE, (t_stop, stop_s, t_held, trace)
        # held where the stop found it: the hold is the commanded state plus its way to rest
        # (v T / 2 <= a T^2 / 2 for T = stop_s), and the measured state is within the
        # executor's tracking tolerance of the commanded one; the arm neither runs on along
        # its plan nor jumps back
        q_stop = next(q for t, q, _ in reversed(list(graph.rec.joint_states)) if t <= t_stop)
        bound = TRACKING_TOLERANCE + 0.5 * ACCELERATION * stop_s**2
        assert float(np.max(np.abs(q_held - q_stop))) <= bound, (q_held - q_stop, bound)
        # then the arm parks (the next frame must not show it over the object; cancelled
        # that early it may still be within a hundredth of a radian of the park posture)
        graph.wait(lambda: graph.rec.executor_status[-1].get("at_park") == "true"
                   and graph.rec.executor_status[-1].get("state") != "parking", 60.0,
                   "the arm parked after ~/cancel")
    finally:
        graph.set_parameters("sim_bridge_node", {"arm.real_time_factor": 0.0})
        _reset_when_idle(graph)


def _start_moving(graph: GraphRunner, client, attempts: int = 3) -> None:
    """Publish :data:`FAR_PUSH` until the arm moves with it. What the cancel test is about
    starts once the arm moves; a push the executor refuses first (on a loaded machine its
    wall-time start watchdog may stop a motion the simulator started late, kind ``fault``;
    ``busy`` or ``no_state`` right after the reset) is published again, at most ``attempts``
    times, and the refusals are reported if the arm never moved."""
    refused = []
    for _ in range(attempts):
        # the executor says when it can take a push (its model and a joint state arrived, the
        # arm held): a graph just started or a simulator just reset may not be there yet
        graph.wait(lambda: graph.rec.executor_status
                   and graph.rec.executor_status[-1].get("ready") == "true", 60.0,
                   "executor/status ready")
        n, n_refusals = len(graph.rec.joint_states), len(graph.rec.refusals)
        client.publish_push(FAR_PUSH)

        def moving_or_refused(n: int = n, n_refusals: int = n_refusals) -> str | None:
            if any(np.max(np.abs(v)) > 0.05 for _, _, v in list(graph.rec.joint_states)[n:]):
                return "moving"
            new = graph.rec.refusals[n_refusals:]
            return "refused" if new else None

        if graph.wait(moving_or_refused, 60.0, "the arm to move") == "moving":
            return
        refused += graph.rec.refusals[n_refusals:]
        _held_joint_state(graph)
    pytest.fail(f"the arm never moved with the push; refusals: {refused}")


def _reset_when_idle(graph: GraphRunner, timeout: float = 60.0) -> None:
    """Reset the simulator once it accepts: while it follows a trajectory (after ``~/cancel``
    it may still hold the arm for a while) it refuses ``~/reset`` as busy (cc5 under load)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            graph.reset("sim_bridge_node")
            return
        except GraphError as exc:
            if "busy" not in str(exc) or time.monotonic() > deadline:
                raise
        time.sleep(0.5)


def test_a_dry_run_episode_ends_waiting_with_no_step_spent(graph: GraphRunner) -> None:
    """The executor disabled: the planner's push is planned (executor/path) and refused as
    disabled, the episode waits for the robot ('robot unavailable: disabled: ...') with no step
    spent; the graph runner's record and ``pushbot goal --wait`` (exit 3) say so."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from pushbot.runner.arm_faults import DryRun

    trial = Trial(object="rect1", task="mixed", method="ana", k=3, state="filter",
                  com="centre", index=1, seed=0)
    rec = graph.run(trial, DryRun())
    assert rec["fault"] == "dry-run" and rec["steps"] == 0, rec
    assert rec["reason"].startswith("robot unavailable: disabled: "), rec["reason"]
    assert rec["executor_paths"] >= 1 and not rec["success"]
    client = graph._client()
    client.executor_enable(False)
    try:
        exe = Path(sys.executable).parent / "pushbot"
        result = subprocess.run([str(exe), "goal", "0.03", "0.0", "0.0", "--wait", "--timeout",
                                 "120"], capture_output=True, text=True, timeout=180,
                                env=dict(os.environ), stdin=subprocess.DEVNULL)
        assert result.returncode == 3, result.stdout + result.stderr
        assert result.stderr.startswith("pushbot goal: dry run: the executor is disabled")
        assert "robot unavailable: disabled" in result.stdout
    finally:
        graph.reset("planner_node")
        client.executor_enable(True)
