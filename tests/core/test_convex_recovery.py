"""Truncated recovery (paper §7.1–7.2, eqs. 8 and 10): core/truncated_recovery.py, with
core/triangle_constraints.py (Props. 5–6) and core/low_rank.py."""

import warnings

import numpy as np
import pytest

import core
from core import RecoveryError, ShapeDifferenceWarning, admm, truncated_recovery
from core.geometry import heron
from core.low_rank import low_rank_gram, randomly_pivoted_cholesky
from core.reference_shape import ReferenceShape
from core.triangle_constraints import CONSTRAINT_TOLERANCE, project_triangles
from core.truncated_recovery import TruncatedRecovery

from meshes import drape, grid, stretch_and_bend


def _rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def _check_constraints(squared, areas, topology):
    xt = squared[topology.triangle_edges]
    assert np.all(squared > 0)
    lengths = np.sqrt(xt)
    # Strict triangle inequality in every triangle.
    assert np.all(lengths.sum(axis=1) - 2 * lengths.max(axis=1) > 0)
    # det E3 = q / 4 >= 4 µ², up to the documented tolerance.
    assert np.all(heron(xt) >= 16 * areas**2 * (1 - 10 * CONSTRAINT_TOLERANCE))
    assert np.all(areas >= 0)


def test_projection_onto_triangle_set():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(500, 3)) * 2 + 0.5
    mu = np.abs(rng.normal(size=500))
    p = project_triangles(x, mu)
    q = heron(p)
    assert np.all(q >= 16 * mu**2 * (1 - 1e-7)) and np.all(p.sum(axis=1) > 0)
    assert np.allclose(project_triangles(p, mu * (1 - 1e-6)), p)  # feasible points stay
    # Nearest point: no feasible perturbation of p is closer to x.
    for _ in range(20):
        y = project_triangles(p + 0.05 * rng.normal(size=p.shape), mu)
        assert np.all(np.sum((p - x) ** 2, 1) <= np.sum((y - x) ** 2, 1) + 1e-9)


def test_pivoted_cholesky_of_the_edge_gram_matches_its_eigendecomposition():
    # W = (U Uᵀ)∘² of a small layer, formed explicitly here only to check the factor.
    v, t = grid(12, jitter=0.3)
    ref = ReferenceShape(v, t, use_extrinsic=False)
    solver = TruncatedRecovery(ref.base, ref.base.basis(30))
    u = solver.U
    gram = (u @ u.T) ** 2
    tolerance = 1e-6
    factor = randomly_pivoted_cholesky(lambda s: (u @ u[s].T) ** 2, np.diag(gram).copy(),
                                       tolerance=tolerance, max_rank=u.shape[0])
    residual = gram - factor @ factor.T
    exact = np.linalg.eigvalsh(gram)
    # A PSD residual whose trace is what the stopping rule promises.
    assert np.linalg.eigvalsh(residual).min() > -1e-9 * exact[-1]
    assert np.trace(residual) <= tolerance * np.trace(gram) * (1 + 1e-6)
    # Fewer columns than edges (the spectrum falls fast), at most k(k+1)/2.
    assert factor.shape[1] < min(u.shape[0], 30 * 31 // 2)
    low = low_rank_gram(factor, float(np.mean(np.diag(gram))))
    assert np.allclose(low.vectors.T @ low.vectors, np.eye(low.values.size), atol=1e-8)
    assert np.allclose(low.vectors * low.values @ low.vectors.T, factor @ factor.T, atol=1e-9 * exact[-1])
    # Leading eigenvalues agree with the exact ones.
    assert np.allclose(low.values[:50], exact[::-1][:50], rtol=1e-6)


def test_pivoted_cholesky_reserves_memory_for_the_rank_it_finds():
    # The edge program passes the number of edges as the rank bound; a Gram of rank 5 over 100,000
    # points needs a 100,000 × 5 factor. A buffer sized for the bound (N × N float64, 80 GB) was
    # requested up front: MemoryError (a 10k-vertex offset surface's 92,160 edges: 63 GiB).
    f = np.random.default_rng(0).normal(size=(100_000, 5))
    factor = randomly_pivoted_cholesky(lambda s: f @ f[s].T, np.einsum("ij,ij->i", f, f), tolerance=1e-12,
                                       max_rank=f.shape[0])
    assert factor.shape == f.shape
    probe = np.random.default_rng(1).normal(size=(f.shape[0], 3))
    assert np.allclose(factor @ (factor.T @ probe), f @ (f.T @ probe), rtol=1e-8, atol=1e-8 * np.abs(f).max() ** 2)


@pytest.fixture(scope="module")
def small_sheet():
    v, t = grid(10, jitter=0.3)
    return v, t, stretch_and_bend(v)


def test_converges_to_exact_as_k_grows(small_sheet):
    v, t, target = small_sheet
    ref = ReferenceShape(v, t, use_extrinsic=False)
    truth = ref.pose_metric(target).base
    errors = []
    for k in (15, 40, ref.topology.n_vertices - 1):
        metric = ref.recover_metric(ref.shape_differences(target, k_M=k)).base
        _check_constraints(metric.squared_lengths, metric.areas, ref.topology)
        errors.append((_rel(metric.areas, truth.areas), _rel(metric.squared_lengths, truth.squared_lengths)))
    areas_err, length_err = np.array(errors).T
    assert areas_err[-1] < areas_err[0] and length_err[-1] < length_err[0]
    assert areas_err[-1] < 1e-3 and length_err[-1] < 1e-2


@pytest.mark.parametrize("k_N", [None, 60])
def test_a_rigid_motion_is_recovered_exactly_from_truncated_differences(k_N):
    """Every difference of a rigid motion is the identity: eqs. (8) and (10) are solved about the
    base's metric with its product exact, so the base's areas and lengths come back to round-off
    whatever the low-rank edge Gram leaves out (before: squared lengths 1.7e-3 off and the pose
    1.7e-4 of the diagonal on this jittered grid at k_M = 30)."""
    from meshes import random_rotation

    v, t = grid(20, jitter=0.3)
    moved = v @ random_rotation(3).T + [0.3, -0.2, 0.5]
    differences = core.shape_differences(v, moved, t, k_M=30, k_N=k_N)
    metric = differences.reference.recover_metric(differences)
    for layer, base in ((metric.base, differences.reference.base), (metric.offset, differences.reference.offset_layer)):
        assert _rel(layer.areas, base.areas) < 1e-8
        assert _rel(layer.squared_lengths, base.squared_lengths) < 1e-8
    pose = core.reconstruct(v, t, differences)
    assert np.abs(pose - v).max() < 1e-8 * np.linalg.norm(np.ptp(v, axis=0))  # placed at the base


def test_constraints_hold_on_both_layers():
    v, t = grid(12, jitter=0.3)
    ref = ReferenceShape(v, t)
    diffs = ref.shape_differences(drape(v, 2.0), k_M=30, k_N=60)
    metric = ref.recover_metric(diffs)
    _check_constraints(metric.base.squared_lengths, metric.base.areas, ref.topology)
    _check_constraints(metric.offset.squared_lengths, metric.offset.areas, ref.offset_layer.topology)


def test_nonpositive_area_is_a_clear_error(small_sheet):
    v, t, target = small_sheet
    ref = ReferenceShape(v, t, use_extrinsic=False)
    diffs = ref.shape_differences(target, k_M=20)
    solver = ref.base.truncated_solver(diffs.area.basis)
    areas = ref.base.areas.copy()
    areas[3] = -1e-3
    with pytest.raises(RecoveryError, match="triangle 3"):
        solver.squared_lengths(diffs.conformal.product_matrix(), areas)


@pytest.mark.parametrize("settings", ["same-mesh", "transfer"])
def test_matches_conic_solver(settings):
    """The ADMM optimum of eq. (10) agrees with CLARABEL on the same (low-rank) program, with the
    same-mesh settings and with the transfer's (looser tolerance, so float32 products in the
    x-updates, and a 10× larger initial penalty)."""
    cp = pytest.importorskip("cvxpy")
    from core.transfer import RECOVERY_RHO_SCALE, RECOVERY_TOLERANCE

    options = {} if settings == "same-mesh" else {"tolerance": RECOVERY_TOLERANCE, "rho_scale": RECOVERY_RHO_SCALE}
    v, t = grid(7, jitter=0.3)
    ref = ReferenceShape(v, t, use_extrinsic=False)
    target = drape(v, 2.0)
    diffs = ref.shape_differences(target, k_M=15, k_N=30)
    solver = ref.base.truncated_solver(diffs.area.basis)
    areas = ref.pose_metric(target).base.areas
    solution = solver.squared_lengths(diffs.conformal.product_matrix(), areas, **options)
    assert solution.iterations > 0  # the constraints are active: ADMM ran
    x_admm = solution.squared_lengths
    program = solver.edge_program(diffs.conformal.product_matrix(), areas)
    eps, f, g = program.epsilon, program.factor, program.target
    topo = ref.topology
    x = cp.Variable(topo.n_edges)
    te = topo.triangle_edges
    a, c = x[te[:, 0]], x[te[:, 1]]
    b = (x[te[:, 2]] - a - c) / 2
    cons = [cp.SOC(a + c, cp.vstack([2 * b, cp.Constant(4 * areas), a - c]), axis=0)]
    objective = 0.5 * cp.sum_squares(f @ x - g) + 0.5 * eps * cp.sum_squares(x - ref.base.squared_lengths)
    cp.Problem(cp.Minimize(objective), cons).solve(solver="CLARABEL")

    def value(y):
        return 0.5 * np.sum((f @ y - g) ** 2) + 0.5 * eps * np.sum((y - ref.base.squared_lengths) ** 2)

    if settings == "transfer":
        # Stopped at a 30× looser tolerance: the squared lengths within ~1 % of the optimum (as
        # on the 5k limb's offset surface against a run to 1e-5: 1.2 % RMS), below the error the
        # change of mesh puts in transferred data; the data term, far more sensitive, is not
        # minimized to the same relative precision.
        assert _rel(x_admm, x.value) < 2e-2
        return
    # Known gap (see the report of issue 4): the accelerated ADMM stops within ~2 % of the
    # conic optimum in objective; the squared lengths agree to ~1e-4.
    assert value(x_admm) <= value(x.value) * 1.03
    assert _rel(x_admm, x.value) < 1e-2


def test_matrix_free_operators_are_adjoint_and_consistent(small_sheet):
    """⟨H x, P⟩ = ⟨x, Hᵀ P⟩ for both data terms, and the target's own metric fits eq. (5)
    differences to round-off (the data term is consistent)."""
    v, t, target = small_sheet
    ref = ReferenceShape(v, t, use_extrinsic=False)
    diffs = ref.shape_differences(target, k_M=20)
    solver = ref.base.truncated_solver(diffs.area.basis)
    rng = np.random.default_rng(0)
    k, topo = solver.k, ref.topology
    p = rng.normal(size=(k, k))
    p = p + p.T
    mu = rng.uniform(0.5, 1.5, topo.n_triangles)
    assert np.isclose(np.sum(solver.area_operator(mu) * p), mu @ solver.area_data(p), rtol=1e-10)
    c = rng.normal(size=topo.n_edges)
    lap = ref.base.assembler.from_entries(ref.base.assembler.laplacian_diagonal(c), c)
    assert np.isclose(np.sum(solver.reduce(lap) * p), c @ solver.edge_data(p), rtol=1e-10)
    truth = ref.pose_metric(target).base
    area_product = diffs.area.product_matrix()
    assert np.linalg.norm(solver.area_operator(truth.areas) - area_product) < 1e-10 * np.linalg.norm(area_product)
    conformal = ref.base.assembler.conformal_matrix(truth.squared_lengths, truth.areas)
    product = diffs.conformal.product_matrix()
    assert np.linalg.norm(solver.reduce(conformal) - product) < 1e-10 * np.linalg.norm(product)


def test_functional_map_differences_improve_on_the_reference():
    """Eq. (6) (source- and target-truncated) differences: the recovered metric is closer to the
    target's than the base pose's is, on both layers, and satisfies every constraint."""
    v, t = grid(12, jitter=0.3)
    target = drape(v, 2.0)
    ref = ReferenceShape(v, t)
    metric = ref.recover_metric(ref.shape_differences(target, k_M=30, k_N=60))
    truth = ref.pose_metric(target)
    # Measured ratios (recovered error / base pose's error): base 0.26 (µ) and 0.26 (ℓ²), offset
    # 0.61 and 0.58 (the offset surface has 3× the vertices for the same k).
    layers = ((ref.base, metric.base, truth.base, 0.5), (ref.offset_layer, metric.offset, truth.offset, 0.8))
    for layer, got, true, ratio in layers:
        assert _rel(got.areas, true.areas) < ratio * _rel(layer.areas, true.areas)
        reference_error = _rel(layer.squared_lengths, true.squared_lengths)
        assert _rel(got.squared_lengths, true.squared_lengths) < ratio * reference_error
        _check_constraints(got.squared_lengths, got.areas, layer.topology)


def test_bounded_area_program_matches_conic_solver():
    """When µ ≥ 0 is active (differences of no valid mesh), the bounded solve is the optimum of
    eq. (8): it agrees with CLARABEL on the same program."""
    cp = pytest.importorskip("cvxpy")
    v, t = grid(7, jitter=0.3)
    ref = ReferenceShape(v, t, use_extrinsic=False)
    diffs = ref.shape_differences(drape(v, 2.0), k_M=25)
    solver = ref.base.truncated_solver(diffs.area.basis)
    bad = ref.base.areas.copy()
    bad[::5] *= -3.0  # an "area difference" whose triangles partly have negative area
    product = solver.area_operator(bad)
    relative = 1e-6
    with warnings.catch_warnings():
        # Converged (a stalled line search at round-off included): no "stopped before convergence".
        warnings.simplefilter("error", ShapeDifferenceWarning)
        solution = solver.areas(product, epsilon=relative, floor=False)
    assert solution.method == "bounded"
    mu = solution.areas
    assert np.all(mu >= 0)
    eps = solution.epsilon
    assert np.isclose(eps, relative * solver.area_scale(), rtol=1e-12)
    x = cp.Variable(ref.topology.n_triangles)
    # Φᵀ A(µ) Φ is linear in µ: build it column by column (small mesh).
    columns = np.stack([solver.area_operator(e).ravel() for e in np.eye(x.size)], axis=1)
    objective = cp.sum_squares(columns @ x - product.ravel()) + eps * cp.sum_squares(x - ref.base.areas)
    cp.Problem(cp.Minimize(objective), [x >= 0]).solve(solver="CLARABEL")

    def value(y):
        return np.sum((solver.area_operator(y) - product) ** 2) + eps * np.sum((y - ref.base.areas) ** 2)

    assert value(mu) <= value(np.maximum(x.value, 0)) * (1 + 1e-4) + 1e-12
    assert _rel(mu, np.maximum(x.value, 0)) < 1e-3


def test_non_finite_difference_is_a_clear_error(small_sheet):
    v, t, target = small_sheet
    ref = ReferenceShape(v, t, use_extrinsic=False)
    diffs = ref.shape_differences(target, k_M=20)
    solver = ref.base.truncated_solver(diffs.area.basis)
    product = diffs.area.product_matrix().copy()
    product[2, 5] = np.nan
    with pytest.raises(RecoveryError, match="non-finite"):
        solver.areas(product)


def test_layers_recovered_concurrently_match_one_after_the_other(monkeypatch):
    # recover_metric runs the base and offset programs in two threads (one BLAS thread each);
    # the result must be that of the layers solved one at a time on a fresh reference.
    #
    # Tolerance. The two runs do the same arithmetic except for BLAS's summation order, which
    # depends on its thread count and kernel (bit-for-bit equal with OPENBLAS_NUM_THREADS=1, not
    # with two threads on every kernel). The programs are solved iteratively (CG for the areas,
    # ADMM for the lengths) and stopped at relative residuals CG_TOLERANCE / ADMM_TOLERANCE; any
    # point of that stopping ball around the optimum is an equally valid answer, and a round-off
    # perturbation may land on another one (measured: 1e-10 to 1.4e-5 relative under the
    # Haswell, Zen, Sandybridge and Prescott kernels with two threads). So each quantity may
    # differ by up to twice the ball's radius, measured here as the distance from a run at the
    # shipped tolerances to one converged far tighter. A threading fault (layers swapped, shared
    # state) shows as O(1) differences, far outside it.
    import warnings

    from core.errors import ShapeDifferenceWarning

    v, t = grid(14, jitter=0.2)
    target = drape(v, 1.5)

    def separately():
        reference = ReferenceShape(v, t)
        d = reference.shape_differences(target, k_M=30, k_N=60)
        return [reference.base.recover(d.area, d.conformal),
                reference.offset_layer.recover(d.offset_area, d.offset_conformal)]

    with warnings.catch_warnings():
        # Both ADMM runs converge (a stalled run, with its warning, would widen the ball).
        warnings.simplefilter("error", ShapeDifferenceWarning)
        together = ReferenceShape(v, t)
        metric = together.recover_metric(together.shape_differences(target, k_M=30, k_N=60))
        apart = separately()
        monkeypatch.setattr(truncated_recovery, "CG_TOLERANCE", 1e-2 * truncated_recovery.CG_TOLERANCE)
        monkeypatch.setattr(admm, "ADMM_TOLERANCE", 1e-2 * admm.ADMM_TOLERANCE)
        converged = separately()
    for got, expected, tight in zip((metric.base, metric.offset), apart, converged):
        for name in ("areas", "squared_lengths"):
            a, b, c = getattr(got, name), getattr(expected, name), getattr(tight, name)
            radius = np.linalg.norm(b - c)
            assert 0 < radius < 1e-2 * np.linalg.norm(b)  # the tighter run did converge further
            assert np.linalg.norm(a - b) <= 2 * radius


def test_woodbury_single_precision_products_agree_with_double():
    """(FᵀF + D) x = r through the capacitance matrix: exact in float64 against a dense solve, and
    with float32 products with F (ADMM at loose tolerances) within float32 rounding of it."""
    from core.low_rank import SplitGram

    rng = np.random.default_rng(4)
    f = rng.standard_normal((40, 300)) * np.logspace(0, -4, 40)[:, None]
    counts = rng.integers(1, 3, 300).astype(float)
    split = SplitGram(f, counts)
    r = rng.standard_normal(300)
    eps, rho = 1e-3, 0.5
    dense = np.linalg.solve(f.T @ f + np.diag(eps + rho * counts), r)
    double = split.woodbury(eps, rho).solve(r)
    single = split.woodbury(eps, rho, single=True).solve(r)
    assert _rel(double, dense) < 1e-10
    assert 1e-12 < _rel(single, dense) < 1e-5
