"""CHOLMOD called directly, without Python's global lock: the factorization and solves of
:class:`core.sparse_cholesky.SPDFactor` through the C functions cholespy's extension exports.

cholespy's own binding holds the global lock through its factorization and its solves (a NumPy
loop in another thread keeps 0–2 % of its rate meanwhile), so the in-betweens' second thread stops
for every factorization (70–80 ms at 15k vertices) and solve. Its extension links CHOLMOD and
exports CHOLMOD's C functions (``cholmod_start``, ``cholmod_analyze``, ``cholmod_factorize``,
``cholmod_solve``, …); ctypes releases the lock around each foreign call, so the same CHOLMOD run
on the same matrix with the same options lets the other thread work (96–97 % of its rate) and
gives the same bits. The options are those cholespy's CPU solver uses: a simplicial ``LLᵀ``
(``supernodal`` = CHOLMOD_SIMPLICIAL, ``final_ll``) after CHOLMOD's nested dissection alone
(``nmethods`` = 1, ``method[0].ordering`` = CHOLMOD_NESDIS; postordered, CHOLMOD's default), each
solve ``cholmod_solve(CHOLMOD_A, …)`` on the right-hand sides as one column-major dense matrix:
solutions bitwise cholespy's (tests/core/test_sparse_cholesky.py; the other option sets tried
differ by 5e-16–8e-15 relative). The ordering and symbolic analysis depend on the matrix's
pattern alone, and the in-betweens factor one pattern (the mesh's) for several anchor weights: the
analysis of a pattern is kept (:class:`_Analysis`, the last :data:`KEPT_ANALYSES` patterns) and a
later factorization of that pattern copies it and runs the numeric factorization alone, the same
bits as an analysis made anew (19 against 74 ms at 15,400 unknowns; the ordering is ~57 % of a
factorization at 100k). A pattern's ordering (the analysis's fill-reducing permutation, postordered)
can be handed to another process (:func:`orderings`, :func:`take_orderings`: the in-betweens' gap
worker, :mod:`core.gap_processes`), whose analysis of that pattern then takes it as given instead of
running the nested dissection again: the same permutation, so the same symbolic and numeric factor
to the bit (23 against 75 ms at 15,400 unknowns). :func:`library` checks that the ``cholmod_common`` layout below
is the linked CHOLMOD's (its documented defaults read back through it) and gives None otherwise
(another platform's or version's extension: cholespy's own binding is used then; cholespy 2.2.0's
Linux and macOS extensions export the functions, its Windows one does not).
Hand-written because no packaged binding does it: cholespy's holds the global lock and analyses
every matrix anew, and another CHOLMOD binding (scikit-sparse) is a second build of CHOLMOD (other
bits) and a second dependency for the extension's zips.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import threading
import weakref

import numpy as np
import scipy.sparse as sp

from .errors import MeshError

_SIZE, _INT, _DOUBLE, _POINTER = ctypes.c_size_t, ctypes.c_int, ctypes.c_double, ctypes.c_void_p
_MAXMETHODS = 9  # CHOLMOD_MAXMETHODS
_SIMPLICIAL, _NESDIS, _REAL, _SOLVE_A = 0, 4, 1, 0  # CHOLMOD_SIMPLICIAL, CHOLMOD_NESDIS, CHOLMOD_REAL, CHOLMOD_A
_GIVEN = 1  # CHOLMOD_GIVEN: the ordering is the permutation passed to cholmod_analyze_p
#: Patterns whose analysis is kept for later factorizations (a sequence factors one pattern, its
#: seams and two poses' blend anchor another few), and orderings another process gave that are held
#: for a first analysis (:func:`take_orderings`).
KEPT_ANALYSES = 4
#: Bytes held for a ``cholmod_common`` (the linked CHOLMOD 3's is under 2 KB past the fields
#: read here; the rest of the struct is CHOLMOD's own, never read from Python).
_COMMON_BYTES = 1 << 16


class _Method(ctypes.Structure):
    """``cholmod_common.method[k]``: one ordering method's statistics and parameters."""
    _fields_ = [("lnz", _DOUBLE), ("fl", _DOUBLE), ("prune_dense", _DOUBLE), ("prune_dense2", _DOUBLE),
                ("nd_oksep", _DOUBLE), ("other1", _DOUBLE * 4), ("nd_small", _SIZE), ("other2", _SIZE * 4),
                ("aggressive", _INT), ("order_for_lu", _INT), ("nd_compress", _INT), ("nd_camd", _INT),
                ("nd_components", _INT), ("ordering", _INT), ("other3", _SIZE * 4)]


class _Common(ctypes.Structure):
    """The leading fields of CHOLMOD 3's ``cholmod_common``, up to ``postorder``."""
    _fields_ = [("dbound", _DOUBLE), ("grow0", _DOUBLE), ("grow1", _DOUBLE), ("grow2", _SIZE), ("maxrank", _SIZE),
                ("supernodal_switch", _DOUBLE), ("supernodal", _INT), ("final_asis", _INT), ("final_super", _INT),
                ("final_ll", _INT), ("final_pack", _INT), ("final_monotonic", _INT), ("final_resymbol", _INT),
                ("zrelax", _DOUBLE * 3), ("nrelax", _SIZE * 3), ("prefer_zomplex", _INT), ("prefer_upper", _INT),
                ("quick_return_if_not_posdef", _INT), ("prefer_binary", _INT), ("print", _INT), ("precise", _INT),
                ("try_catch", _INT), ("error_handler", _POINTER), ("nmethods", _INT), ("current", _INT),
                ("selected", _INT), ("method", _Method * (_MAXMETHODS + 1)), ("postorder", _INT)]


class _Sparse(ctypes.Structure):
    """``cholmod_sparse``: a compressed-column matrix."""
    _fields_ = [("nrow", _SIZE), ("ncol", _SIZE), ("nzmax", _SIZE), ("p", _POINTER), ("i", _POINTER),
                ("nz", _POINTER), ("x", _POINTER), ("z", _POINTER), ("stype", _INT), ("itype", _INT),
                ("xtype", _INT), ("dtype", _INT), ("sorted", _INT), ("packed", _INT)]


class _Dense(ctypes.Structure):
    """``cholmod_dense``: a column-major dense matrix."""
    _fields_ = [("nrow", _SIZE), ("ncol", _SIZE), ("nzmax", _SIZE), ("d", _SIZE), ("x", _POINTER),
                ("z", _POINTER), ("xtype", _INT), ("dtype", _INT)]


class _FactorHead(ctypes.Structure):
    """The leading fields of ``cholmod_factor``: its order, the column where a factorization
    found the matrix not positive definite (``n`` if it did not) and its fill-reducing permutation
    (``int`` (n,), the rows' order in the factor)."""
    _fields_ = [("n", _SIZE), ("minor", _SIZE), ("Perm", _POINTER)]


_library = None  # the loaded extension with its functions typed, False where unusable, None before the first look
_look_lock = threading.Lock()
#: Factorizations run one at a time (CHOLMOD's nested dissection calls METIS, whose
#: thread safety this build does not promise); cholespy's held the global lock, so they did before.
_factor_lock = threading.Lock()


def _new_locks_after_fork() -> None:
    """A forked child (multiprocessing, a farm's workers) has only the thread that forked: a lock
    another thread held at the fork would never be released there, so the child gets new ones.
    The kept analyses are complete copies in the child's memory and stay usable."""
    global _look_lock, _factor_lock, _given_lock
    _look_lock, _factor_lock, _given_lock = threading.Lock(), threading.Lock(), threading.Lock()


if hasattr(os, "register_at_fork"):  # not on Windows, which does not fork
    os.register_at_fork(after_in_child=_new_locks_after_fork)


def library(cholespy_module):
    """The ctypes handle of ``cholespy_module``'s compiled extension with CHOLMOD's functions
    typed, or None where they cannot be used as this module does: the extension not found, the
    functions not exported (a platform whose linker hides them) or a ``cholmod_common`` whose
    documented defaults do not read back through :class:`_Common` (another CHOLMOD)."""
    global _library
    with _look_lock:
        if _library is None:
            _library = _load(cholespy_module) or False
        return _library or None


def _load(cholespy_module):
    folder = os.path.dirname(getattr(cholespy_module, "__file__", "") or "")
    names = sorted(f for f in os.listdir(folder) if f.startswith("_cholespy_core")) if os.path.isdir(folder) else []
    for name in names:
        try:
            lib = ctypes.CDLL(os.path.join(folder, name))
            _typed(lib)
        except (OSError, AttributeError):  # not loadable, or CHOLMOD's functions not exported
            continue
        return lib if _layout_is_cholmods(lib) else None
    return None


def _typed(lib) -> None:
    """Argument and result types of the CHOLMOD functions used (AttributeError if one is missing)."""
    pointer = _POINTER
    lib.cholmod_start.argtypes = [pointer]
    lib.cholmod_finish.argtypes = [pointer]
    lib.cholmod_allocate_sparse.restype = ctypes.POINTER(_Sparse)
    lib.cholmod_allocate_sparse.argtypes = [_SIZE, _SIZE, _SIZE, _INT, _INT, _INT, _INT, pointer]
    lib.cholmod_free_sparse.argtypes = [ctypes.POINTER(ctypes.POINTER(_Sparse)), pointer]
    lib.cholmod_analyze.restype = pointer
    lib.cholmod_analyze.argtypes = [ctypes.POINTER(_Sparse), pointer]
    lib.cholmod_factorize.argtypes = [ctypes.POINTER(_Sparse), pointer, pointer]
    lib.cholmod_free_factor.argtypes = [ctypes.POINTER(pointer), pointer]
    lib.cholmod_allocate_dense.restype = ctypes.POINTER(_Dense)
    lib.cholmod_allocate_dense.argtypes = [_SIZE, _SIZE, _SIZE, _INT, pointer]
    lib.cholmod_solve.restype = ctypes.POINTER(_Dense)
    lib.cholmod_solve.argtypes = [_INT, pointer, ctypes.POINTER(_Dense), pointer]
    lib.cholmod_free_dense.argtypes = [ctypes.POINTER(ctypes.POINTER(_Dense)), pointer]
    lib.cholmod_copy_factor.restype = pointer
    lib.cholmod_copy_factor.argtypes = [pointer, pointer]
    analyze_p = getattr(lib, "cholmod_analyze_p", None)  # optional: orderings given by another process
    if analyze_p is not None:
        analyze_p.restype = pointer
        analyze_p.argtypes = [ctypes.POINTER(_Sparse), pointer, pointer, _SIZE, pointer]


def _layout_is_cholmods(lib) -> bool:
    """Whether CHOLMOD's documented ``cholmod_start`` defaults read back through :class:`_Common`
    (every field set here or read before ``postorder`` sits where this module puts it)."""
    memory = ctypes.create_string_buffer(_COMMON_BYTES)
    if not lib.cholmod_start(ctypes.addressof(memory)):
        return False
    try:
        c = _Common.from_buffer(memory)
        orderings = [m.ordering for m in c.method[:_MAXMETHODS]]
        return (c.grow0 == 1.2 and c.grow1 == 1.2 and c.grow2 == 5 and c.maxrank == 8 and c.supernodal_switch == 40.0
                and (c.supernodal, c.final_asis, c.final_super, c.final_ll, c.final_pack) == (1, 1, 1, 0, 1)
                and list(c.zrelax) == [0.8, 0.1, 0.05] and list(c.nrelax) == [4, 16, 48]
                and (c.print, c.nmethods, c.postorder) == (3, 0, 1)
                and orderings == [1, 2, 3, 4, 0, 4, 4, 4, 5]  # given, AMD, METIS, NESDIS, natural, NESDIS ×3, COLAMD
                and [m.nd_small for m in c.method[:_MAXMETHODS]] == [200, 200, 200, 200, 200, 20000, 4, 200, 200]
                and c.method[3].prune_dense == 10.0 and c.method[3].nd_oksep == 1.0)
    finally:
        lib.cholmod_finish(ctypes.addressof(memory))


class _Started:
    """A started ``cholmod_common`` with this module's options (finished when let go)."""

    def __init__(self, lib):
        self.memory = ctypes.create_string_buffer(_COMMON_BYTES)
        self.address = ctypes.addressof(self.memory)
        if not lib.cholmod_start(self.address):
            raise MemoryError("CHOLMOD could not start")
        self.held = [None]  # the address of the factor made in it, once made: freed with it
        # not run at exit (the process's memory goes with it): a thread still solving then would
        # find its factor freed under it
        weakref.finalize(self, _release, lib, self.memory, self.held).atexit = False
        common = _Common.from_buffer(self.memory)
        common.print = 0  # errors come back as exceptions, not printed
        common.supernodal, common.final_ll = _SIMPLICIAL, 1
        common.nmethods, common.method[0].ordering = 1, _NESDIS


class _Analysis:
    """The ordering and symbolic factor of one sparsity pattern (``indptr``, ``indices`` of its
    sorted compressed columns), made by ``cholmod_analyze`` from any matrix of that pattern, or by
    ``cholmod_analyze_p`` with the ordering ``given`` (int32 (n,), a permutation another process's
    analysis of the pattern made: :func:`take_orderings`)."""

    def __init__(self, lib, a, indptr: np.ndarray, indices: np.ndarray, given: np.ndarray | None = None):
        self.indptr, self.indices = indptr, indices
        self._common = _Started(lib)
        self._digest = None
        self.ordering_given = given is not None
        if given is None:
            self.factor = self._common.held[0] = lib.cholmod_analyze(a, self._common.address)
        else:
            _Common.from_buffer(self._common.memory).method[0].ordering = _GIVEN
            self.factor = self._common.held[0] = lib.cholmod_analyze_p(a, given.ctypes.data, None, 0,
                                                                       self._common.address)
        # a null factor from a given ordering is left to the caller (:func:`_analysis`), which orders
        # the pattern here instead; without one, CHOLMOD ran out of memory
        if not self.factor and given is None:
            raise MemoryError(f"CHOLMOD could not order a matrix of {len(indptr) - 1} unknowns")

    def fits(self, indptr: np.ndarray, indices: np.ndarray) -> bool:
        return np.array_equal(self.indptr, indptr) and np.array_equal(self.indices, indices)

    @property
    def digest(self) -> bytes:
        """:func:`pattern_digest` of its pattern (made once)."""
        if self._digest is None:
            self._digest = pattern_digest(self.indptr, self.indices)
        return self._digest

    def permutation(self) -> np.ndarray:
        """A copy of its ordering (int32 (n,): the factor's rows in the matrix's numbering)."""
        n = len(self.indptr) - 1
        perm = _FactorHead.from_address(self.factor).Perm
        return np.ctypeslib.as_array(ctypes.cast(perm, ctypes.POINTER(ctypes.c_int32)), shape=(n,)).copy()


_analyses: list = []  # the last KEPT_ANALYSES patterns' analyses, the latest last
#: Orderings another process sent (:func:`take_orderings`), by :func:`pattern_digest`, for the first
#: analysis of their patterns here; the last KEPT_ANALYSES taken are held (under :data:`_given_lock`,
#: not the factorizations' lock: a message reader takes them while a factorization runs).
_given: dict = {}
_given_lock = threading.Lock()


def pattern_digest(indptr: np.ndarray, indices: np.ndarray) -> bytes:
    """A hash (16 bytes) of a sparsity pattern's sorted compressed columns (int32 ``indptr``,
    ``indices``): what an ordering handed between processes is filed under."""
    digest = hashlib.blake2b(digest_size=16)
    digest.update(np.ascontiguousarray(indptr, dtype=np.int32).tobytes())
    digest.update(np.ascontiguousarray(indices, dtype=np.int32).tobytes())
    return digest.digest()


def _pattern(matrix: sp.spmatrix) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
    """``matrix`` (n, n) as the sorted compressed columns CHOLMOD is given (float64, duplicates
    summed) and their int32 index pointers and row indices (:func:`int32_columns`)."""
    csc = sp.csc_matrix(matrix, dtype=np.float64, copy=True)
    csc.sum_duplicates()
    csc.sort_indices()
    indptr, indices = int32_columns(csc)
    return csc, indptr, indices


def orderings(lib, matrix=None) -> dict:
    """{:func:`pattern_digest`: ordering (int32 (n,))} of the patterns whose analysis is kept here,
    ``matrix``'s (n, n; or a function of nothing making it) first analysed where it is not (its
    numeric factor is not made): for another process to factor those patterns without ordering them
    again (:func:`take_orderings`)."""
    if matrix is not None:
        csc, indptr, indices = _pattern(matrix() if callable(matrix) else matrix)
        with _factor_lock:
            if _kept_analysis(indptr, indices) is None:
                owner = _Started(lib)
                a = _copied_sparse(lib, csc, indptr, indices, owner)
                try:
                    _keep(_Analysis(lib, a, indptr, indices))
                finally:
                    lib.cholmod_free_sparse(ctypes.byref(a), owner.address)
    with _factor_lock:
        return {analysis.digest: analysis.permutation() for analysis in _analyses}


def take_orderings(orderings: dict) -> None:
    """Keep the ``orderings`` another process's :func:`orderings` gave, for the first analysis here of
    each of their patterns (one of another pattern under the same digest, or one CHOLMOD would not
    keep as given, is not used: that pattern is ordered anew)."""
    with _given_lock:
        for digest, ordering in orderings.items():
            _given.pop(digest, None)  # sent again: filed as the latest
            _given[digest] = np.ascontiguousarray(ordering, dtype=np.int32)
        for digest in list(_given)[:-KEPT_ANALYSES]:
            del _given[digest]


def _analysis(lib, a, indptr: np.ndarray, indices: np.ndarray) -> _Analysis:
    """A new analysis of the pattern of ``a`` (call under :data:`_factor_lock`): from the ordering
    another process gave for it, where there is one of its length that CHOLMOD keeps as it is
    (the factor of an ordering made here, to the bit), else ordered here."""
    if _given and getattr(lib, "cholmod_analyze_p", None) is not None:
        digest = pattern_digest(indptr, indices)
        with _given_lock:
            given = _given.pop(digest, None)
        n = len(indptr) - 1
        if given is not None and given.shape == (n,) and np.array_equal(np.sort(given), np.arange(n)):
            analysis = _Analysis(lib, a, indptr, indices, given)
            if analysis.factor and np.array_equal(analysis.permutation(), given):
                return analysis
    return _Analysis(lib, a, indptr, indices)


def _kept_analysis(indptr: np.ndarray, indices: np.ndarray) -> _Analysis | None:
    """The kept analysis of this pattern, or None (call under :data:`_factor_lock`)."""
    for analysis in _analyses:
        if analysis.fits(indptr, indices):
            _analyses.remove(analysis)
            _analyses.append(analysis)
            return analysis
    return None


def _keep(analysis: _Analysis) -> None:
    _analyses.append(analysis)
    del _analyses[:-KEPT_ANALYSES]


def int32_columns(csc: sp.csc_matrix) -> tuple[np.ndarray, np.ndarray]:
    """The index pointers (n + 1,) and row indices (nnz,) of ``csc`` (n, n) as the 32-bit integers
    CHOLMOD's ``int`` interface (the one cholespy's extension exports) reads them. MeshError where
    they do not fit (2³¹ − 1 at most: ``scipy.sparse.safely_cast_index_arrays``): cast unchecked, the
    pointers past it wrap to negative offsets and CHOLMOD reads outside the matrix. Neither
    cholespy's binding nor SciPy's SuperLU takes more (both index in 32 bits)."""
    try:
        indices, indptr = sp.safely_cast_index_arrays(csc, np.int32, "CHOLMOD's 32-bit indices")
    except ValueError as error:
        raise _too_large(csc, int(csc.indptr[-1]), error) from error
    return indptr, indices


def int32_coordinates(coo: sp.coo_matrix) -> tuple[np.ndarray, np.ndarray]:
    """The row and column indices (nnz,) of ``coo`` (n, n) as the 32-bit integers cholespy's binding
    reads them (it counts the unknowns and the nonzeros in C ``int`` too). MeshError where they do
    not fit, as :func:`int32_columns`: cast unchecked, an index past 2³¹ − 1 wraps to a negative row."""
    if coo.nnz > np.iinfo(np.int32).max:
        raise _too_large(coo, coo.nnz, "more nonzeros than cholespy's 32-bit count")
    try:
        rows, columns = sp.safely_cast_index_arrays(coo, np.int32, "cholespy's 32-bit indices")
    except ValueError as error:
        raise _too_large(coo, coo.nnz, error) from error
    return rows, columns


def _too_large(matrix: sp.spmatrix, nonzeros: int, error) -> MeshError:
    """The error of a system ``matrix`` (n, n) of ``nonzeros`` nonzeros whose indices do not fit in
    32 bits (``error``: what did not fit), in the user's terms."""
    return MeshError(f"The mesh is too large to solve: its system of {matrix.shape[0]:,} unknowns has {nonzeros:,} "
                     "nonzeros, and the sparse factorizations index at most 2,147,483,647 of either "
                     f"({error}); split it into pieces of fewer vertices")


class CholmodFactor:
    """The simplicial ``LLᵀ`` factor of a sparse symmetric positive definite ``matrix`` (n, n)
    made by ``lib`` (:func:`library`), as cholespy makes it; :meth:`solve` takes right-hand sides
    (n,) or (n, k). Not positive definite: ``numpy.linalg.LinAlgError``; CHOLMOD out of memory:
    ``MemoryError``. Solves on one factor are serialized by its caller (CHOLMOD solves in the
    factor's own workspace). ``analysed_anew``: whether its pattern was analysed for it (else a
    kept analysis was copied); ``ordering_given``: whether that analysis took the ordering another
    process gave (:func:`take_orderings`) instead of ordering the matrix here."""

    def __init__(self, lib, matrix: sp.spmatrix):
        self._lib, self.n = lib, matrix.shape[0]
        csc, indptr, indices = _pattern(matrix)
        self._owner = _Started(lib)
        self._common = self._owner.address
        with _factor_lock:
            a = _copied_sparse(lib, csc, indptr, indices, self._owner)
            try:
                analysis = _kept_analysis(indptr, indices)
                self.analysed_anew = analysis is None
                if analysis is None:
                    analysis = _analysis(lib, a, indptr, indices)
                    _keep(analysis)
                self.ordering_given = self.analysed_anew and analysis.ordering_given
                self._factor = self._owner.held[0] = lib.cholmod_copy_factor(analysis.factor, self._common)
                if not self._factor:
                    raise MemoryError(f"CHOLMOD could not hold the factor of a matrix of {self.n} unknowns")
                # FALSE only where CHOLMOD failed (out of memory): the factor is then still the
                # symbolic copy, whose ``minor`` is ``n``; a matrix not positive definite gives TRUE
                factored = lib.cholmod_factorize(a, self._factor, self._common)
            finally:
                lib.cholmod_free_sparse(ctypes.byref(a), self._common)
        if not factored:
            raise MemoryError(f"CHOLMOD could not factor a matrix of {self.n} unknowns")
        if _FactorHead.from_address(self._factor).minor < self.n:
            raise np.linalg.LinAlgError(f"Matrix is not positive definite! (CHOLMOD, {self.n} unknowns)")

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """The solution (shape of ``rhs``) of ``matrix @ x = rhs``."""
        lib, n = self._lib, self.n
        columns = 1 if rhs.ndim == 1 else rhs.shape[1]
        b = lib.cholmod_allocate_dense(n, columns, n, _REAL, self._common)
        if not b:
            raise MemoryError(f"CHOLMOD could not hold {columns} right-hand side(s) of {n} unknowns")
        x = None
        try:
            _as_array(b, columns, n)[...] = rhs.reshape(n, columns).T  # column-major, as cholespy copies it
            x = lib.cholmod_solve(_SOLVE_A, self._factor, b, self._common)
            if not x:
                raise MemoryError(f"CHOLMOD could not solve for {columns} right-hand side(s) of {n} unknowns")
            return _as_array(x, columns, n).T.reshape(rhs.shape).copy()
        finally:
            lib.cholmod_free_dense(ctypes.byref(b), self._common)
            if x:
                lib.cholmod_free_dense(ctypes.byref(x), self._common)


def _copied_sparse(lib, csc: sp.csc_matrix, indptr: np.ndarray, indices: np.ndarray, owner: _Started):
    """A ``cholmod_sparse`` copy of ``csc`` (n, n; its int32 ``indptr``, ``indices``) in CHOLMOD's
    memory, whole and in sorted compressed columns as cholespy hands it to CHOLMOD (stype −1: the
    lower triangle is read), allocated in ``owner``'s common (free it there)."""
    n, values = csc.shape[0], np.ascontiguousarray(csc.data, dtype=np.float64)
    a = lib.cholmod_allocate_sparse(n, n, max(values.size, 1), 1, 1, -1, _REAL, owner.address)
    if not a:
        raise MemoryError(f"CHOLMOD could not hold a matrix of {n} unknowns")
    ctypes.memmove(a.contents.p, indptr.ctypes.data, indptr.nbytes)
    ctypes.memmove(a.contents.i, indices.ctypes.data, indices.nbytes)
    ctypes.memmove(a.contents.x, values.ctypes.data, values.nbytes)
    return a


def _as_array(dense, columns: int, n: int) -> np.ndarray:
    """The values (columns, n) of a ``cholmod_dense`` (n, columns), as a view."""
    return np.ctypeslib.as_array(ctypes.cast(dense.contents.x, ctypes.POINTER(_DOUBLE)), shape=(columns, n))


def _release(lib, memory, held: list) -> None:
    """Free a factor's CHOLMOD data: the factor at ``held[0]`` (if made) and its ``cholmod_common``
    in ``memory``."""
    common = ctypes.addressof(memory)
    if held[0]:
        factor = _POINTER(held[0])
        lib.cholmod_free_factor(ctypes.byref(factor), common)
        held[0] = None
    lib.cholmod_finish(common)
