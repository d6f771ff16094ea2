"""Runs of poses read that are the same to the bit, and a span of frames as the messages name it
(shared by the checks of caches and bakes).
"""

from __future__ import annotations

import numpy as np


def held_run(poses: list[np.ndarray], indices) -> list[int]:
    """The first of ``indices`` and those following it (in the order given) whose ``poses`` are the
    same to the bit as its pose, when they are two or more; else empty."""
    run = [indices[0]]
    for index in indices[1:]:
        if not np.array_equal(poses[index], poses[run[0]]):
            break
        run.append(index)
    return run if len(run) >= 2 else []


def all_the_same(poses: list[np.ndarray]) -> bool:
    """Whether there are two or more ``poses`` and all are the same, to the bit."""
    return len(poses) >= 2 and all(np.array_equal(pose, poses[0]) for pose in poses[1:])


def frame_span(frames: list[int]) -> str:
    """"frame 7" or "frames 50–65" for the ascending ``frames``."""
    return f"frame {frames[0]}" if len(frames) == 1 else f"frames {frames[0]}–{frames[-1]}"
