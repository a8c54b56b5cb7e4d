"""``hlaid fleet``: a 3-building fleet on an in-process dask cluster, resume, failure
isolation, output protection, config validation and Ctrl-C."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import import_optional, window

import_optional("dask.distributed")

from hlaid import identify_clone  # noqa: E402
from hlaid.errors import ConfigError, InputError  # noqa: E402
from hlaid.fleet import POINT, load_fleet_config, point_assess, run_fleet  # noqa: E402
from hlaid.io import read  # noqa: E402
from hlaid.model import Building  # noqa: E402
from hlaid.motions import load_builtin  # noqa: E402
from hlaid.synthetic import simulate_measurement  # noqa: E402

STORIES = {  # three small buildings: (k0 scale, alpha, dy)
    "B1": (1.0, (0.23, 0.12), (7.0, 3.0)),
    "B2": (0.8, (0.20, 0.15), (6.0, 4.0)),
    "B3": (1.3, (0.25, 0.10), (8.0, 3.5)),
}

CONFIG = """
name: test fleet
events: [{name: ev1, description: "Kocaeli Duzce 180 at 0.5 g, 10 s"}]
records: ["builtin:northridge-1994-mul009", "builtin:kobe-1995-nis000", "builtin:lomaprieta-1989-cap000"]
n_ensemble: 3
seed: 1
identify:
  training: {samples: 60, n_segments: 8}
  outer: {max_iterations: 1}
  refine: {method: none}
ida: {n_levels: 3, max_hunt: 6, max_fill: 2, tolerance: 0.2, bootstrap: 20}
cluster: {n_workers: 2, threads_per_worker: 1, processes: false}
buildings:
"""

BUILDING = """  - name: {name}
    mass_t: [17.5, 9.2]
    height_mm: [3000, 3000]
    measurements:
      ev1: {{file: {name}.npz}}
"""


def _building(name: str) -> Building:
    s, alpha, dy = STORIES[name]
    return Building(mass=np.array([17.5, 9.2]), k0=s * np.array([1.94e4, 1.37e4]), alpha=np.array(alpha),
                    p=np.array([2.0, 1.8]), dy=np.array(dy), delta_eta=np.array([0.7, 1.5]),
                    height=np.array([3000.0, 3000.0]), name=name)


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory) -> Path:
    """A config with three buildings, each with a simulated 10 s measurement (NPZ)."""
    d = tmp_path_factory.mktemp("fleet")
    gm = window(load_builtin("kocaeli-1999-dzc180").scaled_to_pga(0.5).resampled(200.0), 10.0)
    for i, name in enumerate(STORIES):
        simulate_measurement(_building(name), gm, noise_rms=0.05, seed=i).save(d / f"{name}.npz")
    (d / "fleet.yaml").write_text(CONFIG + "".join(BUILDING.format(name=n) for n in STORIES))
    return d


def fake_assess(clone, records, *, n_ensemble=20, ida_config=None, own_motion=None, seed=0):
    """A quick stand-in with the contract of hlaid.ida.assess: risk from the clone's k0."""
    k = float(clone.building.k0[0])
    return {"collapse_median": k / 1e4, "collapse_median_band": [k / 1.2e4, k / 0.8e4], "own_im": 0.5,
            "p_collapse": round(1e4 / k / 10, 4), "drift_limits": [0.01, 0.02], "p_exceed": [0.5, 0.2],
            "indicator": "green", "n_ensemble": n_ensemble, "n_records": len(records),
            "member_median": [1.0, 2.0, 3.0][:n_ensemble]}


fake_assess.engine = "fake"


class FailingAssess:
    """:func:`fake_assess` (the same engine name, so its results count as the same inputs), with
    the buildings in ``fail`` raising."""

    engine = "fake"

    def __init__(self, fail=()):
        self.fail = set(fail)

    def __call__(self, clone, records, **kw):
        if clone.building.name.split("@")[0] in self.fail:  # clones are named BUILDING@EVENT
            raise RuntimeError("ensemble diverged\nsecond line")
        return fake_assess(clone, records, **kw)


def _rows(out: Path) -> list[dict]:
    with open(out / "results.csv") as fh:
        return list(csv.DictReader(fh))


def test_three_buildings_on_an_in_process_cluster(fleet_dir, tmp_path):
    """Real identification and the point-clone IDA fallback on a LocalCluster(processes=False)."""
    cfg = dataclasses.replace(load_fleet_config(fleet_dir / "fleet.yaml"), n_ensemble=0)  # the point clone
    out = tmp_path / "out"
    t0 = time.perf_counter()
    s = run_fleet(cfg, out, base_dir=fleet_dir, cache_dir=str(tmp_path / "cache"))
    wall = time.perf_counter() - t0
    assert sorted(s.computed) == ["B1@ev1", "B2@ev1", "B3@ev1"] and not s.failed
    rows = _rows(out)
    assert [r["rank"] for r in rows] == ["1", "2", "3"]
    for r in rows:
        assert r["status"] == "ok" and r["ensemble"] == "0" and r["engine"] == POINT
        assert float(r["collapse_median"]) > 0 and 0 <= float(r["p_collapse"]) <= 1
        assert float(r["collapse_median_band_lo"]) <= float(r["collapse_median"]) <= float(r["collapse_median_band_hi"])
        assert r["indicator"] in ("green", "yellow", "red") and float(r["own_im"]) > 0
        assert 0 <= float(r["p_exceed_0.01"]) <= 1 and float(r["p_exceed_0.01"]) >= float(r["p_exceed_0.04"])
        assert float(r["replay_r_min"]) > 0.9  # the identification worked
    p = [float(r["p_collapse"]) for r in rows]
    assert p == sorted(p, reverse=True)  # ranked by risk
    html = (out / "report.html").read_text()
    assert "Ranked by risk" in html and html.count("data:image/png;base64,") == 3 and "ensemble: 0" in html
    for name in STORIES:  # each result holds the clone of its own building: identify_clone of its own file
        res = json.loads((out / "buildings" / f"{name}@ev1.json").read_text())
        assert res["clone"]["format"] == "hlaid-clone" and len(res["digest"]) == 64
        meas = dataclasses.replace(read(fleet_dir / f"{name}.npz", "measurement"), mass=np.array([17.5, 9.2]),
                                   height=np.array([3000.0, 3000.0]))
        own = identify_clone(meas, cfg.identify, cache_dir=str(tmp_path / "cache")).clone.building
        for field in ("k0", "alpha", "p", "dy", "delta_eta"):
            got = [s_[field] for s_ in res["clone"]["stories"]]
            np.testing.assert_allclose(got, getattr(own, field), rtol=1e-6, err_msg=f"{name} {field}")
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == [".hlaid-output.json"]  # no temporary files
    try:
        import pyarrow.parquet as pq
    except ImportError:
        pq = None
    if pq is not None:  # Parquet too when pyarrow is installed
        t = pq.read_table(out / "results.parquet")
        assert t.num_rows == 3 and str(t.schema.field("p_collapse").type) == "double"
        assert t.column("building").to_pylist() == [r["building"] for r in rows]
    print(f"3-building fleet: {wall:.1f} s")


def test_three_buildings_with_the_ensemble(fleet_dir, tmp_path):
    """With the ensemble: hlaid.ida.assess through the fleet's seam."""
    cfg = load_fleet_config(fleet_dir / "fleet.yaml")
    cfg = dataclasses.replace(cfg, n_ensemble=2, identify=dataclasses.replace(
        cfg.identify, refine=dataclasses.replace(cfg.identify.refine, method="eiv", max_iterations=10)))
    s = run_fleet(cfg, tmp_path / "out", base_dir=fleet_dir, cache_dir=str(tmp_path / "cache"))
    assert not s.failed, [r["reason"] for r in s.rows]
    for r in _rows(tmp_path / "out"):
        assert r["engine"] == "hlaid.ida" and r["ensemble"] == "2"
        assert float(r["collapse_median_band_lo"]) <= float(r["collapse_median"]) <= float(r["collapse_median_band_hi"])
        assert r["indicator"] in ("green", "yellow", "red") and 0 <= float(r["p_collapse"]) <= 1


def test_resume_skips_finished_buildings_and_retries_failed(fleet_dir, tmp_path):
    cfg = load_fleet_config(fleet_dir / "fleet.yaml")
    out = tmp_path / "out"
    s1 = run_fleet(cfg, out, base_dir=fleet_dir, assess=FailingAssess({"B2"}), cache_dir=str(tmp_path / "cache"))
    assert s1.failed == ("B2@ev1",) and sorted(s1.computed) == ["B1@ev1", "B3@ev1"]
    rows = {r["building"]: r for r in _rows(out)}
    assert rows["B2"]["status"] == "failed"
    assert rows["B2"]["reason"] == "assess: RuntimeError: ensemble diverged second line"  # one line
    assert rows["B2"]["rank"] == "3"  # failures last
    before = (out / "buildings" / "B1@ev1.json").stat().st_mtime_ns
    s2 = run_fleet(cfg, out, base_dir=fleet_dir, assess=fake_assess, cache_dir=str(tmp_path / "cache"))
    assert s2.computed == ("B2@ev1",) and sorted(s2.skipped) == ["B1@ev1", "B3@ev1"]
    assert (out / "buildings" / "B1@ev1.json").stat().st_mtime_ns == before  # not recomputed
    assert all(r["status"] == "ok" for r in _rows(out))
    # changed inputs: the stored results are stale, recomputed only with force
    cfg2 = dataclasses.replace(cfg, seed=2)
    with pytest.raises(InputError, match="other inputs.*--force"):
        run_fleet(cfg2, out, base_dir=fleet_dir, assess=fake_assess)
    s3 = run_fleet(cfg2, out, base_dir=fleet_dir, assess=fake_assess, force=True, cache_dir=str(tmp_path / "cache"))
    assert len(s3.computed) == 3


def test_an_existing_scheduler(fleet_dir, tmp_path):
    """--scheduler: the fleet runs on a cluster it did not start, and leaves it running."""
    from dask.distributed import Client, LocalCluster
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as lc:
        s = run_fleet(load_fleet_config(fleet_dir / "fleet.yaml"), tmp_path / "out", base_dir=fleet_dir,
                      scheduler=lc.scheduler_address, assess=fake_assess, cache_dir=str(tmp_path / "cache"))
        assert len(s.computed) == 3
        with Client(lc) as c:  # still up
            assert len(c.scheduler_info()["workers"]) == 1
    rows = _rows(tmp_path / "out")
    assert {r["worker"].split(":")[1] for r in rows} == {str(os.getpid())}  # one in-process worker


def test_a_bad_measurement_file_fails_alone(fleet_dir, tmp_path):
    d = tmp_path / "cfg"
    d.mkdir()
    for n in STORIES:
        (d / f"{n}.npz").write_bytes((fleet_dir / f"{n}.npz").read_bytes())
    (d / "B3.npz").write_text("not a measurement\n")
    (d / "fleet.yaml").write_text((fleet_dir / "fleet.yaml").read_text())
    s = run_fleet(load_fleet_config(d / "fleet.yaml"), tmp_path / "out", base_dir=d, assess=fake_assess,
                  cache_dir=str(tmp_path / "cache"))
    assert s.failed == ("B3@ev1",)
    r = {r["building"]: r for r in _rows(tmp_path / "out")}["B3"]
    assert r["reason"].startswith("measurement: ") and "B3.npz" in r["reason"] and "\n" not in r["reason"]


def test_output_folder_is_protected(fleet_dir, tmp_path):
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("x")
    with pytest.raises(InputError, match="not an hlaid fleet output.*--force"):
        run_fleet(load_fleet_config(fleet_dir / "fleet.yaml"), other, base_dir=fleet_dir, assess=fake_assess)
    assert (other / "keep.txt").read_text() == "x" and not (other / "buildings").exists()
    # a run refused before it starts (here: no such record) leaves no output folder behind
    cfg = dataclasses.replace(load_fleet_config(fleet_dir / "fleet.yaml"), records=["nothing-here.AT2"])
    with pytest.raises(InputError, match="nothing-here.AT2: record file or folder not found"):
        run_fleet(cfg, tmp_path / "new", base_dir=fleet_dir, assess=fake_assess)
    assert not (tmp_path / "new").exists()


@pytest.mark.parametrize("text, match", [
    ("buildings: []\n", "buildings: list at least one"),
    ("records: builtin-suite\nbuildings:\n  - name: A\n    measurements: {ev1: {file: a.npz}}\n    masses: [1]\n",
     ":5: unknown key 'buildings\\[0\\].masses'"),
    ("events: [{name: e1}]\nbuildings:\n  - name: A\n    measurements:\n      e2: {file: a.npz}\n",
     ":5: buildings.A.measurements: event 'e2' is not in events"),
    ("buildings:\n  - name: A\n    measurements: {e: {file: a.npz}}\n"
     "  - name: A\n    measurements: {e: {file: b.npz}}\n",
     ":4: buildings: building name 'A' appears twice"),
    ("buildings:\n  - name: A\n    measurements: {e: {file: a.npz, simulate: null, station: null}}\n"
     "ida: {n_levels: 1}\n", ":4: ida.n_levels = 1"),
    ("buildings:\n  - name: A\n    measurements:\n      e: {}\n", ":4: .*exactly one of file, station or simulate"),
    ("buildings:\n  - name: a/b\n    measurements: {e: {file: a.npz}}\n", ":2: .*building name 'a/b'"),
])
def test_config_errors_name_the_line(tmp_path, text, match):
    p = tmp_path / "f.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=match) as e:
        load_fleet_config(p)
    assert str(e.value).startswith(str(p)) and "\n" not in str(e.value)


def test_cli_bad_config_exit_2(tmp_path):
    p = tmp_path / "f.yaml"
    p.write_text("buildings:\n  - name: A\n    measurementz: {}\n")
    r = subprocess.run([sys.executable, "-m", "hlaid", "fleet", str(p), "-o", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and f"{p}:3: unknown key" in r.stderr


@pytest.mark.skipif(sys.platform != "linux", reason="process groups are Linux-specific here")
@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_ctrl_c_closes_the_cluster(fleet_dir, tmp_path):
    """SIGINT to the whole group while the LocalCluster's worker processes run: exit 130, one line,
    no process left, finished units kept."""
    cfg = (fleet_dir / "fleet.yaml").read_text().replace("processes: false", "processes: true")
    cfg = cfg.replace("n_levels: 3,", "n_levels: 100, refine: false,")  # long enough to interrupt
    cfg = cfg.replace("n_ensemble: 3", "n_ensemble: 0")  # the point clone: refine: none carries no uncertainty
    d = tmp_path / "cfg"
    d.mkdir()
    for n in STORIES:
        (d / f"{n}.npz").write_bytes((fleet_dir / f"{n}.npz").read_bytes())
    (d / "fleet.yaml").write_text(cfg)
    env = {**os.environ, "HLAID_CACHE": str(tmp_path / "cache"), "PYTHONUNBUFFERED": "1"}
    p = subprocess.Popen([sys.executable, "-m", "hlaid", "fleet", str(d / "fleet.yaml"), "-o", str(tmp_path / "out"),
                          "-v"],  # -v: the workers' messages too, so the test sees a task running
                         env=env, start_new_session=True, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    seen = threading.Event()

    def read():
        for ln in p.stderr:
            lines.append(ln.rstrip("\n"))
            if "IDA of" in ln:  # a worker process is in a task
                seen.set()

    threading.Thread(target=read, daemon=True).start()
    try:
        assert seen.wait(120), lines[-5:]
        time.sleep(0.5)
        os.killpg(p.pid, signal.SIGINT)
        t_int = time.monotonic()
        rc = p.wait(timeout=30)
        elapsed = time.monotonic() - t_int
        t = time.monotonic()
        while time.monotonic() - t < 10:
            try:
                os.killpg(p.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.2)
        else:
            pytest.fail("processes of the fleet are left running")
    finally:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    time.sleep(0.2)
    assert rc == 130, lines[-8:]
    assert elapsed < 15, elapsed  # the workers' graceful stop is 4 s; the machine may be busy
    assert lines[-1] == "hlaid fleet: interrupted", lines[-8:]
    assert not any("Traceback" in ln or "KeyboardInterrupt" in ln for ln in lines), lines


def test_the_seam_is_hlaid_uncertainty():
    import hlaid.uncertainty
    from hlaid.fleet import default_assess
    from hlaid.fleet.assess import engine_label

    fn, engine = default_assess()
    assert fn is hlaid.ida.assess and engine == "hlaid.ida"
    assert engine_label(point_assess) == POINT


def test_flatten_keeps_bands_and_exceedance_by_limit():
    from hlaid.fleet.assess import flatten
    d = {"collapse_median": 2.0, "collapse_median_band": [1.5, 2.6], "member_median": [1.9, 2.1],
         "drift_limits": [0.005, 0.01], "p_exceed": [0.9, 0.5], "p_exceed_band": [[0.8, 1.0], [0.3, 0.6]],
         "timing": {"wall_s": 3.0}, "indicator": "green", "own_peak_drift": [0.01, 0.02]}
    f = flatten(d)
    assert f["collapse_median_band_lo"] == 1.5 and f["collapse_median_band_hi"] == 2.6
    assert f["p_exceed_0.005"] == 0.9 and f["p_exceed_0.01"] == 0.5
    assert f["p_exceed_0.01_band_lo"] == 0.3 and f["p_exceed_0.01_band_hi"] == 0.6
    assert f["timing.wall_s"] == 3.0 and f["indicator"] == "green"
    assert not any(k.startswith(("member_median", "own_peak_drift", "drift_limits")) for k in f)
