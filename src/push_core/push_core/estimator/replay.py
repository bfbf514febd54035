"""Inputs applied in stamp order, with a bounded replay history: a late push is re-filtered.

The estimator applies observations at their stamps and pushes from their start to their end
stamp. Messages on different topics are not ordered by the middleware (a reliable sample
repaired after a lost packet arrives late), so the observation after a push can arrive before
the push. :class:`ReplayHistory` keeps the last ``size`` applied inputs, each with the filter's
snapshot before and after it; a push that arrives after inputs it precedes is inserted at its
place and the later observations are re-applied on top of it (a *replay*).

Rules:

- an observation older than the last applied input is refused (``out_of_order``);
- a push is placed after every applied input up to its start; it is refused (``out_of_order``)
  when inputs follow that place and it would come before the first kept input, overlap an
  observation (one stamped before the push's end) or follow another later push;
- an input the filter cannot apply (it raises, or its result is not finite) is refused
  (``filter_error``) and the filter and the history are exactly as before; in a replay the
  whole insertion is undone;
- at most ``size`` inputs are kept (oldest dropped): a late push re-applies at most ``size``.

ROS-free: times are float seconds; the filter is anything with ``snapshot()``,
``restore(snapshot)``, ``predict_push(start, end)``, ``update_pose(pose, covariance)`` (its
result with ``nis``, ``reinitialized``) and the arrays ``x``, ``P``
(:class:`push_core.estimator.PushEKF`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["FILTER_ERRORS", "HISTORY", "Applied", "PushReplay", "ReplayHistory", "Rejected"]

#: Inputs kept by default (a late push re-applies at most this many).
HISTORY = 32
#: What a filter may raise on an input it cannot apply: bad values, a singular matrix, an
#: overflow.
FILTER_ERRORS = (ValueError, ArithmeticError, np.linalg.LinAlgError, RuntimeError)


class Rejected(Exception):
    """An input refused by the history: ``kind`` (``out_of_order``, ``filter_error``) and the
    reason (the exception's text)."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.kind = kind


@dataclass
class Applied:
    """An applied input with the filter's state around it.

    Attributes
    ----------
    key : float
        Stamp of an observation, end stamp of a push, s.
    data : tuple
        (pose (3,), covariance (3, 3) or None) of an observation; (start (2,), end (2,)) of a
        push, m in ``world``.
    before, after : tuple
        Filter snapshots before and after the input.
    push : (float, float) or None
        (t_start, t_end) of a push, s; None for an observation.
    gated : bool
        The observation failed the gate and re-initialised the pose.
    """

    key: float
    data: tuple
    before: tuple
    push: tuple[float, float] | None = None
    after: tuple = ()
    gated: bool = False


@dataclass(frozen=True)
class PushReplay:
    """What :meth:`ReplayHistory.insert_push` did.

    Attributes
    ----------
    prediction : Any
        The filter's push prediction (``predict_push``'s result).
    replayed : int
        Later observations re-applied on top of the push (0: it arrived in order).
    gated_change : int
        Change of the number of gated observations among the re-applied ones.
    still_gated : bool
        A re-applied observation still fails the gate.
    nis : float or None
        NIS of the last re-applied observation, None without a replay.
    """

    prediction: Any
    replayed: int
    gated_change: int
    still_gated: bool
    nis: float | None


class ReplayHistory:
    """The applied inputs of one episode (module docstring).

    Parameters
    ----------
    filter : PushEKF
        The filter the inputs are applied to (replace it with :meth:`clear` too).
    size : int
        Inputs kept (>= 1).
    """

    def __init__(self, filter: Any, size: int = HISTORY) -> None:  # noqa: A002
        if int(size) < 1:
            raise ValueError(f"size: expected >= 1, got {size!r}")
        self.filter = filter
        self.size = int(size)
        #: Applied inputs, in stamp order (the last ``size``).
        self.entries: list[Applied] = []

    def clear(self, filter: Any = None) -> None:  # noqa: A002
        """A new episode: forget every input (and use ``filter`` from now on, if given)."""
        self.entries.clear()
        if filter is not None:
            self.filter = filter

    @property
    def last_key(self) -> float:
        """Stamp of the last applied input, s (-inf if none)."""
        return self.entries[-1].key if self.entries else -np.inf

    def has_push(self, t_start: float, t_end: float) -> bool:
        """Whether the push (t_start, t_end) is among the kept inputs (a duplicate)."""
        return any(e.push == (t_start, t_end) for e in self.entries)

    def check_order(self, stamp: float) -> None:
        """Refuse (``out_of_order``) an observation older than the last applied input."""
        if stamp < self.last_key:
            raise Rejected("out_of_order", f"stamped {stamp:.6f} s: older than the last applied "
                           f"input ({self.last_key:.6f} s)")

    def observe(self, stamp: float, pose: NDArray[np.float64],
                covariance: NDArray[np.float64] | None) -> Any:
        """Apply an observation at ``stamp`` (s) and keep it; returns ``update_pose``'s result.

        Raises
        ------
        Rejected
            ``out_of_order`` (older than the last input) or ``filter_error``.
        """
        self.check_order(stamp)
        entry = Applied(stamp, (pose, covariance), self.filter.snapshot())
        result = self._apply_or_restore(entry)
        self.entries.append(entry)
        self._trim()
        return result

    def insert_push(self, t_start: float, t_end: float, start: NDArray[np.float64],
                    end: NDArray[np.float64]) -> PushReplay:
        """Place a push (pusher ``start`` -> ``end`` from ``t_start`` to ``t_end``), apply it
        and re-apply the observations after it; on a refusal nothing changed.

        Raises
        ------
        Rejected
            ``out_of_order`` (cannot be placed) or ``filter_error``.
        """
        i = len(self.entries)
        while i > 0 and self.entries[i - 1].key > t_start:
            i -= 1
        later = self.entries[i:]
        if later and (i == 0 or any(e.push is not None or e.key < t_end for e in later)):
            raise Rejected("out_of_order", f"{t_start:.6f} -> {t_end:.6f} s: it cannot be "
                           "placed among the applied inputs (before the first observation, "
                           "overlapping an observation or another push, or older than the "
                           "kept history)")
        current = self.filter.snapshot()
        saved = [(e.before, e.after, e.gated) for e in later]
        entry = Applied(t_end, (start, end), later[0].before if later else current,
                        push=(t_start, t_end))
        self.filter.restore(entry.before)
        nis = None
        try:
            prediction = self._apply_or_restore(entry)
            for e in later:  # the push arrived after inputs it precedes: re-apply them
                e.before = self.filter.snapshot()
                nis = self._apply_or_restore(e).nis
        except Rejected:
            for e, (b, a, g) in zip(later, saved, strict=True):
                e.before, e.after, e.gated = b, a, g
            self.filter.restore(current)
            raise
        self.entries.insert(i, entry)
        self._trim()
        return PushReplay(prediction, len(later),
                          sum(int(e.gated) - int(g) for e, (_, _, g) in zip(later, saved,
                                                                           strict=True)),
                          any(e.gated for e in later), nis)

    def _apply_or_restore(self, entry: Applied) -> Any:
        """Apply one input; if the filter raises or its result is not finite, restore the
        filter and raise :class:`Rejected` (``filter_error``)."""
        before, gated = self.filter.snapshot(), entry.gated
        try:
            if entry.push is not None:
                result = self.filter.predict_push(*entry.data)
            else:
                result = self.filter.update_pose(*entry.data)
                entry.gated = bool(result.reinitialized)
            ok = bool(np.all(np.isfinite(self.filter.x)) and np.all(np.isfinite(self.filter.P)))
            problem = "the result is not finite"
        except FILTER_ERRORS as exc:
            ok, problem = False, f"{type(exc).__name__}: {exc}"
        if not ok:
            self.filter.restore(before)
            entry.gated = gated
            raise Rejected("filter_error", f"the filter cannot apply it ({problem}); filter "
                           "unchanged")
        entry.after = self.filter.snapshot()
        return result

    def _trim(self) -> None:
        del self.entries[:-self.size]
