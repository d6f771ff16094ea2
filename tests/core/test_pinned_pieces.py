"""Pinned pieces: a piece holding vertices still in every key (pins) is fitted rigid motions that
keep them there where that leaves its triangles less to turn (core.inbetween_rigid_fits.pin_held_fits,
core.rigid_alignment.pivoted_alignment)."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import core
from core.rigid_alignment import pivoted_alignment
from inbetween_helpers import _flipped

DATA = Path(__file__).parent / "data" / "pinned_handkerchief.npz"


@pytest.mark.parametrize("pivots, free", [(3, 0), (2, 1), (1, 3)])
def test_pivoted_alignment_keeps_the_pivots_and_finds_a_turn_about_them(pivots, free):
    """Pivots spanning a plane allow no turn; on a line, a turn about it; at a point, any turn
    about it: a rigid motion of that kind is found exactly, and the pivots stay."""
    rng = np.random.default_rng(pivots)
    source = rng.normal(size=(40, 3))
    points = source[:pivots] if pivots > 1 else source[:1]
    centre = points.mean(axis=0)
    axis = (points[1] - points[0]) / np.linalg.norm(points[1] - points[0]) if pivots == 2 else np.array([0.3, -0.5, 0.8])
    turn = Rotation.from_rotvec(2.5 * axis / np.linalg.norm(axis)).as_matrix() if free else np.eye(3)
    target = (source - centre) @ turn.T + centre
    rotation, translation = pivoted_alignment(source, target, points, np.ones(len(source)))
    assert np.allclose(source @ rotation.T + translation, target, atol=1e-10)
    assert np.allclose(points @ rotation.T + translation, points, atol=1e-10)


@pytest.mark.parametrize("count", [1, 3])
def test_the_pin_fits_measure_the_turn_left_to_each_triangle(count):
    """The angle each triangle's rotation ``W`` still turns once its piece's rigid rotation ``R``
    is undone (``Rᵀ W``), from the nine products of the entries, against SciPy's angle of the
    composed matrices (to arccos's rounding near 0 and π), one piece and several."""
    from core.inbetween_rigid_fits import _fit_undone_angles

    rng = np.random.default_rng(count)
    whole = Rotation.random(300, random_state=count).as_matrix()
    rotations = Rotation.random(count, random_state=10 + count).as_matrix()
    pieces = rng.integers(0, count, size=len(whole))
    whole[:5] = rotations[pieces[:5]]  # nothing left to turn
    expected = Rotation.from_matrix(np.transpose(rotations[pieces], (0, 2, 1)) @ whole).magnitude()
    angles = _fit_undone_angles(np.ascontiguousarray(whole.transpose(1, 2, 0)), rotations, pieces)
    np.testing.assert_allclose(angles, expected, rtol=0, atol=1e-7)


def test_a_pinned_gap_makes_its_whole_rotations_once_per_relative(monkeypatch):
    """A gap of the pinned handkerchief: the pins' fits, the reading of which way its parts turn
    and the test whether its residuals add turn all read the triangles' whole rotations from the
    base key; each relative forms rotations' entries on all its triangles twice at most (its
    residuals' and, once for all those readers, its whole rotations'), and none keeps them (nor
    the frames they are made from) once the gap is prepared."""
    import core.deformation_fields as df
    import core.inbetween_keys as keys_module

    data = np.load(DATA)
    keys, triangles = data["keys"].astype(np.float64), data["triangles"]
    seq = core.SequenceInterpolator(keys, triangles, start="keys")
    made, relatives = [], []
    real_entries, real_init = df.frame_rows_rotation_entries, keys_module.Relative.__init__
    monkeypatch.setattr(df, "frame_rows_rotation_entries", lambda f, b: made.append(f.shape[-1]) or real_entries(f, b))
    monkeypatch.setattr(keys_module.Relative, "__init__",
                        lambda self, *args, **kw: relatives.append(self) or real_init(self, *args, **kw))
    gap = seq._gap(1)
    assert seq._topo.pinned is not None and relatives
    full = [rows for rows in made if rows == len(triangles)]
    assert len(full) <= 2 * len(relatives), (len(full), len(relatives))
    assert all(r.__dict__.get("_whole") is None and r.__dict__.get("_plane_frames") is None for r in gap.relatives)


@pytest.mark.parametrize("seed", range(8))
def test_the_pins_fit_is_measured_only_where_it_can_win_and_chosen_as_when_always_measured(monkeypatch, seed):
    """Each piece's pins' fit is taken where it leaves its triangles' median angle smaller by
    PIN_FIT_MARGIN and fewer of them near a half turn; a triangle's angle under it is at least the
    two fits' angle apart less its angle under the free fit, so where that bound (or no triangle
    near a half turn under the free fit) rules it out, its angles are not measured. Over pieces
    whose triangles turn little about the free fit, little about the pins' one, or anywhere, the
    fits chosen are those of measuring both, with angles from SciPy; the first two seeds are the
    extremes (every triangle on the free fit: the pins' fit not measured; on the pins' one, turned
    170° from the free fit: measured and taken)."""
    import core.inbetween_rigid_fits as fits_module
    from core.inbetween_keys import Key
    from core.inbetween_rigid_fits import NEAR_HALF_TURN, PIN_FIT_MARGIN, pin_held_fits
    from core.inbetween_topology import Topology
    from core.mesh_topology import mesh_topology
    from meshes import grid

    rng = np.random.default_rng(seed)
    sheet, tri = grid(9, 9, size=1.0)
    count = 1 if seed < 2 else 3
    vertices = np.vstack([sheet + [2.0 * c, 0.0, 0.0] for c in range(count)])
    triangles = np.vstack([tri + c * len(sheet) for c in range(count)])
    topo = Topology(mesh_topology(triangles, len(vertices)), vertices)
    topo.pinned = np.array([c * len(sheet) for c in range(count)])
    key = Key(topo, vertices)
    free = Rotation.random(count, random_state=seed).as_matrix()
    held = (Rotation.from_rotvec(rng.normal(size=(count, 3)) * rng.uniform(0.2, 3.0, size=(count, 1)))
            * Rotation.from_matrix(free)).as_matrix()
    if seed == 1:
        held = (Rotation.from_rotvec([[0.0, 0.0, np.radians(170.0)]]) * Rotation.from_matrix(free)).as_matrix()
    pieces = topo.triangle_component
    spread = [0.0, 0.0, 0.3, 3.0][min(seed, 3)]
    around = np.where((rng.random(count) < 0.5)[pieces, None, None], held[pieces], free[pieces])
    around = held[pieces] if seed == 1 else free[pieces] if seed == 0 else around
    whole = (Rotation.from_rotvec(spread * rng.normal(size=(len(pieces), 3))) * Rotation.from_matrix(around)).as_matrix()
    entries = np.ascontiguousarray(whole.transpose(1, 2, 0))
    calls = iter(range(count))
    monkeypatch.setattr(fits_module, "pivoted_alignment", lambda *a: (held[next(calls)], np.zeros(3)))
    measured = []
    real = fits_module._fit_undone_angles
    monkeypatch.setattr(fits_module, "_fit_undone_angles", lambda e, r, p: measured.append(r.copy()) or real(e, r, p))
    rotations, _, _ = pin_held_fits(topo, key, key, lambda: entries, free, np.zeros((count, 3)), np.zeros(count))

    def left(fits):  # per piece: the median angle and the count near a half turn, with the fit undone
        angles = (Rotation.from_matrix(fits[pieces]).inv() * Rotation.from_matrix(whole)).magnitude()
        return (np.array([np.median(angles[pieces == c]) for c in range(count)]),
                np.bincount(pieces, angles > NEAR_HALF_TURN, count))
    apart = (Rotation.from_matrix(held).inv() * Rotation.from_matrix(free)).magnitude()
    (held_median, held_near), (free_median, free_near) = left(held), left(free)
    use = (apart > PIN_FIT_MARGIN) & (held_median < free_median - PIN_FIT_MARGIN) & (held_near < free_near)
    np.testing.assert_array_equal(rotations, np.where(use[:, None, None], held, free))
    if seed == 0:
        assert len(measured) == 1 and not use.any()
    if seed == 1:
        assert len(measured) == 2 and use.all()


def test_a_handkerchief_pinned_at_its_centre_is_not_turned_half_round():
    """Keys 8 frames apart of a Blender cloth pinned at its four centre vertices and blown by
    turbulence into a bundle that looks alike after a half turn (frames 8, 16, 24, 32 and the
    simulated frame 20 of a 10,000-vertex bake nobody on the team made): the free rigid fit between
    keys 16 and 24 turned 176° about the pins, and splined with the triangles' residuals (110°
    median where they turn 82°) the in-between at frame 20 had 6,007 flipped triangles and 1.6 ×
    the blend's error; the two-pose in-between at factor 1/8 lay 0.13 from the blend (a pop next
    to the key). Fitted keeping the pins: no flipped triangle, half the blend's error, and the
    two-pose in-betweens near the blend next to the keys (0.75: 0.25 from it before, 0.04 now)."""
    data = np.load(DATA)
    keys, middle, triangles = data["keys"].astype(np.float64), data["middle"].astype(np.float64), data["triangles"]
    a, b = keys[1], keys[2]

    def rms(x, y):
        return float(np.sqrt(np.mean(np.sum((x - y) ** 2, axis=1))))

    x = core.SequenceInterpolator(keys, triangles, start="keys").pose(1, 0.5)
    assert _flipped(x, a, b, triangles) == 0
    assert rms(x, middle) < 0.6 * rms(0.5 * (a + b), middle)
    pair = core.Interpolator(a, b, triangles)
    for s in (0.125, 0.75):  # nearer the blend than the blend is to the nearer key (before: 2 ×)
        y = pair.pose(s)
        assert _flipped(y, a, b, triangles) == 0
        assert rms(y, (1 - s) * a + s * b) < min(s, 1 - s) * rms(a, b)
