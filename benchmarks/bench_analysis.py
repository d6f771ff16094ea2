"""What the shape differences show (paper §8.1 and §8.3, Figs. 7, 9, 11, 12), with the numbers the
judging criteria ask for.

    python -m benchmarks.bench_analysis [--only bumps|cloth|timing|pullback] [--poses 50]

- ``bumps`` (Fig. 7, top row): cubes with a bump on one face, its height swept from inward to
  outward and its radius in two sizes (k_M = 50, k_N = 100). Mirror-image bumps are isometric:
  the distance between their points in the intrinsic embeddings over the embedding's spread
  (should be ~0) and in the offset embeddings (should be clearly > 0).
- ``cloth`` (Fig. 9): frames of a Blender cloth simulation (benchmarks/cloth_scenes.py, 1,024
  vertices, baked headless on first use); how many frames have their nearest neighbour in the 2-D
  embedding among their time neighbours, and the length of the path through the frames in playing
  order over the shortest greedy nearest-neighbour path (≈ 1: the frames lie along a curve in order).
- ``timing``: seconds for ``--poses`` frames of that 1,024-vertex cloth, as a ratio to the
  per-pose cost of the code path before this module (``ReferenceShape.shape_differences`` with
  the default threaded BLAS), timed on a subset in the same run.
- ``pullback`` (Figs. 11–12): a sphere and a squashed, twisted copy; truncated differences
  (k_M = 100, k_N = 200) pulled back to the sphere: eigenvalue and geodesic errors against the
  target's own (potpourri3d's heat method on the target's embedding), next to the base's own.

Figures go to docs/images/ (shape_space_bumps.png, shape_space_cloth.png, pull_back.png).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "core"))

import core  # noqa: E402
from core.shape_space_pca import KIND_LABELS, KINDS  # noqa: E402

IMAGES = ROOT / "docs" / "images"


def spread(points):
    return float(np.linalg.norm(points - points.mean(axis=0), axis=1).max())


def scatter_panels(space, colors, title, path, *, cmap="viridis", connect=False, colorbar_label=""):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(16, 4.0))
    for ax, kind in zip(axes, KINDS):
        xy = space.coordinates(kind, 2)
        ratio = space.explained_variance_ratio(kind)
        if connect:
            ax.plot(xy[:, 0], xy[:, 1], "-", color="0.8", lw=0.8, zorder=1)
        points = ax.scatter(xy[:, 0], xy[:, 1], c=colors, cmap=cmap, s=28, edgecolors="k", linewidths=0.3, zorder=2)
        ax.set_title(KIND_LABELS[kind], fontsize=10)
        ax.set_xlabel(f"PC 1 ({100 * ratio[0]:.1f} %)")
        ax.set_ylabel(f"PC 2 ({100 * ratio[1]:.1f} %)" if ratio.size > 1 else "PC 2")
        ax.ticklabel_format(style="sci", scilimits=(-2, 3))
    fig.colorbar(points, ax=axes, shrink=0.8, label=colorbar_label)
    fig.suptitle(title, fontsize=11, y=1.03)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


# -- Fig. 7 ----------------------------------------------------------------------------------------
def bumps(k_m=50, k_n=100):
    from meshes import cube_with_bump

    heights = np.linspace(-0.35, 0.35, 8)
    radii = (0.5, 0.8)
    base, triangles = cube_with_bump(10, 0.0)
    poses, params = [base], [(0.0, 0.0)]
    for radius in radii:
        for h in heights:
            poses.append(cube_with_bump(10, h, radius)[0])
            params.append((h, radius))
    params = np.array(params)
    start = time.perf_counter()
    space = core.shape_space(poses, triangles, k_M=k_m, k_N=k_n)
    seconds = time.perf_counter() - start
    print(f"Fig. 7 bumps: {len(poses)} poses of a {len(base)}-vertex cube, k_M={k_m}, k_N={k_n}: {seconds:.1f} s")
    print("  mirror pair distance / spread (max over pairs, all PCA dims):")
    for kind in KINDS:
        points = space.coordinates(kind, len(poses))
        gaps = []
        for radius in radii:
            for h in heights[heights > 0]:
                up = np.flatnonzero((params[:, 1] == radius) & np.isclose(params[:, 0], h))[0]
                down = np.flatnonzero((params[:, 1] == radius) & np.isclose(params[:, 0], -h))[0]
                gaps.append(np.linalg.norm(points[up] - points[down]) / spread(points))
        ratio = space.explained_variance_ratio(kind)
        print(f"    {kind:17s} min {min(gaps):.2e}  max {max(gaps):.2e}   variance PC1/PC2 {100 * ratio[0]:.1f}/{100 * ratio[1]:.1f} %")
    colors = params[:, 0]
    scatter_panels(space, colors, "Cubes with a bump (height −0.35 … 0.35, two radii): mirror images coincide "
                   "in the intrinsic embeddings, separate with the offset", IMAGES / "shape_space_bumps.png",
                   cmap="coolwarm", colorbar_label="bump height")


# -- Fig. 9 ----------------------------------------------------------------------------------------
def curve_scores(xy):
    """How well the playing order follows the embedded curve: the share of frames whose nearest
    neighbour is the previous or next frame, and the length of the path through the frames in
    playing order over the shortest greedy nearest-neighbour path (best start): ~1 or below when
    the frames lie along a curve in their order (a closed curve, as a motion that returns to its
    start, is fine for both)."""
    distance = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    np.fill_diagonal(distance, np.inf)
    nearest = distance.argmin(axis=1)
    neighbours = float(np.mean(np.abs(nearest - np.arange(len(xy))) == 1))
    playing = float(sum(distance[i, i + 1] for i in range(len(xy) - 1)))
    shortest = np.inf
    for start in range(len(xy)):
        order, length = [start], 0.0
        while len(order) < len(xy):
            row = distance[order[-1]].copy()
            row[order] = np.inf
            order.append(int(row.argmin()))
            length += row[order[-1]]
        shortest = min(shortest, length)
    return neighbours, playing / shortest


def cloth_frames(count):
    from benchmarks.cloth_scenes import load_scene

    scene = load_scene("drape_sphere")
    frames = scene.frames[:: max(1, (len(scene.frames) - 1) // (count - 1))][:count]
    return scene, frames


def cloth(count=24, k_m=50, k_n=100, figure=True):
    scene, frames = cloth_frames(count)
    start = time.perf_counter()
    space = core.shape_space(frames, scene.triangles, k_M=k_m, k_N=k_n)
    seconds = time.perf_counter() - start
    print(f"Fig. 9 cloth: {len(frames)} frames of drape_sphere ({frames.shape[1]} vertices), k_M={k_m}, "
          f"k_N={k_n}: {seconds:.1f} s")
    for kind in KINDS:
        xy = space.coordinates(kind, 2)
        neighbours, path = curve_scores(xy)
        ratio = space.explained_variance_ratio(kind)
        print(f"    {kind:17s} nearest is a time neighbour {100 * neighbours:5.1f} %  playing-order path / shortest {path:.2f}  "
              f"variance PC1/PC2 {100 * ratio[0]:.1f}/{100 * ratio[1]:.1f} %")
    if not figure:
        return
    blender_image(space, IMAGES / "shape_space_blender_image.png")
    scatter_panels(space, np.arange(len(frames)), "Frames of a cloth simulation (drape over a sphere), coloured by "
                   "frame: the offset embeddings recover the playing order", IMAGES / "shape_space_cloth.png",
                   connect=True, colorbar_label="frame index")


def blender_image(space, path):
    """The picture the Shape Space operator draws into a Blender image (NumPy raster, bitmap font)."""
    import importlib.util

    import matplotlib.image

    # operators/ is a package of the extension (relative imports of bridge, bpy); this module of
    # it is bpy-free, so load it by path.
    spec = importlib.util.spec_from_file_location("analysis_plot", ROOT / "operators" / "analysis_plot.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    shape_space_image = module.shape_space_image

    canvas = shape_space_image({kind: space.coordinates(kind, 2) for kind in KINDS},
                               {kind: space.explained_variance_ratio(kind) for kind in KINDS})
    matplotlib.image.imsave(path, np.clip(canvas.pixels, 0.0, 1.0))


# -- speed -----------------------------------------------------------------------------------------
def timing(count=50, k_m=50, k_n=100, baseline_poses=4):
    from core.reference_shape import ReferenceShape

    scene, frames = cloth_frames(count)
    t = scene.triangles
    # Reference: the per-pose cost of the previous path (a ReferenceShape per collection, default
    # threaded BLAS), on a few poses of the same collection in the same run.
    reference = ReferenceShape(frames[0], t)
    reference.shape_differences(frames[1], k_M=k_m, k_N=k_n)  # base bases, as shape_space prepares them
    start = time.perf_counter()
    for pose in frames[1 : 1 + baseline_poses]:
        reference.shape_differences(pose, k_M=k_m, k_N=k_n)
    per_pose_before = (time.perf_counter() - start) / baseline_poses
    start = time.perf_counter()
    core.shape_space(frames, t, k_M=k_m, k_N=k_n)
    ours = time.perf_counter() - start
    start = time.perf_counter()
    core.shape_space(frames, t, k_M=k_m, k_N=None)
    eq5 = time.perf_counter() - start
    print(f"Speed: {len(frames)} poses of {frames.shape[1]} vertices, k_M={k_m}:")
    print(f"  shape_space k_N={k_n}: {ours:.1f} s ({ours / len(frames):.2f} s/pose); before: "
          f"{per_pose_before:.2f} s/pose -> {per_pose_before * len(frames):.0f} s; ratio {per_pose_before * len(frames) / ours:.1f}x")
    print(f"  shape_space k_N=None (eq. 5): {eq5:.1f} s ({eq5 / len(frames):.3f} s/pose), {per_pose_before * len(frames) / eq5:.0f}x")


# -- Figs. 11–12 -----------------------------------------------------------------------------------
def squashed_twisted(vertices):
    out = vertices * np.array([1.0, 0.75, 0.55])
    angle = 0.8 * out[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * out[:, 0] - s * out[:, 1], s * out[:, 0] + c * out[:, 1], out[:, 2]], axis=1)


def pullback(k_m=100, k_n=200):
    import potpourri3d as pp3d
    import scipy.linalg as sla
    from meshes import icosphere

    v, t = icosphere(3)
    target = squashed_twisted(v)
    start = time.perf_counter()
    differences = core.shape_differences(v, target, t, k_M=k_m, k_N=k_n, use_extrinsic=False)
    pulled = core.pull_back(v, t, differences)
    seconds = time.perf_counter() - start
    exact = core.pull_back(v, t, core.shape_differences(v, target, t, use_extrinsic=False))
    base = core.pull_back(v, t, core.shape_differences(v, v, t, use_extrinsic=False))
    count = 21
    truth = exact.laplacian_eigenvalues(count)[1:]
    ours = pulled.laplacian_eigenvalues(count)[1:]
    own = base.laplacian_eigenvalues(count)[1:]
    rel = lambda a: np.abs(a - truth) / truth  # noqa: E731
    print(f"Fig. 11 pull-back: {len(v)}-vertex sphere -> squashed twisted, k_M={k_m}, k_N={k_n}: {seconds:.1f} s")
    print("  λ2..λ21  base  " + " ".join(f"{x:6.1f}" for x in own))
    print("           target" + " ".join(f"{x:6.1f}" for x in truth))
    print("           ours  " + " ".join(f"{x:6.1f}" for x in ours))
    print(f"  eigenvalue error: base mean {100 * rel(own).mean():.1f} % (max {100 * rel(own).max():.1f}), "
          f"pulled back mean {100 * rel(ours).mean():.2f} % (max {100 * rel(ours).max():.2f}); "
          f"ratio {rel(ours).mean() / rel(own).mean():.3f}")
    mass = np.bincount(t.ravel(), np.repeat(core.ReferenceShape(target, t, use_extrinsic=False).base.areas / 3, 3))
    solver = pp3d.MeshHeatMethodDistanceSolver(target, t, use_robust=True)
    err = lambda d, ref: np.sqrt(np.sum(mass * (d - ref) ** 2) / np.sum(mass * ref**2))  # noqa: E731
    rows = []
    for source in (0, 100, 300, 500):
        heat = solver.compute_distance(source)
        rows.append((err(base.geodesic_distances(source), heat), err(pulled.geodesic_distances(source), heat),
                     err(exact.geodesic_distances(source), heat)))
    rows = np.array(rows)
    print(f"  geodesic L2 error vs the target's heat-method distances (4 sources): base {100 * rows[:, 0].mean():.1f} %, "
          f"pulled back {100 * rows[:, 1].mean():.2f} %, full-basis pull-back {100 * rows[:, 2].mean():.1e} %; "
          f"ratio {rows[:, 1].mean() / rows[:, 0].mean():.3f}")
    energies = exact.wks_energies(50, k=100)
    wks = [x.wave_kernel_signature(energies, k=100) for x in (base, pulled, exact)]
    wks_err = [np.linalg.norm(w - wks[2]) / np.linalg.norm(wks[2]) for w in wks[:2]]
    print(f"  WKS relative error (50 energies, 100 eigenpairs): base {100 * wks_err[0]:.1f} %, pulled back {100 * wks_err[1]:.1f} %")
    figure_pullback(v, t, target, base, pulled, exact, truth, own, ours)


def figure_pullback(v, t, target, base, pulled, exact, truth, own, ours):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(15, 8))
    source = 0
    rows = [("Base (sphere)", v, base), ("Pulled back to the sphere", v, pulled), ("Target (its own)", target, exact)]
    d_max = exact.geodesic_distances(source).max()
    for column, (name, positions, metric) in enumerate(rows):
        for row, (what, values, cmap, limits) in enumerate(
            [("geodesic distance from vertex 0", metric.geodesic_distances(source), "magma", (0, d_max)),
             ("eigenfunction 6", metric.eigenfunctions(6)[:, 5], "RdBu_r", None)]):
            ax = fig.add_subplot(2, 4, row * 4 + column + 1, projection="3d")
            face_values = values[t].mean(axis=1)
            lo, hi = limits if limits else (-np.abs(face_values).max(), np.abs(face_values).max())
            colors = plt.get_cmap(cmap)((face_values - lo) / (hi - lo))
            collection = ax.plot_trisurf(positions[:, 0], positions[:, 1], positions[:, 2], triangles=t, linewidth=0)
            collection.set_facecolors(colors)
            ax.set_box_aspect(np.ptp(positions, axis=0))
            ax.view_init(elev=25, azim=-60)
            ax.set_axis_off()
            ax.set_title(f"{name}\n{what}", fontsize=9)
    ax = fig.add_subplot(1, 4, 4)
    index = np.arange(2, 2 + len(truth))
    ax.plot(index, own, "o-", label="base (sphere)")
    ax.plot(index, truth, "s-", label="target")
    ax.plot(index, ours, "x--", label="pulled back, k 100/200")
    ax.set_xlabel("eigenvalue index")
    ax.set_ylabel("λ")
    ax.legend(fontsize=8)
    ax.set_title("Laplacian eigenvalues (Fig. 11)", fontsize=9)
    fig.savefig(IMAGES / "pull_back.png", dpi=100, bbox_inches="tight")
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", choices=["bumps", "cloth", "timing", "pullback"])
    parser.add_argument("--poses", type=int, default=50)
    args = parser.parse_args(argv)
    IMAGES.mkdir(parents=True, exist_ok=True)
    for name, run in (("bumps", bumps), ("cloth", cloth), ("pullback", pullback),
                      ("timing", lambda: timing(args.poses))):
        if name == "cloth" and args.only in (None, name):
            cloth(k_n=None, figure=False)  # eq. (5): the same order without a per-frame eigenbasis?
        if args.only in (None, name):
            run()


if __name__ == "__main__":
    main()
