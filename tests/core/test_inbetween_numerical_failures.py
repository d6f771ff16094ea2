"""The in-betweens' safety net (paper §8.4; docs/errors.md, *RecoveryError* and the in-between
fallback warning): a raw numerical failure of a solver inside :class:`core.Interpolator` or
:class:`core.SequenceInterpolator` (constructors, ``pose``, ``poses``, and through them
``core.interpolate`` and ``core.retime``) is a :class:`~core.errors.RecoveryError` naming the keys,
after which the interpolator gives the same poses as a fresh one; non-finite coordinates past the
fits and repairs give their pieces the keys' linear blend with a ShapeDifferenceWarning, the other
pieces as they were. No natural input found makes the solvers fail, so the failures are forced
by replacing the sparse solve or the gap's solver; the natural hostile inputs found are at the end."""

import re
import warnings

import numpy as np
import pytest
from scipy.sparse.linalg import ArpackNoConvergence

import core
import core.sequence_inbetweens as sequence_inbetweens
from core import MeshError, RecoveryError, ShapeDifferenceWarning
from core.sparse_cholesky import SPDFactor

from meshes import drape, grid


@pytest.fixture(scope="module")
def two_pieces():
    """Two sheets side by side (vertices 0..n-1 and n..2n-1), bent differently, and three keys."""
    v, t = grid(6, jitter=0.2)
    n = len(v)
    rest = np.concatenate([v, v + [2.0, 0.0, 0.0]])
    triangles = np.concatenate([t, t + n])
    keys = [rest, np.concatenate([drape(v, 1.0), v + [2.0, 0.0, 0.3]]),
            np.concatenate([drape(v, 1.5), drape(v, 0.5) + [2.0, 0.0, 0.3]])]
    return keys, triangles, n


FAILURES = [
    np.linalg.LinAlgError("Matrix is not positive definite! (CHOLMOD, 72 unknowns)"),
    RuntimeError("Factor is exactly singular"),
    ArpackNoConvergence("ARPACK error -1: No convergence", np.empty(0), np.empty((0, 0))),
    FloatingPointError("overflow encountered in multiply"),
]


def _failing(error):
    def solve(self, rhs):
        raise error
    return solve


@pytest.mark.parametrize("error", FAILURES, ids=lambda e: type(e).__name__)
def test_a_solver_failure_in_a_two_pose_in_between_is_a_recovery_error_that_changes_nothing(
        two_pieces, monkeypatch, error):
    keys, triangles, _ = two_pieces
    interpolator = core.Interpolator(keys[0], keys[1], triangles, key_names=["shape key 'A'", "shape key 'B'"])
    with monkeypatch.context() as patch:
        patch.setattr(SPDFactor, "solve", _failing(error))
        with pytest.raises(RecoveryError, match=rf"in-between at factor 0.5 between shape key 'A' and shape key "
                                                rf"'B' failed numerically \({type(error).__name__}"):
            interpolator.pose(0.5)
    fresh = core.Interpolator(keys[0], keys[1], triangles).pose(0.5)
    assert np.array_equal(interpolator.pose(0.5), fresh)


@pytest.mark.parametrize("error", FAILURES, ids=lambda e: type(e).__name__)
def test_a_solver_failure_in_a_sequence_gap_is_a_recovery_error_that_changes_nothing(two_pieces, monkeypatch, error):
    keys, triangles, _ = two_pieces
    sequence = core.SequenceInterpolator(keys, triangles)
    factors = [0.25, 0.5, 0.75]
    with monkeypatch.context() as patch:
        patch.setattr(SPDFactor, "solve", _failing(error))
        with pytest.raises(RecoveryError, match=r"in-betweens at factors 0.25, 0.5, 0.75 between key pose 1 and key pose 2 failed numerically"):
            sequence.poses(1, factors)
    fresh = core.SequenceInterpolator(keys, triangles).poses(1, factors)
    assert np.array_equal(sequence.poses(1, factors), fresh)


def test_a_solver_failure_through_interpolate_and_retime_is_a_recovery_error(two_pieces, monkeypatch):
    from core.retime import retime

    keys, triangles, _ = two_pieces
    monkeypatch.setattr(SPDFactor, "solve", _failing(np.linalg.LinAlgError("singular")))
    with pytest.raises(RecoveryError, match="LinAlgError"):
        core.interpolate(keys[0], keys[1], triangles, 0.5)
    samples = np.stack([keys[0], 0.5 * (keys[0] + keys[1]), keys[1], 0.5 * (keys[1] + keys[2]), keys[2]])
    with pytest.raises(RecoveryError, match="LinAlgError"):
        retime(samples, triangles, step=2, speed=0.5)


@pytest.mark.parametrize("two_poses", [True, False], ids=["Interpolator", "SequenceInterpolator"])
def test_a_failure_while_preparing_the_keys_is_a_recovery_error(two_pieces, monkeypatch, two_poses):
    """The constructors' own work (seams, still vertices, pieces, pins) wrapped as the solves are."""
    keys, triangles, _ = two_pieces

    def failing(*args, **kwargs):
        raise FloatingPointError("invalid value encountered in divide")

    monkeypatch.setattr("core.sequence_keys.still_vertices", failing)
    with pytest.raises(RecoveryError, match=r"Preparing the in-betweens of .* failed numerically \(FloatingPointError"):
        if two_poses:
            core.Interpolator(keys[0], keys[1], triangles)
        else:
            core.SequenceInterpolator(keys, triangles)


@pytest.mark.parametrize("error", [IndexError("index 72 is out of bounds for axis 0 with size 72"),
                                   TypeError("unsupported operand type(s) for *: 'NoneType' and 'float'"),
                                   NotImplementedError("a piece of no kind")], ids=lambda e: type(e).__name__)
@pytest.mark.parametrize("two_poses", [True, False], ids=["Interpolator", "SequenceInterpolator"])
def test_an_error_of_the_code_itself_is_not_passed_off_as_a_numerical_failure(two_pieces, monkeypatch, error,
                                                                               two_poses):
    """An IndexError or TypeError inside a solve comes from the code, not from the input (every
    argument is checked before): it escapes as it is, not as a RecoveryError telling the user to
    change a valid pose."""
    keys, triangles, _ = two_pieces

    def failing(segment, factors, *ahead):
        raise error

    monkeypatch.setattr(sequence_inbetweens, "gap_poses", failing)
    with pytest.raises(type(error)) as raised:
        if two_poses:
            core.Interpolator(keys[0], keys[1], triangles).pose(0.5)
        else:
            core.SequenceInterpolator(keys, triangles).poses(1, [0.25, 0.5])
    assert raised.value is error


def _poisoned(original, rows):
    """``gap_poses`` with NaN in ``rows`` of every pose it returns (what no fit or repair returns
    on any input found: the last net is reached only past them)."""
    def gap_poses(segment, factors, *ahead):
        solved = original(segment, factors, *ahead)
        for x, _ in solved:
            x[rows] = np.nan
        return solved
    return gap_poses


@pytest.mark.parametrize("factor", [0.5, 1.5], ids=["in-between", "exaggeration"])
def test_non_finite_coordinates_give_their_piece_the_blend_and_a_warning(two_pieces, monkeypatch, factor):
    keys, triangles, n = two_pieces
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        clean = core.Interpolator(keys[0], keys[1], triangles).pose(factor)
    monkeypatch.setattr(sequence_inbetweens, "gap_poses", _poisoned(sequence_inbetweens.gap_poses, [3]))
    with pytest.warns(ShapeDifferenceWarning, match=r"1 vertex\(es\) came out with non-finite coordinates .* their 1 "
                                                    r"piece\(s\) \(36 vertices\) are the keys' linear"):
        x = core.Interpolator(keys[0], keys[1], triangles).pose(factor)
    assert np.isfinite(x).all()
    blend = (1.0 - factor) * keys[0][:n] + factor * keys[1][:n]
    assert np.array_equal(x[:n], blend)  # the failed piece: the keys' blend (extrapolated past them)
    assert np.array_equal(x[n:], clean[n:])  # the other piece as it was


def test_non_finite_coordinates_in_a_sequence_leave_the_other_pieces_as_they_were(two_pieces, monkeypatch):
    keys, triangles, n = two_pieces
    factors = [0.25, 0.5, 0.75]
    clean = core.SequenceInterpolator(keys, triangles).poses(1, factors)
    monkeypatch.setattr(sequence_inbetweens, "gap_poses", _poisoned(sequence_inbetweens.gap_poses, [n + 7]))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        poses = core.SequenceInterpolator(keys, triangles).poses(1, factors)
    # said once for the gap, with how many of its in-betweens it is about, not once per in-between
    said = [w.message for w in caught if "non-finite" in str(w.message)]
    assert len(said) == 1 and said[0].kind == "non_finite", [str(m) for m in said]
    assert said[0].gap == ("key pose 1", "key pose 2") and said[0].factors == tuple(factors)
    assert re.search(r"between key pose 1 and key pose 2, 3 of the 3 in-betweens alike, the first at factor 0.25: "
                     r"1 vertex\(es\) came out with non-finite.*; in-betweens alike at factors 0.25, 0.5, 0.75\.$",
                     str(said[0]))
    assert np.isfinite(poses).all()
    for x, y, s in zip(poses, clean, factors):
        assert np.array_equal(x[n:], (1.0 - s) * keys[1][n:] + s * keys[2][n:])
        assert np.array_equal(x[:n], y[:n])


@pytest.mark.parametrize("factor", [1000.0, -1000.0, -100.0])
def test_a_pose_exaggerated_to_the_largest_factor_gives_no_numpy_warning(factor):
    """Far past the keys the interpolated lengths underflow (or cancel to NaN): the misfit and the
    extrapolated metric's lengths said so as NumPy RuntimeWarnings ("divide by zero", "invalid value
    in sqrt"), which a farm job running with ``np.seterr(all="raise")`` gets as FloatingPointError."""
    v, t = grid(6)
    bent = v.copy()
    turned = bent[:, 0] > 0.5
    angle = np.radians(100.0)
    bent[turned, 0] = 0.5 + np.cos(angle) * (v[turned, 0] - 0.5)
    bent[turned, 2] = np.sin(angle) * (v[turned, 0] - 0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        warnings.simplefilter("ignore", ShapeDifferenceWarning)  # said where the pose grows: not this test's
        x = core.Interpolator(v, bent, t).pose(factor)
    assert np.isfinite(x).all()


def test_a_mesh_rounded_flat_far_from_its_origin_is_a_mesh_error():
    """A sheet 1e7 units out in single precision: its coordinates round to a grid coarser than its
    edges, so most edges round to zero length; the advice's share of the median edge divided by it."""
    v, t = grid(6)
    far = (v + 1e7).astype(np.float32)
    with pytest.raises(MeshError, match=r"lies 1e\+07 units from its origin.*more than most of its edges are long"):
        core.Interpolator(far, far, t)


def test_a_key_far_larger_than_the_others_in_a_truncated_basis_is_a_recovery_error():
    """A key 1e20 × the size of the others (a broken frame, inside the accepted 1e30) overflows the
    truncated area program's low-rank system: a RecoveryError naming the gap (before: SciPy's bare
    "array must not contain infs or NaNs" ValueError from its Cholesky factorization); through
    :class:`core.Transfer` too."""
    v, t = grid(8)
    keys = [v, drape(v, 1.0), drape(v, 1.0) * 1e20]
    sequence = core.SequenceInterpolator(keys, t, k_M=12)
    with pytest.raises(RecoveryError, match=r"^The in-between at factor 0.5 between key pose 1 and key pose 2 failed "
                                            r"numerically \(FloatingPointError: .*overflowed\)"):
        sequence.pose(1, 0.5)
    target, target_triangles = grid(6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)  # the basis sizes' advice: not this test's
        transfer = core.Transfer(target, target_triangles, v, t, k_M=9, k_N=20)
    with pytest.raises(RecoveryError, match=r"^Transferring the pose failed numerically \(FloatingPointError"):
        transfer.pose(drape(v, 1.0) * 1e20)
