"""Cross-check against OpenSeesPy through the exported script (skipped without openseespy).

The script written by ``export_opensees`` builds the clone from zeroLength elements with
``uniaxialMaterial BoucWen`` (docs/DESIGN.md section 3 mapping), Rayleigh damping with
``-doRayleigh 1`` and P-Delta as a parallel negative Elastic spring; ``run_opensees`` executes
that same text. OpenSees runs at dt/10 (Newmark average acceleration; implicit BoucWen),
hlaid at its defaults; the peaks of hlaid are at the record samples, OpenSees' over every
analysis step.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import needs_opensees, paper_record

from hlaid.opensees import (
    export_opensees,
    opensees_script,
    run_opensees,
    run_opensees_batch,
)
from hlaid.simulate import simulate_response

HEIGHTS = [3000.0, 3000.0, 3000.0]


def test_script_is_written_without_opensees(table1, tmp_path):
    path = export_opensees(table1.replace(height=HEIGHTS, pdelta=True), tmp_path / "model.py")
    text = path.read_text()
    compile(text, str(path), "exec")  # valid Python
    assert "uniaxialMaterial BoucWen" in text and '"-doRayleigh", 1' in text and "UniformExcitation" in text
    assert text == opensees_script(table1.replace(height=HEIGHTS, pdelta=True))
    with pytest.raises(Exception, match="already exists"):
        export_opensees(table1, path)




@needs_opensees
@pytest.mark.parametrize("pdelta", [False, True])
@pytest.mark.parametrize("name", ["elcentro-1940-ns", "kocaeli-1999-dzc180"])
def test_peak_drifts_agree_with_opensees_at_dt_over_10(table1, name, pdelta):
    """Table 1 at PGA 0.62 g, 200 Hz: peak drifts within 1 % of OpenSees at dt/10."""
    b = table1.replace(height=HEIGHTS, pdelta=pdelta)
    gm = paper_record(name)
    histories = name == "elcentro-1940-ns" and pdelta  # one case checks the whole history (slower)
    ours = simulate_response(b, gm, substeps=4)
    ref = run_opensees(b, gm, dt_factor=10, histories=histories)
    assert ref.ok
    err = np.abs(ours.peak_drift[0] / ref.peak_drift - 1)
    assert err.max() < 0.01, err
    assert np.allclose(ours.residual_drift[0], ref.residual_drift, atol=0.05 * np.abs(ref.peak_drift).max())
    if histories:
        for i in range(b.n_stories):
            assert np.corrcoef(ours.drift[0, :, i], ref.drift[:, i])[0, 1] > 0.999


@needs_opensees
def test_exported_script_runs_standalone(table1, tmp_path, data_dir):
    b = table1.replace(height=HEIGHTS, pdelta=True, name="table1")
    script = export_opensees(b, tmp_path / "model.py")
    rec = data_dir / "ground_motions" / "classic_peer_at2" / "RSN6_IMPVALL.I_I-ELC180-hor1.AT2"
    out = tmp_path / "peaks.json"
    p = subprocess.run([sys.executable, str(script), str(rec), "--pga-g", "0.62", "--out", str(out)],
                       capture_output=True, text=True, timeout=300, cwd=tmp_path, check=False)
    assert p.returncode == 0, p.stderr
    peaks = json.loads(out.read_text())
    from hlaid.io import read
    gm = read(rec, "motion").scaled_to_pga(0.62)
    ref = run_opensees(b, gm, dt_factor=10)
    assert np.allclose(peaks["peak_drift_mm"], ref.peak_drift, rtol=1e-9)
    assert np.allclose(peaks["peak_drift_ratio"], ref.peak_drift / 3000.0, rtol=1e-9)
    assert "story 1: peak drift" in p.stdout


@needs_opensees
def test_ida_points_agree_with_opensees(table1):
    """A small IDA of the Table 1 clone (P-Delta on): every point re-run in OpenSees at dt/10;
    median difference of the peak drifts below 2 % (the full 10 records x 8 levels check is
    ``test_ida_cross_check_full`` / scripts/bench_ida.py)."""
    from hlaid.ida import IDAConfig, run_ida
    from hlaid.motions import load_builtin
    motions = [load_builtin(n) for n in ("northridge-1994-mul009", "kobe-1995-nis000")]
    res = run_ida(table1, motions, IDAConfig(levels=[1.0, 4.0], refine=False, heights_mm=HEIGHTS))
    diffs = _compare(res, motions)
    assert np.median(diffs) < 0.02 and diffs.size >= 9


def _compare(res, motions):
    diffs = []
    for k in np.flatnonzero((res.point_stage == "grid") & (res.point_status == 0)):
        ref = run_opensees(res.building, motions[res.point_record[k]], scale=res.point_scale[k], dt_factor=10)
        if ref.ok:
            diffs.extend(np.abs(res.peak_drift[k] / ref.peak_drift - 1))
    return np.array(diffs)


@needs_opensees
@pytest.mark.slow
def test_ida_cross_check_full(table1, data_dir):
    """10 far-field records x 8 levels: median |difference| of the peak drifts below 2 %."""
    from hlaid.ida import IDAConfig, run_ida
    from hlaid.io import read
    files = sorted((data_dir / "ground_motions" / "fema_p695_farfield").glob("FF*.AT2"))[::4][:10]
    motions = read(files, "records")
    res = run_ida(table1, motions, IDAConfig(levels=np.linspace(0.5, 4.0, 8), refine=False, heights_mm=HEIGHTS))
    diffs = _compare(res, motions)
    assert np.median(diffs) < 0.02


@needs_opensees
def test_batch_on_worker_processes_keeps_the_job_order(table1):
    """run_opensees_batch (the benchmarks' peer) returns each job's peaks in job order."""
    gm = paper_record("kocaeli-1999-dzc180")
    jobs = [(gm, 0.3), (gm, 1.0), (gm, 0.6)]
    wall, cpu, peaks = run_opensees_batch(table1, jobs, dt_factor=1, workers=2)
    assert peaks.shape == (3, 3) and wall > 0 and cpu > 0
    for (m, s), pk in zip(jobs, peaks, strict=True):
        np.testing.assert_allclose(pk, run_opensees(table1, m, scale=s, dt_factor=1).peak_drift, rtol=1e-12)
    assert peaks[0, 0] < peaks[2, 0] < peaks[1, 0]
