"""``hlaid run`` / ``hlaid report``: the whole pipeline writes every promised file with the
values it promises (the identified parameters near the simulated truth, the collapse fragility
the lognormal maximum likelihood of the records' collapse intensities), the report embeds every
figure and renders in a headless browser, and nothing is replaced without force."""

from __future__ import annotations

import csv
import json
import shutil

import numpy as np
import pytest
from conftest import requires

from hlaid.clone import load_clone
from hlaid.errors import InputError
from hlaid.run.config import load_run_config
from hlaid.run.report import FIGURES, build_report, embedded_figures, screenshot
from hlaid.run.runner import run_pipeline
from hlaid.run.sections import assessment
from hlaid.run.summary import RunSummary

CONFIG = """
name: small run
measurement:
  simulate:
    building:
      stories:
        - {weight_kN: 171.85, k0: 1.94e4, alpha: 0.23, p: 2.5, dy: 7.0, delta_eta: 0.70, height_mm: 3000}
        - {weight_kN: 90.0,   k0: 1.37e4, alpha: 0.12, p: 1.9, dy: 3.0, delta_eta: 1.54, height_mm: 3000}
    motion: {file: "builtin:kocaeli-1999-dzc180", pga_g: 0.62}
    measurement: {rate_hz: 200, noise_rms: 0.05}
    seed: 1
identify:
  training: {samples: 300}
  outer: {max_iterations: 1}
ida:
  records: ["builtin:northridge-1994-mul009", "builtin:kobe-1995-nis000", "builtin:lomaprieta-1989-cap000"]
  n_levels: 4
  bootstrap: 50
assess: {n_ensemble: 2, n_boot: 5}
"""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    base = tmp_path_factory.mktemp("run")
    (base / "run.yaml").write_text(CONFIG)
    cfg = load_run_config(base / "run.yaml")
    out = base / "out"
    summary = run_pipeline(cfg, out, base_dir=base, cache_dir=str(base / "cache"))
    return out, summary


def test_every_output_is_written(run_dir):
    out, summary = run_dir
    for rel in ["report.html", "clone.json", "summary.json", "parameters.csv", "parameters.json",
                "identification.json", "measurement.npz", "hla", "ida/summary.json", "ida/points.csv", "ida/ida.npz",
                "tensorboard"]:
        assert (out / rel).exists(), rel
    assert list((out / "tensorboard").rglob("events.out.tfevents.*"))
    assert not list(out.parent.glob(".out.*"))  # no temporary folder left behind
    clone = load_clone(out / "clone.json")
    assert clone.building.n_stories == 2
    rows = json.loads((out / "parameters.json").read_text())["identified"]
    assert {r["parameter"] for r in rows} == {"k0", "alpha", "p", "dy", "delta_eta"} and len(rows) == 10
    # the table's errors are the identified values against the simulated truth
    for r in rows:
        assert r["error"] == pytest.approx(abs(r["identified"] / r["true"] - 1.0))
        assert r["error"] < 0.05, r  # 5 % noise, 300 samples, one outer iteration: 1.3 % at most
    with open(out / "parameters.csv", newline="") as fh:  # the same table as parameters.json
        table = list(csv.DictReader(fh))
    assert [(r["parameter"], int(r["story"])) for r in table] == [(r["parameter"], r["story"]) for r in rows]
    np.testing.assert_allclose([float(r["identified"]) for r in table], [r["identified"] for r in rows], rtol=1e-12)
    written = json.loads((out / "summary.json").read_text())
    assert written["name"] == "small run" and written["n_stories"] == 2
    assert json.loads((out / "ida" / "summary.json").read_text()) == written["ida"]
    assert [s["story"] for s in json.loads((out / "identification.json").read_text())["stories"]] == [1, 2]
    assert len(json.loads((out / "hla" / "hla.json").read_text())["stories"]) == 2
    with np.load(out / "hla" / "hla.npz") as h:
        assert h["force"].shape == h["drift"].shape and h["drift"].shape[1] == 2
    with np.load(out / "measurement.npz") as m:
        assert m["floor_acc"].shape == (m["ground_acc"].shape[0], 2) and np.isfinite(m["floor_acc"]).all()
    with np.load(out / "ida" / "ida.npz") as z:
        assert list(z["record_names"]) == ["northridge-1994-mul009", "kobe-1995-nis000", "lomaprieta-1989-cap000"]
        peak = z["peak_drift"][np.lexsort((z["point_scale"], z["point_record"]))]
    with open(out / "ida" / "points.csv", newline="") as fh:  # one row per point of ida.npz
        points = list(csv.DictReader(fh))
    points.sort(key=lambda r: (int(r["record_index"]), float(r["scale"])))
    assert len(points) == len(peak) > 0 and peak.shape[1] == 2
    np.testing.assert_allclose([[float(r["peak_drift_mm_1"]), float(r["peak_drift_mm_2"])] for r in points], peak,
                               rtol=1e-5)
    # every record collapsed inside the grid: the maximum-likelihood lognormal of the collapse
    # intensities is their geometric mean and the (population) standard deviation of their logs
    with np.load(out / "ida" / "ida.npz") as z:
        cap, cen = z["collapse_im"], z["censored_im"]
    fit = summary.ida.collapse_fragility.capacities
    assert np.all(np.isfinite(cap)) and not np.any(np.isfinite(cen)) and fit.n_censored == 0
    assert fit.median_g == pytest.approx(np.exp(np.mean(np.log(cap))), rel=1e-6)
    assert fit.beta == pytest.approx(np.std(np.log(cap)), rel=1e-4)
    assert min(summary.replay.r_true) > 0.999  # the clone's replay against the simulated truth
    # the summary written is the one returned, and reads back as it was written
    assert written["format"] == "hlaid-run" and written["version"] == 2
    assert RunSummary.from_dict(written) == summary and RunSummary.from_dict(written).to_dict() == written


def test_report_embeds_every_figure(run_dir):
    out, _ = run_dir
    alts = {alt for alt, size in embedded_figures(out / "report.html") if size > 10_000}
    expected = {rel.split("/")[-1] for rel, _ in FIGURES} | {assessment.FIGURE.split("/")[-1]}
    assert alts == expected | {"aftershock.png"}  # the fragility before and after the event
    text = (out / "report.html").read_text()
    assert "median collapse" in text and "drift ratio &gt; 1.0%" in text and "src=\"file:" not in text
    # the ensemble assessment: indicator, P(collapse) at the measured record, intervals per parameter
    assert "Collapse risk with identification uncertainty" in text and "re-occupancy indicator" in text
    assert "90 % interval" in text


def test_assessment_is_written(run_dir):
    out, summary = run_dir
    a = summary.assessment
    assert a.n_ensemble == 2 and a.indicator in ("green", "yellow", "red")
    assert 0 <= a.p_collapse <= 1 and a.own_im > 0
    full = json.loads((out / "assessment.json").read_text())
    assert len(full["member_median"]) == 2 and len(full["fragility_median"]) == len(full["im_grid"])
    # the building survived its record: P(collapse | another record of its intensity) there is the identified
    # clone's IDA fragility, as every command reports it; the ensemble's band (conditioned on it) beside
    from hlaid.ida.basis import p_collapse

    (ev,) = summary.events
    fit = summary.ida.collapse_fit
    assert ev.im == pytest.approx(a.own_im) and ev.p_collapse_band is not None
    assert ev.p_collapse == pytest.approx(p_collapse(a.own_im, fit.median_g, fit.beta), rel=1e-6)
    own = summary.basis["own_motion"][0]  # the other question: the clone replaying the record's own motion
    assert own["p_collapse_own_motion"] == 0.0 and own["in_clone"] is True
    assert summary.survival.nominal_survives is True and summary.survival.n_members == 2
    assert summary.survival.n_drawn == 2 + summary.survival.n_rejected
    assert "What the decision rests on" in (out / "report.html").read_text()
    clone = load_clone(out / "clone.json")
    assert clone.uncertainty is not None and clone.uncertainty.info["fit_consistent"] in (True, False)
    rows = json.loads((out / "parameters.json").read_text())["identified"]
    assert all(r["lo90"] <= r["identified"] <= r["hi90"] for r in rows if r["lo90"] is not None)


def test_assess_block_needs_ida(tmp_path):
    (tmp_path / "a.yaml").write_text(CONFIG.split("ida:")[0] + "assess: {n_ensemble: 2}\n")
    with pytest.raises(InputError, match="the assess block needs an ida block"):
        load_run_config(tmp_path / "a.yaml")
    (tmp_path / "b.yaml").write_text(CONFIG.replace("n_boot: 5", "n_boots: 5"))
    with pytest.raises(InputError, match="n_boots"):
        load_run_config(tmp_path / "b.yaml")
    (tmp_path / "c.yaml").write_text(CONFIG.replace("n_ensemble: 2", "n_ensemble: 0"))
    with pytest.raises(InputError, match="n_ensemble"):
        load_run_config(tmp_path / "c.yaml")


def test_report_rebuilds_and_refuses_to_replace_a_run(run_dir, tmp_path):
    out, _ = run_dir
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "report.html").unlink()
    build_report(copy)
    assert embedded_figures(copy / "report.html") == embedded_figures(out / "report.html")
    before = (copy / "clone.json").read_bytes()
    cfg = load_run_config(out.parent / "run.yaml")
    with pytest.raises(InputError, match="--force"):
        run_pipeline(cfg, copy, base_dir=out.parent)
    assert (copy / "clone.json").read_bytes() == before


@requires(any(shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome")),
          "no headless Chromium installed")
def test_report_renders_in_headless_chromium(run_dir, tmp_path):
    import matplotlib.image as mpimg
    out, _ = run_dir
    png = screenshot(out / "report.html", tmp_path / "report.png")
    img = mpimg.imread(png)
    assert img.shape[1] == 1200 and img.shape[0] > 4000
    # figures rendered: many rows of the page carry colour, not only white background and text
    rows_with_colour = (np.ptp(img[..., :3], axis=2) > 0.2).any(axis=1).mean()
    assert rows_with_colour > 0.3
