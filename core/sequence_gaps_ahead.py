"""The next gap's in-betweens begun in the pool while the caller's gap ends: one gap ahead.

In a gap whose in-betweens keep a defect, one repaired prediction (solved instead, repaired
again: 200–315 ms CPU on a 15k curtain) runs alone in the pool after the others of its batch are
done, and the other core idles (docs/inbetween-measurements.md, *Cost*). A caller visiting the
gaps in order at one set of factors (the benchmark, the *In-between Frames* operator,
:func:`core.retime.retime` at its own speed) asks next for the next gap at the same factors, so
:class:`GapsAhead` (a mixin of :class:`~core.sequence_inbetweens.SequenceInterpolator`) begins that
call in the pool when the caller's gap reaches its prediction batch (the ``ahead`` of
:func:`core.inbetween_prediction.gap_poses`), and the next gap's fits fill the idle core. Only
while the caller's calls go so: a sequence's first call, or one on the gap after the previous
call's at the same factors. A caller whose factors change from gap to gap (a retime to another
speed) or who visits gaps out of order has at most one call begun ahead in vain per break of that
pattern, which the next call waits for (a gap's work, in the pool).

What keeps it safe (a gap's data, :class:`~core.inbetween_solver.Gap`, keeps per-call state —
the fits' misfits, the checks' outcomes, the fit's tolerance and rotation limit — that two calls
on one gap at once would overwrite):

- at most one call is held ahead, begun only by a caller's own call (the call ahead begins none),
  for the gap after the caller's: never the gap the caller is solving;
- every later call first settles it: the same gap at the same factors (bit for bit) takes its
  result, or its exception, raised there as the call would have raised it; any other call (other
  factors, another gap, a single :meth:`pose`) cancels it if the pool has not begun it, else waits
  until it ends and drops its result and its exception — so no two calls ever run on one gap's
  state, and a gap's results depend only on the keys, the gap and the factors asked for;
- its warnings are returned with its poses (``_poses``), said by the call that takes them;
- a caller that knows it asks nothing more of the next gap (its last gap: :func:`core.retime.iter_retime`'s
  gap before the shorter last gap, which another sequence keys, or a chunk's last gap; the *In-between
  Frames* operator's likewise) says so (``poses(…, ahead=False)``): nothing is begun for it, where a
  call begun ahead would run a whole gap's work to waste in the pool after the caller has its poses
  (the process's exit, and the caller's next work, wait or compete for it);
- in a child forked while a call ahead (or a gap's preparation) runs, the pool's threads are gone:
  its Future never ends there, so the child drops it and computes the call itself (waiting for it,
  the child hung), with the caches' lock made anew (a lock the parent's pool thread held at the
  fork is never given back in the child), as are the factors' solve locks
  (:mod:`core.sparse_cholesky`); the gaps' cached properties hold no lock (:mod:`core.cached_property`);
- nothing is begun while a second process computes later gaps of the sequence (the caller's calls
  then run in one thread, :mod:`core.gap_processes`), nor for a gap it holds, nor by a call under way when
  :func:`core.gap_processes.stop` (the operators' Esc) came, which also cancels the call held ahead
  where the pool has not begun it (one it runs ends with its gap);
- only with a second core (:func:`core.concurrency.in_background`; one core: nothing is begun,
  every call is computed where it is asked), on meshes of
  :data:`~core.inbetween_threads.CONCURRENT_VERTICES` vertices or more, and without a truncated
  metric (its recovery warns as it runs), as the background preparation of a gap.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import wait

from .concurrency import in_background, result
from .inbetween_threads import CONCURRENT_VERTICES


class GapsAhead:
    """The call of ``_computed_poses`` begun one gap ahead of the caller's (see the module)."""

    #: ``(gap, the factors' bits, Future)`` of the call begun ahead, or None.
    _ahead = None
    #: ``(gap, the factors' bits)`` of the caller's last call, or None before its first.
    _last_asked = None
    #: Whether the caller's last call followed an in-order visit at one set of factors (see the module).
    _in_order = True
    #: The process whose pool holds the calls begun ahead and the gaps' preparations (see :meth:`_forked`).
    _pool_process = None
    #: Set by :func:`core.gap_processes.stop` (the operators' Esc): the call under way begins nothing ahead.
    _halted = False

    def _beginning_ahead(self, gap: int, factors: list[float]):
        """A function of no arguments that begins ``_computed_poses(gap + 1, factors)`` in the
        pool, to be called by the caller's call on gap ``gap`` when its own work no longer fills
        both cores; None where none is begun (a caller off an in-order visit at one set of factors,
        the last gap, a small mesh, a truncated metric)."""
        if (not self._in_order or gap + 1 >= len(self) or self.k_M is not None
                or self._topo.n < CONCURRENT_VERTICES or self._worker_holds(gap + 1)):
            return None

        def begin() -> None:
            # one at a time (a call taken or dropped is no longer held); none once core.gap_processes.stop halted it
            if self._ahead is None and not self._halted:
                future = in_background(self._computed_poses, gap + 1, factors, False)
                if future is not None:
                    self._ahead = (gap + 1, factor_bits(factors), future)

        return begin

    def _forked(self) -> None:
        """In a child process forked since the pool was last handed work: the call held ahead and
        the gaps' preparations dropped (their pool threads do not exist here: their Futures never
        end; those not yet begun are computed again where they are needed), the caches' lock made
        anew (one a pool thread held at the fork stays held in the child)."""
        process = os.getpid()
        if self._pool_process is not None and self._pool_process != process:
            self._ahead = None
            self._pending.clear()
            self._cache_lock = threading.RLock()
        self._pool_process = process

    def _taken_ahead(self, gap: int, factors: list[float], ahead: bool = True):
        """The call held ahead settled before a call on gap ``gap`` at (checked) ``factors``: its
        ``(poses, warnings)`` if it was begun for exactly these (its exception raised here, or
        computed here if the pool had not begun it, ``ahead`` as for ``_computed_poses``); else None,
        once it is cancelled or has ended (its result and exception dropped). Notes whether this call
        continues an in-order visit at one set of factors."""
        self._forked()
        asked = (gap, factor_bits(factors))
        self._in_order = self._last_asked is None or self._last_asked == (gap - 1, asked[1])
        self._last_asked = asked
        held, self._ahead = self._ahead, None
        if held is None:
            return None
        at, bits, future = held
        if (at, bits) == asked:
            return result(future, self._computed_poses, gap, factors, ahead)
        if not future.cancel():
            wait([future])  # running on gap ``at``'s state: ended before any call goes on
        return None


def factor_bits(factors: list[float]) -> tuple[str, ...]:
    """The factors exactly (−0.0 and 0.0 apart): a call ahead is taken only for the same ones."""
    return tuple(float(s).hex() for s in factors)
