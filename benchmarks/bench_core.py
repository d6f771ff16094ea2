"""Full-basis pipeline speed (issue 2): per-stage seconds and peak memory of
differences → recovery → exact embedding for sheets of about 1k, 10k and 50k vertices.

    python -m benchmarks.bench_core [--sizes 32 100 224] [--pose drape|crumple]

Each size runs in a fresh subprocess so that its peak resident memory (``ru_maxrss``) is its own.
Stages: ``prepare`` (topology, offset surface, products and factorizations of the base: once per
base shape), ``differences`` (the four full-basis differences of one target), ``recovery`` (areas
and squared lengths of the target and of its offset surface), ``embedding`` (the canonical
thickening from its edge lengths, then rigid placement). The error columns are the reconstructed
pose against the target after a best rigid alignment, relative to the bounding-box diagonal.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "core"))


def target_pose(vertices: np.ndarray, pose: str) -> np.ndarray:
    from meshes import drape

    draped = drape(vertices, 3.0)  # a flat sheet rolled three quarters around a bar, twisted
    if pose == "drape":
        return draped
    rng = np.random.default_rng(3)  # plus a crumple: a non-isometric, wrinkled pose
    out = draped.copy()
    for _ in range(4):
        k = rng.normal(scale=6.0, size=(3, 3))
        out += 0.02 * np.sin(vertices @ k + rng.uniform(0, 2 * np.pi, 3))
    return out


def run_one(side: int, pose: str) -> dict:
    import core
    from core.rigid_alignment import align_rigidly
    from meshes import grid

    vertices, triangles = grid(side, jitter=0.3)
    target = target_pose(vertices, pose)
    times = {}
    start = time.perf_counter()
    reference = core.ReferenceShape(vertices, triangles)
    times["prepare"] = time.perf_counter() - start
    start = time.perf_counter()
    differences = reference.shape_differences(target)
    times["differences"] = time.perf_counter() - start
    start = time.perf_counter()
    metric = reference.recover_metric(differences)
    times["recovery"] = time.perf_counter() - start
    start = time.perf_counter()
    result = reference.place_near(reference.embed(metric), reference.base_positions)
    times["embedding"] = time.perf_counter() - start
    truth = reference.pose_metric(target)
    relative = lambda a, b: float(np.abs(a - b).max() / np.abs(b).max())  # noqa: E731
    aligned = align_rigidly(result, target)
    diagonal = float(np.linalg.norm(np.ptp(target, axis=0)))
    error = np.linalg.norm(aligned - target, axis=1)
    return {
        "vertices": int(vertices.shape[0]),
        "thickening_points": int(reference.surface.n_thickening_points),
        "seconds": times,
        "total_per_target": times["differences"] + times["recovery"] + times["embedding"],
        "area_error": max(relative(metric.base.areas, truth.base.areas), relative(metric.offset.areas, truth.offset.areas)),
        "length_error": max(
            relative(metric.base.squared_lengths, truth.base.squared_lengths),
            relative(metric.offset.squared_lengths, truth.offset.squared_lengths),
        ),
        "rms_over_diagonal": float(np.sqrt(np.mean(error**2)) / diagonal),
        "max_over_diagonal": float(error.max() / diagonal),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[32, 100, 224], help="grid side lengths")
    parser.add_argument("--pose", choices=["drape", "crumple"], default="crumple")
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(run_one(args.child, args.pose)))
        return
    header = f"{'|V|':>7} {'prepare':>8} {'diffs':>7} {'recovery':>9} {'embed':>7} {'total':>7}  " \
             f"{'µ err':>8} {'ℓ² err':>8} {'RMS/diag':>9} {'max/diag':>9} {'peak MB':>8}"
    print(f"pose: {args.pose}; seconds per stage; 'total' = differences + recovery + embedding of one target")
    print(header)
    for side in args.sizes:
        output = subprocess.run(
            [sys.executable, __file__, "--child", str(side), "--pose", args.pose],
            check=True, capture_output=True, text=True,
        ).stdout
        r = json.loads(output.strip().splitlines()[-1])
        s = r["seconds"]
        print(f"{r['vertices']:>7} {s['prepare']:>8.2f} {s['differences']:>7.2f} {s['recovery']:>9.2f} "
              f"{s['embedding']:>7.2f} {r['total_per_target']:>7.2f}  {r['area_error']:>8.1e} "
              f"{r['length_error']:>8.1e} {r['rms_over_diagonal']:>9.1e} {r['max_over_diagonal']:>9.1e} "
              f"{r['peak_rss_mb']:>8.0f}", flush=True)


if __name__ == "__main__":
    main()
