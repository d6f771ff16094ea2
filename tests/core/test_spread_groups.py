"""Groups of points within their spreads (core.spread_groups): the same groups, numbered the same,
as the connected components of every linked pair, whichever way they are found."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.csgraph import connected_components
from scipy.spatial.distance import cdist

import core.spread_groups as sg


def _components(points, spread):
    """The groups from the full distance matrix: an independent reading of the definition."""
    linked = cdist(points, points) <= spread[:, None] + spread[None, :]
    return connected_components(linked, directed=False)[1]


def _clustered(seed, n=600, d=12):
    """Points in clusters (tight ones, loose ones, exact duplicates) with spreads varying 100-fold."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-1.0, 1.0, (12, d))
    width = np.array([0.0, 1e-7, 1e-6, 3e-6, 1e-5, 3e-5] * 2)
    which = rng.integers(0, len(centres), n)
    points = centres[which] + width[which, None] * rng.standard_normal((n, d))
    spread = 10.0 ** rng.uniform(-7.0, -5.0, n)
    return points[rng.permutation(n)], spread


@pytest.mark.parametrize("batch", [1, 7, 64])
@pytest.mark.parametrize("seed", range(4))
def test_the_groups_are_the_components_of_every_linked_pair(monkeypatch, seed, batch):
    """The groups are the components of the full distance matrix's links, label for label,
    whatever number of points are queried together."""
    monkeypatch.setattr(sg, "BATCH", batch)
    points, spread = _clustered(seed)
    expected = _components(points, spread)
    assert 1 < expected.max() + 1 < len(points)  # neither all apart nor all together
    np.testing.assert_array_equal(sg.spread_groups(points, spread), expected)


@pytest.mark.parametrize("batch", [1, 64])
def test_a_chain_of_links_joins_points_far_apart(monkeypatch, batch):
    """Each point 1.9 spreads from the next links it, the chain's ends 7.6 spreads apart: one group;
    a point 2.02 spreads beyond the chain's end (linked to none) stays apart. Points listed out of
    order along the chain."""
    monkeypatch.setattr(sg, "BATCH", batch)
    step = 1e-6
    along = np.array([0.0, 1.9, 3.8, 5.7, 7.6, 9.62]) * step
    points = np.zeros((6, 12))
    points[:, 3] = along
    order = np.array([3, 0, 5, 1, 4, 2])
    spread = np.full(6, step)
    labels = sg.spread_groups(points[order], spread)
    np.testing.assert_array_equal(labels, [0, 0, 1, 0, 0, 0])
    np.testing.assert_array_equal(labels, _components(points[order], spread))


def test_thousands_of_coincident_points_are_one_group():
    """20,000 points at one place (to round-off) and 10 apart: 11 groups (2e8 pairs, not listed)."""
    rng = np.random.default_rng(5)
    points = np.ones((20_010, 12)) + 1e-15 * rng.standard_normal((20_010, 12))
    points[-10:] += 1.0 + np.arange(10)[:, None]
    spread = np.full(len(points), 0.5e-6)
    np.testing.assert_array_equal(sg.spread_groups(points, spread), np.r_[np.zeros(20_000), np.arange(1, 11)])
