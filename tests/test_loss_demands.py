"""Demands of a clone in pelicun's format (hlaid.loss.demands): checked against separate runs of the
simulator's full histories, the intensity measure, a long free-vibration reference for the residual
drift, and pelicun's file conventions. No pelicun needed."""

from __future__ import annotations

import re

import numpy as np
import pytest
from reference_systems import table1_stories

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.ida import IDAConfig, intensity
from hlaid.ida.analysis import upsampled
from hlaid.loss import clone_demands, read_demand_csv
from hlaid.model import Building
from hlaid.motions import load_builtin
from hlaid.simulate import simulate_response
from hlaid.units import G_MM_S2

CFG = IDAConfig(pdelta=False, max_step=0.005)


def _clone(alpha: float | None = None) -> Clone:
    st = table1_stories()
    for s in st:
        s["height_mm"] = 3000.0
        if alpha is not None:
            s["alpha"] = alpha
    return Clone(building=Building.from_stories(st, name="table1", pdelta=False))


@pytest.fixture(scope="module")
def strong():
    """El Centro at 1.2 g: the Table 1 building yields (and keeps a residual drift with a low alpha)."""
    return load_builtin("elcentro-1940-ns").scaled_to_pga(1.2)


def test_residual_drift_is_the_settled_drift_of_a_long_free_vibration(strong):
    c = _clone(alpha=0.03)
    d = clone_demands(c, strong, ida_config=CFG)
    assert not d.collapsed.any()
    # reference: the same record followed by 60 s of free vibration, the drift at its very end
    gm = upsampled(strong, 2)
    r = simulate_response(c.building, gm, substeps=1, outputs="full", free_vibration=60.0)
    ref = np.abs(r.drift[0, -1]) / 3000.0
    assert ref.max() > 3e-4  # a residual drift well above the tolerance below
    np.testing.assert_allclose(d.rid[0], ref, rtol=0.02, atol=2e-5)
    assert d.rid_settling.max() < 0.02 * ref.max()  # the oscillation left over the averaging window


def test_peaks_follow_the_full_histories_realization_by_realization():
    """2 buildings x 2 records x a stripe: every row is its own member and record (ordering), PID and
    PFA are the peaks of the full histories, PFA-0 the scaled PGA, the intensity the stripe's."""
    from hlaid.uncertainty import ParameterUncertainty

    c = _clone()
    unc = ParameterUncertainty(slots=(("k0", 0), ("dy", 1)), transform=("log", "log"),
                               centre=np.log([1.94e4, 6.0]), covariance=np.diag([0.1, 0.1]) ** 2,
                               method="laplace-sandwich", info={})
    c = Clone(building=c.building, uncertainty=unc)
    recs = [load_builtin("northridge-1994-mul009"), load_builtin("kobe-1995-nis000")]
    d = clone_demands(c, recs, level=0.8, n_ensemble=2, seed=3, ida_config=CFG)
    from hlaid.uncertainty import clone_ensemble

    members = clone_ensemble(c, 2, seed=3)
    assert d.n_realizations == 4 and list(d.member) == [0, 0, 1, 1] and list(d.record) == [0, 1, 0, 1]
    T1 = c.building.periods()[0]
    for i in range(4):
        b, gm = members[d.member[i]], recs[d.record[i]]
        scale = 0.8 / intensity(gm, period=T1)[0]
        assert intensity(gm, period=T1)[0] * scale == pytest.approx(d.im[i], rel=1e-9)
        r = simulate_response(b.replace(pdelta=False), upsampled(gm, 2), scale, substeps=1, outputs="full")
        np.testing.assert_allclose(d.pid[i], np.nanmax(np.abs(r.drift[0]), axis=0) / 3000.0, rtol=1e-9)
        np.testing.assert_allclose(d.pfa[i, 1:], np.nanmax(np.abs(r.acc[0]), axis=0), rtol=1e-9)
        assert d.pfa[i, 0] == pytest.approx(gm.pga * scale, rel=1e-12)


def test_demand_csv_is_pelicuns_format_and_reads_back(strong, tmp_path):
    d = clone_demands(_clone(), strong, ida_config=CFG)
    path = d.write_csv(tmp_path / "demands.csv")
    lines = path.read_text().splitlines()
    T = f"{d.period:.3g}"
    assert lines[0] == (",1-PFA-0-1,1-PFA-1-1,1-PFA-2-1,1-PFA-3-1,1-PID-1-1,1-PID-2-1,1-PID-3-1,"
                        f"1-RID-1-1,1-RID-2-1,1-RID-3-1,1-SA_{T}-0-1")
    assert lines[1] == "Units,g,g,g,g,rad,rad,rad,rad,rad,rad,g" and len(lines) == 3
    row = np.array(lines[2].split(",")[1:], dtype=float)
    np.testing.assert_allclose(row, np.concatenate([d.pfa[0] / G_MM_S2, d.pid[0], d.rid[0], d.im]), rtol=1e-7)
    f = read_demand_csv(path)
    assert (f.n_stories, f.im_type, f.n_realizations) == (3, f"SA_{T}", 1)


def test_a_collapsed_run_is_flagged_and_written_above_the_limit():
    d = clone_demands(_clone(), load_builtin("elcentro-1940-ns").scaled_to_pga(6.0),
                      ida_config=CFG.replace(drift_limit=0.02))
    assert d.collapsed.all() and d.pid.max() > 0.02
    assert d.summary()["pid_median"] is None and "collapsed" in d.notes[-1]


@pytest.mark.parametrize("kw, message", [({"level": -1.0}, "positive intensity"),
                                         ({"n_ensemble": -2}, "whole number"),
                                         ({"n_ensemble": 3}, "no uncertainty")])
def test_bad_arguments(kw, message, strong):
    with pytest.raises(InputError, match=message):
        clone_demands(_clone(), strong, ida_config=CFG, **kw)


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("Units,g,g,g,g,rad", "Units,g,g,g,g,g", 1), "1-PID-1-1: unit 'g' is not a drift ratio"),
    (lambda t: t.replace("Units,g,g", "Units,rad,g", 1), "1-PFA-0-1: unit 'rad' is not an acceleration"),
    (lambda t: t.replace("Units,", "units,", 1), "line 2: expected the Units row"),
    (lambda t: t.replace(",1-PFA-0-1", ",PFA_0", 1), "line 1: column 2 ('PFA_0') is not a demand name"),
    (lambda t: t.replace("Units,g,g,g,g,rad,rad,rad,rad,rad,rad,g", "Units,g,g", 1), "2 units for 11"),
])
def test_bad_demand_file(edit, message, strong, tmp_path):
    d = clone_demands(_clone(), strong, ida_config=CFG)
    bad = tmp_path / "bad.csv"
    bad.write_text(edit(d.csv_text()))
    with pytest.raises(InputError, match=re.escape(message)) as err:
        read_demand_csv(bad)
    assert str(bad) in str(err.value) and "\n" not in str(err.value)
