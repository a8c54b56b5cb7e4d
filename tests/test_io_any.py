"""read / detect_format: every shipped dataset is recognised; unknown files get a clear error."""

from __future__ import annotations

import numpy as np
import pytest
from io_checks import data_path

from hlaid.errors import InputError
from hlaid.io import MEASUREMENT_READERS, detect_format, read
from hlaid.measurement import Measurement

CASES = [
    (("shake_table_3story_steel_mrf_fixedbase", "filtered_fbgm152s1_denoised.tsv.gz"), "steel-frame", {}),
    (("mini_shake_table_3story_model", "flexible_3story_sine1p5.csv"), "mini-shake-table", {}),
    (("nsmp1103_berkeley_building_2018",), "smc", {}),
    (("painter_street_overpass_petrolia1992", "petrolia_25apr1992_ce89324p.zip"), "csmip",
     {"ground": 3, "floors": [7]}),
    (("phycnn_6story_hotel", "data_exp.mat"), "hotel", {"event": 13}),
]


@pytest.mark.parametrize("parts, fmt, kw", CASES, ids=[c[1] for c in CASES])
def test_each_dataset_is_detected_and_read(parts, fmt, kw):
    path = data_path(*parts)
    assert detect_format(path) == fmt
    m = read(path, "measurement", **kw)
    assert isinstance(m, Measurement) and m.n_floors >= 1 and m.source


def test_registry_names():
    assert {"npz", "csv", "steel-frame", "mini-shake-table", "smc", "columns"} <= set(MEASUREMENT_READERS)


def test_hlaid_measurement_files_round_trip_through_read(tmp_path):
    t = np.arange(200) * 0.01
    m = Measurement(dt=0.01, ground_acc=1000 * np.sin(7 * t), floor_acc=np.column_stack([np.cos(t), np.sin(t)]) * 100)
    for ext, fmt in ((".npz", "npz"), (".csv", "csv")):
        p = m.save(tmp_path / f"m{ext}")
        assert detect_format(p) == fmt
        np.testing.assert_allclose(read(p, "measurement").floor_acc, m.floor_acc)


def test_columns_yaml_is_detected(tmp_path):
    (tmp_path / "d.csv").write_text("t,a,b\n" + "\n".join(f"{i * 0.01},{np.sin(i)},{np.cos(i)}" for i in range(50)))
    (tmp_path / "d.yaml").write_text("file: d.csv\ntime: t\nground: {column: a, units: g}\n"
                                     "floors: [{column: b, units: g}]\n")
    assert detect_format(tmp_path / "d.yaml") == "columns"
    assert read(tmp_path / "d.yaml", "measurement").n_floors == 1


def test_unknown_files_and_formats(tmp_path):
    p = tmp_path / "mystery.dat"
    p.write_text("1 2 3\n4 5 6\n")
    with pytest.raises(InputError) as err:
        read(p, "measurement")
    assert "mystery.dat" in str(err.value) and "format=" in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(InputError, match="unknown measurement format 'xml'"):
        read(p, "measurement", format="xml")
    with pytest.raises(InputError, match="file not found"):
        read(tmp_path / "nope.csv", "measurement")
    with pytest.raises(InputError, match="no .smc"):
        read(tmp_path, "measurement")
    with pytest.raises(InputError, match="unexpected keyword"):
        read(data_path("mini_shake_table_3story_model", "flexible_3story_sine1p5.csv"), "measurement", colour="red")


def test_read_infers_the_kind(tmp_path):
    from hlaid.io import infer_kind
    from hlaid.motions import GroundMotion

    t = np.arange(200) * 0.01
    m = Measurement(dt=0.01, ground_acc=1000 * np.sin(7 * t), floor_acc=np.column_stack([np.cos(t)]) * 100)
    for ext in (".npz", ".csv"):
        assert infer_kind(m.save(tmp_path / f"m{ext}")) == "measurement"
        assert isinstance(read(tmp_path / f"m{ext}"), Measurement)
    rec = tmp_path / "recs"
    rec.mkdir()
    (rec / "a.txt").write_text("# dt=0.01, units: g\n" + "\n".join(f"{0.01 * np.sin(i):.5f}" for i in range(100)))
    (rec / "b.csv").write_text("time,acc (g)\n"
                               + "\n".join(f"{i * 0.01:.2f},{0.01 * np.cos(i):.5f}" for i in range(100)))
    assert [infer_kind(rec / n) for n in ("a.txt", "b.csv")] == ["motion", "motion"]
    assert isinstance(read(rec / "a.txt"), GroundMotion) and isinstance(read(rec / "b.csv"), GroundMotion)
    assert infer_kind(rec) == "records" and [g.name for g in read(rec)] == ["a", "b"]
    assert infer_kind("builtin:elcentro-1940-ns") == "motion"
    assert infer_kind("builtin-suite") == "records" and infer_kind(["builtin:elcentro-1940-ns"]) == "records"
    assert infer_kind(rec / "a.txt", format="csv") == "measurement"
    assert infer_kind(rec / "a.txt", format="at2") == "motion"
    assert infer_kind(rec / "x.AT2.gz") == "motion"


def test_read_refuses_an_unknown_kind_and_a_format_for_records(tmp_path):
    with pytest.raises(InputError, match="unknown kind 'table'; expected one of measurement, motion, records"):
        read(tmp_path, "table")
    with pytest.raises(InputError, match="format= applies to one file"):
        read("builtin-suite", "records", format="at2")
