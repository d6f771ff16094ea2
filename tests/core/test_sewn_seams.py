"""The per-gap joins of core/sewn_seams.py: groups of vertices a gap's keys keep together, solved
as one unknown each at their offsets."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from core.sewn_seams import SewnFactor, sewn_groups

from meshes import grid


def _two_panels():
    """Two 6 × 5 grids side by side, the right one's left column over the left one's right column
    (no shared vertex): triangles, vertex count and the seam's pairs (left side, right side)."""
    _, tri = grid(6, 5)
    n = tri.max() + 1
    triangles = np.concatenate([tri, tri + n])
    columns = np.arange(n) % 6
    return triangles, 2 * n, np.flatnonzero(columns == 5), n + np.flatnonzero(columns == 0)


def _normal_matrix(triangles, n, weight=1e-2):
    """The in-betweens' normal matrix: the graph Laplacian of the corner edges plus ``weight``."""
    i, j = triangles.ravel(), triangles[:, [1, 2, 0]].ravel()
    rows = np.arange(i.size)
    incidence = sp.csr_matrix((np.r_[-np.ones(i.size), np.ones(i.size)], (np.r_[rows, rows], np.r_[i, j])),
                              shape=(i.size, n))
    return (incidence.T @ incidence + weight * sp.identity(n)).tocsc()


def test_the_sewn_solve_is_the_constrained_minimizer():
    """With the seam's pairs one unknown at given offsets, the solve is the minimizer of
    ½ xᵀ A x − bᵀ x with each pair at its offset: the same, to round-off, as the dense solve of its
    Lagrange (KKT) system, an independent formula; the pairs sit at their offsets exactly."""
    triangles, n, left, right = _two_panels()
    groups = sewn_groups(left, right, triangles, n)
    matrix = _normal_matrix(triangles, n)
    rng = np.random.default_rng(1)
    rhs = rng.standard_normal((n, 3))
    offsets = np.zeros((n, 3))
    first = groups.first
    offsets[groups.vertices] = rng.standard_normal((groups.vertices.size, 3)) * 1e-2
    offsets[first] = 0.0
    x = SewnFactor(matrix, groups).solve(rhs, offsets)
    others = groups.vertices[groups.vertices != first]
    partners = first[groups.vertices != first]
    p = others.size
    constraints = sp.csr_matrix((np.r_[np.ones(p), -np.ones(p)], (np.r_[np.arange(p), np.arange(p)],
                                                                   np.r_[others, partners])), shape=(p, n)).toarray()
    kkt = np.block([[matrix.toarray(), constraints.T], [constraints, np.zeros((p, p))]])
    expected = np.linalg.solve(kkt, np.r_[rhs, offsets[others]])[:n]
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    np.testing.assert_allclose(x[others] - x[partners], offsets[others], rtol=0, atol=1e-14)
    # without offsets the pairs are one place, bit for bit (one unknown copied to both)
    y = SewnFactor(matrix, groups).solve(rhs)
    assert np.array_equal(y[left], y[right])


def test_pairs_that_would_collapse_a_triangle_are_not_joined():
    """Pairs found near each other can chain along a seam onto an edge (a vertex of one panel near
    both ends of a short edge of the other): joined, that edge's triangles would collapse, so that
    group is left apart; the other pairs are joined."""
    triangles, n, left, right = _two_panels()
    a = np.r_[left, right[2]]
    b = np.r_[right, left[3]]  # right[2] with left[2] and left[3]: the ends of an edge of the left panel
    groups = sewn_groups(a, b, triangles, n)
    assert not np.isin([left[2], left[3], right[2], right[3]], groups.vertices).any()
    kept = np.setdiff1d(np.arange(left.size), [2, 3])
    assert np.array_equal(np.sort(groups.vertices), np.sort(np.r_[left[kept], right[kept]]))
    assert sewn_groups(np.array([left[2]]), np.array([left[3]]), triangles, n) is None


def test_joins_added_to_a_factor_of_fewer_solve_as_a_factor_of_their_own():
    """A gap whose seam closes further than the gap before's (more pairs joined) adds the new
    joins to that gap's factor as constraints (core.sewn_seams.AddedJoins, through their Schur
    complement): its solves, with and without offsets, are those of a factor of its own groups to
    round-off; a gap with a join across two of the earlier groups gets none from it."""
    from core.sewn_seams import AddedJoins, _added_joins

    triangles, n, left, right = _two_panels()
    matrix = _normal_matrix(triangles, n)
    earlier = sewn_groups(left[:2], right[:2], triangles, n)
    later = sewn_groups(left, right, triangles, n)
    base = SewnFactor(matrix, earlier)
    constraints = _added_joins(earlier, later)
    assert constraints.shape[0] == left.size - 2
    added, own = AddedJoins(base, later, constraints), SewnFactor(matrix, later)
    rng = np.random.default_rng(2)
    rhs = rng.standard_normal((n, 3))
    offsets = np.zeros((n, 3))
    offsets[later.vertices] = rng.standard_normal((later.vertices.size, 3)) * 1e-2
    offsets[later.first] = 0.0
    for t in (None, offsets):
        expected = own.solve(rhs, t)
        np.testing.assert_allclose(added.solve(rhs, t), expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    across = sewn_groups(left[:2], right[1::-1], triangles, n)  # left 0 with right 1, left 1 with right 0
    assert across.count == n - 2 and _added_joins(earlier, across) is None


def test_two_threads_asking_for_one_sewn_factor_share_one_base(monkeypatch):
    """Two gaps solved at once (a gap begun ahead) asking for the factor of the same groups and
    weight get the same factor, built once, and keep one base: a base built twice would leave one
    of them lost, and a later gap building on the other would differ in its last bits from run to
    run (core.sewn_seams.sewn_factor holds a lock while it looks up, builds and keeps them)."""
    import threading
    import time
    from types import SimpleNamespace

    import core.sewn_seams as sewn

    triangles, n, left, right = _two_panels()
    groups = sewn_groups(left, right, triangles, n)
    topo = SimpleNamespace(_uniform={}, n=n, laplacian=_normal_matrix(triangles, n, 0.0), mass=np.ones(n))
    built = []

    class SlowFactor(SewnFactor):  # long enough to build for the other thread to ask meanwhile
        def __init__(self, *arguments):
            built.append(self)
            time.sleep(0.2)
            super().__init__(*arguments)

    monkeypatch.setattr(sewn, "SewnFactor", SlowFactor)
    got = [None, None]

    def ask(i):
        got[i] = sewn.sewn_factor(topo, 1e-2, None, groups)

    threads = [threading.Thread(target=ask, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(built) == 1
    assert got[0] is got[1] is built[0]
    assert topo._uniform[("sewn bases", 1e-2)] == [built[0]]
