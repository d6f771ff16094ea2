"""The in-betweens' warnings point at the line of the caller's own code that called the core (the
warning's filename and line), not at a line inside the library, so that a pipeline's
``warnings.filterwarnings(…, module=…)`` and the printed location find its own call; no bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import core
from core.errors import ShapeDifferenceWarning
from core.retime import iter_retime, plan_retime, retime
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator
from inbetween_helpers import _bend
from test_placement_pieces import _tetrahedra


def _located(call, line):
    """Every ShapeDifferenceWarning ``call()`` issues, as ``(filename, line)``; at least one."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    said = [(w.filename, w.lineno) for w in caught if issubclass(w.category, ShapeDifferenceWarning)]
    assert said, "the constructed case warns"
    return said, [(__file__, line)] * len(said)


@pytest.fixture
def every_fit_flips(monkeypatch, strip):
    """Every in-between's fit keeps 3 flipped triangles (as the repairs' tests construct it): each
    in-between warns when it is solved, after the keys are prepared."""
    import core.inbetween_repair as repair

    def defects(self, x, *args, rows=None, **kwargs):
        out = np.zeros(len(strip[1]), dtype=bool)
        out[:3] = True
        return out if rows is None else out[rows]

    monkeypatch.setattr(repair.Repair, "problem", lambda self, x, *args: "3 triangle(s) flipped")
    monkeypatch.setattr(repair.Repair, "defects", defects)


@pytest.mark.parametrize("path", ["SequenceInterpolator.poses", "SequenceInterpolator.pose", "Interpolator.pose",
                                  "interpolate", "iter_retime", "retime"])
def test_an_in_betweens_warning_points_at_the_callers_line(path, strip, every_fit_flips):
    """A warning issued while an in-between is solved (its fit keeps flipped triangles) names the
    caller's line, for each public entry point: the generator of a retime at the line that
    advances it."""
    flat, tri = strip
    a, b, c = (_bend(flat, t) - [1.0, 0.0, 0.0] for t in (0.0, 2.0, 3.0))
    sequence, two = SequenceInterpolator([a, b, c], tri), Interpolator(a, b, tri)
    samples = np.array([_bend(flat, t) for t in np.linspace(0.0, 2.0, 5)])
    plan = plan_retime(len(samples), 4, 1.0)

    def steps():
        for _ in iter_retime(samples, tri, plan):  # the caller advances the generator
            pass

    calls = {  # each call on a line of its own, with that line
        "SequenceInterpolator.poses": lambda: sequence.poses(0, [0.25, 0.5, 0.75]),
        "SequenceInterpolator.pose": lambda: sequence.pose(1, 0.5),
        "Interpolator.pose": lambda: two.pose(0.5),
        "interpolate": lambda: core.interpolate(a, b, tri, 1.5),
        "iter_retime": steps,
        "retime": lambda: retime(samples, tri, step=4, speed=1.0),
    }
    call = calls[path]
    line = call.__code__.co_firstlineno + (1 if path == "iter_retime" else 0)
    said, expected = _located(call, line)
    assert said == expected


@pytest.mark.parametrize("sequence", [False, True])
def test_a_warning_of_the_keys_points_at_the_constructors_caller(sequence):
    """A warning of the keys themselves (pieces mirrored between them), issued while the
    interpolator is built, names the line that builds it."""
    a, tri = _tetrahedra()
    b = a @ np.diag([-1.0, 1.0, 1.0])
    build = (lambda: SequenceInterpolator([a, b, b + 0.1], tri)) if sequence else (lambda: Interpolator(a, b, tri))
    said, expected = _located(build, build.__code__.co_firstlineno)
    assert said == expected


def test_a_transfers_warning_points_at_the_line_that_builds_it():
    """A Transfer built straight from a script with a map matching under half of the base's
    vertices (``core.transfer_checks.WARN_MATCHED_FRACTION``) warns at the line that builds it, as
    every warning of the core does: the warning is issued two calls deep in the core, whatever
    depth its own code assumes."""
    from core.functional_map import closest_point_correspondence
    from core.transfer import Transfer
    from meshes import grid

    base, base_tris = grid(10, jitter=0.3)
    target, target_tris = grid(12, jitter=0.3, seed=3, alternate=False)
    vertex_map = closest_point_correspondence(base, target)
    vertex_map[np.random.default_rng(4).random(len(base)) >= 0.4] = -1
    build = lambda: Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=16, k_N=32)  # noqa: E731
    said, expected = _located(build, build.__code__.co_firstlineno)
    assert said == expected
