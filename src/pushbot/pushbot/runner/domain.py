"""One pushbot graph per ROS domain: ``pushbot up`` and ``pushbot demo`` refuse a domain where a
graph already runs, and name a free one.

Two graphs on one domain cross-talk (the second bridge's ``/clock`` drives the first graph's
nodes, its estimator refuses poses stamped by the other clock). Before starting its nodes a
command claims its domain (:func:`claim_domain`):

1. a lock file per domain (``<tmp>/pushbot-graph-domain-<id>.lock``, an exclusive ``flock``
   held for the command's life and released by the kernel when it ends, even by SIGKILL) that
   another ``pushbot up`` / ``demo`` of this machine holds: refused at once, naming its pid;
2. otherwise a short DDS look (at most :data:`PROBE_TIME` s, ended by the first node found) for
   a node of the graph (:data:`pushbot.runner.graph_nodes.ARM_NODES`) on the domain: a graph
   started by ``ros2 launch`` or on another machine of a networked profile: refused too.

The refusal is one line naming the nodes found and the first domain after this one whose lock
no process holds (a graph started another way on that domain is not looked for).
"""

from __future__ import annotations

import fcntl
import os
import tempfile
import time
from pathlib import Path
from typing import IO

from pushbot.runner.graph_nodes import ARM_NODES

__all__ = ["MAX_DOMAIN_ID", "PROBE_TIME", "DomainClaim", "claim_domain", "free_domain",
           "graph_nodes_on_domain", "lock_path"]

#: Longest look for a running graph's nodes on the domain, s (discovery on one machine takes
#: well under a second; the look ends at the first node found).
PROBE_TIME = 2.0
#: Largest ROS domain id rmw_fastrtps accepts on Linux (ports of higher ids collide).
MAX_DOMAIN_ID = 232


def lock_path(domain: int) -> Path:
    """The lock file of ``domain``."""
    return Path(tempfile.gettempdir()) / f"pushbot-graph-domain-{int(domain)}.lock"


class DomainClaim:
    """The lock of one domain, held until :meth:`release` (or the process ends)."""

    def __init__(self, domain: int, handle: IO[str]) -> None:
        self.domain, self._handle = domain, handle

    def release(self) -> None:
        """Give the domain up (idempotent)."""
        if self._handle is not None:
            self._handle.close()
            self._handle = None

    def __enter__(self) -> DomainClaim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _try_lock(domain: int, owner: str) -> tuple[IO[str] | None, str]:
    """(the open, locked file, "") or (None, what the holder wrote in it)."""
    path = lock_path(domain)
    handle = open(path, "a+")  # noqa: SIM115 - kept open: the open file holds the lock
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.seek(0)
        holder = handle.read(200).strip()
        handle.close()
        return None, holder
    handle.seek(0)
    handle.truncate()
    handle.write(owner)
    handle.flush()
    return handle, ""


def free_domain(domain: int) -> int | None:
    """The first domain after ``domain`` (wrapping at :data:`MAX_DOMAIN_ID`) whose lock no
    process holds, or None."""
    for step in range(1, MAX_DOMAIN_ID + 1):
        candidate = (domain + step) % (MAX_DOMAIN_ID + 1)
        handle, _ = _try_lock(candidate, "")
        if handle is not None:
            handle.close()
            return candidate
    return None


def graph_nodes_on_domain(timeout: float = PROBE_TIME) -> list[str]:
    """The graph's node names (:data:`ARM_NODES`) seen on this process's domain within
    ``timeout`` s (the look ends at the first one found)."""
    from pushbot.ros2cli.discovery import cli_node

    found: list[str] = []
    with cli_node("domain_probe") as (node, executor):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not found:
            executor.spin_once(timeout_sec=0.05)
            found = sorted({name for name, _ in node.get_node_names_and_namespaces()
                            if name in ARM_NODES})
    return found


def claim_domain(command: str, probe_time: float = PROBE_TIME
                 ) -> tuple[DomainClaim | None, str]:
    """Claim this process's ``ROS_DOMAIN_ID`` for a graph (module docstring).

    Returns
    -------
    (DomainClaim, "") or (None, refusal)
        The refusal is one line starting with ``pushbot <command>:``.
    """
    try:
        domain = int(os.environ.get("ROS_DOMAIN_ID", "") or 0)
    except ValueError:
        return None, (f"pushbot {command}: ROS_DOMAIN_ID="
                      f"{os.environ.get('ROS_DOMAIN_ID')!r} is not a number (0-{MAX_DOMAIN_ID})")
    handle, holder = _try_lock(domain, f"pushbot {command}, pid {os.getpid()}")
    if handle is None:
        return None, _refusal(command, domain, f"held by {holder or 'another process'}")
    try:
        nodes = graph_nodes_on_domain(probe_time)
    except Exception:  # noqa: BLE001 - ROS that cannot start is the nodes' own error to report
        nodes = []
    if nodes:
        handle.close()
        return None, _refusal(command, domain, f"its nodes {', '.join(nodes)} answer")
    return DomainClaim(domain, handle), ""


def _refusal(command: str, domain: int, evidence: str) -> str:
    free = free_domain(domain)
    use = (f"start this one on another domain, e.g. ROS_DOMAIN_ID={free} pushbot {command}"
           if free is not None else "no free domain found")
    return (f"pushbot {command}: a pushbot graph already runs on ROS_DOMAIN_ID={domain} "
            f"({evidence}); two graphs on one domain cross-talk: stop it, or {use}")
