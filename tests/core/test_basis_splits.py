"""A truncated basis size that splits a group of equal Laplace–Beltrami eigenvalues (paper §4–5:
the differences live in the first k_M eigenfunctions of the base, eq. (6) also in the first k_N of
the target) holds an arbitrary part of that eigenspace, chosen by rounding: the core warns
(``truncated``) and names the nearest sizes that split no group."""

import warnings

import numpy as np
import pytest
from meshes import grid, icosphere, stretch_and_bend

from core.laplace_basis import REPEATED_GAP, split_group
from core.reference_shape import ReferenceShape


def _split_warnings(vertices, triangles, target, k_M, k_N=None, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ReferenceShape(vertices, triangles, **options).shape_differences(target, k_M=k_M, k_N=k_N)
    return [str(w.message) for w in caught
            if getattr(w.message, "kind", None) == "truncated" and "splits" in str(w.message)]


def test_split_group_finds_the_whole_group_of_equal_eigenvalues_around_the_cut():
    """Against the groups read off by hand: equal within :data:`REPEATED_GAP` (relative) joins,
    twice it does not; a group reaching the last value computed ends there."""
    values = np.array([0.0, 2.0, 2.0 * (1 + REPEATED_GAP / 2), 2.0 * (1 + REPEATED_GAP), 5.0, 7.0, 7.0])
    assert split_group(values, 1) is None  # 0 | 2
    assert split_group(values, 2) == (1, 4)
    assert split_group(values, 3) == (1, 4)
    assert split_group(values, 4) is None  # 2.0…2.00000003 | 5
    assert split_group(values, 6) == (5, 7)  # reaches the end: may go on
    spread = np.array([1.0, 1.0 + 3 * REPEATED_GAP, 2.0])
    assert split_group(spread, 1) is None


def test_an_icosphere_warns_at_a_size_inside_its_five_fold_eigenvalue_and_names_the_safe_sizes():
    """The 162-vertex icosphere's eigenvalues 17–21 of the base (22.64, 5-fold; 22.71 4-fold
    after it) and 21–25 of the offset surface (the 4-fold one first) are equal groups: k_M = 20
    and 21 each split one, 16 and 25 neither — the sizes the message offers."""
    vertices, triangles = icosphere(2)
    target = vertices * np.array([1.2, 1.0, 0.8])
    assert _split_warnings(vertices, triangles, target, 16) == []
    assert _split_warnings(vertices, triangles, target, 25) == []
    at_20 = _split_warnings(vertices, triangles, target, 20)
    assert len(at_20) == 1 and "k_M = 20 splits a group of 5 equal frequencies" in at_20[0]
    assert "base mesh" in at_20[0] and "use k_M = 16 or 25" in at_20[0]
    at_21 = _split_warnings(vertices, triangles, target, 21)
    assert len(at_21) == 1 and "offset surface" in at_21[0] and "use k_M = 16 or 25" in at_21[0]
    # intrinsic only: the base alone decides, and 21 splits none of its groups
    assert _split_warnings(vertices, triangles, target, 21, use_extrinsic=False) == []


def test_a_regular_grid_warns_at_a_size_inside_an_eigenvalue_pair():
    """A square grid's Laplacian has pairs of equal eigenvalues (x ↔ y): its 10th and 11th."""
    vertices, triangles = grid(11)
    target = stretch_and_bend(vertices)
    found = _split_warnings(vertices, triangles, target, 10)
    assert len(found) == 1 and "a group of 2 equal frequencies" in found[0] and "use k_M = 9 or 11" in found[0]
    assert _split_warnings(vertices, triangles, target, 11) == []


@pytest.mark.parametrize("n, jitter", [(11, 0.1), (20, 0.02)])
def test_meshes_without_a_symmetry_do_not_warn_at_any_size(n, jitter):
    """Jittered grids (irregular, as a scan re-meshed): no basis size from 3 to 40 warns."""
    vertices, triangles = grid(n, jitter=jitter)
    target = stretch_and_bend(vertices)
    reference = ReferenceShape(vertices, triangles)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for k in range(3, 41):
            reference.shape_differences(target, k_M=k)
    assert not [w for w in caught if "splits" in str(w.message)]


def test_a_symmetric_target_warns_where_k_N_splits_its_equal_eigenvalues():
    """Eq. (6): the target's basis is truncated too; a jittered base posed as the regular grid
    (pairs of equal eigenvalues, its 10th and 11th) warns at k_N = 10, not at 11."""
    regular, triangles = grid(11)
    jittered, _ = grid(11, jitter=0.1)
    found = _split_warnings(jittered, triangles, regular, 5, 10, use_extrinsic=False)
    assert len(found) == 1 and "k_N = 10" in found[0] and "target pose" in found[0]
    assert "use k_N = 9 or 11" in found[0]
    assert _split_warnings(jittered, triangles, regular, 5, 11, use_extrinsic=False) == []


# -- the other paths that truncate a base (or pulled-back) basis at a size the user gives ---------

def _turned(vertices, angle=1e-9):
    """``vertices`` turned by ``angle`` rad about a fixed oblique axis (a rounding-size change)."""
    from scipy.spatial.transform import Rotation

    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    return vertices @ Rotation.from_rotvec(angle * axis).as_matrix().T


def _splits(call):
    """``(result, split warnings' messages)`` of ``call()``."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = call()
    return result, [str(w.message) for w in caught
                    if getattr(w.message, "kind", None) == "truncated" and "splits" in str(w.message)]


def test_a_transfer_warns_where_k_M_splits_a_group_of_the_base():
    """A Transfer writes the target's differences in the base's first k_M functions: from the
    162-vertex icosphere to the 642-vertex one, k_M = 20 ends inside the base's five-fold group
    (17–21; intrinsic, so the offset surface's groups do not count) and warns; 16 does not."""
    from core.transfer import Transfer

    base, triangles = icosphere(2)
    target, target_triangles = icosphere(3)
    _, found = _splits(lambda: Transfer(base, triangles, target, target_triangles, k_M=20, k_N=40))
    assert len(found) == 1 and "k_M = 20 splits a group of 5 equal frequencies" in found[0]
    assert "use k_M = 16 or 21" in found[0]
    _, found = _splits(lambda: Transfer(base, triangles, target, target_triangles, k_M=16, k_N=40))
    assert found == []


def test_shape_space_warns_where_k_M_splits_and_not_where_k_N_cuts_a_group():
    """The shape space's features are the differences in the base's first k_M functions: k_M = 20
    splits the icosphere's five-fold group and warns. k_N = 38 ends inside a group of the base pose
    (36–39) but the pose's basis is cut at a spectral gap, and eq. (6) is unchanged by a turn of
    that basis within whole groups: no warning, and the coordinates of a 1e-9 rad turned copy of
    every pose agree to round-off (measured 4e-14 of their largest)."""
    from core.shape_space_pca import KINDS, shape_space

    vertices, triangles = icosphere(2)
    poses = [vertices, stretch_and_bend(vertices), stretch_and_bend(vertices, seed=2), vertices * [1.1, 1.0, 0.9]]
    _, found = _splits(lambda: shape_space(poses, triangles, k_M=20, k_N=None))
    assert len(found) == 1 and "k_M = 20" in found[0] and "use k_M = 16 or 25" in found[0]
    space, found = _splits(lambda: shape_space(poses, triangles, k_M=25, k_N=38))
    assert found == []
    turned = shape_space([_turned(pose) for pose in poses], triangles, k_M=25, k_N=38)
    for kind in KINDS:
        coordinates = space.coordinates(kind, 3)
        assert np.allclose(turned.coordinates(kind, 3), coordinates, rtol=0, atol=1e-10 * np.abs(coordinates).max())


def test_distortion_eigenfunctions_warn_where_k_splits_the_layer_they_live_on():
    """The eigenfunctions of a difference operator are those of its restriction to the first k
    functions of their layer: k = 20 splits the icosphere's base group (17–21), not the offset
    surface's (21–25), so the offset kinds do not warn and their eigenpairs agree with those of a
    1e-9 rad turned copy to round-off (1e-13 measured); the intrinsic kinds warn, once."""
    from core.distortion_maps import DistortionAnalyzer

    vertices, triangles = icosphere(2)
    pose = stretch_and_bend(vertices)
    analyzer = DistortionAnalyzer(vertices, triangles, k=20)
    turned = DistortionAnalyzer(_turned(vertices), triangles, k=20).pose(_turned(pose))
    distortion = analyzer.pose(pose)
    for kind in ("offset_area", "offset_conformal"):
        (values, functions), found = _splits(lambda: distortion.eigenfunctions(kind, 4))
        assert found == []
        turned_values, turned_functions = turned.eigenfunctions(kind, 4)
        assert np.allclose(turned_values, values, rtol=1e-10, atol=0)
        # each function up to its sign: a turn may flip which of its extremes is the largest
        apart = np.minimum(np.abs(turned_functions - functions), np.abs(turned_functions + functions)).max()
        assert apart < 1e-9
    _, found = _splits(lambda: [distortion.eigenfunctions(kind, 4) for kind in ("area", "conformal")])
    assert len(found) == 1 and "k = 20 splits" in found[0] and "use k = 16 or 25" in found[0]
    _, found = _splits(lambda: DistortionAnalyzer(vertices, triangles, k=25).pose(pose).eigenfunctions("area", 4))
    assert found == []


def test_the_wave_kernel_signature_warns_where_k_splits_and_the_eigenpairs_do_not():
    """The WKS weighs a group's functions alike: a sum over the whole group is the same for any
    orthonormal basis of it (at k = 25 the WKS of a 1e-9 rad turned copy agrees to round-off,
    1e-14 measured), over part of it is not: k = 20 warns. The eigenvalues do not depend on where
    the basis ends and eigenfunctions of a group are an arbitrary choice at any k: no warning."""
    import core

    vertices, triangles = icosphere(2)

    def metric(base):  # a uniformly scaled sphere: the pulled-back metric keeps its symmetry
        return core.pull_back(base, triangles, core.shape_differences(base, 1.5 * base, triangles))

    pulled = metric(vertices)
    _, found = _splits(lambda: (pulled.laplacian_eigenvalues(20), pulled.eigenfunctions(20)))
    assert found == []
    _, found = _splits(lambda: pulled.wave_kernel_signature(20, k=20))
    assert len(found) == 1 and "k = 20 splits" in found[0] and "pulled-back metric" in found[0]
    signature, found = _splits(lambda: pulled.wave_kernel_signature(20, k=25))
    assert found == []
    turned = metric(_turned(vertices)).wave_kernel_signature(20, k=25)
    assert np.allclose(turned, signature, rtol=0, atol=1e-10 * signature.max())


@pytest.mark.parametrize("path", ["shape_differences", "another mesh", "Transfer", "shape_space",
                                  "shape_space_steps", "eigenfunctions", "wave_kernel_signature"])
def test_the_split_warning_points_at_the_callers_line(path):
    """Each path's warning is attributed to the line of the caller's own code that made the call
    (the warning's filename and line), not to a line inside the library: the shape space's
    generator advanced by :func:`shape_space`, and a Transfer built by ``shape_differences`` with
    another target mesh, included."""
    import core
    from core.distortion_maps import DistortionAnalyzer
    from core.shape_space_pca import shape_space_steps
    from core.transfer import Transfer

    vertices, triangles = icosphere(2)
    target, target_triangles = icosphere(3)
    pose = stretch_and_bend(vertices)
    poses = [vertices, pose, vertices * [1.1, 1.0, 0.9]]
    distortion = DistortionAnalyzer(vertices, triangles, k=20).pose(pose)
    pulled = core.pull_back(vertices, triangles, core.shape_differences(vertices, 1.5 * vertices, triangles))

    def steps():
        for _ in shape_space_steps(poses, triangles, k_M=20, k_N=None):  # the caller advances the generator
            pass

    calls = {  # each call on a line of its own, with that line
        "shape_differences": lambda: core.shape_differences(vertices, pose, triangles, k_M=20),
        "another mesh": lambda: core.shape_differences(vertices, target, triangles, k_M=20, k_N=40,
                                                       target_triangles=target_triangles),
        "Transfer": lambda: Transfer(vertices, triangles, target, target_triangles, k_M=20, k_N=40),
        "shape_space": lambda: core.shape_space(poses, triangles, k_M=20, k_N=None),
        "shape_space_steps": steps,
        "eigenfunctions": lambda: distortion.eigenfunctions("area", 4),
        "wave_kernel_signature": lambda: pulled.wave_kernel_signature(20, k=20),
    }
    call = calls[path]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    (warning,) = [w for w in caught if "splits" in str(w.message)]
    code = call.__code__ if path != "shape_space_steps" else steps.__code__
    line = code.co_firstlineno + (1 if path == "shape_space_steps" else 0)
    assert (warning.filename, warning.lineno) == (__file__, line)


def test_the_wave_kernel_signature_warns_whatever_was_computed_before():
    """Whether a size splits a group does not depend on the calls before: the pulled-back metric of
    a scaled icosphere has equal eigenvalues 37–39 (its indices 36–38), so k = 38 splits them,
    fresh or after a call at k = 36 (whose basis, computed two past it, ends exactly at 38), and
    k = 36, which ends a group, warns neither way."""
    import core

    vertices, triangles = icosphere(2)

    def metric():
        return core.pull_back(vertices, triangles, core.shape_differences(vertices, 1.5 * vertices, triangles))

    values = metric().laplacian_eigenvalues(45)
    assert split_group(values, 38) == (36, 39) and split_group(values, 36) is None
    fresh = metric()
    _, found = _splits(lambda: fresh.wave_kernel_signature(10, k=38))
    assert len(found) == 1 and "k = 38 splits a group of 3" in found[0]
    after = metric()
    _, found = _splits(lambda: after.wave_kernel_signature(10, k=36))
    assert found == []
    _, found = _splits(lambda: after.wave_kernel_signature(10, k=38))
    assert len(found) == 1 and "k = 38 splits a group of 3" in found[0]
