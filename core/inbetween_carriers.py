"""Which piece of a joint group carries the others in a sequence: the piece whose motion over the
keys about a gap keeps to one screw (:func:`screw_departures`), which
:func:`core.inbetween_joints.joint_tree` makes the group's root.

A group's in-betweens compose its root's own motion, splined as screws across the keys
(:class:`core.splines.ScrewGap`), with each jointed piece's motion relative to its parent, splined
the same way (:func:`core.inbetween_joints.joint_screws`). The relative motions are the same
whichever piece is the root (a joint's, or its inverse); the root's motion in the world is not. A
spline of screws lying on one line through the base key's (zero) stays on that line: a motion along
one screw at any rate (a carried box moving and turning steadily, a robot's link turning about its
base) is reproduced on its screw, and a piece hung from it is placed by it exactly where its motion
relative to it is steady too. A lid opening on that box has the box's screw composed with the
hinge's turn, about an axis that turns from key to key: its key screws leave any line, so the box
carries the lid even where the lid moves less (docs/inbetween-measurements.md, *A carried lid's
carrier told by its steady screw*). Two poses have no key beyond the gap (its end conditions are
no keys): every piece keeps to its screw there, and the group hangs from the piece that moves least.
"""

from __future__ import annotations

import numpy as np

from .coordinate_rounding import RIGID_ROUNDING
from .rigid_alignment import group_covariances

#: A piece keeps to one screw over a gap's keys where its key screws leave the line of the next
#: key's by at most this many times its RMS rigid misfit over the keys (plus the coordinates'
#: rounding): what its rigid fits resolve, as :data:`core.inbetween_joints.JOINT_SLIDE` takes a
#: joint's slide. Pieces within it tie, and of those the one that moves least is the root.
STEADY_SLACK = 3.0


def screw_departures(screws: list, keys: list, points: np.ndarray, labels: np.ndarray, count: int,
                     misfits: np.ndarray) -> np.ndarray:
    """Per component (``count``,), how far its screws at the keys about a gap leave the line through
    the base key's (zero) and the next key's: ``screws`` the components' screw coordinates ``(ω, v)``
    (C, 6) at the keys of times −1, 0, 1, 2 from the base key (as the gap's screw spline takes them),
    ``keys`` (4,) whether each stands for a key (not a sequence's end condition past the keys,
    which is read from the keys beside it; a key rescaled to even spacing, keys unevenly timed,
    does: :meth:`core.inbetween_keys.Relative.rescaled` moves its screw along the line through the
    base key's and its own). Each key's screw ``σ`` less its least-squares multiple of the next key's ``σ₁``
    is a screw ``(δω, δv)`` whose displacement field ``δv + δω × x`` is measured as its RMS over the
    component's vertices ``points`` (k, 3; in the base key, ``labels`` (k,) their components) —
    first order in the residual, a length: ``|δv + δω × c|² + δωᵀ K δω`` with ``c`` the vertices'
    centroid and ``K`` the mean of ``|y|² I − y yᵀ`` over them about it — and summed in quadrature
    over the keys before and after the gap; 0 where that is within :data:`STEADY_SLACK` times its
    RMS rigid misfit ``misfits`` (C,, lengths) plus the coordinates' rounding. All 0 without a key
    beyond the gap (two poses)."""
    out = np.zeros(count)
    far = [k for k in (0, 3) if keys[k]]
    if not far:
        return out
    counts = np.maximum(np.bincount(labels, minlength=count), 1)
    scatter, centre = group_covariances(points, points, labels, count, np.ones(len(points)))[:2]
    spread = scatter / counts[:, None, None]  # mean y yᵀ about each component's centroid
    inertia = np.trace(spread, axis1=1, axis2=2)[:, None, None] * np.eye(3) - spread  # mean |y|² I − y yᵀ

    def inner(p: np.ndarray, q: np.ndarray) -> np.ndarray:  # per component, the fields' mean product
        at_p = p[:, 3:] + np.cross(p[:, :3], centre)
        at_q = q[:, 3:] + np.cross(q[:, :3], centre)
        return np.einsum("ca,ca->c", at_p, at_q) + np.einsum("ca,cab,cb->c", p[:, :3], inertia, q[:, :3])

    nxt = screws[2]
    norm = inner(nxt, nxt)
    for k in far:
        share = np.where(norm > 0, inner(screws[k], nxt) / np.where(norm > 0, norm, 1.0), 0.0)
        residual = screws[k] - share[:, None] * nxt
        out += np.maximum(inner(residual, residual), 0.0)
    out = np.sqrt(out)
    rounding = RIGID_ROUNDING * (np.abs(points).max(initial=0.0) + np.sqrt(np.trace(spread, axis1=1, axis2=2)))
    return np.where(out <= STEADY_SLACK * misfits + rounding, 0.0, out)
