"""Hostile arguments to the entry points past the mesh (the pulled-back metric's methods, the shape
space's, a sequence's factors and key names, the retime, the point cache writer, the OBJ and map
readers): each bad value is a MeshError in the argument's own terms, never NumPy's or Python's own
exception, a silent coercion or a file holding values the caller did not give (docs/errors.md).
Each case here escaped as something else before (said in the test)."""

import warnings

import numpy as np
import pytest

import core
import core.resources
from core import MeshError
from core.obj_file import read_obj
from core.point_cache import read_pc2, write_pc2
from core.retime import plan_retime, retime
from core.vertex_maps import read_vertex_map

from meshes import drape
from test_hostile_inputs import sheet  # noqa: F401 — the fixture: a jittered 6 × 6 sheet and its drape


@pytest.fixture(scope="module")
def pulled(sheet):
    v, t, target = sheet
    return core.pull_back(v, t, core.shape_differences(v, target, t, use_extrinsic=False))


def test_a_basis_size_below_one_is_refused_after_a_larger_basis_was_computed(pulled):
    """k = −3 after k = 10 was asked for took the cached basis cut at −3, its first 7 eigenpairs,
    without a word; it is refused as k = 0 is, and the next call answers as before."""
    first = pulled.eigenfunctions(10)
    for k in (-3, 0, -1):
        with pytest.raises(MeshError, match=rf"between 1 and \d+; got {k}\. Lower k\.$"):
            pulled.eigenfunctions(k)
    np.testing.assert_array_equal(pulled.eigenfunctions(10), first)


@pytest.mark.parametrize("call, message", [
    # NaN, inf, None: ValueError / OverflowError / TypeError of int() before
    (lambda p: p.geodesic_distances(float("nan")), "source_vertex must be a vertex index"),
    (lambda p: p.geodesic_distances(None), "source_vertex must be a vertex index"),
    (lambda p: p.geodesic_distances(np.array([3])), "source_vertex must be a vertex index"),  # a NumPy DeprecationWarning
    # a variance of 0, NaN or below: a signature of NaN, returned
    (lambda p: p.wave_kernel_signature(5, k=8, variance=0.0), "variance must be a positive number"),
    (lambda p: p.wave_kernel_signature(5, k=8, variance=float("nan")), "variance must be a finite number"),
    (lambda p: p.wave_kernel_signature(5, k=8, variance=-7.0), "variance must be a positive number"),
    # 0 energies: NumPy's divide-by-zero warnings and an empty signature; −3: NumPy's ValueError
    (lambda p: p.wave_kernel_signature(0, k=8), r"energies \(a count\) must be at least 1"),
    (lambda p: p.wave_kernel_signature(-3, k=8), r"energies \(a count\) must be at least 1"),
    (lambda p: p.wave_kernel_signature([0.5, float("nan")], k=8), "finite log-energies"),
    # a single log-energy read from an array: 2.0 was two energies (silently), 2.5 "energies (a count)
    # must be a whole number", which said nothing of log-energies
    (lambda p: p.wave_kernel_signature(np.float64(2.0), k=8), r"not an integer: pass 2 for a count, or \[2\.0\] for one"),
    (lambda p: p.wave_kernel_signature(2.5, k=8), r"not an integer: .* or \[2\.5\] for one log-energy"),
    (lambda p: p.wave_kernel_signature(np.array(3.0), k=8), r"pass 3 for a count"),
    # a fractional or textual k: IndexError / TypeError of slicing; a negative one was clamped silently
    (lambda p: p.wave_kernel_signature(5, k=2.5), "k must be a whole number"),
    (lambda p: p.wave_kernel_signature(5, k="8"), "k must be a whole number"),
    (lambda p: p.wave_kernel_signature(5, k=-8), "k must be at least 1"),
    (lambda p: p.eigenfunctions("8"), "k must be a whole number"),
    (lambda p: p.wks_energies(0, k=8), "count must be at least 1"),
])
def test_the_pulled_back_metric_checks_its_arguments(pulled, call, message):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no NumPy warning on the way
        with pytest.raises(MeshError, match=message):
            call(pulled)


def test_a_count_past_the_memory_is_refused_before_allocating(sheet, pulled, monkeypatch):
    """dims = 2^40 (ShapeSpace.coordinates, zero beyond the rank) and 2^40 energies asked NumPy for
    terabytes: a MemoryError (or a hang in the system's swap), and 2^63 NumPy's "maximum allowed
    dimension exceeded" / an IndexError. Refused against the memory the system says is available."""
    v, t, target = sheet
    space = core.shape_space([v, target, drape(v, 0.5)], t, k_M=5, k_N=10)
    monkeypatch.setattr(core.resources, "available_memory", lambda: 4e9)
    for count in (2**40, 2**63):
        with pytest.raises(MeshError, match="GB of memory available"):
            space.coordinates("area", count)
        with pytest.raises(MeshError, match="GB of memory available"):
            pulled.wave_kernel_signature(count, k=8)
    assert space.coordinates("area", 10).shape == (3, 10)  # zero beyond the rank, as documented


def test_sequence_factors_and_key_names_are_refused_in_their_terms(sheet):
    v, t, target = sheet
    sequence = core.SequenceInterpolator([v, target], t)
    # a nested factor: NumPy's "inhomogeneous shape" ValueError before
    with pytest.raises(MeshError, match="factors must be a number or a list of numbers"):
        sequence.poses(0, [0.5, [0.25]])
    # a 0-d array of names has __len__ but no length: TypeError before
    with pytest.raises(MeshError, match="key_names must be a list of names"):
        core.SequenceInterpolator([v, target], t, key_names=np.array("ab"))
    np.testing.assert_array_equal(sequence.poses(0, np.array([0.5])), sequence.poses(0, [0.5]))


def test_retime_checks_its_samples_and_settings(sheet):
    v, t, target = sheet
    keys = [v, target, v, target]
    # samples of other shapes: NumPy's "inhomogeneous shape" ValueError before
    # (named as the retime names its keys, no longer as the sequence's "key pose 1 of key_poses")
    with pytest.raises(MeshError, match="key pose 1 has 35 vertices but the base mesh has 36"):
        retime([v, target[:-1], v, target], t, step=1, speed=0.5)
    with pytest.raises(MeshError, match=r"key pose 0 must be an array of shape \(n, 3\)"):
        retime([v[:, :2], target, v, target], t, step=1, speed=0.5)
    # complex samples: the imaginary part dropped with NumPy's ComplexWarning only
    with pytest.raises(MeshError, match="complex values"):
        retime([k.astype(complex) for k in keys], t, step=1, speed=0.5)
    with pytest.raises(MeshError, match="samples must be a sequence of poses"):
        retime(None, t, step=1, speed=0.5)  # TypeError of len() before
    # True as a step ran with step 1; NaN and None were ValueError / TypeError of int()
    for step in (True, float("nan"), None, "2"):
        with pytest.raises(MeshError, match="The frame step must be a whole number of at least 1"):
            retime(keys, t, step=step, speed=0.5)
    for speed in (None, "0.5", True, 1j):  # TypeError of NumPy before; True ran at speed 1
        with pytest.raises(MeshError, match="The speed must be a positive number"):
            retime(keys, t, step=1, speed=speed)
    with pytest.raises(MeshError, match="must be a whole number"):
        plan_retime(4.5, 1, 0.5)  # planned as if 4.5 frames
    # 2^63 frames at a speed that gives few outputs: NumPy's ValueError listing 2^63 keys before
    with pytest.raises(MeshError, match="key poses, more than 1,048,574"):
        plan_retime(2**63, 1, 2.0**61)
    with pytest.raises(MeshError, match="is not a contiguous range"):
        retime(keys, t, step=1, speed=0.5, gaps=[0, 1])  # AttributeError before
    retimed = retime(keys, t, step=1, speed=0.5)
    np.testing.assert_array_equal(retimed[::2], np.asarray(keys, dtype=np.float32))  # keys exact


def test_the_pc2_writer_refuses_what_a_pc2_cannot_hold(tmp_path, sheet):
    """Complex positions were written without their imaginary part (NumPy's ComplexWarning only),
    coordinates past float32's 3.4e38 as infinite (a file every reader refuses, or plays with
    vertices at infinity), text as NumPy's TypeError; nothing is written now."""
    v, _, target = sheet
    poses = np.stack([v, target])
    for bad, message in ((poses.astype(complex), "complex values"), (poses * 1e39, "beyond the 3.4e"),
                         (poses.astype(str).astype(object), "must hold numbers")):
        with pytest.raises(MeshError, match=message):
            write_pc2(tmp_path / "out.pc2", bad)
        assert not list(tmp_path.iterdir())
    huge = poses * 3e38  # within float32's range: written as given
    np.testing.assert_array_equal(read_pc2(write_pc2(tmp_path / "out.pc2", huge)).positions, huge.astype(np.float32))


def test_an_obj_with_a_non_finite_coordinate_is_refused_at_its_line(tmp_path):
    """"v 0 0 nan" was read as a vertex at NaN (and its faces fanned by NaN areas)."""
    for value in ("nan", "inf", "1e400"):
        path = tmp_path / f"{value}.obj"
        path.write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 {value}\nf 1 2 3\n")
        with pytest.raises(MeshError, match=rf"line 3 cannot be read \(a vertex coordinate is not a finite number\)"):
            read_obj(path)


def test_an_empty_map_file_is_refused_without_numpys_warning(tmp_path):
    path = tmp_path / "empty.vts"
    path.write_text("")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # NumPy's UserWarning "input contained no data" before
        with pytest.raises(MeshError, match="is empty"):
            read_vertex_map(path)


def test_a_key_the_first_keys_place_flattens_is_refused(sheet):
    """The in-betweens take every key about the first key's middle in double precision: a key 1
    unit across after one 3e15 across (its middle 1.5e15 out, rounding coordinates to 0.33) lost
    every triangle's shape there, and came back with NumPy's division warnings (a pair) or, after a
    key 1e30 across, a raw ValueError (a sequence). Refused, naming the key; keys of comparable
    size, keys all far from the origin and a key far larger than the first (rounded so as given)
    run as before."""
    v, t, target = sheet
    for scale in (3e15, 1e30):
        with pytest.raises(MeshError, match="vertices_b has no triangle higher than 0.1.* flattened"):
            core.Interpolator(v * scale, target, t)
        with pytest.raises(MeshError, match="key pose 1 has no triangle higher than 0.1.* flattened"):
            core.SequenceInterpolator([v * scale, target, v * scale], t)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pose = core.Interpolator(v * 1e14, target, t).pose(0.5)
        far = core.SequenceInterpolator([v + 1e12, target + 1e12, v], t).pose(0, 0.5)  # key 2 rounds to 2e-4
    assert np.isfinite(pose).all() and np.isfinite(far).all()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", core.ShapeDifferenceWarning)  # the large key's own slivers
        warnings.simplefilter("error", RuntimeWarning)
        assert np.isfinite(core.Interpolator(v, target * 1e30, t).pose(0.5)).all()


def test_a_correspondence_is_checked_before_its_cast_to_int64():
    """uint64 2^64 − 1 was cast to −1 and read as "unmatched"; booleans as indices 0 and 1; 1e20 as
    target vertex −9223372036854775808 (with NumPy's cast warning)."""
    from core.functional_map import check_correspondence

    with pytest.raises(MeshError, match="to target vertex 18446744073709551615, but the target has 3"):
        check_correspondence(np.full(4, 2**64 - 1, dtype=np.uint64), 4, 3, allow_unmatched=True)
    with pytest.raises(MeshError, match="holds booleans"):
        check_correspondence(np.array([True, False, True, False]), 4, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(MeshError, match="to target vertex 100000000000000000000, but"):
            check_correspondence(np.array([1e20, 0.0, 1.0, 2.0]), 4, 3)
    np.testing.assert_array_equal(check_correspondence(np.array([0, 1, 2, -1], dtype=np.int32), 4, 3,
                                                       allow_unmatched=True), [0, 1, 2, -1])


def test_a_low_rank_solve_past_its_products_range_fails_once_without_numpys_warnings():
    """Woodbury with float32 products (the ADMM's): a right-hand side past float32's 3.4e38 became
    inf in the cast and NaN in the products, with NumPy's overflow and invalid-value warnings at
    every iteration; it is a FloatingPointError naming the overflow. Within range the solve agrees
    with a dense solve of (FᵀF + diag(d)) x = r."""
    from core.low_rank import Woodbury

    rng = np.random.default_rng(0)
    f, d = rng.standard_normal((4, 30)), 1.0 + rng.random(30)
    solver = Woodbury(f, d, products=f.astype(np.float32))
    r = rng.standard_normal(30)
    dense = np.linalg.solve(f.T @ f + np.diag(d), r)
    np.testing.assert_allclose(solver.solve(r), dense, rtol=1e-5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(FloatingPointError, match=r"right-hand side, up to 1\.\d+e\+40 where its products hold 3\.4e\+38, overflowed"):
            solver.solve(r * 1e40)
    assert not caught, [str(w.message) for w in caught]


def test_a_transfer_of_a_pose_1e30_across_ends_in_a_recovery_error_without_numpys_warnings(sheet):
    """A target pose 1e30 across against a base (and target rest) 1 across: the recovery's squared
    lengths (~1e60) overflow its float32 products; the documented RecoveryError came after NumPy's
    "overflow encountered in cast" and "invalid value encountered in matmul" warnings."""
    v, t, target = sheet
    transfer = core.Transfer(v, t, v, t, k_M=10, k_N=10)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(core.RecoveryError, match="overflowed"):
            transfer.pose(target * 1e30)
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in caught]


def _sliver_messages(*args):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        core.Interpolator(*args).pose(0.5)
    return [str(w.message) for w in caught if "less high than twice the rounding" in str(w.message)]


def test_the_sliver_warning_names_the_cause_of_the_rounding(sheet):
    """The `sliver` warning advised moving the mesh's origin whatever set the rounding. A first key
    5e14 across (its own coordinates set the rounding, 0.11, wherever the origin is) is named with
    its size ratio; keys 3e14 out (1 across) with their place and the origin; a sliver 1.5e-7 high in
    float32 keys at the origin (rounding 1.2e-7) as the mesh's own, to dissolve."""
    v, t, target = sheet
    [size] = _sliver_messages(v * 5e14, target, t)
    assert "set by vertices_a, 5e+14 across, 5e+14 times the size of vertices_b" in size and "origin" not in size
    [place] = _sliver_messages(v + 3e14, target + 3e14, t)
    assert "3e+14 units from the origin; move the mesh's origin near it" in place and "times the size" not in place
    a, b, c = t[4]

    def with_sliver(pose):  # corner c 1.5e-7 off the middle of side ab, in float32
        pose = pose.astype(np.float32)
        side = pose[b] - pose[a]
        across = np.cross(side, [0.0, 0.0, 1.0])
        pose[c] = 0.5 * (pose[a] + pose[b]) + 1.5e-7 * across / np.linalg.norm(across)
        return pose

    [own] = _sliver_messages(with_sliver(v), with_sliver(target), t)
    assert "1 triangle(s)" in own and "the mesh's own slivers" in own and "Degenerate Dissolve" in own
    assert "origin" not in own and "times the size" not in own


def test_in_betweens_of_a_key_1e20_times_the_others_in_a_truncated_basis_leak_no_numpy_warning():
    """The truncated area program's low-rank solve took an inf right-hand side into NumPy's
    "invalid value encountered in multiply" before the documented RecoveryError naming the gap."""
    from meshes import grid

    v, t = grid(8)
    sequence = core.SequenceInterpolator([v, drape(v, 1.0), drape(v, 1.0) * 1e20], t, k_M=12)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(core.RecoveryError, match="between key pose 1 and key pose 2 failed numerically"):
            sequence.pose(1, 0.5)
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in caught]


def test_a_nested_list_of_factors_is_refused_as_factors(sheet):
    """One row of factors (``[[0.5, 0.25]]``) is no list of factors: refused naming ``factors``, not
    taken row by row into ``check_factor`` ("factor must be a real number; got array([0.5, 0.25])")."""
    v, t, target = sheet
    sequence = core.SequenceInterpolator([v, target], t)
    with pytest.raises(MeshError, match="factors must be a number or a list of numbers"):
        sequence.poses(0, [[0.5, 0.25]])


def test_in_betweens_past_half_the_memory_are_refused_before_any_work(sheet, monkeypatch):
    """``SequenceInterpolator.poses`` and ``core.retime.retime`` refuse an output past half the memory
    available, as the command and the operators do (``check_output_memory``), before any in-between:
    a list of factors or a speed asking for more poses than fit filled the memory one in-between after
    another (or, past the machine's memory, NumPy's raw MemoryError). Asked in parts, they run."""
    import core.sequence_inbetweens

    v, t, target = sheet
    keys = [v, target, drape(v, 1.5)]
    sequence = core.SequenceInterpolator(keys, t)
    factors = np.linspace(0.0, 1.0, 1001)[1:-1]  # 999 poses of 36 vertices, 54 bytes a vertex while made: 1.9 MB
    monkeypatch.setattr(core.resources, "available_memory", lambda: 10**6)  # half of it: 500 kB
    calls = []
    monkeypatch.setattr(core.sequence_inbetweens.SequenceInterpolator, "_computed_poses",
                        lambda self, *args: calls.append(args))
    with pytest.raises(MeshError, match="The in-betweens asked of gap 1 at once is 999 poses of 36 vertices.*fewer"):
        sequence.poses(1, factors)
    # speed 0.0005 over 9 samples: 16,001 poses of 36 vertices, float32: 6.9 MB
    samples = [drape(v, s) for s in np.linspace(0.0, 1.5, 9)]
    built = []
    monkeypatch.setattr(core.sequence_inbetweens.SequenceInterpolator, "__init__",
                        lambda self, *args, **kwargs: built.append(args))
    with pytest.raises(MeshError, match="The output of this retime is 16,001 poses of 36 vertices"):
        retime(samples, t, step=4, speed=0.0005)
    assert not calls and not built  # nothing computed, no sequence prepared
    monkeypatch.undo()
    monkeypatch.setattr(core.resources, "available_memory", lambda: 10**6)
    assert sequence.poses(1, factors[:250]).shape == (250, 36, 3)  # 432 kB: within half of it


def test_retimed_samples_are_the_in_betweens_in_single_precision(sheet):
    """``retime`` fills its float32 output in place (no list of float64 poses beside it): the same
    values as the in-betweens ``iter_retime`` gives, rounded once, in every chunk."""
    from core.retime import iter_retime

    v, t, _ = sheet
    samples = [drape(v, s) for s in np.linspace(0.0, 1.5, 11)]  # a last gap shorter than the step
    plan = plan_retime(len(samples), 4, 0.6)
    for gaps in (None, plan.chunk(0, 2), plan.chunk(1, 2), range(1, 1)):
        expected = [pose for _, pose in iter_retime(samples, t, plan, gaps)]
        got = retime(samples, t, step=4, speed=0.6, gaps=gaps)
        assert got.dtype == np.float32 and got.shape == (len(expected), len(v), 3)
        np.testing.assert_array_equal(got, np.asarray(expected, dtype=np.float32).reshape(-1, len(v), 3))


def test_key_times_past_double_precisions_range_are_refused():
    """Key times 1.7e308 on either side of 0 are finite and increasing, but the gap between them is
    not: its duration came out infinite with NumPy's "overflow encountered in subtract", and every
    time in that gap was read as its first key."""
    from meshes import grid

    v, t = grid(5)
    keys = [v, drape(v, 1.0), drape(v, 1.5)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no NumPy overflow warning on the way
        with pytest.raises(MeshError, match="key_times -1.7e.308 and 1.7e.308 .keys 0 and 1. are farther apart than"):
            core.SequenceInterpolator(keys, t, key_times=[-1.7e308, 1.7e308, 1.75e308])
    sequence = core.SequenceInterpolator(keys, t, key_times=[-1.7e308, 0.0, 1.7e308])  # each gap finite
    np.testing.assert_allclose(sequence.pose_at(0.0), keys[1], rtol=0, atol=1e-12)  # its second key's time


def test_retime_checks_its_keys_and_faces_before_reading_how_the_motion_starts(sheet):
    """Keys four samples apart: the samples in the middle of the first and last gaps tell how the
    motion starts and ends (``core.retime.motion_ends``), read before the sequence checks its keys.
    A key of another vertex count reached it as NumPy's "operands could not be broadcast together",
    an empty mesh with NumPy's "Mean of empty slice" warning before its refusal."""
    v, t, target = sheet
    samples = [v] * 4 + [target[:-1]] + [drape(v, 1.5)] * 4
    with pytest.raises(MeshError, match="key pose 1 has 35 vertices but the base mesh has 36"):
        retime(samples, t, step=4, speed=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no NumPy warning on the way
        with pytest.raises(MeshError, match="The mesh has no triangles"):
            retime(np.zeros((9, 0, 3)), np.zeros((0, 3), dtype=int), step=4, speed=0.5)


def test_a_flat_retime_sample_is_refused_by_its_shape_not_counted_as_thrice_its_vertices(sheet, monkeypatch):
    """Samples given flat ((3n,) each: a cache's rows read as they are stored) were counted as 3n
    vertices by the retime's memory check, before the keys are read: with memory enough for the
    output of the 36-vertex sheet but not of 108 vertices, the refusal said "17 poses of 108 vertices"
    and asked for a higher speed. The sample's shape is refused first, as with the memory to spare."""
    v, t, target = sheet
    samples = [drape(v, s) for s in np.linspace(0.0, 1.5, 9)]
    # keyed every 4th at speed 0.5: 17 poses (float32) and 7 in-betweens of a gap at once (54 bytes a vertex)
    need = 17 * 12 + 7 * 54
    monkeypatch.setattr(core.resources, "available_memory", lambda: 2.5 * need * 36)  # half: 36 fit, 108 do not
    with pytest.raises(MeshError, match=r"key pose 0 must be an array of shape \(n, 3\); got shape \(108,\)"):
        retime([s.ravel() for s in samples], t, step=4, speed=0.5)
    monkeypatch.setattr(core.resources, "available_memory", lambda: 1.5 * need * 36)
    with pytest.raises(MeshError, match="is 17 poses of 36 vertices"):
        retime(samples, t, step=4, speed=0.5)  # the memory counted of its 36 vertices


def test_a_masked_coordinate_is_refused_not_read_under_its_mask(sheet):
    """A key given as a masked array lost its mask (``np.asarray``): the values under it (a missing
    sample's fill value, or what was there) were in-betweened without a word. A key with a value masked
    is refused, naming where; a masked array with none masked is its data (the same in-betweens)."""
    v, t, target = sheet
    third = drape(v, 1.5)
    gappy = np.ma.masked_array(target.copy(), mask=False)
    gappy[7, 2] = np.ma.masked
    gappy.data[7, 2] = 1e6  # under the mask: not a coordinate
    with pytest.raises(MeshError, match=r"key pose 1 of key_poses is a masked array with 1 masked value\(s\), the "
                                        r"first at index \(7, 2\)"):
        core.SequenceInterpolator([v, gappy, third], t)
    with pytest.raises(MeshError, match="masked value"):
        core.SequenceInterpolator(np.ma.stack([v, gappy, third]), t)  # the keys as one (K, n, 3) masked array
    with pytest.raises(MeshError, match="masked value"):
        retime([v, gappy, v, target], t, step=1, speed=0.5)
    whole = np.ma.masked_array(target)  # nothing masked
    np.testing.assert_array_equal(core.SequenceInterpolator([v, whole, third], t).poses(0, [0.25, 0.5]),
                                  core.SequenceInterpolator([v, target, third], t).poses(0, [0.25, 0.5]))


@pytest.mark.skipif(np.finfo(np.longdouble).max <= np.finfo(np.float64).max, reason="long double is double here")
def test_a_longdouble_coordinate_past_double_precision_is_refused_by_its_size(sheet):
    """A long-double key with a coordinate of 1e400 (finite there, past double precision) was refused
    as "a non-finite coordinate [inf, …]" after NumPy's "overflow encountered in cast"; it is refused as
    past the supported 1e+30, with its value, without NumPy's warning."""
    v, t, target = sheet
    far = target.astype(np.longdouble)
    far[4, 1] = np.longdouble("1e400")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no NumPy overflow warning on the way
        with pytest.raises(MeshError, match=r"key pose 1 of key_poses: vertex 4 has coordinate 1e\+400, beyond the "
                                            r"supported 1e\+30"):
            core.SequenceInterpolator([v, far], t)


def test_a_masked_array_is_refused_in_the_terms_of_what_it_holds(sheet):
    """Triangles given as a masked array with an index masked are refused naming the triangles and
    what to do with them; before, the message ended "or leave that pose out", about a pose the user
    had not given. A mask given as one value (``nomask``, False) masks nothing: the array is its data;
    one given as True masks every value, and is refused."""
    v, t, target = sheet
    holed = np.ma.masked_array(t.copy(), mask=False)
    holed[3, 1] = np.ma.masked
    with pytest.raises(MeshError, match=r"triangles is a masked array with 1 masked value\(s\), the first at index "
                                        r"\(3, 1\)") as refused:
        core.SequenceInterpolator([v, target], holed)
    assert "pose" not in str(refused.value)
    for whole in (np.ma.masked_array(target, mask=np.ma.nomask), np.ma.masked_array(target, mask=False)):
        np.testing.assert_array_equal(core.SequenceInterpolator([v, whole], t).poses(0, [0.5]),
                                      core.SequenceInterpolator([v, target], t).poses(0, [0.5]))
    with pytest.raises(MeshError, match=rf"{target.size:,} masked value\(s\), the first at index \(0, 0\)"):
        core.SequenceInterpolator([v, np.ma.masked_array(target, mask=True)], t)
