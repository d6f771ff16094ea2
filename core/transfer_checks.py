"""What a :class:`~core.transfer.Transfer` refuses or warns about in the meshes and the
correspondence it is given (paper §6.3 needs a map of the surface): a target's zero-area
triangles, non-manifold edges and vertices split along seams (welded), and a correspondence that
matches too few base vertices, holds matches its neighbours contradict, lays the base on a point
or a line, turns a closed part of the base inside out (a left/right flip of a symmetric shape), lays
the base over a hole of the target, or (closest points) matches meshes that do not overlap at rest
or lie off each other."""

from __future__ import annotations


import numpy as np

from .errors import MeshError, warn

#: A partial correspondence (entries UNMATCHED, -1: base vertices no map entry lands on, as when
#: two template maps are composed) must match at least this fraction of the base vertices, and
#: warns below the second: the unmatched ones get their images from the local affine fit of
#: matched neighbours (:func:`~core.functional_map.locally_affine_images`, rings widened until they
#: hold enough matches). Measured (random subsets of a nearest-vertex map; docs/transfer.md): 73 %
#: matched costs a few tenths of a point of Hausdorff / diagonal, 43 % 0.4–1.1 point, 21 % about a
#: point on the 1k limb (frame 40 3.62 → 3.99 / 4.02 / 4.63 %).
MIN_MATCHED_FRACTION = 0.1
WARN_MATCHED_FRACTION = 0.5
#: Closest points match two meshes that overlap at rest: a base vertex is then within about half a
#: target edge of its nearest target vertex. When the median distance is more than this many
#: target edge lengths the meshes are elsewhere (a remeshed copy placed beside the original),
#: and the transfer is refused: it returned a flat sheet with warnings about the recovery.
OVERLAP_EDGES = 2.0
#: ... and it warns when more than this share of them is that far (the meshes overlap in part).
PARTLY_BESIDE = 0.1
#: A base vertex counts as over a hole of the target (:func:`check_covered`) where its closest
#: point on the target lies on the target's boundary more than this many target edge lengths away
#: while the base has no boundary there: on meshes laid on each other a base vertex is within a
#: fraction of a target edge of the target surface, so this leaves out the rounding of two
#: polylines along a boundary both meshes have. A vertex of the base's boundary past the target's
#: by more than this shows meshes out of place (closest points, :func:`check_covered`): the base's
#: border strip is squashed onto the target's rim (the cloth sheet's re-meshed targets: at most 0.11
#: edge in place, sampled, decimated and hostile; its sampled target slid in its plane by 0.52 / 0.78 /
#: 1.04 edges: 0.03 / 1.6 / 3.2 % of the base's area past, Hausdorff distance at frame 20 1.66 →
#: 1.78 / 3.04 / 2.72 % of the diagonal; the decimated target by 0.53 edge: 1.6 %, 2.06 → 2.60 %).
UNCOVERED_EDGES = 0.5
#: Closest points of meshes laid on each other are within a fraction of a target edge of the base
#: (at most 0.6 edge on the benchmark's re-meshed targets, sampled, decimated and hostile); a base
#: vertex farther than this many target edges from the target's surface, off its boundary, shows
#: meshes out of place (a limb's target slid along its axis by 5 % of its length: 7.9 % of the
#: base's area over 1 edge off, 2.4 % RMS of the diagonal off against 1.2 %; by 2 %: none, 1.2 %).
OFF_SURFACE_EDGES = 1.0
#: ... and either check warns once those vertices hold at least this share of the base's area: the few missing
#: fans of a hostile re-mesh (0.1–0.5 % of the base's area on the benchmark's hostile targets)
#: cost no accuracy there (the hostile targets' frames are rebuilt as well as the decimated ones'),
#: while a hole of 8 % of a limb's area (6 % of the base's over it) costs 1.0–2.6 points of RMS.
UNCOVERED_SHARE = 0.01
#: A closed part of the base counts as turned inside out by a correspondence (:func:`check_orientation`)
#: where the signed volume of its triangles placed on the target's matched positions has the other
#: sign than at rest and is at least this share of the sum of the absolute volumes of its
#: tetrahedra (to the part's centre): a convex part, carried either way, gives all of it, so the
#: sign is not decided by a few triangles an imprecise map folds.
INSIDE_OUT_SHARE = 0.5
#: Smallest spread of the target positions a given correspondence matches, along each of their two
#: widest axes, as a share of the target's own (:func:`check_spread`): a map onto a point
#: or a line is refused; a map onto part of the target (a head on a body) spreads over far more.
MIN_MAP_SPREAD = 0.01
#: A target resolves about this many Laplace–Beltrami eigenfunctions per vertex
#: (:func:`check_target_resolution`): beyond, its functions are at the scale of its edges and the
#: base's k_M functions come back roughly through them. Limb base (992 vertices) onto coarser
#: sampled targets, bent pose, RMS of the diagonal off (k_N from 2 k_M to the target's vertex count):
#: 131-vertex target, k_M = 20 / 30 / 40 / 60 / 100: 1.19–1.24 / 1.36–1.41 / 1.44–1.61 / 1.49–1.94 /
#: 2.23–2.40 %; 97 vertices, k_M = 20 / 30 / 40: 1.75–2.03 / 1.98–2.23 / 2.39–2.60 %; 385 vertices,
#: k_M = 50 / 100 / 150: 1.11–1.16 / 1.25–1.30 / 1.58–1.62 %; 1,273 vertices, k_M = 100: 0.90–1.33 %.
TARGET_FUNCTIONS_PER_VERTEX = 1 / 3
#: Target vertices closer than this fraction of the bounding-box diagonal at rest are one vertex
#: (welded): exporters split vertices along UV seams and sharp edges, which would otherwise cut
#: the target surface open there (on the re-meshed 1k limb a seam of 10 split vertices made
#: the recovery fail).
WELD_DISTANCE = 1e-7


#: What the warnings about a transfer's target mesh call it (:class:`~core.transfer.Transfer`'s
#: ``target_label``; the add-on names the source object).
TARGET_LABEL = "the target mesh"


def sentence(label: str) -> str:
    """``label`` opening a sentence: its first letter a capital."""
    return label[:1].upper() + label[1:]


def degenerate_at_rest(rest, triangles, name: str, label: str = TARGET_LABEL) -> np.ndarray:
    """Indices of the target triangles of zero area at rest (as
    :func:`~core.mesh_topology.check_nondegenerate` measures it), left out with a warning
    (``label`` names the target mesh there): a decimated or remeshed target may carry a few
    collinear slivers, which add nothing to its surface but would make its Laplacian infinite. A
    target pose where a kept triangle collapses is still an error; so is a target with no triangle
    left (``name`` names it)."""
    from .mesh_topology import DEGENERATE_TRIANGLE_RATIO

    corners = rest[triangles]
    sides = corners[:, [1, 2, 0]] - corners[:, [2, 0, 1]]
    doubled_area = np.linalg.norm(np.cross(sides[:, 0], sides[:, 1]), axis=1)
    flat = np.flatnonzero(~(doubled_area > DEGENERATE_TRIANGLE_RATIO * np.einsum("tki,tki->tk", sides, sides).max(axis=1)))
    if flat.size == triangles.shape[0]:
        raise MeshError(f"{name}: every triangle has zero area (the mesh lies on a line or a point, or its "
                        "coincident vertices welded leave no triangle).")
    if flat.size:
        warn(
            f"{sentence(label)} has {flat.size} triangle(s) of zero area at rest (triangle {int(flat[0])}, vertices "
            f"{triangles[flat[0]].tolist()}); they are left out (in Blender: Mesh > Clean Up > Degenerate "
            "Dissolve removes them).",
            "target",
        )
    return flat


def mean_edge_length(positions, edges) -> float:
    """The mean length of the ``edges`` (E, 2) of ``positions`` (n, 3)."""
    return float(np.mean(np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)))


def check_overlap(base, nearest, target, target_edges, parts=None) -> bool:
    """Raise :class:`MeshError` when the base positions (n, 3) are not on the target's rest
    surface: their median distance to their ``nearest`` target vertices over :data:`OVERLAP_EDGES`
    target edge lengths (``target_edges`` (E, 2) of positions ``target``). Warns when they are on
    it only in part: more than :data:`PARTLY_BESIDE` of them that far, or a whole connected part
    of the base (``parts``: each base vertex's part, (n,)) that far by its median — a part the
    target does not have (a hat, a button, an eye), which closest points squash onto the target's
    nearest surface, and the transfer with it. Returns whether either was warned."""
    edge = mean_edge_length(target, target_edges)
    distances = np.linalg.norm(base - nearest, axis=1)
    apart = float(np.median(distances))
    if apart > OVERLAP_EDGES * edge:
        raise MeshError(
            f"The two meshes do not overlap at rest: half of the base's vertices are more than {apart:.3g} "
            f"from the target's ({apart / edge:.1f} of its edge lengths), and closest points match only "
            "meshes laid on each other. Place the target's rest pose where the base is, or give a "
            "correspondence (in Blender: Map › Attribute or File)")
    beside = float(np.mean(distances > OVERLAP_EDGES * edge))
    if beside > PARTLY_BESIDE:
        warn(
            f"{100 * beside:.0f} % of the base's vertices are more than {OVERLAP_EDGES:g} target edge lengths "
            "from the target at rest: the meshes overlap only in part, and there closest points match the "
            "base to the target's edge, which distorts the transfer. Place the target's rest pose where the "
            "base is, or give a correspondence (in Blender: Map › Attribute or File)",
            "correspondence")
        return True
    if parts is None:
        return False
    order = np.argsort(parts, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(parts[order]) != 0])
    medians = np.array([np.median(d) for d in np.split(distances[order], starts[1:])])
    off = np.flatnonzero(medians > OVERLAP_EDGES * edge)
    if not off.size:
        return False
    first = int(order[starts[off[0]]])
    warn(
        f"{off.size} connected part(s) of the base (first: the part of vertex {first}, "
        f"{int(np.sum(parts == parts[first]))} vertices) lie off the target at rest, a median "
        f"{medians[off[0]] / edge:.1f} target edge lengths away: the target has no such part there, and "
        "closest points squash it onto the target's nearest surface, which distorts the transfer. Give the "
        "target that part, leave it out of the base (in Blender: Mesh › Separate), or give a correspondence "
        "(in Blender: Map › Attribute or File)",
        "correspondence")
    return True


def check_covered(base, base_topology, target, target_topology, image_triangles, weights, *,
                  given_map: bool = False) -> None:
    """Warn where the target's rest surface has a hole (or ends) over a part of the base that goes on:
    base vertices ``base`` (n, 3), off the base's boundary (``base_topology``), whose closest points
    on the target (positions ``target``, ``target_topology``; in its triangles ``image_triangles``
    (n,) at barycentric ``weights`` (n, 3)) lie on the target's boundary, more than
    :data:`UNCOVERED_EDGES` target edge lengths (their mean) from them. The base's triangles over
    the hole are laid on its rim, and the pulled-back metric and the transfer measure a stretch
    and squash the base does not have (a sphere's target with a cap of 1 % of its area cut out:
    the median edge near the hole 3.4 → 4.8 % off, eigenvalues 3.3 → 3.7 %; 15 %: 16 %, 7.3 %),
    which the overlap check does not see (the base is within a few target edges of the rim).
    Either way a warning needs :data:`UNCOVERED_SHARE` of the base's area.

    Closest points (not ``given_map``) also warn where base vertices off the target's boundary lie
    more than :data:`OFF_SURFACE_EDGES` from the target's surface, or vertices of the base's
    boundary more than :data:`UNCOVERED_EDGES` past the target's (beyond the rounding of two
    boundaries): the meshes are not on each other there (a target slid along the base, a sheet slid
    in its own plane), and closest points match other points than their own (past the target's
    edge, the base's border strip is squashed onto the target's rim).

    ``given_map``: ``base`` are then the base vertices' images by a given correspondence, smoothed
    by the local affine fit of their neighbours' matches
    (:func:`~core.functional_map.locally_affine_images`): over a hole the matches are on its rim
    (a nearest-vertex map) or missing (a template map), and the fit of a ring spread around the
    rim, or extrapolated from it, lies inside the hole, off the target's surface."""
    corners = target_topology.triangles[image_triangles]
    boundary = np.zeros(target_topology.n_vertices, dtype=bool)
    boundary[target_topology.edges[target_topology.boundary_edges]] = True
    # on a boundary edge: the weight of the corner opposite it is zero (closest points clamp to
    # the sides exactly); at a boundary vertex: the other two are
    open_sides = (target_topology.edge_triangles[target_topology.triangle_edges[image_triangles]] < 0).any(axis=2)
    on_rim = ((weights == 0) & open_sides).any(axis=1) | (boundary[corners] & (weights == 1)).any(axis=1)
    base_boundary = np.zeros(base_topology.n_vertices, dtype=bool)
    base_boundary[base_topology.edges[base_topology.boundary_edges]] = True
    images = np.einsum("nk,nki->ni", weights, target[corners])
    edge = mean_edge_length(target, target_topology.edges)
    distances = np.linalg.norm(base - images, axis=1)
    uncovered = on_rim & ~base_boundary & (distances > UNCOVERED_EDGES * edge)
    past_edge = on_rim & base_boundary & (distances > UNCOVERED_EDGES * edge)  # the base's edge past the target's
    off = (~on_rim & (distances > OFF_SURFACE_EDGES * edge)) | past_edge if not given_map else np.zeros_like(on_rim)
    if not (uncovered.any() or off.any()):
        return
    from .geometry import lumped_vertex_areas
    from .mesh_topology import triangle_areas

    vertex_area = lumped_vertex_areas(base_topology.triangles, triangle_areas(base, base_topology.triangles),
                                      base_topology.n_vertices)
    off_share = float(vertex_area[off].sum() / vertex_area.sum())
    if off_share >= UNCOVERED_SHARE:
        warn(
            f"{100 * off_share:.1f} % of the base's area ({int(off.sum())} vertices) lies off the target's surface at "
            "rest, more than a target edge length from it or half of one past its edge (up to "
            f"{distances[off].max():.3g}, {distances[off].max() / edge:.1f} edge lengths): the meshes are not laid on "
            "each other there (one slid or turned against the other, or shaped otherwise), and closest points match "
            "the base to other points of the target than its own, which distorts the transfer. Place the target's "
            "rest pose exactly where the base is, or give a correspondence (in Blender: Map › Attribute or File)",
            "correspondence")
    share = float(vertex_area[uncovered].sum() / vertex_area.sum())
    if share < UNCOVERED_SHARE:
        return
    how, advice = (("the correspondence lays", "") if given_map else
                   ("closest points lay", ", or give a correspondence (in Blender: Map › Attribute or File)"))
    warn(
        f"{100 * share:.1f} % of the base's area ({int(uncovered.sum())} vertices) lies over a hole in "
        f"the target at rest (or past its edge) where the base goes on: {how} it on the hole's rim, "
        "which stretches and squashes the transfer and the pulled-back metric there. Fill the target's holes "
        f"(in Blender: Mesh › Clean Up › Fill Holes){advice}",
        "correspondence")


def check_spread(images, target) -> None:
    """Raise :class:`MeshError` when a given correspondence lays the base on a point or a line
    of the target: the matched target positions ``images`` (k, 3) spread, along either of
    their two widest axes, less than :data:`MIN_MAP_SPREAD` of the target's rest positions
    ``target`` (n, 3) do (RMS) — an attribute created and never filled holds 0 for every vertex,
    and the transfer squashed the target to that one vertex with warnings about its faces."""
    spread = [np.linalg.svd(x - x.mean(axis=0), compute_uv=False)[:2] / np.sqrt(len(x)) for x in (images, target)]
    if len(images) < 3 or (spread[0] < MIN_MAP_SPREAD * spread[1]).any():
        raise MeshError(
            f"The correspondence lays the base on {'a point' if spread[0][0] < MIN_MAP_SPREAD * spread[1][0] else 'a line'} "
            f"of the target ({len(np.unique(images, axis=0))} distinct target vertices for "
            f"{len(images)} matched base vertices): it is not a map of the surface. Check it (an attribute "
            "created and never filled holds 0 for every vertex)")


def resolved_functions(n_target: int) -> int:
    """How many of the base's eigenfunctions a target of ``n_target`` vertices (in triangles)
    carries faithfully: :data:`TARGET_FUNCTIONS_PER_VERTEX` of them, at least 1."""
    return max(int(TARGET_FUNCTIONS_PER_VERTEX * n_target), 1)


def check_target_resolution(k_M: int, n_target: int, label: str = TARGET_LABEL) -> None:
    """Warn when the base's ``k_M`` eigenfunctions are more than a target of ``n_target``
    vertices (in triangles) resolves (:func:`resolved_functions`): a coarse target carries the
    base's higher functions only through its own at the scale of its edges. ``label`` names the
    target mesh."""
    if k_M <= resolved_functions(n_target):
        return
    warn(
        f"k_M is {k_M} base eigenfunctions, but {label} has only {n_target} vertices: a mesh resolves "
        f"about {TARGET_FUNCTIONS_PER_VERTEX:.2g} × as many functions as it has vertices, and the base's detail "
        "beyond that comes back roughly (a limb target of 131 vertices: 2.2–2.4 % RMS of the diagonal off at "
        f"k_M = 100 against 1.2 % at k_M = 20). Lower k_M to {resolved_functions(n_target)} "
        "or less, or transfer from a finer mesh.",
        "target",
    )


def check_matched_fraction(matched, *, warns: bool = True):
    """A partial map must match at least :data:`MIN_MATCHED_FRACTION` of the base vertices
    (``matched`` bool (n,); :class:`MeshError`); below :data:`WARN_MATCHED_FRACTION` it warns
    (when ``warns``)."""
    fraction = float(matched.mean())
    if fraction < MIN_MATCHED_FRACTION:
        raise MeshError(
            f"The correspondence matches only {100 * fraction:.0f} % of the base vertices "
            f"({int(matched.sum())} of {matched.size}); at least {100 * MIN_MATCHED_FRACTION:.0f} % "
            "are needed: the unmatched ones take their images from matched neighbours, which must be "
            "close enough to describe the map at the scale of the k_M basis. Use a denser map."
        )
    if warns and fraction < WARN_MATCHED_FRACTION:
        warn(
            f"The correspondence matches only {100 * fraction:.0f} % of the base vertices; the others "
            f"take their images from matched neighbours, which below {100 * WARN_MATCHED_FRACTION:.0f} % "
            "typically costs about a point of accuracy (Hausdorff / diagonal).",
            "correspondence",
        )


def warn_outlying_matches(outlying, n_matched: int) -> None:
    """Say which matches of a given correspondence were left out as outlying (base vertex indices
    ``outlying`` (k,), k ≥ 1, of ``n_matched`` matched; :func:`~core.functional_map.reject_outlying_matches`):
    they take their images from their neighbours' matches, as unmatched vertices do."""
    from .functional_map import OUTLIER_EDGES

    warn(
        f"{len(outlying)} of the correspondence's {n_matched} matches ({100 * len(outlying) / n_matched:.1f} %; first: "
        f"base vertex {int(outlying[0])}) lie more than {OUTLIER_EDGES:g} target edge lengths from where their "
        "neighbours' matches put them (stray matches, which would pull their neighbours across the target): they "
        "are left out, and those base vertices are placed on the target from their neighbours' matches, as "
        "unmatched ones are. Check the map near them.",
        "correspondence",
    )


def warn_non_manifold(topology, label: str = TARGET_LABEL):
    """Warn about the target's (``topology``) non-manifold or inconsistently oriented edges, which
    a transfer accepts; ``label`` names the target mesh."""
    counts = np.bincount(topology.triangle_edges.ravel(), minlength=topology.n_edges)
    hinged = (topology.edge_triangles >= 0).sum(axis=1)
    odd = np.flatnonzero((counts > 2) | ((counts == 2) & (hinged < 2)))
    if odd.size:
        named = ", ".join(str(tuple(int(v) for v in topology.edges[e])) for e in odd[:5])
        warn(
            f"{sentence(label)} has {odd.size} non-manifold or inconsistently oriented edge(s) "
            f"({named}{', ...' if odd.size > 5 else ''}). They are used for its Laplacian and mass "
            "matrix; its offset surface (extrinsic differences) is cut open along them.",
            "target",
        )


def coincident_vertices(rest, used) -> np.ndarray | None:
    """For every target vertex ``(n_N,)`` the vertex it is welded to: the lowest-numbered of the
    ``used`` vertices within :data:`WELD_DISTANCE` × the bounding-box diagonal of it at ``rest``
    ``(n_N, 3)`` (itself where none is); ``None`` when no two used vertices coincide."""
    from .spread_groups import spread_groups

    points = rest[used]
    scale = np.linalg.norm(np.ptp(points, axis=0))
    n = used.size
    # vertices within the weld distance linked, without listing every pair (thousands at one place)
    labels = spread_groups(points, np.full(n, 0.5 * WELD_DISTANCE * scale))
    if not n or labels.max() + 1 == n:
        return None
    first = np.full(labels.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, labels, np.arange(n))
    welded = np.arange(rest.shape[0])
    welded[used] = used[first[labels]]
    return welded



def _signed_volumes(positions, triangles, labels, count):
    """Per connected part: the signed volume enclosed by its triangles and the sum of the absolute
    volumes of their tetrahedra to the part's centre (its triangle corners' mean), ``(count,)`` each."""
    corners = positions[triangles]  # (m, 3, 3)
    sizes = np.bincount(labels, minlength=count)[:, None]
    centres = np.stack([np.bincount(labels, corners[:, :, d].mean(axis=1), minlength=count)
                        for d in range(3)], axis=1) / np.maximum(sizes, 1)
    relative = corners - centres[labels][:, None, :]
    tetrahedra = np.einsum("ij,ij->i", relative[:, 0], np.cross(relative[:, 1], relative[:, 2])) / 6.0
    return np.bincount(labels, tetrahedra, minlength=count), np.bincount(labels, np.abs(tetrahedra), minlength=count)


def check_orientation(base, base_topology, carried) -> None:
    """ShapeDifferenceWarning where a correspondence turns closed parts of the base inside out:
    ``carried`` ``(n, 3)`` are the target rest positions it matches to the base's vertices ``base``
    ``(n, 3)``. A map that reverses orientation (a symmetric shape matched left to right, as
    functional maps often do) places the base's triangles on the target facing the other way, and
    every transferred pose follows it: the same surface as the target's pose, inside out and with
    its sides exchanged. Only closed parts have an inside (:data:`INSIDE_OUT_SHARE`)."""
    count, labels = base_topology.components()
    closed = np.ones(count, dtype=bool)
    boundary = base_topology.boundary_edges
    if boundary.size:
        closed[labels[base_topology.edge_triangles[boundary, 0]]] = False
    if not closed.any():
        return
    triangles = base_topology.triangles
    at_rest, _ = _signed_volumes(base, triangles, labels, count)
    volume, total = _signed_volumes(carried, triangles, labels, count)
    inside_out = np.flatnonzero(closed & (volume * at_rest < 0) & (np.abs(volume) >= INSIDE_OUT_SHARE * total))
    if inside_out.size:
        first = int(np.flatnonzero(labels == inside_out[0])[0])
        warn(
            f"The correspondence turns {inside_out.size} of {int(closed.sum())} closed part(s) of the base "
            f"inside out (first: the part of triangle {first}): it matches them to the target mirrored, "
            "as a left/right flip of a symmetric shape does, so every transferred pose is the target's "
            "surface inside out with its sides exchanged. Check the map (its left and right).",
            "correspondence",
        )
