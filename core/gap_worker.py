"""The second process's side of :mod:`core.gap_processes`: a loop that builds a sequence from the
keys it is sent and returns the in-betweens of the gaps it is given, one message per gap.

Started by :func:`core.gap_processes.kept_worker` as ``python -I -c BOOT`` (a fresh interpreter,
never a fork), which loads this package from its folder under a private name and calls
:func:`serve`. Messages are pickles of NumPy arrays and builtins on the process's standard input
and output (the output the loop writes to is a duplicate of it made first; anything else the
process prints goes to its standard error):

- in: ``("job", job, token, arguments, calls)`` — ``arguments`` ``(keys, triangles, options)``:
  ``keys`` a list of float64 ``(n, 3)`` C-contiguous arrays, ``triangles`` int ``(m, 3)``, ``options``
  the sequence's keyword arguments, all as the caller's constructor checked them (not checked again:
  :class:`CallerSequence`), the sequence built from them and kept under ``token`` (bytes: a hash of them)
  for the next jobs; or None for the sequence kept under ``token``; ``calls`` a list of
  ``(gap, factors)`` computed in that order; ``("orderings", orderings)`` — the caller's
  factorization orderings (:func:`core.sparse_cholesky.orderings`), taken as they arrive: the
  factors made after take them instead of ordering their matrices again; ``("drop", job)`` — the job's remaining gaps left
  undone; ``("skip", job, gap, bits)`` — that call left undone, unless begun (the caller computes
  it); ``("quit",)``.
- out: ``("ready", pid, names, cpu)`` once the core is imported (``names``: the modules named
  ``core…`` or ``bl_ext…`` imported in this process, none expected, and those of its own core); per call ``("gap", job, gap,
  bits, poses, problems, warnings, cpu)`` (what :meth:`core.SequenceInterpolator._poses` returns,
  and the core's warnings raised meanwhile as ``(message, attributes)``; any other is shown on the
  worker's standard error), after ``("begun", job,
  gap, bits, cpu)`` as it begins, or ``("failed", job,
  gap, bits, class name, message, cpu)``; ``("done", job, cpu)`` after a job's last call, or after
  the gap it was on when dropped; ``("broken", job, class name, message, cpu)`` where the sequence
  cannot be built (or none is kept under the job's token); ``("forgot", cpu)`` once it has let its
  kept sequence go. ``cpu``: this process's CPU seconds so far (:func:`time.process_time`).

One sequence is kept between jobs (a new one replaces it): a second job of the same keys (a sequence
asked for other gaps, an operator run again) is not built again. After :data:`IDLE_SECONDS` without
a message the worker lets it go and hands its free heap back to the system
(:func:`core.allocator.give_back_heap`), so that an idle worker holds little more than its modules.

The whole loop runs in one thread with BLAS single-threaded (:func:`core.concurrency.one_thread`):
the other core is the caller's. The standard input ending (the caller gone) ends the process.
"""

from __future__ import annotations

import gc
import os
import pickle
import queue
import sys
import threading
import time
import warnings

from .sequence_inbetweens import SequenceInterpolator

#: Seconds without a message after which the worker lets its kept sequence go and hands its free heap
#: back: jobs of a script, a retime or an operator's redo follow one another within it (a rerun of
#: the curtain at g = 4: 0.15–0.19 s of the worker's CPU saved, 0.90–0.95 × the run's), while an idle
#: worker holds neither that sequence nor its last job's heap (resident 205 → 81 MB after the curtain
#: at g = 4, 454 → 86 MB after the 50k sheet at g = 8; 66 MB when ready).
IDLE_SECONDS = 30.0


class CallerSequence(SequenceInterpolator):
    """The caller's sequence, built here from the keys, triangles and options its constructor checked
    and sent (:meth:`core.gap_processes.GapProcesses._share_gaps_later`): the keys are not checked again
    (:func:`core.validation.check_sequence`'s ``checked``; at 50k vertices 0.11 s of the 0.35 s build),
    the same sequence to the bit."""

    _keys_checked = True


def serve() -> None:
    """The worker's loop (see the module); returns at ``("quit",)``."""
    from . import concurrency
    from .allocator import give_back_heap, keep_heap
    from .concurrency import one_thread
    from .errors import ShapeDifferenceWarning
    from .sequence_gaps_ahead import factor_bits
    from .sparse_cholesky import load_library, take_orderings

    channel = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())  # stray prints go to standard error, not the channel
    sys.stdout = sys.stderr
    inbox, dropped, skipped = queue.Queue(), set(), set()

    def send(message) -> None:
        pickle.dump(message + (time.process_time(),), channel, protocol=pickle.HIGHEST_PROTOCOL)
        channel.flush()

    def read() -> None:
        source = sys.stdin.buffer
        while True:
            try:
                message = pickle.load(source)
            except Exception:  # the caller closed its end (or is gone): nothing more will be asked
                os._exit(0)
            if message[0] == "drop":
                dropped.add(message[1])
            elif message[0] == "orderings":  # read here: the build under way may factor with them
                try:
                    take_orderings(message[1])
                except Exception:  # not taken: the factors order their matrices here, as without them
                    pass
            elif message[0] == "skip":
                skipped.add(message[1:])
            else:
                inbox.put(message)

    # The reader starts after threadpoolctl's look-up of the BLAS libraries (made as the core was
    # imported: core.concurrency) and loads no library itself (CHOLMOD's is loaded here first): before
    # threadpoolctl 3.7 the look-up runs Python inside glibc's dl_iterate_phdr, under the loader's lock,
    # and a library loaded by the reader meanwhile (at the first orderings: cholespy imported) waits
    # for that lock holding Python's: neither ever goes on.
    with one_thread():
        load_library()
        threading.Thread(target=read, daemon=True, name="gap-worker-inbox").start()
        concurrency.USE_PROCESSES = False  # its sequences share no gaps: it is the second process
        keep_heap()
        own = __name__.rpartition(".")[0]  # the private name it was loaded under
        names = sorted(m for m in sys.modules if m in ("core", own) or m.startswith(("core.", "bl_ext", own + ".")))
        # what the imports made lives as long as the process: set apart from the collections below, which
        # then walk only what the jobs made (a kept sequence let go) instead of the modules' ~36,000 objects
        gc.freeze()
        send(("ready", os.getpid(), names))
        kept_token, kept = None, None  # the sequence kept between jobs, and the token it was sent with
        idle = False  # nothing kept and the heap handed back since the last job
        while True:
            try:
                message = inbox.get(timeout=None if idle else IDLE_SECONDS)
            except queue.Empty:  # idle: its sequence and its heap's free memory let go
                kept_token, kept, idle = None, None, True
                gc.collect()
                give_back_heap()
                send(("forgot",))
                continue
            if message[0] == "quit":
                return
            _, job, token, arguments, calls = message
            idle = False
            if kept is None or token != kept_token:  # a sequence of other keys (or options): built from them
                kept_token, kept = None, None
                gc.collect()  # the sequence kept before let go first: one at a time
                try:
                    if arguments is None:
                        raise LookupError("no sequence kept under this token (let go while idle)")
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")  # the caller's own sequence said them
                        kept = CallerSequence(arguments[0], arguments[1], **arguments[2])
                except Exception as error:
                    send(("broken", job, type(error).__name__, str(error)))
                    continue
                kept_token = token
            message = arguments = None  # the keys as sent: the sequence holds what it needs of them
            for gap, factors in calls:
                if job in dropped:
                    break
                bits = factor_bits(factors)
                if (job, gap, bits) in skipped:  # taken back by the caller, which computes it
                    skipped.discard((job, gap, bits))
                    continue
                send(("begun", job, gap, bits))
                try:
                    with warnings.catch_warnings(record=True) as caught:
                        warnings.simplefilter("always")
                        poses, problems = kept._poses(gap, factors, False)
                except Exception as error:
                    send(("failed", job, gap, bits, type(error).__name__, str(error)))
                    continue
                # the core's warnings go back to the caller; any other (NumPy's) is shown here, on standard error
                said = [(str(w.message.args[0]), dict(vars(w.message))) for w in caught
                        if isinstance(w.message, ShapeDifferenceWarning)]
                for w in caught:
                    if not isinstance(w.message, ShapeDifferenceWarning):
                        warnings.showwarning(w.message, w.category, w.filename, w.lineno)
                send(("gap", job, gap, bits, poses, problems, said))
                del poses
            send(("done", job))  # idle for the next job, its sequence kept
            dropped.discard(job)
