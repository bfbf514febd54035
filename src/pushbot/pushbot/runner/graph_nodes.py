"""The graph's node processes: started, watched and stopped (the supervisor of
:mod:`pushbot.runner.episode`).

:class:`GraphNodes` starts ``sim_bridge_node``, ``segmentation_node``, ``ekf_node`` and
``planner_node`` as ``pushbot run <node>`` processes, each in its own process group with a
parent-death signal (SIGTERM) and its log in ``<log_dir>/<node>.log``; :meth:`GraphNodes.stop`
sends SIGINT (what rclpy shuts down cleanly on), then SIGTERM, then SIGKILL to each group, so
Ctrl-C leaves no process behind.
"""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from push_ros.dds import apply_default_profile

__all__ = ["ARM_NODES", "EXECUTOR_NODE", "NODES", "PUSH_TIMEOUT", "GraphError", "GraphNodes",
           "graph_node_names"]

NODES = ("sim_bridge_node", "segmentation_node", "ekf_node", "planner_node")
#: The arm's push executor (``robot`` arm: the bridge simulates a Panda behind ros2_control's
#: interface and no longer executes ``planner/push`` itself).
EXECUTOR_NODE = "push_executor_node"
ARM_NODES = (*NODES, EXECUTOR_NODE)


def graph_node_names(robot: str = "pusher") -> tuple[str, ...]:
    """The protocol graph's node names for ``robot`` (``pusher`` or ``arm``).

    Raises
    ------
    ValueError
        Another ``robot``.
    """
    if robot not in ("pusher", "arm"):
        raise ValueError(f"robot must be 'pusher' or 'arm', got {robot!r}")
    return ARM_NODES if robot == "arm" else NODES
#: planner_node's wait for a push the bridge never reports (it refused it, e.g. an approach
#: point inside the object), wall seconds; the push then counts as a step and nothing moved, as
#: in-process. A push takes well under a second of wall time (the physics runs ~100x real time).
PUSH_TIMEOUT = 5.0
#: The same for the simulated arm: a push is a whole arm motion (transit, descend, push, retreat,
#: lift, park: about 12 s of sim time at ARM_REAL_TIME_FACTOR, longer with the monitor
#: rendering); a push the executor refuses is answered on pusher/refused at once anyway.
ARM_PUSH_TIMEOUT = 60.0
#: The simulated arm's sim time / wall time limit in protocol graphs (``arm.real_time_factor``):
#: fast enough for evaluations, slow enough that the executor's joint-state stream and its
#: trajectory start stay within its tracking window (unpaced, the simulator ran ~50x real time
#: and the executor's clock lagged its joint states by over 10 s of sim time).
ARM_REAL_TIME_FACTOR = 5.0
#: planner_node's ``robot_timeout`` in protocol graphs of the arm: an episode whose robot stays
#: unavailable (a posture the executor cannot leave, a driver that never comes back) fails
#: after this long (wall s), within the runner's STEP_TIMEOUT of no progress.
ARM_ROBOT_TIMEOUT = 60.0
#: The simulated arm's ``/joint_states`` rate in protocol graphs, Hz of sim time
#: (``arm.joint_state_rate``; 250 a second of wall time at ARM_REAL_TIME_FACTOR): at 100 Hz
#: (500 a second) the Python readers -- the executor, perception's self-filter, this client --
#: fell behind on a loaded machine, by seconds, and dropped states; 20 ms apart the contact
#: segment and the tool tip's ground truth are still sampled every 0.4 mm at 20 mm/s.
ARM_JOINT_STATE_RATE = 50.0
#: Grace periods of the shutdown: SIGINT, then SIGTERM, then SIGKILL.
STOP_GRACE = (10.0, 5.0)


class GraphError(RuntimeError):
    """The graph did not do what an episode needs (a timeout, a refused call, a dead node)."""


def _parent_death_signal() -> None:  # pragma: no cover - runs in the child before exec
    """Ask Linux to SIGTERM the child when this process dies (even by SIGKILL)."""
    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


class GraphNodes:
    """The graph's node processes, started with ``pushbot run`` in their own process groups.

    Parameters
    ----------
    log_dir : Path
        One ``<node>.log`` per node (stdout and stderr).
    node_args : dict, optional
        Extra ``-p name:=value`` strings per node name.
    ros_args : dict, optional
        ``pushbot up``: the nodes to start, each with its whole ``--ros-args`` list, instead
        of the protocol graph's nodes and parameters.
    robot : str
        ``pusher`` (the four nodes) or ``arm`` (the bridge with ``robot:=arm`` and
        ``push_executor_node``, enabled, as a fifth node).
    node_exe : Path, optional
        The ``pushbot`` executable the nodes run from (default: this interpreter's): another
        installation's, e.g. a checkout of an earlier version, so that its nodes meet this
        client on the same trials.
    """

    def __init__(self, log_dir: Path, node_args: dict[str, Sequence[str]] | None = None,
                 ros_args: dict[str, Sequence[str]] | None = None, robot: str = "pusher",
                 node_exe: Path | None = None) -> None:
        self.log_dir = Path(log_dir)
        self.robot = robot
        self.node_exe = None if node_exe is None else Path(node_exe)
        self.names = graph_node_names(robot)
        self.node_args = {n: list((node_args or {}).get(n, ())) for n in self.names}
        self.ros_args = ros_args
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self) -> None:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        for name in self.names if self.ros_args is None else self.ros_args:
            self._start_one(name)

    def _start_one(self, name: str, extra: Sequence[str] = ()) -> None:
        """Start one node process (``extra``: more ``name:=value`` start-up parameters)."""
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        apply_default_profile(env)
        exe = self.node_exe or Path(sys.executable).parent / "pushbot"
        base = [str(exe)] if exe.exists() else [sys.executable, "-m", "pushbot.cli"]
        if self.ros_args is not None:  # pushbot up: the launch file's arguments as they are
            params = list(self.ros_args[name])
        else:
            params = ["-p", "use_sim_time:=true"] if name != "sim_bridge_node" else []
            if name == "planner_node":
                # A protocol episode ends at "goal reached" (as in-process): the planner only
                # reports it if the object leaves the region afterwards, it pushes no more.
                timeout = ARM_PUSH_TIMEOUT if self.robot == "arm" else PUSH_TIMEOUT
                params += ["-p", f"push_timeout:={timeout}", "-p", "after_goal:=report"]
                if self.robot == "arm":
                    params += ["-p", f"robot_timeout:={ARM_ROBOT_TIMEOUT}"]
            if name == "sim_bridge_node":
                params += ["-p", f"robot:={self.robot}"]
                if self.robot == "arm":
                    params += ["-p", f"arm.real_time_factor:={ARM_REAL_TIME_FACTOR}",
                               "-p", f"arm.joint_state_rate:={ARM_JOINT_STATE_RATE}"]
            if name == EXECUTOR_NODE:
                params += ["-p", "start_enabled:=true"]
            if name == "segmentation_node" and self.robot == "arm":  # the arm may be in view
                params += ["-p", "robot_filter.enabled:=true"]
            params += [arg for value in self.node_args[name] for arg in ("-p", value)]
        params += [arg for value in extra for arg in ("-p", value)]
        with open(self.log_dir / f"{name}.log", "ab") as log:  # a restart appends
            log.write(f"=== pushbot run {name}, started {time.ctime()} ===\n".encode())
            log.flush()
            self.procs[name] = subprocess.Popen(
                [*base, "run", name, "--ros-args", *params], stdout=log,
                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env,
                start_new_session=True, preexec_fn=_parent_death_signal)

    def kill_and_restart(self, name: str, extra: Sequence[str] = ()) -> None:
        """SIGKILL the process group of node ``name`` (a crash: no clean shutdown), wait for
        it, and start the node again with its start-up parameters plus ``extra``
        (``name:=value``; e.g. the episode's parameters, as a launch file's YAML would give)."""
        self.kill(name)
        self._start_one(name, extra)

    def kill(self, name: str) -> None:
        """SIGKILL the process group of node ``name`` and wait for it; :meth:`restart` starts
        it again (:meth:`check_alive` does not report it meanwhile)."""
        proc = self.procs.pop(name)
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=30.0)

    def restart(self, name: str, extra: Sequence[str] = ()) -> None:
        """Start node ``name`` again (after :meth:`kill`) with ``extra`` parameters more."""
        self._start_one(name, extra)

    def signal(self, name: str, sig: int) -> None:
        """Send ``sig`` to the process group of node ``name`` (SIGSTOP / SIGCONT: a hang)."""
        try:
            os.killpg(self.procs[name].pid, sig)
        except ProcessLookupError:
            pass

    def log_tail(self, name: str, chars: int = 1500) -> str:
        try:
            return (self.log_dir / f"{name}.log").read_text(errors="replace")[-chars:]
        except OSError:
            return ""

    def check_alive(self) -> None:
        """Raise :class:`GraphError` naming a node process that exited."""
        for name, proc in self.procs.items():
            if proc.poll() is not None:
                raise GraphError(f"{name} exited with status {proc.returncode}; the end of "
                                 f"{self.log_dir / (name + '.log')}:\n{self.log_tail(name)}")

    def stop(self) -> None:
        """SIGINT each process group, then SIGTERM, then SIGKILL (newest node first). A second
        Ctrl-C meanwhile does not interrupt the shutdown."""
        try:
            previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        except ValueError:  # not the main thread
            previous = None
        try:
            self._stop()
        finally:
            if previous is not None:
                signal.signal(signal.SIGINT, previous)

    def _stop(self) -> None:
        procs = [p for p in reversed(list(self.procs.values())) if p.poll() is None]
        for sig, grace in ((signal.SIGINT, STOP_GRACE[0]), (signal.SIGTERM, STOP_GRACE[1]),
                           (signal.SIGKILL, 5.0)):
            for proc in procs:
                if proc.poll() is None:
                    try:
                        os.killpg(proc.pid, sig)
                    except ProcessLookupError:
                        pass
            deadline = time.monotonic() + grace
            for proc in procs:
                try:
                    proc.wait(timeout=max(0.0, deadline - time.monotonic()))
                except subprocess.TimeoutExpired:
                    pass
            procs = [p for p in procs if p.poll() is None]
            if not procs:
                break
        self.procs.clear()

    @property
    def pids(self) -> list[int]:
        return [p.pid for p in self.procs.values()]
