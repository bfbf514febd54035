"""Session-wide ROS isolation and helpers for tests that start rclpy or node processes.

At import time, before any test module can import rclpy, this sets for the whole session (and
so for every child process, which inherits ``os.environ``):

- ``ROS_DOMAIN_ID``: ``PUSHBOT_TEST_DOMAIN_ID`` when that is set (plus the worker's number
  under pytest-xdist, whose every worker is a session of its own), otherwise the first domain in
  1-100, starting at 1 + (pid % 100), whose lock file (``<tmp>/pushbot-test-domain-<id>.lock``,
  ``flock`` held for the whole session, released by the kernel when the session ends) no
  other session holds, so concurrent pytest sessions on one machine never share a domain (the
  graph tests also use 101 + (domain % 100) for a second graph);
- ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``: nothing leaves the machine;
- ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``: only for participants that do not use the bundled
  profile (a profile set by the user); the bundled profile declares its own transports (shared
  memory with 32 MB segments and UDPv4 with 4 MB buffers, so camera images reach other
  processes) and Fast DDS then ignores this variable (docs/design/dds.md);
- ``ROS_LOCALHOST_ONLY`` removed (deprecated in Jazzy; it conflicts with the range above);
- ``FASTRTPS_DEFAULT_PROFILES_FILE`` = the bundled profile (``push_ros.dds``) unless set: the
  transports above, and reliable writers heartbeat every 100 ms, so a sample lost behind
  camera-image fragments is repaired at once instead of after Fast DDS's default 3 s.

Fixtures:

- ``ros_context``: a dedicated, initialised :class:`rclpy.context.Context` for in-process
  node tests, shut down afterwards (``module_ros_context``: one per test module);
- ``wait_for``: ``wait_for(predicate, timeout=10.0, executor=None)`` polls (or spins
  ``executor``) until the predicate holds; returns its final truth value;
- ``processes``: a :class:`ProcessManager` that starts commands (``start``) and nodes
  (``node``: ``pushbot run <node> ...``) with the session environment and always stops them at
  teardown (SIGINT, then SIGKILL);
- ``module_processes``: the same, shared by the tests of one module;
- ``node_process``: shortcut for ``processes.node``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest

from push_ros.dds import apply_default_profile
from pushbot.ros2cli.discovery import spin_until  # imports no rclpy at module level

REPO_ROOT = Path(__file__).resolve().parents[1]


_DOMAIN_LOCK: Any = None  # the open, flock-ed lock file of this session's domain


def _free_domain() -> int:
    """The first domain from 1 + (pid % 100) on whose lock file this session gets the lock."""
    global _DOMAIN_LOCK
    import fcntl
    import tempfile

    start = os.getpid() % 100
    for offset in range(100):
        domain = 1 + (start + offset) % 100
        lock = open(Path(tempfile.gettempdir()) / f"pushbot-test-domain-{domain}.lock", "a")
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        _DOMAIN_LOCK = lock
        return domain
    raise RuntimeError("all ROS test domains 1-100 are held by other pytest sessions")


def _isolate_ros_session() -> int:
    override = os.environ.get("PUSHBOT_TEST_DOMAIN_ID")
    # pytest-xdist workers (gw0, gw1, ...) each take their own domain: the override plus the
    # worker's number, or a free one like any session.
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    domain = int(override) + int(worker[2:] or 0) if override else _free_domain()
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"  # ignored under the bundled profile
    os.environ.pop("ROS_LOCALHOST_ONLY", None)
    apply_default_profile()  # image-sized transports, 100 ms heartbeats (push_ros.dds)
    return domain


TEST_DOMAIN_ID = _isolate_ros_session()


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Keep the tests that share a module- or class-scoped fixture on one xdist worker.

    ``make test`` runs the suite with ``pytest-xdist --dist loadgroup``: tests are spread over
    the workers one by one, except those with an ``xdist_group`` mark, which stay together. A
    module that shares one started graph (or one node, one context) among its tests is given
    the group of its file here, so the graph is started once, on one worker, and its tests run
    in file order as without xdist. Runs before xdist's own hook, which reads the mark.
    """
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if info is None:
            continue
        shared = any(defs and defs[-1].scope in ("module", "class", "package")
                     for defs in (info.name2fixturedefs.get(n) for n in item.fixturenames))
        if shared:
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::", 1)[0]))


def pytest_report_header(config: pytest.Config) -> str:
    return (f"ROS isolation: ROS_DOMAIN_ID={TEST_DOMAIN_ID}, "
            "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, FASTDDS_BUILTIN_TRANSPORTS=UDPv4")


def venv_executable(name: str) -> str:
    """Path of a console script installed next to the running Python (the .venv's bin)."""
    candidate = Path(sys.executable).parent / name
    if candidate.exists():
        return str(candidate)
    found = shutil.which(name)
    if found is None:
        pytest.fail(f"{name} is not installed next to {sys.executable}: run make venv")
    return found


@contextlib.contextmanager
def _initialised_context() -> Iterator[Any]:
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(args=[], context=context)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


@pytest.fixture
def ros_context() -> Iterator[Any]:
    """An initialised rclpy Context of its own; shut down after the test."""
    with _initialised_context() as context:
        yield context


@pytest.fixture(scope="module")
def module_ros_context() -> Iterator[Any]:
    """The same, shared by the tests of one module (e.g. one node under fuzzing)."""
    with _initialised_context() as context:
        yield context


def _wait_for(
    predicate: Callable[[], Any],
    timeout: float = 10.0,
    executor: Any = None,
    interval: float = 0.05,
) -> bool:
    """Poll ``predicate`` until it is truthy or ``timeout`` seconds passed.

    With an rclpy ``executor``, spin it between polls instead of sleeping, so callbacks run.
    """
    return spin_until(executor, predicate, time.monotonic() + timeout, interval)


@pytest.fixture
def wait_for() -> Callable[..., bool]:
    """The ``wait_for(predicate, timeout=10.0, executor=None, interval=0.05)`` helper."""
    return _wait_for


class ProcessManager:
    """Starts child processes with the session environment; stops them all at teardown.

    Output of each process goes to a log file under the test's ``tmp_path`` (a pipe could fill
    up and block a chatty node); read it with :meth:`output`.
    """

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self._procs: list[tuple[subprocess.Popen, Path]] = []

    def start(
        self, argv: Sequence[str], *, env: dict[str, str] | None = None, name: str | None = None
    ) -> subprocess.Popen:
        """Start ``argv``; ``env`` entries are added to the session environment."""
        full_env = {**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}
        label = name or Path(argv[0]).name
        log = self.log_dir / f"{len(self._procs):02d}_{label}.log"
        with open(log, "wb") as out:
            proc = subprocess.Popen(
                list(argv), env=full_env, stdout=out, stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
            )
        self._procs.append((proc, log))
        return proc

    def node(
        self, node: str, *node_args: str, env: dict[str, str] | None = None
    ) -> subprocess.Popen:
        """Start ``pushbot run <node> <node_args...>`` (e.g. ``--ros-args -p x:=1``)."""
        return self.start([venv_executable("pushbot"), "run", node, *node_args],
                          env=env, name=node)

    def output(self, proc: subprocess.Popen) -> str:
        """Everything the process wrote so far (stdout and stderr interleaved)."""
        for candidate, log in self._procs:
            if candidate is proc:
                return log.read_text(errors="replace")
        raise KeyError(f"process {proc.pid} was not started by this manager")

    @staticmethod
    def stop(proc: subprocess.Popen, grace: float = 5.0) -> int:
        """SIGINT (what Ctrl-C sends; nodes shut down cleanly), then SIGKILL after ``grace``."""
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        return proc.returncode

    def stop_all(self) -> None:
        """Stop every process, newest first."""
        for proc, _ in reversed(self._procs):
            self.stop(proc)


@contextlib.contextmanager
def _managed_processes(log_dir: Path) -> Iterator[ProcessManager]:
    manager = ProcessManager(log_dir)
    try:
        yield manager
    finally:
        manager.stop_all()


@pytest.fixture
def processes(tmp_path: Path) -> Iterator[ProcessManager]:
    """A :class:`ProcessManager` whose processes are always stopped after the test."""
    log_dir = tmp_path / "process_logs"
    log_dir.mkdir()
    with _managed_processes(log_dir) as manager:
        yield manager


@pytest.fixture(scope="module")
def module_processes(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ProcessManager]:
    """Like ``processes``, shared by the tests of one module (e.g. one bridge for all)."""
    with _managed_processes(tmp_path_factory.mktemp("process_logs")) as manager:
        yield manager


@pytest.fixture
def node_process(processes: ProcessManager) -> Callable[..., subprocess.Popen]:
    """``node_process('sim_bridge_node', '--ros-args', '-p', 'x:=1')`` -> a running process."""
    return processes.node
