"""The input rules of ``ekf_node``, ROS-free: positions, push lengths, stamps, covariances.

Each rule raises :class:`push_core.estimator.replay.Rejected` (``kind`` = the node's
``refused_<kind>`` class) or answers a plain question, on float seconds, metres and numpy arrays,
so it is tested without rclpy (``tests/estimator/test_inputs.py``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_core.episode import precedes_episode
from push_core.estimator.replay import Rejected

__all__ = [
    "COVARIANCE_RANGE",
    "REFERENCE_MARGIN",
    "EpisodeInputs",
    "MAX_OUTLINE_CLOUD_POINTS",
    "MAX_POSITION",
    "SAME_OUTLINE_TOL",
    "check_outline_extent",
    "check_position",
    "check_push_length",
    "check_stamp_order",
    "observation_problem",
    "outline_summary",
    "same_outline",
    "usable_covariance",
]

#: Largest |x|, |y| (m) of an observation, a pusher position or an outline point: the table
#: scene spans a few metres (the perception's transforms have the same 100 m bound).
MAX_POSITION = 100.0
#: An outline cloud of more points is refused before it is decoded (a refusal cap; the filter
#: works on at most ``ekf_node.OUTLINE_WORKING_POINTS`` of the points it accepts).
MAX_OUTLINE_CLOUD_POINTS = 4000
#: Tolerance (m) under which a re-published outline counts as the same outline.
SAME_OUTLINE_TOL = 1e-6
#: Eigenvalues (m^2, rad^2) of a message covariance the filter uses; outside, the configured
#: sigmas (1e-12: 1 um / 1 urad; 1e8 keeps the perception's "orientation not observed" 1e6).
COVARIANCE_RANGE = (1e-12, 1e8)


def check_position(values: Iterable[float]) -> None:
    """Raise ``Rejected("out_of_range")`` if a coordinate (m) exceeds ``MAX_POSITION``."""
    worst = max(abs(v) for v in values)
    if worst > MAX_POSITION:
        raise Rejected("out_of_range", f"a coordinate of {worst:.6g} m, more than "
                       f"MAX_POSITION = {MAX_POSITION:g} m from the origin")


def check_outline_extent(points: NDArray[np.float64]) -> None:
    """``ValueError`` if an outline point (``object`` frame, m) lies farther than
    ``MAX_POSITION`` from the object origin along x or y."""
    worst = float(np.max(np.abs(points)))
    if worst > MAX_POSITION:
        raise ValueError(f"a point {worst:.6g} m from the object origin, more than "
                         f"MAX_POSITION = {MAX_POSITION:g} m")


def check_push_length(start: NDArray[np.float64], end: NDArray[np.float64],
                      max_length: float) -> float:
    """The pusher's travel (m) from ``start`` to ``end`` (``world``, m); raise
    ``Rejected("out_of_range")`` above ``max_length`` (m)."""
    length = math.hypot(*(np.asarray(end, float) - np.asarray(start, float)))
    if length > max_length:
        raise Rejected("out_of_range", f"the pusher travels {length:.6g} m, more than "
                       f"max_push_length = {max_length:g} m")
    return length


def check_stamp_order(stamp: float, episode_start: float, what: str = "stamped") -> None:
    """Raise ``Rejected("out_of_order")`` if ``stamp`` (s) is before the episode's first
    observation ``episode_start`` (s; ``-inf`` before it)."""
    if stamp < episode_start:
        raise Rejected("out_of_order", f"{what} {stamp:.6f} s: before the episode (its first "
                       f"observation at {episode_start:.6f} s)")


def usable_covariance(cov: NDArray[np.float64] | None) -> bool:
    """Whether a message's (3, 3) pose covariance is usable: symmetric eigenvalues within
    ``COVARIANCE_RANGE`` (None: no covariance, not usable)."""
    if cov is None:
        return False
    eig = np.linalg.eigvalsh(cov)
    return bool(COVARIANCE_RANGE[0] <= eig[0] and eig[-1] <= COVARIANCE_RANGE[1])


def same_outline(a: NDArray[np.float64] | None, b: NDArray[np.float64]) -> bool:
    """Whether outline ``b`` repeats ``a`` (same shape, every coordinate within
    ``SAME_OUTLINE_TOL`` m): a re-published latched outline, not a new episode."""
    return (a is not None and a.shape == b.shape
            and bool(np.allclose(a, b, rtol=0.0, atol=SAME_OUTLINE_TOL)))


#: An observation stamped this much (s) before the episode's outline is of the previous
#: episode (the outline's own frame, at its stamp, is the episode's first observation).
REFERENCE_MARGIN = 1e-6


class EpisodeInputs:
    """Which observations belong to the current episode (``ekf_node``).

    Dropped: a repeat of the last observation's stamp, and an observation taken before the
    episode began (:func:`push_core.episode.precedes_episode`): before ``~/reset`` (the newest
    observation then; not the clock, since perception, reset first, may start its episode with
    a frame taken before the estimator's reset) or before the episode outline's frame
    (perception's new episode starts at it).
    """

    def __init__(self) -> None:
        self.last = -math.inf  # stamp of the last observation taken, s
        self.boundary = -math.inf  # observations at or shortly before it are of the last episode

    def old(self, stamp: float) -> bool:
        """Whether the observation stamped ``stamp`` (s) is dropped."""
        return stamp == self.last or precedes_episode(stamp, self.boundary)

    def reset(self) -> str:
        """``~/reset``: a new episode; returns ``" (inputs after T s)"`` or ""."""
        self.boundary, self.last = self.last, -math.inf
        return f" (inputs after {self.boundary:.9f} s)" if math.isfinite(self.boundary) else ""

    def new_outline(self, reference: float) -> None:
        """A new episode outline, of the frame stamped ``reference`` (s)."""
        self.boundary, self.last = max(self.boundary, reference - REFERENCE_MARGIN), -math.inf


def observation_problem(stamp: float, result: Any, relearned: bool, gate_threshold: float) -> str:
    """What an observation update (``push_core.estimator.ekf.UpdateResult``-like: ``nis``,
    ``reinitialized``) at ``stamp`` (s) reports on /diagnostics and as a warning; "" if
    nothing: re-learning of c, l, m, or a failed gate (pose re-initialised, c, l, m kept)."""
    if relearned:
        return (f"observation at {stamp:.3f} s contradicted the last push's prediction (NIS "
                f"{result.nis:.1f}): c, l, m re-learnt from the prior"
                + ("; pose re-initialised" if result.reinitialized else ""))
    if result.reinitialized:
        return (f"observation at {stamp:.3f} s failed the gate (NIS {result.nis:.1f} > "
                f"{gate_threshold:.1f}): pose re-initialised, c, l, m kept")
    return ""


def outline_summary(outline: Any, n_points: int, n_received: int, replaced: bool) -> str:
    """The log line of an outline the filter was built on
    (``push_core.estimator.contact.ContactOutline``: ``vertices``, ``limit_surface`` m,
    ``symmetry_order``)."""
    decimated = f" (decimated from {n_received})" if n_points < n_received else ""
    return (f"{'new ' if replaced else ''}outline: {n_points} points{decimated} -> "
            f"{len(outline.vertices)} contact vertices, l_0 = {1e3 * outline.limit_surface:.1f} "
            f"mm, symmetry order {outline.symmetry_order}{'; new episode' if replaced else ''}")
