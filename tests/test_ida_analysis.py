"""IDA mechanics: batching, collapse detection and refinement, P-Delta rules, results, bad input.

References: every IDA point is re-run alone with ``simulate`` (same scale, same step) and must
match to round-off; each record's collapse intensity is checked against a brute-force scan
of the drift limit with ``simulate``; the collapse rules against hand-made curves.
"""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest

from hlaid.clone import Clone
from hlaid.errors import HlaidWarning, InputError
from hlaid.ida import IDAConfig, IDAResult, prepare_building, run_ida, scan_collapse
from hlaid.io import read
from hlaid.model import Building
from hlaid.motions import GroundMotion, load_builtin
from hlaid.simulate import simulate_response

HEIGHTS = [3000.0, 3000.0, 3000.0]
RECS = ("elcentro-1940-ns", "kocaeli-1999-dzc180", "northridge-1994-mul009")


@pytest.fixture(scope="module")
def motions():
    return [load_builtin(n) for n in RECS]


@pytest.fixture(scope="module")
def result(table1, motions) -> IDAResult:
    # a 3 % drift limit keeps collapse intensities low (short runs)
    return run_ida(table1, motions, IDAConfig(levels=[0.5, 1.0, 1.5, 2.0, 3.0], drift_limit=0.03, heights_mm=HEIGHTS))


def test_every_point_matches_a_direct_simulation(result, motions):
    """Each run is the record scaled to its level, integrated with ``substeps`` RK4 steps per
    sample; peaks are taken at every step (the record interpolated linearly, exactly)."""
    b = result.building
    assert b.pdelta_active and np.allclose(b.height, HEIGHTS)
    stop = 0.03 * np.asarray(HEIGHTS)
    for k in range(0, result.point_im.size, 3):
        gm, f = motions[result.point_record[k]], int(result.point_substeps[k])
        t = np.arange((gm.npts - 1) * f + 1) * gm.dt / f
        fine = GroundMotion(dt=gm.dt / f, acc=np.interp(t, gm.time, gm.acc))
        d = simulate_response(b, fine, result.point_scale[k], substeps=1, outputs="peaks", stop_drift=stop)
        assert np.allclose(d.peak_drift[0], result.peak_drift[k], rtol=1e-12, atol=1e-12)
        assert d.status[0] == result.point_status[k]
        if d.status[0] == 0:  # the same run with peaks at the record's samples only: lower, barely
            c = simulate_response(b, gm, result.point_scale[k], substeps=f, outputs="peaks")
            assert np.all(c.peak_drift[0] <= result.peak_drift[k] * (1 + 1e-9))
            assert np.all(c.peak_drift[0] >= 0.98 * result.peak_drift[k])
            assert np.allclose(c.residual_drift[0], result.residual_drift[k], rtol=1e-9, atol=1e-9)
    # the scale brings each record exactly to its IM level
    assert np.allclose(result.point_scale * result.record_im[result.point_record], result.point_im)


def test_collapse_bracket_is_refined_and_consistent(result):
    tol = result.settings["tolerance"]
    edp, failed = result.edp, (result.point_status != 0) | (result.edp > result.drift_limit)
    for r in range(result.n_records):
        lo, hi, c = result.collapse_lo[r], result.collapse_hi[r], result.collapse_im[r]
        assert np.isfinite(c) and lo < c < hi and hi - lo <= tol * hi
        at_hi = (result.point_record == r) & (result.point_im == hi)
        at_lo = (result.point_record == r) & (result.point_im == lo)
        if result.collapse_mode[r] == "drift limit":
            assert failed[at_hi].all() and not failed[at_lo].any() and (edp[at_lo] < result.drift_limit).all()
        assert {"probe", "grid", "fill"} <= set(result.point_stage[result.point_record == r])
    assert result.collapsed.sum() >= result.n_records


def test_collapse_im_agrees_with_brute_force_scan(result, motions):
    """Independent check: scan the scale factor densely with simulate, find where the drift
    ratio first exceeds the limit, and compare with the refined collapse IM."""
    b = result.building
    for r in range(result.n_records):
        if result.collapse_mode[r] != "drift limit":
            continue
        c = result.collapse_im[r]
        ims = np.linspace(0.8 * c, 1.2 * c, 81)
        d = simulate_response(b, motions[r], ims / result.record_im[r], substeps=int(result.point_substeps[0]),
                              outputs="peaks", stop_drift=1.001 * result.drift_limit * np.asarray(b.height))
        ratio = (d.peak_drift / np.asarray(b.height)).max(axis=1)
        first = ims[np.argmax(ratio > result.drift_limit)]
        assert abs(first / c - 1) <= result.settings["tolerance"] + (ims[1] - ims[0]) / c


def test_scan_collapse_rules():
    im = np.array([0.2, 0.4, 0.6, 0.8, 1.0])
    ok = np.zeros(5, dtype=bool)
    # linear: no collapse; elastic slope 10 (IM per unit EDP)
    assert scan_collapse(im, im / 10, ok, 10.0, 0.2) == (None, "none")
    # the drift limit or divergence at the 4th point
    assert scan_collapse(im, im / 10, np.array([0, 0, 0, 1, 0], bool), 10.0, 0.2) == (3, "failed")
    # a flat segment 0.6 -> 0.8 (slope 0.2/0.2 = 1 < 0.2*10): the 0.8 point is on the flatline
    edp = np.array([0.02, 0.04, 0.06, 0.26, 0.3])
    assert scan_collapse(im, edp, ok, 10.0, 0.2) == (3, "slope")
    # weaving (EDP decreasing with IM) is not a collapse; order of the points does not matter
    edp = np.array([0.02, 0.05, 0.04, 0.06, 0.08])
    p = np.array([4, 2, 0, 3, 1])
    assert scan_collapse(im[p], edp[p], ok, 10.0, 0.2) == (None, "none")


@pytest.mark.parametrize("kind", ["jump", "diverged"])
def test_integration_blow_up_is_rerun_not_taken_for_collapse(table1, monkeypatch, kind):
    """A run that comes back from the simulator diverged, or stopped far past the drift limit
    (a jump within one step), is re-run with 4x the steps; only the re-run counts."""
    from hlaid.ida import analysis as A
    real = A.simulate_response
    calls = []

    def flaky(*args, substeps=1, **kw):
        r = real(*args, substeps=substeps, **kw)
        calls.append(substeps)
        if substeps == 1:  # the first attempt "blows up"
            bad = np.full_like(r.peak_drift, 1e6 if kind == "jump" else np.nan)
            return dataclasses.replace(r, peak_drift=bad, status=np.full_like(r.status, 1 if kind == "jump" else 2))
        return r
    monkeypatch.setattr(A, "simulate_response", flaky)
    gm = load_builtin("landers-1992-yer270")
    res = run_ida(table1, gm, IDAConfig(im="pga", levels=[0.5], refine=False, heights_mm=HEIGHTS, max_step=0.02))
    k = np.flatnonzero(res.point_stage == "grid")[0]
    assert calls == [1, 4, 1, 4]  # probe and grid point, each re-run once
    assert res.point_substeps[k] == 4 and res.point_status[k] == 0 and res.peak_drift[k].max() < 100.0
    assert np.isnan(res.collapse_im[0])  # not a collapse


def test_pdelta_and_heights_rules(table1, tmp_path, capsys):
    with pytest.raises(InputError, match="story heights are unknown"):
        prepare_building(table1)
    b, notes = prepare_building(table1, heights=HEIGHTS)  # table1 says pdelta: false
    assert b.pdelta_active and any("although the clone says pdelta: false" in n for n in notes)
    b, _ = prepare_building(table1, heights=HEIGHTS, pdelta=False)
    assert not b.pdelta_active
    # a mass-normalised clone: masses are ratios, stiffnesses per unit of total mass; gravity as
    # relative mass x g is per unit mass too, so P-Delta is consistent and on
    ratios = table1.mass / table1.mass.sum()
    norm = Clone(building=table1.replace(height=HEIGHTS, mass=ratios, k0=table1.k0 / table1.mass.sum()),
                 mass_normalised=True)
    b, notes = prepare_building(norm)
    assert b.pdelta_active and any("mass-normalised" in n for n in notes)
    full, _ = prepare_building(table1, heights=HEIGHTS)
    assert np.allclose(b.geometric_stiffness() * table1.mass.sum(), full.geometric_stiffness())
    with pytest.raises(InputError, match="mass-normalised"):
        prepare_building(norm, gravity_load=[1e5, 1e5, 5e4])
    b, _ = prepare_building(table1, heights=HEIGHTS, gravity_load=[1e5, 1e5, 5e4])
    assert b.pdelta_active and np.allclose(b.geometric_stiffness(), [2.5e5 / 3000, 1.5e5 / 3000, 5e4 / 3000])
    path = tmp_path / "clone.json"
    Clone(building=table1.replace(height=HEIGHTS)).save(path)
    b, _ = prepare_building(path)
    assert b.pdelta_active


def test_bad_input(table1, motions, tmp_path, capsys):
    with pytest.raises(InputError, match="strictly increasing; level 3 .0.5 g. is not above level 2"):
        run_ida(table1, motions, IDAConfig(levels=[0.2, 0.8, 0.5], heights_mm=HEIGHTS))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no record files in the folder"):
        run_ida(table1, empty, IDAConfig(heights_mm=HEIGHTS))
    folder = tmp_path / "recs"
    folder.mkdir()
    src = load_builtin(RECS[0]).source
    with open(folder / "good.AT2", "w") as fh:
        import gzip
        from importlib import resources
        with resources.as_file(resources.files("hlaid").joinpath("data/records/elcentro-1940-ns.AT2.gz")) as p:
            fh.write(gzip.decompress(p.read_bytes()).decode())
    (folder / "broken.AT2").write_text("not\nan\nAT2\nfile\n1 2 3\n")
    with pytest.warns(HlaidWarning) as seen:
        recs = read(folder, "records")
    err = " ".join(str(w.message) for w in seen)
    assert [m.name for m in recs] == ["good"] and "skipped 1 unreadable record(s)" in err and "broken.AT2" in err
    (folder / "good.AT2").unlink()
    with pytest.raises(InputError, match="none of the 1 record file"), pytest.warns(HlaidWarning, match="skipped"):
        read(folder, "records")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(InputError, match="not an hlaid clone"):
        run_ida(bad, motions)
    d = Clone(building=table1).to_dict()
    d["version"] = 99
    bad.write_text(json.dumps(d))
    with pytest.raises(InputError, match="clone version 99 is not supported"):
        run_ida(bad, motions)
    assert src


def test_summaries_are_consistent(result):
    # exceedance at a grid level = fraction of records whose grid point there exceeds the limit
    exc = result.exceedance([0.01, 0.02])
    for j, L in enumerate(result.levels):
        at = (result.point_stage == "grid") & (result.point_im == L)
        if at.sum() != result.n_records:  # a record that collapsed below L has no point there
            continue
        for i, d in enumerate([0.01, 0.02]):
            assert exc[i, j] == pytest.approx((result.edp[at] > d).mean())
    fr = result.fractiles()
    for j in range(fr.shape[1]):  # 16 <= 50 <= 84 %
        assert fr[0, j] <= fr[1, j] <= fr[2, j]
    f = result.collapse_fragility(n_boot=50)
    assert f.n_records == result.n_records and f.median > 0
    cap, cen = result.limit_capacities(0.01)
    assert np.all(np.isfinite(cap) | np.isfinite(cen))
    assert np.all(cap[np.isfinite(cap)] <= result.collapse_im[np.isfinite(cap)] + 1e-12)


def test_save_is_atomic_and_complete(result, tmp_path, monkeypatch):
    out = tmp_path / "ida"
    result.save(out, n_boot=50)
    names = sorted(p.name for p in out.iterdir())
    assert names == [".hlaid-output.json", "exceedance.png", "fragility.png", "ida.npz", "ida_curves.png",
                     "points.csv", "summary.json"]
    rows = (out / "points.csv").read_text().splitlines()
    assert len(rows) == 1 + result.point_im.size
    s = json.loads((out / "summary.json").read_text())
    assert s["format"] == "hlaid-ida" and len(s["records"]) == 3
    assert set(s["collapse_fragility"]) == {"capacities", "counts"}
    assert np.load(out / "ida.npz")["peak_drift"].shape == result.peak_drift.shape
    with pytest.raises(InputError, match="not empty; use --force"):
        result.save(out)

    from hlaid.ida import plots

    def boom(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(plots, "plot_fragility", boom)
    out2 = tmp_path / "ida2"
    with pytest.raises(KeyboardInterrupt):
        result.save(out2, n_boot=0)
    assert not out2.exists() and [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    with pytest.raises(KeyboardInterrupt):  # --force on an existing result: the old one survives intact
        result.save(out, force=True, n_boot=0)
    assert sorted(p.name for p in out.iterdir()) == names
    shutil.rmtree(out)


def test_building_argument_kinds(table1, motions, tmp_path):
    """A Building, a Clone, a clone file (path or str): the same building to analyse; else an InputError."""
    with pytest.raises(InputError, match="expected a Clone, a Building or a clone file"):
        run_ida(42, motions)
    ref, _ = prepare_building(table1, heights=HEIGHTS)
    assert isinstance(ref, Building) and ref.pdelta
    path = Clone(building=table1).save(tmp_path / "clone.json")
    for model in (Clone(building=table1), path, str(path)):
        b, _ = prepare_building(model, heights=HEIGHTS)
        for name in ("mass", "k0", "alpha", "p", "dy", "delta_eta", "height"):
            np.testing.assert_array_equal(getattr(b, name), getattr(ref, name), err_msg=name)
        assert b.pdelta == ref.pdelta
        np.testing.assert_array_equal(b.rayleigh(), ref.rayleigh())


@pytest.mark.parametrize("n", [1, 20, 99, 100, 200, 1000])
def test_auto_levels_stay_strictly_increasing(n):
    """Rounding keeps the automatic levels distinct for any count (n_levels 200 once failed
    with "level 142 is not above level 141"); the default 20 keeps 3 digits. The levels are
    geometric from half the equal-displacement IM of the smallest reported drift (0.5 %: top / 40),
    so the small-drift fragilities, which rise there, have stripes on their rise."""
    from hlaid.ida.analysis import _auto_levels
    from hlaid.ida.config import check_levels

    for top in (0.37, 1.0, 9.87, 13.8):
        lv = _auto_levels(np.array([top / 0.1]), 0.1, n, 0.005)
        assert len(lv) == n and check_levels(lv) == lv
        assert lv[-1] == pytest.approx(top, rel=1e-3)
        if n > 1:
            assert lv[0] == pytest.approx(min(top / n, top / 40), rel=5e-3)
            exact = np.geomspace(min(top / n, top / 40), top, n)  # one ratio from level to level
            np.testing.assert_allclose(lv, exact, rtol=5e-3)
        if n == 20:
            assert all(v == float(f"{v:.3g}") for v in lv)
            assert sum(v < top * 0.005 / 0.1 * 2 for v in lv) >= 5  # stripes where the 0.5 % fragility rises
        if n > 1:
            equal = _auto_levels(np.array([top / 0.1]), 0.1, n)  # no smallest limit: from top / n
            assert equal[0] == pytest.approx(top / n, rel=5e-3)
