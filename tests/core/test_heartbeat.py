"""core.heartbeat: lines on stderr stay whole whoever prints them, and a heartbeat names a step
only after the line that ends the one before."""

import io
import re
import sys
import threading
import time
import warnings

import core.__main__ as command
from core.heartbeat import Heartbeat


class _SlowStream(io.StringIO):
    """stderr whose writes of a text starting with ``slow`` pause after writing, as a full pipe
    does: the pause falls between a printed line's text and its newline (``print`` writes them
    apart), where another thread's write would land inside the line."""

    def __init__(self, slow: str):
        super().__init__()
        self.slow, self.entered = slow, threading.Event()

    def write(self, text):
        written = super().write(text)
        if text.startswith(self.slow):
            self.entered.set()
            time.sleep(0.3)
        return written


def _python_s_own(message, category, filename, lineno, file=None, line=None):
    """Python's own way of showing a warning: its text in one write to stderr."""
    sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def test_python_s_own_warnings_never_split_a_heartbeat_line(monkeypatch):
    """A warning that is not the core's (NumPy's RuntimeWarning), shown by Python inside a
    retime while the heartbeat's thread is printing a line, waits for that line to end."""
    stream = _SlowStream("job: working on")
    monkeypatch.setattr(sys, "stderr", stream)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = _python_s_own
        with command._warnings_as_lines("retime"):
            with Heartbeat("job", time.monotonic(), every=0.05) as beat:
                beat.doing = "a slow step"
                assert stream.entered.wait(5)
                warnings.warn("overflow encountered", RuntimeWarning)
    lines = stream.getvalue().splitlines()
    beats = [line for line in lines if line.startswith("job:")]
    assert beats and all(re.fullmatch(r"job: working on a slow step, \d+\.\d s", line) for line in beats), lines
    assert any(line.endswith("RuntimeWarning: overflow encountered") for line in lines), lines


def test_the_next_step_is_named_only_after_the_line_that_ends_the_last(monkeypatch):
    """``say(text, doing=...)``: while the line saying step 1 ended is being printed (slowly), the
    heartbeat names neither step 1, which that line says has ended, nor step 2 before it; after
    it, it names step 2, and every line is whole."""
    stream = _SlowStream("step 1 done")
    monkeypatch.setattr(sys, "stderr", stream)
    with Heartbeat("job", time.monotonic(), every=0.05) as beat:
        beat.doing = "step 1"
        time.sleep(0.02)  # shorter than the heartbeat: nothing said yet
        beat.say("step 1 done", doing="step 2")
        time.sleep(0.3)
    lines = stream.getvalue().splitlines()
    assert "step 1 done" in lines, lines
    done = lines.index("step 1 done")
    assert all(re.fullmatch(r"job: working on step 1, \d+\.\d s", line) for line in lines[:done]), lines
    after = lines[done + 1:]
    assert after and all(re.fullmatch(r"job: working on step 2, \d+\.\d s", line) for line in after), lines
