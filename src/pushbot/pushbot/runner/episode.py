"""Protocol trials through the real ROS graph: four node processes over DDS.

:func:`run_graph_trials` (``pushbot eval push --graph``) and the demo (``pushbot demo``) start
``sim_bridge_node``, ``segmentation_node``, ``ekf_node`` and ``planner_node`` as separate
processes (``pushbot run <node>``, simulated time from the bridge's ``/clock``, the bundled DDS
profile of :mod:`push_ros.dds`) once, and run every trial through them. A hidden client node in
this process drives the episodes only through the nodes' public interfaces:

1. **Episode parameters.** ``planner_node``: ``method``, ``direct``, ``k``,
   ``goal_tolerance.{xy,theta}``, ``max_steps``, ``seed``, ``lookahead.horizon``,
   ``avoid_contradicted`` (:func:`pushbot.runner.protocol.planner_episode_params`);
   ``ekf_node``: ``relearn.enabled`` (:attr:`Trial.relearn`), via their
   ``set_parameters`` services; then ``/segmentation_node/reset`` (the next *new* frame
   becomes the episode's reference; repeated frames of the old scene are skipped),
   ``/ekf_node/reset`` (repeated observations of the old scene are dropped) and
   ``/planner_node/reset`` (applies the parameters, forgets the goal and estimates).
2. **Scene.** ``sim_bridge_node``: ``object``, ``initial_pose.{x,y,theta}``, ``com_offset``
   (``[0, 0]`` for COM at the centre, empty = the randomised COM), ``seed``, ``randomize``,
   ``support_cell`` (:meth:`Trial.world_kwargs`), then ``/sim_bridge_node/reset``, which
   rebuilds the scene and publishes its first frame (stamps strictly later than the previous
   scene's).
3. **Goal.** The first ``estimator/object_pose`` at or after the new scene's reference frame
   (the new ``perception/outline``'s stamp) plus
   :meth:`Trial.goal_offset` (docs/design/evaluation.md#goal-frame: yaw in the episode frame) on
   ``goal_pose``.
4. **Run** until ``planner/status`` (with this goal) says ``goal reached`` or ``failed``.
5. **Record** (docs/design/evaluation.md#episode-record): ground truth from ``sim/object_pose`` (the
   pose at the stamp of each frame the pipeline saw), estimates from
   ``estimator/object_pose``, pushes from ``planner/push``; success from the *true* pose
   against the true initial pose plus the offset, orientation modulo the object's symmetry
   (:func:`push_core.episode.end_score`); ``com_error`` from
   ``estimator/center_of_mass`` against the true COM (parsed from the bridge's reset message, 0.1 mm
   resolution) turned into the episode frame. ``planning_ms`` is empty (planning happens inside
   ``planner_node``); ``step_latency_ms`` holds, per step, the wall time from ``pusher/executed`` to
   the next ``planner/push`` as seen here (perception + estimation + planning + DDS).

Fault scenarios: ``GraphRunner.run(trial, fault)`` with a
:class:`pushbot.runner.faults.Fault` adds its episode parameters (the bridge's ``faults.*``,
the planner's ``after_goal``), lets it act on every spin of the end wait (kill and restart a
node, knock the object, send a push or a second goal) and ends the episode only at an end
status it accepts; the record is scored against the episode's last goal and carries the fault's
fields. ``benchmarks/bench_faults.py`` repeats every scenario.

Every wait has a deadline and names what it waited for; a node process that exits is reported
with the tail of its log. Node processes run in their own process groups with a parent-death
signal (SIGTERM); :meth:`GraphNodes.stop` sends SIGINT (what rclpy shuts down cleanly on),
then SIGTERM, then SIGKILL to each group, so Ctrl-C leaves no process behind.

Only ``state="filter"`` trials with ``estimate_com`` and planner methods (``ana``, ``lrn``,
``geo``, ``rdn`` and the ``-direct`` variants) can run in the graph: it has no ground-truth
state source, no COM pinning and no Push-Net node.
"""

from __future__ import annotations

import math
import re
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from push_core.episode import new_record
from pushbot.ros2cli.discovery import sigterm_as_keyboard_interrupt
from pushbot.runner.client import GraphClient, Recorded
from pushbot.runner.faults import Fault
from pushbot.runner.graph_nodes import NODES, GraphError, GraphNodes
from pushbot.runner.graph_record import (
    end_reason,
    first_estimate,
    graph_robot_times,
    latencies,
    line_deviation,
    same_goal,
    status_seconds,
)
from pushbot.runner.protocol import (
    Trial,
    bridge_scene_params,
    check_graph_trial,
    planner_episode_params,
)
from pushbot.runner.scenario import Episode

__all__ = ["NODES", "GraphError", "GraphNodes", "GraphRunner", "Recorded", "run_graph_trials"]

#: Seconds from the scene reset to the first estimate (segmentation of the first frame), and
#: how often the episode set-up is repeated when none arrives.
FIRST_ESTIMATE_TIMEOUT, FIRST_ESTIMATE_ATTEMPTS = 30.0, 3
#: Seconds without any progress (push, executed push, status change) before an episode fails.
STEP_TIMEOUT = 90.0
#: Scenes and seconds per scene to wait for the first estimate at the planner at start-up.
WARM_UP_ATTEMPTS, WARM_UP_TIMEOUT = 24, 5.0
#: The bridge's fault injection, off (every episode sets it; a fault scenario overrides it).
NO_BRIDGE_FAULTS = {"faults.frame_drop": 0.0, "faults.frame_delay": 0.0,
                    "faults.push_refusal": 0.0, "faults.seed": 0}
_COM_RE = re.compile(r"COM \((-?[0-9.]+), (-?[0-9.]+)\) m")
_FIRST_FRAME_RE = re.compile(r"first frame at ([0-9.]+) s")
_INPUTS_AFTER_RE = re.compile(r"inputs after ([0-9.]+) s")


class GraphRunner:
    """The graph (processes + client node); a context manager. See the module docstring.

    Parameters
    ----------
    log_dir : Path, optional
        Node logs (default: a temporary directory).
    record_frames : bool
        Also keep every new camera frame and perception mask (the demo's video).
    node_args : dict, optional
        Extra start-up parameters per node (``"name:=value"`` strings).
    robot : str
        ``pusher`` (the simulator's finger) or ``arm`` (``push_executor_node`` and the
        simulated Panda; :class:`pushbot.runner.graph_nodes.GraphNodes`).
    node_exe : Path, optional
        The ``pushbot`` executable of the node processes (:class:`GraphNodes`).
    """

    def __init__(self, log_dir: Path | None = None, record_frames: bool = False,
                 node_args: dict[str, Sequence[str]] | None = None, robot: str = "pusher",
                 node_exe: Path | None = None) -> None:
        self._tmp = None
        if log_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="pushbot_graph_")
            log_dir = Path(self._tmp.name)
        self.log_dir = Path(log_dir)
        self.record_frames = record_frames
        self.robot = robot
        self.nodes = GraphNodes(self.log_dir, node_args, robot=robot, node_exe=node_exe)
        self.rec = Recorded()
        self.client: GraphClient | None = None
        self._com_true: np.ndarray | None = None
        self._c_true_episode: np.ndarray | None = None

    # ---- lifecycle ---------------------------------------------------------------------------
    def __enter__(self) -> GraphRunner:
        try:
            self.start()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def start(self) -> None:
        """Start the processes and the client; wait until every endpoint is discovered and an
        estimate has gone all the way from the bridge's camera to the planner."""
        self.nodes.start()
        self.client = GraphClient(self.rec, self.nodes.check_alive, self.log_dir,
                                  self.record_frames, robot=self.robot)
        self.client.start()
        self.client.wait_ready()
        self._warm_up()

    def close(self) -> None:
        """Stop the client and every node process (idempotent)."""
        try:
            if self.client is not None:
                self.client.close()
        finally:
            self.client = None
            self.nodes.stop()
            if self._tmp is not None:
                self._tmp.cleanup()
                self._tmp = None

    def restart(self) -> None:
        """Stop everything and start again (after a failed episode)."""
        self.close()
        self.rec = Recorded()
        self.nodes = GraphNodes(self.log_dir, self.nodes.node_args, robot=self.robot,
                                node_exe=self.nodes.node_exe)
        self.start()

    # ---- the client's waits and calls -----------------------------------------------------------
    def wait(self, predicate: Callable[[], Any], timeout: float, what: str) -> Any:
        """:meth:`GraphClient.wait` (spin until ``predicate()`` is not None/False)."""
        return self._client().wait(predicate, timeout, what)

    def reset(self, node_name: str) -> str:
        """Call ``/<node_name>/reset``; its message (:class:`GraphError` if refused)."""
        return self._client().reset(node_name)

    def set_parameters(self, node_name: str, values: dict[str, Any]) -> None:
        """Set parameters of ``node_name`` (:class:`GraphError` if one is refused)."""
        self._client().set_parameters(node_name, values)

    def _client(self) -> GraphClient:
        if self.client is None:
            raise GraphError("the graph is not running (start() it, or use it as a context "
                             "manager)")
        return self.client

    def knock(self, delta: np.ndarray) -> None:
        """Displace the object by ``delta`` (dx, dy m, dyaw rad) on ``sim/knock``."""
        self._client().publish_knock(delta)

    def foreign_push(self, points: np.ndarray) -> None:
        """Send a push (approach, contact, end; (3, 2) m) on ``planner/push`` as another
        client."""
        self._client().publish_push(points)

    def send_goal(self, goal: np.ndarray, other: bool = False) -> str:
        """Send a goal (``other``: from the second, volatile sender); its status text."""
        return self._client().publish_goal(goal, other=other)

    def client_matched(self) -> bool:
        """Whether the client's fault publishers (second goal sender, knock) are matched."""
        return self._client().matched()

    def foreign_trajectory(self, names: list[str], positions: list[float], seconds: float
                           ) -> None:
        """Command the arm to ``positions`` in ``seconds`` as another client (``robot`` arm)."""
        self._client().publish_trajectory(names, positions, seconds)

    def executor_enable(self, enable: bool) -> str:
        """``/push_executor_node/enable`` (``robot`` arm); its message."""
        return self._client().executor_enable(enable)

    def _planner_estimates(self) -> int:
        return self._client().planner_estimates()

    def _warm_up(self) -> None:
        """Wait until planner_node counts an estimate and this client received one: the whole
        chain bridge -> perception -> estimator -> planner (and this client) is matched.

        Seeing an endpoint in the graph does not mean every other participant has matched it
        yet, and a reliable, volatile sample published before the match is lost (found on a
        loaded machine: the planner never got the first estimate of the first episode, and
        the estimator publishes one estimate per new frame). If no estimate arrives, the
        scene is rebuilt (new frames, so a new estimate) and the wait repeated.
        """
        for _ in range(WARM_UP_ATTEMPTS):
            before, n_est = self._planner_estimates(), len(self.rec.est)
            for name in ("segmentation_node", "ekf_node", "planner_node", "sim_bridge_node"):
                self.reset(name)
            try:
                self.wait(lambda b=before, n=n_est: (self._planner_estimates() > b
                                                     and len(self.rec.est) > n) or None,
                          WARM_UP_TIMEOUT, "an estimate at planner_node and at this client")
                return
            except GraphError:
                self.nodes.check_alive()
        raise GraphError(f"planner_node received no estimate in {WARM_UP_ATTEMPTS} scenes of "
                         f"{WARM_UP_TIMEOUT:.0f} s; node logs in {self.log_dir}")

    # ---- one episode -------------------------------------------------------------------------
    def run(self, trial: Trial, fault: Fault | None = None) -> dict[str, Any]:
        """Run ``trial`` through the graph; returns its episode record (module docstring).

        ``fault``: a fault scenario (:mod:`pushbot.runner.faults`) injected during the episode;
        the record then also has its fields (``fault``, ``fault_injected``, ``pushes_sent``,
        ``goal_switches``, ``left_goal``, ...) and is scored against the episode's last goal.
        """
        check_graph_trial(trial)
        scenario, fault = fault is not None, fault if fault is not None else Fault()
        t_start = time.perf_counter()
        rec = new_record(trial.as_dict(), step_latency_ms=[], engine="graph")
        reference, first_stamp, first_est = self._first_estimate(trial, fault)
        # The planner must hold this scene's outline (stamped with its reference frame) before
        # the goal: with the previous scene's outline it would plan, or declare the goal
        # reached, for the wrong object.
        self.wait(lambda: any(status_seconds(s, "outline_stamp") >= reference - 1e-6
                                for s in self.rec.status),
                  STEP_TIMEOUT, f"planner_node to hold the outline of the frame at "
                  f"{reference:.3f} s")
        pose0_true = self._true_at(first_stamp)
        goal = trial.goal(first_est)
        n_push, n_exec, n_status = (len(self.rec.pushes), len(self.rec.executed),
                                    len(self.rec.status))
        t_goal = self.rec.clock  # the simulated time when the goal goes out
        fault.before_goal(self)
        goal_text = self._client().publish_goal(goal)
        episode = Episode(trial, n_push, n_exec, n_status, np.asarray(goal, dtype=float),
                          np.asarray(trial.goal_offset(), dtype=float), goal_text)
        try:
            status = self._wait_end(episode, fault)
        finally:
            fault.after_episode(self)
        self._wait_recorded(status, n_push, n_exec)
        pushes = self.rec.pushes[n_push:]
        # A restarted simulator's clock starts again near 0: (wall time, index of the first
        # ground truth and estimate of the new clock); later pushes are matched from there.
        restart = episode.notes.get("clock_restart")
        executed = [e for e in self.rec.executed[n_exec:]
                    if e[1] >= first_stamp or (restart and e[0] >= restart[0])]

        def since(e: tuple[float, float, float], which: int) -> int:
            return restart[which] if restart and e[0] >= restart[0] else 0
        rec["steps"] = int(status.get("step", len(pushes)))
        rec["refused"] = max(0, rec["steps"] - len(executed))
        rec["reason"] = end_reason(status["_message"])
        if executed:  # the truth after the last push has arrived too
            t_last = executed[-1][2]
            self.wait(lambda: any(s >= t_last for s, _ in self.rec.true), STEP_TIMEOUT,
                      "sim/object_pose after the last push")
        rec["pushes"] = [p.tolist() for _, p in pushes]
        rec["poses_true"] = [pose0_true.tolist()] + [
            self._true_after(e[2], since(e, 1)).tolist() for e in executed]
        rec["poses_est"] = [first_est.tolist()] + [
            self._est_after(e[2], first_est, since(e, 2)).tolist() for e in executed]
        # Stamps of the camera frames the estimates came from (before the first push, after each).
        rec["frame_stamps"] = [first_stamp] + [
            next((st for st, _ in self.rec.est[since(e, 2):] if st >= e[2]), e[2])
            for e in executed]
        rec["step_latency_ms"] = latencies(executed, pushes)
        rec.update(graph_robot_times(t_goal, first_stamp, self.rec.push_stamps[n_push:],
                                     rec["frame_stamps"][-1] if executed else None))
        if self.robot == "arm":
            rec["contact_line_error_mm"] = self._line_errors(executed, pushes,
                                                             restart[0] if restart else -math.inf)
        end_true = (self._true_after(executed[-1][2], since(executed[-1], 1)) if executed
                    else pose0_true)
        from push_core.episode import end_score
        from push_core.objects import load_object
        from push_core.symmetry import symmetry_order_of_polygon

        polyline = load_object(trial.object).polyline()
        order = symmetry_order_of_polygon(polyline)
        rec.update(end_score(polyline, end_true, pose0_true + episode.offset,
                             trial.tolerances))
        rec["com_error"] = self._com_error(pose0_true, end_true, order)
        rec["goal"] = episode.goal.tolist()
        if scenario:
            rec.update(fault.record(self, episode))
        rec["com_true"] = None if self._com_true is None else self._com_true.tolist()
        rec["com_true_episode"] = (None if self._c_true_episode is None
                                   else self._c_true_episode.tolist())
        rec["com_est"] = self.rec.com[-1][1].tolist() if self.rec.com else None
        rec["wall_s"] = time.perf_counter() - t_start
        if restart:  # later episodes are matched on the new clock only
            self.rec.forget_stamps()
        if self.robot == "arm":
            self._wait_arm_parked()
        return rec

    def _wait_arm_parked(self) -> None:
        """The executor parks the arm once the episode is over; the next scene is not set up
        while it moves (the simulator refuses ``~/reset`` while it follows a trajectory). A
        stopped arm stays where it is (the next scene's reset parks it)."""
        def parked() -> bool:
            status = self.rec.executor_status[-1] if self.rec.executor_status else {}
            return status.get("state") == "stopped" or (
                status.get("state") in ("idle", "disabled")
                and status.get("at_park", "true") == "true")

        self.wait(parked, STEP_TIMEOUT, "the arm parked after the episode (executor/status)")

    def _line_errors(self, executed: list[tuple[float, float, float]],
                     pushes: list[tuple[float, np.ndarray]], since: float = -math.inf
                     ) -> list[float]:
        """Per executed arm push: the true tool tip's largest distance from the commanded
        contact segment (``sim/tool_tip`` vs ``planner/push``), mm (:func:`line_deviation`).
        Waited for from wall time ``since`` on (a simulator killed during a run never sent
        that run's)."""
        def runs_in() -> bool:  # sim/tool_tip goes out before the run's camera frame
            return all(any(st[0] <= t0 and st[-1] >= t1 for _, st, _ in self.rec.tool_tip
                           if len(st)) for wall, t0, t1 in executed if wall >= since)

        self.wait(runs_in, STEP_TIMEOUT, "sim/tool_tip of every executed push")
        errors = []
        for wall, t0, t1 in executed:
            commanded = [p for w, p in pushes if w <= wall]
            run = next((tip for _, st, tip in self.rec.tool_tip
                        if len(st) and st[0] <= t0 and st[-1] >= t1), None)
            if not commanded or run is None:
                continue
            deviation = line_deviation(run, commanded[-1][1], commanded[-1][2])
            if deviation is not None:
                errors.append(1e3 * deviation)
        return errors

    def _setup_episode(self, trial: Trial, fault: Fault) -> None:
        self.set_parameters("planner_node", {**planner_episode_params(trial),
                                             "after_goal": "report", **fault.planner_params()})
        self.reset("planner_node")  # drop the old goal before the scene changes under it
        self.set_parameters("ekf_node", {"relearn.enabled": trial.relearn})  # at its reset
        self.set_parameters("sim_bridge_node", {**bridge_scene_params(trial),
                                                **NO_BRIDGE_FAULTS, **fault.bridge_params(trial)})
        message = self._reset_simulator()
        match = _COM_RE.search(message)
        self._com_true = (np.array([float(match.group(1)), float(match.group(2))])
                          if match else None)
        # The scene first, then the pipeline, as with a real camera: frames stamped before a
        # node's ~/reset belong to the old episode (push_ros.stamps.episode_boundary), so the
        # new episode starts with the next frame of the new scene (the camera streams); the
        # planner's second reset forgets the estimates of the scene change.
        first = _FIRST_FRAME_RE.search(message)
        if first is None:
            raise GraphError(f"sim_bridge_node's ~/reset answer names no first frame: {message}")
        self._last_stamp = self._first_frame = float(first.group(1))
        for name in ("segmentation_node", "ekf_node", "planner_node"):
            answer = self.reset(name)
            after = _INPUTS_AFTER_RE.search(answer) if name == "ekf_node" else None
            if after is not None:  # estimates of the old episode are stamped at or before it
                self._last_stamp = max(self._last_stamp, float(after.group(1)))

    def _reset_simulator(self) -> str:
        """``/sim_bridge_node/reset``, again while it answers busy: the arm may still settle
        after the episode's park (the executor reports it idle once the trajectory has ended,
        the simulator's run ends when the arm and the object are at rest)."""
        deadline = time.monotonic() + STEP_TIMEOUT
        while True:
            try:
                return self.reset("sim_bridge_node")
            except GraphError as exc:
                if "busy" not in str(exc) or time.monotonic() > deadline:
                    raise
            pause = time.monotonic() + 0.2
            self.wait(lambda until=pause: time.monotonic() >= until, 5.0, "a pause")

    def _first_estimate(self, trial: Trial, fault: Fault) -> tuple[float, float, np.ndarray]:
        """Set the episode up and wait for the first estimate of the new scene: (the stamp of
        its reference frame, the estimate's stamp, the estimate). The estimator publishes one
        estimate per new frame; should it be lost, the set-up (resets, a new scene with new
        frames) is repeated.

        The estimate is the first one at or after the episode's reference frame (the stamp of
        the new ``perception/outline``, a frame of the new scene): a frame of the new scene
        that perception measured before its ``~/reset`` (against the old episode's reference)
        can reach the estimator after *its* reset, and a filter built on the old outline
        would give that estimate (a disc's unobserved yaw kept, in one CI run 1.1 deg)."""
        for attempt in range(1, FIRST_ESTIMATE_ATTEMPTS + 1):
            self._setup_episode(trial, fault)
            after, scene = self._last_stamp, self._first_frame

            def first(after: float = after, scene: float = scene
                      ) -> tuple[float, float, np.ndarray] | None:
                return first_estimate(self.rec.outline_stamps, self.rec.est, scene, after)

            try:
                return self.wait(first, FIRST_ESTIMATE_TIMEOUT, "the first estimate of the new "
                                 f"scene on estimator/object_pose (attempt {attempt} of "
                                 f"{FIRST_ESTIMATE_ATTEMPTS})")
            except GraphError as exc:
                self.nodes.check_alive()
                if attempt == FIRST_ESTIMATE_ATTEMPTS:
                    raise
                print(f"pushbot graph: {exc}; repeating the episode set-up", file=sys.stderr,
                      flush=True)
        raise AssertionError("unreachable")

    def _true_at(self, stamp: float) -> np.ndarray:
        def at() -> np.ndarray | None:
            return next((p for s, p in reversed(self.rec.true) if s == stamp), None)

        return self.wait(at, STEP_TIMEOUT, f"sim/object_pose stamped {stamp:.3f} s")

    def _true_after(self, stamp: float, start: int = 0) -> np.ndarray:
        """The first ground truth at or after ``stamp`` (from entry ``start`` on)."""
        return next((p for s, p in self.rec.true[start:] if s >= stamp), self.rec.true[-1][1])

    def _est_after(self, stamp: float, default: np.ndarray, start: int = 0) -> np.ndarray:
        """The last estimate of the frame after the push that ended at ``stamp`` (from entry
        ``start`` on)."""
        later = [(s, p) for s, p in self.rec.est[start:] if s >= stamp]
        if not later:
            return default
        first = later[0][0]
        return [p for s, p in later if s == first][-1]

    def _wait_end(self, episode: Episode, fault: Fault) -> dict[str, str]:
        """Wait for ``goal reached`` / ``failed`` for the episode's goal (that ``fault``
        accepts); fail after STEP_TIMEOUT s without progress."""
        progress = [None, time.monotonic()]
        trial = episode.trial

        def done() -> dict[str, str] | None:
            fault.poll(self, episode)
            mine = [(i, s) for i, s in enumerate(self.rec.status[episode.n_status:],
                                                 episode.n_status)
                    if same_goal(s.get("goal", ""), episode.goal_text)]
            key = (len(self.rec.pushes), len(self.rec.executed), len(mine))
            if key != progress[0]:
                progress[0], progress[1] = key, time.monotonic()
            end = next((s for i, s in reversed(mine) if s.get("state") in fault.end_states
                        and fault.accepts_end(self, i)), None)
            if end is not None:
                return end
            if time.monotonic() - progress[1] > STEP_TIMEOUT:
                last = mine[-1][1]["_message"] if mine else "no status for this goal"
                raise GraphError(f"no progress for {STEP_TIMEOUT:.0f} s (planner: {last!r}); "
                                 f"node logs in {self.log_dir}")
            return None

        limit = STEP_TIMEOUT * (trial.max_steps + 2)
        return self.wait(done, limit, f"the end of the episode ({trial.max_steps} steps max)")

    def _wait_recorded(self, status: dict[str, str], n_push: int, n_exec: int) -> None:
        """After the final status: wait until this client has received every ``planner/push``
        of the episode (``step`` of them), the ``pusher/executed`` of the last push the planner
        saw executed (``last_push_end``) and the estimate after it (the planner decided on one).
        They come from other publishers than the status, so they can still be in flight (or
        queued here) when it arrives."""
        steps = int(status.get("step", 0))
        last_end = status_seconds(status, "last_push_end")

        def complete() -> bool:
            if len(self.rec.pushes) - n_push < steps:
                return False
            if not math.isfinite(last_end):
                return True
            return (any(e[2] >= last_end - 1e-6 for e in self.rec.executed[n_exec:])
                    and any(st >= last_end - 1e-6 for st, _ in self.rec.est))

        self.wait(complete, STEP_TIMEOUT, f"the {steps} planner/push, the pusher/executed "
                  f"ending at {last_end:.3f} s and the estimate after it")

    def _com_error(self, pose0_true: np.ndarray, end_true: np.ndarray, order: int
                   ) -> float | None:
        """|c_est - c_true| in the episode frame (as :mod:`pushbot.experiments.inprocess`),
        metres."""
        self._c_true_episode = None
        if self._com_true is None or not self.rec.com or not self.rec.est:
            return None
        from push_core.geometry import rot2, wrap_angle

        theta_est = self.rec.est[-1][1][2]
        theta0 = float(pose0_true[2])
        period = 2.0 * math.pi / max(order, 1)
        shift = period * round(float(wrap_angle(theta_est - (end_true[2] - theta0))) / period)
        c_true = rot2(theta0 - shift) @ self._com_true
        self._c_true_episode = c_true
        return float(math.hypot(*(self.rec.com[-1][1] - c_true)))


def run_graph_trials(trials: list[Trial], *, out_dir: Path | str | None = None,
                     progress: bool = True, robot: str = "pusher",
                     node_exe: Path | None = None,
                     run: Callable[[GraphRunner, Trial], dict[str, Any]] | None = None,
                     node_args: dict[str, Sequence[str]] | None = None
                     ) -> list[dict[str, Any]]:
    """Run ``trials`` through the ROS graph (four node processes, started once) in order.

    Parameters
    ----------
    trials : list of Trial
        ``state="filter"`` trials (see :func:`pushbot.runner.protocol.check_graph_trial`).
    out_dir : path, optional
        The node logs go to ``out_dir/graph_logs``; default: a temporary directory.
    progress : bool
        One line per trial on stderr.
    robot : str
        ``pusher`` or ``arm`` (:class:`GraphRunner`).
    node_exe : Path, optional
        The ``pushbot`` executable of the node processes (:class:`GraphNodes`).
    run : callable, optional
        ``run(graph, trial) -> record`` instead of ``graph.run(trial)`` (a benchmark that also
        reads what the graph's client recorded meanwhile).
    node_args : dict, optional
        Extra start-up parameters per node (:class:`GraphRunner`): a camera profile, the
        segmentation method.

    Returns
    -------
    list of dict
        One episode record per trial (docs/design/evaluation.md#episode-record). A trial that
        breaks the graph (a timeout, a node that died) gets ``success=False`` and the error as
        ``reason``; the graph is then restarted for the next trial.
    """
    for trial in trials:
        check_graph_trial(trial)
    log_dir = Path(out_dir) / "graph_logs" if out_dir is not None else None
    records: list[dict[str, Any]] = []
    with sigterm_as_keyboard_interrupt(), GraphRunner(log_dir=log_dir, robot=robot,
                                                       node_exe=node_exe,
                                                       node_args=node_args) as graph:
        for i, trial in enumerate(trials):
            try:
                record = graph.run(trial) if run is None else run(graph, trial)
            except GraphError as exc:
                record = new_record(trial.as_dict(), reason=f"graph error: {exc}",
                                    engine="graph")
                graph.restart()
            records.append(record)
            if progress:
                err = record["end_error_xy"]
                print(f"graph trial {i + 1}/{len(trials)}: {trial.object} {trial.task} "
                      f"{trial.method} k={trial.k} #{trial.index}: {record['reason']}, "
                      f"{record['steps']} steps"
                      + (f", end error {1e3 * err:.1f} mm / "
                         f"{math.degrees(record['end_error_theta']):.1f} deg" if err is not None
                         else "")
                      + f", {record['wall_s']:.1f} s", file=sys.stderr, flush=True)
    return records
