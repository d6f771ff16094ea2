"""Fingerprints of every in-between of the benchmark's cloth scenes, to tell whether a change that
should keep the in-betweens bit for bit does.

    python -m benchmarks.hash_inbetweens OUT [scene ...]

writes one line per scene and gap g in 4, 8, 16: ``seq NAME gG HASH cpu SECONDS`` for a
:class:`core.SequenceInterpolator` keyed every g-th frame (all its in-betweens), and, on scenes up
to 30,000 vertices, ``pair NAME gG HASH`` for two poses g frames apart, every 4th start, at 0.5.
Compare two files' first four columns (``cpu`` is the sequence's CPU time, for orientation only).
The scenes are the cached bakes of :mod:`benchmarks.cloth_scenes` (all of them by default).
The fingerprint is the benchmark's own (``bench_inbetween._fingerprint``).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from benchmarks.bench_inbetween import _fingerprint, kept_keys
from benchmarks.cloth_scenes import SCENES, load_scene
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator

#: Two-pose pairs are hashed on scenes up to this many vertices (larger ones take minutes).
PAIR_VERTICES = 30_000


def scene_lines(name: str):
    """The fingerprint lines of scene ``name``, one at a time."""
    scene = load_scene(name)
    frames, triangles = scene.frames, scene.triangles
    for g in (4, 8, 16):
        keys = kept_keys(frames, g)
        if len(keys) < 2:
            continue
        start = time.process_time()
        sequence = SequenceInterpolator(keys, triangles)
        poses = [sequence.poses(k, np.arange(1, g) / g) for k in range(len(sequence))]
        cpu = time.process_time() - start
        yield f"seq {name} g{g} {_fingerprint(poses)[:16]} cpu {cpu:.2f}"
        if frames.shape[1] > PAIR_VERTICES:
            continue
        pairs = (Interpolator(frames[i], frames[i + g], triangles).pose(0.5) for i in range(0, len(frames) - g, 4))
        yield f"pair {name} g{g} {_fingerprint(pairs)[:16]}"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", help="file to write the fingerprints to")
    parser.add_argument("scenes", nargs="*", help=f"scenes to hash (default: all): {', '.join(SCENES)}")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.scenes) - set(SCENES))
    if unknown:
        parser.error(f"unknown scene(s) {', '.join(unknown)}: choose from {', '.join(SCENES)}")
    warnings.simplefilter("ignore")
    with open(args.out, "w") as out:
        for name in args.scenes or list(SCENES):
            for line in scene_lines(name):
                out.write(line + "\n")
                out.flush()


if __name__ == "__main__":
    main()
