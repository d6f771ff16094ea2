"""The next gap's in-betweens begun in the pool one gap ahead (core.sequence_gaps_ahead): the same
in-betweens and warnings to the bit whatever the order and factors asked, no two calls at once on
one gap's state, and an error of the call begun ahead raised by the call that asks for it."""

from __future__ import annotations

import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from core import concurrency, inbetween_prediction, sequence_gaps_ahead, sequence_inbetweens
from core.errors import RecoveryError
from core.sequence_inbetweens import SequenceInterpolator
from meshes import drape, grid



def _inflated(vertices: np.ndarray, amount: float) -> np.ndarray:
    """``vertices`` (n, 3) of a unit sheet with a patch of ~1 % of its area stretched radially by up
    to ``amount`` (its edges' changes are then what a trimmed tolerance leaves out)."""
    centre = np.array([0.3, 0.6, 0.0])
    bump = np.exp(-np.sum((vertices - centre) ** 2, axis=1) / (2 * 0.03 ** 2))
    return centre + (vertices - centre) * (1.0 + amount * bump)[:, None]


#: A 5,184-vertex draped sheet (over CONCURRENT_VERTICES, as the gaps begun ahead need), six keys.
FLAT, TRIANGLES = grid(72, jitter=0.3)
KEYS = [drape(_inflated(FLAT, 0.4 * (k % 2)), 0.15 + 0.3 * k) for k in range(6)]
#: Keys 16 frames apart (a batch that trims the fit's tolerance) and a batch of three.
SIXTEENTHS = list(np.arange(1, 16) / 16)
THREE = [0.3, 0.55, 0.8]


@pytest.fixture(autouse=True)
def two_cores(monkeypatch):
    if concurrency.available_cores() < 2:
        pytest.skip("one core: nothing is begun ahead")
    monkeypatch.setattr(concurrency, "USE_PROCESSES", False)  # the threads' rule alone (no gaps in a second process)


def _never_ahead(self, gap, factors):
    return None


def _asked(sequence, requests):
    """``(poses, warnings' messages)`` of each request ``(gap, factors)`` (or ``(gap, factor)``:
    :meth:`pose`), asked in order of ``sequence``."""
    out = []
    for gap, factors in requests:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            poses = sequence.pose(gap, factors) if np.isscalar(factors) else sequence.poses(gap, factors)
        out.append((poses, [str(w.message) for w in said]))
    return out


def _begun(sequence):
    """Wait until the pool has begun the call held ahead (None if none is held)."""
    held = sequence._ahead
    if held is None:
        return None
    deadline = time.monotonic() + 60
    while not (held[2].running() or held[2].done()) and time.monotonic() < deadline:
        time.sleep(0.001)
    return held


def _counted(monkeypatch):
    """Lists that receive the gap of each call begun ahead and of each taken."""
    begun, taken = [], []
    original_begin, original_result = sequence_gaps_ahead.in_background, sequence_gaps_ahead.result

    def counted_begin(function, gap, *arguments):
        begun.append(gap)
        return original_begin(function, gap, *arguments)

    def counted_result(future, function, gap, *arguments):
        taken.append(gap)
        return original_result(future, function, gap, *arguments)

    monkeypatch.setattr(sequence_gaps_ahead, "in_background", counted_begin)
    monkeypatch.setattr(sequence_gaps_ahead, "result", counted_result)
    return begun, taken


def test_same_in_betweens_and_warnings_whatever_the_order_and_factors(monkeypatch):
    """In order at one set of factors (calls begun ahead and taken), at other factors, out of
    order, again, and one pose at a time (dropping the call begun ahead): every answer is to the
    bit that of a sequence that begins nothing ahead, asked the same."""
    requests = [(0, SIXTEENTHS), (1, SIXTEENTHS), (2, SIXTEENTHS), (3, THREE), (4, SIXTEENTHS), (0, THREE),
                (1, THREE), (2, THREE), (3, THREE), (4, THREE), (2, THREE), (1, THREE), (2, THREE), (3, 0.5),
                (3, THREE), (4, THREE)]
    begun, taken = _counted(monkeypatch)
    ahead = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests)
    # begun by the calls that continue an in-order visit at one set of factors (and the first): (0, 16ths),
    # the third (2, 3), and between them those the pool has begun or not when asked (a call not begun is
    # computed by the caller, which begins the next); taken by (1, 16ths) and others; the last dropped by
    # the single pose (3, 0.5)
    assert begun[0] == 1 and taken[0] == 1 and begun[-1] == 3 and set(taken) <= set(begun) and len(taken) >= 2
    monkeypatch.setattr(SequenceInterpolator, "_beginning_ahead", _never_ahead)
    alone = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests)
    for (x, said), (y, told) in zip(ahead, alone):
        assert x.tobytes() == y.tobytes() and said == told


def test_factors_that_change_from_gap_to_gap_begin_one_call_ahead_at_most(monkeypatch):
    """A caller asking each gap at factors of its own (a retime to another speed) has one call
    begun ahead in vain, after its first call, and none after."""
    begun, taken = _counted(monkeypatch)
    sequence = SequenceInterpolator(KEYS, TRIANGLES)
    for gap in range(len(sequence)):
        sequence.poses(gap, list(np.arange(1, 8) / 8 + 0.01 * gap))
    assert begun == [1] and taken == []


def test_a_call_on_the_gap_begun_ahead_waits_for_it_to_end(monkeypatch):
    """A call on the gap begun ahead at other factors runs only once that call has ended. A cloth
    dragged over the floor (three keys of a bake: tests/core/data/dragged_cloth.npz), whose second
    gap fits to its trimmed tolerance (16 in-betweens, 0.8 %) otherwise than to its whole change's
    (one in-between, 1.3 %): the call begun ahead pauses after setting the gap's tolerance until
    the other call has set it, or 2 s. Run at once (the probe of session 72 did), the two share the
    gap's per-call state (its tolerance, the fits' misfits, the checks' outcomes) and the 16
    in-betweens taken after are fitted to the wrong tolerance."""
    data = np.load(Path(__file__).parent / "data" / "dragged_cloth.npz")
    keys, triangles = list(data["frames"]), data["triangles"]
    monkeypatch.setattr(sequence_gaps_ahead, "CONCURRENT_VERTICES", 0)  # its 1,089 vertices begun ahead too
    caller_in, ahead_in = threading.Event(), threading.Event()
    original = inbetween_prediction._solved
    tolerances = {}

    def paused(gap, factors, known):
        if threading.current_thread() is threading.main_thread():
            if factors == [0.5]:
                tolerances["caller"] = gap.tolerance
                caller_in.set()
        elif not ahead_in.is_set():
            tolerances["ahead"] = gap.tolerance
            ahead_in.set()
            caller_in.wait(2.0)  # the call on its gap at other factors, if it runs meanwhile
            tolerances["ahead, resumed"] = gap.tolerance
        return original(gap, factors, known)

    monkeypatch.setattr(inbetween_prediction, "_solved", paused)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sequence = SequenceInterpolator(keys, triangles)
        sequence.poses(0, SIXTEENTHS)  # begins gap 1 at the 16ths
        assert _begun(sequence)[0] == 1 and ahead_in.wait(60)
        one = sequence.pose(1, 0.5)
        sixteen = sequence.poses(1, SIXTEENTHS)
        monkeypatch.setattr(inbetween_prediction, "_solved", original)
        monkeypatch.setattr(SequenceInterpolator, "_beginning_ahead", _never_ahead)
        alone = SequenceInterpolator(keys, triangles)
        alone.poses(0, SIXTEENTHS)
        assert one.tobytes() == alone.pose(1, 0.5).tobytes()
        assert sixteen.tobytes() == alone.poses(1, SIXTEENTHS).tobytes()
    assert tolerances["ahead"] < tolerances["caller"]  # the state the two calls would share
    assert tolerances["ahead, resumed"] == tolerances["ahead"]


def test_an_error_of_the_call_begun_ahead_is_raised_by_the_call_that_asks_for_it(monkeypatch):
    """The call begun ahead fails (made to here, in the pool only): the call asking for that gap at
    those factors raises its error; a call at other factors drops it and answers."""
    original = sequence_inbetweens.gap_poses

    def failing_ahead(*arguments):
        if threading.current_thread() is not threading.main_thread() and arguments[2] is None:
            raise RecoveryError("failed ahead")
        return original(*arguments)

    monkeypatch.setattr(sequence_inbetweens, "gap_poses", failing_ahead)
    sequence = SequenceInterpolator(KEYS, TRIANGLES)
    sequence.poses(0, THREE)
    assert _begun(sequence)[0] == 1
    with pytest.raises(RecoveryError, match="failed ahead"):
        sequence.poses(1, THREE)
    assert sequence._ahead is None
    sequence.poses(2, THREE)  # computed here (nothing held), begins gap 3
    assert _begun(sequence)[0] == 3
    assert np.isfinite(sequence.poses(3, SIXTEENTHS)).all()  # other factors: its error dropped


#: A small draped sheet's samples, 15 frames: keyed every 4th, the last gap shorter (frames 12–14).
SMALL, SMALL_TRIANGLES = grid(16, jitter=0.3)
SAMPLES = np.array([drape(SMALL, 0.1 * f) for f in range(15)])


@pytest.mark.parametrize("gaps", [None, range(0, 3)])
def test_a_retime_begins_no_gap_it_does_not_ask_for(monkeypatch, gaps):
    """A retime whose last gap is shorter (keyed by a sequence of its own) or one chunk of it asks the
    main sequence for its gaps in order at one set of factors, and nothing after its last: no call
    is begun ahead for a gap it does not ask for (it would run a gap's work to waste in the pool once
    the retime is done), and the poses are those of a sequence that begins nothing."""
    from core import retime

    monkeypatch.setattr(sequence_gaps_ahead, "CONCURRENT_VERTICES", 0)  # its 256 vertices begun ahead too
    begun, _ = _counted(monkeypatch)
    asked = []
    original_poses = SequenceInterpolator.poses

    def counted_poses(self, gap_index, factors, **options):
        asked.append((len(self), gap_index))
        return original_poses(self, gap_index, factors, **options)

    monkeypatch.setattr(SequenceInterpolator, "poses", counted_poses)
    plan = retime.plan_retime(len(SAMPLES), 4, 1.0)
    main = len(plan.keys) - 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        poses = retime.retime(SAMPLES, SMALL_TRIANGLES, step=4, speed=1.0, gaps=gaps)
        main_asked = {gap for count, gap in asked if count == main}
        assert len(main_asked) >= 2 and begun and set(begun) <= main_asked
        monkeypatch.setattr(SequenceInterpolator, "_beginning_ahead", _never_ahead)
        alone = retime.retime(SAMPLES, SMALL_TRIANGLES, step=4, speed=1.0, gaps=gaps)
    assert poses.tobytes() == alone.tobytes()


def test_a_child_forked_while_a_call_runs_ahead_computes_it_itself(monkeypatch):
    """A process forked while the call begun ahead runs in the pool (a pipeline's worker processes):
    the child has no pool thread to end it, so it computes the call itself and answers as a sequence
    that begins nothing; it waited for that call forever before."""
    import os
    import signal

    if not hasattr(os, "fork"):
        pytest.skip("no fork on this system")
    monkeypatch.setattr(sequence_gaps_ahead, "CONCURRENT_VERTICES", 0)
    keys = [drape(SMALL, 0.3 * k) for k in range(4)]
    release = threading.Event()
    original = sequence_inbetweens.gap_poses

    def held_in_the_pool(*arguments):
        if threading.current_thread() is not threading.main_thread():
            release.wait(60)  # still running when the process forks
        return original(*arguments)

    monkeypatch.setattr(sequence_inbetweens, "gap_poses", held_in_the_pool)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        monkeypatch.setattr(SequenceInterpolator, "_beginning_ahead", _never_ahead)
        expected = SequenceInterpolator(keys, SMALL_TRIANGLES).poses(1, THREE)
        monkeypatch.undo()
        monkeypatch.setattr(sequence_gaps_ahead, "CONCURRENT_VERTICES", 0)
        monkeypatch.setattr(sequence_inbetweens, "gap_poses", held_in_the_pool)
        sequence = SequenceInterpolator(keys, SMALL_TRIANGLES)
        sequence.poses(0, THREE)
        assert _begun(sequence)[0] == 1 and sequence._ahead[2].running()
        reading, writing = os.pipe()
        child = os.fork()
        if child == 0:  # the child: answers within 60 s, or is stopped
            try:
                signal.alarm(60)
                same = sequence.poses(1, THREE).tobytes() == expected.tobytes()
                os.write(writing, b"same" if same else b"different")
            finally:
                os._exit(0)
        release.set()
        os.close(writing)
        _, status = os.waitpid(child, 0)
        told = os.read(reading, 16)
        os.close(reading)
    assert told == b"same", (told, status)
