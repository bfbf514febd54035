"""Shared helper of the closed-loop benchmarks: pushes against the physical minimum.

``pushes / min`` of a set of episode records is the mean, over the successful trials, of
``steps / n_min`` with ``n_min`` from :func:`push_core.reach.model_min_pushes` for the trial's
goal offset, goal region, the planner's longest push (5 cm), the object's rotational symmetry
and, where the trial fixes the COM (``com`` ``centre`` or ``spec``), the object's outline, COM
and uniform-pressure ``l`` (definition: docs/design/physical-minimum.md). With a random COM
only the geometric bound (:func:`push_core.episode.min_pushes`) is used.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np

from push_core.episode import min_pushes
from push_core.geometry import rot2
from push_core.objects import load_object
from push_core.planner import PlannerConfig
from push_core.reach import model_min_pushes
from push_core.symmetry import symmetry_order_of_polygon
from pushbot.runner.protocol import Trial

#: The planner's longest push past the contact (m), the L_max of the minimum.
MAX_PUSH_LENGTH = PlannerConfig().max_push_length


@cache
def _order(obj: str) -> int:
    return symmetry_order_of_polygon(load_object(obj).polyline())


@cache
def _model_minimum(obj: str, com_mode: str, offset: tuple[float, float, float],
                   tolerances: tuple[float, float]) -> int:
    spec = load_object(obj)
    com = np.zeros(2) if com_mode == "centre" else np.asarray(spec.com)
    return model_min_pushes(offset, tolerances, MAX_PUSH_LENGTH, spec.polyline(), com,
                            spec.replace(com=com).limit_surface_guess(), _order(obj))


def trial_minimum(trial: dict[str, Any]) -> int:
    """The physical minimum of pushes of one trial (``Trial.as_dict()``)."""
    t = Trial(**trial)
    offset = t.goal_offset()
    if t.com not in ("centre", "spec"):
        return min_pushes(offset, t.tolerances, MAX_PUSH_LENGTH, _order(t.object))
    # the offset in the object's initial frame, rounded so that equal goals share the search
    local = np.asarray(rot2(-t.initial_yaw)) @ offset[:2]
    key = tuple(round(float(v), 9) for v in (*local, offset[2]))
    return _model_minimum(t.object, t.com, key, tuple(t.tolerances))


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
