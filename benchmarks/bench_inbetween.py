"""In-betweening benchmark on Blender cloth simulations: ``core`` against the linear blend and a
per-vertex Catmull–Rom spline of the same keys, and against the cost of simulating (issue 17).

Run from the repository root (bakes the scenes with the ``bpy`` module on first use, then reads
the cache in ``benchmarks/output/``):

    python -m benchmarks.bench_inbetween --quick         # 1k scenes + the 14k tablecloth, one repeat
    python -m benchmarks.bench_inbetween                 # every scene, three repeats
    python -m benchmarks.bench_inbetween --scenes tablecloth --gaps 4 8 --protocols seq --repeats 1
    python -m benchmarks.bench_inbetween --scenes sleeve_armature_12k --protocols seq op --repeats 1
    python -m benchmarks.bench_inbetween --plot docs/images/inbetween_error.png \
        --side-by-side docs/images/inbetween_side_by_side.png

Protocols (g = gap between kept frames):

- ``seq``: keep every g-th frame as key poses of a ``core.SequenceInterpolator`` and predict every
  dropped frame i·g + j at factor j/g with ``poses(gap, factors)`` (all in-betweens of a gap at
  once). Compared with the linear blend and the per-vertex uniform Catmull–Rom spline of the same
  keys (end gaps: the missing neighbour extrapolated linearly), what Houdini, Cinema 4D and
  Blender's Mesh Cache offer;
- ``op`` (opt-in: ``--protocols seq op pair``): the keys and dropped frames of ``seq``, the sequence
  built as the *In-between Frames* operator builds it for that source (frames 0 … (K − 1)·g, step
  g): ``start`` and ``end`` chosen from the source's frames in the middle of the first and last
  gaps by :func:`core.retime.motion_ends`, the operator's own function, and the keys' frames as
  ``key_times`` (:func:`operator_options`), where ``seq`` keeps the constructor's defaults, the
  keys alone. ``seq`` is what a caller of ``core.SequenceInterpolator(keys)`` gets, ``op`` what an
  artist gets from the same keys in Blender. The protocol cell names the ends, ``op (start,
  end)``; the JSON has every sequence row's (``ends``). Timed as ``seq`` (every repeat; choosing the ends, a few milliseconds, outside the
  timing);
- ``pair``: keep frames i and i+g, predict frame i+g/2 with ``core.Interpolator(a, b).pose(0.5)``
  (two poses only; i runs over every ``--stride``-th frame).

Metrics (per predicted frame, then median or mean over frames):

- ``rms``: positional RMS error to the true frame / the true frame's bounding-box diagonal (median);
  ``÷ linear`` and ``÷ Catmull–Rom`` are ratios of medians, our median over the frames ÷ the
  peer's: issue 17's criterion ("median RMS at gaps 4/8/16 at least as close as the peer") and
  the headline;
- ``per frame`` (``seq`` and ``op``): each dropped frame's RMS error ÷ the peer's on the same frame,
  the median of those ratios ÷ linear / ÷ Catmull–Rom (JSON ``frames``: median, 90th percentile,
  largest, how many above 1). Shown beside the headline because a ratio of medians compares two
  frames that can be far apart: where the medians fall on different frames it can read above 1
  while ours is within a fraction of a percent of the peer frame by frame (an unseen bake of a silk
  flag at g = 16: 1.044 × Catmull–Rom, the per-frame median 1.002, each gap's ratio of medians at
  most 1.004), and
  below 1 while ours loses on most frames. Neither replaces the other: the ratio of medians
  weighs the frames by how far they are from the keys, the per-frame median counts them alike.
  ``pair`` rows give the per-pair median ÷ the blend there (the line under the row has more);
- ``dev``: mean relative edge-length deviation from the rest shape (frame 0); ``sim`` is the
  same on the true frames; the issue's bound is ``dev ≤ 2·dev_sim + 0.1 %``;
- ``flips``: triangles whose normal opposes the normals of both keys of the gap (sum);
- ``pairs`` (``pair``, a line under the row): each pair's RMS error ÷ the blend's, its median, 90th
  percentile, largest and how many pairs are above 1. The row's ratio is one of medians, which the
  pairs with the most motion set; "never worse than the blend" is a property of every pair;
- ``jump`` (``seq``, ``op``): the largest frame-to-frame acceleration of the whole sequence, keys
  included (RMS over the vertices of ``x[f+1] − 2 x[f] + x[f−1]``), divided by the simulation's
  largest: a pose that jumps away from its neighbours and back (a pop) shows here, not in the
  per-frame errors (the linear blend's kinks at the keys count too);
- ``s/inb``: seconds per in-between (wall clock), the preparation of the keys included (``seq``:
  the whole ``SequenceInterpolator`` construction and every gap's ``poses`` divided by the
  in-betweens; ``pair``: one ``Interpolator`` construction and ``pose``), the least over the
  repeats. Each repeat is a first request of its keys: before every timed sequence the gap worker
  (:mod:`core.gap_processes`) is started afresh and waited for until ready, outside the timing
  (:func:`fresh_worker`), since a worker serves the same keys asked again from the sequence it
  kept (nothing sent or built: cheaper than the user's first run, and the least of the repeats
  would take it); the worker's start, which a process pays once (a Blender session's first run,
  each ``python -m core retime``), is shown apart on the scene's timing line;
- ``× bake``: its ratio to Blender's cloth bake per frame of the same scene, timed in this run:
  per scene ``--repeats`` K times (default 3, 1 with ``--quick``), interleaved — a bake in a child
  process (a fresh Blender builds the scene from its spec and bakes it; the cached frames are not
  touched), then the sequences at every gap, then the next bake … — so both sides see the same
  load. The cell is the least ours ÷ the least bake with the range of the per-repeat ratios, e.g.
  ``0.083 (0.079–0.097)`` (:func:`cost_ratio` says why the least). Wall clock on both sides:
  what a user waits for, and Blender's bake keeps a second thread busy part of the time. CPU
  times (``time.process_time``, every thread; the bake's in its child) are in the line under each
  scene and, with every repeat's seconds, in the JSON. Quality comes from the first repeat; the
  later ones must give the same in-betweens bit for bit (the run stops otherwise). The two-pose
  protocol is timed in the first repeat only (a pair costs 0.3–3 × a bake's frame, nowhere near
  issue 17's 0.1 bound). ``--rebake NAME…`` re-bakes those scenes and rewrites their cached frames
  before the run (a re-bake can change the frames compared against: the 10k drape's bake is not
  bitwise repeatable); timing never needs it. A cache is otherwise re-baked only when its scene's
  parameters changed;
- ``MB``: peak resident memory of a child process that prepares the keys and computes the
  in-betweens of the sequence (``--memory``; the ``seq`` protocol's), its gap worker's added, and
  what the child's peak holds (:class:`HeapWatch`: glibc's heap in use and freed but kept, the
  libraries, the rest).
"""

from __future__ import annotations

import argparse
import hashlib
import inspect
import json
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.cloth_scenes import SCENES, load_scene  # noqa: E402
from core.errors import ShapeDifferenceWarning  # noqa: E402
from core.retime import motion_ends  # noqa: E402
from core.sequence_inbetweens import SequenceInterpolator  # noqa: E402
from core.two_pose_inbetweens import Interpolator  # noqa: E402

QUICK_SCENES = ["drape_sphere", "fall_box", "tablecloth"]
#: The protocols that in-between a sequence of keys (every g-th frame), each dropped frame predicted.
SEQUENCE_PROTOCOLS = ("seq", "op")
LARGE_SCENES = ["drape_sphere_hd", "tablecloth", "sheet_cube_50k", "sheet_cube_100k", "hang_10k", "flag_soft_10k",
                "flag_soft_20k", "banner_10k", "curtain_ball_15k", "balloon_10k", "two_sheets_10k", "lift_10k",
                "flag_leather_12k", "flag_denim_12k", "sleeve_armature_12k"]
#: Scenes whose two-pose protocol runs on 8 start frames per gap (a pair costs seconds there); the
#: others on every ``--stride``-th start frame: with 8 of 24 the 10k drape's median at g = 16 was
#: 1.049 × the blend's against 0.995 over all 24 (its pairs span two decades of RMS).
PAIR_SAMPLED_SCENES = ["sheet_cube_50k", "sheet_cube_100k"]
#: Scenes drawn by ``--plot`` (each gets one of the ten colours of Matplotlib's cycle; all nineteen
#: would crowd it): the quick ones, the 10k drape, the hanging sheet, the soft flag and the curtain.
PLOT_SCENES = ["drape_sphere", "fall_box", "tablecloth", "drape_sphere_hd", "hang_10k", "flag_soft_10k", "curtain_ball_15k"]


def unique_edges(triangles: np.ndarray) -> np.ndarray:
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


class Metrics:
    """Error measures of predicted poses against the true frames of one scene."""

    def __init__(self, frames: np.ndarray, triangles: np.ndarray):
        self.triangles = triangles
        self.edges = unique_edges(triangles)
        self.rest = self.lengths(frames[0])

    def lengths(self, x):
        return np.linalg.norm(x[self.edges[:, 0]] - x[self.edges[:, 1]], axis=1)

    def normals(self, x):
        t = self.triangles
        return np.cross(x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]])

    def __call__(self, pose, true, key_a, key_b) -> dict:
        diag = np.linalg.norm(true.max(0) - true.min(0))
        n = self.normals(pose)
        flips = (np.einsum("ij,ij->i", n, self.normals(key_a)) < 0) & (np.einsum("ij,ij->i", n, self.normals(key_b)) < 0)
        return {
            "rms": float(np.sqrt(np.mean(np.sum((pose - true) ** 2, axis=1))) / diag),
            "dev": float(np.mean(np.abs(self.lengths(pose) / self.rest - 1.0))),
            "flips": int(flips.sum()),
            "nan": int(not np.isfinite(pose).all()),
        }


def catmull_rom(keys: np.ndarray, gap: int, s: float) -> np.ndarray:
    """Per-vertex uniform Catmull–Rom spline of ``keys`` (K, n, 3) at factor ``s`` of ``gap``;
    a missing neighbour at either end is the linear extrapolation of the last two keys."""
    p1, p2 = keys[gap], keys[gap + 1]
    p0 = keys[gap - 1] if gap >= 1 else 2 * p1 - p2
    p3 = keys[gap + 2] if gap + 2 < len(keys) else 2 * p2 - p1
    s2, s3 = s * s, s * s * s
    return 0.5 * (2 * p1 + (p2 - p0) * s + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s2 + (3 * p1 - p0 - 3 * p2 + p3) * s3)


def largest_jump(pose_at, count: int) -> float:
    """Largest RMS over the vertices of the second difference ``x[f+1] − 2 x[f] + x[f−1]`` of
    the poses ``pose_at(f)`` (n, 3), f = 0 … count − 1."""
    largest, before, last = 0.0, None, None
    for f in range(count):
        x = pose_at(f)
        if before is not None:
            largest = max(largest, float(np.sqrt(np.mean(np.sum((x - 2.0 * last + before) ** 2, axis=1)))))
        before, last = last, x
    return largest


def _sequence_jumps(frames, keys, g, predicted) -> dict:
    """``largest_jump`` of ours, the blend and Catmull–Rom over the kept span of a sequence
    (frames 0 … (K − 1)·g), each divided by the simulated frames'."""
    count = (len(keys) - 1) * g + 1

    def series(inside):
        return lambda f: keys[f // g] if f % g == 0 else inside(f // g, f % g)

    truth = largest_jump(lambda f: frames[f], count)
    return {
        "ours": largest_jump(series(lambda k, j: predicted[k][j - 1]), count) / truth,
        "blend": largest_jump(series(lambda k, j: (1 - j / g) * keys[k] + j / g * keys[k + 1]), count) / truth,
        "cubic": largest_jump(series(lambda k, j: catmull_rom(keys, k, j / g)), count) / truth,
    }


def _summary(rows: list[dict]) -> dict:
    out = {"n": len(rows)}
    out["rms"] = float(np.median([r["rms"] for r in rows]))
    out["dev"] = float(np.mean([r["dev"] for r in rows]))
    out["flips"] = int(sum(r["flips"] for r in rows))
    out["nan"] = int(sum(r["nan"] for r in rows))
    return out


def per_frame_ratios(ours: list[dict], peer: list[dict]) -> dict:
    """Each predicted frame's (or pair's) RMS error ÷ the peer's on the same frame — 0 ÷ 0 counts
    as 1, a positive error against an exact peer as infinite — and their median, 90th percentile,
    largest, and how many are above 1. The table's ratio of medians compares the two medians
    wherever they fall (the frames or pairs with the most motion set it); these compare frame by
    frame."""
    ratios = np.array([o["rms"] / p["rms"] if p["rms"] > 0 else (1.0 if o["rms"] == 0 else np.inf)
                       for o, p in zip(ours, peer)])
    with np.errstate(invalid="ignore"):  # interpolating toward an infinite ratio: NaN, taken as infinite
        p90 = float(np.percentile(ratios, 90))
    return {"median": float(np.median(ratios)), "p90": np.inf if np.isnan(p90) else p90,
            "max": float(ratios.max()), "above": int((ratios > 1.0).sum()), "n": len(ratios)}


def operator_options(frames, keyed) -> dict:
    """The ``SequenceInterpolator`` keyword arguments besides the core settings that the *In-between
    Frames* operator (``operators/frames.py``) gives a sequence keyed on frames ``keyed`` (ints,
    strictly increasing, evenly spaced) of the source ``frames`` ((F, n, 3), or a dict frame →
    (n, 3)), for a frame range that ends on the last key (no shorter last gap): ``start`` and
    ``end`` from :func:`core.retime.motion_ends` — the operator's function, fed the same frames —
    and the keys' frames as ``key_times``."""
    keyed = [int(frame) for frame in keyed]
    return {**motion_ends(frames, keyed, []), "key_times": keyed}


def sequence_ends(options: dict) -> dict:
    """``start`` and ``end`` of the ``SequenceInterpolator`` given ``options``: theirs, else the
    constructor's defaults (``motion_ends`` leaves them out where the keys do not tell)."""
    defaults = inspect.signature(SequenceInterpolator).parameters
    return {name: options.get(name, defaults[name].default) for name in ("start", "end")}


def format_pairs(e: dict) -> str:
    p = e["pairs"]
    return (f"  {e['scene']} g = {e['gap']} pairs: ours ÷ blend per pair median {p['median']:.3f}, 90th percentile "
            f"{p['p90']:.3f}, largest {p['max']:.3f}, {p['above']} of {p['n']} above 1")


def _poses(seq, gap, factors):
    """All in-betweens of one gap (the batch API when this ``core`` has it)."""
    if hasattr(seq, "poses"):
        return seq.poses(gap, factors)
    return np.stack([seq.pose(gap, f) for f in factors])


def _timed(compute, *args):
    """``compute(*args)`` and its seconds: ``(result, wall, cpu)``; the CPU time counts every thread
    of this process (the in-betweens use threads from ``CONCURRENT_VERTICES`` on) and the second
    process a sequence shares its gaps with (``core.gap_processes``, its start included where the
    sequence started it)."""
    worker = _worker_cpu()
    wall, cpu = time.perf_counter(), time.process_time()
    out = compute(*args)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return out, wall, cpu + _worker_cpu() - worker


def _worker_cpu() -> float:
    """CPU seconds of the processes this one's sequences have shared gaps with (0 for a core without them)."""
    try:
        from core.gap_processes import worker_cpu
    except ImportError:
        return 0.0
    return worker_cpu()


def kept_keys(frames: np.ndarray, g: int) -> np.ndarray:
    """The keys of the sequence protocol: every ``g``-th of ``frames`` (F, n, 3) from the first,
    up to the last frame a whole number of gaps reaches."""
    return frames[: (len(frames) - 1) // g * g + 1: g]


def _fingerprint(arrays) -> str:
    """SHA-1 of the arrays' bytes: the repeats' in-betweens compared bit for bit."""
    h = hashlib.sha1()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def cost_ratio(ours, bake) -> dict:
    """Cost of an in-between against Blender's bake per frame from repeated timings (seconds; the
    r-th of ``ours`` taken right after the r-th of ``bake``): ``ratio`` = least ours ÷ least bake,
    and ``low`` / ``high`` the least and largest per-repeat ratio ``ours[r] / bake[r]``.

    Least ÷ least because load from other processes only ever adds time: each side's least over
    the repeats is its nearest to its cost on an idle machine, whereas a per-repeat ratio mixes
    two moments of a shared machine (three runs of the balloon at g = 4 under load: least ÷ least
    0.080–0.105, the per-repeat ratios' median 0.101–0.149). Every repeat is a first request of its
    keys (:func:`fresh_worker`): the least is no repeat's discount. The per-repeat range
    (which always contains the ratio when both sides have every repeat) shows how far a single run
    could land."""
    ours, bake = np.asarray(ours, dtype=float), np.asarray(bake, dtype=float)
    if ours.size == 0 or bake.size == 0 or not (bake > 0).all():
        raise ValueError(f"cost_ratio needs timings and positive bake times: ours {ours}, bake {bake}")
    per_repeat = ours[: bake.size] / bake[: ours.size]
    return {"ratio": float(ours.min() / bake.min()), "low": float(per_repeat.min()),
            "high": float(per_repeat.max()), "repeats": int(per_repeat.size)}


def format_cost(cost: dict) -> str:
    """``0.083 (0.079–0.097)``: the ratio, and the per-repeat range when there are two repeats or more."""
    text = f"{cost['ratio']:.3f}"
    return text + (f" ({cost['low']:.3f}–{cost['high']:.3f})" if cost["repeats"] > 1 else "")


def _middle_pose(a, b, triangles):
    """The two-pose in-between half-way, its interpolator's preparation included."""
    return Interpolator(a, b, triangles).pose(0.5)


def _time_sequence(keys, triangles, factors, **options):
    """Every in-between of a sequence with its keys' preparation: ``(predicted, wall, cpu, start)``;
    ``options`` go to ``SequenceInterpolator`` (none: its defaults, the ``seq`` protocol). Each
    call is a first request of its keys: :func:`fresh_worker` before the timing, whose start's CPU
    seconds are ``start`` (0 where no worker started), outside ``cpu``."""
    def compute():
        seq = SequenceInterpolator(keys, triangles, **options)
        return [_poses(seq, k, factors) for k in range(len(seq))]

    start = fresh_worker(np.shape(keys[0])[0], len(keys) - 1)
    predicted, wall, cpu = _timed(compute)
    # ended once its CPU is read: idle for core.gap_worker.IDLE_SECONDS, it would let its sequence go and
    # trim its heap inside a later timing (a pair's, which counts the worker's CPU too)
    _end_worker()
    return predicted, wall, cpu, start or 0.0


def _end_worker() -> bool:
    """End the session's gap worker (:func:`core.gap_processes.shut_down`; its CPU stays counted by
    :func:`_worker_cpu`); False for a core without one."""
    try:
        from core import gap_processes
    except ImportError:
        return False
    gap_processes.shut_down()
    return True


def fresh_worker(vertices: int, gaps: int, timeout: float = 120.0) -> float | None:
    """Before a timed sequence of ``vertices`` vertices and ``gaps`` key gaps, outside the timing: the
    session's gap worker (:mod:`core.gap_processes`) ended and, where the sequence will share its
    gaps, a new one started and waited for until ready (:func:`_time_sequence` ends it again after
    the timing). Returns the CPU seconds its start took (a fresh interpreter importing NumPy, SciPy
    and the core, as the worker said when ready); None where no worker is ready (a core without
    one, a sequence that shares no gaps, or not ready within ``timeout`` seconds).

    A worker keeps the last sequence it built and serves the same keys asked again from it (nothing
    sent or built, its caches warm), so the repeats of one cell timed back to back (a run of one
    gap) would time a cheaper run than a user's first, and the least of the repeats would take it
    (measured: docs/benchmarks.md, *How the cost column is measured*). A worker that has seen no
    keys makes each repeat a first request of its keys, whatever the worker's rules for taking a job
    become. Its start is left out of the timing because a user does not pay it at each request: the
    worker is kept for the whole Python process (:func:`core.gap_processes.kept_worker`; idle, it lets
    its sequence go but keeps running), so in Blender the session's first *In-between Frames* or
    *Retime* run starts it (before reading the keys, its start overlapping that) and the later runs
    find it ready; but every ``python -m core retime`` (each farm task of two gaps or more) is a
    process of its own and pays it. :func:`run_scene` reports it beside the cost column
    (:func:`format_timing`), as the bake's column leaves out Blender's start and the scene's build."""
    if not _end_worker():
        return None
    from core import gap_processes

    if not gap_processes.start_worker(int(vertices), int(gaps)):
        return None
    worker = gap_processes._worker
    deadline = time.monotonic() + timeout
    while worker is not None and worker.alive and not worker.ready and time.monotonic() < deadline:
        time.sleep(0.005)
    return worker.cpu if worker is not None and worker.alive and worker.ready else None


def run_scene(name: str, gaps, *, stride: int = 2, protocols=("seq", "pair"), repeats: int = 1,
              bake_timer=None, max_pairs=None, log=print):
    """Rows of the table for one scene. Blender's bake is timed ``repeats`` times by
    ``bake_timer(name) -> (wall, cpu)`` seconds per frame (default :func:`bake_per_frame`), each
    followed by a timing of the sequences at every gap, so both see the same load; the metrics come
    from the first repeat, the later ones must give the same in-betweens bit for bit. The two-pose
    protocol runs (and is timed) in the first repeat only: one pair costs 0.3–3 × a bake's frame,
    nowhere near issue 17's 0.1 bound, and its repeats would add about 13 minutes to a full run."""
    bake_timer = bake_timer or bake_per_frame
    scene = load_scene(name, verbose=True)
    frames, triangles = scene.frames, scene.triangles
    metric = Metrics(frames, triangles)
    bake = {"wall": [], "cpu": []}
    timing = {(g, p): {"wall": [], "cpu": [], "start": []} for g in gaps for p in protocols}
    entries, fingerprints, warned = {}, {}, []
    for repeat in range(repeats):
        wall, cpu = bake_timer(name)
        bake["wall"].append(wall)
        bake["cpu"].append(cpu)
        timed_now = protocols if repeat == 0 else [p for p in protocols if p in SEQUENCE_PROTOCOLS]
        for g in gaps:
            for protocol in timed_now:
                rows = {"ours": [], "blend": [], "cubic": [], "sim": []}
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always", ShapeDifferenceWarning)
                    if protocol == "pair":
                        starts = list(range(0, len(frames) - g, stride))
                        if max_pairs is not None:
                            starts = starts[:: max(1, len(starts) // max_pairs)][:max_pairs]
                        wall = cpu = 0.0
                        for i in starts:
                            a, b, true = frames[i], frames[i + g], frames[i + g // 2]
                            ours, w, c = _timed(_middle_pose, a, b, triangles)
                            wall, cpu = wall + w, cpu + c
                            rows["ours"].append(metric(ours, true, a, b))
                            rows["blend"].append(metric(0.5 * (a + b), true, a, b))
                            rows["cubic"].append(rows["blend"][-1])
                            rows["sim"].append(metric(true, true, a, b))
                        count = len(starts)
                    else:
                        keys = kept_keys(frames, g)
                        keyed = np.arange(len(keys)) * g  # the keys' frames
                        factors = np.arange(1, g) / g
                        options = operator_options(frames, keyed) if protocol == "op" else {}
                        predicted, wall, cpu, start = _time_sequence(keys, triangles, factors, **options)
                        count = len(predicted) * len(factors)
                        timing[g, protocol]["start"].append(start / count)
                        fingerprint = _fingerprint(predicted)
                        if fingerprints.setdefault((g, protocol), fingerprint) != fingerprint:
                            raise RuntimeError(f"{name} g = {g}: repeat {repeat + 1} gives other in-betweens "
                                               "than the first (the benchmark assumes deterministic outputs)")
                timing[g, protocol]["wall"].append(wall / count)
                timing[g, protocol]["cpu"].append(cpu / count)
                if repeat > 0:
                    continue
                warned.extend(str(w.message) for w in caught)
                if protocol in SEQUENCE_PROTOCOLS:
                    for k in range(len(predicted)):
                        a, b = keys[k], keys[k + 1]
                        for j, s in enumerate(factors, start=1):
                            true = frames[k * g + j]
                            rows["ours"].append(metric(predicted[k][j - 1], true, a, b))
                            rows["blend"].append(metric((1 - s) * a + s * b, true, a, b))
                            rows["cubic"].append(metric(catmull_rom(keys, k, s), true, a, b))
                            rows["sim"].append(metric(true, true, a, b))
                entry = {"scene": name, "n_vertices": frames.shape[1], "gap": g, "protocol": protocol,
                         **{key: _summary(value) for key, value in rows.items()}}
                if protocol in SEQUENCE_PROTOCOLS:
                    entry["jump"] = _sequence_jumps(frames, keys, g, predicted)
                    entry["frames"] = {"linear": per_frame_ratios(rows["ours"], rows["blend"]),
                                       "cubic": per_frame_ratios(rows["ours"], rows["cubic"])}
                    entry["ends"] = sequence_ends(options)
                else:
                    entry["pairs"] = per_frame_ratios(rows["ours"], rows["blend"])
                entries[g, protocol] = entry
    results = []
    for (g, protocol), entry in entries.items():
        ours = timing[g, protocol]
        entry.update(seconds=min(ours["wall"]), bake=min(bake["wall"]), cost=cost_ratio(ours["wall"], bake["wall"]),
                     cpu_cost=cost_ratio(ours["cpu"], bake["cpu"]),
                     timing={"ours_wall": ours["wall"], "ours_cpu": ours["cpu"],
                             "bake_wall": bake["wall"], "bake_cpu": bake["cpu"]})
        if protocol in SEQUENCE_PROTOCOLS:  # the gap worker's start, per in-between: not in the cost (fresh_worker)
            entry["timing"]["worker_start_cpu"] = ours["start"]
        results.append(entry)
        log(format_row(entry))
        if protocol == "pair":
            log(format_pairs(entry))
    log(format_timing(results))
    if warned:
        log(f"  {name}: {len(warned)} fallback warning(s), e.g. {warned[0]}")
    return results


def format_header() -> str:
    return (
        "| scene | n | g | protocol | s / in-between | × bake | RMS ours | ÷ linear | ÷ Catmull–Rom | "
        "per frame ÷ linear / ÷ Catmull–Rom | dev ours | dev sim | bound | flips ours / linear / sim | "
        "jump ours / linear / Catmull–Rom |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    )


def format_row(e: dict) -> str:
    o, b, c, s = e["ours"], e["blend"], e["cubic"], e["sim"]
    bound = 2 * s["dev"] + 0.001
    ok = "✓" if o["dev"] <= bound else "✗"
    sequence = e["protocol"] in SEQUENCE_PROTOCOLS
    cubic = f"{o['rms'] / c['rms']:.3f}" if sequence else "–"
    # the medians of the per-frame ratios; two poses: the per-pair median against the blend
    per_frame = (f"{e['frames']['linear']['median']:.3f} / {e['frames']['cubic']['median']:.3f}" if sequence
                 else f"{e['pairs']['median']:.3f} / –")
    protocol = f"op ({e['ends']['start']}, {e['ends']['end']})" if e["protocol"] == "op" else e["protocol"]
    j = e.get("jump")
    jump = f"{j['ours']:.2f} / {j['blend']:.2f} / {j['cubic']:.2f}" if j else "–"
    return (
        f"| {e['scene']} | {e['n_vertices']} | {e['gap']} | {protocol} | {e['seconds']:.4f} | "
        f"{format_cost(e['cost'])} | {o['rms']:.2e} | {o['rms'] / b['rms']:.3f} | "
        f"{cubic} | {per_frame} | {o['dev'] * 100:.2f}% {ok} | {s['dev'] * 100:.2f}% | {bound * 100:.2f}% | "
        f"{o['flips']} / {b['flips']} / {s['flips']} | {jump} |"
    )


def format_timing(entries: list[dict]) -> str:
    """A line under a scene's rows: Blender's bake per frame (wall: least and range over the
    repeats; CPU, and CPU ÷ wall: above 1 where the bake had both cores, below where other
    processes took them), the rows' cost by CPU time (least ÷ least, per-repeat range) and, for
    the sequences that started a gap worker, what its start adds to that where a process pays it
    (:func:`fresh_worker`: least ÷ least bake, per in-between of the sequence)."""
    t = entries[0]["timing"]
    wall, cpu = np.array(t["bake_wall"]), np.array(t["bake_cpu"])

    def span(values, digits):
        low, high = f"{values.min():.{digits}f}", f"{values.max():.{digits}f}"
        return low if values.size == 1 else f"{low}–{high}"

    cells = ", ".join(f"g = {e['gap']} {e['protocol']} {format_cost(e['cpu_cost'])}" for e in entries)
    repeats = f", least of {wall.size}: {span(wall, 3)}" if wall.size > 1 else ""
    started = ", ".join(f"g = {e['gap']} {e['protocol']} +{min(e['timing']['worker_start_cpu']) / cpu.min():.3f}"
                        for e in entries if any(e["timing"].get("worker_start_cpu", ())))
    start = (f"; the gap worker's start, outside these (paid once per process: a Blender session's first "
             f"run, each python -m core retime): {started}") if started else ""
    return (f"  {entries[0]['scene']}: Blender's bake {wall.min():.3f} s per frame (wall{repeats}), CPU "
            f"{cpu.min():.3f} s (CPU ÷ wall {span(cpu / wall, 2)}); by CPU time × bake: {cells}{start}")


class HeapWatch:
    """What a process's resident memory holds at its peak (Linux with glibc: ``split`` is None
    elsewhere). A thread of its own reads, every ``interval`` seconds, the resident set
    (``/proc/self/status``: ``VmRSS``, of it ``RssFile``, the mapped libraries) and glibc's heap
    (``mallinfo2``: bytes in use, bytes free but kept, bytes in blocks mapped on their own). At the
    resident peak the heap's free bytes are memory the process freed and the allocator kept: holes
    between blocks still in use, which the heap cannot hand back, and free memory at its top below
    ``core.allocator.TRIM_THRESHOLD``; resident, counted by the peak, holding no data. The live peak
    (in use plus mapped, at most) comes at another moment. Sampled: the resident peak read may lie
    below the kernel's exact ``VmHWM`` by what one interval allocates and frees. A sample costs the
    thread about 0.3 ms of CPU (``mallinfo2`` 0.06 ms of it, with glibc's heaps locked), 3.5–4.6 %
    of the 15k curtain's CPU at g = 4: used in :func:`peak_memory`'s child, never in a timed run. Off glibc
    (``core.allocator`` decides: macOS, Windows, musl) and where the kernel gives no ``RssFile``
    (before Linux 4.5) it starts no thread and ``split`` is None."""

    def __init__(self, interval: float = 0.02):
        import ctypes
        import threading

        class Mallinfo2(ctypes.Structure):
            _fields_ = [(field, ctypes.c_size_t) for field in (
                "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                "keepcost")]

        from core.allocator import _glibc

        libc = _glibc()  # None off Linux and under other C libraries (musl), as core.allocator decides
        try:
            self._mallinfo = libc.mallinfo2
            self._mallinfo.restype = Mallinfo2
            self._sample_status()
        except (OSError, AttributeError, KeyError):  # no glibc, one before 2.33 (no mallinfo2), no VmRSS / RssFile
            self._mallinfo = None
        self.interval, self.peak, self.live = interval, None, 0.0
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True, name="heap-watch")
        if self.available:
            self._thread.start()

    @property
    def available(self) -> bool:
        """Whether this platform gives the split (Linux with glibc 2.33 or later)."""
        return self._mallinfo is not None

    @staticmethod
    def _sample_status() -> tuple[float, float]:
        """The resident set and its mapped files (MB, ``VmRSS`` and ``RssFile``; KeyError where the
        kernel gives no ``RssFile``, before Linux 4.5)."""
        status = {}
        with open("/proc/self/status") as lines:
            for line in lines:
                field, _, value = line.partition(":")
                if field in ("VmRSS", "RssFile"):
                    status[field] = int(value.split()[0]) / 1024
        return status["VmRSS"], status["RssFile"]

    def _sample(self) -> dict:
        resident, libraries = self._sample_status()
        heap = self._mallinfo()
        mb = 1.0 / (1 << 20)
        return {"resident": resident, "libraries": libraries, "heap_in_use": heap.uordblks * mb,
                "heap_free": heap.fordblks * mb, "mapped": heap.hblkhd * mb}

    def _watch(self) -> None:
        while True:
            sample = self._sample()
            self.live = max(self.live, sample["heap_in_use"] + sample["mapped"])
            if self.peak is None or sample["resident"] > self.peak["resident"]:
                self.peak = sample
            if self._done.wait(self.interval):
                return

    def split(self) -> dict | None:
        """Stop watching; the sample at the resident peak (MB: ``resident``, ``libraries``,
        ``heap_in_use``, ``heap_free``, ``mapped``, and ``other``: the rest, the interpreter's own
        small-object arenas, thread stacks, BLAS buffers) and ``live_peak``, the most the heap held
        in use plus mapped at any sample; None where nothing could be read."""
        if not self.available:
            return None
        self._done.set()
        self._thread.join()
        if self.peak is None:  # the thread read nothing (a /proc without the fields)
            return None
        peak = dict(self.peak)
        peak["other"] = peak["resident"] - peak["libraries"] - peak["heap_in_use"] - peak["heap_free"] - peak["mapped"]
        peak["live_peak"] = self.live
        return peak


def peak_memory(name: str, gap: int) -> tuple[float, float, float, dict | None]:
    """Peak resident memory (MB, the kernel's ``VmHWM`` of the child's own address space:
    ``ru_maxrss`` would keep the parent's across ``exec``) of a child process that loads scene
    ``name``, prepares its keys (every ``gap``-th frame) and computes every in-between of the
    sequence; its baseline after loading and the imports too; the peak of the gap worker it
    shared gaps with (:mod:`core.gap_processes`; 0 where none ran), read before the child ends:
    the two peaks' sum bounds what the sequence held at once; and what the child's peak holds
    (:class:`HeapWatch`; None off glibc)."""
    code = f"""
import json, sys, warnings
sys.path.insert(0, {str(ROOT)!r})
import numpy as np
from benchmarks.cloth_scenes import load_scene
from core.sequence_inbetweens import SequenceInterpolator
from benchmarks.bench_inbetween import HeapWatch, _poses
scene = load_scene({name!r})
keys = np.ascontiguousarray(scene.frames[::{gap}]); triangles = scene.triangles
del scene
from core import gap_processes
def peak(pid="self"):
    for line in open(f"/proc/{{pid}}/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
base = peak()
warnings.simplefilter("ignore")
watch = HeapWatch()
seq = SequenceInterpolator(keys, triangles)
for k in range(len(seq)):
    _poses(seq, k, np.arange(1, {gap}) / {gap})
worker = gap_processes._worker
split = watch.split()
print(json.dumps([base, peak(), peak(worker.process.pid) if worker is not None and worker.alive else 0.0, split]))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    base, peak, worker, split = json.loads(out.stdout.splitlines()[-1])
    return base, peak, worker, split


def format_split(split: dict | None) -> str:
    """``peak_memory``'s split of the caller's peak, for the line under a scene ('' off glibc)."""
    if split is None:
        return ""
    return (f"; at its peak (sampled {split['resident']:.0f} MB) glibc's heap {split['heap_in_use']:.0f} MB in use "
            f"and {split['heap_free']:.0f} MB freed but kept, blocks mapped on their own {split['mapped']:.0f} MB, "
            f"libraries {split['libraries']:.0f} MB, the rest {split['other']:.0f} MB; the heap's live peak "
            f"{split['live_peak']:.0f} MB")


def analytic_sheet_memory(side: int = 317, n_keys: int = 6, gap: int = 16) -> tuple[float, float, float]:
    """Peak memory (MB) and seconds per in-between of a child that in-betweens an analytic sheet of
    ``side``² vertices (317² = 100,489) waving and curling over ``n_keys`` keys, ``gap − 1``
    in-betweens per gap: the 100k-vertex size of issue 17, without a bake."""
    code = f"""
import sys, time, warnings
sys.path.insert(0, {str(ROOT)!r})
import numpy as np
from core.sequence_inbetweens import SequenceInterpolator
def peak():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
u, v = np.meshgrid(np.linspace(0, 1, {side}), np.linspace(0, 1, {side}), indexing="ij")
i = np.arange({side} - 1)[:, None] * {side} + np.arange({side} - 1)[None, :]
quads = np.stack([i, i + {side}, i + {side} + 1, i + 1], axis=-1).reshape(-1, 4)
triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
keys = []
for k in range({n_keys}):
    t = 0.3 * k
    bend = 1.2 * t * u
    keys.append(np.stack([np.sin(bend) / max(1.2 * t, 1e-9) if k else u, v,
                          (1 - np.cos(bend)) / max(1.2 * t, 1e-9) * (k > 0) + 0.02 * np.sin(6 * v + t)],
                         axis=-1).reshape(-1, 3))
base = peak()
warnings.simplefilter("ignore")
t0 = time.perf_counter()
seq = SequenceInterpolator(keys, triangles)
for k in range(len(seq)):
    seq.poses(k, np.arange(1, {gap}) / {gap})
print(base, peak(), (time.perf_counter() - t0) / (len(seq) * ({gap} - 1)))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    base, peak, seconds = map(float, out.stdout.split()[-3:])
    return base, peak, seconds


def plot(results, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), dpi=90)
    scenes = sorted({r["scene"] for r in results})
    colors = dict(zip(scenes, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
    for scene in scenes:
        for protocol, marker in (("pair", "o"), ("seq", "s")):
            rs = sorted((r for r in results if r["scene"] == scene and r["protocol"] == protocol), key=lambda r: r["gap"])
            if not rs:
                continue
            g = [r["gap"] for r in rs]
            c = colors[scene]
            label = f"{scene} ({protocol})"
            axes[0].plot(g, [r["ours"]["rms"] for r in rs], marker=marker, color=c, label=label)
            if protocol == "pair":
                axes[0].plot(g, [r["blend"]["rms"] for r in rs], ls="--", marker="x", color=c, alpha=0.6)
                axes[1].plot(g, [r["blend"]["dev"] * 100 for r in rs], ls="--", marker="x", color=c, alpha=0.6)
                axes[1].plot(g, [r["sim"]["dev"] * 100 for r in rs], ls=":", color=c, alpha=0.8)
            axes[1].plot(g, [r["ours"]["dev"] * 100 for r in rs], marker=marker, color=c)
    for ax in axes:
        ax.set_xscale("log", base=2)
        ax.set_xlabel("gap g between kept frames")
        ax.grid(alpha=0.3)
    axes[0].set_yscale("log")
    axes[0].set_ylabel("median RMS error / bbox diagonal")
    axes[0].set_title("position (solid: ours, dashed: linear blend)")
    axes[1].set_yscale("log")
    axes[1].set_ylabel("mean |ℓ/ℓ_rest − 1|  (%)")
    axes[1].set_title("edge-length deviation (dotted: simulation)")
    axes[0].legend(fontsize=6, loc="lower right")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def side_by_side(path, scene_name="drape_sphere", gap=16, key=3):
    """True frame / linear blend / ours for the middle of one gap, coloured by edge stretch."""
    from benchmarks.render import common_bounds, draw_mesh, pyplot, save

    scene = load_scene(scene_name)
    frames, tri = scene.frames, scene.triangles
    keys = frames[::gap]
    seq = SequenceInterpolator(keys, tri)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        ours = seq.pose(key, 0.5)
    a, b = keys[key], keys[key + 1]
    true = frames[key * gap + gap // 2]
    blend = 0.5 * (a + b)
    rest = frames[0]
    metric = Metrics(frames, tri)

    def stretch(x):  # per-triangle mean relative edge change vs rest
        out = 0
        for i, j in ((0, 1), (1, 2), (2, 0)):
            out = out + np.linalg.norm(x[tri[:, i]] - x[tri[:, j]], axis=1) / np.linalg.norm(rest[tri[:, i]] - rest[tri[:, j]], axis=1)
        return out / 3 - 1

    poses = [("key frame", a), ("true frame (dropped)", true), ("linear blend", blend), ("ours", ours), ("key frame", b)]
    bounds = common_bounds([p for _, p in poses])
    fig = pyplot().figure(figsize=(12.5, 3.0), dpi=80)
    for k, (title, x) in enumerate(poses):
        ax = fig.add_subplot(1, len(poses), k + 1, projection="3d")
        rms = np.sqrt(np.mean(np.sum((x - true) ** 2, 1))) / np.linalg.norm(true.max(0) - true.min(0))
        dev = np.mean(np.abs(metric.lengths(x) / metric.rest - 1))
        draw_mesh(ax, x, tri, np.clip(stretch(x) / 0.05, -1, 1) * 0.5 + 0.5, bounds,
                  title=f"{title}\nRMS {rms:.1e}, edges {dev * 100:.1f}%")
    fig.suptitle(
        f"{scene_name}: frames {key * gap} and {(key + 1) * gap} kept, frame {key * gap + gap // 2} predicted "
        "(colour: edge stretch vs rest, blue −5% … red +5%)", fontsize=9)
    save(fig, path, top=0.9)


def exaggeration_check(log=print):
    """Factor 1.5 of an isometric motion (a strip bending about an axis): edge deviation."""
    n = 40
    u, v = np.meshgrid(np.linspace(0, 2.0, n), np.linspace(0, 0.5, 8))
    tri = []
    for j in range(7):
        for i in range(n - 1):
            a = j * n + i
            tri += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    tri = np.array(tri)

    def bent(angle):
        if angle == 0:
            return np.stack([u.ravel(), v.ravel(), np.zeros(u.size)], 1)
        r = 2.0 / angle
        th = u.ravel() / r
        return np.stack([r * np.sin(th), v.ravel(), r * (1 - np.cos(th))], 1)

    a, b = bent(0.0), bent(np.pi / 2)
    metric = Metrics(np.stack([a]), tri)
    for f in (1.5, 2.0, -0.5):
        ours = Interpolator(a, b, tri).pose(f)
        lin = (1 - f) * a + f * b
        log(f"exaggeration factor {f}: edge dev ours {np.mean(np.abs(metric.lengths(ours) / metric.rest - 1)) * 100:.3f}%"
            f", linear extrapolation {np.mean(np.abs(metric.lengths(lin) / metric.rest - 1)) * 100:.3f}%, "
            f"RMS to the true bend {np.sqrt(np.mean(np.sum((ours - bent(f * np.pi / 2)) ** 2, 1))):.2e} "
            f"(linear {np.sqrt(np.mean(np.sum((lin - bent(f * np.pi / 2)) ** 2, 1))):.2e})")


def bake_per_frame(name: str) -> tuple[float, float]:
    """Blender's cloth bake of scene ``name`` timed in a child process (a fresh Blender builds the
    scene from its spec and bakes it, :func:`benchmarks.cloth_scenes.time_bake`; Blender's memory
    and threads stay out of this process and the cached frames are not touched): ``(wall, cpu)``
    seconds per frame."""
    code = (f"import sys; sys.path.insert(0, {str(ROOT)!r}); from benchmarks.cloth_scenes import SCENES, time_bake; "
            f"print(*time_bake(SCENES[{name!r}]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    wall, cpu = map(float, out.stdout.split()[-2:])
    return wall, cpu


def rebake(name: str) -> None:
    """Bake scene ``name`` again in a child process and rewrite its cached frames."""
    code = (f"import sys; sys.path.insert(0, {str(ROOT)!r}); from benchmarks.cloth_scenes import load_scene; "
            f"load_scene({name!r}, rebake=True, verbose=True)")
    subprocess.run([sys.executable, "-c", code], check=True)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--scenes", nargs="*", default=None)
    parser.add_argument("--gaps", nargs="*", type=int, default=[4, 8, 16])
    parser.add_argument("--stride", type=int, default=2, help="pair protocol: every stride-th start frame")
    parser.add_argument("--protocols", nargs="*", default=["seq", "pair"], choices=["seq", "op", "pair"],
                        help="seq: SequenceInterpolator's defaults; op: the ends the In-between Frames "
                             "operator chooses for the source (opt-in); pair: two poses")
    parser.add_argument("--quick", action="store_true",
                        help=f"scenes {' '.join(QUICK_SCENES)}, one repeat, pairs at most 8 per gap")
    parser.add_argument("--repeats", type=int, default=None,
                        help="times Blender's bake and the sequences are timed per scene, interleaved "
                             "(default 3, 1 with --quick); the table gives least ÷ least and the "
                             "per-repeat range")
    parser.add_argument("--rebake", nargs="+", default=[], metavar="SCENE",
                        help="re-bake these scenes and rewrite their cached frames before the run (the "
                             "frames compared against change: some bakes are not bitwise repeatable); "
                             "not needed for timing, which bakes every scene of the run afresh without "
                             "touching the cache")
    parser.add_argument("--memory", action="store_true", help="peak memory of the sequence in a child process")
    parser.add_argument("--json", default=None, help="write the results as JSON (every repeat's seconds)")
    parser.add_argument("--plot", default=None, help="save the error/deviation-vs-gap plot (PNG)")
    parser.add_argument("--side-by-side", default=None, help="save a side-by-side image (PNG)")
    args = parser.parse_args(argv)
    args.scenes = args.scenes or (QUICK_SCENES if args.quick else list(SCENES))
    if args.repeats is None:
        args.repeats = 1 if args.quick else 3
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    unknown = [s for s in args.scenes + args.rebake if s not in SCENES]
    if unknown:
        parser.error(f"unknown scene(s) {' '.join(unknown)}; the scenes are {' '.join(SCENES)}")
    return args


def main(argv=None, *, bake_timer=None):
    """Run the benchmark with the command line ``argv``; ``bake_timer`` stands in for
    :func:`bake_per_frame` (tests time no Blender)."""
    args = parse_args(argv)
    exaggeration_check()
    for name in args.rebake:
        rebake(name)
    print(format_header())
    results = []
    for name in args.scenes:
        results += run_scene(name, args.gaps, stride=args.stride, protocols=args.protocols, repeats=args.repeats,
                             bake_timer=bake_timer,
                             max_pairs=8 if args.quick or name in PAIR_SAMPLED_SCENES else None)
        if args.memory and name in LARGE_SCENES:
            base, peak, worker, split = peak_memory(name, min(args.gaps))
            print(f"  {name}: peak memory {peak + worker:.0f} MB (this process {peak:.0f}, after loading and "
                  f"imports {base:.0f}; the gap worker {worker:.0f}), gap {min(args.gaps)}{format_split(split)}")
            results[-1]["memory_mb"] = peak + worker
            results[-1]["memory_split"] = split
    if args.memory:
        base, peak, seconds = analytic_sheet_memory()
        print(f"  analytic sheet, 100,489 vertices, 6 keys, 15 in-betweens per gap: peak memory {peak:.0f} MB "
              f"(after imports: {base:.0f} MB), {seconds:.2f} s per in-between")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    if args.plot:
        plot([r for r in results if r["scene"] in PLOT_SCENES], args.plot)
    if args.side_by_side:
        side_by_side(args.side_by_side)
    return results


if __name__ == "__main__":
    main()
