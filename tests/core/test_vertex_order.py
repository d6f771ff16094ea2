"""Positions in another vertex order than the mesh's (a cache of another mesh with as many
vertices, or of this one renumbered) against any motion of the mesh (core.vertex_order)."""

from pathlib import Path

import numpy as np
import pytest

from core.vertex_order import FOREIGN_GROWTH, SCATTERED_SPAN, UNEVEN_LENGTHS, EdgeSpread, edge_growth

from meshes import grid, icosphere, random_rotation

HANDKERCHIEF = Path(__file__).parent / "data" / "pinned_handkerchief.npz"


def _edges(triangles):
    pairs = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    return np.unique(pairs, axis=0)


def test_moving_turning_or_scaling_the_parts_leaves_the_edges_as_they_were():
    """Two parts, each turned, moved and scaled on its own (a cache in centimetres, pieces flying
    apart): the edges against their parts' sizes do not change, to rounding."""
    sheet, sheet_triangles = grid(12)
    ball, ball_triangles = icosphere(2)
    rest = np.concatenate([sheet, ball + 3.0])
    edges = _edges(np.concatenate([sheet_triangles, ball_triangles + len(sheet)]))
    moved = np.concatenate([100.0 * sheet @ random_rotation(1).T + 7.0, 0.01 * ball @ random_rotation(2).T - 40.0])
    assert abs(edge_growth(rest, moved, edges) - 1.0) < 1e-9


def test_a_folded_sheet_and_a_crumpled_cloth_stay_below_the_limit_a_random_order_passes():
    """A sheet folded double (half its size, its edges kept) and Blender's cloth crumpling onto a
    pin grow the edges against their sizes by at most about 2; the same positions in a random
    vertex order, or reversed on a sphere, by far more than FOREIGN_GROWTH."""
    sheet, triangles = grid(30)
    edges = _edges(triangles)
    folded = sheet.copy()
    far = folded[:, 0] > 0.5
    folded[far, 0], folded[far, 2] = 1.0 - folded[far, 0], 0.01
    spread = EdgeSpread(sheet, edges)
    assert 1.2 < spread.growth(folded) < 2.0
    shuffled = folded[np.random.default_rng(0).permutation(len(sheet))]
    assert spread.growth(shuffled) > 2 * FOREIGN_GROWTH

    data = np.load(HANDKERCHIEF)
    keys, edges = data["keys"], _edges(data["triangles"])
    spread = EdgeSpread(keys[0], edges)
    growths = [spread.growth(key) for key in keys]
    assert max(growths) < FOREIGN_GROWTH / 2
    assert spread.growth(keys[-1][np.random.default_rng(1).permutation(keys.shape[1])]) > 5 * FOREIGN_GROWTH

    ball, ball_triangles = icosphere(3)
    assert edge_growth(ball, ball[::-1], _edges(ball_triangles)) > FOREIGN_GROWTH


def _rolled_strip(vertices: tuple[int, int], size: tuple[float, float], inner: float, gap: float):
    """A strip of ``vertices`` (along, across) spanning ``size`` and the same rolled up along its
    length on an Archimedean spiral from radius ``inner``, ``gap`` between its turns, its edges
    kept: (rest, rolled, edges)."""
    sheet, triangles = grid(*vertices)
    rest = (sheet - sheet.min(axis=0)) / np.ptp(sheet, axis=0).clip(1e-12) * np.array([*size, 0.0])
    arc = rest[:, 0]
    order = np.argsort(arc, kind="stable")
    turn = np.zeros(len(arc))
    for previous, vertex in zip(order[:-1], order[1:]):  # the angle wound up to each arc length
        radius = inner + gap * turn[previous] / (2 * np.pi)
        turn[vertex] = turn[previous] + (arc[vertex] - arc[previous]) / radius
    radius = inner + gap * turn / (2 * np.pi)
    rolled = np.stack([radius * np.cos(turn), rest[:, 1], radius * np.sin(turn)], axis=1)
    return rest, rolled, _edges(triangles)


@pytest.mark.parametrize("inner", [0.3, 0.05])
def test_a_carpet_rolled_up_is_not_scattered_though_its_edges_grow(inner):
    """Rolled up, a long carpet (10 × 1, 200 × 20 vertices, 0.02 between its turns) shrinks its
    size many times while its edges keep their length: growth over FOREIGN_GROWTH (6–8), yet its
    edges stay far shorter than its size, so it is not scattered; the same positions in a random
    vertex order are."""
    rest, rolled, edges = _rolled_strip((200, 20), (10.0, 1.0), inner, 0.02)
    spread = EdgeSpread(rest, edges)
    assert spread.growth(rolled) > FOREIGN_GROWTH
    assert not spread.scattered(rolled)
    assert spread.scattered(rolled[np.random.default_rng(2).permutation(len(rolled))])


@pytest.mark.parametrize("vertices, inner, gap", [((50, 2), 1.0, 0.3), ((60, 4), 1.0, 0.25), ((45, 3), 1.5, 0.2)])
def test_a_narrow_strap_rolled_up_tight_keeps_its_edges_lengths_and_is_not_scattered(vertices, inner, gap):
    """A low-poly strap (edges 1 long, 2–4 vertices across) rolled up tight round an inner turn
    one edge across (a tape measure retracting): its vertices lie within a few edges of each other,
    so its edges grow 6–8 times against its size and are over a third of it (median |edge|² / S
    0.11–0.18), as in another order; but each keeps its length (to 4 %), which another order's
    do not (their lengths spread as the distances between random vertices do, 0.27–0.33:
    over 1.5 times UNEVEN_LENGTHS). Not scattered; the same positions in a random vertex order are."""
    rest, rolled, edges = _rolled_strip(vertices, (vertices[0] - 1.0, vertices[1] - 1.0), inner, gap)
    kept = np.linalg.norm(rolled[edges[:, 0]] - rolled[edges[:, 1]], axis=1) / np.linalg.norm(
        rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    assert 0.95 < kept.min() and kept.max() < 1.0 + 1e-9  # a winding, not a stretch
    spread = EdgeSpread(rest, edges)
    terms = spread._terms(rolled)
    assert spread.growth(rolled) > FOREIGN_GROWTH and np.median(terms) > SCATTERED_SPAN
    assert spread.uneven_lengths(rolled) < UNEVEN_LENGTHS / 10
    assert not spread.scattered(rolled)
    shuffled = rolled[np.random.default_rng(2).permutation(len(rolled))]
    assert spread.uneven_lengths(shuffled) > 1.5 * UNEVEN_LENGTHS
    assert spread.scattered(shuffled)


def test_parts_without_size_are_left_out():
    """A part whose vertices all coincide (at rest, or collapsed in a frame) has no size to compare
    with: it is left out, and a mesh with nothing left reads 1."""
    sheet, triangles = grid(6)
    point = np.zeros((3, 3))
    rest = np.concatenate([sheet, point])
    edges = _edges(np.concatenate([triangles, [[len(sheet), len(sheet) + 1, len(sheet) + 2]]]))
    assert abs(edge_growth(rest, 2.0 * rest, edges) - 1.0) < 1e-12
    collapsed = np.concatenate([np.zeros_like(sheet), [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    assert edge_growth(rest, collapsed, edges) == 1.0
