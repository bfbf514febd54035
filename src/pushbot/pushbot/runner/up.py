"""``pushbot up``: the whole node graph as separate processes until Ctrl-C (``ros2 launch``
is not on PyPI; this is ``ros2 launch pushbot_bringup pushbot.launch.py`` for the pip install).

Which nodes, parameter files and remappings: the launch file's own decision,
``pushbot_bringup.graph.graph_nodes`` (one rule for both), with the workspace parameter files
(``src/pushbot_bringup/config/<package>.yaml``, ``share/pushbot_bringup/config`` on a full
install; ``--params-dir DIR`` replaces those of the packages that have a file there):

- ``--sim`` (default): ``sim_bridge_node`` (``--object NAME|FILE`` sets its ``object``) and
  simulated time for the others;
- ``--no-sim``: no bridge, wall time, and segmentation_node reads the RealSense ROS 2 wrapper's
  topics (``/camera/camera/...``), as ``sim:=false`` of the launch file;
- ``--robot pusher|arm``: what executes the pushes, as ``robot:=`` of the launch file (``arm``
  adds ``push_executor_node``; with ``--sim`` the bridge simulates a Panda arm).

The processes are started and stopped by ``pushbot.runner.graph_nodes.GraphNodes`` (the one
launcher: ``pushbot run <node> --ros-args ...`` each in its own process group, a parent-death
signal, the project's DDS profile) once the domain is claimed (:mod:`pushbot.runner.domain`: a
domain where a pushbot graph already runs is refused with one line naming a free one, exit
1); their output goes to ``<log dir>/<node>.log`` and is echoed here
with a ``[<node>]`` prefix on every line. Ctrl-C or SIGTERM stops every node (SIGINT, then SIGTERM,
then SIGKILL after a grace period) and exits 0. If a node exits on its own, the others are
stopped and ``pushbot up`` exits 1 naming it.

Exit codes: 0 stopped by Ctrl-C/SIGTERM, 1 a node died or a graph already runs on the
domain, 2 bad arguments.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from pushbot.ros2cli.discovery import EXIT_USAGE

if TYPE_CHECKING:
    from pushbot.runner.graph_nodes import GraphNodes

POLL_INTERVAL = 0.1
"""Seconds between two looks at the logs and the processes."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pushbot up``."""
    parser.add_argument("--object", default="",
                        help="object library name or object specification file for the "
                             "simulator (default: sim_bridge.yaml's)")
    sim = parser.add_mutually_exclusive_group()
    sim.add_argument("--sim", dest="sim", action="store_true", default=True,
                     help="start sim_bridge_node and run on its /clock (default)")
    sim.add_argument("--no-sim", dest="sim", action="store_false",
                     help="a real robot: no simulator, wall time, RealSense camera topics")
    parser.add_argument("--robot", default="", choices=("", "pusher", "arm"),
                        help="what executes the pushes: pusher (the simulated finger) or arm "
                             "(push_executor_node; the simulated Panda with --sim); default: "
                             "pusher with --sim, arm with --no-sim (robot:= of the launch file)")
    parser.add_argument("--params-dir", type=Path, default=None,
                        help="directory of <package>.yaml parameter files replacing the "
                             "bundled ones (packages without a file there keep theirs)")
    parser.add_argument("--log-dir", type=Path, default=None,
                        help="where the node logs go (default: $ROS_LOG_DIR or ~/.ros/log, "
                             "subdirectory pushbot_up_<date>_<pid>)")


def default_config_dir() -> str:
    """The bundled parameter files: the installed share directory on a full ROS install,
    else the source tree's ``src/pushbot_bringup/config``."""
    from pushbot_bringup.graph import DEFAULT_CONFIG_DIR

    try:
        from ament_index_python.packages import get_package_share_directory

        share = Path(get_package_share_directory("pushbot_bringup")) / "config"
    except (ImportError, LookupError, OSError, ValueError):  # no ament index: pip install
        return DEFAULT_CONFIG_DIR
    return str(share) if share.is_dir() else DEFAULT_CONFIG_DIR


def _yaml_scalar(value: object) -> str:
    """A ``-p name:=value`` value: bools as true/false, strings quoted (a name like ``1e3``
    stays a string)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return "'" + value.replace("'", "''") + "'"
    return repr(value)


def ros_arguments(sim: bool, object_name: str = "", config_dir: str | None = None,
                  robot: str = "") -> dict[str, list[str]]:
    """Node name -> its ``--ros-args`` (without the flag) for ``pushbot up``.

    The nodes, parameter files, overrides and remappings of
    :func:`pushbot_bringup.graph.graph_nodes` (what the launch file starts) as command-line
    arguments: ``--params-file`` per file, ``-p name:=value`` per override (after the file, so
    they win, as in the launch file), ``-r from:=to`` per remapping.

    Raises
    ------
    ValueError
        ``object_name`` with ``sim`` false; ``robot`` pusher with ``sim`` false.
    """
    from pushbot_bringup.graph import graph_nodes

    out: dict[str, list[str]] = {}
    for launch in graph_nodes(sim, object_name, config_dir, default_config_dir(), robot):
        args: list[str] = []
        for entry in launch.parameters:
            if isinstance(entry, dict):
                for name, value in entry.items():
                    args += ["-p", f"{name}:={_yaml_scalar(value)}"]
            else:
                args += ["--params-file", str(entry)]
        for source, target in launch.remappings:
            args += ["-r", f"{source}:={target}"]
        out[launch.name] = args
    return out


class LogFollower:
    """Echo the new lines of each node's log file with a ``[<node>]`` prefix."""

    def __init__(self, log_dir: Path, names: list[str], out: TextIO) -> None:
        self.paths = {name: log_dir / f"{name}.log" for name in names}
        self.offsets = dict.fromkeys(names, 0)
        self.partial = dict.fromkeys(names, "")
        self.out = out

    def poll(self) -> None:
        """Print every complete line written since the last call."""
        for name, path in self.paths.items():
            try:
                with open(path, "rb") as log:
                    log.seek(self.offsets[name])
                    data = log.read(1 << 20)
            except OSError:
                continue
            self.offsets[name] += len(data)
            lines = (self.partial[name] + data.decode(errors="replace")).split("\n")
            self.partial[name] = lines.pop()
            for line in lines:
                print(f"[{name}] {line}", file=self.out)
        self.out.flush()

    def finish(self) -> None:
        """Print what is left, including a last line without a newline."""
        self.poll()
        for name, rest in self.partial.items():
            if rest:
                print(f"[{name}] {rest}", file=self.out)
                self.partial[name] = ""
        self.out.flush()


def default_log_dir() -> Path:
    root = Path(os.environ.get("ROS_LOG_DIR") or Path.home() / ".ros" / "log")
    return root / f"pushbot_up_{datetime.now().strftime('%Y-%m-%d-%H-%M-%S')}_{os.getpid()}"


def _report_params_dir(config_dir: Path, sim: bool, robot: str) -> None:
    """Say which files of ``--params-dir`` are used, and warn about those no node reads."""
    from pushbot_bringup.graph import graph_nodes, unused_parameter_files

    launches = graph_nodes(sim, "", None, default_config_dir(), robot)
    used = [f"{launch.package}.yaml" for launch in launches
            if (config_dir / f"{launch.package}.yaml").is_file()]
    print(f"pushbot up: --params-dir {config_dir}: using {', '.join(used) or 'no file'}",
          flush=True)
    unused = unused_parameter_files(config_dir, launches)
    if unused:
        print(f"pushbot up: warning: --params-dir {config_dir}: {', '.join(unused)} not read "
              f"(a file is read only as <package>.yaml: "
              f"{', '.join(launch.package + '.yaml' for launch in launches)})",
              file=sys.stderr, flush=True)


def run_up(args: argparse.Namespace) -> int:
    """Handler of ``pushbot up``."""
    from pushbot.runner.graph_nodes import GraphNodes

    if args.params_dir is not None and not args.params_dir.is_dir():
        print(f"pushbot up: --params-dir {args.params_dir}: no such directory", file=sys.stderr)
        return EXIT_USAGE
    if args.object and Path(args.object).suffix and not Path(args.object).is_file():
        print(f"pushbot up: --object {args.object}: no such file", file=sys.stderr)
        return EXIT_USAGE
    try:
        node_args = ros_arguments(args.sim, args.object,
                                  str(args.params_dir) if args.params_dir else None,
                                  args.robot)
    except ValueError as exc:
        print(f"pushbot up: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.params_dir is not None:
        _report_params_dir(args.params_dir, args.sim, args.robot)
    from pushbot.runner.domain import claim_domain

    claim, refusal = claim_domain("up")  # one graph per ROS domain
    if claim is None:
        print(refusal, file=sys.stderr)
        return 1
    log_dir = args.log_dir or default_log_dir()
    nodes = GraphNodes(log_dir, ros_args=node_args)
    follower = LogFollower(log_dir, list(node_args), sys.stdout)
    # SIGINT reaches us even from a background job: pushbot.cli.main takes it for every command.
    with claim:
        return _supervise(nodes, follower, log_dir)


def _supervise(nodes: GraphNodes, follower: LogFollower, log_dir: Path) -> int:
    """Start the nodes, echo their logs until Ctrl-C/SIGTERM or a node's exit, stop them."""
    from pushbot.ros2cli.discovery import sigterm_as_keyboard_interrupt

    status = 0
    with sigterm_as_keyboard_interrupt():
        try:
            nodes.start()
            procs = dict(nodes.procs)
            print(f"[up] started {', '.join(f'{n} (pid {p.pid})' for n, p in procs.items())}; "
                  f"logs in {log_dir}; Ctrl-C stops them", flush=True)
            while True:
                follower.poll()
                dead = [(n, p.returncode) for n, p in procs.items() if p.poll() is not None]
                if dead:
                    follower.poll()
                    for name, code in dead:
                        print(f'pushbot up: {name} exited with status {code}; stopping the '
                              f'others (its log: {log_dir / (name + ".log")})', file=sys.stderr)
                    status = 1
                    break
                time.sleep(POLL_INTERVAL)
        except KeyboardInterrupt:
            print("[up] stopping every node", file=sys.stderr, flush=True)
        finally:
            procs = dict(nodes.procs)
            nodes.stop()
            follower.finish()
            print("[up] stopped: " + ", ".join(f"{n} (status {p.returncode})"
                                               for n, p in procs.items()),
                  file=sys.stderr, flush=True)
    return status
