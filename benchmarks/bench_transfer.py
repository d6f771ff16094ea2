"""Transfer across meshes (issue 21, paper Fig. 15): a Blender cloth simulation re-meshed.

The target is the simulated surface sampled at the vertices of a different triangulation (a
Delaunay triangulation of jittered points of the rest sheet, each point carried through the
frames by its barycentric coordinates in the simulated triangle it lies in); the base is the
simulation's own mesh at rest, or a third triangulation of it. The map that "ships" with the data
is a vertex map: for every base vertex the nearest target vertex at rest. The ``limb`` scenes are
an articulated closed limb instead, meshed twice independently (``benchmarks/limb_scenes.py``),
like a re-meshed scan sequence of a body. Each target frame is
rebuilt on the base (``core.Transfer``, k_M = 100, k_N = 200) and compared with the target:

- Hausdorff distance / bounding-box diagonal between the surfaces (vertices, edge midpoints and
  triangle centroids of each, both directions) after the rigid alignment that best matches the
  base vertices to their mapped target vertices, for the rebuilt pose and for the unchanged base
  pose (the judged ratio is rebuilt / unchanged ≤ 0.5);
- seconds per frame, against the same-mesh truncated reconstruction of the same frame (the base's
  own simulated pose, eq. 6 with the identity map) timed in the same run.

    python -m benchmarks.bench_transfer [--scene drape|drape5k|limb|limb5k] [--frames 20,40,60] [--third]
                                        [--same-mesh all|first|none] [--target sampled|decimated|hostile]
                                        [--map nearest|template|closest] [--matched 0.7] [--extrinsic]
                                        [--hole 0.08] [--stray 0.01] [--slide 0.02]
    python -m benchmarks.bench_transfer --picture docs/images/transfer_cloth.png
    python -m benchmarks.bench_transfer --scene limb --frames 10,20,30,40 --picture docs/images/transfer_limb.png

Frames are rebuilt in the order given by one ``core.Transfer``, each warm-started from the one
before (an animation: give consecutive frames to time the steady state).

Scenes are baked headless on first use (``benchmarks/cloth_scenes.py``) and cached in
``benchmarks/output``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import core  # noqa: E402
from benchmarks import cloth_scenes, limb_scenes, remeshed_targets  # noqa: E402
from core.functional_map import closest_point_correspondence  # noqa: E402
from core.rigid_alignment import rigid_alignment  # noqa: E402

#: Scenes: (cloth_scenes spec, target vertices per base vertex, third-triangulation vertices per base vertex).
SCENES = {
    "drape": (cloth_scenes.SCENES["drape_sphere"], 1.3, 0.65),
    "drape5k": (cloth_scenes.SceneSpec("drape_sphere_5k", "drape", (72, 72), frames=64, quality=10,
                                       params=(("stiffness", 80.0), ("bending", 5.0))), 1.3, 0.65),
}


#: Procedural articulated limbs (benchmarks/limb_scenes.py): base vertices (the target has 1.3 ×).
LIMBS = {"limb": 1000, "limb5k": 5000}


def load(spec) -> cloth_scenes.ClothScene:
    """Bake (or load from the cache) a cloth_scenes spec that need not be in its SCENES table."""
    if spec.name in cloth_scenes.SCENES:
        return cloth_scenes.load_scene(spec.name)
    path = cloth_scenes.OUTPUT_DIR / f"cloth_{spec.name}.npz"
    if path.exists():
        data = np.load(path)
        if str(data["key"]) == spec.key():
            return cloth_scenes.ClothScene(spec.name, data["frames"], data["triangles"], float(data["bake_seconds"]))
    cloth_scenes.OUTPUT_DIR.mkdir(parents=True, exist_ok=True)
    frames, triangles, seconds = cloth_scenes.bake(spec)
    np.savez_compressed(path, frames=frames, triangles=triangles, key=spec.key(), bake_seconds=seconds)
    return cloth_scenes.ClothScene(spec.name, frames, triangles, seconds)


def sheet_plane(scene):
    """2-D coordinates ``(n, 2)`` of the flat rest sheet (axes along its sides) and their bounds."""
    rest = scene.rest
    origin = rest.mean(axis=0)
    nx = cloth_scenes_grid_width(scene)
    first = rest[1] - rest[0]  # along a row of Blender's grid
    second = rest[nx] - rest[0]  # along a column
    first /= np.linalg.norm(first)
    second -= first * (second @ first)
    second /= np.linalg.norm(second)
    plane = (rest - origin) @ np.stack([first, second]).T
    return plane, plane.min(0), plane.max(0)


def remesh(scene, density: float, seed: int):
    """A Delaunay triangulation of ``density × n`` jittered points of the flat rest sheet and the
    simulated frames sampled at its vertices: (frames (F, n', 3), triangles (m', 3))."""
    from scipy.spatial import Delaunay

    plane, lo, hi = sheet_plane(scene)
    side = int(round(np.sqrt(density * len(plane))))
    u, v = np.meshgrid(np.linspace(0, 1, side), np.linspace(0, 1, side))
    rng = np.random.default_rng(seed)
    interior = (u > 0) & (u < 1) & (v > 0) & (v < 1)
    u = u + interior * rng.uniform(-0.35, 0.35, u.shape) / (side - 1)
    v = v + interior * rng.uniform(-0.35, 0.35, v.shape) / (side - 1)
    points = lo + np.stack([u.ravel(), v.ravel()], axis=1) * (hi - lo)
    triangles = Delaunay(points).simplices.astype(np.int64)
    return sample_sheet(scene, plane, points, triangles)


def decimated_sheet(scene, density: float, seed: int):
    """Like :func:`remesh`, but the points are 4 × denser on one side of the sheet than on the
    other and the triangulation is then subdivided and simplified by quadric edge collapse to
    ``density × n`` vertices (``benchmarks/remeshed_targets.py``)."""
    plane, lo, hi = sheet_plane(scene)
    points, triangles = remeshed_targets.varying_density_sheet(lo, hi, int(1.5 * density * len(plane)), seed)
    flat, triangles = remeshed_targets.decimated(np.column_stack([points, np.zeros(len(points))]), triangles,
                                                 int(density * len(plane)))
    return sample_sheet(scene, plane, flat[:, :2], triangles)


def sample_sheet(scene, plane, points, triangles):
    """The simulated frames sampled at ``points`` ``(n', 2)`` of the rest sheet's ``plane``
    coordinates (each point carried by its barycentric coordinates in the simulated triangle it
    lies in), and ``triangles`` oriented as the simulated mesh: (frames (F, n', 3), triangles)."""
    from scipy.spatial import cKDTree

    triangles = np.asarray(triangles, dtype=np.int64).copy()
    # Counter-clockwise as the simulated mesh (its normals give the offset side).
    sim_tris = scene.triangles
    p = plane[sim_tris]
    sim_sign = np.sign(np.median(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])))
    q = points[triangles]
    flip = np.sign(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])) != sim_sign
    triangles[flip] = triangles[flip][:, ::-1]
    # Barycentric coordinates of every new point in the simulated triangle containing it (the
    # least outside among the 8 with the nearest centroids).
    centers = plane[sim_tris].mean(axis=1)
    _, nearest = cKDTree(centers).query(points, k=8)
    best_tri, best_w, best_out = np.zeros(len(points), int), np.zeros((len(points), 3)), np.full(len(points), np.inf)
    for j in range(nearest.shape[1]):
        tri = nearest[:, j]
        a, b, c = (plane[sim_tris[tri, k]] for k in range(3))
        m = np.stack([b - a, c - a], axis=2)
        st = np.linalg.solve(m, (points - a)[..., None])[..., 0]
        w = np.stack([1 - st.sum(axis=1), st[:, 0], st[:, 1]], axis=1)
        out = -np.minimum(w.min(axis=1), 0.0)
        better = out < best_out
        best_tri[better], best_w[better], best_out[better] = tri[better], w[better], out[better]
    frames = np.einsum("nk,fnki->fni", best_w, scene.frames[:, sim_tris[best_tri]])
    return frames, triangles


def cloth_scenes_grid_width(scene) -> int:
    """Vertices per row of the simulated grid (Blender's grid numbers them row by row)."""
    rest = scene.rest
    row = rest[1] - rest[0]
    steps = (rest[1:] - rest[:-1]) @ row / (row @ row)
    return int(np.flatnonzero(np.abs(steps - 1.0) > 1e-3)[0]) + 1


def surface_samples(vertices, triangles):
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    return np.concatenate([vertices, vertices[edges].mean(axis=1), vertices[triangles].mean(axis=1)])


def hausdorff_over_diagonal(a, a_tris, b, b_tris):
    """Symmetric Hausdorff distance between two surfaces (vertices, edge midpoints, centroids)
    over the bounding-box diagonal of ``b``."""
    from scipy.spatial import cKDTree

    sa, sb = surface_samples(a, a_tris), surface_samples(b, b_tris)
    d = max(cKDTree(sa).query(sb)[0].max(), cKDTree(sb).query(sa)[0].max())
    return d / np.linalg.norm(b.max(0) - b.min(0))


def aligned(pose, target, correspondence):
    """``pose`` moved by the rigid motion best matching its vertices to ``target[correspondence]``."""
    rotation, translation = rigid_alignment(pose, target[correspondence])
    return pose @ rotation.T + translation


def prepare(scene_name: str, third: bool, target: str = "sampled", hole: float = 0.0):
    """(scene, base frames, base triangles, target frames, target triangles). ``target``:
    ``sampled`` (the simulated surface or the limb sampled at an independent Delaunay-like
    triangulation), ``decimated`` (subdivided, then quadric edge collapse; on the sheet from
    points of varying density) or ``hostile`` (decimated, with holes, a tiny floating component,
    a seam of duplicated vertices and unreferenced vertices: ``benchmarks/remeshed_targets.py``).
    ``hole``: that share of the target's area cut out at its middle (:func:`remeshed_targets.cut_hole`)."""
    if scene_name in LIMBS:
        if third:
            raise SystemExit("--third applies to the cloth scenes only")
        n = LIMBS[scene_name]
        scene = None
        base_frames, base_tris, target_frames, target_tris = limb_scenes.limb_scene(n)
        if target != "sampled":
            dense, dense_tris = limb_scenes.sampled_capsule(3 * n, seed=4)
            rest, target_tris = remeshed_targets.decimated(dense, dense_tris, int(1.3 * n))
            phases = np.linspace(0.0, 1.0, len(base_frames))
            target_frames = np.stack([limb_scenes.pose(rest, p) for p in phases])
    else:
        spec, density, third_density = SCENES[scene_name]
        scene = load(spec)
        if target == "sampled":
            target_frames, target_tris = remesh(scene, density, seed=1)
        else:
            target_frames, target_tris = decimated_sheet(scene, density, seed=1)
        if third:
            base_frames, base_tris = remesh(scene, third_density, seed=2)
        else:
            base_frames, base_tris = scene.frames, scene.triangles
    if target == "hostile":
        _, target_tris, source = remeshed_targets.hostile(target_frames[0], target_tris, seed=5)
        target_frames = np.stack([remeshed_targets.hostile_pose(f, source, target_frames[0]) for f in target_frames])
    if hole:
        _, target_tris, kept = remeshed_targets.cut_hole(target_frames[0], target_tris, hole)
        target_frames = target_frames[:, kept]
    return scene, base_frames, base_tris, target_frames, target_tris


def template_rest(scene_name: str, scene, base_frames):
    """A third mesh's rest pose (the template of ``.vts``-style maps): an independent sampling of
    the same surface with as many vertices as the base."""
    if scene_name in LIMBS:
        return limb_scenes.sampled_capsule(len(base_frames[0]), seed=7)[0]
    return remesh(scene, 1.0, seed=3)[0][0]


def correspondence(scene_name, scene, base, target_rest, how: str, matched: float, log, stray: float = 0.0):
    """The map given to the transfer: ``nearest`` (the nearest target vertex of each base vertex
    at rest), ``template`` (two ``.vts``-style maps of a third mesh, composed) or ``closest``
    (none: the transfer's closest points); then only a random ``matched`` fraction of its entries
    kept (the others -1, unmatched), and a ``stray`` fraction sent to random target vertices."""
    if how == "closest":
        log("map: closest points at rest")
        return None
    if how == "template":
        base_vts, target_vts = remeshed_targets.template_maps(template_rest(scene_name, scene, [base]), base,
                                                              target_rest)
        vertex_map = core.template_correspondence(base_vts, target_vts, len(base), len(target_rest))
    else:
        vertex_map = closest_point_correspondence(base, target_rest)
    if matched < 1.0:
        rng = np.random.default_rng(11)
        vertex_map = vertex_map.copy()
        vertex_map[rng.random(len(base)) >= matched] = -1
    if stray:
        vertex_map = remeshed_targets.stray_matches(vertex_map, len(target_rest), stray, seed=12)
    log(f"map: {how}, {100 * np.mean(vertex_map >= 0):.1f} % of the base vertices matched")
    return vertex_map


def run(scene_name="drape", frames=(20, 40, 60), *, third=False, k_m=100, k_n=200, same_mesh="all", target="sampled",
        map_kind="nearest", matched=1.0, use_extrinsic=False, hole=0.0, stray=0.0, slide=0.0, log=print):
    scene, base_frames, base_tris, target_frames, target_tris = prepare(scene_name, third, target, hole)
    base, target_rest = base_frames[0], target_frames[0]
    vertex_map = closest_point_correspondence(base, target_rest)  # to align the results for the errors
    given_map = correspondence(scene_name, scene, base, target_rest, map_kind, matched, log, stray)
    if slide:  # the target's rest placed off the base along its longest axis (its frames where they are)
        axis = np.linalg.svd(target_rest - target_rest.mean(axis=0), full_matrices=False)[2][0]
        target_rest = target_rest + slide * np.linalg.norm(np.ptp(target_rest, axis=0)) * axis
    log(f"{scene_name}{' (third triangulation)' if third else ''}: base {len(base)} vertices, target "
        f"{len(target_rest)} vertices ({target}), k_M = {k_m}, k_N = {k_n}")
    rows = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", core.ShapeDifferenceWarning)
        t0 = time.perf_counter()
        transfer = core.Transfer(base, base_tris, target_rest, target_tris, correspondence=given_map, k_M=k_m,
                                 k_N=k_n, use_extrinsic=use_extrinsic)
        prep = time.perf_counter() - t0
    for warning in caught:  # what the transfer says about the meshes and the map
        if issubclass(warning.category, core.ShapeDifferenceWarning):
            log(f"  warned: {str(warning.message)[:160]}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", core.ShapeDifferenceWarning)
        for f in frames:
            target = target_frames[f]
            t0 = time.perf_counter()
            rebuilt = transfer.pose(target)
            seconds = time.perf_counter() - t0
            row = {
                "frame": f,
                "rebuilt": hausdorff_over_diagonal(aligned(rebuilt, target, vertex_map), base_tris, target, target_tris),
                "unchanged": hausdorff_over_diagonal(aligned(base, target, vertex_map), base_tris, target, target_tris),
                "truth": hausdorff_over_diagonal(aligned(rebuilt, base_frames[f], np.arange(len(base))), base_tris,
                                                 base_frames[f], base_tris),
                "seconds": seconds,
                "load": os.getloadavg()[0],
                "pose": rebuilt,
            }
            if same_mesh == "all" or (same_mesh == "first" and f == frames[0]):
                t0 = time.perf_counter()
                diffs = transfer.reference.shape_differences(base_frames[f], k_M=k_m, k_N=k_n)
                same = core.reconstruct(base, base_tris, diffs)
                row["same_seconds"] = time.perf_counter() - t0
                row["same"] = hausdorff_over_diagonal(aligned(same, base_frames[f], np.arange(len(base))), base_tris,
                                                      base_frames[f], base_tris)
            rows.append(row)
            log(format_row(row))
    log(f"preparation (once per base and map): {prep:.1f} s")
    return {"scene": scene_name, "rows": rows, "prep": prep, "base": base, "base_tris": base_tris,
            "target_frames": target_frames, "target_tris": target_tris}


def format_row(row) -> str:
    text = (f"  frame {row['frame']:3d}: rebuilt {100 * row['rebuilt']:5.2f} % (to its ground truth on the base "
            f"{100 * row['truth']:5.2f} %), unchanged base {100 * row['unchanged']:5.2f} %, ratio "
            f"{row['rebuilt'] / row['unchanged']:.2f}; {row['seconds']:.1f} s (load {row['load']:.1f})")
    if "same_seconds" in row:
        text += (f" (same-mesh eq. 6: {100 * row['same']:5.2f} %, {row['same_seconds']:.1f} s; ratio "
                 f"{row['seconds'] / row['same_seconds']:.2f})")
    return text


def picture(path, result):
    """Fig. 15 style: the base at rest, then per frame the re-meshed target and its rebuild."""
    from benchmarks.render import common_bounds, draw_mesh, pyplot, save

    rows = result["rows"]
    plt = pyplot()
    poses = [result["base"]] + [result["target_frames"][r["frame"]] for r in rows] + [r["pose"] for r in rows]
    bounds = common_bounds(poses)
    fig = plt.figure(figsize=(2.6 * (len(rows) + 1), 5.2))
    ax = fig.add_subplot(2, len(rows) + 1, 1, projection="3d")
    base_tris = result["base_tris"]
    draw_mesh(ax, result["base"], base_tris, np.full(len(base_tris), 0.25), bounds,
              title=f"base ({len(result['base'])} vertices)")
    for j, row in enumerate(rows):
        ax = fig.add_subplot(2, len(rows) + 1, j + 2, projection="3d")
        tt = result["target_frames"][row["frame"]]
        draw_mesh(ax, tt, result["target_tris"], np.full(len(result["target_tris"]), 0.8), bounds,
                  title=f"target frame {row['frame']} ({len(tt)} vertices)")
        ax = fig.add_subplot(2, len(rows) + 1, len(rows) + j + 3, projection="3d")
        draw_mesh(ax, row["pose"], base_tris, np.full(len(base_tris), 0.25), bounds,
                  title=f"rebuilt on the base: {100 * row['rebuilt']:.1f} % (base {100 * row['unchanged']:.1f} %)")
    what = "Articulated limb" if result["scene"] in LIMBS else "Blender cloth"
    fig.suptitle(f"Re-meshed {what} rebuilt on the base mesh (Hausdorff / diagonal), k_M = 100, k_N = 200",
                 fontsize=9)
    save(fig, path, top=0.93)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scene", default="drape", choices=sorted(SCENES) + sorted(LIMBS))
    parser.add_argument("--frames", default="20,40,60")
    parser.add_argument("--third", action="store_true", help="base = a third triangulation, not the sim mesh")
    parser.add_argument("--same-mesh", choices=["all", "first", "none"], default="all",
                        help="frames that also get the same-mesh reference reconstruction (timed)")
    parser.add_argument("--target", choices=["sampled", "decimated", "hostile"], default="sampled",
                        help="how the target is re-meshed (benchmarks/remeshed_targets.py)")
    parser.add_argument("--map", choices=["nearest", "template", "closest"], default="nearest",
                        help="nearest target vertex at rest, two .vts-style template maps composed, or none "
                             "(the transfer's closest points)")
    parser.add_argument("--matched", type=float, default=1.0, help="keep this random fraction of the map")
    parser.add_argument("--hole", type=float, default=0.0, help="cut this share of the target's area out")
    parser.add_argument("--stray", type=float, default=0.0, help="send this share of the map to random vertices")
    parser.add_argument("--slide", type=float, default=0.0,
                        help="place the target's rest off the base by this share of its diagonal, along its long axis")
    parser.add_argument("--extrinsic", action="store_true",
                        help="also transfer the offset layer and embed the thickening (Transfer(use_extrinsic=True))")
    parser.add_argument("--picture", help="write a Fig. 15-style picture to this path")
    args = parser.parse_args(argv)
    frames = tuple(int(f) for f in args.frames.split(","))
    result = run(args.scene, frames, third=args.third, same_mesh=args.same_mesh, target=args.target,
                 map_kind=args.map, matched=args.matched, use_extrinsic=args.extrinsic, hole=args.hole,
                 stray=args.stray, slide=args.slide)
    if args.picture:
        picture(args.picture, result)


if __name__ == "__main__":
    main()
