"""Unit tests of push_core.planner_config: a bad parameter is refused, naming itself."""

import pytest

from push_core.planner_config import PlannerConfig


@pytest.mark.parametrize(("changes", "field"), [
    ({"method": "best"}, "method"),
    ({"direct": "yes"}, "direct"),
    ({"k": 0}, "k"),
    ({"k": 1.5}, "k"),
    ({"seed": -1}, "seed"),
    ({"lam": -1.0}, "lam"),
    ({"lam": float("nan")}, "lam"),
    ({"temperature": 0.0}, "temperature"),
    ({"tolerance_xy": 0.0}, "tolerance_xy"),
    ({"tolerance_theta": -1.0}, "tolerance_theta"),
    ({"approach_clearance": 0.0}, "approach_clearance"),
    ({"min_push_length": 0.06}, "max_push_length"),
    ({"substep": 0.0}, "substep"),
    ({"workspace": ((0.1, -0.1), (-0.3, 0.3))}, "workspace"),
    ({"workspace": (0.0, 1.0)}, "workspace"),
    ({"stop_confidence": 0.2}, "stop_confidence"),
])
def test_bad_config_names_the_field(changes, field):
    with pytest.raises(ValueError, match=f"^{field}"):
        PlannerConfig(**changes)
