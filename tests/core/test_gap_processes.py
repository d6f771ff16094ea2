"""A sequence's gaps shared with a second, kept process (core.gap_processes, core.gap_worker): the
same in-betweens, warnings and errors to the bit as in one process, in the caller's order; the
caller computing what a worker that cannot start, dies or is stopped leaves; no worker on one core;
the worker's core loaded under a private name. Small meshes: the vertex threshold is lowered."""

from __future__ import annotations

import os
import pickle
import shutil
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from core import allocator, concurrency, gap_processes, retime
from core.errors import MeshError, RecoveryError, ShapeDifferenceWarning
from core.sequence_inbetweens import SequenceInterpolator
from meshes import drape, grid

#: A sheet spun through half turns (tests/core/data/spinning_sheet.npz): six keys, five gaps, the
#: last two warned of (its turns), 150 vertices.
DATA = np.load(Path(__file__).parent / "data" / "spinning_sheet.npz")
KEYS, TRIANGLES = list(DATA["keys"]), DATA["triangles"]
SIXTEENTHS = list(np.arange(1, 16) / 16)
#: The longest the tests wait for a state of the worker (ready, a gap begun, a pause released): far past
#: what a worker starved of CPU by other processes (one core, a loaded CI machine) takes to get there.
STARVED = 120.0


@pytest.fixture(autouse=True)
def shared(monkeypatch):
    """Gaps shared on these small meshes, on any machine (two cores read even on one: the results do
    not depend on the threads), the switch on."""
    monkeypatch.setattr(gap_processes, "CONCURRENT_VERTICES", 0)
    monkeypatch.setattr(concurrency, "available_cores", lambda: 2)
    monkeypatch.setattr(concurrency, "USE_PROCESSES", True)
    monkeypatch.setattr(gap_processes, "_unstartable", False)


@pytest.fixture(scope="module", autouse=True)
def no_worker_left():
    yield
    gap_processes.shut_down()
    assert gap_processes._worker is None


def _ready_worker():
    worker = gap_processes.kept_worker()
    deadline = time.monotonic() + STARVED
    while not worker.ready and worker.alive and time.monotonic() < deadline:
        time.sleep(0.01)
    assert worker.ready
    return worker


def _idle(worker):
    """Wait until ``worker`` has no job left (the last job's end said)."""
    deadline = time.monotonic() + 60
    while not worker.idle() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert worker.idle()


def _begun(worker, gap: int):
    """Wait until ``worker`` has begun gap ``gap`` of its one job (its "begun" message read), or has
    ended that job (done with every call of it): under load a fresh worker may still be building its
    sequence when the caller reaches that gap, and the caller then takes the worker's last call back
    (two not begun: :data:`~core.gap_processes.TAKEN_BACK_LEAST`), which the split these tests assert
    does not expect."""
    with worker.condition:
        jobs = list(worker.jobs.values())
    if not jobs:  # its one job ended already (what the worker did of it, the test's own asserts read)
        return
    (job,) = jobs
    deadline = time.monotonic() + STARVED
    while not any(at == gap for at, _ in job.begun) and not job.ended and time.monotonic() < deadline:
        time.sleep(0.01)
    assert any(at == gap for at, _ in job.begun) or job.ended


def _asked(sequence, requests, *, after_first=None):
    """``(poses, the warnings' (message, kind, gap, factors, excess))`` of each request ``(gap,
    factors)``, or ``(type, message)`` of the error it raised; ``after_first()`` run after the first."""
    out = []
    for index, (gap, factors) in enumerate(requests):
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            try:
                poses = sequence.poses(gap, factors, ahead=gap + 1 < len(sequence))
            except RecoveryError as error:
                poses = (type(error), str(error))
        out.append((poses, [(str(w.message), w.message.kind, w.message.gap, w.message.factors, w.message.excess)
                            for w in said if isinstance(w.message, ShapeDifferenceWarning)]))
        if index == 0 and after_first is not None:
            after_first()
    return out


def _one_process(requests, monkeypatch, keys=KEYS):
    with monkeypatch.context() as patch:
        patch.setattr(concurrency, "USE_PROCESSES", False)
        return _asked(SequenceInterpolator(keys, TRIANGLES), requests)


def _same(these, those):
    assert len(these) == len(those)
    for (x, said), (y, told) in zip(these, those):
        assert said == told
        if isinstance(x, tuple):
            assert x == y
        else:
            assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


def _counted_jobs(monkeypatch):
    """The gaps of each job given to the worker, and the calls taken from it."""
    given, taken = [], []
    submit, take = gap_processes._Worker.submit, gap_processes.GapProcesses._taken_from_worker

    def counted_submit(self, job, *arguments):
        given.append(sorted(gap for gap, _ in job.calls))
        return submit(self, job, *arguments)

    def counted_take(self, worker, job, gap, factors, bits):
        taken.append(gap)
        return take(self, worker, job, gap, factors, bits)

    monkeypatch.setattr(gap_processes._Worker, "submit", counted_submit)
    monkeypatch.setattr(gap_processes.GapProcesses, "_taken_from_worker", counted_take)
    return given, taken


def _counted_take_backs(monkeypatch):
    """The gaps the caller takes back from the worker, in order."""
    taken_back, take_back = [], gap_processes.GapProcesses._take_back

    def counted(self, call, factors):
        taken_back.append(call[0])
        return take_back(self, call, factors)

    monkeypatch.setattr(gap_processes.GapProcesses, "_take_back", counted)
    return taken_back


def test_same_poses_and_warnings_in_order_as_one_process(monkeypatch):
    """Five gaps in order at 15 factors: the worker takes the later three (the half of five rounded
    up, the last contested: the warned gaps among them), and every pose and warning (message, kind,
    gap, factors, excess), in order, is one process's. The caller goes on after its first call once the
    worker has begun gap 2; its gap 4 is the worker's or, where the worker has not begun it when the
    caller waits for gap 2 or 3, taken back."""
    worker = _ready_worker()
    given, taken = _counted_jobs(monkeypatch)
    taken_back = _counted_take_backs(monkeypatch)
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    shared = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests, after_first=lambda: _begun(worker, 2))
    assert given == [[2, 3, 4]] and taken_back in ([], [4]) and sorted(taken + taken_back) == [2, 3, 4]
    alone = _one_process(requests, monkeypatch)
    assert sum(len(said) for _, said in alone[3:]) >= 2  # the worker's gaps warn
    _same(shared, alone)


def test_the_worker_starts_no_worker_of_its_own(monkeypatch):
    """The worker's own sequences (built for each job, of a size that shares gaps) start no process."""
    worker = _ready_worker()
    children = Path(f"/proc/{worker.process.pid}/task/{worker.process.pid}/children")
    if not children.exists():
        pytest.skip("no /proc children list on this system")
    given, taken = _counted_jobs(monkeypatch)
    flat, triangles = grid(72)  # 5,184 vertices: past CONCURRENT_VERTICES in the worker too
    keys = [drape(flat, amount) for amount in (0.2, 0.4, 0.6)]
    _asked(SequenceInterpolator(keys, triangles), [(0, [0.5]), (1, [0.5])])
    assert given == [[1]] and taken == [1]
    time.sleep(1.0)  # a process it started would be there by now
    assert children.read_text().split() == []


def test_a_retime_at_another_speed_shares_its_planned_gaps(monkeypatch):
    """A retime whose factors change from gap to gap says its plan (will_ask): the worker takes the
    later half of it (five calls: three, the half rounded up), and the retimed samples are one
    process's to the bit."""
    _ready_worker()
    given, _ = _counted_jobs(monkeypatch)
    samples = np.array([KEYS[k // 3] if k % 3 == 0 else
                        (1 - (k % 3) / 3) * KEYS[k // 3] + (k % 3) / 3 * KEYS[k // 3 + 1] for k in range(16)])
    shared = retime.retime(samples, TRIANGLES, step=3, speed=0.7)
    assert given and len(given[0]) == 3
    monkeypatch.setattr(concurrency, "USE_PROCESSES", False)
    assert shared.tobytes() == retime.retime(samples, TRIANGLES, step=3, speed=0.7).tobytes()


def _patched_core(folder: Path, gap: int, action: str) -> Path:
    """A copy of the core whose sequences run ``action`` (a statement) first when they solve gap
    ``gap``."""
    core = folder / "core"
    shutil.copytree(Path(gap_processes.__file__).parent, core, ignore=shutil.ignore_patterns("__pycache__"))
    with open(core / "sequence_inbetweens.py", "a") as module:
        module.write(f"\n\nimport os as _os\nimport time as _time\nfrom .errors import RecoveryError as _Failed\n"
                     f"_solved = SequenceInterpolator._solved_poses\n\n\n"
                     f"def _patched(self, gap, *arguments, **options):\n"
                     f"    if gap == {gap}:\n"
                     f"        {action}\n"
                     f"    return _solved(self, gap, *arguments, **options)\n\n\n"
                     f"SequenceInterpolator._solved_poses = _patched\n")
    return core


def _paused_until(released: Path) -> str:
    """An ``action`` of :func:`_patched_core`: wait until the file ``released`` exists (at most
    :data:`STARVED` s), a pause the test ends when the state it needs is reached rather than after a
    time the caller might outlast on a loaded machine."""
    return (f"_until = _time.monotonic() + {STARVED}\n"
            f"        while not _os.path.exists({str(released)!r}) and _time.monotonic() < _until:\n"
            f"            _time.sleep(0.01)")


def test_a_failing_gap_raises_when_the_caller_reaches_it(monkeypatch, tmp_path):
    """Gap 3 fails (in the worker, which holds it, and in the parent alike): the calls before it
    answer, it raises the core's error with one process's message, the gap after it answers. Each of
    the worker's gaps (2, 3 and 4) is taken from it or taken back and computed by the caller: gap 4
    where the worker has not begun it when the caller waits (contested), and gap 3 too where the
    worker had begun neither as the caller waited for gap 2 (a loaded machine)."""
    gap_processes.shut_down()
    monkeypatch.setattr(gap_processes, "_FOLDER", str(_patched_core(tmp_path, 3, "raise _Failed('gap 3 fails here')")))
    solved = SequenceInterpolator._solved_poses

    def failing(self, gap, *arguments, **options):
        if gap == 3:
            raise RecoveryError("gap 3 fails here")
        return solved(self, gap, *arguments, **options)

    monkeypatch.setattr(SequenceInterpolator, "_solved_poses", failing)
    try:
        _ready_worker()
        given, taken = _counted_jobs(monkeypatch)
        taken_back = _counted_take_backs(monkeypatch)
        requests = [(gap, SIXTEENTHS) for gap in range(5)]
        shared = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests)
        assert given == [[2, 3, 4]] and taken_back in ([], [4], [4, 3])
        assert sorted(taken + taken_back) == [2, 3, 4]
    finally:
        gap_processes.shut_down()
    assert shared[3][0][0] is RecoveryError and "gap 3 fails here" in shared[3][0][1]
    assert all(isinstance(x, np.ndarray) for x, _ in shared[:3] + shared[4:])
    _same(shared, _one_process(requests, monkeypatch))


def test_calls_the_worker_has_not_begun_are_taken_back(monkeypatch, tmp_path):
    """Ten gaps (the spun sheet there and back), the worker's first (gap 5) paused there (in its core)
    until the caller has taken three calls back: the caller, waiting for it, computes the worker's last
    gaps meanwhile, which the worker skips, down to the one it would do next; one process's poses and
    warnings. The caller goes on after its first call once the worker has begun gap 5 (else it takes
    back gap 6 too), and the pause lasts until the take-backs (it was 3 s, which a starved caller's
    gaps 1-4 and three take-backs could outlast, the worker then beginning gap 6 or 7 first)."""
    gap_processes.shut_down()
    released = tmp_path / "released"
    monkeypatch.setattr(gap_processes, "_FOLDER", str(_patched_core(tmp_path, 5, _paused_until(released))))
    taken_back = []
    take_back = gap_processes.GapProcesses._take_back

    def counted(self, call, factors):
        taken_back.append(call[0])
        try:
            return take_back(self, call, factors)
        finally:
            if len(taken_back) == 3:
                released.touch()

    monkeypatch.setattr(gap_processes.GapProcesses, "_take_back", counted)
    keys = KEYS + KEYS[-2::-1]
    try:
        worker = _ready_worker()
        given, taken = _counted_jobs(monkeypatch)
        requests = [(gap, SIXTEENTHS) for gap in range(10)]
        shared = _asked(SequenceInterpolator(keys, TRIANGLES), requests, after_first=lambda: _begun(worker, 5))
        assert given == [[5, 6, 7, 8, 9]] and taken == [5, 6] and taken_back == [9, 8, 7]
    finally:
        gap_processes.shut_down()
    _same(shared, _one_process(requests, monkeypatch, keys))


def test_a_worker_that_cannot_start_leaves_the_gaps_to_the_caller(monkeypatch):
    """No interpreter to start: nothing given, the session marks it, the poses are one process's."""
    monkeypatch.setattr(gap_processes, "_worker", None)
    monkeypatch.setattr(gap_processes.sys, "executable", "/nonexistent/python")
    given, _ = _counted_jobs(monkeypatch)
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    shared = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests)
    assert given == [] and gap_processes._unstartable and gap_processes._worker is None
    _same(shared, _one_process(requests, monkeypatch))


def test_a_worker_killed_mid_sequence_leaves_its_gaps_to_the_caller(monkeypatch):
    """The worker is killed once it holds the later gaps: the caller computes them, the poses and
    warnings are one process's; the next sequence has a new worker."""
    worker = _ready_worker()
    given, _ = _counted_jobs(monkeypatch)
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    shared = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests, after_first=worker.process.kill)
    assert given[0] == [2, 3, 4] and not worker.alive
    _same(shared, _one_process(requests, monkeypatch))
    assert _ready_worker() is not worker


def test_stopped_sequences_compute_what_the_worker_held(monkeypatch):
    """stop() (the operators' Esc) after the first call: the worker drops its gaps, the caller computes
    them, one process's poses and warnings; the worker is idle after."""
    worker = _ready_worker()
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    shared = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests, after_first=gap_processes.stop)
    _same(shared, _one_process(requests, monkeypatch))
    _idle(worker)


def test_one_core_starts_no_worker(monkeypatch):
    """One core (a CPU affinity of one): no worker started, nothing given."""
    monkeypatch.setattr(concurrency, "available_cores", lambda: 1)
    monkeypatch.setattr(gap_processes, "_worker", None)
    given, _ = _counted_jobs(monkeypatch)
    _asked(SequenceInterpolator(KEYS, TRIANGLES), [(gap, SIXTEENTHS) for gap in range(5)])
    assert given == [] and gap_processes._worker is None


def test_the_worker_loads_the_core_under_a_private_name():
    """The worker imported no module named core (nor bl_ext…): its core is the private package."""
    worker = _ready_worker()
    private = gap_processes.PRIVATE_NAME
    assert {private, private + ".sequence_inbetweens", private + ".gap_worker"} <= set(worker.modules)
    assert [m for m in worker.modules if not m.startswith(private)] == []


def test_start_worker_starts_one_only_where_a_sequence_would_share_its_gaps(monkeypatch):
    """``start_worker`` (what the operators and ``python -m core retime`` call before they read the
    keys) starts the worker for a sequence that shares its gaps, and the sequence built after uses
    that worker; nothing below the vertex threshold, above PROCESS_VERTICES, with one gap, a truncated
    metric, one core or processes off. Counts that are not whole numbers are refused."""
    gap_processes.shut_down()
    monkeypatch.setattr(gap_processes, "CONCURRENT_VERTICES", 100)
    for vertices, gaps, k_M in ((99, 5, None), (gap_processes.PROCESS_VERTICES + 1, 5, None), (150, 1, None),
                                (150, 5, 20)):
        assert not gap_processes.start_worker(vertices, gaps, k_M) and gap_processes._worker is None
    for patched in ((concurrency, "available_cores", lambda: 1), (concurrency, "USE_PROCESSES", False)):
        with monkeypatch.context() as patch:
            patch.setattr(*patched)
            assert not gap_processes.start_worker(150, 5) and gap_processes._worker is None
    for vertices, gaps in ((150.0, 5), (True, 5), ("150", 5), (150, 5.0)):
        with pytest.raises(MeshError, match="whole number"):
            gap_processes.start_worker(vertices, gaps)
    assert gap_processes.start_worker(np.int64(150), 5)
    started = gap_processes._worker
    assert started is not None and started.alive
    assert gap_processes.start_worker(150, 5) and gap_processes._worker is started  # kept, not another
    given, _ = _counted_jobs(monkeypatch)
    _ready_worker()
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    shared = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests)
    assert given and gap_processes._worker is started
    _same(shared, _one_process(requests, monkeypatch))


@pytest.mark.parametrize("eligible", [True, False], ids=["shared", "small"])
def test_the_retime_command_starts_the_worker_before_it_reads_the_keys(monkeypatch, tmp_path, eligible):
    """``python -m core retime`` on a mesh whose sequence shares its gaps has the worker started when
    it reads the OBJ (before the keys' samples), and writes the file one process writes, byte for
    byte; on a mesh below the threshold no worker is started at all."""
    from core import __main__ as command
    from core.obj_file import write_obj
    from core.point_cache import write_pc2

    gap_processes.shut_down()
    monkeypatch.setattr(gap_processes, "CONCURRENT_VERTICES", 100 if eligible else 151)
    cache = write_pc2(tmp_path / "in.pc2", np.array(KEYS), start=1.0)
    topology = write_obj(tmp_path / "sheet.obj", KEYS[0], TRIANGLES)
    running = []
    read_obj = command.read_obj

    def reading(path):
        running.append(gap_processes._worker is not None)
        if running[-1]:  # ready before the gaps, which take milliseconds here: the worker takes its share
            _ready_worker()
        return read_obj(path)

    monkeypatch.setattr(command, "read_obj", reading)
    given, _ = _counted_jobs(monkeypatch)
    arguments = ["retime", str(cache), "--topology", str(topology), "--step", "1", "--speed", "0.4", "-q"]
    assert command.main([*arguments, "-o", str(tmp_path / "shared.pc2")]) == 0
    assert running == [eligible] and (gap_processes._worker is not None) == eligible and bool(given) == eligible
    with monkeypatch.context() as patch:
        patch.setattr(concurrency, "USE_PROCESSES", False)
        assert command.main([*arguments, "-o", str(tmp_path / "alone.pc2")]) == 0
    assert (tmp_path / "shared.pc2").read_bytes() == (tmp_path / "alone.pc2").read_bytes()


def _digest(answers) -> list:
    """The bytes of each answer's poses (or its error) and its warnings, to compare across processes."""
    return [(x.tobytes() if isinstance(x, np.ndarray) else x, said) for x, said in answers]


def _slowed_at_gap_3(monkeypatch, tmp_path, seconds: float, first_calls: int):
    """A new worker whose core pauses ``seconds`` at gap 3, a sequence of the spun sheet and the
    answers of its first ``first_calls`` calls (gaps in order at 15 factors; after the first, the
    worker's gap 3 begun: else a caller waiting for gap 2 takes gaps 4 and 3 back): the worker then
    holds gaps 2, 3 and 4 (the last contested). ``(sequence, answers, the gaps taken from the worker,
    worker)``."""
    gap_processes.shut_down()
    monkeypatch.setattr(gap_processes, "_FOLDER", str(_patched_core(tmp_path, 3, f"_time.sleep({seconds})")))
    worker = _ready_worker()
    given, taken = _counted_jobs(monkeypatch)
    sequence = SequenceInterpolator(KEYS, TRIANGLES)
    answers = _asked(sequence, [(gap, SIXTEENTHS) for gap in range(first_calls)],
                     after_first=lambda: _begun(worker, 3))
    assert given == [[2, 3, 4]]
    return sequence, answers, taken, worker


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this system")
def test_a_child_forked_while_the_worker_holds_gaps_computes_them_itself(monkeypatch, tmp_path):
    """A process forked while the worker (slowed at gap 3) holds a sequence's gaps 2, 3 and 4: the
    worker's messages are read by the parent's thread, which the child does not have, so the child
    computes those gaps itself (one process's poses and warnings) rather than wait for ever (before:
    the child hung at gap 3, ended here by its alarm); the parent still gets them from the worker."""
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    try:
        sequence, first, taken, worker = _slowed_at_gap_3(monkeypatch, tmp_path, 3.0, 1)
        _begun(worker, 3)  # else a parent reaching gap 3 first takes gap 4 back (neither begun)
        reading, writing = os.pipe()
        child = os.fork()
        if child == 0:  # the child: its answers through the pipe, or its error's name
            try:
                signal.alarm(60)
                out = pickle.dumps(_digest(first + _asked(sequence, requests[1:])))
            except BaseException as error:
                out = pickle.dumps(repr(error))
            finally:
                with os.fdopen(writing, "wb") as pipe:
                    pipe.write(out)
                os._exit(0)
        os.close(writing)
        with os.fdopen(reading, "rb") as pipe:
            in_child = pickle.loads(pipe.read() or pickle.dumps("no answer"))
        _, status = os.waitpid(child, 0)
        in_parent = first + _asked(sequence, requests[1:])
        assert 2 in taken and 3 in taken  # the parent's from its worker (4, contested, may be taken back)
    finally:
        gap_processes.shut_down()
    assert os.waitstatus_to_exitcode(status) == 0
    alone = _digest(_one_process(requests, monkeypatch))
    assert in_child == alone and _digest(in_parent) == alone


def test_stop_lets_a_caller_waiting_for_the_worker_go(monkeypatch, tmp_path):
    """stop() (the operators' Esc, from another thread) while the caller waits for a gap the worker
    has begun and takes 40 s on: the caller computes it itself at once, one process's poses (before:
    it waited the worker's 40 s, for ever where the worker hangs)."""
    try:
        sequence, shared, _, _ = _slowed_at_gap_3(monkeypatch, tmp_path, 40.0, 3)
        escape = threading.Timer(1.0, gap_processes.stop)
        escape.start()
        began = time.monotonic()
        shared += _asked(sequence, [(3, SIXTEENTHS)])
        waited = time.monotonic() - began
        escape.join()
        shared += _asked(sequence, [(4, SIXTEENTHS)])
    finally:
        gap_processes.shut_down()
    assert waited < 20.0
    _same(shared, _one_process([(gap, SIXTEENTHS) for gap in range(5)], monkeypatch))


def test_a_sequence_let_go_inside_the_pipes_lock_drops_its_gaps(monkeypatch, tmp_path):
    """A sequence whose gaps the worker holds let go while the caller's thread holds the pipe's lock
    (the cyclic garbage collector runs finalizers inside any allocation, a message's pickling
    included): its drop still reaches the worker, which never begins gap 4, without waiting for that
    lock (before: the thread waited for its own lock for ever)."""
    try:
        sequence, _, _, worker = _slowed_at_gap_3(monkeypatch, tmp_path, 3.0, 1)
        (job,) = worker.jobs.values()
        held = [sequence]
        del sequence

        def let_go():
            with worker._write_lock:
                held.clear()  # its last reference: the finalizer runs here

        thread = threading.Thread(target=let_go, daemon=True)
        thread.start()
        thread.join(10.0)
        stuck = thread.is_alive()
        if stuck:
            worker._write_lock = threading.Lock()  # so that shut_down can write
        assert not stuck
        _idle(worker)
        assert 4 not in {gap for gap, _ in job.begun}  # dropped before gap 3's 3 s were over
    finally:
        gap_processes.shut_down()

def test_a_caller_without_standard_error_still_starts_a_worker():
    """A caller whose standard error is closed (a daemon, a detached farm job): its worker starts
    and says it is ready (before: it started with no standard error, failed at once, and the
    session gave up on workers)."""
    script = ("import os, time\n"
              "from core import concurrency, gap_processes\n"
              "worker = gap_processes.kept_worker()\n"
              "deadline = time.monotonic() + 120\n"
              "while not worker.ready and worker.alive and time.monotonic() < deadline:\n"
              "    time.sleep(0.01)\n"
              "os.write(1, repr((worker.ready, worker.alive)).encode())\n"
              "gap_processes.shut_down()\n")
    root = Path(gap_processes.__file__).parents[1]
    told = subprocess.run([sys.executable, "-c", script], cwd=root, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                          pass_fds=(), preexec_fn=lambda: os.close(2), timeout=300,
                          env={**os.environ, "PYTHONPATH": str(root)})
    assert told.stdout.decode() == "(True, True)"


def _sent_jobs(monkeypatch):
    """Each job message sent to the worker: ``(job id, whether the keys were sent)``, and the kinds of
    the worker's messages the caller took (``gap``: computed there)."""
    sent, answered = [], []
    send, outcome = gap_processes._Worker._send, gap_processes._Worker.outcome

    def recorded_send(self, message):
        if message[0] == "job":
            sent.append((message[1], message[3] is not None))
        return send(self, message)

    def recorded_outcome(self, *arguments, **options):
        answer = outcome(self, *arguments, **options)
        answered.append(None if answer is None else answer[0])
        return answer

    monkeypatch.setattr(gap_processes._Worker, "_send", recorded_send)
    monkeypatch.setattr(gap_processes._Worker, "outcome", recorded_outcome)
    return sent, answered


def test_a_second_job_of_the_same_keys_sends_and_builds_nothing(monkeypatch):
    """A sequence of the same keys built again (an operator run again) and asked its gaps again: the
    worker computes its share from the sequence it kept, the keys not sent again (before: sent, and the
    sequence built again, for every job), with one process's poses and warnings, its warned gaps
    included; a sequence of other keys replaces it (one kept), after which the first keys are sent again.
    A worker of its own: one an earlier test left may keep these keys already (their first job then sends none)."""
    gap_processes.shut_down()
    worker = _ready_worker()
    sent, answered = _sent_jobs(monkeypatch)
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    alone = _one_process(requests, monkeypatch)
    _same(_asked(SequenceInterpolator(KEYS, TRIANGLES), requests), alone)
    assert sent and sent[0][1] and not any(with_keys for _, with_keys in sent[1:])  # once per sequence
    _idle(worker)
    before, heard = len(sent), len(answered)
    _same(_asked(SequenceInterpolator([key.copy() for key in KEYS], TRIANGLES), requests), alone)
    assert sent[before:] and not any(with_keys for _, with_keys in sent[before:]) and "gap" in answered[heard:]
    others = KEYS[::-1]
    _idle(worker)
    before = len(sent)
    _same(_asked(SequenceInterpolator(others, TRIANGLES), requests), _one_process(requests, monkeypatch, others))
    assert sent[before:] and sent[before][1]
    _idle(worker)
    before = len(sent)
    _same(_asked(SequenceInterpolator(KEYS, TRIANGLES), requests), alone)
    assert sent[before:] and sent[before][1]


def test_a_job_with_the_keys_is_followed_by_the_meshs_factor_ordering(monkeypatch):
    """Where the worker is sent the keys (it builds a sequence), the caller sends its ordering of the
    mesh's normal matrix right after the job (the pattern of every anchor weight's factor, filed under
    that pattern's hash), so that the worker's first factorization does not order it again; a job on
    the sequence the worker keeps sends none. The poses stay one process's (before: no ordering sent)."""
    cholespy = pytest.importorskip("cholespy")
    from core import cholmod_direct

    if cholmod_direct.library(cholespy) is None:
        pytest.skip("CHOLMOD's functions are not exported by this platform's cholespy")
    gap_processes.shut_down()
    worker = _ready_worker()
    messages = []
    send = gap_processes._Worker._send

    def recorded_send(self, message):
        messages.append(message)
        return send(self, message)

    monkeypatch.setattr(gap_processes._Worker, "_send", recorded_send)
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    sequence = SequenceInterpolator(KEYS, TRIANGLES)
    shared = _asked(sequence, requests)
    _idle(worker)
    before = len(messages)
    again = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests)  # the same keys: the kept sequence
    kinds = [message[0] for message in messages]
    assert kinds[:2] == ["job", "orderings"] and messages[0][3] is not None
    if messages[before][3] is None:  # sent without the keys (not where the idle worker let them go meanwhile)
        assert "job" in kinds[before:] and "orderings" not in kinds[before:]
    topo = sequence._topo
    matrix = (topo.laplacian + sp.diags(0.37 * topo.mass)).tocsc()  # any weight: one pattern
    matrix.sort_indices()
    digest = cholmod_direct.pattern_digest(matrix.indptr, matrix.indices)
    assert digest in messages[1][1] and sorted(messages[1][1][digest]) == list(range(topo.n))
    alone = _one_process(requests, monkeypatch)
    _same(shared, alone)
    _same(again, alone)


def test_triangles_the_caller_reuses_after_the_build_change_nothing(monkeypatch):
    """A caller that reuses its triangles' buffer once the sequence is built (here every triangle
    turned over in place, as a loader filling the same array with the next mesh would): the worker
    builds its sequence from the sequence's own copy, so the shared gaps are one process's poses of the
    triangles given (before: the worker built from the caller's array as it was at the hand-over, and
    its gaps came back up to 0.044 off, silently)."""
    gap_processes.shut_down()
    _ready_worker()
    given, taken = _counted_jobs(monkeypatch)
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    triangles = TRIANGLES.copy()
    sequence = SequenceInterpolator(KEYS, triangles)
    triangles[:] = triangles[:, ::-1]
    try:
        shared = _asked(sequence, requests)
    finally:
        gap_processes.shut_down()
    assert given == [[2, 3, 4]] and 2 in taken
    _same(shared, _one_process(requests, monkeypatch))


def test_a_job_sent_as_the_idle_worker_lets_its_sequence_go_is_handed_over_again(monkeypatch):
    """The caller sends a job without the keys because the worker kept their sequence, but the worker
    let it go (idle) while the job was on its way (here: the caller's record says it keeps the
    sequence of a fresh worker, which keeps none): the worker answers that it keeps nothing under that
    token, and its calls are handed over again, with the keys, at the next call: the worker computes
    them, one process's poses (before: the caller computed that job's five gaps itself, in one thread,
    each outcome it waited for None)."""
    gap_processes.shut_down()
    worker = _ready_worker()
    sent, answered = _sent_jobs(monkeypatch)
    flat, triangles = grid(8)
    keys = [drape(flat, amount) for amount in np.linspace(0.1, 0.9, 12)]
    requests = [(gap, [0.25, 0.5, 0.75]) for gap in range(11)]
    sequence = SequenceInterpolator(keys, triangles)
    worker.kept = gap_processes._digest(sequence._worker_arguments)

    def refused():  # the worker's answer to the keyless job read before the next call
        deadline = time.monotonic() + 60
        while worker.jobs and time.monotonic() < deadline:
            time.sleep(0.01)

    try:
        shared = _asked(sequence, requests, after_first=refused)
    finally:
        gap_processes.shut_down()
    # every call waited for came from the worker: none of a job that ended without it (None: computed here)
    assert sent[0][1] is False and any(with_keys for _, with_keys in sent[1:]) and answered
    assert None not in answered, answered
    with monkeypatch.context() as patch:
        patch.setattr(concurrency, "USE_PROCESSES", False)
        _same(shared, _asked(SequenceInterpolator(keys, triangles), requests))


def _patched_worker(folder: Path, statement: str) -> Path:
    """A copy of the core whose gap_worker module runs ``statement`` (a module-level statement) last."""
    core = folder / "core"
    shutil.copytree(Path(gap_processes.__file__).parent, core, ignore=shutil.ignore_patterns("__pycache__"))
    with open(core / "gap_worker.py", "a") as module:
        module.write(f"\n\n{statement}\n")
    return core


def _resident_mb(pid: int) -> float:
    """The resident set (MB) of process ``pid`` (Linux's /proc)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="no /proc on this system")
@pytest.mark.skipif(allocator._glibc() is None, reason="no glibc: its heap is not handed back (give_back_heap)")
def test_an_idle_worker_lets_its_sequence_and_heap_go(monkeypatch, tmp_path):
    """A worker idle for IDLE_SECONDS (0.5 s here) after a job on a 14,400-vertex sheet lets its kept
    sequence go and hands its free heap back: its resident set returns to within 40 MB of what it was
    when ready (before: 144 MB against 66 when ready, for the rest of the session), and the next job of
    those keys sends them again."""
    gap_processes.shut_down()
    monkeypatch.setattr(gap_processes, "_FOLDER", str(_patched_worker(tmp_path, "IDLE_SECONDS = 0.5")))
    try:
        worker = _ready_worker()
        time.sleep(1.0)  # its own idle time after the start
        ready = _resident_mb(worker.process.pid)
        flat, triangles = grid(120)
        keys = [drape(flat, amount) for amount in (0.1, 0.3, 0.5, 0.7)]
        sent, answered = _sent_jobs(monkeypatch)
        _asked(SequenceInterpolator(keys, triangles), [(gap, [0.25, 0.5, 0.75]) for gap in range(3)])
        assert "gap" in answered
        deadline = time.monotonic() + 60
        while (worker.jobs or worker.kept is not None) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.2)  # its heap handed back after it said so
        idle = _resident_mb(worker.process.pid)
        assert worker.kept is None and idle - ready < 40, (ready, idle)
        _asked(SequenceInterpolator(keys, triangles), [(gap, [0.25, 0.5, 0.75]) for gap in range(3)])
        assert sent[-1][1]
    finally:
        gap_processes.shut_down()


def test_a_worker_that_hangs_is_ended_and_its_gaps_computed_here(monkeypatch, tmp_path):
    """The worker hangs in gap 3 (a pause of 60 s) while the caller waits for it with no call left to
    take back: after HANG_LEAST (1 s here; the sheet's gaps take milliseconds) without a message the
    caller ends it, warns once (kind ``process``) and computes gaps 3 and 4 itself, one process's poses
    and warnings; no worker is started again in the session (before: the caller waited the 60 s, for
    ever for a worker that never answers). The 1 s holds from the worker's gap 3 begun: before it, the
    job's keys are still written to a worker that may be starved, which HANG_LEAST bounds too (the
    write's rule, whose warning is another; a worker stopped 3 s after its job: failed 1 of 1). The
    wait is HANG_LEAST alone (HANG_GAPS 0): HANG_GAPS times the caller's slowest gap, milliseconds on
    an idle machine, was 1.6 s on one loaded core, and the caller waited 48.6 s."""
    try:
        sequence, shared, _, worker = _slowed_at_gap_3(monkeypatch, tmp_path, 60.0, 3)
        _begun(worker, 3)  # the job written, the worker in its pause: nothing more is written to it
        monkeypatch.setattr(gap_processes, "HANG_LEAST", 1.0)
        monkeypatch.setattr(gap_processes, "HANG_GAPS", 0)
        began = time.monotonic()
        shared += _asked(sequence, [(3, SIXTEENTHS), (4, SIXTEENTHS)])
        waited = time.monotonic() - began
        ended = worker.process.wait(timeout=10)
    finally:
        gap_processes.shut_down()
    assert waited < 45.0 and ended != 0  # before the worker's 60 s pause ends (1 s and its two gaps here)
    hung = [told for _, said in shared for told in said if told[1] == "process"]
    assert len(hung) == 1 and "second process sent nothing" in hung[0][0]
    shared[3] = (shared[3][0], [told for told in shared[3][1] if told[1] != "process"])
    _same(shared, _one_process([(gap, SIXTEENTHS) for gap in range(5)], monkeypatch))
    assert gap_processes._unstartable and not gap_processes.start_worker(150, 5)


def test_a_one_gap_part_starts_no_worker(monkeypatch, tmp_path):
    """A sequence whose caller asks one gap (a farm's one-gap chunk: ``iter_retime`` over one gap of
    many, or a plan of one call) starts no worker; a plan of two calls does (before: the sequence
    started one when built, 0.24–0.26 s of CPU for nothing). ``python -m core retime --chunk`` of one gap
    starts none either, and writes the file one process writes."""
    from core import __main__ as command
    from core.obj_file import write_obj
    from core.point_cache import write_pc2

    gap_processes.shut_down()
    sequence = SequenceInterpolator(KEYS, TRIANGLES)
    sequence.will_ask([(2, SIXTEENTHS)])
    sequence.poses(2, SIXTEENTHS, ahead=False)
    assert gap_processes._worker is None
    samples = np.array(KEYS)
    assert retime.retime(samples, TRIANGLES, step=1, speed=0.5, gaps=range(1, 2)).shape[0] >= 1
    assert gap_processes._worker is None
    cache = write_pc2(tmp_path / "in.pc2", samples, start=1.0)
    topology = write_obj(tmp_path / "sheet.obj", KEYS[0], TRIANGLES)
    arguments = ["retime", str(cache), "--topology", str(topology), "--step", "1", "--speed", "0.4", "-q",
                 "--chunk", "2/5"]
    assert command.main([*arguments, "-o", str(tmp_path / "shared.pc2")]) == 0
    assert gap_processes._worker is None
    with monkeypatch.context() as patch:
        patch.setattr(concurrency, "USE_PROCESSES", False)
        assert command.main([*arguments, "-o", str(tmp_path / "alone.pc2")]) == 0
    assert (tmp_path / "shared.pc2").read_bytes() == (tmp_path / "alone.pc2").read_bytes()
    SequenceInterpolator(KEYS, TRIANGLES).will_ask([(1, SIXTEENTHS), (2, SIXTEENTHS)])
    assert gap_processes._worker is not None
    gap_processes.shut_down()


def test_the_worker_opens_no_console_window_on_windows(monkeypatch):
    """On Windows the worker is created with CREATE_NO_WINDOW (a console program started from Blender's
    window would open a console of its own); elsewhere with no creation flags (which POSIX refuses)."""
    flags = []

    def recorded(command, **options):
        flags.append(options.get("creationflags"))
        raise OSError("recorded, not started")

    monkeypatch.setattr(gap_processes.subprocess, "Popen", recorded)
    for platform in ("win32", "linux"):
        with monkeypatch.context() as patch:
            patch.setattr(sys, "platform", platform)
            with pytest.raises(OSError, match="recorded"):
                gap_processes._Worker()
    assert flags == [0x08000000, 0]
    assert getattr(subprocess, "CREATE_NO_WINDOW", 0x08000000) == gap_processes.WINDOWLESS


@pytest.mark.skipif(not hasattr(signal, "SIGSTOP"), reason="no SIGSTOP on this system")
def test_a_worker_stopped_while_a_job_is_written_is_ended_and_its_gaps_computed_here(monkeypatch):
    """The worker is stopped (SIGSTOP: a job controller, a debugger; a machine swapping is alike) as it
    waits for a job: the caller's write of the keys (4 × 6,400 vertices, 0.9 MB, far past a pipe's
    64 kB) found the pipe full and waited for ever, a headless script with it (the caller's wait for
    results is bounded, its write was not). After HANG_LEAST (1 s here) with nothing taken the caller
    ends the worker, warns once (kind ``process``), computes every gap itself (one process's poses and
    warnings) and starts no worker again in the session."""
    monkeypatch.setattr(gap_processes, "HANG_LEAST", 1.0)
    gap_processes.shut_down()
    flat, triangles = grid(80)
    keys = [drape(flat, amount) for amount in (0.1, 0.3, 0.5, 0.7)]
    requests = [(gap, [0.25, 0.5, 0.75]) for gap in range(3)]
    worker = _ready_worker()
    shared = []
    caller = threading.Thread(target=lambda: shared.extend(_asked(SequenceInterpolator(keys, triangles), requests)),
                              daemon=True)
    worker.process.send_signal(signal.SIGSTOP)
    try:
        caller.start()
        caller.join(timeout=60)
        hung = caller.is_alive()
    finally:
        worker.process.send_signal(signal.SIGCONT)  # before: the write goes on, and the caller with it
        caller.join(timeout=60)
        gap_processes.shut_down()
    assert not hung, "the caller still writing to the stopped worker after 60 s"
    assert worker.process.poll() is not None and not worker.alive
    warned = [told for _, said in shared for told in said if told[1] == "process"]
    assert len(warned) == 1 and "took nothing this process sent it for" in warned[0][0]
    with monkeypatch.context() as patch:
        patch.setattr(concurrency, "USE_PROCESSES", False)
        alone = _asked(SequenceInterpolator(keys, triangles), requests)
    _same([(poses, [told for told in said if told[1] != "process"]) for poses, said in shared], alone)
    assert gap_processes._unstartable and not gap_processes.start_worker(len(flat), 3)


class _FakeProcess:
    """A worker process as :meth:`gap_processes._Worker._send` sees it: its input ``stdin``; ``kill``
    noted (``killed``) and, as a real kill does, ending whatever waits on it."""

    def __init__(self, stdin):
        self.stdin, self.killed = stdin, threading.Event()

    def kill(self):
        self.killed.set()


def _fake_worker(stdin) -> gap_processes._Worker:
    worker = gap_processes._Worker.__new__(gap_processes._Worker)  # no process spawned: its input is faked
    worker.process, worker.alive, worker.jobs = _FakeProcess(stdin), True, {}
    worker.condition, worker._write_lock = threading.Condition(), threading.Lock()
    return worker


def test_a_worker_reading_a_large_job_slowly_but_steadily_is_not_ended(monkeypatch):
    """A worker that takes a 2 MB key a pipe's worth (64 kB) every 30 ms (a farm node swapping) is
    reading: it must not be ended as hung after HANG_LEAST (0.3 s here) although the whole key takes
    1 s. Before, a key was noted taken only once all of it was (one write of 2 MB): the worker was
    killed, with a warning, and its gaps lost to it. The bytes it gets are the message's pickle."""
    monkeypatch.setattr(gap_processes, "HANG_LEAST", 0.3)

    class Slow:
        def __init__(self):
            self.got = bytearray()

        def write(self, data):
            time.sleep(0.03 * memoryview(data).nbytes / 65536)
            self.got += bytes(data)
            return memoryview(data).nbytes

        def flush(self):
            pass

    stream = Slow()
    worker = _fake_worker(stream)
    message = ("job", 7, np.arange(2**18, dtype=np.float64))  # 2 MB
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        assert worker._send(message)
    assert not worker.process.killed.is_set() and worker.alive
    assert bytes(stream.got) == pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)


def test_a_worker_killed_as_its_message_was_taken_is_told_not_taken_as_sent(monkeypatch):
    """The watch ends a worker that took nothing for HANG_LEAST (0.2 s here) just as the message's last
    part goes through (the flush returns once the kill has come). Before, the write had not failed, so
    the caller counted the message sent and waited on a killed worker: no warning, and a worker started
    again later. Now the kill is always told: not sent, one warning (kind ``process``), none again."""
    monkeypatch.setattr(gap_processes, "HANG_LEAST", 0.2)
    monkeypatch.setattr(gap_processes, "_unstartable", False)

    class TakenAtTheKill:
        def write(self, data):
            return memoryview(data).nbytes

        def flush(self):
            assert worker.process.killed.wait(5.0)

    worker = _fake_worker(TakenAtTheKill())
    with pytest.warns(ShapeDifferenceWarning, match="took nothing this process sent it for") as told:
        assert not worker._send(("job", 7, np.zeros(10)))
    assert [warning.message.kind for warning in told] == ["process"]
    assert not worker.alive and gap_processes._unstartable


#: Run in the worker before its boot (the test below): threadpoolctl's look-up of the BLAS libraries
#: (before threadpoolctl 3.7 in a callback glibc's ``dl_iterate_phdr`` runs holding the loader's lock),
#: held until another thread of the worker is about to load a compiled module (at once where the worker
#: has no other thread, as when the look-up is made as it imports the core, or CHOLMOD's library is
#: loaded already; at most 60 s).
HELD_LOOKUP = (
    "import sys, threading, time, threadpoolctl\n"
    "_make = threadpoolctl.ThreadpoolController._make_controller_from_path\n"
    "def _loading():\n"
    "    for ident, frame in sys._current_frames().items():\n"
    "        while ident != threading.get_ident() and frame is not None:\n"
    "            if frame.f_code.co_name == 'create_module' and 'importlib' in frame.f_code.co_filename:\n"
    "                return True\n"
    "            frame = frame.f_back\n"
    "    return False\n"
    "def _held(self, filepath):\n"
    "    deadline = time.monotonic() + 60\n"
    "    while len(sys._current_frames()) > 1 and 'cholespy._cholespy_core' not in sys.modules \\\n"
    "            and time.monotonic() < deadline:\n"
    "        if _loading():\n"
    "            time.sleep(0.5)\n"
    "            break\n"
    "        time.sleep(0.01)\n"
    "    return _make(self, filepath)\n"
    "threadpoolctl.ThreadpoolController._make_controller_from_path = _held\n"
)


def test_the_worker_loads_no_library_in_its_reader_while_it_looks_its_blas_up(monkeypatch):
    """The worker's reader thread takes the caller's orderings (CHOLMOD's library loaded at the first:
    cholespy imported). Loaded while threadpoolctl before 3.7 makes its view of the BLAS libraries (a
    Python callback run by glibc under the loader's lock), each waits for the other's lock for ever,
    and the worker is silent (ended as hung, the second core lost for the session). The look-up is
    made as the worker imports the core, before its reader exists (core.concurrency), and CHOLMOD's
    library is loaded before the reader starts; held here until another thread is about to load a
    library (not held where the worker has no other thread then): the worker still answers its job,
    no ``process`` warning, the same in-betweens as one process."""
    from core import sparse_cholesky

    if sparse_cholesky._direct_library() is None:
        pytest.skip("CHOLMOD not called directly: no orderings sent, no library loaded by the reader")
    assert hasattr(__import__("threadpoolctl").ThreadpoolController, "_make_controller_from_path")
    gap_processes.shut_down()
    monkeypatch.setattr(gap_processes, "BOOT", HELD_LOOKUP + gap_processes.BOOT)
    monkeypatch.setattr(gap_processes, "HANG_LEAST", 20.0)
    given, _ = _counted_jobs(monkeypatch)
    worker = _ready_worker()
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    shared = _asked(SequenceInterpolator(KEYS, TRIANGLES), requests)  # a worker ended says so among these warnings
    assert given and worker.alive and gap_processes._worker is worker
    _same(shared, _one_process(requests, monkeypatch))
    gap_processes.shut_down()


def test_the_workers_build_takes_the_keys_as_the_caller_checked_them(monkeypatch):
    """The worker builds the caller's sequence from the keys, triangles and options the caller's
    constructor checked and sent (``_worker_arguments``) without checking the keys again
    (``core.gap_worker.CallerSequence``): built with every pose check refusing, it is the caller's
    sequence to the bit, each gap's poses and warnings (the spinning sheet warns of its last two gaps)."""
    from core import gap_worker, validation

    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    keys, triangles, options = SequenceInterpolator(KEYS, TRIANGLES)._worker_arguments  # no worker started yet

    def refused(*args, **kwargs):
        raise AssertionError("a key checked again")

    with monkeypatch.context() as patch:
        patch.setattr(concurrency, "USE_PROCESSES", False)  # as in the worker: its sequences share no gaps
        with monkeypatch.context() as checks:
            checks.setattr(validation, "check_pose", refused)
            checks.setattr(validation, "check_key_poses", refused)
            built = gap_worker.CallerSequence(keys, triangles, **options)
        shared = _asked(built, requests)
    _same(shared, _one_process(requests, monkeypatch))


@pytest.mark.parametrize("form", ["float32", "lists", "fortran_stack"])
def test_keys_in_any_accepted_form_reach_the_workers_unchecked_build_as_checked(form, monkeypatch):
    """The worker takes the keys it is sent as checked (``core.gap_worker.CallerSequence``), so the
    caller sends its checked copies, float64 ``(n, 3)`` C-contiguous, whatever form the user gave:
    keys given as float32 arrays, nested lists or a Fortran-ordered ``(K, n, 3)`` stack. The worker
    builds its sequence and begins its gaps (none answered ``broken`` and left to the caller), and
    every pose and warning is one process's of the same keys to the bit."""
    worker = _ready_worker()
    keys = {"float32": [key.astype(np.float32) for key in KEYS], "lists": [key.tolist() for key in KEYS],
            "fortran_stack": np.asfortranarray(np.stack(KEYS))}[form]
    jobs, submit = [], gap_processes._Worker.submit

    def kept_submit(self, job, *arguments):
        jobs.append(job)
        return submit(self, job, *arguments)

    monkeypatch.setattr(gap_processes._Worker, "submit", kept_submit)
    requests = [(gap, SIXTEENTHS) for gap in range(5)]
    sequence = SequenceInterpolator(keys, TRIANGLES)
    assert all(type(key) is np.ndarray and key.dtype == np.float64 and key.flags.c_contiguous and
               key.shape == KEYS[0].shape for key in sequence._worker_arguments[0])
    shared = _asked(sequence, requests, after_first=lambda: _begun(worker, 3))
    assert jobs and any(job.begun for job in jobs)  # the worker built the sequence and computed gaps of it
    _same(shared, _one_process(requests, monkeypatch, keys=keys))


def test_three_gaps_the_contested_last_goes_to_the_caller_free_first(monkeypatch, tmp_path):
    """Three gaps in order (an odd count: the caller's two against the worker's one left the worker
    idle half the caller's time): the worker is given the later two, the last contested; its gap 1 is
    paused (in its core) until the caller, done with gap 0 and waiting for gap 1, has taken gap 2 back
    though it is the only call not begun. Every pose and warning is one process's, to the bit. Failed
    on the old code: the worker was given gap 2 alone (``given`` [[2]])."""
    gap_processes.shut_down()
    released = tmp_path / "released"
    monkeypatch.setattr(gap_processes, "_FOLDER", str(_patched_core(tmp_path, 1, _paused_until(released))))
    taken_back, take_back = [], gap_processes.GapProcesses._take_back

    def counted(self, call, factors):
        taken_back.append(call[0])
        try:
            return take_back(self, call, factors)
        finally:
            released.touch()

    monkeypatch.setattr(gap_processes.GapProcesses, "_take_back", counted)
    requests = [(gap, SIXTEENTHS) for gap in range(3)]
    try:
        worker = _ready_worker()
        given, taken = _counted_jobs(monkeypatch)
        shared = _asked(SequenceInterpolator(KEYS[:4], TRIANGLES), requests, after_first=lambda: _begun(worker, 1))
        assert given == [[1, 2]] and taken == [1] and taken_back == [2]
    finally:
        gap_processes.shut_down()
    _same(shared, _one_process(requests, monkeypatch, keys=KEYS[:4]))
