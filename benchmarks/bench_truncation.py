"""Effects of truncation (paper §8.2, Fig. 10): sweep k_M and k_N, recover the target's areas and
edge lengths from the source- and target-truncated intrinsic differences (eq. 6, the convex
programs of §7.1–7.2), and plot the relative errors of the face areas µ, edge lengths ℓ, the first
k_N eigenvalues, all |V| eigenvalues and the Laplacian's entries as upper-triangular heat maps
(k_N ≥ k_M), once with our ε (core/truncated_recovery.py: fixed, relative to the data term's
curvature) and once with the paper's rule (the largest of ε = 10·ours, ours, ours/10, … for which the
viscosity term is below 10 % of the optimal objective).

    python -m benchmarks.bench_truncation [--cube 9] [--ks 40 80 160 320] [--picture docs/images/truncation.png]

The pair: a bumpy sphere (spherified cube, 488 vertices by default — the paper uses |V| = 1000,
``--cube 13`` gives 1,016 but one recovery then took 84 s on the shared machine) and a squashed,
twisted copy, in vertex correspondence (a ground-truth map, as in the paper). Both full
eigendecompositions are computed once (dense), so every (k_M, k_N) pair reuses them.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "core"))

from core import truncated_recovery as cr  # noqa: E402
from core.inner_products import pose_products  # noqa: E402
from core.laplace_basis import LaplaceBasis  # noqa: E402
from core.reference_shape import ReferenceShape  # noqa: E402
from core.shape_difference import functional_map_differences  # noqa: E402

#: The paper's rule tries ε = 10·ours, ours, ours/10, … at most this many times.
PAPER_STEPS = 6
QUANTITIES = ("µ", "ℓ", "λ, first k_N", "λ, all |V|", "Δ entries")


def meshes(n=9):
    from meshes import cube

    v, t = cube(n)
    v = v / np.linalg.norm(v, axis=1, keepdims=True)
    v = v * (1 + 0.15 * np.sin(3 * v[:, 0]) * np.cos(2 * v[:, 1]))[:, None]
    target = v * np.array([1.0, 0.75, 0.55])
    angle = 0.8 * target[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    target = np.stack([c * target[:, 0] - s * target[:, 1], s * target[:, 0] + c * target[:, 1], target[:, 2]], axis=1)
    return v, t, target


def relative(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def eigenvalue_error(values, truth):
    keep = truth > 1e-9 * truth.max()
    return float(np.mean(np.abs(values[keep] - truth[keep]) / truth[keep]))


def errors(layer, areas, squared, truth):
    """The five relative errors of a recovered metric against the target's (``truth``)."""
    mass = layer.assembler.mass_matrix(areas)
    stiffness = layer.assembler.conformal_matrix(squared, areas)
    values = sla.eigh(stiffness.toarray(), mass.toarray(), eigvals_only=True)
    k_n = truth["k_N"]
    return (
        relative(areas, truth["areas"]),
        relative(np.sqrt(np.maximum(squared, 0)), np.sqrt(truth["squared"])),
        eigenvalue_error(values[:k_n], truth["values"][:k_n]),
        eigenvalue_error(values, truth["values"]),
        relative(stiffness.toarray(), truth["stiffness"]),
    )


def recover(solver, area_product, conformal_product, rule):
    """Areas and squared lengths with our ε (``rule="ours"``) or the paper's 10 % rule."""
    layer = solver.layer
    if rule == "ours":
        areas = solver.areas(area_product, epsilon=cr.AREA_EPSILON).areas
        squared = solver.squared_lengths(conformal_product, areas, epsilon=cr.LENGTH_EPSILON).squared_lengths
        return areas, squared, (cr.AREA_EPSILON, cr.LENGTH_EPSILON)
    chosen = []
    epsilon = 10 * cr.AREA_EPSILON
    for _ in range(PAPER_STEPS):
        solution = solver.areas(area_product, epsilon=epsilon)
        areas = solution.areas
        data = np.sum((solver.area_operator(areas) - area_product) ** 2)
        viscosity = solution.epsilon * np.sum((areas - layer.areas) ** 2)
        if viscosity < 0.1 * (data + viscosity):
            break
        epsilon /= 10
    chosen.append(epsilon)
    epsilon = 10 * cr.LENGTH_EPSILON
    for _ in range(PAPER_STEPS):
        solution = solver.squared_lengths(conformal_product, areas, epsilon=epsilon)
        squared = solution.squared_lengths
        fitted = solver.reduce(layer.assembler.conformal_matrix(squared, areas))
        data = np.sum((fitted - conformal_product) ** 2)
        viscosity = solution.epsilon * np.sum((squared - layer.squared_lengths) ** 2)
        if viscosity < 0.1 * (data + viscosity):
            break
        epsilon /= 10
    chosen.append(epsilon)
    return areas, squared, tuple(chosen)


def sweep(ks, cube=9):
    import warnings

    v, t, target = meshes(cube)
    reference = ReferenceShape(v, t, use_extrinsic=False)
    layer = reference.base
    start = time.perf_counter()
    base_values, base_functions = sla.eigh(layer.conformal.toarray(), layer.mass.toarray())
    areas, squared, mass, conformal = pose_products(layer.assembler, target)
    values, functions = sla.eigh(conformal.toarray(), mass.toarray())
    print(f"{len(v)} vertices; both full eigendecompositions: {time.perf_counter() - start:.1f} s")
    truth = {"areas": areas, "squared": squared, "values": values, "stiffness": conformal.toarray(), "k_N": len(v)}
    source = errors(layer, layer.areas, layer.squared_lengths, truth)
    print("source (the base's own metric): " + "  ".join(f"{q} {100 * e:.2f} %" for q, e in zip(QUANTITIES, source)))
    results = {}
    for k_m in ks:
        base_basis = LaplaceBasis(base_values[:k_m], base_functions[:, :k_m])
        solver = cr.TruncatedRecovery(layer, base_basis)
        for k_n in ks:
            if k_n < k_m:
                continue
            area, conformal_difference = functional_map_differences(
                base_basis, LaplaceBasis(values[:k_n], functions[:, :k_n]), mass)
            truth["k_N"] = k_n
            for rule in ("ours", "paper"):
                start = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    mu, l2, eps = recover(solver, area.product_matrix(), conformal_difference.product_matrix(), rule)
                seconds = time.perf_counter() - start
                results[(k_m, k_n, rule)] = errors(layer, mu, l2, truth)
                print(f"k_M {k_m:4d} k_N {k_n:4d} {rule:5s} ε ({eps[0]:.0e}, {eps[1]:.0e}) {seconds:5.1f} s: "
                      + "  ".join(f"{q} {100 * e:6.2f} %" for q, e in zip(QUANTITIES, results[(k_m, k_n, rule)])),
                      flush=True)
    return source, results


def picture(ks, source, results, path, n_vertices):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(QUANTITIES), figsize=(3.2 * len(QUANTITIES), 6.4))
    for column, quantity in enumerate(QUANTITIES):
        grids = {}
        for rule in ("ours", "paper"):
            grid = np.full((len(ks), len(ks)), np.nan)
            for i, k_m in enumerate(ks):
                for j, k_n in enumerate(ks):
                    if (k_m, k_n, rule) in results:
                        grid[i, j] = 100 * results[(k_m, k_n, rule)][column]
            grids[rule] = grid
        top = max(np.nanmax(grids["ours"]), np.nanmax(grids["paper"]))
        for row, rule in enumerate(("ours", "paper")):
            ax = axes[row, column]
            image = ax.imshow(grids[rule], cmap="viridis", vmin=0, vmax=top)
            for i in range(len(ks)):
                for j in range(len(ks)):
                    if np.isfinite(grids[rule][i, j]):
                        ax.text(j, i, f"{grids[rule][i, j]:.1f}", ha="center", va="center", fontsize=7,
                                color="w" if grids[rule][i, j] < 0.6 * top else "k")
            ax.set_xticks(range(len(ks)), ks, fontsize=7)
            ax.set_yticks(range(len(ks)), ks, fontsize=7)
            ax.set_xlabel("k_N", fontsize=8)
            ax.set_ylabel("k_M", fontsize=8)
            ax.set_title(f"{quantity} error, % ({'our ε' if rule == 'ours' else 'paper: ε at 10 %'})\n"
                         f"source: {100 * source[column]:.1f} %", fontsize=8)
            fig.colorbar(image, ax=ax, shrink=0.7)
    fig.suptitle("Fig. 10: relative errors of the metric recovered from truncated intrinsic differences "
                 f"(bumpy sphere → squashed, twisted; {n_vertices} vertices)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cube", type=int, default=9, help="grid size per cube face (9: 488 vertices)")
    parser.add_argument("--ks", type=int, nargs="+", default=[40, 80, 160, 320])
    parser.add_argument("--picture", default=str(ROOT / "docs" / "images" / "truncation.png"))
    args = parser.parse_args(argv)
    source, results = sweep(args.ks, args.cube)
    picture(args.ks, source, results, args.picture, len(meshes(args.cube)[0]))


if __name__ == "__main__":
    main()
