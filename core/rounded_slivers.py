"""Triangles the keys' rounding reshapes: slivers less high than twice the rounding of the keys'
coordinates (:func:`core.coordinate_rounding.coordinate_rounding`: single precision where every coordinate is a
float32, as Blender stores shape keys and caches; large far from the origin). The in-betweens
(paper §8.4) read each triangle's stretch and turn between the keys; a sliver that high is
stretched, squashed or turned over by the rounding alone, and the fit bends the mesh around what
the rounding made: a sphere 3.5 across with four slivers 1e-5–1e-4 high, turned rigidly 1,000
units from the origin in single precision (rounding 1.2e-4), came 1.2e-4–1.0e-3 of its diagonal
off at 0.5 and 0.17–2 % at ×2 (the keys' own rounding: 1.7e-5 of it) with their own targets.
A sliver less high than the fits' floor in both keys takes a told neighbour's targets instead
(:mod:`core.untold_triangles`: 0.7 of the rounding off); the others, and those with no told
neighbour, are counted, so that the gap warns of them.
"""

from __future__ import annotations

import numpy as np

#: A triangle is thin against the rounding ``r`` (machine epsilon times the largest coordinate: one
#: to two steps of the coordinates' grid) where its smallest height
#: (:func:`core.untold_triangles.triangle_heights`) is at most ``r / ROUNDED_SLIVER``:
#: rounding each corner's coordinates by up to half a step moves it by up to 0.87 of a step, which
#: changes such a height by a fifth or more.
ROUNDED_SLIVER = 0.5


def rounded_slivers(heights: list[np.ndarray], rounding: float) -> np.ndarray:
    """Indices (k,) of the triangles thin against the ``rounding`` (:data:`ROUNDED_SLIVER`)
    in any of the keys whose triangles' smallest ``heights`` ((m,) each: the keys' own,
    :attr:`core.inbetween_keys.Key.heights`, made once per key for every reading of them) are
    given: the keys do not tell their shape nor which way they face."""
    if not rounding > 0.0 or not heights or not len(heights[0]):
        return np.zeros(0, dtype=np.int64)
    thin = np.zeros(len(heights[0]), dtype=bool)
    for height in heights:
        thin |= height <= rounding / ROUNDED_SLIVER
    return np.flatnonzero(thin)


def sliver_excess(heights: list[np.ndarray], rows: np.ndarray, rounding: float) -> float:
    """How far past its allowance the thinnest of the triangles ``rows`` (int (k,), of
    :func:`rounded_slivers`) is in the keys whose triangles' smallest ``heights`` ((m,) each, as
    there) are given: the least height the keys' ``rounding`` allows (``rounding /
    ROUNDED_SLIVER``) ÷ its smallest height in any key (at least 1 for such a triangle; a key's
    triangles are not degenerate); 0 where ``rows`` is empty (:attr:`core.errors.ShapeDifferenceWarning.excess`)."""
    if not rows.size:
        return 0.0
    thinnest = min(float(height[rows].min()) for height in heights)
    return rounding / ROUNDED_SLIVER / thinnest


#: The factor by which a change must lower the keys' rounding to be named as its cause in the
#: ``sliver`` warning (:func:`rounding_cause`): a coordinate's rounding is machine epsilon times its
#: power of two, so a change that lowers the largest coordinate less than twofold may leave it.
ROUNDING_STEP = 2.0


def rounding_cause(poses: list[np.ndarray], pair: tuple[int, int], names: list[str]) -> str:
    """What sets the keys' rounding (:func:`core.coordinate_rounding.coordinate_rounding`, machine
    epsilon times the keys' largest coordinate), as the ``sliver`` warning's reason and advice:
    ``poses`` the keys (K, each (n, 3)), ``pair`` the gap's two keys (indices into ``poses`` and
    ``names``). Moving the origin to the keys' common middle lowers the largest coordinate to their
    common half extent: where that lowers it more than :data:`ROUNDING_STEP` times, the keys' place is
    the cause; else where the largest key is that many times the smaller of the gap's two keys across,
    it is the keys' size ratio (a key far larger than the smaller of the gap's keys rounds that one as its
    own size is rounded); else the triangles are the mesh's own slivers."""
    low = np.min([pose.min(axis=0) for pose in poses], axis=0)
    high = np.max([pose.max(axis=0) for pose in poses], axis=0)
    largest = float(np.max(np.maximum(np.abs(low), np.abs(high))))
    centred = float(np.max(0.5 * (high - low)))
    if largest > ROUNDING_STEP * centred:
        return (f"their precision {largest:.3g} units from the origin; move the mesh's origin near it, or dissolve the "
                "slivers: Mesh > Clean Up > Degenerate Dissolve")
    sizes = [float(np.max(pose.max(axis=0) - pose.min(axis=0))) for pose in poses]
    big = int(np.argmax(sizes))
    small = pair[0] if sizes[pair[0]] <= sizes[pair[1]] else pair[1]
    if sizes[big] >= ROUNDING_STEP * sizes[small]:
        return (f"set by {names[big]}, {sizes[big]:.3g} across, {sizes[big] / sizes[small]:.3g} times the size of "
                f"{names[small]}; give keys of comparable size (a key scaled by mistake: apply its scale)")
    return "the mesh's own slivers at this size; dissolve them: Mesh > Clean Up > Degenerate Dissolve"


def rounded_sliver_warning(count: int, rounding: float, names: tuple[str, str], cause: str) -> list[str]:
    """The gap's warning (list of at most one message) for ``count`` triangles that
    :func:`rounded_slivers` found in the keys ``names``, whose coordinates are rounded to
    ``rounding`` for the reason ``cause`` (:func:`rounding_cause`, with its advice)."""
    if not count:
        return []
    return [f"between {names[0]} and {names[1]}, {count} triangle(s) are less high than twice the rounding "
            f"of the keys' coordinates ({rounding:.2g}, {cause}): "
            "the keys do not tell their shape nor which way they face, and the in-betweens may bend the "
            "mesh around what the rounding made of them"]
