"""Factor once per anchor weight, solve many times: a sparse symmetric positive definite matrix.

The in-betweens solve the same normal matrix (graph Laplacian plus a diagonal anchor) a few times
per pose and factor it once per anchor weight a sequence uses (one to three on the benchmark's
sequences), so the solve is what counts. ``cholespy`` (wheels for Linux, macOS and Windows) runs
CHOLMOD's simplicial LLᵀ after a nested-dissection ordering (METIS) and solves several right-hand
sides per pass over the factor: on the 99,856-vertex sheet three in 13–19 ms, SuperLU's LU in
symmetric mode 31–34 ms (factorizations 0.76–1.01 s against 0.58–0.64 s). About two thirds of a
factorization is that ordering (15,400 vertices: 54 of 72–95 ms), which cholespy's binding
redoes for every weight (it has no separate analysis; called directly, below, CHOLMOD keeps a
pattern's analysis for the next weight); QDLDL's numeric update, CVXOPT's CHOLMOD given a permutation
and SuperLU given one reuse an ordering but solve three right-hand sides 2–3 × slower: on the
benchmark's sequences 1–4 % of the CPU saved where each factor serves few solves, 2–10 % lost
where it serves many (measured in docs/inbetweens.md). Without
``cholespy`` the same matrix is factored by SuperLU with a minimum-degree ordering of ``A + Aᵀ``
and no pivoting; both give the solution to round-off (tests/core/test_sparse_cholesky.py).
CHOLMOD is called through the C functions cholespy's extension exports where they can be
(:mod:`core.cholmod_direct`): the same factor and solutions to the bit, without holding Python's
global lock, which cholespy's binding holds (the in-betweens' other thread stopped meanwhile), and
with a pattern's ordering and symbolic analysis made once for all its weights; through cholespy's
binding elsewhere.
"""

from __future__ import annotations

import atexit
import os
import threading
import weakref

import numpy as np
import scipy.sparse as sp

from . import cholmod_direct

_live: weakref.WeakSet = weakref.WeakSet()  # factors holding a CHOLMOD solver
_factors: weakref.WeakSet = weakref.WeakSet()  # every factor: their solves' locks (see _new_locks_after_fork)


@atexit.register
def _release():
    """Drop the CHOLMOD solvers still held at exit, before the interpreter's teardown (the
    extension module otherwise reports them on stderr as leaked)."""
    for factor in list(_live):
        factor._cholmod = None


def _direct_library():
    """CHOLMOD's library as :mod:`core.cholmod_direct` calls it, or None (no cholespy, or its
    functions not callable directly)."""
    try:
        import cholespy
    except ImportError:
        return None
    return cholmod_direct.library(cholespy)


def orderings(matrix=None) -> dict:
    """The fill-reducing orderings of the patterns factored in this process, ``matrix``'s (n, n; or a
    function of nothing making it, called only where CHOLMOD is called directly) made now where it was
    not (:func:`core.cholmod_direct.orderings`), for another process's :func:`take_orderings`; {}
    where CHOLMOD is not called directly."""
    lib = _direct_library()
    return {} if lib is None else cholmod_direct.orderings(lib, matrix)


def take_orderings(orderings: dict | None) -> None:
    """Factor the patterns of ``orderings`` (another process's :func:`orderings`) here without
    ordering them again: the same factors to the bit (:func:`core.cholmod_direct.take_orderings`)."""
    if orderings and _direct_library() is not None:
        cholmod_direct.take_orderings(orderings)


def load_library() -> None:
    """CHOLMOD's library loaded now (cholespy imported), for a process that will take orderings in
    another thread (:mod:`core.gap_worker`'s reader), which then loads no library."""
    _direct_library()


def _new_locks_after_fork() -> None:
    """In a child process forked from this one (a pipeline's workers forked while a sequence runs):
    a factor another thread was solving with at the fork (a pool thread solving the next gap,
    :mod:`core.sequence_gaps_ahead`) has its lock held by a thread that does not exist here, and the
    child's first solve with it would wait for ever; every factor gets a new one. The factor itself is
    a complete copy (a solve writes only the right-hand sides and solutions it allocates)."""
    for factor in list(_factors):
        factor._lock = threading.Lock()


if hasattr(os, "register_at_fork"):  # not on Windows, which does not fork
    os.register_at_fork(after_in_child=_new_locks_after_fork)


class SPDFactor:
    """The factor of a sparse symmetric positive definite ``matrix`` (n, n); :meth:`solve` takes
    right-hand sides (n,) or (n, k). Safe to share between threads (solves are serialized).
    A matrix CHOLMOD finds not positive definite raises ``numpy.linalg.LinAlgError``; SuperLU
    raises ``RuntimeError`` for an exactly singular one; one whose indices do not fit in 32 bits
    (2³¹ − 1 unknowns or nonzeros) :class:`~core.errors.MeshError` through CHOLMOD."""

    def __init__(self, matrix: sp.spmatrix):
        self.shape = matrix.shape
        self._lock = threading.Lock()
        _factors.add(self)
        try:
            import cholespy
            from cholespy import CholeskySolverD, MatrixType
        except ImportError:  # not bundled for this platform or Python: SuperLU
            from scipy.sparse.linalg import splu

            self._superlu = splu(sp.csc_matrix(matrix), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                 options={"SymmetricMode": True})
            self._cholmod = self._direct = None
            return
        self._superlu = None
        lib = cholmod_direct.library(cholespy)
        if lib is not None:  # CHOLMOD without the global lock
            self._direct, self._cholmod = cholmod_direct.CholmodFactor(lib, matrix), None
            return
        self._direct = None
        coo = sp.coo_matrix(matrix)
        rows, columns = cholmod_direct.int32_coordinates(coo)  # MeshError past 32-bit indices
        try:
            self._cholmod = CholeskySolverD(matrix.shape[0], rows, columns, coo.data.astype(np.float64), MatrixType.COO)
        except ValueError as error:  # cholespy's "Matrix is not positive definite!": NumPy's error for it
            raise np.linalg.LinAlgError(f"{error} (CHOLMOD, {matrix.shape[0]} unknowns)") from error
        _live.add(self)

    @property
    def backend(self) -> str:
        return "SuperLU" if self._superlu is not None else "CHOLMOD"

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """The solution (shape of ``rhs``) of ``matrix @ x = rhs``."""
        if self._superlu is not None:
            return self._superlu.solve(rhs)
        b = np.ascontiguousarray(rhs, dtype=np.float64)
        if self._direct is not None:
            with self._lock:  # CHOLMOD solves in the factor's own workspace
                return self._direct.solve(b)
        x = np.empty_like(b)
        with self._lock:  # cholespy does not say its solves may share a factor concurrently
            self._cholmod.solve(b, x)
        return x
