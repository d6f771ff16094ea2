"""The pool of core.concurrency in a child process forked from one whose pool threads are at work
(a pipeline's worker processes): the child's work runs in threads of its own, and a lock a parent's
thread held at the fork (the pool's, a cached property's, a factor's solve) does not stop it."""

from __future__ import annotations

import os
import signal
import threading
import warnings

import numpy as np
import pytest

from core import concurrency
from core.inbetween_guide import Guide
from core.sequence_inbetweens import SequenceInterpolator
from meshes import drape, grid

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this system")


def _in_child(check) -> bytes:
    """What ``check()`` (bytes) gives in a forked child, b"" where it did not answer within 30 s."""
    reading, writing = os.pipe()
    child = os.fork()
    if child == 0:
        try:
            signal.alarm(30)
            os.write(writing, check())
        finally:
            os._exit(0)
    os.close(writing)
    os.waitpid(child, 0)
    told = os.read(reading, 64)
    os.close(reading)
    return told


def test_work_handed_to_the_pool_in_a_forked_child_runs_there():
    """A Future handed to the pool in the child ends without its caller computing it (the parent's
    threads, all at work at the fork and copied with the pool, are gone: at HEAD it never began)."""
    if concurrency.available_cores() < 2:
        pytest.skip("one core: nothing goes to the pool")
    release, started = threading.Event(), threading.Semaphore(0)

    def busy():
        started.release()
        release.wait(60)

    # every thread of the parent's pool busy at the fork (the child's copy of the pool then makes no thread)
    running = [concurrency.in_background(busy) for _ in range(concurrency.available_cores())]
    for _ in running:
        assert started.acquire(timeout=30)

    def check():
        future = concurrency.in_background(lambda: threading.current_thread().name)
        try:
            return future.result(timeout=20).encode()
        except Exception as error:  # noqa: BLE001 (told to the parent)
            return type(error).__name__.encode()

    try:
        told = _in_child(check)
    finally:
        release.set()
        for future in running:
            future.result()
    assert told.startswith(b"shape-differences")


def test_a_pool_lock_held_at_the_fork_does_not_stop_the_child():
    """The pool's lock held by another thread at the fork (a thread handing work to the pool then):
    the child hands work to the pool and gets its result (at HEAD it waited for the lock forever)."""
    release, held = threading.Event(), threading.Event()

    def holding():
        with concurrency._pool_lock:
            held.set()
            release.wait(60)

    holder = threading.Thread(target=holding)
    holder.start()
    held.wait(10)
    try:
        told = _in_child(lambda: str(concurrency.concurrently(lambda x: x * x, [1, 2, 3])).encode())
    finally:
        release.set()
        holder.join()
    assert told == b"[1, 4, 9]"



#: A small draped sheet (every gap's preparation reads Guide.arc_guided, a cached property), four keys.
SMALL, SMALL_TRIANGLES = grid(16, jitter=0.3)
KEYS = [drape(SMALL, 0.3 * k) for k in range(4)]
THREE = [0.3, 0.55, 0.8]


def _poses(gap):
    """A new sequence's in-betweens of gap ``gap`` of KEYS at THREE."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return SequenceInterpolator(KEYS, SMALL_TRIANGLES).poses(gap, THREE)


def _held_in_arc_guide(monkeypatch):
    """A thread named "held" started on gap 0's in-betweens and held inside the computation of
    Guide.arc_guided (a cached property) until the returned Event is set, and that thread; the
    property's computations counted in the list returned third."""
    entered, release, computed = threading.Event(), threading.Event(), []
    original = Guide.turning_as_a_whole  # what arc_guided computes

    def held(self):
        computed.append(threading.current_thread().name)
        if threading.current_thread().name == "held":
            entered.set()
            release.wait(60)
        return original(self)

    monkeypatch.setattr(Guide, "turning_as_a_whole", held)
    holder = threading.Thread(target=_poses, args=(0,), name="held", daemon=True)
    holder.start()
    assert entered.wait(60)
    return release, holder, computed


def test_a_cached_property_another_thread_computes_does_not_hold_this_ones(monkeypatch):
    """Guide.arc_guided of one sequence's gap computed by a thread held there: another thread
    computes it for another sequence's gap meanwhile (Python 3.11's functools.cached_property
    computes under one lock per property of the class: at HEAD the second waited for the first)."""
    expected = _poses(1)
    release, holder, computed = _held_in_arc_guide(monkeypatch)
    answer = []
    try:
        mine = threading.Thread(target=lambda: answer.append(_poses(1)), name="mine", daemon=True)
        mine.start()
        mine.join(30)
        assert not mine.is_alive(), "it waited for the other thread's computation of the property"
    finally:
        release.set()
        holder.join(60)
    assert computed == ["held", "mine"]  # each gap's preparation computed it (for its own Guide)
    assert answer[0].tobytes() == expected.tobytes()


def test_a_child_forked_while_a_thread_computes_a_cached_property_computes_it_itself(monkeypatch):
    """A process forked while another thread computes Guide.arc_guided (a pool thread preparing the
    next gap): the child computes a gap's in-betweens, the property among them, to the same bits (at
    HEAD the property's lock stayed held in the child, which waited for it until its alarm)."""
    expected = _poses(1)
    release, holder, _ = _held_in_arc_guide(monkeypatch)
    try:
        with warnings.catch_warnings():  # Python 3.12+ warns of a fork beside threads: the case tested
            warnings.simplefilter("ignore", DeprecationWarning)
            told = _in_child(lambda: b"same" if _poses(1).tobytes() == expected.tobytes() else b"different")
    finally:
        release.set()
        holder.join(60)
    assert told == b"same"


def test_a_child_forked_while_a_thread_solves_with_a_factor_solves_with_it():
    """A factor's solve lock held by another thread at the fork (a pool thread solving with the
    topology's factor, which every gap of a sequence shares): the child solves with the same factor
    to the same bits (at HEAD it waited for the lock until its alarm)."""
    import scipy.sparse as sp

    from core.sparse_cholesky import SPDFactor

    _, triangles = grid(15, 12)
    i, j = triangles.ravel(), triangles[:, [1, 2, 0]].ravel()
    adjacency = sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(180, 180)).tocsr()
    adjacency = ((adjacency + adjacency.T) > 0).astype(float)
    matrix = sp.diags(np.asarray(adjacency.sum(axis=1)).ravel() + 1e-2) - adjacency
    factor, rhs = SPDFactor(matrix.tocsc()), np.linspace(-1.0, 1.0, 180)
    expected = factor.solve(rhs)
    release, held = threading.Event(), threading.Event()

    def solving():  # holds the lock as a solve in this thread would
        with factor._lock:
            held.set()
            release.wait(60)

    holder = threading.Thread(target=solving)
    holder.start()
    assert held.wait(30)
    try:
        told = _in_child(lambda: b"same" if factor.solve(rhs).tobytes() == expected.tobytes() else b"different")
    finally:
        release.set()
        holder.join()
    assert told == b"same"
