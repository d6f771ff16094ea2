"""Vertex maps as data sets ship them, turned into the correspondence :class:`core.Transfer` takes.

Two forms are common:

- **one index per vertex**: for each vertex of one mesh, the index of its matched vertex on the
  other (0-based from Python tools, 1-based from MATLAB ones);
- **template maps** (``.vts`` files of the re-meshed benchmarks FAUST_r, SCAPE_r, SHREC'19,
  SMAL_r, DT4D-H): for each vertex of a common template, the 1-based index of its vertex on a
  re-meshed shape. A map between two shapes is the composition base → template → target; it
  covers only the base vertices some template vertex lands on, the others are unmatched
  (:data:`~core.functional_map.UNMATCHED`, which :class:`core.Transfer` fills from matched
  neighbours).

:func:`read_vertex_map` reads either kind of file (one integer per line; ``np.loadtxt``, or
``.npy``); :func:`template_correspondence` composes two template maps.
"""

from __future__ import annotations

import os
import warnings

import numpy as np

from .errors import MeshError
from .functional_map import UNMATCHED


def read_vertex_map(path) -> np.ndarray:
    """The integer indices ``(L,)`` of a map file: one index per line (text, as ``.vts`` files
    and most map files are; a single column, integers possibly written as ``12.0``), or a 1-D
    ``.npy`` array. Indices are returned as stored (no change of base); raises
    :class:`MeshError` for a missing, empty or malformed file."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise MeshError(f"The map file '{path}' is a folder: give the map file in it.")
    if not os.path.isfile(path):
        raise MeshError(f"The map file '{path}' does not exist.")
    try:  # utf-8-sig: a byte-order mark (Notepad's) is not part of the first index
        with warnings.catch_warnings():  # an empty file: NumPy's UserWarning, then the MeshError below
            warnings.filterwarnings("ignore", "loadtxt: input contained no data", UserWarning)
            values = np.load(path) if path.lower().endswith(".npy") else np.loadtxt(path, ndmin=1, encoding="utf-8-sig")
    except ValueError as error:
        raise MeshError(f"The map file '{path}' is not a list of vertex indices, one per line ({error}).") from error
    values = np.asarray(values)
    if values.ndim == 2 and values.shape[1] == 1:
        values = values[:, 0]
    if values.ndim != 1:
        raise MeshError(
            f"The map file '{path}' holds a table of shape {values.shape}; a vertex map has one index per line."
        )
    if not values.size:
        raise MeshError(f"The map file '{path}' is empty.")
    return _indices(values, f"the map file '{path}'")


def _indices(values, what: str) -> np.ndarray:
    array = np.asarray(values)
    if array.ndim != 1:
        raise MeshError(f"{what} must be a list of vertex indices (1-D); got shape {array.shape}.")
    if not np.issubdtype(array.dtype, np.integer):
        if not np.issubdtype(array.dtype, np.floating):
            raise MeshError(f"{what} must hold whole vertex indices; got values of type {array.dtype}.")
        whole = np.isfinite(array) & (np.mod(np.nan_to_num(array), 1) == 0)
        if not whole.all():
            first = int(np.flatnonzero(~whole)[0])
            raise MeshError(f"{what} holds a value that is not a whole vertex index (entry {first}: {array[first]}).")
        # int64 cannot hold these: the cast would wrap them to another (negative) index
        beyond = np.abs(array) >= 2.0**63
        if beyond.any():
            first = int(np.flatnonzero(beyond)[0])
            raise MeshError(f"{what} holds {array[first]:g} at entry {first}, beyond any vertex index.")
    return array.astype(np.int64)


def vertex_map_indices(values, n_target: int, *, one_based: bool, what: str = "the map") -> np.ndarray:
    """Indices ``values`` ``(L,)`` of vertices of a mesh with ``n_target`` vertices, stored
    1-based (``one_based``, MATLAB's convention) or 0-based, as 0-based int64 ``(L,)``. Raises
    :class:`MeshError` for an index out of range, saying whether the other convention fits."""
    array = _indices(values, what)
    zero_based = array - 1 if one_based else array
    bad = np.flatnonzero((zero_based < 0) | (zero_based >= n_target))
    if bad.size:
        i = int(bad[0])
        low, high = (1, n_target) if one_based else (0, n_target - 1)
        hint = ""
        other = array if one_based else array - 1
        if np.all((other >= 0) & (other < n_target)):
            hint = (" The indices fit the other convention: the map is "
                    f"{'0' if one_based else '1'}-based.")
        raise MeshError(
            f"Entry {i} of {what} is {int(array[i])}, but {'1-based' if one_based else '0-based'} indices of a "
            f"mesh with {n_target} vertices run from {low} to {high} ({bad.size} entries out of range).{hint}"
        )
    return zero_based


def template_correspondence(base_vts, target_vts, n_base: int, n_target: int | None = None, *,
                            one_based: bool = True,
                            names: tuple[str, str] = ("the base's template map", "the target's template map")) -> np.ndarray:
    """The correspondence base → target composed from two template maps.

    ``base_vts`` / ``target_vts`` int ``(T,)``: for each of the ``T`` template vertices, its
    vertex on the base (``n_base`` vertices) and on the target (``n_target``, checked when given),
    1-based as ``.vts`` files store them (``one_based=False`` for 0-based). Returns int64
    ``(n_base,)``: for each base vertex the target vertex of the template vertex landing on it,
    or :data:`~core.functional_map.UNMATCHED` (-1) where none does (where several do, the first).
    Raises :class:`MeshError` naming what is wrong (lengths, an index out of range), calling the
    two maps by ``names``."""
    base = vertex_map_indices(base_vts, int(n_base), one_based=one_based, what=names[0])
    target_values = _indices(target_vts, names[1])
    if base.shape != target_values.shape:
        raise MeshError(
            f"The two template maps have different lengths ({base.size} and {target_values.size} entries): both must "
            "list every vertex of the same template, in the same order. Use the maps of one data set."
        )
    if n_target is None:
        target = target_values - 1 if one_based else target_values
        if target.size and target.min() < 0:
            raise MeshError(
                f"Entry {int(np.argmin(target))} of {names[1]} is {int(target_values.min())}: "
                f"{'1-based indices start at 1 (the map looks 0-based)' if one_based else 'indices are never negative'}."
            )
    else:
        target = vertex_map_indices(target_values, int(n_target), one_based=one_based, what=names[1])
    correspondence = np.full(int(n_base), UNMATCHED, dtype=np.int64)
    landed, first = np.unique(base, return_index=True)  # the first template vertex on each base vertex
    correspondence[landed] = target[first]
    return correspondence
