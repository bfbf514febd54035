"""Shared helper of the closed-loop benchmarks: pushes against the physical minimum (issue 22).

``pushes / min`` of a set of episode records is the mean, over the successful trials, of
``steps / n_min`` with ``n_min`` from :func:`push_core.episode.min_pushes` for the trial's goal
offset, goal region, the planner's longest push (5 cm) and the object's rotational symmetry
(definition: docs/ARCHITECTURE.md, "Pushes against the physical minimum").
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np

from push_core.episode import min_pushes
from push_core.objects import load_object
from push_core.planner import PlannerConfig
from push_core.symmetry import symmetry_order_of_polygon
from pushbot.experiments.protocol import Trial

#: The planner's longest push past the contact (m), the L_max of the minimum.
MAX_PUSH_LENGTH = PlannerConfig().max_push_length


@cache
def _order(obj: str) -> int:
    return symmetry_order_of_polygon(load_object(obj).polyline())


def trial_minimum(trial: dict[str, Any]) -> int:
    """The physical minimum of pushes of one trial (``Trial.as_dict()``)."""
    t = Trial(**trial)
    return min_pushes(t.goal_offset(), t.tolerances, MAX_PUSH_LENGTH, _order(t.object))


def pushes_over_minimum(records: list[dict[str, Any]]) -> float | None:
    """Mean of ``steps / n_min`` over the successful records with ``n_min >= 1``; None if
    there are none."""
    ratios = []
    for r in records:
        if r["success"]:
            n_min = trial_minimum(r["trial"])
            if n_min >= 1:
                ratios.append(r["steps"] / n_min)
    return float(np.mean(ratios)) if ratios else None
