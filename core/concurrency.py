"""Independent pieces of work in threads, one per available core.

The in-betweens of a gap and the embedding's raced starts (:mod:`core.embedding`) are
independent computations whose time goes to NumPy array arithmetic and sparse products, which
release Python's global lock, so two threads on two cores take less time than one piece after the
other (numbers in docs/inbetweens.md and docs/design-decisions.md). The threads are kept for the
life of the process (starting a pool costs milliseconds, as much as a small mesh's in-between).
A thread that hands out work does the first piece itself and, when it needs a result whose piece
no thread has started, does that piece too (work stealing): no thread waits idle while work is
queued, and work handed out from inside a piece (a gap prepared in the background computes its
keys' relatives concurrently) cannot deadlock the pool. Every piece is computed as it would be
alone, with BLAS single-threaded (two multithreaded BLAS calls at once oversubscribe the cores; a
multithreaded BLAS sums in another order, ~1e-14 relative), so the results do not depend on the
number of threads. The two surface layers of a reconstruction or a transfer (the mesh and its
offset surface) run in threads of their own (:func:`per_layer_threads`).

BLAS's thread count is the process's, not a thread's: :func:`single_threaded_blas` is one limit
for the process, set by the first of its holders (of any thread: the in-betweens, the pieces,
work handed to the background) and given back as it found it when the last lets go, so a
computation inside it runs with one BLAS thread whatever else runs or ran before in the process
(a gap still being prepared in the background included), and the process's own setting is back
once no such work is left.

A child process forked from one whose pool is at work makes a pool of its own at first use, with
new locks (the parent's threads do not exist in it, and a lock one of them held would stay held).

threadpoolctl's view of the BLAS libraries (:func:`_blas_controller`) is made as this module is
imported, in the importing thread, before any thread of the core exists (its pool, a layer's, a gap
worker's reader, an operator's worker thread): threadpoolctl before 3.7 lists the libraries on Linux
by running Python inside glibc's ``dl_iterate_phdr``, under the loader's lock, and a thread that
loads a library meanwhile (an extension module imported, holding Python's lock) stops both for ever.

Inside :func:`one_thread` every piece runs in the thread that asks for it, with BLAS
single-threaded: a sequence whose gaps a second process shares (:mod:`core.gap_processes`) runs so
in both processes, since a third busy thread on two cores costs more than it gains.
:data:`USE_PROCESSES` (the environment variable ``SHAPE_DIFFERENCES_PROCESSES=0`` sets it False)
turns that second process off.
"""

from __future__ import annotations

import os
import threading
from contextlib import contextmanager

_pool = None
_pool_threads = 0  # the threads _pool was made with
_pool_lock = threading.Lock()
_controller = None  # see _blas_controller
_limit_lock = threading.Lock()
_limit_holders = 0  # the single_threaded_blas contexts open in the process
_limiter = None  # threadpoolctl's limit while any is open (it gives back the original counts)
_one_thread_holders = 0  # the one_thread contexts open in the process

#: Whether a sequence's gaps may be shared with a second, kept process (:mod:`core.gap_processes`):
#: True unless the environment variable ``SHAPE_DIFFERENCES_PROCESSES`` is ``0`` when the core is
#: imported; a script may set it (``core.concurrency.USE_PROCESSES = False``) at any time.
USE_PROCESSES = os.environ.get("SHAPE_DIFFERENCES_PROCESSES", "1").strip() != "0"


def _new_pool_after_fork() -> None:
    """In a child process forked from this one: the parent's pool threads do not exist here (work
    handed to its pool would never run, only be stolen by the thread that waits for it), and a lock
    one of them held at the fork would never be given back; a new pool is made at first use, with
    new locks. (The single-threaded-BLAS count keeps the parent's holders: the limit stays set.)"""
    global _pool, _pool_threads, _pool_lock, _limit_lock
    _pool, _pool_threads = None, 0
    _pool_lock, _limit_lock = threading.Lock(), threading.Lock()


if hasattr(os, "register_at_fork"):  # not on Windows, which does not fork
    os.register_at_fork(after_in_child=_new_pool_after_fork)


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
    if not worth_it or len(items) < 2 or not _threads_allowed():
        return [function(item) for item in items]
    with single_threaded_blas():
        futures = [_submitted(function, item) for item in items[1:]]
        outcomes = [_outcome(lambda: function(items[0]))]
        outcomes += [_outcome(lambda: result(future, function, item)) for future, item in zip(futures, items[1:])]
    for value, error in outcomes:  # every piece finished: none left running on shared state
        if error is not None:
            raise error
    return [value for value, _ in outcomes]


def in_background(function, *arguments):
    """A Future of ``function(*arguments)`` run in a pool thread (read it with :func:`result`),
    or None with a single core or inside :func:`one_thread` (the caller then does the work when it
    needs it)."""
    if not _threads_allowed():
        return None
    return _submitted(_single_threaded, function, *arguments)


def _single_threaded(function, *arguments):
    """``function(*arguments)`` with BLAS single-threaded (work in the background holds the limit
    itself: its caller may let go of its own before this work is done)."""
    with single_threaded_blas():
        return function(*arguments)


def result(future, function, *arguments):
    """The result of ``future`` (``function(*arguments)`` handed to the pool), computed in this
    thread if no pool thread has started it."""
    if future.cancel():
        return function(*arguments)
    return future.result()


def _outcome(call):
    """``(call(), None)``, or ``(None, the exception)`` it raised."""
    try:
        return call(), None
    except BaseException as error:  # re-raised by the caller once every piece is done
        return None, error


def _submitted(function, *arguments):
    """A Future of ``function(*arguments)`` handed to the process's pool, of one thread per core
    it may run on now: a pool made for another count (the process's CPU affinity changed, as a
    farm's scheduler may change it) is replaced, and the work already handed to it still runs (its
    threads end once it is done). The pool is taken and given the work under one lock, so no work
    goes to a pool another thread has just replaced (shut down, it would refuse it)."""
    global _pool, _pool_threads
    cores = available_cores()
    with _pool_lock:
        if _pool is None or _pool_threads != cores:
            from concurrent.futures import ThreadPoolExecutor

            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool, _pool_threads = ThreadPoolExecutor(cores, thread_name_prefix="shape-differences"), cores
        return _pool.submit(function, *arguments)


@contextmanager
def single_threaded_blas():
    """A context limiting BLAS to one thread, shared by the process's threads (a no-op without
    threadpoolctl): the first context opened sets the limit, the last one closed gives back the
    counts the first found, whichever threads open and close them in whatever order. Also a
    decorator (each call opens a context)."""
    global _limit_holders, _limiter
    controller = _blas_controller()
    if controller is None:
        yield
        return
    with _limit_lock:
        if _limit_holders == 0:
            _limiter = controller.limit(limits=1, user_api="blas")
        _limit_holders += 1
    try:
        yield
    finally:
        with _limit_lock:
            _limit_holders -= 1
            if _limit_holders == 0:
                _limiter.restore_original_limits()
                _limiter = None


def per_layer_threads(calls, *, parallel: bool = True) -> list:
    """``[call() for call in calls]`` — for the two layers' independent work — in one thread per
    call, each with a single-threaded BLAS (their work is BLAS, LAPACK and sparse products, which
    release the GIL; faster than one layer after the other with a multithreaded BLAS, and far
    faster on a busy machine, see docs/design-decisions.md). Sequential without threadpoolctl or
    a second core, or unless ``parallel``. Threads of its own, not the shared pool
    (:func:`concurrently`): each layer's embedding still races its starts there."""
    import importlib.util

    parallel = (parallel and len(calls) > 1 and _threads_allowed()
                and importlib.util.find_spec("threadpoolctl") is not None)
    if not parallel:
        return [call() for call in calls]
    from concurrent.futures import ThreadPoolExecutor

    with single_threaded_blas(), ThreadPoolExecutor(len(calls)) as pool:
        futures = [pool.submit(call) for call in calls]
        return [future.result() for future in futures]


def _threads_allowed() -> bool:
    """Whether work may go to other threads: a second core, and no :func:`one_thread` open."""
    return _one_thread_holders == 0 and available_cores() > 1


@contextmanager
def one_thread():
    """A context in which :func:`concurrently`, :func:`in_background` and :func:`per_layer_threads`
    run every piece in the calling thread, with BLAS single-threaded: the process's other core is
    another process's (:mod:`core.gap_processes`). Process-wide, counted like
    :func:`single_threaded_blas`: the last context closed lets the threads work again."""
    global _one_thread_holders
    with single_threaded_blas():
        with _limit_lock:
            _one_thread_holders += 1
        try:
            yield
        finally:
            with _limit_lock:
                _one_thread_holders -= 1


def _blas_controller():
    """threadpoolctl's view of the process's BLAS libraries, made once (None without
    threadpoolctl): ``threadpool_limits`` looks the loaded libraries up again at every call, 1–4 ms,
    as much as a tenth of a 10k-vertex in-between. Made when this module is imported (below), once
    NumPy's and SciPy's BLAS are loaded, so that no thread of the core can load a library while the
    look-up runs (see the module). A thread that is not the core's (another add-on's, Blender's) can:
    threadpoolctl 3.7 (the one the extension bundles) lists the libraries on Linux from
    ``/proc/self/maps`` and runs no Python under the loader's lock."""
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


# Before any thread of the core exists (see the module's docstring): the look-up in the importing thread.
_blas_controller()
