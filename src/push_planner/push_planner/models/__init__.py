"""Bundled weights of the learned affordance model (``lrn``); see ``MODEL_CARD.md`` here."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

#: File name of the bundled weights.
WEIGHTS = "affordances.pt"


def default_weights() -> Path:
    """Path of the bundled weights (``push_planner/models/affordances.pt``)."""
    return Path(str(resources.files("push_planner.models").joinpath(WEIGHTS)))
