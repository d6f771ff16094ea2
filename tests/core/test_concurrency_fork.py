"""The pool of core.concurrency in a child process forked from one whose pool threads are at work
(a pipeline's worker processes): the child's work runs in threads of its own, and a lock a parent's
thread held at the fork does not stop it."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from core import concurrency

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
