"""The column-mapped reader: YAML schema, units, signs, time axes, and a cross-check on real data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from io_checks import data_path

from hlaid.errors import ConfigError, InputError
from hlaid.io import ChannelSpec, ColumnsConfig, read_columns, read_mini_shake_table
from hlaid.units import G_MM_S2, INCH_MM


def _table(tmp_path, *, n=400, dt=0.01, jitter=0.0, sep=",", name="rec.csv", seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt + (rng.uniform(-jitter, jitter, n) if jitter else 0.0)
    cols = {"t": t, "ag_g": 0.1 * np.sin(2 * np.pi * 1.3 * t), "a1": rng.normal(0, 50, n),
            "a2": rng.normal(0, 50, n), "d0_in": 0.05 * np.cos(t), "d1_in": 0.3 * np.sin(t), "d2_in": 0.6 * np.sin(t)}
    head = sep.join(cols)
    body = "\n".join(sep.join(repr(float(v)) for v in row) for row in np.column_stack(list(cols.values())))
    (tmp_path / name).write_text(f"# made by a test\n{head}\n{body}\n")
    return cols


YAML = """\
file: rec.csv
time: t
ground: {column: ag_g, units: g}
floors:
  - {column: a1, units: cm/s^2}
  - {column: a2, units: cm/s^2, sign: -1}
floor_disp:
  - {column: d1_in, units: in}
  - {column: d2_in, units: in}
ground_disp: {column: d0_in, units: in}
weight_kN: [171.85, 90]
height_mm: [3000, 3200]
"""


def test_units_signs_relative_displacement_and_masses(tmp_path):
    cols = _table(tmp_path)
    (tmp_path / "rec.yaml").write_text(YAML)
    m = read_columns(tmp_path / "rec.yaml")
    assert m.dt == pytest.approx(0.01) and m.n_floors == 2 and not m.extra["resampled"]
    np.testing.assert_allclose(m.ground_acc, cols["ag_g"] * G_MM_S2)
    np.testing.assert_allclose(m.floor_acc[:, 0], cols["a1"] * 10)
    np.testing.assert_allclose(m.floor_acc[:, 1], -cols["a2"] * 10)
    np.testing.assert_allclose(m.floor_disp[:, 1], (cols["d2_in"] - cols["d0_in"]) * INCH_MM)
    np.testing.assert_allclose(m.mass, [17.524, 9.177], rtol=1e-4)
    np.testing.assert_allclose(m.height, [3000, 3200])
    assert m.source == str(tmp_path / "rec.csv") and m.name == "rec"


def test_irregular_time_column_is_interpolated_onto_a_uniform_grid(tmp_path):
    cols = _table(tmp_path, jitter=0.003, seed=1)
    (tmp_path / "rec.yaml").write_text(YAML)
    m = read_columns(tmp_path / "rec.yaml")
    assert m.extra["resampled"] and m.extra["time_jitter_s"] > 0.0005
    grid = cols["t"][0] + m.dt * np.arange(m.n_samples)
    np.testing.assert_allclose(m.ground_acc, np.interp(grid, cols["t"], cols["ag_g"]) * G_MM_S2)


def test_index_columns_whitespace_dt_and_offsets(tmp_path):
    x = np.column_stack([np.sin(np.arange(300) / 7) + 2.0, np.cos(np.arange(300) / 5) - 1.0])
    np.savetxt(tmp_path / "plain.txt", x)
    (tmp_path / "p.yaml").write_text("file: plain.txt\ndt: 0.02\nheader: false\noffset: mean\n"
                                     "ground: {column: 0, units: m/s^2}\nfloors: [{column: 1, units: mm/s^2}]\n")
    m = read_columns(tmp_path / "p.yaml")
    assert m.dt == 0.02
    np.testing.assert_allclose(m.ground_acc, 1000 * (x[:, 0] - x[:, 0].mean()))
    np.testing.assert_allclose(m.floor_acc[:, 0], x[:, 1] - x[:, 1].mean())
    cfg = ColumnsConfig(file="plain.txt", dt=0.02, header=False, ground=ChannelSpec(column=0, units="m/s^2"),
                        floors=[ChannelSpec(column=1, units="mm/s^2")], offset="mean")
    same = read_columns(cfg, base=tmp_path)
    np.testing.assert_allclose(same.floor_acc, m.floor_acc)


@pytest.mark.parametrize("yaml_text, message", [
    (YAML + "colour: red\n", ":13: unknown key 'colour'"),
    (YAML.replace("units: g}", "units: furlongs}"), "unknown acceleration unit"),
    (YAML.replace("sign: -1", "sign: 2"), "sign = 2 is out of range; expected -1 <= sign <= 1"),
    (YAML.replace("sign: -1", "sign: 0.5"), "sign must be 1 or -1"),
    (YAML.replace("time: t\n", ""), "exactly one of time"),
    (YAML.replace("  - {column: d2_in, units: in}\n", ""), "one displacement per floor"),
    (YAML.replace("weight_kN: [171.85, 90]", "weight_kN: [171.85]"), "weight_kN has 1 values"),
    (YAML.replace("floors:", "floors: 3\nfloorz:"), "expected a list"),
    (YAML + "format: columns\n", "format: 'columns' is not a delimiter; this key (now delimiter:)"),
    (YAML + "format: csv\ndelimiter: csv\n", "give delimiter only"),
])
def test_bad_configs_name_file_and_line(tmp_path, yaml_text, message):
    _table(tmp_path)
    p = tmp_path / "rec.yaml"
    p.write_text(yaml_text)
    with pytest.raises(ConfigError) as err:
        read_columns(p)
    assert "\n" not in str(err.value) and str(p) in str(err.value) and message in str(err.value)


def test_bad_data_files(tmp_path):
    _table(tmp_path)
    (tmp_path / "rec.yaml").write_text(YAML.replace("column: a1,", "column: a9,"))
    with pytest.raises(InputError, match="no column 'a9'; columns are t, ag_g"):
        read_columns(tmp_path / "rec.yaml")
    (tmp_path / "rec.yaml").write_text(YAML.replace("rec.csv", "missing.csv"))
    with pytest.raises(InputError, match="missing.csv: file not found"):
        read_columns(tmp_path / "rec.yaml")


def test_reproduces_the_mini_shake_table_reader_on_real_data(tmp_path):
    """A YAML description of the IMU CSV gives the same measurement as the dedicated reader."""
    path = data_path("mini_shake_table_3story_model", "stiff_3story_sine1p5.csv")
    (tmp_path / "imu.yaml").write_text(
        f"file: {path}\ntime: t_s\noffset: pre-event\npre_event_s: 5.0\n"
        "ground: {column: ground_AccX, units: m/s^2}\nfloors:\n"
        + "".join(f"  - {{column: floor{k}_AccX, units: m/s^2}}\n" for k in (1, 2, 3)))
    a = read_columns(tmp_path / "imu.yaml")
    b = read_mini_shake_table(path)
    assert a.dt == pytest.approx(b.dt)
    np.testing.assert_allclose(a.ground_acc, b.ground_acc, atol=1e-9)
    np.testing.assert_allclose(a.floor_acc, b.floor_acc, atol=1e-9)


def test_the_shipped_example_reads_and_format_is_the_older_name_of_delimiter(tmp_path):
    """configs/columns_example.yaml reads its table (g and cm/s^2 converted to mm/s^2, weights to
    masses); ``format: csv`` (the older key) reads the same."""
    example = Path(__file__).resolve().parents[1] / "configs" / "columns_example.yaml"
    m = read_columns(example)
    assert (m.n_floors, m.n_samples, m.dt) == (3, 1000, pytest.approx(0.01))
    np.testing.assert_allclose(m.mass, np.array([171.85, 171.85, 90.0]) / 9.80665, rtol=1e-12)
    assert 0.2 * 9806.65 < np.max(np.abs(m.ground_acc)) < 0.4 * 9806.65  # El Centro at 0.3 g
    (tmp_path / "columns_example.csv").write_bytes(example.with_suffix(".csv").read_bytes())
    (tmp_path / "old.yaml").write_text(example.read_text().replace("delimiter: csv", "format: csv"))
    np.testing.assert_array_equal(read_columns(tmp_path / "old.yaml").floor_acc, m.floor_acc)
