"""The factor of core/sparse_cholesky.py (CHOLMOD through cholespy's extension, called directly where it
can be, or SuperLU without it) and the threads of core/concurrency.py: same solutions, same in-betweens."""

from __future__ import annotations

import builtins
import ctypes
import os
import threading
import time
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import core.concurrency as concurrency
import core.inbetween_threads as inbetween_threads
from core.concurrency import concurrently
from core.sequence_inbetweens import SequenceInterpolator
from core.sparse_cholesky import SPDFactor

from meshes import grid


def _normal_matrix(weight):
    """Graph Laplacian of a 15 × 12 grid plus ``weight`` on the diagonal (the in-betweens' matrix)."""
    _, triangles = grid(15, 12)
    i, j = triangles.ravel(), triangles[:, [1, 2, 0]].ravel()
    n = triangles.max() + 1
    rows = np.arange(i.size)
    incidence = sp.csr_matrix((np.r_[-np.ones(i.size), np.ones(i.size)], (np.r_[rows, rows], np.r_[i, j])),
                              shape=(i.size, n))
    return (incidence.T @ incidence + weight * sp.identity(n)).tocsc()


@pytest.fixture(params=["installed", "SuperLU"])
def backend(request, monkeypatch):
    if request.param == "SuperLU":
        real_import = builtins.__import__

        def no_cholespy(name, *args, **kwargs):
            if name == "cholespy":
                raise ImportError("cholespy hidden by the test")
            return real_import(name, *args, **kwargs)

        monkeypatch.setattr(builtins, "__import__", no_cholespy)
    return request.param


@pytest.mark.parametrize("weight", [1e-7, 1e-2, 1e3])
def test_solves_agree_with_a_direct_solve(backend, weight):
    matrix = _normal_matrix(weight)
    factor = SPDFactor(matrix)
    if backend == "SuperLU":
        assert factor.backend == "SuperLU"
    rng = np.random.default_rng(0)
    rhs = rng.standard_normal((matrix.shape[0], 3))
    reference = spla.spsolve(matrix, rhs)
    scale = np.abs(reference).max()
    for b, expected in ((rhs, reference), (np.asfortranarray(rhs), reference), (rhs[:, 1].copy(), reference[:, 1])):
        x = factor.solve(b)
        assert x.shape == b.shape
        # backward stable factorizations: error ~ condition number (≤ 1e8 here) × machine epsilon
        assert np.abs(x - expected).max() <= 1e-6 * scale
        # and a residual of round-off size: a small multiple of ε ‖A‖ ‖x‖
        bound = 1e3 * np.finfo(float).eps * spla.norm(matrix, np.inf) * np.abs(x).max()
        assert np.abs(matrix @ x - b).max() <= bound


def _sheet_matrix(side, weight):
    """The in-betweens' normal matrix (graph Laplacian plus ``weight`` on the diagonal) of a ``side``
    × ``side`` grid sheet."""
    _, triangles = grid(side, side)
    i, j = triangles.ravel(), triangles[:, [1, 2, 0]].ravel()
    n = triangles.max() + 1
    rows = np.arange(i.size)
    incidence = sp.csr_matrix((np.r_[-np.ones(i.size), np.ones(i.size)], (np.r_[rows, rows], np.r_[i, j])),
                              shape=(i.size, n))
    return (incidence.T @ incidence + sp.diags(weight * (1.0 + np.arange(n) % 7))).tocsc()


def _direct_library():
    """cholespy, core.cholmod_direct and its library; the test skipped where CHOLMOD's functions
    cannot be called directly."""
    cholespy = pytest.importorskip("cholespy")
    from core import cholmod_direct

    lib = cholmod_direct.library(cholespy)
    if lib is None:
        pytest.skip("CHOLMOD's functions are not exported by this platform's cholespy")
    return cholespy, cholmod_direct, lib


def _cholespys_solution(cholespy, matrix, rhs):
    """cholespy's own solver's solution of ``matrix @ x = rhs`` (the matrix ordered anew)."""
    coo = matrix.tocoo()
    theirs = cholespy.CholeskySolverD(matrix.shape[0], coo.row.astype(np.int32), coo.col.astype(np.int32),
                                      coo.data.astype(np.float64), cholespy.MatrixType.COO)
    expected = np.empty_like(rhs)
    theirs.solve(rhs, expected)
    return expected


def test_cholmod_called_directly_gives_cholespys_bits():
    """Where CHOLMOD is called through the functions cholespy's extension exports (without the
    global lock), the solutions are bitwise those of cholespy's own solver on the same matrix: the
    in-betweens do not change with the way in."""
    cholespy, cholmod_direct, _ = _direct_library()
    rng = np.random.default_rng(3)
    for side, weight in ((15, 1e-2), (60, 0.1), (90, 1e-3)):
        matrix = _sheet_matrix(side, weight)
        factor = SPDFactor(matrix)
        assert factor._direct is not None
        coo = matrix.tocoo()
        theirs = cholespy.CholeskySolverD(matrix.shape[0], coo.row.astype(np.int32), coo.col.astype(np.int32),
                                          coo.data.astype(np.float64), cholespy.MatrixType.COO)
        for rhs in (rng.standard_normal((matrix.shape[0], 3)), rng.standard_normal(matrix.shape[0])):
            expected = np.empty_like(rhs)
            theirs.solve(rhs, expected)
            assert np.array_equal(factor.solve(rhs), expected)
            assert np.array_equal(factor.solve(np.asfortranarray(rhs)), expected)


def test_a_kept_analysis_gives_the_bits_of_a_factorization_made_anew():
    """A second anchor weight on the same mesh copies the first one's ordering and symbolic analysis
    (its pattern is the same) and factors numerically alone: the solutions are bitwise those of
    cholespy's solver, which orders the matrix anew."""
    cholespy, cholmod_direct, _ = _direct_library()
    rng = np.random.default_rng(5)
    first = SPDFactor(_sheet_matrix(70, 0.1))
    for weight in (1e-3, 0.03, 10.0):
        matrix = _sheet_matrix(70, weight)
        factor = SPDFactor(matrix)
        assert not factor._direct.analysed_anew
        rhs = rng.standard_normal((matrix.shape[0], 3))
        assert np.array_equal(factor.solve(rhs), _cholespys_solution(cholespy, matrix, rhs))
    assert first.solve(np.ones(first.shape[0])).shape == (first.shape[0],)  # the first factor still solves


def _in_another_process(monkeypatch, cholmod_direct):
    """This process's kept analyses and given orderings set aside, as a fresh process has none."""
    monkeypatch.setattr(cholmod_direct, "_analyses", [])
    monkeypatch.setattr(cholmod_direct, "_given", {})


def test_an_ordering_another_process_made_gives_the_bits_of_one_made_here(monkeypatch):
    """A mesh's ordering made in one process (the caller's, :func:`orderings`) and taken in another (the
    gap worker's, :func:`take_orderings`): that process's first factor of the pattern is not ordered
    again, and its solutions are bitwise those of cholespy's solver, which orders the matrix anew, for
    every anchor weight (before: no ordering could be handed over; the worker ordered it again)."""
    cholespy, cholmod_direct, _ = _direct_library()
    from core.sparse_cholesky import orderings, take_orderings

    _in_another_process(monkeypatch, cholmod_direct)
    sent = orderings(_sheet_matrix(70, 1.0))  # made here without a factor, as the caller does at the hand-over
    assert len(sent) == 1 and sorted(next(iter(sent.values()))) == list(range(70 * 70))
    _in_another_process(monkeypatch, cholmod_direct)
    take_orderings(sent)
    rng = np.random.default_rng(8)
    for weight, given in ((1e-3, True), (0.1, False)):  # the second weight copies the first one's analysis
        matrix = _sheet_matrix(70, weight)
        factor = SPDFactor(matrix)
        assert factor._direct.ordering_given == given and factor._direct.analysed_anew == given
        rhs = rng.standard_normal((matrix.shape[0], 3))
        assert np.array_equal(factor.solve(rhs), _cholespys_solution(cholespy, matrix, rhs))


def test_an_ordering_of_another_pattern_or_one_cholmod_would_change_is_not_taken(monkeypatch):
    """An ordering handed over is taken only by its own pattern's first analysis, and only as CHOLMOD
    keeps it: another mesh orders its matrix here, and a permutation under the right pattern that CHOLMOD's
    postordering would change (not one its analysis made) is dropped for the ordering made here: the
    solutions stay cholespy's to the bit."""
    cholespy, cholmod_direct, _ = _direct_library()
    from core.sparse_cholesky import orderings, take_orderings

    _in_another_process(monkeypatch, cholmod_direct)
    sent = orderings(_sheet_matrix(40, 1.0))
    _in_another_process(monkeypatch, cholmod_direct)
    take_orderings(sent)
    assert not SPDFactor(_sheet_matrix(41, 0.1))._direct.ordering_given  # another pattern
    digest = next(iter(sent))
    shuffled = np.random.default_rng(2).permutation(40 * 40).astype(np.int32)
    for wrong in (shuffled, np.zeros(40 * 40, dtype=np.int32)):  # not kept as given; not a permutation
        monkeypatch.setattr(cholmod_direct, "_analyses", [])
        take_orderings({digest: wrong})
        factor = SPDFactor(_sheet_matrix(40, 0.1))
        assert factor._direct.analysed_anew and not factor._direct.ordering_given and not cholmod_direct._given
    rhs = np.random.default_rng(4).standard_normal((40 * 40, 3))
    assert np.array_equal(factor.solve(rhs), _cholespys_solution(cholespy, _sheet_matrix(40, 0.1), rhs))


def test_a_matrix_that_is_not_positive_definite_is_refused_in_numpys_terms():
    pytest.importorskip("cholespy")
    matrix = (_sheet_matrix(15, 1e-2) - 20.0 * sp.identity(225)).tocsc()
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite.*225 unknowns"):
        SPDFactor(matrix)


def test_a_factorization_lets_other_threads_run():
    """Python code in another thread keeps running while a factor is made (cholespy's binding
    holds the global lock through its factorization: the other thread stood still for all of it).
    The longest pause between the other thread's steps is compared with the factorization's own
    time in that thread."""
    _direct_library()
    matrix = _sheet_matrix(120, 1e-2)  # 14,400 unknowns: a factorization of ~0.1 s
    started, done, spans = threading.Event(), threading.Event(), []

    def factorize():
        started.set()
        begin = time.perf_counter()
        SPDFactor(matrix)
        spans.append(time.perf_counter() - begin)
        done.set()

    worker = threading.Thread(target=factorize)
    worker.start()
    started.wait()
    last, longest = time.perf_counter(), 0.0
    while not done.is_set():
        now = time.perf_counter()
        longest, last = max(longest, now - last), now
    worker.join()
    assert longest < 0.5 * spans[0]


def test_a_factorization_cholmod_could_not_finish_is_refused():
    """``cholmod_factorize`` returns FALSE where it fails (out of memory), leaving the copied
    symbolic factor, whose ``minor`` reads as positive definite: the factor is refused then, not
    kept to fail (or solve with nothing) later."""
    _, cholmod_direct, lib = _direct_library()

    class Failing:  # CHOLMOD with a factorization that runs out of memory
        def __getattr__(self, name):
            return getattr(lib, name)

        @staticmethod
        def cholmod_factorize(a, factor, common):
            return 0

    with pytest.raises(MemoryError, match="could not factor a matrix of 225 unknowns"):
        cholmod_direct.CholmodFactor(Failing(), _sheet_matrix(15, 1e-2))


def test_compressed_columns_past_32_bit_indices_are_refused_not_wrapped():
    """CHOLMOD's ``int`` interface reads 32-bit column pointers: a matrix of 2³¹ nonzeros (its arrays
    broadcast, nothing of that size allocated) cast unchecked wraps its last pointer to −2³¹, an offset
    before the matrix; it is refused with the counts instead. A matrix that fits keeps its indices."""
    from core.cholmod_direct import int32_columns
    from core.errors import MeshError

    nonzeros = 2 ** 31
    huge = sp.csc_matrix((np.broadcast_to(1.0, (nonzeros,)), np.broadcast_to(np.int64(0), (nonzeros,)),
                          np.array([0, nonzeros], dtype=np.int64)), shape=(1, 1))
    assert huge.indptr.astype(np.int32)[-1] < 0  # what the unchecked cast handed CHOLMOD
    with pytest.raises(MeshError, match="1 unknowns has 2,147,483,648 nonzeros, and the sparse factorizations "
                                        "index at most 2,147,483,647"):
        int32_columns(huge)
    matrix = _normal_matrix(1e-2)
    indptr, indices = int32_columns(matrix)
    assert indptr.dtype == indices.dtype == np.int32
    assert np.array_equal(indptr, matrix.indptr) and np.array_equal(indices, matrix.indices)


def test_coordinates_past_32_bit_indices_are_refused_not_wrapped_through_cholespys_binding(monkeypatch):
    """Where CHOLMOD is reached through cholespy's binding (its functions not readable directly), the
    matrix goes as coordinates in 32-bit integers: a row past 2³¹ − 1 (a system of 2³¹ + 1 unknowns,
    one nonzero) cast unchecked wrapped to −2³¹ and reached the binding (before: handed to it); it is
    refused with the counts, as are 2³¹ nonzeros (their arrays broadcast, nothing of that size
    allocated), before anything is cast or factored. A matrix that fits factors as before."""
    cholespy, cholmod_direct, _ = _direct_library()
    from core.errors import MeshError

    handed = []

    class Binding:  # cholespy's solver, recording what it is handed instead of factoring it
        def __init__(self, n, rows, columns, data, kind):
            handed.append(rows)

    monkeypatch.setattr(cholmod_direct, "_library", False)
    monkeypatch.setattr(cholespy, "CholeskySolverD", Binding)
    last = 2 ** 31
    beyond = sp.coo_matrix(([1.0], ([last], [last])), shape=(last + 1, last + 1))
    assert np.array_equal(beyond.row.astype(np.int32), [-last])  # what the unchecked cast handed the binding
    with pytest.raises(MeshError, match="2,147,483,649 unknowns has 1 nonzeros, and the sparse factorizations "
                                        "index at most 2,147,483,647"):
        SPDFactor(beyond)
    many = sp.coo_matrix(([1.0], ([0], [0])), shape=(1, 1))
    many.coords, many.data = (np.broadcast_to(np.int64(0), (last,)),) * 2, np.broadcast_to(1.0, (last,))
    with pytest.raises(MeshError, match="1 unknowns has 2,147,483,648 nonzeros"):
        SPDFactor(many)
    assert handed == []
    monkeypatch.undo()
    monkeypatch.setattr(cholmod_direct, "_library", False)
    matrix, rhs = _sheet_matrix(15, 1e-2), np.ones(225)
    np.testing.assert_allclose(matrix @ SPDFactor(matrix).solve(rhs), rhs, atol=1e-10)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_child_forked_while_another_thread_factors_can_factor():
    """A process forked while another thread holds the factorization lock (multiprocessing, a
    farm's workers) factors and solves in the child: the child gets new locks instead of one no
    thread of it will ever release."""
    _, cholmod_direct, _ = _direct_library()
    matrix, rhs = _sheet_matrix(15, 1e-2), np.ones(225)
    expected = SPDFactor(matrix).solve(rhs)
    held, release = threading.Event(), threading.Event()

    def factoring():  # holds the lock as a factorization in this thread would
        with cholmod_direct._factor_lock:
            held.set()
            release.wait()

    other = threading.Thread(target=factoring)
    other.start()
    held.wait()
    with warnings.catch_warnings():  # Python 3.12+ warns of a fork beside threads: the case tested
        warnings.simplefilter("ignore", DeprecationWarning)
        child = os.fork()
    if child == 0:  # the child: exit status 0 if it factors and solves to the same bits
        status = 1
        try:
            status = 0 if np.array_equal(SPDFactor(matrix).solve(rhs), expected) else 2
        finally:
            os._exit(status)
    release.set()
    other.join()
    for _ in range(300):  # up to 30 s: the child's factorization takes milliseconds
        done, status = os.waitpid(child, os.WNOHANG)
        if done:
            break
        time.sleep(0.1)
    else:
        os.kill(child, 9)
        os.waitpid(child, 0)
        pytest.fail("the forked child waited for a lock no thread of it holds")
    assert os.waitstatus_to_exitcode(status) == 0


_SOLVE_AFTER_EXIT_FINALIZERS = """
import sys, weakref
import numpy as np
sys.path[:0] = sys.argv[1:]
from core.sparse_cholesky import SPDFactor
from test_sparse_cholesky import _sheet_matrix
factor = SPDFactor(_sheet_matrix(100, 1e-2))
rhs = np.ones((factor.shape[0], 3))
expected = factor.solve(rhs)
weakref.finalize._exitfunc()  # what the interpreter's exit runs, here while the factor is in use
sys.exit(0 if np.array_equal(factor.solve(rhs), expected) else 3)
"""


def test_a_factor_still_in_use_at_exit_is_not_freed_under_its_thread():
    """At exit the interpreter runs the finalizers of objects still alive before daemon threads
    stop: a thread still solving (a user's daemon thread, an interrupted run) found its CHOLMOD
    factor freed under it, a crash at exit (a daemon thread solving at exit: 3 segmentation faults
    in 6 runs). The factors' memory goes with the process instead; here the exit's finalizers are
    run, then the factor solves to the same bits (a crash or other bits before)."""
    import subprocess
    import sys

    _direct_library()
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    run = subprocess.run([sys.executable, "-c", _SOLVE_AFTER_EXIT_FINALIZERS, root, os.path.dirname(__file__)],
                         capture_output=True, timeout=120)
    assert run.returncode == 0, run.stderr.decode()[-2000:]


def test_a_cholmod_the_module_cannot_read_falls_back_to_cholespys_binding(monkeypatch):
    """Another CHOLMOD's ``cholmod_common`` layout (simulated: every field one int further) or a
    function the extension does not export leaves the direct calls unused; SPDFactor then factors
    through cholespy's binding, to the same bits."""
    cholespy, cholmod_direct, _ = _direct_library()
    matrix = _sheet_matrix(30, 0.1)
    rhs = np.random.default_rng(7).standard_normal((900, 3))
    direct = SPDFactor(matrix).solve(rhs)

    class Shifted(ctypes.Structure):
        _fields_ = [("padding", ctypes.c_int)] + cholmod_direct._Common._fields_

    with monkeypatch.context() as patch:
        patch.setattr(cholmod_direct, "_Common", Shifted)
        assert cholmod_direct._load(cholespy) is None

    def unexported(lib):
        raise AttributeError("cholmod_copy_factor")

    with monkeypatch.context() as patch:
        patch.setattr(cholmod_direct, "_typed", unexported)
        assert cholmod_direct._load(cholespy) is None
    monkeypatch.setattr(cholmod_direct, "_library", False)
    factor = SPDFactor(matrix)
    assert factor._direct is None and factor._cholmod is not None
    assert np.array_equal(factor.solve(rhs), direct)


def test_concurrently_keeps_order_and_raises(monkeypatch, own_pool):
    monkeypatch.setattr(concurrency, "available_cores", lambda: 2)
    assert concurrently(lambda k: k * k, range(7)) == [k * k for k in range(7)]

    def fails(k):
        if k == 3:
            raise ValueError("piece 3")
        return k

    with pytest.raises(ValueError, match="piece 3"):
        concurrently(fails, range(5))


def test_inbetweens_do_not_depend_on_the_threads(monkeypatch, own_pool):
    """Solved and predicted in-betweens of a sequence are the same in one thread and in several
    (to the round-off of a BLAS that may sum in another order when it is limited to one thread)."""
    flat, triangles = grid(24, 16, size=1.0)
    times = np.linspace(0.0, 1.0, 4)
    keys = [np.c_[flat[:, 0], flat[:, 1] * np.cos(1.2 * t), flat[:, 1] * np.sin(1.2 * t) - 0.4 * t * t]
            + 0.05 * np.sin(3 * flat[:, [0]] + t) for t in times]
    factors = np.arange(1, 8) / 8
    monkeypatch.setattr(inbetween_threads, "CONCURRENT_VERTICES", 0)  # this small mesh in threads too
    results = {}
    for cores in (1, 2):
        monkeypatch.setattr(concurrency, "available_cores", lambda cores=cores: cores)
        seq = SequenceInterpolator(keys, triangles)
        results[cores] = np.array([seq.poses(k, factors) for k in range(len(seq))])
    np.testing.assert_allclose(results[2], results[1], rtol=0, atol=1e-12 * np.abs(results[1]).max())
    assert np.isfinite(results[2]).all()


def test_concurrently_nested_in_every_thread_finishes(monkeypatch, own_pool):
    # pieces that hand out pieces of their own, more than there are pool threads: a thread
    # waiting for a piece nobody started does it itself, so the pool cannot deadlock
    monkeypatch.setattr(concurrency, "available_cores", lambda: 2)

    def tree(depth):
        return 1 if depth == 0 else sum(concurrently(tree, [depth - 1] * 3))

    assert tree(4) == 3 ** 4


def test_a_background_piece_nobody_started_is_done_by_its_reader(monkeypatch, own_pool):
    monkeypatch.setattr(concurrency, "available_cores", lambda: 2)
    import threading

    release = threading.Event()
    busy = [concurrency.in_background(release.wait) for _ in range(2)]  # both pool threads held
    queued = concurrency.in_background(threading.get_ident)
    assert concurrency.result(queued, threading.get_ident) == threading.get_ident()
    release.set()
    assert all(concurrency.result(f, release.wait) for f in busy)


@pytest.mark.parametrize("cores", [2, 3])
def test_the_pool_has_a_thread_per_core_the_process_may_run_on_now(monkeypatch, own_pool, cores):
    """Pieces in the background run in as many threads at once as the cores the process may run
    on when they are handed out, whatever count the pool was first made for (a farm's scheduler
    may change a process's CPU affinity; so do the tests here)."""
    import threading

    monkeypatch.setattr(concurrency, "available_cores", lambda: cores)
    together = threading.Barrier(cores)  # passed only by `cores` threads waiting at once
    futures = [concurrency.in_background(together.wait, 10) for _ in range(cores)]
    assert sorted(future.result() for future in futures) == list(range(cores))



def test_pieces_handed_out_while_another_thread_makes_the_pool_again_all_run(monkeypatch, own_pool):
    """A thread handing out pieces (``concurrently``) while another one finds the cores changed
    and makes the pool again (a gap prepared in the background hands out work of its own): every
    piece runs and its result comes back, in order. With the pool taken once and then handed the
    pieces one by one, the piece handed out after the other thread replaced the pool went to the
    pool it had shut down (RuntimeError: cannot schedule new futures after shutdown)."""
    import threading
    from concurrent.futures import ThreadPoolExecutor

    cores = {"count": 2}
    monkeypatch.setattr(concurrency, "available_cores", lambda: cores["count"])
    real_submit, handed, other = ThreadPoolExecutor.submit, [], []

    def submit(pool, function, *arguments, **keywords):
        handed.append(pool)
        if len(handed) == 2:  # between the first piece handed out and the second
            cores["count"] = 3
            other.append(threading.Thread(target=lambda: concurrency.result(concurrency.in_background(int), int)))
            other[0].start()
            other[0].join(timeout=0.5)  # it waits for the pool's lock where this thread holds it
        return real_submit(pool, function, *arguments, **keywords)

    monkeypatch.setattr(ThreadPoolExecutor, "submit", submit)
    assert concurrency.concurrently(lambda i: i * i, range(4)) == [0, 1, 4, 9]
    other[0].join(timeout=10)
    assert not other[0].is_alive() and len(handed) == 4  # the other thread's work was handed out too
