"""The reconstruction's fit tolerances (core.inbetween_fit; issue 3); no bpy."""

from __future__ import annotations

import numpy as np
import pytest


def test_fit_tolerance_leaves_out_the_edges_a_fold_collapses():
    """Keys whose edges all change by 2 % but for 0.5 % of them that collapse by 60 %: the fit's
    tolerance is half the 2 % (TOLERANCE_TRIM drops the largest 1 %), the whole change's includes
    them; no change gives the METRIC_TOLERANCE floor."""
    from core.inbetween_fit import METRIC_TOLERANCE, change_tolerance, trimmed_tolerance

    base = np.random.default_rng(5).uniform(0.5, 2.0, size=(3, 20000))
    change = np.full(base.shape, 0.02)
    change.ravel()[::200] = -0.6
    assert trimmed_tolerance(base, base * (1.0 + change)) == pytest.approx(0.5 * 0.02, rel=1e-12)
    assert change_tolerance(base, base * (1.0 + change)) == pytest.approx(0.5 * (0.995 * 0.02 + 0.005 * 0.6), rel=1e-12)
    assert trimmed_tolerance(base, base.copy()) == change_tolerance(base, base.copy()) == METRIC_TOLERANCE
