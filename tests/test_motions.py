"""Ground motion records: readers on the real files, PGA against the FEMA P695 table,
resampling (anti-aliasing), scaling, built-in records and one-line errors for bad files."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest
from conftest import GROUND_MOTIONS, ON_CI, requires_data

from hlaid.errors import InputError
from hlaid.io import read
from hlaid.motions import GroundMotion, builtin_records, builtin_suite, load_builtin
from hlaid.units import G_MM_S2

# Text files whose header does not state units or dt (README section 1d/1e): what the README says.
_TEXT_HINTS = {"newhall.txt": {"units": "cm/s^2", "dt": 0.005},
               "LomaPrietaHallsValley90.dat": {"units": "m/s^2"},
               "Northridge_Sylmar_County.dat": {"units": "m/s^2"}}


def _all_record_files():
    if not GROUND_MOTIONS.is_dir():
        return [GROUND_MOTIONS] if ON_CI else []  # under CI one case, which requires_data fails
    return sorted(p for p in GROUND_MOTIONS.glob("*/*") if p.name != "records_farfield.csv")


# ---------------------------------------------------------------------- real files
@requires_data
@pytest.mark.parametrize("path", _all_record_files(), ids=lambda p: p.name)
def test_every_real_record_parses(path):
    kw = _TEXT_HINTS.get(path.name, {})
    columns = [0, 1] if path.parent.name == "basei_benchmark_7records" else [None]
    for col in columns:
        gm = read(path, "motion", column=col, **kw)
        assert gm.npts > 500 and 0.002 <= gm.dt <= 0.02
        assert 0.02 < gm.pga_g < 1.5 and np.isfinite(gm.acc).all()
        assert gm.source == str(path) and gm.name == path.name.rsplit(".", 1)[0]


@requires_data
def test_text_reader_pga_against_readme():
    """Two-column cm/s^2 files of the base-isolation benchmark (README table 1d)."""
    d = GROUND_MOTIONS / "basei_benchmark_7records"
    readme = {"elcentro.txt": (0.313, 0.215), "kobe.txt": (0.841, 0.631), "jiji.txt": (0.512, 0.369)}
    for name, pgas in readme.items():
        for col, pga in enumerate(pgas):
            gm = read(d / name, "motion", column=col)
            assert gm.dt == 0.005
            assert gm.pga_g == pytest.approx(pga, abs=1e-3)


@requires_data
def test_fema_p695_pga_npts_dt_match_the_table():
    folder = GROUND_MOTIONS / "fema_p695_farfield"
    with open(folder / "records_farfield.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 44
    errs = []
    for row in rows:
        gm = read(folder / row["file"], "motion")
        assert gm.npts == int(row["npts"]) and gm.dt == pytest.approx(float(row["dt"]), rel=1e-12)
        errs.append(abs(gm.pga_g / float(row["pga_g"]) - 1.0))
    assert max(errs) <= 0.005, max(errs)  # measured: worst 1.9e-4 (the table has 4 digits)


@requires_data
def test_time_column_and_csv_readers():
    osm = read(GROUND_MOTIONS / "openseismomatlab" / "Northridge_Sylmar_County.dat", "motion", units="m/s^2")
    assert osm.dt == pytest.approx(0.02) and osm.npts == 3000
    assert osm.pga == pytest.approx(8.268e3, rel=1e-3)  # README: 8.268 m/s^2
    chopra = read(GROUND_MOTIONS / "classic_peer_at2" / "elcentro_chopra_appendix6.csv", "motion")
    assert chopra.dt == pytest.approx(0.02) and chopra.npts == 1560
    assert chopra.pga_g == pytest.approx(0.3188, abs=1e-4)
    with pytest.raises(InputError, match="dt = 0.01 s given but the time column steps by 0.02"):
        read(GROUND_MOTIONS / "openseismomatlab" / "Northridge_Sylmar_County.dat", "motion", units="m/s^2", dt=0.01)


def test_builtin_records():
    recs = builtin_records()
    suite = builtin_suite()
    assert len(suite) == 10 and len(recs) == 11
    for gm in suite + [load_builtin("elcentro-1940-ns")]:
        assert gm.source.startswith("builtin:") and gm.npts > 1000 and 0.1 < gm.pga_g < 1.0
    assert read("builtin:kocaeli-1999-dzc180", "motion").pga_g == pytest.approx(0.3121, abs=1e-4)
    with pytest.raises(InputError, match="unknown built-in record 'elcentro'"):
        read("builtin:elcentro", "motion")


@requires_data
def test_builtin_records_are_the_real_files():
    pairs = {"elcentro-1940-ns": "classic_peer_at2/RSN6_IMPVALL.I_I-ELC180-hor1.AT2",
             "kocaeli-1999-dzc180": "fema_p695_farfield/FF09_RSN1158_KOCAELI_DZC180.AT2",
             "northridge-1994-mul009": "fema_p695_farfield/FF01_RSN953_NORTHR_MUL009.AT2"}
    for name, rel in pairs.items():
        a, b = load_builtin(name), read(GROUND_MOTIONS / rel, "motion")
        assert a.dt == b.dt
        np.testing.assert_array_equal(a.acc, b.acc)


# ---------------------------------------------------------------------- transformations
def _tone(f_hz, rate, seconds=20.0, amp=1000.0, phase=0.3):
    t = np.arange(int(seconds * rate)) / rate
    return amp * np.sin(2 * np.pi * f_hz * t + phase), t


def _amplitude(x, t, f_hz):
    """Least-squares amplitude of a sinusoid of frequency f_hz in x (edges trimmed)."""
    k = slice(len(t) // 10, -len(t) // 10)
    A = np.stack([np.sin(2 * np.pi * f_hz * t[k]), np.cos(2 * np.pi * f_hz * t[k])], axis=1)
    c = np.linalg.lstsq(A, x[k], rcond=None)[0]
    return float(np.hypot(*c))


@pytest.mark.parametrize("rate_in,rate_out", [(200.0, 100.0), (200.0, 50.0), (100.0, 40.0)])
def test_downsampling_removes_tones_above_the_new_nyquist(rate_in, rate_out):
    low, high = 3.0, 0.8 * rate_in / 2  # the high tone is above the new Nyquist frequency
    assert high > rate_out / 2
    x = _tone(low, rate_in)[0] + _tone(high, rate_in, phase=1.1)[0]
    gm = GroundMotion(dt=1 / rate_in, acc=x).resampled(rate_out)
    assert gm.dt == pytest.approx(1 / rate_out)
    t = gm.time
    assert gm.npts == pytest.approx(len(x) * rate_out / rate_in, abs=1)
    assert _amplitude(gm.acc, t, low) == pytest.approx(1000.0, rel=0.01)
    alias = abs(high - rate_out * round(high / rate_out))  # where the high tone would fold to
    assert _amplitude(gm.acc, t, alias) < 10.0  # < 1% of the tone survives as an alias
    residual = gm.acc - 1000.0 * np.sin(2 * np.pi * low * t + 0.3)
    k = slice(gm.npts // 10, -gm.npts // 10)
    assert np.sqrt(np.mean(residual[k] ** 2)) < 10.0


def test_upsampling_keeps_a_tone_and_the_record():
    x, t = _tone(4.0, 100.0)
    up = GroundMotion(dt=0.01, acc=x).resampled(200.0)
    expected = 1000.0 * np.sin(2 * np.pi * 4.0 * up.time + 0.3)
    k = slice(200, -200)
    assert np.abs(up.acc[k] - expected[k]).max() < 5.0
    ec = load_builtin("elcentro-1940-ns")
    ec200 = ec.resampled(200.0)
    np.testing.assert_allclose(ec200.acc[::2][: ec.npts - 5], ec.acc[: ec.npts - 5], atol=0.05 * ec.pga)
    assert ec200.duration == pytest.approx(ec.duration, abs=0.01)
    same = ec.resampled(100.0)  # already at 100 Hz: unchanged
    assert same.npts == ec.npts and same.dt == ec.dt and np.array_equal(same.acc, ec.acc)


def test_scaling():
    gm = load_builtin("northridge-1994-mul009")
    s = gm.scaled_to_pga(0.62)
    assert s.pga_g == pytest.approx(0.62, rel=1e-12) and s.pga == pytest.approx(0.62 * G_MM_S2)
    np.testing.assert_allclose(s.acc / gm.acc, 0.62 / gm.pga_g, rtol=1e-12)  # one factor everywhere
    np.testing.assert_allclose(gm.scaled(-2.0).acc, -2.0 * gm.acc)
    p = gm.padded(1.0)
    assert p.npts == gm.npts + 100 and (p.acc[gm.npts:] == 0).all()
    assert gm.time[-1] == pytest.approx(gm.duration)
    with pytest.raises(InputError, match="target PGA = 0 g"):
        gm.scaled_to_pga(0)
    with pytest.raises(InputError, match="all zeros"):
        GroundMotion(dt=0.01, acc=np.zeros(100)).scaled_to_pga(0.5)
    with pytest.raises(ValueError):
        gm.acc[0] = 1.0  # records are immutable


# ---------------------------------------------------------------------- bad input: one-line errors
_HEADER = "PEER NGA STRONG MOTION DATABASE RECORD\nSomewhere, 1/1/2000, Station, 90\n" \
          "ACCELERATION TIME SERIES IN UNITS OF G\n"


def _at2(tmp_path, name, npts_line, values):
    p = tmp_path / name
    p.write_text(_HEADER + npts_line + "\n" + values + "\n")
    return p


@pytest.mark.parametrize("name,npts_line,values,match", [
    ("short.AT2", "NPTS=   12, DT=   .0100 SEC", "1 2 3 4 5\n6 7 8 9 10",
     "header says NPTS = 12 but the file holds 10"),
    ("long.AT2", "NPTS=   9, DT=   .0100 SEC", "1 2 3 4 5\n6 7 8 9 10", "header says NPTS = 9 but the file holds 10"),
    ("nan.AT2", "NPTS=   10, DT=   .0100 SEC", "1 2 NaN 4 5\n6 7 8 9 10", "1 NaN or inf samples"),
    ("inf.AT2", "NPTS=   10, DT=   .0100 SEC", "1 2 3 4 5\n6 7 8 -inf 10", "first at sample 8"),
    ("dt0.AT2", "NPTS=   10, DT=   .0000 SEC", "1 2 3 4 5\n6 7 8 9 10", "dt = 0.0 s; expected a positive"),
    ("dtneg.AT2", "NPTS=   10, DT=  -.0100 SEC", "1 2 3 4 5\n6 7 8 9 10", "dt = -0.01 s; expected a positive"),
    ("text.AT2", "NPTS=   10, DT=   .0100 SEC", "1 2 3 4 5\n6 7 8 9 ten", "non-numeric value at line 6 \\(value 5"),
    ("header.AT2", "10 points every 0.01 s", "1 2 3 4 5\n6 7 8 9 10", "line 4 should give NPTS and DT"),
])
def test_malformed_at2(tmp_path, name, npts_line, values, match):
    p = _at2(tmp_path, name, npts_line, values)
    with pytest.raises(InputError, match=match) as err:
        read(p, "motion")
    msg = str(err.value)
    assert msg.startswith(str(p) + ": ") and "\n" not in msg


def test_old_at2_layout(tmp_path):
    p = _at2(tmp_path, "old.AT2", "   10    0.0100    NPTS, DT", "1 2 3 4 5\n6 7 8 9 10")
    gm = read(p, "motion")
    assert gm.npts == 10 and gm.dt == 0.01 and gm.acc[-1] == pytest.approx(10 * G_MM_S2)


@pytest.mark.parametrize("content,kwargs,match", [
    ("", {}, "holds no data lines"),
    ("1\n2\n3\n4\n5\n6\n7\n8\n9\n", {}, "units are not stated"),
    ("1\n2\n3\n4\n5\n6\n7\n8\n9\n", {"units": "g"}, "no time column and no dt"),
    ("1\n2\n3\n4\n5\n6\n7\n8\n9\n", {"units": "g", "dt": 0.0}, "dt = 0.0 s; expected a positive"),
    ("1\n2\n3\n4\n5\n6\n7\n8\n9\n", {"units": "furlongs", "dt": 0.01}, "unknown acceleration unit 'furlongs'"),
    ("1\n2\n3\n", {"units": "g", "dt": 0.01}, "record has 3 samples; expected at least 8"),
    ("1 2\n3\n", {"units": "g", "dt": 0.01}, "rows have different numbers of columns"),
    ("0 1\n0.01 2\n0.03 3\n0.04 4\n0.05 5\n0.06 6\n0.07 7\n0.08 8\n0.09 9\n", {"units": "g", "dt": 0.01},
     "first column increases like a time axis but its steps are not uniform"),
    ("0 1 2\n0.01 2 3\n0.02 3 4\n0.03 4 5\n0.04 5 6\n0.05 6 7\n0.06 7 8\n0.07 8 9\n", {"units": "g", "column": 2},
     "column 2 requested but the file has 2 acceleration column"),
])
def test_malformed_text(tmp_path, content, kwargs, match):
    p = tmp_path / "rec.txt"
    p.write_text(content)
    with pytest.raises(InputError, match=match) as err:
        read(p, "motion", **kwargs)
    assert str(err.value).startswith(str(p) + ": ") and "\n" not in str(err.value)


@pytest.mark.parametrize("content,match", [
    ("time,acc (g)\n0,1\n0.01,2\n0.03,3\n0.04,4\n0.05,5\n0.06,6\n0.07,7\n0.08,8\n", "time column is not uniformly"),
    ("time,acc (g)\n0,1\n0.01\n", "line 3 has 1 fields but the header has 2"),
    ("time,acc\n" + "".join(f"{0.01 * i},{i}\n" for i in range(10)), "units of column 'acc' are not stated"),
    ("time,acc (g)\n" + "".join(f"{0.01 * i},{'nan' if i == 5 else i}\n" for i in range(10)), "NaN or inf"),
])
def test_malformed_csv(tmp_path, content, match):
    p = tmp_path / "rec.csv"
    p.write_text(content)
    with pytest.raises(InputError, match=match) as err:
        read(p, "motion")
    assert str(err.value).startswith(str(p) + ": ")


def test_fortran_exponents_and_header_hints(tmp_path):
    at2 = _at2(tmp_path, "d.AT2", "NPTS=   10, DT=   .1D-01 SEC", "1 2 3 4 5\n6 7 8 9 1.0D+01")
    gm = read(at2, "motion")
    assert gm.dt == 0.01 and gm.acc[-1] == pytest.approx(10 * G_MM_S2)
    txt = tmp_path / "hint.txt"
    txt.write_text("% Acc. in cm/sec^2 and dt=0.5d-2 sec.\n" + "".join(f"{(-1) ** i * i} {-i}\n" for i in range(10)))
    gm = read(txt, "motion", column=1)  # two channels (no time column): dt and units from the comment
    assert gm.dt == 0.005 and gm.acc[3] == pytest.approx(-30.0)  # cm/s^2 -> mm/s^2
    units = tmp_path / "units.txt"
    units.write_text("# units: g\n" + "".join(f"{5.0 + 0.02 * i:.2f} {0.01 * i}\n" for i in range(10)))
    gm = read(units, "motion")  # a time column that starts at 5 s: the record starts at its first sample
    assert gm.dt == pytest.approx(0.02) and gm.npts == 10 and gm.acc[1] == pytest.approx(0.01 * G_MM_S2)


@pytest.mark.parametrize("row,match", [("0.05,", "line 7, column 'acc (g)': not a number"),
                                       ("0.05,0.05 00", "line 7, column 'acc (g)': not a number")])
def test_csv_fields_must_be_numbers(tmp_path, row, match):
    p = tmp_path / "rec.csv"
    p.write_text("time,acc (g)\n" + "".join(f"{0.01 * i:.2f},{0.1 * i}\n" for i in range(5)) + row + "\n")
    with pytest.raises(InputError, match=re.escape(match)) as err:
        read(p, "motion")
    assert str(err.value).startswith(str(p) + ": ")


def test_missing_and_binary_files(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read(tmp_path / "nothing.AT2", "motion")
    p = tmp_path / "noise.AT2"
    p.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(InputError, match="binary file"):
        read(p, "motion")
    with pytest.raises(InputError, match="unknown record format 'mseed'"):
        read(tmp_path / "x.AT2", "motion", format="mseed")


def test_gzipped_and_named_records(tmp_path):
    import gzip
    p = tmp_path / "RSN1.X_Y-Z180.AT2.gz"
    p.write_bytes(gzip.compress((_HEADER + "NPTS=   10, DT=   .0100 SEC\n1 2 3 4 5\n6 7 8 9 10\n").encode()))
    gm = read(p, "motion")
    assert gm.name == "RSN1.X_Y-Z180" and gm.npts == 10


@pytest.mark.parametrize("kwargs,match", [
    ({"dt": 0.0}, "dt = 0"), ({"dt": -1.0}, "dt = -1"), ({"dt": float("nan")}, "dt = nan"),
    ({"acc": np.ones((10, 2))}, "one channel"), ({"acc": [1.0, np.inf] * 5}, "NaN or inf"),
])
def test_ground_motion_validation(kwargs, match):
    args = {"dt": 0.01, "acc": np.ones(10), "source": "rec.txt"} | kwargs
    with pytest.raises(InputError, match=match) as err:
        GroundMotion(**args)
    assert str(err.value).startswith("rec.txt: ")
