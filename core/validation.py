"""Argument checks of the public API, in one place (see ``docs/errors.md``).

Every public function of :mod:`core` (and the operators) calls these once, at its boundary, and
works with what they return. Bad input raises :class:`~core.errors.MeshError` (a ``ValueError``)
naming the argument, the first offending index of the caller's own data and what to do; nothing
is coerced silently (a complex coordinate, a fractional index, ``k_M=10.5``, ``True`` as a
number or ``"False"`` as a flag are errors, not conversions). Inputs are never modified.

Checks: :func:`check_vertices`, :func:`check_triangles`, :func:`check_mesh` (both, plus the
topology: manifold edges *and* vertices, consistent orientation), :func:`check_basis_sizes`,
:func:`check_offset`, :func:`check_factor`, :func:`check_gap_index`, :func:`check_time`,
:func:`check_flag`, :func:`check_key_poses`, :func:`check_key_names`, :func:`check_output_memory`,
:func:`check_working_memory`, :func:`check_positive`, :func:`check_factors`, :func:`check_energies`,
:func:`check_result_memory`, :func:`check_shared_frame`;
:func:`numerical_failures` turns a solver's raw
exception into a :class:`~core.errors.RecoveryError`.
"""

from __future__ import annotations

import math
import numbers
from contextlib import contextmanager

import numpy as np

from .errors import MeshError, MeshIndexError, RecoveryError

#: Largest accepted coordinate magnitude. The method squares lengths twice (Heron's formula,
#: 16µ² = 2Σx_i x_j − Σx_i², x = ℓ²), so ℓ⁴ must stay far inside float64's range (1e±308).
MAX_COORDINATE = 1e30
#: Smallest accepted mesh size (largest extent of its bounding box), for the same reason: ℓ⁴ of a
#: mesh 1e-80 across underflows to zero and every triangle looks degenerate.
MIN_EXTENT = 1e-30
#: Accepted |factor| (and distance of a time outside the keys): beyond, rotations wrap around many
#: times and the interpolated metric overflows; an exaggeration of 1000× is already meaningless.
MAX_FACTOR = 1e3
#: Largest share of the memory available now that a job's output poses may take: the rest is
#: for the job's own work and for whatever else the machine runs (Blender itself, other jobs).
OUTPUT_MEMORY_SHARE = 0.5
#: Memory each in-between asked of a gap at once takes per vertex while it is made
#: (:meth:`core.SequenceInterpolator.poses`): its float64 pose (24 bytes) and the working copy it is
#: solved in; measured peak 2.06 / 2.22 × the poses' 24 bytes (a 2,500-vertex sheet, 400 / 100 in-betweens),
#: so 2.25 × 24 bytes.
INBETWEEN_BYTES_PER_VERTEX = 54
#: Said after the memory available in a refusal: on a farm node or in a container it is the job's
#: memory limit less what the job uses (:func:`core.resources.cgroup_headroom`), not the machine's.
LIMITS_NOTE = " (within its container's or farm job's memory limit, if any)"
#: Memory a sequence's in-betweens take per vertex at their peak (keys, fields, factorizations):
#: the benchmark's 100k-vertex sheets peak at 948 MB, the analytic one with 15 in-betweens per gap
#: at 1,114 MB (docs/inbetweens.md).
WORKING_BYTES_PER_VERTEX = 12_000
#: The same for two poses (``Interpolator`` and its poses at 0.5 and 2): a grid rolled up, peak
#: resident memory over the process's before, 5.5 / 4.6 / 4.5 kB per vertex at 10k / 40k / 100k.
PAIR_WORKING_BYTES_PER_VERTEX = 6_000
#: The same for rebuilding a pose from its differences with the full basis (``ReferenceShape``,
#: ``shape_differences``, ``reconstruct``: the offset surface and the extrinsic embedding), measured
#: so: 24 / 30 / 33 kB per vertex at 10k / 40k / 100k, growing with the mesh (sparse factors).
RECONSTRUCT_WORKING_BYTES_PER_VERTEX = 40_000


def describe(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def real_array(values, name: str, what: str) -> np.ndarray:
    """``values`` as a NumPy array of real numbers (no copy if already one); MeshError otherwise, and
    for a masked array with values masked (a masked array with none is its data)."""
    if isinstance(values, np.ma.MaskedArray) and np.ma.getmaskarray(values).any():
        # the values under a mask are no data (a missing sample), and np.asarray would use them
        masked = np.ma.getmaskarray(values)
        at = tuple(int(i) for i in np.argwhere(masked)[0])
        raise MeshError(f"{name} is a masked array with {int(masked.sum()):,} masked value(s), the first at index "
                        f"{at[0] if len(at) == 1 else at}: every one of its {what} is needed (the values under "
                        "the mask would be used as they are). Fill them with the values meant (numpy.ma.filled), or "
                        "pass the data without them.")
    try:
        array = np.asarray(values)
    except Exception as error:  # ragged lists, objects NumPy cannot hold
        raise MeshError(f"{name} must be {what}; got {type(values).__name__} ({error}).") from error
    kind = array.dtype.kind
    if kind == "c":
        raise MeshError(
            f"{name} has complex values; {what} must be real numbers (the imaginary part would be "
            "lost). Pass the real coordinates, e.g. numpy.real(...) if the imaginary part is zero."
        )
    if kind == "b":
        raise MeshError(f"{name} holds booleans; {what} must be numbers.")
    if kind not in "iuf":
        if kind == "O" and array.size and all(isinstance(x, numbers.Real) and not isinstance(x, bool)
                                              for x in array.ravel()):
            return array.astype(np.float64)
        raise MeshError(f"{name} must hold numbers; got an array of dtype {array.dtype} ({what} expected).")
    return array


def check_vertices(vertices, n_vertices: int | None = None, *, name: str = "vertices", kept: bool = False) -> np.ndarray:
    """``vertices`` as contiguous float64 ``(n, 3)`` (a copy is made only if needed; the input is
    never modified). MeshError on a non-numeric or complex array, a wrong shape, a vertex count
    different from ``n_vertices``, a non-finite coordinate or a magnitude beyond
    :data:`MAX_COORDINATE`. ``kept``: the result is kept past the call (the in-betweens' keys), so
    it is a copy wherever it would share memory with a caller's array the caller can write to
    (a frame buffer filled again with the next frame would change the keys under the prepared
    in-betweens); an array that owns its memory and is read-only is kept as it is."""
    array = real_array(vertices, name, "vertex coordinates (n, 3)")
    if array.ndim != 2 or array.shape[1] != 3:
        raise MeshError(f"{name} must be an array of shape (n, 3); got shape {array.shape}.")
    if n_vertices is not None and array.shape[0] != n_vertices:
        raise MeshError(
            f"{name} has {array.shape[0]} vertices but the base mesh has {n_vertices}. Poses must "
            "be in vertex-for-vertex correspondence with the base: use shape keys or frames of "
            "the same mesh, and avoid modifiers that add or remove vertices (Subdivision, "
            "Decimate, Remesh) or apply them to every pose."
        )
    with np.errstate(over="ignore"):  # a longdouble past double precision's range: refused below by its size
        given, array = array, np.ascontiguousarray(array, dtype=np.float64)
    if kept and not isinstance(vertices, (list, tuple)) and np.may_share_memory(array, given) and \
            (array.flags.writeable or array.base is not None):
        array = array.copy()
    if not np.isfinite(array).all():  # whole-array checks first: row-wise reductions are slow
        bad = int(np.flatnonzero(~np.isfinite(array).all(axis=1))[0])
        if np.isfinite(given[bad]).all():  # finite as given, past float64 (a longdouble 1e400)
            raise _too_far(name, bad, np.format_float_scientific(np.abs(given[bad]).max(), precision=9, trim="-"))
        raise MeshError(
            f"{name}: vertex {bad} has a non-finite coordinate {array[bad].tolist()}. Fix the pose "
            "(e.g. a simulation that exploded) or remove that frame."
        )
    if array.size and np.abs(array).max() > MAX_COORDINATE:
        magnitude = np.abs(array).max(axis=1)
        bad = int(np.argmax(magnitude))
        raise _too_far(name, bad, f"{magnitude[bad]:.10g}")
    return array


def _too_far(name: str, vertex: int, coordinate: str) -> MeshError:
    """The refusal of vertex ``vertex`` of ``name``, whose largest coordinate (``coordinate``, as text)
    is past :data:`MAX_COORDINATE`."""
    return MeshError(
        f"{name}: vertex {vertex} has coordinate {coordinate}, beyond the supported "
        f"{MAX_COORDINATE:.0e} (edge lengths to the fourth power would overflow). Scale the "
        "mesh down (in Blender: scale the object, then Object > Apply > Scale), or fix that vertex."
    )


def check_triangles(triangles, n_vertices: int, *, name: str = "triangles") -> np.ndarray:
    """``triangles`` as contiguous int64 ``(m, 3)``, ``m ≥ 1``, every index in ``0..n_vertices−1``
    and no vertex twice in a triangle. Integer-valued floats are accepted; fractional, complex,
    boolean or text indices are a MeshError (nothing is rounded or wrapped)."""
    array = real_array(triangles, name, "integer vertex indices (m, 3)")
    if array.ndim != 2 or array.shape[1] != 3:
        raise MeshError(f"{name} must be an integer array of shape (m, 3); got shape {array.shape}.")
    if array.shape[0] < 1:
        raise MeshError(f"The mesh has no triangles ({name} is empty): shape differences need at least one face.")
    if array.dtype.kind == "f":
        bad = ~np.isfinite(array) | (np.mod(array, 1) != 0)
        if bad.any():
            t = int(np.flatnonzero(bad.any(axis=1))[0])
            raise MeshError(
                f"Triangle {t} (row {t} of {name}) has index values {array[t].tolist()}, which are not whole numbers; "
                "triangles must hold integer vertex indices."
            )
    out_of_range = (array < 0) | (array >= n_vertices)
    if out_of_range.any():
        t = int(np.flatnonzero(out_of_range.any(axis=1))[0])
        shown = [int(x) if isinstance(x, int) or (float(x).is_integer() and abs(x) < 2**62) else x
                 for x in array[t].tolist()]
        raise MeshError(
            f"Triangle {t} (row {t} of {name}) refers to vertex indices {shown}, but the mesh has "
            f"{n_vertices} vertices (valid indices are 0..{n_vertices - 1}; negative indices are "
            "not counted from the end). Pass the triangles and vertices of the same mesh."
        )
    tris = np.ascontiguousarray(array, dtype=np.int64)
    repeated = np.flatnonzero((tris[:, 0] == tris[:, 1]) | (tris[:, 1] == tris[:, 2]) | (tris[:, 2] == tris[:, 0]))
    if repeated.size:
        t = int(repeated[0])
        raise MeshError(
            f"Triangle {t} (row {t} of {name}) uses a vertex twice ({tris[t].tolist()}). Remove degenerate faces: "
            "in Blender use Mesh > Clean Up > Degenerate Dissolve, or Merge by Distance."
        )
    return tris


def check_mesh(vertices, triangles, *, name: str = "vertices", allow_bow_ties: bool = False, kept: bool = False):
    """Validate a mesh: :func:`check_vertices`, :func:`check_triangles`, its topology (manifold
    edges and vertices, consistent orientation), its size and its triangles (none degenerate).
    Returns ``(vertices float64 (n, 3), topology)`` with the topology of
    :func:`core.mesh_topology.mesh_topology` (``allow_bow_ties``: as there; ``kept``: as
    :func:`check_vertices`)."""
    from .mesh_topology import mesh_topology

    array = check_vertices(vertices, name=name, kept=kept)
    topology = mesh_topology(triangles, array.shape[0], allow_bow_ties=allow_bow_ties)
    check_pose(array, topology, name=name)
    return array, topology


def check_pose(vertices: np.ndarray, topology, *, name: str = "vertices", kept: bool = False,
               earlier=None) -> np.ndarray:
    """Validate one pose ``(n, 3)`` of a mesh of known topology: count, finite, range, size of the
    used part (≥ :data:`MIN_EXTENT`), no degenerate triangle. Returns float64 ``(n, 3)``
    (``kept``: as :func:`check_vertices`; ``earlier``: as :func:`core.mesh_topology.check_nondegenerate`)."""
    from .mesh_topology import check_nondegenerate

    array = check_vertices(vertices, topology.n_vertices, name=name, kept=kept)
    rows = np.ascontiguousarray(array.T)  # by coordinate: reductions along contiguous rows, 5× faster
    used = rows if topology.used_vertices.size == rows.shape[1] else rows[:, topology.used_vertices]
    extent = float(np.max(used.max(axis=1) - used.min(axis=1)))
    if not extent >= MIN_EXTENT:
        raise MeshError(
            f"{name}: the mesh is only {extent:.3g} units across, below the supported "
            f"{MIN_EXTENT:.0e} (areas and squared lengths would underflow). Scale it up (in "
            "Blender: scale the object, then Object > Apply > Scale)."
        )
    check_nondegenerate(rows.T, topology.triangles, name=name, earlier=earlier)
    return array


def _whole_number(value, name: str, *, allow_none: bool = False):
    """``value`` as a Python int if it is a whole number (int, NumPy integer, or an integral float);
    MeshError for booleans, fractions, text and anything else."""
    value = _scalar(value)
    if value is None and allow_none:
        return None
    if isinstance(value, (bool, np.bool_)):
        raise MeshError(f"{name} must be a whole number; got the boolean {value!r}.")
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real) and math.isfinite(float(value)) and float(value).is_integer():
        return int(value)
    raise MeshError(f"{name} must be a whole number; got {describe(value)}.")


def check_count(value, name: str, *, minimum: int | None = 0) -> int:
    """``value`` as a Python int if it is a whole number of at least ``minimum`` (how many
    eigenfunctions or axes to return; ``None``: any whole number, for a caller that checks the
    range itself); MeshError otherwise."""
    count = _whole_number(value, name)
    if minimum is not None and count < minimum:
        raise MeshError(f"{name} must be at least {minimum}; got {count}.")
    return count


def check_basis_sizes(k_M, k_N, n_vertices: int | None = None, n_components: int = 1, *,
                      full_basis: bool = True, target_vertices: int | None = None,
                      geometry=None) -> tuple[int | None, int | None]:
    """Basis sizes of eqs. (5)–(6): ``None`` or ``0`` means the full basis (the sidebar's
    convention). Each must be a whole number in ``n_components + 1..n_vertices − 1``
    (``n_vertices``: vertices in at least one triangle, unchecked when ``None``; the first
    ``n_components`` eigenfunctions are constant per connected component and carry no conformal
    information); ``k_N`` (target basis) needs ``k_M`` and is at least ``k_M``.
    ``full_basis=False``: a caller that needs a truncated ``k_M`` (the shape space, the distortion
    maps' eigenfunctions) — the messages do not offer the full basis. ``target_vertices``:
    vertices in triangles of another mesh whose basis ``k_N`` is (a cross-mesh transfer's target);
    ``k_N`` is then checked against it. ``geometry``: its positions ``(n, 3)`` and topology, where a
    refusal for too few eigenfunctions says to weld parts whose vertices coincide
    (:func:`core.seam_welds.weld_advice`)."""
    full = ", or 0 / None for the full basis" if full_basis else ""
    sizes = []
    target = n_vertices if target_vertices is None else target_vertices
    for label, k, mesh, count in (("k_M (base basis size)", k_M, "mesh", n_vertices),
                                  ("k_N (target basis size)", k_N, "mesh" if target_vertices is None
                                   else "target mesh", target)):
        k = _whole_number(k, label, allow_none=True)
        if k is not None and k < 0:
            raise MeshError(f"{label} must be 0 / None (full basis) or a positive number of eigenfunctions; got {k}.")
        if k and k <= n_components:
            from .seam_welds import weld_advice

            raise MeshError(
                f"{label} is {k}, but the first {n_components} Laplace–Beltrami eigenfunctions of this "
                f"mesh ({n_components} connected part(s)) are constant on each part, so the conformal "
                f"difference would be empty. Use at least {n_components + 1} (typically 50–300){full}."
                + (weld_advice(*geometry) if geometry is not None else "")
            )
        if k and count is not None and k >= count:
            raise MeshError(
                f"{label} is {k}, but the {mesh} has {count} vertices in triangles, so at most "
                f"{count - 1} Laplace–Beltrami eigenfunctions exist. Lower it"
                + (f"{full} (exact, and faster than a basis this large)." if full_basis else ".")
            )
        sizes.append(k or None)
    if sizes[1] is not None and sizes[0] is None:
        raise MeshError("k_N (target basis size) needs k_M (base basis size); set both or neither.")
    if sizes[1] is not None and sizes[1] < sizes[0]:
        # Eq. (6)'s map F is k_N × k_M: with k_N < k_M it has rank k_N at most, so the k_M × k_M
        # differences FᵀF, Fᵀ diag(λ_N) F are singular and the recovery has nothing to fit in the
        # other directions; the paper's recovery assumes k_N ≥ k_M (§8.2).
        raise MeshError(
            f"k_N (target basis size) is {sizes[1]}, below k_M (base basis size) {sizes[0]}: the "
            f"target's {sizes[1]} functions cannot represent the base's {sizes[0]}, and the pose "
            f"would not be recoverable. Use k_N of at least k_M (about 2 × k_M recovers well, "
            f"e.g. k_M = {sizes[0]}, k_N = {2 * sizes[0]})."
        )
    return sizes[0], sizes[1]


def _scalar(value):
    """A 0-d NumPy array as its scalar (e.g. a value read from an array); anything else unchanged."""
    return value.item() if isinstance(value, np.ndarray) and value.ndim == 0 else value


def check_real(value, name: str) -> float:
    """``value`` as a finite Python float; MeshError for booleans, text, complex and non-finite."""
    value = _scalar(value)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise MeshError(f"{name} must be a real number; got {describe(value)}.")
    number = float(value)
    if not math.isfinite(number):
        raise MeshError(f"{name} must be a finite number; got {value!r}.")
    return number


def check_positive(value, name: str) -> float:
    """``value`` as a finite Python float above 0 (a width, a speed); MeshError otherwise
    (:func:`check_real`'s cases, 0 and below)."""
    number = check_real(value, name)
    if not number > 0:
        raise MeshError(f"{name} must be a positive number; got {describe(value)}.")
    return number


def check_energies(energies):
    """The wave kernel signature's ``energies`` (:meth:`core.PulledBackMetric.wave_kernel_signature`):
    a count (an integer, at least 1) as a Python int, or explicit log-energies as float64
    ``(e,)``, finite, at least one; MeshError otherwise. A single number that is not an integer
    (a float, a value read from an array of log-energies) is refused, not read as a count: ``2.0``
    would be taken as two energies where one log-energy of 2 was meant; one log-energy is a list
    of one."""
    try:
        values = np.asarray(energies)
    except (ValueError, TypeError):  # ragged
        values = None
    if values is not None and values.ndim == 0:
        value = _scalar(energies)
        if isinstance(value, numbers.Real) and not isinstance(value, numbers.Integral):
            number = float(value)
            count = int(number) if number.is_integer() and number >= 1 else "an integer of at least 1"
            one = f", or [{number!r}] for one log-energy" if math.isfinite(number) else ""
            raise MeshError(f"energies must be a count (an integer, such as 100) or a list of finite log-energies "
                            f"(see wks_energies); got the single number {number!r}, not an integer: pass {count} "
                            f"for a count{one}.")
        return check_count(energies, "energies (a count)", minimum=1)  # booleans and text refused there
    if values is None or values.ndim != 1 or not values.size or values.dtype.kind not in "iuf" \
            or not np.isfinite(values).all():
        raise MeshError("energies must be a count or a list of finite log-energies (see wks_energies); "
                        f"got {describe(energies)}.")
    return values.astype(np.float64)


def check_offset(offset) -> float | None:
    """The offset distance t (§5.2): ``None`` (automatic, :func:`core.default_offset`) or a finite
    positive number in the mesh's units."""
    if offset is None:
        return None
    t = check_real(offset, "offset (the offset distance t)")
    if not t > 0:
        raise MeshError(
            f"offset (the offset distance t) must be positive; got {offset!r}. Use None for the "
            "automatic distance (half the mean edge length)."
        )
    return t


def check_factor(factor, *, name: str = "factor") -> float:
    """An interpolation factor (0 = first pose, 1 = second, outside: extrapolation), finite and
    within ±:data:`MAX_FACTOR`."""
    s = check_real(factor, name)
    if abs(s) > MAX_FACTOR:
        raise MeshError(
            f"{name} is {s:g}; factors beyond ±{MAX_FACTOR:g} are not supported (rotations wrap "
            "around many times and lengths overflow). Use a factor between 0 and 1 for in-betweens, "
            "slightly beyond for exaggeration."
        )
    return s


def check_factors(factors) -> list[float]:
    """Interpolation factors: a number or a flat sequence of numbers, each :func:`check_factor`'s,
    as a list of Python floats. A nested or ragged sequence is a MeshError (NumPy would raise its
    own ValueError making an array of it)."""
    try:
        values = np.atleast_1d(factors)
    except (ValueError, TypeError):
        values = None
    if values is None or values.ndim != 1:  # ragged, or nested ([[0.5, 0.25]]: one row, not a factor)
        raise MeshError(f"factors must be a number or a list of numbers; got {describe(factors)}.")
    return [check_factor(f) for f in values]


def check_gap_index(gap_index, n_gaps: int) -> int:
    """A gap of a sequence: a whole number in ``0..n_gaps − 1`` (negative indices are not counted
    from the end). Raises :class:`~core.errors.MeshIndexError` (a MeshError and an IndexError)."""
    try:
        gap = _whole_number(gap_index, "gap_index")
    except MeshError as error:
        raise MeshIndexError(str(error)) from None
    if not 0 <= gap < n_gaps:
        raise MeshIndexError(
            f"gap_index {gap} is out of range: the sequence has {n_gaps + 1} keys, so gaps "
            f"0..{n_gaps - 1} (gap i runs from key i to key i + 1)."
        )
    return gap


def check_time(time, n_gaps: int) -> float:
    """A global time in key units (``gap_index + factor``; outside ``0..n_gaps`` extrapolates),
    finite and at most :data:`MAX_FACTOR` gaps outside the keys."""
    value = check_real(time, "time")
    if value < -MAX_FACTOR or value > n_gaps + MAX_FACTOR:
        raise MeshError(
            f"time is {value:g}, more than {MAX_FACTOR:g} gaps outside the keys (0..{n_gaps}); "
            "extrapolation that far is not supported."
        )
    return value


def check_flag(value, name: str) -> bool:
    """A boolean switch: ``True``/``False`` (or NumPy booleans). Text such as ``"False"`` and numbers
    are MeshError (``bool("False")`` is true)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise MeshError(f"{name} must be True or False; got {describe(value)}.")


#: How a sequence's first gap starts (see :class:`core.SequenceInterpolator`).
START_MODES = ("rest", "keys")


def check_start(value) -> str:
    """A sequence's ``start``: one of :data:`START_MODES`; anything else is a MeshError."""
    return _check_mode("start", value, START_MODES)


#: How a sequence's last gap ends (see :class:`core.SequenceInterpolator`).
END_MODES = ("keys", "rest")


def check_end(value) -> str:
    """A sequence's ``end``: one of :data:`END_MODES`; anything else is a MeshError."""
    return _check_mode("end", value, END_MODES)


def _check_mode(name: str, value, modes: tuple) -> str:
    if isinstance(value, str) and value in modes:
        return value
    raise MeshError(f"{name} must be one of {', '.join(repr(m) for m in modes)}; got {describe(value)}.")


def check_key_times(value, count: int) -> np.ndarray | None:
    """A sequence's ``key_times``: ``None`` (evenly spaced) or ``count`` finite real numbers,
    strictly increasing, as float64 ``(count,)``; anything else is a MeshError."""
    if value is None:
        return None
    try:
        times = np.asarray(value)
    except Exception:  # noqa: BLE001 — ragged or exotic input: reported below in the user's terms
        times = None
    if times is None or times.dtype == bool or not np.issubdtype(times.dtype, np.number) \
            or np.iscomplexobj(times) or times.shape != (count,):
        raise MeshError(f"key_times must be {count} numbers, one per key pose; got {describe(value)}.")
    times = times.astype(np.float64)
    with np.errstate(over="ignore", invalid="ignore"):  # steps past float64's range: said below, not as NumPy's
        steps = np.diff(times)
    if not np.isfinite(times).all() or not (steps > 0).all():
        raise MeshError(f"key_times must be finite and strictly increasing (the frame of each key pose); "
                        f"got {times.tolist()}.")
    if not np.isfinite(steps).all():  # a gap's duration, which its splines' tangents are scaled by, infinite
        gap = int(np.flatnonzero(~np.isfinite(steps))[0])
        raise MeshError(f"key_times {times[gap]:g} and {times[gap + 1]:g} (keys {gap} and {gap + 1}) are farther "
                        "apart than double precision holds: give the keys' frames, or times in a unit nearer them.")
    return times


def check_key_names(key_names, count: int, default: list[str], what: str = "poses") -> list:
    """The names of ``count`` poses in messages: ``key_names`` (one per pose, such as the operators'
    frames or shape keys), else ``default``. Raises :class:`MeshError` unless one per pose."""
    if key_names is None:
        return default
    if isinstance(key_names, (str, bytes)) or not hasattr(key_names, "__len__") or \
            (isinstance(key_names, np.ndarray) and key_names.ndim != 1):  # a 0-d array has __len__ and no length
        raise MeshError(f"key_names must be a list of names, one for each of the {count} {what}; "
                        f"got {type(key_names).__name__}.")
    if len(key_names) != count:
        raise MeshError(f"key_names must name each of the {count} {what}; got {len(key_names)}.")
    return list(key_names)


def check_key_poses(key_poses, *, minimum: int = 2, name: str = "key_poses", key_names=None,
                    kept: bool = False) -> list[np.ndarray]:
    """Key poses as a list of float64 ``(n, 3)`` arrays with one vertex count (from a list of
    arrays or an array ``(K, n, 3)``); at least ``minimum``. Topology checks are separate.
    ``key_names``: the poses' names in messages (K strings; default ``key pose i of`` ``name``);
    ``kept``: as :func:`check_vertices`."""
    if isinstance(key_poses, (str, bytes)) or not hasattr(key_poses, "__iter__"):
        raise MeshError(f"{name} must be a sequence of vertex arrays (n, 3); got {type(key_poses).__name__}.")
    poses = list(key_poses)
    if len(poses) < minimum:
        raise MeshError(f"A sequence needs at least {minimum} key poses; got {len(poses)}.")
    names = check_key_names(key_names, len(poses), [f"key pose {i} of {name}" for i in range(len(poses))],
                            "key poses")
    first = check_vertices(poses[0], name=names[0], kept=kept)
    return [first] + [check_vertices(p, first.shape[0], name=n, kept=kept) for p, n in zip(poses[1:], names[1:])]


def check_interpolation(poses, triangles, k_M=None, k_N=None, offset=None, use_extrinsic=True, *,
                        names=None, kept: bool = False):
    """Everything the in-between constructors take, checked once: every pose (count, finite,
    range, size, no degenerate triangle), the topology, the basis sizes against the used vertex
    count, the offset and the flag. Returns ``(poses list of float64 (n, 3), k_M, k_N, offset,
    use_extrinsic)`` normalized and the topology (:func:`core.mesh_topology.mesh_topology`). Bow-tie
    vertices pass here: a mesh split along seams has them where its importer shared one vertex
    between fans alike on both sides, and the in-betweens refuse them only where welding the
    seams leaves them (:func:`core.mesh_topology.check_manifold_vertices`).

    ``poses``: list of vertex arrays; ``names``: their names in messages (default ``key pose i``);
    ``kept``: as :func:`check_vertices` (the caller's poses, not yet checked)."""
    names = list(names) if names is not None and len(names) else [f"key pose {i}" for i in range(len(poses))]  # an array too
    first, topology = check_mesh(poses[0], triangles, name=names[0], allow_bow_ties=True, kept=kept)
    checked = [first]
    for pose, name in zip(poses[1:], names[1:]):  # a later key's flat triangles told against the keys before it
        checked.append(check_pose(pose, topology, name=name, kept=kept, earlier=(names[0], checked)))
    check_shared_frame(checked, topology, names)
    k_M, k_N = check_basis_sizes(k_M, k_N, int(topology.used_vertices.size), topology.components()[0],
                                 geometry=(first, topology))
    return checked, k_M, k_N, check_offset(offset), check_flag(use_extrinsic, "use_extrinsic"), topology


def check_shared_frame(poses: list[np.ndarray], topology, names: list[str]) -> None:
    """Refuse (:class:`~core.errors.MeshError`) a key pose (``poses``: ``(n, 3)`` each, of the mesh
    ``topology``) that the first key's place flattens: the in-betweens take every key about the
    first key's middle (:class:`core.sequence_keys.SequenceKeys`) in double precision, and moving a
    key there rounds its coordinates to machine epsilon times that middle's largest coordinate. Where
    that rounding makes every triangle of a key thin (its height at most the rounding over
    :data:`core.rounded_slivers.ROUNDED_SLIVER`), most of them flattened to zero area, the key keeps
    no shape in the in-betweens: a key 1 unit across after a key 3e15 across gave NumPy's division
    warnings and in-betweens of the flattened key, after one 1e30 across a raw ValueError. A key
    whose own coordinates are as large as that middle (all keys far from the origin, or a key far
    larger than the first) is rounded so as given, and keeps the in-betweens' warning of slivers."""
    from .coordinate_rounding import inverse_heights
    from .rounded_slivers import ROUNDED_SLIVER

    if len(poses) < 2:
        return
    used = topology.used_vertices
    rows = [np.ascontiguousarray(pose.T) if used.size == pose.shape[0] else np.ascontiguousarray(pose[used].T)
            for pose in poses]  # by coordinate: reductions along contiguous rows
    low, high = rows[0].min(axis=1), rows[0].max(axis=1)
    place = float(np.max(np.abs(0.5 * (low + high))))  # the first key's middle, its largest coordinate
    eps = float(np.finfo(np.float64).eps)
    thin = eps * place / ROUNDED_SLIVER
    for name, pose, r in zip(names[1:], poses[1:], rows[1:]):
        own = float(max(np.max(np.abs(r.max(axis=1))), np.max(np.abs(r.min(axis=1)))))
        # rounded at least as coarsely as given; or a key of triangles all at most `thin` high that
        # spans more than 1/√eps (6.7e7) of them across: larger than any mesh in-betweened
        if own >= place or float(np.max(r.max(axis=1) - r.min(axis=1))) > thin / math.sqrt(eps):
            continue
        tallest = 1.0 / float(np.min(inverse_heights(pose, topology.triangles)))
        if tallest <= thin:
            raise MeshError(
                f"{name} has no triangle higher than {tallest:.3g}, and the in-betweens take every key about the "
                f"middle of {names[0]}, {place:.3g} units out, where double precision rounds coordinates to "
                f"{eps * place:.2g}: every triangle of {name} would be flattened or reshaped. The keys differ in "
                "size or place by more than double precision holds (about 1e15): give poses of comparable size "
                "and place (a key scaled down to almost nothing: a small size such as 1e-6 rather than 1e-30)."
            )


def check_output_memory(n_poses: int, n_points: int, what: str, advice: str, *, bytes_per_point: int = 12,
                        working: int = 0) -> None:
    """Refuse (:class:`~core.errors.MeshError`) an output of ``n_poses`` poses of ``n_points``
    points (``bytes_per_point`` each: 12 for float32 coordinates), with ``working`` bytes beside it
    while it is made (a retime's largest gap's in-betweens, :data:`INBETWEEN_BYTES_PER_VERTEX`), that
    would take more than :data:`OUTPUT_MEMORY_SHARE` of the memory available now, before any work:
    the job would swap or be killed by the system after running for a long time (a farm node's other
    jobs with it). ``what`` says which output, ``advice`` how to make it smaller. Nothing is checked
    where the system does not say how much memory is available."""
    from .resources import available_memory

    need = int(n_poses) * int(n_points) * bytes_per_point + int(working)
    free = available_memory()
    if free is not None and need > OUTPUT_MEMORY_SHARE * free:
        beside = f", {working / 1e9:.3g} GB of it its in-betweens while they are made" if working else ""
        raise MeshError(f"{what} is {int(n_poses):,} poses of {int(n_points):,} vertices, {need / 1e9:.3g} GB"
                        f"{beside}, and this process{LIMITS_NOTE} has {free / 1e9:.3g} GB of memory available: "
                        f"{advice}.")


def check_result_memory(shape: tuple, what: str, advice: str) -> None:
    """Refuse (:class:`~core.errors.MeshError`) a float64 result of ``shape`` asked for by a count
    argument (``what``, e.g. ``"dims = 10,000,000,000"``) that would take more than
    :data:`OUTPUT_MEMORY_SHARE` of the memory available now, rather than let NumPy fail allocating
    it (or use the system's swap); ``advice``: the smaller count that serves. Unchecked where the
    system does not say how much memory is available."""
    from .resources import available_memory

    need = math.prod(int(size) for size in shape) * 8
    free = available_memory()
    if free is not None and need > OUTPUT_MEMORY_SHARE * free:
        raise MeshError(f"{what} asks for an array of shape {tuple(int(x) for x in shape)}, {need / 1e9:.3g} GB, and "
                        f"this process{LIMITS_NOTE} has {free / 1e9:.3g} GB of memory available: {advice}.")


def check_working_memory(n_points: int, what: str, advice: str, *,
                         bytes_per_vertex: int = WORKING_BYTES_PER_VERTEX) -> None:
    """Refuse (:class:`~core.errors.MeshError`) in-betweening a mesh of ``n_points`` vertices whose
    working memory (``bytes_per_vertex`` per vertex: :data:`WORKING_BYTES_PER_VERTEX` for a
    sequence, :data:`PAIR_WORKING_BYTES_PER_VERTEX` for two poses,
    :data:`RECONSTRUCT_WORKING_BYTES_PER_VERTEX` for a reconstruction) exceeds the memory available
    now, before any work: the system would kill the process when it runs out (Blender with the
    artist's unsaved work). ``what`` names the job, ``advice`` the way out; unchecked where the
    system does not say how much memory is available."""
    from .resources import available_memory

    need = int(n_points) * int(bytes_per_vertex)
    free = available_memory()
    if free is not None and need > free:
        raise MeshError(f"{what} ({int(n_points):,} vertices) needs about {need / 1e9:.3g} GB of memory and this "
                        f"process{LIMITS_NOTE} has {free / 1e9:.3g} GB available: {advice}.")


@contextmanager
def numerical_failures(what: str):
    """Turn a raw numerical exception escaping a solver (NumPy's LinAlgError, SciPy's "Factor is
    exactly singular" RuntimeError, overflow, division by zero) into a RecoveryError naming the
    step ``what``; documented errors pass through unchanged, and so do errors of the code itself
    (IndexError, TypeError, NotImplementedError, RecursionError: no input makes them, and a
    RecoveryError would send the user to change a valid input)."""
    from .errors import ShapeDifferenceError

    try:
        yield
    except (ShapeDifferenceError, NotImplementedError, RecursionError):
        raise
    except (np.linalg.LinAlgError, FloatingPointError, OverflowError, ZeroDivisionError, RuntimeError) as error:
        raise RecoveryError(
            f"{what} failed numerically ({type(error).__name__}: {error}). The input is valid but "
            "beyond what the solver can handle (e.g. nearly degenerate triangles or an extreme "
            "deformation); try a less extreme pose, a remeshed surface, or report it with the mesh."
        ) from error


def check_sequence(key_poses, triangles, k_M=None, k_N=None, offset=None, use_extrinsic=True, smooth=True,
                   key_names=None, checked: bool = False):
    """:func:`check_key_poses` and :func:`check_interpolation` for a sequence constructor, plus its
    ``smooth`` flag; ``key_names``: the keys' names in messages (K strings, or None). Returns
    ``(key_poses list of float64 (n, 3), k_M, k_N, offset, use_extrinsic, smooth, topology)``.
    ``checked``: ``key_poses`` and the options are what this function returned for ``triangles`` in
    another process (the gap worker builds the caller's sequence, :mod:`core.gap_worker`): the poses
    are taken as they are, not checked again (at 50k vertices the keys' checks are 0.11 of the
    constructor's 0.35 s), and only the topology is made."""
    if checked:
        from .mesh_topology import mesh_topology

        poses = list(key_poses)
        topology = mesh_topology(triangles, poses[0].shape[0], allow_bow_ties=True)
        return poses, k_M, k_N, offset, use_extrinsic, smooth, topology
    poses, k_M, k_N, offset, use_extrinsic, topology = check_interpolation(
        check_key_poses(key_poses, key_names=key_names, kept=True), triangles, k_M, k_N, offset, use_extrinsic, names=key_names)
    return poses, k_M, k_N, offset, use_extrinsic, check_flag(smooth, "smooth"), topology
