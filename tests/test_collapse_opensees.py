"""The collapse law against OpenSeesPy (skipped without a usable openseespy).

OpenSees runs the exported clone script: BoucWen + ElasticPPGap gap springs (damage) + P-Delta
(hlaid.opensees), Newmark average acceleration at dt/10, implicit; hlaid its RK4 simulator. The
collapse search (hunt x1.5, then bisection) is the one of scripts/bench_collapse_opensees.py.
"""

from __future__ import annotations

import io
from contextlib import redirect_stderr

import numpy as np
import pytest
from conftest import needs_opensees, paper_record

from hlaid.opensees import (
    opensees_script,
    run_opensees,
)
from hlaid.simulate import simulate_response

H = 3000.0


def _clone(table1, collapse="steel-mrf"):
    return table1.replace(height=[H] * 3, pdelta=True, collapse=collapse)


def test_script_has_the_gap_springs(table1):
    text = opensees_script(_clone(table1))
    assert "ElasticPPGap" in text and "COLLAPSE = [[(" in text
    assert "COLLAPSE = None" in opensees_script(table1.replace(height=[H] * 3, pdelta=True))


def _os(b, gm, scale):
    with redirect_stderr(io.StringIO()):
        return run_opensees(b, gm, scale=scale, dt_factor=10)


@needs_opensees
def test_past_the_cap_and_collapse_agree_with_opensees(table1):
    """El Centro at 2x PGA 0.62 g goes past the cap of two stories: peak drifts within 1 %;
    at 3x both codes collapse (drift beyond 10 % or no convergence)."""
    b = _clone(table1)
    gm = paper_record("elcentro-1940-ns")
    ours = simulate_response(b, gm, 2.0, substeps=10)
    theirs = _os(b, gm, 2.0)
    xc = b.collapse_values()[:, 0]
    assert theirs.ok and np.sum(ours.peak_drift[0] > xc) >= 2
    np.testing.assert_allclose(ours.peak_drift[0], theirs.peak_drift, rtol=0.01)
    stop = 0.1 * b.height
    ours = simulate_response(b, gm, 3.0, substeps=10, stop_drift=stop)
    theirs = _os(b, gm, 3.0)
    assert ours.status[0] == 1 and (not theirs.ok or np.any(theirs.peak_drift > stop))


def _collapse_im(collapses, im=0.5, factor=1.5, n_bisect=5):
    lo, hi = 0.0, im
    while not collapses(hi):
        lo, hi = hi, hi * factor
        assert hi < 50
    for _ in range(n_bisect):
        mid = np.sqrt(lo * hi) if lo > 0 else hi / factor
        lo, hi = (lo, mid) if collapses(mid) else (mid, hi)
    return hi


@needs_opensees
@pytest.mark.slow
def test_median_collapse_intensity_within_2_percent_of_opensees(table1):
    """5 records, collapse scale (drift > 10 % or no convergence) found by the same search in both."""
    from hlaid.io import read
    b = _clone(table1)
    stop = 0.1 * b.height
    ours, theirs = [], []
    def hlaid_collapses(gm, s):
        sub = int(np.ceil(gm.dt / 0.0005 - 1e-9))
        return simulate_response(b, gm, s, substeps=sub, outputs="peaks", stop_drift=stop).status[0] != 0

    def opensees_collapses(gm, s):
        r = _os(b, gm, s)
        return not r.ok or bool(np.any(r.peak_drift > stop))

    for gm in read("builtin-suite", "records")[:5]:
        ours.append(_collapse_im(lambda s, gm=gm: hlaid_collapses(gm, s)))
        theirs.append(_collapse_im(lambda s, gm=gm: opensees_collapses(gm, s)))
    ours, theirs = np.array(ours), np.array(theirs)
    assert abs(np.median(ours) / np.median(theirs) - 1) < 0.02
    assert np.all(np.abs(ours / theirs - 1) < 0.05)
