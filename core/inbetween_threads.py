"""In-between work in threads (:func:`core.concurrency.concurrently`) on meshes of
:data:`CONCURRENT_VERTICES` vertices or more: the in-betweens of a gap, solved and predicted
(:func:`per_factor`, :mod:`core.inbetween_prediction`), and the relatives of a sequence's keys
(:mod:`core.sequence_keys`).
"""

from __future__ import annotations

from .concurrency import concurrently


#: In-betweens of meshes with at least this many vertices are solved and predicted in threads
#: (:func:`core.concurrency.concurrently`); on smaller meshes the arrays are too short for NumPy's
#: released global lock to outweigh handing the work over (1,024-vertex drape, keys 4 frames
#: apart: 4.2 → 5.0 ms per in-between in two threads).
CONCURRENT_VERTICES = 5000


def per_factor(gap, function, factors) -> list:
    """``[function(s) for s in factors]``, in threads on meshes of :data:`CONCURRENT_VERTICES` or more;
    each call's repairs share the blend's and the spline's local geometry at its factor
    (:meth:`~core.inbetween_repair_rounds.RepairRounds.fields_kept`)."""
    def kept(s):
        with gap.repair.fields_kept():
            return function(s)
    return concurrently(kept, factors, worth_it=gap.topo.n >= CONCURRENT_VERTICES)
