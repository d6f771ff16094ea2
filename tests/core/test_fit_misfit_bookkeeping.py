"""A sequence's gap keeps the misfit of each in-between's fit only where that fit's pose is the
one returned (core.inbetween_prediction_repairs._put_back): a prediction solved to compare, and
its solve not taken, is no fitted in-between to the edge-misfit warning
(core.sequence_edge_misfit). No bpy."""

import warnings

import numpy as np

from core import SequenceInterpolator
from core.inbetween_prediction_repairs import _put_back, _taken

from meshes import grid
from test_sequence_edge_misfit import _waved


def _gap():
    vertices, triangles = grid(33, 7, size=2.0)
    keys = [_waved(vertices, np.radians(80), k * np.radians(150)) for k in range(4)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return SequenceInterpolator(keys, triangles)._gap(1)


def test_a_solve_not_taken_leaves_no_fit_misfit_and_a_taken_one_its_own():
    gap = _gap()
    s = 0.375
    predicted = _taken(gap, s)  # a prediction's: no check, no fit
    assert predicted == (None, None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gap.pose(s)  # the solve tried in its place stores its outcome and its fit's misfit
    assert s in gap.outcomes and gap.fit_misfits[s] > 0.0
    _put_back(gap, s, predicted)  # the prediction is returned
    assert s not in gap.outcomes and s not in gap.fit_misfits
    # a fitted in-between kept over a second fit at its factor keeps its own misfit, not the second's
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gap.pose(0.5)
        kept = _taken(gap, 0.5)
        gap.pose(0.5, iterations=1)  # a fit cut short: another misfit
    assert gap.fit_misfits[0.5] != kept[1]  # the second fit ends elsewhere: the check can fail
    _put_back(gap, 0.5, kept)
    assert gap.fit_misfits[0.5] == kept[1] and gap.outcomes[0.5] is kept[0]
