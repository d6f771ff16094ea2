"""Lines on stderr for long runs without a window (the ``retime`` command, operators run with
``blender -b``): each printed whole whatever thread prints beside it (:func:`line`), and a
heartbeat that says what a run is working on whenever no line came for a while
(:class:`Heartbeat`), so that a farm's watchdog on silence sees a long core call alive.
"""

from __future__ import annotations

import sys
import threading
import time

#: Seconds without a line after which a heartbeat says what the run is working on: at 100k
#: vertices a retime reads for 3 s before its first line and computes a gap's in-betweens together
#: for 11 s between two lines; preparing the keys of *In-between Frames* is one core call as long.
HEARTBEAT_SECONDS = 2.0
#: Held while a line goes to stderr, so that a heartbeat's thread never splits another line
#: (re-entrant: a heartbeat prints its line while holding it for the silence's check).
_STDERR_LOCK = threading.RLock()


def line(text: str) -> None:
    """Print ``text`` as one line on stderr, whole whatever thread prints beside it."""
    whole(print, text, file=sys.stderr, flush=True)


def whole(write, *args, **kwargs):
    """``write(*args, **kwargs)`` (a writer to stderr that is not :func:`line`: Python's own
    warnings) while no other line is being printed, so that neither splits the other."""
    with _STDERR_LOCK:
        return write(*args, **kwargs)


class Heartbeat:
    """Progress lines of a run on stderr (none when ``quiet``): :meth:`say` prints one, and inside
    the ``with`` block a thread prints ``<label>: working on <doing>, T s`` whenever no line came
    for ``every`` seconds (by default :data:`HEARTBEAT_SECONDS`) while :attr:`doing` names
    something. Seconds count from ``began`` (``time.monotonic()``); ``last`` is when the run's
    previous line was printed (by default now). Leaving the block stops the thread and waits for
    it, so no heartbeat line follows the block's last line."""

    def __init__(self, label: str, began: float, quiet: bool = False, every: float | None = None,
                 last: float | None = None):
        self.label, self.began, self.quiet = label, began, quiet
        self.every = HEARTBEAT_SECONDS if every is None else every
        self.last = time.monotonic() if last is None else last
        self.doing = ""  # what the heartbeat names; nothing is said while it is empty
        self._stop = threading.Event()
        self._thread = None

    def say(self, text: str, doing: str | None = None) -> None:
        """Print ``text`` as the run's next line (see :func:`line`) and, given ``doing``, name what
        the run works on next, both at once: no heartbeat line comes between them to name the
        next step before ``text`` says the last one ended, or the step ``text`` says has ended."""
        with _STDERR_LOCK:
            if not self.quiet:
                line(text)
            self.last = time.monotonic()
            if doing is not None:
                self.doing = doing

    def seconds(self) -> str:
        """The seconds since ``began``, as the lines say them."""
        return f"{time.monotonic() - self.began:.1f} s"

    def _beat(self) -> None:
        while not self._stop.wait(max(0.0, self.last + self.every - time.monotonic())):
            with _STDERR_LOCK:  # the silence checked where no other line can end it meanwhile
                if time.monotonic() - self.last >= self.every and self.doing and not self._stop.is_set():
                    line(f"{self.label}: working on {self.doing}, {self.seconds()}")
                    self.last = time.monotonic()

    def __enter__(self):
        if not self.quiet:
            self._thread = threading.Thread(target=self._beat, name=f"{self.label}-heartbeat", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        return False
