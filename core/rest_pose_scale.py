"""The rest pose a caller gives the in-betweens (``rest_pose`` of :class:`core.SequenceInterpolator`,
:class:`core.Interpolator`), checked: the mesh's vertices, finite, and of the keys' scale — a rest
in other units or another object's size than the keys is refused rather than read as the keys' rest.

The in-betweens' ``fit`` warnings hold their edge lengths to what the keys' own deviation from the
rest allows (:mod:`core.sequence_edge_misfit`). A rest 100 × the keys' size (centimetres against metres) makes
every key read 99 % off it, so every gap is allowed a misfit of about 2, and no warning is ever
said; one 0.01 × their size does the same. A cloth's rest differs from its frames by what the cloth
stretches, a few percent over the median edge (:data:`REST_SCALE_LIMIT`), so the median ratio of the
rest's edges to the first key's tells the two apart. A cloth that stretches past it (a soft balloon
under high pressure: tension 5, pressure 60 reads 0.52) is refused too, for the same reason: measured
from its rest, every key is far off it and every misfit allowed.
"""

from __future__ import annotations

import numpy as np

from .deformation_fields import corner_edges
from .errors import MeshError
from .validation import check_vertices

__all__ = ["REST_SCALE_LIMIT", "check_rest_scale", "checked_rest_pose", "rest_scale", "scale_taken"]

#: A rest pose whose edges are a median ratio past this (or under its inverse) of the first key's is
#: refused. On the 19 benchmark bakes with every frame taken as the first key of a range cut from
#: inside the simulation and its first frame as the rest, the median ratio is 0.959–1.003 (the
#: curtain pushed by a ball the lowest; single edges 0.13–3,700, crushed or folded ones): 2 is 16 ×
#: the largest of those off 1 in log terms. Units mistaken are past it (×100, ×0.01, ×1000, feet
#: for metres ×3.28, inches for centimetres ×2.54); yards for metres (×0.914) is within what cloth
#: does and is not told (docs/inbetween-measurements.md, *The rest pose's scale*).
REST_SCALE_LIMIT = 2.0


def rest_scale(rest_pose: np.ndarray, first_key: np.ndarray, triangles: np.ndarray) -> float:
    """The median ratio of the edge lengths of ``rest_pose`` (n, 3) to those of ``first_key`` (n, 3)
    over ``triangles`` (m, 3) (their corner edges, 3 m), on the edges of positive length in the first
    key (a rest's edge of length 0 reads 0: a rest at one point, an array never filled, reads 0, not
    a size it does not have); 1.0 where there is none."""
    rest, key = (np.linalg.norm(corner_edges(x, triangles), axis=2) for x in (rest_pose, first_key))
    kept = key > 0.0
    return float(np.median(rest[kept] / key[kept])) if kept.any() else 1.0


def scale_taken(scale: float) -> bool:
    """Whether a rest :func:`rest_scale` ``scale`` times the first key's size is taken: within
    :data:`REST_SCALE_LIMIT` of it either way."""
    return 1.0 / REST_SCALE_LIMIT <= scale <= REST_SCALE_LIMIT


#: What leaving ``rest_pose`` out does, as a sequence's refusal says it (:func:`check_rest_scale`).
FIRST_KEY_INSTEAD = "measure the warnings from the first key"


def check_rest_scale(rest_pose: np.ndarray, first_key: np.ndarray, triangles: np.ndarray, *,
                     first: str = "the first key", without: str = FIRST_KEY_INSTEAD) -> None:
    """MeshError naming ``rest_pose`` and the scale found where ``rest_pose`` (n, 3) is not
    :func:`scale_taken` against ``first_key`` (n, 3) over ``triangles`` (m, 3). ``first``: the first
    key as the message names it; ``without``: what leaving ``rest_pose`` out does."""
    scale = rest_scale(rest_pose, first_key, triangles)
    if scale_taken(scale):
        return
    if not scale > 0.0:
        raise MeshError("rest_pose has most of its edges of length 0 (its vertices at one point or a few: an array "
                        f"never filled?): give the mesh's rest shape in the keys' space, or leave rest_pose out to "
                        f"{without}.")
    raise MeshError(
        f"rest_pose is {scale:.4g} × the size of {first} (the median ratio of their edge lengths), "
        f"more than the {REST_SCALE_LIMIT:g} × the keys may be off their rest: it is likely in other units or at "
        "another object scale than the keys, or the cloth stretched that far from it (a soft balloon under "
        "pressure), where measured from it every misfit would be allowed. Give it in the keys' space (scale it by "
        f"{1.0 / scale:.4g}, or read it with the same object transform as the keys), or leave rest_pose out to "
        f"{without}.")


def checked_rest_pose(rest_pose, first_key: np.ndarray, triangles: np.ndarray, *, first: str = "the first key",
                      without: str = FIRST_KEY_INSTEAD) -> np.ndarray | None:
    """``rest_pose`` (None, or the mesh's rest shape (n, 3)) as the in-betweens take it: None, or
    float64 (n, 3) of ``first_key``'s (n, 3) vertex count (vertex for vertex the same mesh, the keys'
    ``triangles`` (m, 3)), real and finite (:func:`core.validation.check_vertices`: a copy where the
    caller could write to it), and :func:`scale_taken` against ``first_key`` (:func:`check_rest_scale`,
    ``first`` and ``without`` as it names them); MeshError naming ``rest_pose`` otherwise."""
    if rest_pose is None:
        return None
    rest_pose = check_vertices(rest_pose, len(first_key), name="rest_pose", kept=True)
    check_rest_scale(rest_pose, first_key, triangles, first=first, without=without)  # other units allow every misfit
    return rest_pose
