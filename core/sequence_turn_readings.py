"""Parts of a piece that turn past a half turn from the rest of it between two keys of a sequence
(paper §5.3's rotations across a mesh, §8.4): :class:`TurnReadings` reads which way round each
gap takes their turns and whether the readings of neighbouring gaps agree (kept per gap);
:func:`composed_apart` measures how far the two ways of composing the turns part;
:func:`turn_warnings` words what a gap warns about its turns."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .rotation_continuity import WRAP_CREASE, jumping_pairs
from .rotation_continuity import unwrapped_rotation_vectors
from .inbetween_keys import Relative
from .inbetween_solver import Gap
from .inbetween_topology import Topology
from .sequence_keys import GAP_CACHE

#: A sequence's gap where a part of a piece over this share of its area turns past a half turn
#: from the rest of it between the keys (the triangles' whole rotations, taken continuous across
#: the mesh where no jump joins a fold's crease, are past π there:
#: :func:`core.rotation_continuity.continuous_rotation_vectors`, :data:`~core.rotation_continuity.WRAP_CREASE`)
#: takes that piece's rotations whole, the next key's continuous across the mesh, and does not
#: anchor it to the keys' per-vertex spline (:meth:`core.inbetween_anchor.Anchor.spline_weights`).
#: Residuals to the piece's rigid fit wrap past π where that fit does not take up the curl, and
#: the spline cuts its chord: read as residuals and anchored, a closed tube and a bent arm curling
#: 200–340° per gap at the tip (20–48 % of their area past a half turn) came out 9–34 % of the
#: diagonal off, with up to 307 triangles facing against the curl; as here, within 0.2 %, none
#: against it. Applied to every gap those changes moved 17 of 18 benchmark sequence cells (a
#: wind-blown flag's largest jump 2.58 → 3.63–5.45 × the simulation's, keys 16 frames apart); no
#: gap of theirs has over 2.6 % of a piece's area past a half turn. So does a piece that bends
#: without a crease where over this share of it turns past a right angle from the rest
#: (:data:`core.inbetween_whole_rotations.BENT_TURN`: an arm of one skin bent 70–90° per key, 1.2–12.7 % off
#: anchored to the spline, within 1e-4 so). A piece past a half turn whose rotations jump at a
#: fold's crease is left as it is and its gap warns that the in-betweens may turn it the other
#: way round: a coarse arm (13 rings, 41.7° between them) curled 150° per key is 10–33 % off, a
#: sheet swinging off a rod that stops dead (keys 4 / 8 frames apart, 26 / 73 % past a half turn)
#: is right (0.57 / 0.49 × the linear blend's error).
TURNED_PART_SHARE = 0.1


def composed_apart(topo: Topology, areas: np.ndarray, turning: np.ndarray, root: np.ndarray,
                   continued: np.ndarray) -> np.ndarray:
    """Per component (C,), the share of its area whose whole rotation (``continued``, (m, 3),
    :meth:`TurnReadings._reading`) interpolated as one turn, as the in-betweens take it, is half-way through
    the gap more than :data:`~core.rotation_continuity.WRAP_CREASE` from the turn of the
    part that stays (``root``, bool (m,): its mean rotation vector) composed with its own turn
    from there (zero but in the ``turning`` pieces). Both join the keys; they differ by the two
    turns' commutator where the part that stays turns about another axis than the rest curls
    (an arm curling 170° per key at two joints while it turns 20° per key about z: its forearm
    up to 89° apart, tilted 88–90° off the curl in every gap; 10° per key: 53°; 150° turning
    10°: 18°), and there the keys do not tell which of them a part went.
    ``topo``: the sequence's topology; ``areas``: the triangles' areas (m,) in the gap's first key."""
    pieces, count = topo.triangle_component, len(topo.components)
    held = np.where(root, areas, 0.0)
    stays = np.stack([np.bincount(pieces, held * continued[:, k], minlength=count) for k in range(3)], axis=1)
    stays /= np.maximum(np.bincount(pieces, held, minlength=count), np.finfo(float).tiny)[:, None]
    rows = np.flatnonzero(turning[pieces])
    rest = stays[pieces[rows]]
    own = (Rotation.from_rotvec(rest).inv() * Rotation.from_rotvec(continued[rows])).as_rotvec()
    own = unwrapped_rotation_vectors(own, continued[rows] - rest)
    composed = Rotation.from_rotvec(0.5 * rest) * Rotation.from_rotvec(0.5 * own)
    apart = rows[(composed.inv() * Rotation.from_rotvec(0.5 * continued[rows])).magnitude() > WRAP_CREASE]
    total = np.maximum(np.bincount(pieces, areas, minlength=count), np.finfo(float).tiny)
    return np.bincount(pieces[apart], areas[apart], minlength=count) / total


def turn_warnings(segment: Gap, key_names: list[str], gap: int) -> list[tuple[str, float]]:
    """The warnings ``(message, excess)`` of gap ``gap`` of a sequence about how its pieces
    turn, from its data ``segment`` (``folded_turn``, ``unsure_turn``, ``composed_apart``,
    ``spun_part``, ``untold_half_turns``, ``whole_half_turn``, ``aliased_spin``, ``reversed_spin``); ``key_names``: the keys as
    warnings name them. ``excess`` (:attr:`core.errors.ShapeDifferenceWarning.excess`): the share of
    the piece's area the message names ÷ :data:`TURNED_PART_SHARE` where it names one (a path
    apart, a part spun on), the reversed spin's measure where it names that (``reversed_spin``: how many
    times as closely the long way round continues the gaps beside), else 0 (a way round the keys do
    not tell: no measure)."""
    problems = []
    turned = (f"between {key_names[gap]} and {key_names[gap + 1]}, over "
              f"{100 * TURNED_PART_SHARE:.0f} % of a piece's area turns past a half turn from the rest of it")
    if segment.folded_turn:
        problems.append((f"{turned} across a fold: the in-betweens may turn it the other way round (keys closer "
                         "together tell which way it went)", 0.0))
    if segment.unsure_turn:
        problems.append((f"{turned}, and these keys do not tell which way round it went: the in-betweens may "
                         "turn it the other way round (keys closer together tell which way it went; the gaps next "
                         "to it read the turn differently, or the piece's rigid motion reads it the other way "
                         "round)", 0.0))
    if segment.composed_apart > TURNED_PART_SHARE:
        problems.append((f"{turned} while the rest of it turns about another axis, and the keys do not tell "
                         f"which path it took: half-way, {100 * segment.composed_apart:.0f} % of the piece's area "
                         f"may be over {np.degrees(WRAP_CREASE):.0f}° off it (keys closer together bring the paths "
                         "nearer; each part is turned as one turn, not as the rest's turn composed with its own)",
                         segment.composed_apart / TURNED_PART_SHARE))
    share, spun = segment.spun_part
    if share > TURNED_PART_SHARE:
        problems.append((f"between {key_names[gap]} and {key_names[gap + 1]}, {100 * share:.0f} % of a piece's area "
                         f"spins on more than a half turn (up to {np.degrees(spun):.0f}°) from the rest of it: the "
                         "in-betweens may turn it the short way round, back against the rest (keys at least "
                         f"{int(np.ceil(spun / np.pi))} times as often there tell which way it went; read from "
                         "patches of the mesh turning about the piece's rigid turn axis)", share / TURNED_PART_SHARE))
    if segment.aliased_spin:
        problems.append((f"between {key_names[gap]} and {key_names[gap + 1]}, a piece turns the other way round "
                         "from a gap next to it that turns it nearly a half turn: it may spin on past a half turn "
                         "per gap, which keys this far apart read the short way round, and the in-betweens may "
                         "turn it back the wrong way (keys closer together, under a half turn apart, tell which "
                         "way it spins)", 0.0))
    if segment.reversed_spin > 1.0:
        problems.append((f"between {key_names[gap]} and {key_names[gap + 1]}, a piece turns the other way round "
                         "from both gaps next to it, and its turn taken the long way round, past a half turn, "
                         f"continues theirs {segment.reversed_spin:.1f} times as closely: it may spin on past a "
                         "half turn per gap, which keys this far apart read the short way round, and the "
                         "in-betweens may turn it back the wrong way (keys closer together, under a half turn "
                         "apart, tell which way it spins)", segment.reversed_spin))
    if segment.whole_half_turn:
        problems.append((f"between {key_names[gap]} and {key_names[gap + 1]}, the whole mesh turns a half turn "
                         "(180°) as one to within what the keys tell, and nothing in them tells which way round: "
                         "the in-betweens may turn it the other way round (keys closer together tell which way "
                         "it went)", 0.0))
    elif segment.untold_half_turns:
        problems.append((f"between {key_names[gap]} and {key_names[gap + 1]}, "
                         f"{segment.untold_half_turns} piece(s) turn a half turn (180°) to within what the keys "
                         "tell, and nothing in them tells which way round: the in-betweens may turn them the "
                         "other way round (keys closer together tell which way they went)", 0.0))
    return problems


class TurnReadings:
    """Which way round each gap of a sequence reads its parts' turns, and whether the readings of
    neighbouring gaps agree (kept for the last few gaps); mixed into
    :class:`~core.sequence_inbetweens.SequenceInterpolator`.

    Reads the interpolator's ``_agreements``, ``_cache_lock``, ``_edge_pairs``, ``_raw``,
    ``_readings``, ``_topo``, ``_turnings``, ``_unsures`` and calls its ``_fits``, ``_key``, ``_turning_on``."""

    def _reading(self, gap: int, final: bool = False, relative: Relative | None = None) -> tuple:
        """Which way round gap ``gap`` reads its parts' turns: :meth:`Relative.turning`'s answers
        (per component whether a part of it turns far from the rest, the triangles that the rest
        turns from, whether a turn is at a crease, the whole rotations (m, 3) from key ``gap`` to
        the next taken continuous across the mesh, and whether which end stays is contested).
        Each gap reads it from its own keys: from the part that turns least, or, ``final``, in the
        pieces where the readings of the gaps around disagree (:meth:`_unsure`), from the part
        nearest the piece's rigid turn. ``relative``: key ``gap + 1`` seen from key ``gap``, if
        made. The last few readings are kept where a piece turns or a neighbouring gap asked for
        one."""
        with self._cache_lock:
            known = self._readings.get((gap, final))
        if known is not None:
            return known
        free = None
        if final:
            unsure = self._unsure(gap)
            if not unsure.any():
                return self._reading(gap, relative=relative)
            free = unsure[self._topo.triangle_component]
        topo, base, nxt = self._topo, self._key(gap), self._key(gap + 1)
        # the gap's own relative: its rigid turn unwrapped as the gap takes it (_turning_on)
        made = relative is None  # asked for by a neighbouring gap
        relative = self._turning_on(gap, Relative(topo, base, nxt, fits=self._fits(gap, gap + 1))) if made \
            else relative
        known = relative.turning(topo, base, nxt, self._edge_pairs, TURNED_PART_SHARE, free)
        with self._cache_lock:
            if not final:
                self._turnings[gap] = known[0]
            if known[0].any() or made:  # a gap with no turning piece asks for no neighbour's
                self._readings[(gap, final)] = known
                while len(self._readings) > 2 * GAP_CACHE + 2:
                    self._readings.popitem(last=False)
        return known

    def _held_alone(self, gap: int, held_only: np.ndarray) -> np.ndarray:
        """Per component (bool (C,)), whether the triangle its reading of gap ``gap`` holds still
        (``held_only``: per piece, the one whose hold alone keeps it from being contested, or -1;
        :meth:`Relative.turning`) turns more than the mesh resolves in a neighbouring gap's
        reading. A part held in one gap alone tells no end that stays: every continuous turn
        crosses a whole turn somewhere, and a triangle there reads as held (a tail wagged 1, −1.2,
        1.2, −1.3: the tip winds 362° and 378° in the middle gaps and a ring near it reads 0.7°,
        held, the root read a whole turn off, 88–131 % of the diagonal off, silently) where a
        part held in every gap (a strip's pinned end) reads held in each."""
        last, out = len(self._raw) - 1, np.zeros(held_only.shape, dtype=bool)
        pieces = np.flatnonzero(held_only >= 0)
        for k in (gap - 1, gap + 1):
            if pieces.size and 0 <= k < last:
                still = self._reading(k)[6]  # None where no piece turns far there: it tells nothing
                if still is not None:
                    out[pieces] |= ~still[held_only[pieces]]
        return out

    def _turning(self, gap: int) -> np.ndarray:
        """Per component (bool (C,)), whether a part of it turns far from the rest in gap ``gap``
        (read from its own keys: :meth:`_reading`)."""
        with self._cache_lock:
            turning = self._turnings.get(gap)
        return self._reading(gap)[0] if turning is None else turning

    def _readings_disagree(self, first: int, final: bool) -> tuple[np.ndarray, np.ndarray]:
        """Per component (bool (C,) each), whether the turn from key ``first`` to key ``first + 2``
        is short across it (no jump past a half turn between neighbouring triangles: its own way
        round is not in question), and whether there the readings (:meth:`_reading`, ``final`` as
        there) of gaps ``first`` and ``first + 1`` add up to a whole turn more or less than it over
        more than :data:`TURNED_PART_SHARE` of the piece's area (kept: a few booleans per pair)."""
        with self._cache_lock:
            known = self._agreements.get((first, final))
        if known is not None:
            return known
        topo = self._topo
        pieces, count = topo.triangle_component, len(topo.components)
        a, b = self._reading(first, final)[3], self._reading(first + 1, final)[3]
        span = (Rotation.from_rotvec(b) * Rotation.from_rotvec(a)).as_rotvec()  # key first → first + 2
        pairs = self._edge_pairs
        short = np.bincount(pieces[pairs[jumping_pairs(span, pairs), 0]], minlength=count) == 0
        areas = self._key(first).areas
        area = np.maximum(np.bincount(pieces, areas, minlength=count), np.finfo(float).tiny)
        off = np.linalg.norm(a + b - span, axis=1) > np.pi
        known = short, short & (np.bincount(pieces[off], areas[off], minlength=count) / area > TURNED_PART_SHARE)
        with self._cache_lock:
            self._agreements[(first, final)] = known
        return known

    def _wagging(self, gap: int) -> np.ndarray:
        """Per component (bool (C,)), whether the keys either side of key ``gap`` or of key
        ``gap + 1`` are a short turn apart across it (:meth:`_readings_disagree`): the piece goes
        back about the way it came. There a turning piece whose part that stays is contested
        (:meth:`Relative.turning`) warns: both its ends turn, and its rigid turn reads it the
        other way round (a tail wagged 1, −1.3, 1: 87–130 % of the diagonal off). A piece that
        keeps curling with its part that stays turning a little about another axis (an arm curled
        150° per key at two joints while turning 10° per key about a third axis) is right to 3.3 %
        and its rigid turn reads it the other way round too: it does not warn."""
        last = len(self._raw) - 1
        out = np.zeros(len(self._topo.components), dtype=bool)
        for first in (gap - 1, gap):
            if 0 <= first and first + 2 <= last:
                out |= self._readings_disagree(first, False)[0]
        return out

    def _unsure(self, gap: int, final: bool = False) -> np.ndarray:
        """Per component (bool (C,)), among those of gap ``gap`` where a part turns past a half
        turn from the rest (:meth:`Relative.turning`), whether the way round it is read
        (:meth:`_reading`, ``final`` as there) may be wrong. Where the keys either side of a key
        are a short turn apart the readings of the gaps around that key must add up to that turn
        (:meth:`_readings_disagree`); walked from this gap through the neighbouring gaps so linked
        where the piece turns far too, a pair that does not makes every reading of the run unsure
        (one side of it is wrong, and so is each reading that adds up with a wrong one). A tail
        wagged 1, −1, 1.2, −1 (root 62° then 68° per gap, tip 302° then 332°, the tip read the
        short way, −28°) was read from the root in the first gap and from the tip, a whole turn
        of the tail off, in the two after."""
        with self._cache_lock:
            known = self._unsures.get((gap, final))
        if known is not None:
            return known
        last, turning = len(self._raw) - 1, self._turning(gap)
        out = np.zeros_like(turning)
        for step in (-1, 1):
            pieces, k = turning.copy(), gap
            while pieces.any():
                first = k - 1 if step < 0 else k
                if first < 0 or first + 2 > last:
                    break
                linked, disagree = self._readings_disagree(first, final)
                out |= pieces & disagree
                k += step
                pieces &= linked & self._turning(k)  # on through a neighbour where it turns far too
        with self._cache_lock:
            self._unsures[(gap, final)] = out
        return out
