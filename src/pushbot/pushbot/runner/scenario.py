"""What a graph episode and a fault scenario share: the running :class:`Episode` and the part
of the runner a fault may use (:class:`FaultTarget`).

The graph runner (:class:`pushbot.runner.episode.GraphRunner`) creates the :class:`Episode`
when the goal goes out and hands it, with itself, to the fault's hooks
(:class:`pushbot.runner.faults.Fault`). The faults see the runner only through
:class:`FaultTarget`, so :mod:`pushbot.runner.faults` does not import the runner that calls it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from pushbot.runner.client import Recorded
from pushbot.runner.graph_nodes import GraphNodes
from pushbot.runner.protocol import Trial

__all__ = ["Episode", "FaultTarget"]


@dataclass
class Episode:
    """What the runner knows about the running episode (shared with the fault).

    Attributes
    ----------
    trial : Trial
    n_push, n_exec, n_status : int
        Lengths of the runner's ``planner/push``, ``pusher/executed`` and ``planner/status``
        records when the goal went out (this episode's entries follow).
    goal : (3,) float
        The goal the episode is scored against (x, y m, theta rad in the episode frame).
    offset : (3,) float
        The same goal relative to the first estimate (ground truth target = true initial pose
        + offset).
    goal_text : str
        How planner/status shows that goal.
    notes : dict
        Fields the fault adds to the episode record.
    """

    trial: Trial
    n_push: int
    n_exec: int
    n_status: int
    goal: np.ndarray
    offset: np.ndarray
    goal_text: str
    notes: dict[str, Any] = field(default_factory=dict)


class FaultTarget(Protocol):
    """The runner as a fault sees it: what the graph recorded, its node processes, and the
    client's waits and sends (:class:`pushbot.runner.episode.GraphRunner` has them all)."""

    rec: Recorded
    nodes: GraphNodes

    def wait(self, predicate: Callable[[], Any], timeout: float, what: str) -> Any:
        """Spin until ``predicate()`` is not None/False; ``GraphError`` after ``timeout`` s."""

    def knock(self, delta: np.ndarray) -> None:
        """Displace the object by ``delta`` (dx, dy m, dyaw rad) on ``sim/knock``."""

    def foreign_push(self, points: np.ndarray) -> None:
        """Send a push (approach, contact, end; (3, 2) m) on ``planner/push``."""

    def send_goal(self, goal: np.ndarray, other: bool = False) -> str:
        """Send a goal (``other``: from the second, volatile sender); its status text."""

    def client_matched(self) -> bool:
        """Whether the client's fault publishers are matched."""

    def reset(self, node_name: str) -> str:
        """Call ``/<node_name>/reset``; its message (``GraphError`` when refused)."""

    def foreign_trajectory(self, names: list[str], positions: list[float], seconds: float
                           ) -> None:
        """Command the arm to ``positions`` in ``seconds`` as another client (``robot`` arm)."""

    def executor_enable(self, enable: bool) -> str:
        """``/push_executor_node/enable`` (``robot`` arm); its message."""
