"""The push EKF: pose, centre of mass, limit surface and friction from pushes and poses.

docs/design/estimator.md. ROS-free: numpy in, numpy out, float seconds where time appears.
This package's top level is the estimator's public face (``from push_core.estimator import
PushEKF``); its modules hold the parts:

- :mod:`push_core.estimator.config`: the state layout ``x = (x, y, theta, c_x, c_y, l, m)``
  (``STATE_LABELS``, ``STATE_SIZE``; frames and units there) and :class:`EKFConfig` (every
  setting, the process and observation noise);
- :mod:`push_core.estimator.contact`: :class:`ContactOutline` (the perceived outline decimated
  for contact queries, its convex hull) and the polygon properties of the prior,
  :func:`area_second_moment` and :func:`limit_surface_of_polygon`;
- :mod:`push_core.estimator.process_model`: :func:`predict_push` (the pushing model through one
  straight push in substeps, with its closed-form Jacobian) and :class:`PushPrediction`;
- :mod:`push_core.estimator.kalman`: :class:`~push_core.estimator.kalman.EKFBase`, the small EKF
  base (``P = F P F^T + Q``, the Joseph-form update for ``H = [I_n 0]``);
- :mod:`push_core.estimator.ekf`: :class:`PushEKF` (observation model, symmetry-aware residual,
  gating, clipping, the iterated update) and :class:`UpdateResult`;
- :mod:`push_core.estimator.replay`: inputs applied in stamp order with a bounded replay history
  (a late push is re-filtered); :mod:`push_core.estimator.pairing`: the estimator's two outputs
  paired into estimates; :mod:`push_core.estimator.active`: informative pushes.

Measured figures (cost per push and per active push choice, the closed-form Jacobian against
autodiff, NEES / NIS and COM error with 1 and 2 iterations on the filter's own model) are in
``docs/results/bench_estimator.md``; COM, ``l`` and ``m`` estimation on pybullet
physics in section ``eval_estimator``.
"""

from __future__ import annotations

from push_core.estimator.config import STATE_LABELS, STATE_SIZE, EKFConfig
from push_core.estimator.contact import ContactOutline, area_second_moment, limit_surface_of_polygon
from push_core.estimator.ekf import PushEKF, UpdateResult
from push_core.estimator.process_model import PushPrediction, predict_push
from push_core.estimator.process_model import (
    _twist_with_jacobian as _twist_with_jacobian,  # for tests
)
from push_core.symmetry import symmetry_order_of_polygon

__all__ = [
    "STATE_LABELS",
    "STATE_SIZE",
    "ContactOutline",
    "EKFConfig",
    "PushEKF",
    "area_second_moment",
    "PushPrediction",
    "UpdateResult",
    "limit_surface_of_polygon",
    "predict_push",
    "symmetry_order_of_polygon",
]
