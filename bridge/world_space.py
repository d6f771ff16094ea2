"""Where poses are interpolated: in the world's proportions when an object's world matrix stretches it
(:class:`WorldProportions`), through each frame's matrix when that stretch changes from key to key
(:class:`WorldFrames`), and the world matrices a new object is placed by.
"""

from __future__ import annotations

import bpy
import numpy as np

from .modifier_kinds import SIMULATION_MODIFIERS
from .scene_timing import at_times

#: Relative spread of the singular values of an object's world matrix above which poses are
#: interpolated in the world's proportions (:class:`WorldProportions`).
SIMILARITY_TOLERANCE = 1e-6


class WorldProportions:
    """The linear part of ``obj``'s world matrix when it is not a rotation times one scale (an
    object scaled along one axis in Object Mode, not applied): the simulation (and what the artist
    sees) is in the world, where the mesh's own coordinates are stretched, so a turning fold looks
    sheared there and in-betweens computed there keep the wrong lengths (a flag keyed every 8th
    frame, scaled (2, 1, 1): edge deviation 0.79 → 2.80 %, RMS error ×2; the linear blend does not
    care). Poses go through :meth:`to` before the core and :meth:`back` after; for a similarity
    (any rotation, one scale) nothing is done. ``matrix``: the world matrix (4, 4) the poses were
    shown under (frames read: one of theirs), else ``obj``'s at the current frame (its shape keys).
    An object an armature deforms (one rig, by an Armature modifier, shown or not, or an armature
    parent), and no cloth or soft body simulates in the world, is taken into the rig's space
    instead: the armature turns its bones there (the mesh's coordinates through the rig's inverse
    world matrix), so under a rig scaled (2, 1, 1) a bent limb's turn is a turn there and a shear
    in the world (In-between half-way 0.23 of the diagonal off the rig, 0.026 unscaled). So is an
    object whose Lattice modifier's lattice one rig deforms: a lattice moves the mesh by weights
    fixed in its cells, the same in any space, so the mesh turns where the lattice's points turn, in
    the rig's space (a bar bent 100° under a rig scaled (2, 1, 1): half-way 0.19 of the diagonal
    off the lattice's own pose in the world's proportions, 0.035 in the rig's). A lattice no rig
    deforms is not such a space: its points are turned in the world (Edit Mode in the viewport, a
    hook), where the mesh then turns (the same bar: 0.038 in the world's proportions, 0.18 in the
    lattice object's space, scaled (1.76, 0.9, 0.9) to fit the bar). The rig's space is the one
    of the frame ``matrix`` was read at (``rig_matrix``, the rig's world matrix (4, 4) there; by
    default the rig's at the current frame, that of the shape keys): a mesh the rig carries then
    has the same map whatever the rig's own turn (a rig scaled (2, 1, 1) and turned as an object
    between the frames read and the current one). The rig's space stands for the whole mesh where
    a vertex group limits the armature to a part (the rest does not move, in any space), and
    for Preserve Volume (it turns the bones there too); an Armature modifier counts whether it is
    enabled in the viewport, in renders or in neither. A rig whose scale is keyframed stretches a
    mesh it carries differently from frame to frame: those frames go through the world
    (:class:`WorldFrames`, :func:`frames_space`), not the rig's space."""

    def __init__(self, obj: bpy.types.Object, matrix: np.ndarray | None = None,
                 rig_matrix: np.ndarray | None = None):
        linear = np.array(obj.matrix_world if matrix is None else matrix, dtype=np.float64)[:3, :3]
        rig = the_rig(obj)
        if rig is not None:
            rig = np.array(rig.matrix_world if rig_matrix is None else rig_matrix, dtype=np.float64)[:3, :3]
            if not _flattens(rig):  # else the world's, refused by its scale
                linear = np.linalg.solve(rig, linear)
        sigma = np.linalg.svd(linear, compute_uv=False)
        skewed = sigma[-1] > 0 and sigma[0] / sigma[-1] - 1.0 > SIMILARITY_TOLERANCE
        linear = _unmirrored(linear)
        self.matrix = linear.T if skewed else None  # row vectors: x ↦ x Lᵀ
        self.inverse = np.linalg.inv(linear).T if skewed else None

    def to(self, positions: np.ndarray, time: float | None = None) -> np.ndarray:
        """Positions (…, n, 3) in the world's proportions (the same at every ``time``)."""
        return positions if self.matrix is None else positions @ self.matrix

    def linear(self, time: float | None = None) -> np.ndarray | None:
        """The linear map (3, 3) :meth:`to` applies (the same at every ``time``), None where it
        leaves the poses in the mesh's coordinates."""
        return None if self.matrix is None else self.matrix.T

    def reading(self, times):
        """Nothing to read: the proportions are the same at every time (as :meth:`WorldFrames.reading`)."""
        yield from ()

    def read(self, times) -> None:
        """Nothing to read (as :meth:`WorldFrames.read`)."""

    def back(self, positions: np.ndarray, times=None) -> np.ndarray:
        """Positions (…, n, 3) in the world's proportions back in the mesh's coordinates (the same at
        every time of ``times``)."""
        return positions if self.inverse is None else positions @ self.inverse


def the_rig(obj: bpy.types.Object) -> bpy.types.Object | None:
    """The one armature object that deforms ``obj``, directly (:func:`_rigs`) or through the
    lattices of its Lattice modifiers, where no Cloth or Soft Body modifier simulates it in the
    world; None where none or several do (:class:`WorldProportions` then keeps the world's)."""
    rigs = _rigs(obj)
    for lattice in {modifier.object for modifier in obj.modifiers if modifier.type == 'LATTICE' and modifier.object}:
        rigs |= _rigs(lattice)
    if len(rigs) != 1 or any(modifier.type in SIMULATION_MODIFIERS for modifier in obj.modifiers):
        return None
    return next(iter(rigs))


def _rigs(obj: bpy.types.Object) -> set:
    """The armature objects that deform ``obj`` (a mesh or a lattice): those its Armature modifiers
    name, shown or not (the keys a user applies from them are their turns), and its armature parent."""
    rigs = {modifier.object for modifier in obj.modifiers if modifier.type == 'ARMATURE' and modifier.object}
    if obj.parent is not None and obj.parent_type == 'ARMATURE':
        rigs.add(obj.parent)
    return rigs


def _unmirrored(matrix: np.ndarray) -> np.ndarray:
    """The world matrix ``matrix`` (4, 4), or its linear part (3, 3), with its first row's linear
    part negated where it mirrors: mirrored back in the world (an isometry there), so that the
    triangles keep their side (offset surfaces, bending's sign)."""
    matrix = np.array(matrix, dtype=np.float64)
    if np.linalg.det(matrix[:3, :3]) < 0:
        matrix[0, :3] = -matrix[0, :3]
    return matrix


def _polar(matrix) -> tuple[np.ndarray, np.ndarray]:
    """``(R, S)`` of the linear part ``L = R S`` of the world matrix ``matrix`` (4, 4): ``R`` orthogonal
    (a rotation, or a rotation and a mirror), ``S`` the symmetric stretch."""
    u, sigma, vt = np.linalg.svd(np.asarray(matrix, dtype=np.float64)[:3, :3])
    return u @ vt, (vt.T * sigma) @ vt


def _flattens(linear: np.ndarray) -> bool:
    """Whether the linear map ``linear`` (3, 3) flattens what it maps: its smallest singular value at
    most machine epsilon × its largest (no shape it shows can be taken back)."""
    sigma = np.linalg.svd(linear, compute_uv=False)
    return not sigma[-1] > np.finfo(np.float64).eps * sigma[0]


def shown_under(positions: np.ndarray, shown, under) -> np.ndarray | None:
    """Positions (n, 3) of an object's mesh shown under the world matrix ``shown`` (4, 4), as the
    mesh coordinates that show them at the same places under the world matrix ``under`` (4, 4): a
    pose read at a frame whose matrix is not that of the frames interpolated (a simulation's first
    frame before the range, its object scaled or turned since), taken to theirs, so that its edges
    are the world's there in their proportions. ``positions`` itself where the two matrices are the
    same; None where ``shown`` flattens the mesh (:func:`_flattens`, as :class:`WorldProportions` takes a
    rig's): what the world shows there is no shape the mesh's coordinates can hold."""
    shown, under = np.asarray(shown, dtype=np.float64), np.asarray(under, dtype=np.float64)
    if np.array_equal(shown, under):
        return positions
    if _flattens(shown[:3, :3]):
        return None
    world = positions @ shown[:3, :3].T + shown[:3, 3]
    return np.linalg.solve(under[:3, :3], (world - under[:3, 3]).T).T


def with_proportions(placement, proportions) -> np.ndarray:
    """The world matrix (4, 4) that places an object where ``placement`` (4, 4) does (its turn,
    mirror and translation) and stretches it as ``proportions`` (4, 4) does (:func:`_polar`'s ``S``):
    ``placement`` itself where the two stretch alike (:func:`proportions_change`)."""
    matrix = np.array(placement, dtype=np.float64)
    if proportions_change([placement, proportions]):
        matrix[:3, :3] = _polar(placement)[0] @ _polar(proportions)[1]
    return matrix


def proportions_change(matrices) -> bool:
    """Whether the world matrices (4, 4) ``matrices`` stretch the mesh differently: the symmetric
    factors ``S`` of their linear parts (``L = R S``, :func:`_polar`) differ by more than
    :data:`SIMILARITY_TOLERANCE` of the largest scale (an object whose scale is keyframed)."""
    stretches = [_polar(matrix)[1] for matrix in matrices]
    if not stretches:
        return False
    spread = max(np.abs(stretch - stretches[0]).max() for stretch in stretches)
    return bool(spread > SIMILARITY_TOLERANCE * max(np.abs(stretch).max() for stretch in stretches))


class WorldFrames:
    """Poses of an object whose world matrix stretches it differently from key to key (its scale
    keyframed in Object Mode, not applied). The simulation keeps its lengths in the world, where
    the mesh's own coordinates are scaled by another factor at every frame: there a hanging sheet
    on an object scaled 1 → 1.6 → 0.8 changes its lengths with the scale, and in-betweens computed
    there and played under the object's matrix of their frame come out 4.4 / 9.4 % off their
    lengths (keys 8 / 16 frames apart; the simulation 0.7 %), 1,801 triangles turned over at
    keys 16 apart. Poses go to the world through the matrix of their own frame (:meth:`to`) and
    back through the matrix of each in-between's time (:meth:`back`, read at its sub-frame)."""

    def __init__(self, context: bpy.types.Context, obj: bpy.types.Object, matrices: dict):
        self.context, self.obj = context, obj
        self.matrices = {time: _unmirrored(matrix) for time, matrix in matrices.items()}

    def to(self, positions: np.ndarray, time: float) -> np.ndarray:
        """Positions (n, 3) of the frame ``time`` (one of the frames read) in the world."""
        matrix = self.matrices[time]
        return positions @ matrix[:3, :3].T + matrix[:3, 3]

    def linear(self, time: float) -> np.ndarray:
        """The linear part (3, 3) of the matrix :meth:`to` takes the frame ``time`` through."""
        return self.matrices[time][:3, :3]

    def reading(self, times):
        """Read the object's matrix at each of ``times`` not read yet, yielding after each: one pass
        over the scene's frames for all of them, the scene set to each time once and back to its
        current frame once at the end, rather than once per call of :meth:`back` (a 10k cloth's
        baked frame takes 0.5 ms to set, a return to its start frame 35 ms)."""
        missing = sorted(set(time for time in times if time not in self.matrices))
        for time in at_times(self.context.scene, missing):
            self.matrices[time] = _unmirrored(np.array(self.obj.matrix_world, dtype=np.float64))
            yield time

    def read(self, times) -> None:
        """:meth:`reading` ``times`` at once."""
        for _ in self.reading(times):
            pass

    def back(self, positions: np.ndarray, times) -> np.ndarray:
        """World positions (k, n, 3) of the poses at ``times`` (k) in the mesh's coordinates."""
        self.read(times)
        return np.stack([(pose - self.matrices[time][:3, 3]) @ np.linalg.inv(self.matrices[time][:3, :3]).T
                         for pose, time in zip(positions, times)])


def frames_space(context: bpy.types.Context, obj: bpy.types.Object, matrices: dict):
    """Where to interpolate frames of ``obj`` read with its world matrices ``matrices`` ({frame:
    (4, 4)}): the world through each frame's matrix (:class:`WorldFrames`) where they stretch the
    mesh differently (:func:`proportions_change`: its scale keyframed), else the world's
    proportions, the same at every frame read (:class:`WorldProportions`, those of the frames' matrices:
    the current frame, outside them, may show the object under another scale). Without ``matrices``,
    those of the current frame."""
    if proportions_change(matrices.values()):
        return WorldFrames(context, obj, matrices)
    frame, matrix = next(iter(matrices.items()), (None, None))
    rig, rig_matrix = the_rig(obj), None
    if rig is not None and frame is not None:  # the rig's space of that frame (WorldProportions)
        for _ in at_times(context.scene, [frame]):
            rig_matrix = np.array(rig.matrix_world, dtype=np.float64)
    return WorldProportions(obj, matrix, rig_matrix)
