"""Independent pieces of work in threads, one per available core.

The in-betweens of a gap and the embedding's raced starts (:mod:`core.embedding`) are
independent computations whose time goes to NumPy array arithmetic and sparse products, which
release Python's global lock, so two threads on two cores take less time than one piece after the
other (numbers in docs/inbetweens.md and docs/design-decisions.md). The threads are kept for the
life of the process (starting a pool costs milliseconds, as much as a small mesh's in-between);
each thread's BLAS is single-threaded meanwhile (two multithreaded BLAS calls at once
oversubscribe the cores). Every piece is computed as it would be alone: results depend on the
number of threads only through the round-off of BLAS calls (~1e-14 relative), which a
multithreaded BLAS sums in another order.
"""

from __future__ import annotations

import os
import threading

_pool = None
_pool_lock = threading.Lock()
_controller = None  # see _blas_controller
_worker = threading.local()  # set in the pool's threads: work they submit runs in place


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells it)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def concurrently(function, items, *, worth_it: bool = True) -> list:
    """``[function(item) for item in items]``, in up to :func:`available_cores` threads when
    there are several items and the caller says each is ``worth_it`` (large enough to pay for
    handing it to a thread); in order, the first exception raised."""
    items = list(items)
    if not worth_it or len(items) < 2 or available_cores() < 2 or getattr(_worker, "inside", False):
        return [function(item) for item in items]
    pool = _shared_pool()
    with single_threaded_blas():
        futures = [pool.submit(_in_worker, function, item) for item in items]
        return [future.result() for future in futures]


def in_background(function, *arguments):
    """A Future of ``function(*arguments)`` run in a pool thread, or None with a single core or
    when called from a pool thread (the caller then does the work when it needs it)."""
    if available_cores() < 2 or getattr(_worker, "inside", False):
        return None
    return _shared_pool().submit(_in_worker, lambda _: function(*arguments), None)


def _in_worker(function, item):
    _worker.inside = True
    return function(item)


def _shared_pool():
    global _pool
    with _pool_lock:
        if _pool is None:
            from concurrent.futures import ThreadPoolExecutor

            _pool = ThreadPoolExecutor(available_cores(), thread_name_prefix="shape-differences")
        return _pool


def single_threaded_blas():
    """A context limiting BLAS to one thread (a no-op without threadpoolctl)."""
    controller = _blas_controller()
    if controller is None:
        from contextlib import nullcontext

        return nullcontext()
    return controller.limit(limits=1, user_api="blas")


def _blas_controller():
    """threadpoolctl's view of the process's BLAS libraries, made once (None without
    threadpoolctl): ``threadpool_limits`` looks the loaded libraries up again at every call, 1–4 ms,
    as much as a tenth of a 10k-vertex in-between. Made at first use, when NumPy's and SciPy's
    BLAS are loaded (``core`` imports both)."""
    global _controller
    if _controller is None:
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:
            _controller = False
        else:
            import scipy.linalg  # noqa: F401  (SciPy's own BLAS loaded before the libraries are listed)

            _controller = ThreadpoolController()
    return _controller or None
