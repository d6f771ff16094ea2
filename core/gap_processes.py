"""A sequence's gaps shared with a second, kept process: the later half of the gaps its caller has
yet to ask for computed there while the caller's own process computes the earlier half.

A sequence's second thread hands Python's global lock back and forth with the first at each
NumPy call on the mesh's arrays, and costs 1.3–1.7 × a thread's CPU for 0.80–1.02 × its wall time
(docs/inbetween-measurements.md, *The next gap begun ahead at the prediction batch; one core against two*). The gaps are
independent given the keys (a gap's in-betweens do not depend on the gaps computed before it, nor
on the threads: the same bits), so two single-threaded processes, each taking a contiguous part of
the gaps, use both cores without that hand-over. What :class:`GapProcesses` (a mixin of
:class:`~core.sequence_inbetweens.SequenceInterpolator`) does:

- *The worker.* One process per Python session (:func:`kept_worker`), started when the caller of a
  sequence that could share its gaps is first known to ask two gaps or more (its plan, or the first
  call of a visit in order that leaves later gaps: not for a farm's one-gap chunk), or before its
  keys are read (:func:`start_worker`), and kept for the next ones: its start (a fresh
  interpreter importing NumPy, SciPy and the core, 0.24–0.26 s of its CPU) overlaps the caller's first gaps,
  which the caller computes as before (threads, the next gap begun ahead) until the worker is
  ready. It is spawned, never forked (Blender's process has many threads), as ``sys.executable
  -I -c`` :data:`BOOT` with the caller's ``sys.path``, and loads the core from its folder under a
  private package name (:data:`PRIVATE_NAME`), so it works where the core is
  ``bl_ext.<repo>.<id>.core`` inside Blender (the core imports itself only relatively); its BLAS
  has one thread (``OPENBLAS_NUM_THREADS`` and the like, and :func:`core.concurrency.one_thread`).
  On Windows it opens no console window (:data:`WINDOWLESS`). It keeps the last sequence it built,
  under a hash of its keys, triangles and options (:func:`_digest`), so that the next job of the
  same keys (the sequence asked for other gaps, an operator run again) sends and builds nothing;
  idle for :data:`core.gap_worker.IDLE_SECONDS`, it lets that sequence go and hands its free heap
  back (a job sent without the keys as it did is answered ``broken`` and handed over again with
  them: :attr:`_Job.forgotten`). It builds from the sequence's own copies of the keys and triangles,
  which the caller may reuse. What it does and the messages: :mod:`core.gap_worker`.
- *Which gaps.* Those of a caller visiting the gaps in order at one set of factors (as
  :mod:`core.sequence_gaps_ahead` reads it: a sequence's first call, or the gap after the
  previous call's at the same factors), or following the calls it said it will make
  (:meth:`GapProcesses.will_ask`: :func:`core.retime.iter_retime`, whose factors may change from
  gap to gap). When the worker is ready and idle, the later half of the calls left (the current
  one counted as the caller's) goes to it, contiguous and in order: a gap's relative of its next key
  is kept for the gap after, which alternating gaps would lose. An odd count's middle call cannot be
  halved, and on few gaps it is a whole gap one process idles through (three gaps: the caller's two
  against the worker's one), so the half is rounded up and the worker's last call is *contested*
  (:attr:`_Job.contested`): whichever process is free first computes it, the worker in its order, or
  the caller, done with its own and waiting, taking it back even as the last one not begun. A worker
  done with its share before the caller is done with its own gets the later half of what the caller
  has left, again. Only
  where the sequence's threads would run (:data:`~core.inbetween_threads.CONCURRENT_VERTICES`
  vertices or more, two cores, no truncated metric) and at most :data:`PROCESS_VERTICES` vertices
  (the two processes' memory).
- *The caller's side.* While the worker holds calls of its sequence not yet made, the caller's calls
  run in one thread (:func:`core.concurrency.one_thread`: no gap begun ahead, no per-factor
  threads, nothing prepared in the background; three busy threads on two cores lose, and the threads
  buy the caller's own part 0.80–1.02 × the wall time for 1.3–1.7 × the CPU). A call on a gap the
  worker holds waits for its result: the same poses and warnings (returned with them, said by
  :meth:`poses` as its own), its exception raised there (a :mod:`core.errors` class by name; any
  other exception, and a gap the worker did not return, computed in the caller, which raises as it
  would have). While it waits, the calls the worker has not begun are taken back from the last and
  computed by the caller (the worker skips them) while two or more are left (:data:`TAKEN_BACK_LEAST`),
  or the contested one, so a worker started late, or slowed by other processes, keeps only what it can do.
- *Safety.* A worker that cannot be started (no ``sys.executable``, a sandbox), or that dies,
  or breaks, leaves the gaps to the caller, nothing lost; one that does not start within
  :data:`START_TIMEOUT` seconds is ended and not tried again in the session; one that sends nothing
  on a job for :data:`HANG_GAPS` times the slowest gap so far (at least :data:`HANG_LEAST` seconds)
  while a caller waits for it is ended, with a warning (kind ``process``), its gaps computed by
  their callers, and none is started again in the session (:func:`_end_silent` says why); so is one
  that takes no part of a message written to it for :data:`HANG_LEAST` seconds (stopped with its
  input's pipe full: a job's keys are far more than a pipe holds, and the write would wait for ever).
  :data:`core.concurrency.USE_PROCESSES` (``SHAPE_DIFFERENCES_PROCESSES=0``) turns it off. A caller off
  its visit (another gap or factors than it said or than in order) drops the worker's gaps, as
  does a sequence let go; :func:`stop` (the operators' Esc) drops every sequence's, lets a call
  waiting for one go (computed in the caller) and cancels their calls begun ahead. A process
  forked from the caller forgets its worker (:func:`_forgotten_after_fork`). The worker ends with the session (:mod:`atexit`) or when the
  caller's process is gone (its input closes).
"""

from __future__ import annotations

import atexit
import hashlib
import itertools
import os
import pickle
import subprocess
import sys
import threading
import time
import weakref
from contextlib import contextmanager, nullcontext

import numpy as np

from . import concurrency, errors
from .inbetween_threads import CONCURRENT_VERTICES
from .sequence_gaps_ahead import factor_bits

#: Most vertices a sequence shares its gaps with the worker at: both processes hold a sequence's
#: keys and gap data (sheet over a cube, keys 8 frames apart: 50k vertices 623 + 462 = 1,085 MB for
#: the two, against 695 MB in one; 100k 1,733 MB against 1,197, over issue 17's 1.5 GB), and at
#: 50k–100k one process with its threads is already at 0.081 × the bake.
PROCESS_VERTICES = 60_000
#: Seconds a worker may take to start (import NumPy, SciPy and the core: 0.24–0.26 s of its CPU, 1.0–1.25 s
#: wall at a load of 10 on two cores) before it is ended and none is started again in the session.
START_TIMEOUT = 60.0
#: Calls the worker must have left not begun for the caller, waiting for one of its results, to
#: take the last back and compute it: a gap taken back has no relative kept from the gap before it
#: (curtain, keys 4 apart: 0.18 s against 0.12 s in order), so with one left the worker, ending its
#: gap under way and then that one, is as soon done. The contested call (:attr:`_Job.contested`, an odd
#: share's last) is taken back even alone: the caller, done with its own, would idle through two gaps.
TAKEN_BACK_LEAST = 2
#: A caller waiting for the worker's result ends the worker where it has sent nothing on the job for
#: this many times the slowest gap timed so far (the worker's, from its call begun to its poses, and
#: the caller's own of that sequence), and at least :data:`HANG_LEAST` seconds: a worker that hangs
#: (stopped, swapped out) with fewer than :data:`TAKEN_BACK_LEAST` calls not begun would otherwise hold a
#: script without Esc (``blender --background``, a farm task) for ever. Between two messages the worker
#: builds a sequence or computes one gap (its build, 0.05–0.07 s at 15k vertices, is below a gap's
#: 0.12 s); gaps of one sequence differ in cost up to a few times, and the two processes share cores.
HANG_GAPS = 30
#: The least time (s) a caller waits for a silent worker before it ends it (:data:`HANG_GAPS`), and the
#: longest a message written to the worker may wait with no part of it taken (the worker reads its
#: input at once, in a thread of its own) before it is ended so.
HANG_LEAST = 10.0
#: Bytes of a message written to the worker at a time, each noted taken (:class:`_NotedPipe`): a Linux
#: pipe's capacity (64 kB; Windows' anonymous pipes hold less, and take a part in several reads), so
#: that :data:`HANG_LEAST` bounds a wait for one pipe's worth of reading, not for a whole key (2.4 MB
#: at 100k vertices, 37 pipes' worth).
WRITE_PART = 1 << 16
#: Windows' ``CREATE_NO_WINDOW`` process creation flag (``subprocess.CREATE_NO_WINDOW`` there): the
#: worker, a console program, opens no console window beside Blender's.
WINDOWLESS = 0x08000000
#: The name the worker loads the core's folder under: not ``core`` (a package of that name may be
#: another's on the caller's ``sys.path``) nor the extension's ``bl_ext…`` (made by Blender).
PRIVATE_NAME = "_shape_differences_worker_core"
#: What the worker runs: ``argv`` is the core's folder, :data:`PRIVATE_NAME` and the caller's ``sys.path``.
BOOT = (
    "import importlib, importlib.util, os, sys\n"
    "folder, name = sys.argv[1], sys.argv[2]\n"
    "sys.path[:] = sys.argv[3:]\n"
    "spec = importlib.util.spec_from_file_location(name, os.path.join(folder, '__init__.py'),\n"
    "                                              submodule_search_locations=[folder])\n"
    "package = importlib.util.module_from_spec(spec)\n"
    "sys.modules[name] = package\n"
    "spec.loader.exec_module(package)\n"
    "importlib.import_module(name + '.gap_worker').serve()\n"
)
#: The core's folder, which the worker loads.
_FOLDER = os.path.dirname(os.path.abspath(__file__))
#: The worker's environment beyond the caller's: one BLAS thread (its cores are the caller's too), and
#: no worker of its own.
WORKER_ENVIRONMENT = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                      "SHAPE_DIFFERENCES_PROCESSES": "0"}

_worker = None  # the kept worker (_Worker), or None
_worker_lock = threading.Lock()
_unstartable = False  # a worker failed to start: none is tried again in the session
_ended_cpu = 0.0  # CPU seconds of the workers that have ended
_job_ids = itertools.count()
_sequences = weakref.WeakSet()  # sequences that may have work in the background (for stop)


class _Job:
    """The calls of one sequence given to the worker: ``calls`` {(gap, factor bits): factors} in
    order, ``outcomes`` the worker's messages of those computed and not yet taken, ``ended`` once
    the worker will send no more (done, dropped, broken, or gone)."""

    def __init__(self, calls: list[tuple[int, tuple, list[float]]]):
        self.id = next(_job_ids)
        self.calls = {(gap, bits): factors for gap, bits, factors in calls}
        self.outcomes: dict[tuple, tuple] = {}
        self.begun: dict[tuple, float] = {}  # the calls the worker has begun: when (time.monotonic)
        self.ended = False
        self.heard = time.monotonic()  # when it was given, or the worker's last message on it
        self.keyless = False  # sent without the keys: the worker was thought to keep their sequence
        #: Sent without the keys to a worker that kept no sequence under their token (it let it go, idle,
        #: as the job was on its way): none of its calls begun, they are handed over again with the keys.
        self.forgotten = False
        #: ``(gap, factor bits)`` of the call an odd share gave the worker beyond half (its last), which a
        #: waiting caller takes back even as the last one not begun; None where the share was even.
        self.contested = None


class _Worker:
    """The worker process (spawned at once; ready once it has said so), its messages read by a
    thread of its own (see :mod:`core.gap_worker` for them)."""

    def __init__(self):
        executable = sys.executable
        if not executable or not os.path.isfile(executable):
            raise OSError(f"no Python interpreter to start ({executable!r})")
        path = [os.path.abspath(entry) if entry else os.getcwd() for entry in sys.path]
        self.process = subprocess.Popen([executable, "-I", "-c", BOOT, _FOLDER, PRIVATE_NAME, *path],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=_worker_errors(),
                                        env={**os.environ, **WORKER_ENVIRONMENT},
                                        creationflags=WINDOWLESS if sys.platform == "win32" else 0)
        self.started = time.monotonic()
        self.ready = False
        self.alive = True
        self.cpu = 0.0  # its CPU seconds, as its last message said
        self.modules = None  # the modules named core…, bl_ext… or its own core's it imported (its first message)
        self.kept = None  # the token of the sequence it keeps (as the caller last knew), or None
        self.slowest = 0.0  # its slowest gap so far (s, wall: from its "begun" message to its poses)
        self.jobs: dict[int, _Job] = {}
        self.condition = threading.Condition()
        self._write_lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True, name="gap-worker-reader")
        self._reader.start()

    def idle(self) -> bool:
        """Ready, alive, and no job of any sequence under way."""
        with self.condition:
            return self.ready and self.alive and not self.jobs

    def submit(self, job: _Job, token: bytes, arguments: tuple) -> bool:
        """Give the worker ``job`` on the sequence of ``arguments`` (keys, triangles, options), whose
        hash is ``token``: sent only where the worker does not keep that sequence already."""
        with self.condition:
            self.jobs[job.id] = job
            known, self.kept = self.kept == token, token
            job.keyless = known
        calls = [(gap, factors) for (gap, _), factors in job.calls.items()]
        return self._send(("job", job.id, token, None if known else arguments, calls))

    def give_orderings(self, orderings: dict) -> None:
        """Send the caller's factorization ``orderings`` (:func:`core.sparse_cholesky.orderings`): the
        worker's factors of those patterns made after they arrive take them instead of ordering
        their matrices again (the same factors to the bit); nothing where there are none."""
        if orderings:
            self._send(("orderings", orderings))

    def drop(self, job: int) -> None:
        """The worker leaves the remaining calls of job ``job`` (its id) undone (its gap under way
        ends first)."""
        with self.condition:
            if job not in self.jobs:
                return
        self._send(("drop", job))

    def drop_soon(self, job: int) -> None:
        """:meth:`drop`, sent by a thread of its own: for a sequence's finalizer, which the cyclic
        garbage collector may run inside any allocation, this thread's :meth:`_send` included, whose
        lock it would wait for forever."""
        try:
            threading.Thread(target=self.drop, args=(job,), daemon=True, name="gap-worker-drop").start()
        except RuntimeError:  # the interpreter is ending: so is the worker (shut_down)
            pass

    def outcome(self, job: _Job, key: tuple, steal=None, limit: float = HANG_LEAST):
        """The worker's message on call ``key`` of ``job``, waited for; None where it will send none.
        While it is not there and the worker has :data:`TAKEN_BACK_LEAST` calls of ``job`` or more not
        begun, or its last not begun is the job's contested one (:attr:`_Job.contested`), the last is
        taken back (the worker told to skip it) and given to ``steal(call, factors)``, which computes
        it. Raises :class:`_Silent` where the worker has sent nothing on ``job`` for ``limit`` seconds
        (:data:`HANG_GAPS`)."""
        while True:
            with self.condition:
                call = None
                while key in job.calls and key not in job.outcomes and not job.ended:
                    left = [pending for pending in job.calls if pending not in job.begun]
                    if steal is not None and (len(left) >= TAKEN_BACK_LEAST or left and left[-1] == job.contested):
                        call = left[-1]
                        break
                    silent = time.monotonic() - job.heard
                    if silent >= limit:
                        raise _Silent(silent)
                    self.condition.wait(min(limit - silent, threading.TIMEOUT_MAX))
                else:
                    return job.outcomes.pop(key, None)
                factors = job.calls.pop(call)
            self._send(("skip", job.id, *call))
            steal(call, factors)

    def let_go(self, job: _Job) -> None:
        """Wait no more for the worker's messages on ``job`` (dropped): a call waiting in
        :meth:`outcome` takes what has come and computes the rest itself."""
        with self.condition:
            job.ended = True
            self.condition.notify_all()

    def _send(self, message) -> bool:
        """Write ``message`` to the worker's input; False where the worker is gone (its end closed) or
        took none of it for :data:`HANG_LEAST` seconds (:meth:`_watched`: ended, with a warning)."""
        pipe = _NotedPipe(self.process.stdin)
        try:
            with self._write_lock, self._watched(pipe):
                pickle.dump(message, pipe, protocol=pickle.HIGHEST_PROTOCOL)
                pipe.flush()
        except (OSError, ValueError):  # its end closed: gone, or ended by the watch
            pass
        else:
            if pipe.stalled is None:  # written, and the watch did not end the worker as the last part was taken
                return True
        self._gone()
        if pipe.stalled is not None and message[0] != "quit":  # not at the session's end: nothing waits
            _end_silent(self, pipe.stalled, HANG_LEAST, writing=True)
        return False

    @contextmanager
    def _watched(self, pipe: _NotedPipe):
        """The block, which writes to the worker through ``pipe``, watched by a thread of its own: where
        no write of it has been taken for :data:`HANG_LEAST` seconds (the worker stopped or swapped out
        with the pipe full: its input is read at once by a thread of its own, :mod:`core.gap_worker`),
        the worker is killed, which ends the write with an error (``pipe.stalled``: the seconds). The kill
        is decided under a lock the block's end takes too: a write ending as the kill comes leaves
        ``pipe.stalled`` set (the worker is dead, whatever the write says), a block ended kills nothing."""
        done, deciding = threading.Event(), threading.Lock()

        def watch() -> None:
            while not done.wait(max(pipe.taken + HANG_LEAST - time.monotonic(), 0.0)):
                with deciding:  # the block's end and the kill exclude each other: a kill is always told
                    stalled = time.monotonic() - pipe.taken
                    if done.is_set() or stalled < HANG_LEAST:
                        continue
                    pipe.stalled = stalled
                    try:
                        self.process.kill()
                    except OSError:
                        pass
                    return

        try:
            threading.Thread(target=watch, daemon=True, name="gap-worker-write-watch").start()
        except RuntimeError:  # the interpreter is ending (a finalizer's drop): written unwatched
            pass
        try:
            yield
        finally:
            with deciding:
                done.set()

    def _read(self) -> None:
        stream = self.process.stdout
        try:
            while True:
                message = pickle.load(stream)
                now = time.monotonic()
                with self.condition:
                    self.cpu = message[-1]
                    kind = message[0]
                    if kind == "ready":
                        self.ready, self.modules = True, message[2]
                    elif kind == "forgot":  # idle: its kept sequence let go
                        self.kept = None
                    elif kind in ("gap", "failed", "begun"):
                        job, call = self.jobs.get(message[1]), (message[2], message[3])
                        if job is not None:
                            job.heard = now
                        if job is not None and kind == "begun":
                            job.begun[call] = now
                        elif job is not None:
                            self.slowest = max(self.slowest, now - job.begun.get(call, now))
                            if call in job.calls:  # not taken back
                                job.outcomes[call] = message
                    else:  # done or broken: nothing more of that job
                        if kind == "broken":  # no sequence kept
                            self.kept = None
                        job = self.jobs.pop(message[1], None)
                        if job is not None:
                            job.ended = True
                            job.forgotten = kind == "broken" and job.keyless  # the keys not sent: nothing to build
                    self.condition.notify_all()
        except Exception:  # its output closed (it ended or was killed) or garbled: gone
            pass
        self._gone()
        stream.close()
        try:
            self.process.kill()  # garbled output: ended here (a process that has ended is left as it is)
            self.process.wait()
        except OSError:
            pass

    def _gone(self) -> None:
        with self.condition:
            self.alive = False
            for job in self.jobs.values():
                job.ended = True
            self.jobs.clear()
            self.condition.notify_all()

    def end(self) -> None:
        """Ask the worker to quit, and end it if it has not within a second."""
        self._send(("quit",))
        try:
            self.process.stdin.close()
        except OSError:
            pass
        try:
            self.process.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._gone()
        self._reader.join(timeout=1.0)


def _worker_errors():
    """Where the worker's standard error goes: the caller's (a farm job's log, Blender's console),
    or nowhere where the caller has none (its descriptor 2 closed: a worker given none fails to start)."""
    try:
        os.fstat(2)
    except OSError:
        return subprocess.DEVNULL
    return None


class _NotedPipe:
    """The worker's input (a binary stream) noting when its last write was taken (``taken``,
    :func:`time.monotonic`): pickle writes a message's frames and each of its arrays (a key, the
    triangles: a few MB at most) in writes of their own, passed on here in parts of at most
    :data:`WRITE_PART` bytes, so that a worker reading slowly (swapping) is seen taking each part, not
    only a whole array; ``stalled``: the seconds it had taken none when the worker was ended
    (:meth:`_Worker._watched`), else None."""

    def __init__(self, stream):
        self.stream, self.taken, self.stalled = stream, time.monotonic(), None

    def write(self, data) -> int:
        view = memoryview(data)
        if view.nbytes <= WRITE_PART or not view.c_contiguous:  # (an F-ordered array's buffer: whole, as pickle gives it)
            written = self.stream.write(data)
            self.taken = time.monotonic()
            return written
        view = view.cast("B")
        for start in range(0, len(view), WRITE_PART):
            self.stream.write(view[start:start + WRITE_PART])
            self.taken = time.monotonic()
        return len(view)

    def flush(self) -> None:
        self.stream.flush()
        self.taken = time.monotonic()


class _Silent(Exception):
    """The worker has sent nothing on a job for longer than the caller waits (``args[0]``: seconds)."""


def _end_silent(worker: _Worker, silent: float, limit: float, writing: bool = False) -> None:
    """End ``worker``, silent for ``silent`` seconds past the ``limit`` a caller waits for it
    (:data:`HANG_GAPS`; ``writing``: that took nothing of a message for ``silent`` seconds,
    :data:`HANG_LEAST`), and start none again in the session: its jobs' calls are computed by their
    callers (the same in-betweens), with a warning. None again: what stops a worker (a machine out of
    memory and swapping, a process stopped by a job controller or a debugger, a load that makes a gap
    take 30 times its slowest) outlasts the job, and a new worker would hold the next caller as long
    again, with a second copy of the keys in memory; what is lost is the second core (the same bits)."""
    global _unstartable
    _unstartable = True
    try:
        worker.process.kill()
    except OSError:
        pass
    worker._gone()
    silence = (f"took nothing this process sent it for {silent:.1f} s (at most {limit:g} s allowed)" if writing else
               f"sent nothing for {silent:.1f} s, past the {limit:.1f} s it is allowed ({HANG_GAPS} times the "
               f"slowest gap so far, at least {HANG_LEAST:g} s)")
    errors.warn(f"the in-betweens' second process {silence}: it was ended, its gaps are computed in this process "
                "(the same in-betweens, more slowly), and no second process is started again in this session. "
                "Check the machine's memory and load (a process stopped or swapped out); "
                "SHAPE_DIFFERENCES_PROCESSES=0 starts none", "process")


def _digest(arguments: tuple) -> bytes:
    """A hash of ``arguments`` (keys, triangles, options) as their pickle to the worker (streamed
    into the hash, never held whole): the token the worker keeps their sequence under."""
    digest = hashlib.blake2b(digest_size=20)

    class Stream:
        write = digest.update

    pickle.Pickler(Stream(), protocol=pickle.HIGHEST_PROTOCOL).dump(arguments)
    return digest.digest()


def kept_worker() -> _Worker | None:
    """The session's worker, started now if there is none (it gets ready in the background); None
    where none can be started (see the module)."""
    global _worker, _unstartable, _ended_cpu
    with _worker_lock:
        worker = _worker
        if worker is not None and not worker.alive:
            worker.process.poll()  # reaped
            _ended_cpu += worker.cpu
            _unstartable = _unstartable or not worker.ready  # it died starting: it would again
            _worker = worker = None
        if worker is not None and not worker.ready and time.monotonic() - worker.started > START_TIMEOUT:
            worker.end()
            _ended_cpu += worker.cpu
            _unstartable, _worker, worker = True, None, None
        if worker is None and not _unstartable:
            try:
                _worker = worker = _Worker()
            except (OSError, ValueError, subprocess.SubprocessError):  # no interpreter, a sandbox, no pipes
                _unstartable = True
        return worker


def shares_gaps(vertices: int, k_M) -> bool:
    """Whether a sequence of ``vertices`` vertices (with truncated metric ``k_M``, or None) may share
    its gaps with the worker (see the module)."""
    return (concurrency.USE_PROCESSES and not _unstartable and k_M is None
            and CONCURRENT_VERTICES <= vertices <= PROCESS_VERTICES and concurrency.available_cores() >= 2)


def start_worker(vertices: int, gaps: int = 2, k_M: int | None = None) -> bool:
    """Start the session's worker now, where a sequence of ``vertices`` vertices, ``gaps`` key gaps
    and truncated metric ``k_M`` (None: the full basis) would share its gaps (:func:`shares_gaps`,
    two gaps or more), so that its start (a fresh interpreter importing NumPy, SciPy and the core,
    0.24–0.26 s of its CPU) overlaps the caller's reading of the keys rather than its first gaps: the
    *In-between Frames* and *Retime* operators before they read the frames, ``python -m core retime``
    before it reads the samples, a pipeline before it loads its keys. Nothing is started elsewhere (a small
    mesh, one core, ``SHAPE_DIFFERENCES_PROCESSES=0``), nor where one is running already. Returns
    whether the worker is running (ready or getting ready); the in-betweens are the same to the
    bit either way. Raises :class:`~core.errors.MeshError` for a count that is not a whole number."""
    counts = {"vertices": vertices, "gaps": gaps}
    for name, count in counts.items():
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)):
            raise errors.MeshError(f"start_worker: {name} = {count!r} must be a whole number (the sequence's "
                                   f"{'vertex' if name == 'vertices' else 'key gap'} count)")
    if gaps < 2 or not shares_gaps(int(vertices), k_M):
        return False
    return kept_worker() is not None


def worker_cpu(settle: float = 10.0) -> float:
    """CPU seconds the workers of this process have used (for a benchmark: its own CPU time counts
    only its own process), once the worker has finished its jobs (waited up to ``settle`` s)."""
    worker = _worker
    if worker is None:
        return _ended_cpu
    deadline = time.monotonic() + settle
    with worker.condition:
        while worker.alive and worker.jobs and time.monotonic() < deadline:
            worker.condition.wait(0.05)
        return _ended_cpu + worker.cpu


def stop() -> None:
    """Stop the in-betweens' work in the background (the operators' Esc): every sequence's gaps in
    the worker are dropped (the gap under way there ends first) and its call begun ahead in the pool
    cancelled where the pool has not begun it; a call under way begins nothing more (a call begun
    ahead that is running ends with its gap)."""
    for sequence in list(_sequences):
        sequence._stop_background()


def shut_down() -> None:
    """End the worker (at the session's end)."""
    global _worker, _ended_cpu
    with _worker_lock:
        worker, _worker = _worker, None
    if worker is not None:
        worker.end()
        _ended_cpu += worker.cpu


atexit.register(shut_down)


def _forgotten_after_fork() -> None:
    """In a child process forked from this one: the worker is the parent's (its messages are read
    by the parent's thread, which does not exist here, so a call waiting for one would wait for
    ever; what the child wrote on its pipe would mix with the parent's messages), so the child
    forgets it: its sequences compute the calls they gave it themselves, and the next sequence that
    shares gaps starts a worker of the child's own. The locks are made anew (one the parent's threads
    held at the fork would never be given back), and the child's copies of the pipes are closed (the
    worker sees its input close when the parent ends, whatever the child does)."""
    global _worker, _worker_lock
    worker, _worker = _worker, None
    _worker_lock = threading.Lock()
    if worker is None:
        return
    worker.condition, worker._write_lock = threading.Condition(), threading.Lock()
    worker.alive = False
    for job in worker.jobs.values():
        job.ended = True
    worker.jobs.clear()
    for stream in (worker.process.stdin, worker.process.stdout):
        try:
            stream.raw.close()  # the descriptor only: nothing the parent had buffered is written again
        except (AttributeError, OSError, ValueError):
            pass


if hasattr(os, "register_at_fork"):  # not on Windows, which does not fork
    os.register_at_fork(after_in_child=_forgotten_after_fork)


class GapProcesses:
    """A sequence's gaps shared with the worker process (see the module)."""

    #: ``(worker, job)`` of each job of this sequence's calls given to the worker with calls not yet made.
    _jobs = ()
    #: The calls the caller said it will make (:meth:`will_ask`), ``(gap, factor bits, factors)``, and
    #: how many of them it has made; None where it said none.
    _plan = None
    _planned = 0
    #: The constructor's checked arguments (keys, triangles, options) the worker builds its own
    #: sequence from; None where the sequence shares no gaps.
    _worker_arguments = None
    #: The hash of :attr:`_worker_arguments` (:func:`_digest`), made at the first hand-over.
    _token = None
    #: Calls of the worker's taken back and computed here before they were asked: {(gap, bits): a
    #: function returning their (poses, warnings) or raising their error}.
    _taken_back: dict = {}  # (read only: the first hand-over makes the sequence's own)
    #: The slowest call computed here so far (s, wall), of which the wait for a silent worker is a
    #: multiple (:data:`HANG_GAPS`).
    _slowest = 0.0

    def _share_gaps_later(self, arguments: tuple) -> None:
        """Keep the constructor's ``arguments`` where this sequence may share its gaps. The worker is
        started once the caller is known to ask two gaps or more: at a plan of two calls or more
        (:meth:`will_ask`), or at the first call of a visit in order that leaves later gaps
        (:meth:`_hand_over`), not for a caller that asks one gap (a farm's one-gap chunk)."""
        _sequences.add(self)
        if len(self) >= 2 and shares_gaps(self._topo.n, self.k_M):
            self._worker_arguments = arguments

    def will_ask(self, calls) -> None:
        """Say which calls of :meth:`poses` come next, in order: ``calls`` pairs ``(gap, factors)``
        (:func:`core.retime.iter_retime` says its plan, whose factors may change from gap to gap).
        The later half of those not yet made may then be computed in the worker process; a call
        off the plan forgets it."""
        from .validation import check_factors, check_gap_index

        plan = []
        for gap, factors in calls:
            gap, factors = check_gap_index(gap, len(self)), check_factors(factors)
            plan.append((gap, factor_bits(factors), factors))
        self._plan, self._planned = plan, 0
        if len(plan) >= 2 and self._worker_arguments is not None and shares_gaps(self._topo.n, self.k_M):
            kept_worker()  # started now: it gets ready while the first calls are computed

    def _stop_background(self) -> None:
        """:func:`stop` for this sequence: the call under way begins nothing more in the background
        (``_halted``, cleared by the next call), the worker's gaps dropped and a call waiting for one
        of them let go at once (it computes its gap itself: a worker that hangs would hold it for
        ever), the call held ahead cancelled."""
        self._halted = True
        jobs = self._jobs
        self._drop_jobs()
        for worker, job in jobs:
            worker.let_go(job)
        held = self._ahead
        if held is not None:
            held[2].cancel()  # not begun: the call that asks for it computes it

    def _drop_jobs(self) -> None:
        held, self._jobs = self._jobs, ()
        for worker, job in held:
            worker.drop(job.id)

    def _from_worker(self, gap: int, factors: list[float], ahead: bool, computed: bool = False):
        """Before a call on gap ``gap`` at (checked) ``factors`` is computed: the worker's ``(poses,
        warnings)`` of it where the worker holds it (its warnings raised meanwhile raised here, its
        error raised here); else None, once the later half of the calls left is given to the worker
        where that pays (the caller's visit read here: in order, or as planned, and ``ahead``;
        ``computed``: this call's poses are at hand already, taken from the call begun ahead)."""
        self._halted = False
        bits = factor_bits(factors)
        on_plan = self._plan is not None and self._planned < len(self._plan) and \
            self._plan[self._planned][:2] == (gap, bits)
        if self._plan is not None and not on_plan:
            self._plan = None  # off its plan: read as any other caller from here
        self._planned += on_plan
        taken = None if computed else self._taken_back.pop((gap, bits), None)
        if taken is not None:  # the worker's, taken back and computed here while an earlier call waited
            return taken()
        # a job that reached the worker after it let its sequence go (idle) began nothing: its calls free again
        self._jobs = tuple(held for held in self._jobs if not held[1].forgotten)
        for worker, job in self._jobs:
            if (gap, bits) in job.calls and not computed:
                return self._taken_from_worker(worker, job, gap, factors, bits)
        if not (on_plan or self._in_order):  # off its visit: the worker's gaps would go unasked
            self._drop_jobs()
        elif ahead and not any(not job.ended for _, job in self._jobs):
            self._hand_over(gap, factors, bits, computed)
        return None

    def _hand_over(self, gap: int, factors: list[float], bits: tuple, computed: bool) -> None:
        """Give the worker the later half of the calls left after this one (on gap ``gap``) up to those
        it holds already, this one counted as the caller's unless ``computed`` already, where the
        worker is ready and idle (again once it has done a first share before the caller has done
        its own). An odd count's half is rounded up, the caller keeping one call at least, and the
        worker's last call then contested (:attr:`_Job.contested`)."""
        if self._worker_arguments is None or not shares_gaps(self._topo.n, self.k_M):
            return
        if self._plan is not None:
            rest = self._plan[self._planned:]
        else:
            rest = [(later, bits, factors) for later in range(gap + 1, len(self))]
        held = [call for _, job in self._jobs for call in job.calls] + list(self._taken_back)
        if held:  # the calls before the first the worker holds (those after it are its or asked already)
            first = next((i for i, (at, asked, _) in enumerate(rest) if (at, asked) in held), len(rest))
            rest = rest[:first]
        count = len(rest) + (not computed)  # the calls to share, this one counted where not computed
        share = min((count + 1) // 2, count - 1)  # the caller keeps one at least (this one, where not computed)
        if share < 1:
            return
        worker = kept_worker()
        if worker is None or not worker.idle():
            return
        job = _Job(rest[len(rest) - share:])
        if share > count // 2:  # an odd count's middle call: the worker's last, to whichever is free first
            job.contested = tuple(rest[-1][:2])
        if self._token is None:
            self._token = _digest(self._worker_arguments)
        if worker.submit(job, self._token, self._worker_arguments):
            self._jobs = (*self._jobs, (worker, job))
            if "_taken_back" not in vars(self):
                self._taken_back = {}
            # a sequence let go leaves its gaps undone (not at exit: shut_down ends the worker)
            weakref.finalize(self, worker.drop_soon, job.id).atexit = False
            if not job.keyless:  # a sequence to build: the mesh's ordering made here now (the caller's
                # first gap needs it too) and sent, before the worker's build reaches its first
                # factorization, which then does not order the same pattern again (75 → 23 ms at 15k)
                worker.give_orderings(self._topo.factor_orderings())

    def _taken_from_worker(self, worker: _Worker, job: _Job, gap: int, factors: list[float], bits: tuple):
        """The worker's outcome of call ``(gap, bits)`` of ``job`` (see :meth:`_from_worker`); while
        it is not there, the calls the worker has not begun computed here, from the last."""
        limit = max(HANG_LEAST, HANG_GAPS * max(worker.slowest, self._slowest))
        try:
            outcome = worker.outcome(job, (gap, bits), self._take_back, limit)
        except _Silent as silent:  # hung: ended, and this call and the worker's others computed here
            _end_silent(worker, silent.args[0], limit)
            outcome = None
        job.calls.pop((gap, bits), None)
        if not job.calls:
            self._jobs = tuple(held for held in self._jobs if held[1] is not job)
        taken = self._taken_back.pop((gap, bits), None)
        if taken is not None:  # this very call was taken back
            return taken()
        if outcome is None:  # dropped, broken or gone: computed here
            return None
        if outcome[0] == "failed":
            error = _error(outcome[4], outcome[5])
            if error is None:
                return None  # not one of the core's errors: computed here, raised as it would be
            raise error
        poses, problems, said = outcome[4:7]
        for message, attributes in said:
            _warn_again(message, attributes)
        return poses, problems

    def _take_back(self, call: tuple, factors: list[float]) -> None:
        """Compute here the worker's ``call`` (gap, bits) it has not begun, for when it is asked
        (its poses and warnings, or its error raised then)."""
        with self._timed(), concurrency.one_thread():
            try:
                poses = self._computed_poses(call[0], factors, False)
            except Exception as error:
                def answer(error=error):
                    raise error
            else:
                def answer(poses=poses):
                    return poses
        self._taken_back[call] = answer

    def _worker_holds(self, gap: int) -> bool:
        """Whether the worker computes (or has computed) gap ``gap`` for a call not yet made: nothing
        of it is begun or prepared here."""
        return any(at == gap for _, job in self._jobs for at, _ in list(job.calls))

    @contextmanager
    def _sharing(self):
        """The context of a call computed here, timed (:attr:`_slowest`): one thread while the worker
        holds calls of this sequence not yet made (the caller's own part: threads would buy it 0.80–1.02 ×
        the wall time for 1.3–1.7 × the CPU)."""
        with self._timed(), concurrency.one_thread() if self._jobs else nullcontext():
            yield

    @contextmanager
    def _timed(self):
        """:attr:`_slowest` updated with the wall time of the block, where it ends without an error."""
        began = time.monotonic()
        yield
        self._slowest = max(self._slowest, time.monotonic() - began)


def _error(name: str, message: str) -> Exception | None:
    """The core's error of class ``name`` with ``message``, as the worker raised it; None for any
    other class (or one whose message would read otherwise)."""
    kind = getattr(errors, name, None)
    if not (isinstance(kind, type) and issubclass(kind, errors.ShapeDifferenceError)):
        return None
    error = kind(message)
    return error if str(error) == message else None


def _warn_again(message: str, attributes: dict) -> None:
    """A warning the worker's call raised (the core's: :func:`core.errors.warn`), raised here with its
    attributes (kind, defects, gap, factors, excess)."""
    warning = errors.shape_warning(message, attributes["kind"])
    warning.__dict__.update(attributes)
    errors.warn(warning)
