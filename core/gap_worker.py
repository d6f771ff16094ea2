"""The second process's side of :mod:`core.gap_processes`: a loop that builds a sequence from the
keys it is sent and returns the in-betweens of the gaps it is given, one message per gap.

Started by :func:`core.gap_processes.kept_worker` as ``python -I -c BOOT`` (a fresh interpreter,
never a fork), which loads this package from its folder under a private name and calls
:func:`serve`. Messages are pickles of NumPy arrays and builtins on the process's standard input
and output (the output the loop writes to is a duplicate of it made first; anything else the
process prints goes to its standard error):

- in: ``("job", job, keys, triangles, options, calls)`` — ``keys`` a list of float64 ``(n, 3)``,
  ``triangles`` int ``(m, 3)``, ``options`` the sequence's keyword arguments, ``calls`` a list of
  ``(gap, factors)`` computed in that order; ``("drop", job)`` — the job's remaining gaps left
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
  cannot be built. ``cpu``: this process's CPU seconds so far (:func:`time.process_time`).

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


def serve() -> None:
    """The worker's loop (see the module); returns at ``("quit",)``."""
    from . import concurrency
    from .allocator import keep_heap
    from .concurrency import one_thread
    from .errors import ShapeDifferenceWarning
    from .sequence_gaps_ahead import factor_bits
    from .sequence_inbetweens import SequenceInterpolator

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
            elif message[0] == "skip":
                skipped.add(message[1:])
            else:
                inbox.put(message)

    threading.Thread(target=read, daemon=True, name="gap-worker-inbox").start()
    concurrency.USE_PROCESSES = False  # its sequences share no gaps: it is the second process
    keep_heap()
    own = __name__.rpartition(".")[0]  # the private name it was loaded under
    names = sorted(m for m in sys.modules if m in ("core", own) or m.startswith(("core.", "bl_ext", own + ".")))
    send(("ready", os.getpid(), names))
    with one_thread():
        while True:
            message = inbox.get()
            if message[0] == "quit":
                return
            _, job, keys, triangles, options, calls = message
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # the caller's own sequence said them
                    sequence = SequenceInterpolator(keys, triangles, **options)
            except Exception as error:
                send(("broken", job, type(error).__name__, str(error)))
                continue
            del keys
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
                        poses, problems = sequence._poses(gap, factors, False)
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
            send(("done", job))  # idle for the next job (which waits in the inbox until this one's memory is let go)
            del sequence
            dropped.discard(job)
            gc.collect()
