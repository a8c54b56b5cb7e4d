"""FEMA P-58 losses through pelicun (hlaid.loss): pelicun run by hlaid equals pelicun's own command
line on the files hlaid wrote; the collapse probability follows hlaid's fragility; inventories and
bad input. The tests that run pelicun need the extra ``hlaid[loss]`` (CI installs it)."""

from __future__ import annotations

import csv
import io
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import requires
from scipy.special import ndtr

from hlaid.cli import main
from hlaid.clone import Clone
from hlaid.demo import demo_config
from hlaid.ida import IDAConfig
from hlaid.loss import LossConfig, clone_demands, default_inventory
from hlaid.loss.assess import assess_demands, describe_building
from hlaid.loss.fema_p58 import SAMPLE_COLUMNS
from hlaid.loss.inventory import INVENTORIES, check_inventory


def _pelicun_usable() -> bool:
    try:
        import pelicun.assessment  # noqa: F401
    except ImportError:
        return False
    return True


needs_pelicun = requires(_pelicun_usable(), "pelicun not usable (pip install 'hlaid[loss]')")


@pytest.fixture(scope="module")
def demo_clone() -> Clone:
    """The demo's building (paper Table 1, story heights 3 m) as a clone."""
    return Clone(building=demo_config().measurement.simulate.building.build())


@pytest.fixture(scope="module")
def stripe(demo_clone):
    """Demands of the demo building under the built-in suite scaled to Sa(T1) = 1.0 g."""
    return clone_demands(demo_clone, "builtin-suite", level=1.0, ida_config=IDAConfig(max_step=0.005))


@needs_pelicun
def test_pelicun_through_hlaid_equals_pelicuns_command_line(demo_clone, stripe, tmp_path):
    cfg = LossConfig(realizations=200, seed=7)
    median, beta = 1.3, 0.4  # a collapse fragility in Sa(T1) [g]
    asset = describe_building(3, list(demo_clone.building.mass), cfg, (median, beta))
    res = assess_demands(stripe, asset, cfg, tmp_path, "stripe")
    cli = subprocess.run([sys.executable, "-m", "pelicun.tools.DL_calculation", "-c", "config.json", "-d",
                          "demands.csv", "--dirnameOutput", "cli"], cwd=tmp_path, capture_output=True, text=True,
                         env=dict(os.environ), timeout=600)
    assert cli.returncode == 0, cli.stderr[-2000:]
    with open(tmp_path / "cli" / "DL_summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 200
    for name, col in SAMPLE_COLUMNS.items():
        np.testing.assert_allclose(res.sample[name], [float(r[col]) for r in rows], rtol=1e-9, atol=1e-6,
                                   err_msg=name)
    s = res.summary
    assert s["repair_cost_median"] == pytest.approx(np.median([float(r["repair_cost-"]) for r in rows]), rel=1e-9)
    # collapse: pelicun samples hlaid's fragility at each realization's Sa(T1) = 1.0 g
    p = float(ndtr(np.log(1.0 / median) / beta))
    assert abs(s["p_collapse"] - p) < 4 * np.sqrt(p * (1 - p) / 200)
    col = res.sample["collapse"] > 0.5
    np.testing.assert_allclose(res.sample["repair_cost"][col], asset.replacement_cost, rtol=1e-12)
    assert s["repair_cost_ratio_median"] == pytest.approx(s["repair_cost_median"] / asset.replacement_cost)


@needs_pelicun
def test_unknown_component_is_one_line_exit_2(stripe, tmp_path, capsys):
    stripe.write_csv(tmp_path / "d.csv")
    inv = default_inventory("steel-moment-frame", [100.0] * 3).replace("B.10.35.021", "B.10.99.999", 1)
    (tmp_path / "inv.csv").write_text(inv)
    assert main(["loss", str(tmp_path / "d.csv"), "-o", str(tmp_path / "out"), "--floor-area", "100",
                 "--inventory", str(tmp_path / "inv.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "inv.csv: line 2: component 'B.10.99.999' is not in the FEMA P-58" in err
    assert not (tmp_path / "out").exists()


@needs_pelicun
def test_default_inventories_pass_the_library_check():
    for name in INVENTORIES:
        assert check_inventory(default_inventory(name, [120.0, 100.0]), 2, name) > 10


def test_default_inventory_scales_with_floor_area():
    rows = list(csv.DictReader(io.StringIO(default_inventory("rc-frame", [100.0, 300.0]))))
    part = [float(r["Theta_0"]) for r in rows if r["ID"] == "C.10.11.001a"]
    assert part[1] == pytest.approx(3 * part[0]) and part[0] == pytest.approx(891 * 0.3048 / 1393.5456 * 100, rel=1e-4)
    elev = [r for r in rows if r["ID"] == "D.10.14.011"]
    assert len(elev) == 1 and float(elev[0]["Theta_0"]) == pytest.approx(400 / (4 * 1393.5456), rel=1e-4)
    assert {r["ID"] for r in rows} >= {"B.10.41.001a", "B.10.41.001b", "B.10.49.031"}


def test_wrong_units_row_is_one_line_exit_2(stripe, tmp_path, capsys):
    text = stripe.csv_text().replace("Units,g,g,g,g,rad", "Units,g,g,g,g,mps2", 1)
    (tmp_path / "d.csv").write_text(text)
    assert main(["loss", str(tmp_path / "d.csv"), "-o", str(tmp_path / "out"), "--floor-area", "100"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("hlaid loss: error:") and "1-PID-1-1: unit 'mps2'" in err
    assert not (tmp_path / "out").exists()


def test_demands_command_writes_the_library_demands(demo_clone, tmp_path):
    demo_clone.save(tmp_path / "c.json")
    out = tmp_path / "d.csv"
    assert main(["demands", str(tmp_path / "c.json"), "--records", "builtin:kobe-1995-nis000", "--level", "0.7",
                 "-o", str(out)]) == 0
    d = clone_demands(demo_clone, "builtin:kobe-1995-nis000", level=0.7)
    assert out.read_text() == d.csv_text()
    assert main(["demands", str(tmp_path / "c.json"), "--records", "builtin-suite", "-o", str(out), "--force"]) == 2


@pytest.mark.parametrize("kw, message", [({"system": "timber"}, "structural system 'timber' is unknown"),
                                         ({"irreparable_median": 1.5}, "irreparable_median"),
                                         ({"realizations": 5}, "realizations"),
                                         ({"floor_area_m2": [100.0, -1.0]}, "floor_area_m2")])
def test_loss_config_checked(kw, message):
    from hlaid.errors import InputError

    with pytest.raises(InputError, match=message):
        LossConfig(**kw)


@needs_pelicun
def test_fleet_table_gets_the_losses(tmp_path):
    """A fleet config with a loss block: each unit's losses at its own event become loss.* columns."""
    import dataclasses

    pytest.importorskip("dask.distributed")
    from test_fleet import fake_assess

    from hlaid.fleet import load_fleet_config, run_fleet

    def assess_with_beta(clone, records, **kw):
        return {**fake_assess(clone, records, **kw), "beta": 0.4}

    assess_with_beta.engine = "fake"
    d = _one_building_fleet(tmp_path)
    cfg = load_fleet_config(d / "fleet.yaml")
    cfg = dataclasses.replace(cfg, buildings=cfg.buildings[:1], n_ensemble=0, loss=LossConfig(realizations=20))
    s = run_fleet(cfg, tmp_path / "out", base_dir=d, cache_dir=str(tmp_path / "cache"), assess=assess_with_beta)
    assert not s.failed, [r.get("reason") for r in s.rows]
    with open(tmp_path / "out" / "results.csv") as fh:
        row = next(csv.DictReader(fh))
    assert 0 < float(row["loss.repair_cost_ratio_median"]) <= 1
    assert float(row["loss.repair_cost_ratio_band_lo"]) <= float(row["loss.repair_cost_ratio_median"])
    assert float(row["loss.repair_cost_median"]) == pytest.approx(
        float(row["loss.repair_cost_ratio_median"]) * float(row["loss.replacement_cost"]), rel=1e-5)
    assert "loss.repair_cost_ratio_median" in (tmp_path / "out" / "report.html").read_text()


def _one_building_fleet(tmp_path):
    """The fleet test's one-building config and measurement (as test_fleet's fixture makes them)."""
    from conftest import window
    from test_fleet import BUILDING, CONFIG, _building

    from hlaid.motions import load_builtin
    from hlaid.synthetic import simulate_measurement

    d = tmp_path / "fleet"
    d.mkdir()
    gm = window(load_builtin("kocaeli-1999-dzc180").scaled_to_pga(0.5).resampled(200.0), 10.0)
    simulate_measurement(_building("B1"), gm, noise_rms=0.05, seed=0).save(d / "B1.npz")
    (d / "fleet.yaml").write_text(CONFIG + BUILDING.format(name="B1"))
    return d


def test_run_config_loss_block(tmp_path):
    from test_runner import CONFIG

    from hlaid.errors import InputError
    from hlaid.run.config import load_run_config

    (tmp_path / "a.yaml").write_text(CONFIG.split("ida:")[0] + "loss: {system: rc-frame}\n")
    with pytest.raises(InputError, match="the loss block needs an ida block"):
        load_run_config(tmp_path / "a.yaml")
    (tmp_path / "b.yaml").write_text(CONFIG + "loss: {system: rc-frame, realizations: 200, levels: [0.5, 1.0]}\n")
    cfg = load_run_config(tmp_path / "b.yaml")
    assert cfg.loss == LossConfig(system="rc-frame", realizations=200, levels=[0.5, 1.0])
    (tmp_path / "c.yaml").write_text(CONFIG + "loss: {sytem: rc-frame}\n")
    with pytest.raises(InputError, match="sytem"):
        load_run_config(tmp_path / "c.yaml")
