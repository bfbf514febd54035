"""The ``estimator/state`` std_msgs/Float64MultiArray: its one writer and its checked reader.

Layout (also in the topic table, docs/INTERFACES.md): two blocks concatenated, not a 2-D array.
``layout.dim[0]``: label ``state``, size 7, stride 7 = ``x, y, theta, c_x, c_y, l, m``
(:data:`push_core.estimator.STATE_LABELS`: pose in ``world`` in m and rad, ``theta``
continuous, not wrapped; COM in ``object``, m; limit-surface parameter ``l``, m; pusher-object
friction ``m``); ``layout.dim[1]``: label ``covariance_row_major``, size 49, stride 49 = the
7 x 7 covariance, row-major; ``data_offset`` 0; ``data`` = the 7 state values then the 49
covariance values.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from push_core.estimator import STATE_SIZE

__all__ = ["COVARIANCE_LABEL", "STATE_LABEL", "STATE_SIZE", "state_array_msg",
           "state_from_array_msg"]

STATE_LABEL = "state"
COVARIANCE_LABEL = "covariance_row_major"
_EXPECTED = [(STATE_LABEL, STATE_SIZE), (COVARIANCE_LABEL, STATE_SIZE**2)]


def state_array_msg(state: ArrayLike, covariance: ArrayLike | None = None
                    ) -> Float64MultiArray:
    """State (7,) and covariance (7, 7) (default zeros) -> ``estimator/state``.

    Raises
    ------
    ValueError
        Wrong shapes.
    """
    x = np.asarray(state, dtype=np.float64)
    p = (np.zeros((STATE_SIZE, STATE_SIZE)) if covariance is None
         else np.asarray(covariance, dtype=np.float64))
    if x.shape != (STATE_SIZE,) or p.shape != (STATE_SIZE, STATE_SIZE):
        raise ValueError(f"state must be ({STATE_SIZE},) and covariance ({STATE_SIZE}, "
                         f"{STATE_SIZE}), got {x.shape} and {p.shape}")
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=size, stride=size)
                      for label, size in _EXPECTED]
    msg.layout.data_offset = 0
    msg.data = np.concatenate([x, p.ravel()]).tolist()
    return msg


def state_from_array_msg(msg: Float64MultiArray
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``estimator/state`` -> state (7,) and covariance (7, 7), checked.

    Raises
    ------
    ValueError
        A layout other than the documented one (labels, sizes, ``data_offset`` 0), a data
        length other than 56, a non-finite state value, or a covariance that is not finite
        with a non-negative diagonal.
    """
    dims = [(d.label, d.size) for d in msg.layout.dim]
    if dims != _EXPECTED or msg.layout.data_offset != 0:
        raise ValueError(f"layout dims must be {_EXPECTED} with data_offset 0, got {dims} and "
                         f"{msg.layout.data_offset}")
    data = np.asarray(msg.data, dtype=np.float64)
    if data.shape != (STATE_SIZE + STATE_SIZE**2,):
        raise ValueError(f"data has {data.size} values, expected {STATE_SIZE + STATE_SIZE**2}")
    state = data[:STATE_SIZE].copy()
    if not np.all(np.isfinite(state)):
        raise ValueError(f"state (x, y, theta, c_x, c_y, l, m) = {state.tolist()} is not finite")
    cov = data[STATE_SIZE:].reshape(STATE_SIZE, STATE_SIZE).copy()
    if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) < 0.0):
        raise ValueError("covariance is not finite with a non-negative diagonal")
    return state, cov
