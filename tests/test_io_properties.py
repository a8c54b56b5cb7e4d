"""Property tests of the text readers: garbage in gives InputError (never another exception);
well-formed random files round-trip.

Covers the data readers of :mod:`hlaid.io` and the ground-motion readers of
:mod:`hlaid.motions` (AT2, text, CSV).
"""

from __future__ import annotations

import tempfile
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from io_checks import smc_text, v2_text

from hlaid.errors import InputError
from hlaid.io import (
    read_columns,
    read_csmip_channels,
    read_hotel,
    read_mini_shake_table,
    read_smc_channel,
    read_steel_frame,
)
from hlaid.io.motion import read_at2, read_csv_record, read_text_record
from hlaid.units import G_MM_S2

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
WORK = Path(tempfile.mkdtemp(prefix="hlaid-io-props-"))
(WORK / "c.yaml").write_text("file: c.csv\ntime: t\nground: {column: a, units: g}\nfloors: [{column: b, units: g}]\n")


def _write(name: str, data: bytes | str) -> Path:
    p = WORK / name
    p.write_bytes(data.encode() if isinstance(data, str) else data)
    return p


def _only_input_errors(read, path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            read(path)
        except InputError as err:
            assert "\n" not in str(err) and str(path) in str(err)


# ------------------------------------------------------------------ good files to start from
def _steel(n=1200):
    rows = ("\t".join(f"{v:.5g}" for v in (i / 256, 0.01 * np.sin(i), 0.01 * i, 0.02 * i, 0.03, 0.04))
            for i in range(n))
    return "# c\nTime\taextx\ts2\ts3\ts4\ts5\n" + "\n".join(rows) + "\n"


def _mini(n=1300):
    rows = (f"{(i + 1) * 0.008333:.5f},{np.sin(i):.5f},0.1,{np.cos(i):.5f},0.2" for i in range(n))
    return "# h\nt_s,ground_AccX,ground_AccY,floor1_AccX,floor1_AccY\n" + "\n".join(rows) + "\n"


def _cols(n=60):
    return "t,a,b\n" + "\n".join(f"{i * 0.01:.2f},{np.sin(i):.4f},{np.cos(i):.4f}" for i in range(n)) + "\n"


_VALS = np.round(np.sin(np.arange(37) * 0.3), 4)
IO_READERS = {
    "smc": ("f.smc", read_smc_channel, smc_text(_VALS)),
    "csmip": ("f.v2", read_csmip_channels, v2_text(_VALS * 100)),
    "steel-frame": ("f.tsv", lambda p: read_steel_frame(p, pre_event_s=0.5), _steel()),
    "mini-shake-table": ("f.csv", lambda p: read_mini_shake_table(p, pre_event_s=1.0), _mini()),
    "columns": ("c.csv", lambda p: read_columns(WORK / "c.yaml"), _cols()),
}
_AT2 = ("PEER NGA\nquake, station\nACCELERATION TIME SERIES IN UNITS OF G\nNPTS=   20, DT=   .0100 SEC\n"
        + "\n".join("  .1000000E-01 -.2000000E-01  .3000000E-01  .4000000E-01 -.5000000E-01" for _ in range(4)) + "\n")
_TXT = "# dt=0.01 units g\n" + "\n".join(f"{i * 0.01:.2f} {0.01 * i:.4f}" for i in range(20)) + "\n"
_CSV = "time,acc (g)\n" + "\n".join(f"{i * 0.01:.2f},{0.01 * i:.4f}" for i in range(20)) + "\n"
MOTION_READERS = {
    "at2": ("f.at2", read_at2, _AT2),
    "text": ("f.txt", lambda p: read_text_record(p), _TXT),
    "csv": ("f.csv", lambda p: read_csv_record(p), _CSV),
}

_ALPHABET = "0123456789.-+eEdD ,\n\t=|#%()[]<>xX_:"


@st.composite
def _mutated(draw, text: str):
    """A good file with a few random insertions, deletions and a possible truncation."""
    s = list(text)
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(s)))
        op = draw(st.sampled_from(["insert", "delete", "truncate"]))
        if op == "insert":
            s.insert(i, draw(st.sampled_from(_ALPHABET)))
        elif op == "delete" and s:
            del s[min(i, len(s) - 1)]
        else:
            s = s[:i]
    return "".join(s)


@pytest.mark.parametrize("kind", sorted(IO_READERS))
@SETTINGS
@given(data=st.data())
def test_io_readers_garbage_gives_input_error(kind, data):
    name, read, good = IO_READERS[kind]
    raw = data.draw(st.one_of(st.binary(max_size=600), _mutated(good)))
    _only_input_errors(read, _write(name, raw))


@pytest.mark.parametrize("kind", sorted(MOTION_READERS))
@SETTINGS
@given(data=st.data())
def test_motion_readers_garbage_gives_input_error(kind, data):
    name, read, good = MOTION_READERS[kind]
    raw = data.draw(st.one_of(st.binary(max_size=600), _mutated(good)))
    _only_input_errors(read, _write(name, raw))


@pytest.mark.parametrize("read, name, text", [
    (read_at2, "d.at2", _AT2.replace("DT=   .0100", "DT=   .01D00")),          # Fortran exponent in DT
    (read_text_record, "d.txt", _TXT.replace("dt=0.01", "dt=0.1d-1")),                # ... in a dt= hint
    (read_csv_record, "e.csv", _CSV + "0.20,\n"),                                     # empty last field
    (read_csv_record, "s.csv", _CSV.replace("0.05,0.0500", "0.05,0.05 00")),          # blank inside a field
], ids=["at2-D-exponent", "text-d-exponent", "csv-empty-field", "csv-space-in-field"])
def test_motion_reader_cases_found_by_fuzzing(read, name, text):
    """Each of these once raised a bare ValueError from deep inside hlaid.motions."""
    _only_input_errors(read, _write(name, text))


@SETTINGS
@given(raw=st.binary(max_size=400))
def test_archives_and_mat_files_garbage(raw):
    _only_input_errors(read_csmip_channels, _write("g.zip", b"PK\x03\x04" + raw))
    _only_input_errors(lambda p: read_hotel(p, 1), _write("g.mat", b"MATLAB 5.0 MAT-file" + raw))


# ------------------------------------------------------------------ round trips
_acc = st.lists(st.floats(-2.0, 2.0, allow_nan=False), min_size=20, max_size=120)
_dt = st.sampled_from([0.005, 0.01, 0.02])


@SETTINGS
@given(acc=_acc, dt=_dt)
def test_motion_formats_round_trip(acc, dt):
    a = np.array(acc)
    if np.abs(a).max() == 0:
        a[0] = 0.5
    body = "\n".join(" ".join(f"{v:15.7E}" for v in a[i:i + 5]) for i in range(0, len(a), 5))
    m = read_at2(_write("r.at2", f"PEER\nx\nACCELERATION TIME SERIES IN UNITS OF G\nNPTS= {len(a)}, DT= {dt} SEC\n"
                                  f"{body}\n"))
    np.testing.assert_allclose(m.acc, a * G_MM_S2, rtol=1e-6, atol=1e-6)
    assert m.dt == dt
    t = np.arange(len(a)) * dt
    m = read_text_record(_write("r.txt", "\n".join(f"{ti:.6f} {v:.8e}" for ti, v in zip(t, a))), units="m/s^2")
    np.testing.assert_allclose(m.acc, a * 1000, rtol=1e-7)
    assert m.dt == pytest.approx(dt)
    m = read_csv_record(_write("r.csv", "time,acc (cm/s^2)\n" + "\n".join(f"{ti:.6f},{v:.8e}" for ti, v in zip(t, a))))
    np.testing.assert_allclose(m.acc, a * 10, rtol=1e-7)


@SETTINGS
@given(acc=_acc, rate=st.sampled_from([50.0, 100.0, 200.0]), az=st.integers(0, 359))
def test_smc_round_trip(acc, rate, az):
    a = np.round(np.array(acc) * 50, 3)
    ch = read_smc_channel(_write("r.smc", smc_text(a, rate=rate, az=az)))
    np.testing.assert_allclose(ch.acc, 10 * a, rtol=5e-5, atol=1e-6)
    assert ch.dt == pytest.approx(1 / rate) and ch.azimuth == az and ch.npts == len(a)


@SETTINGS
@given(acc=_acc, dt=_dt)
def test_csmip_round_trip_plain_and_zipped(acc, dt):
    a = np.round(np.array(acc) * 300, 3)
    text = v2_text(a, dt=dt)
    (c,) = read_csmip_channels(_write("r.v2", text))
    np.testing.assert_allclose(c.acc, 10 * a, atol=1e-9)
    assert c.dt == dt and c.npts == len(a)
    inner = WORK / "inner.zip"
    with zipfile.ZipFile(inner, "w") as zf:
        zf.writestr("CHAN7.V2", text)
    outer = WORK / "outer.zip"
    with zipfile.ZipFile(outer, "w") as zf:
        zf.write(inner, "Structure.zip")
    (z,) = read_csmip_channels(outer)
    assert z.key == "Structure.zip/CHAN7.V2"
    np.testing.assert_allclose(z.acc, c.acc)


@SETTINGS
@given(n_floors=st.integers(1, 4), seed=st.integers(0, 2**16), bias=st.floats(-0.3, 0.3))
def test_mini_shake_table_round_trip(n_floors, seed, bias):
    rng = np.random.default_rng(seed)
    n = 400
    x = np.round(rng.normal(0, 2, (n, 1 + n_floors)), 5)
    x[:60] = 0.0
    x = x + bias
    names = ["t_s"] + [f"{lv}_Acc{ax}" for lv in ["ground"] + [f"floor{k}" for k in range(1, n_floors + 1)]
                       for ax in "XY"]
    rows = [[(i + 1) * 0.008333] + [v for v in x[i] for _ in "XY"] for i in range(n)]
    text = "# t\n" + ",".join(names) + "\n" + "\n".join(",".join(f"{v:.6f}" for v in r) for r in rows) + "\n"
    m = read_mini_shake_table(_write("m.csv", text), pre_event_s=0.5)
    np.testing.assert_allclose(m.ground_acc, 1000 * (x[:, 0] - bias), atol=1e-6)
    np.testing.assert_allclose(m.floor_acc, 1000 * (x[:, 1:] - bias), atol=1e-6)
    assert m.n_floors == n_floors


@SETTINGS
@given(seed=st.integers(0, 2**16), n_floors=st.integers(1, 3))
def test_steel_frame_round_trip(seed, n_floors):
    rng = np.random.default_rng(seed)
    n = 700
    t = np.arange(n) / 256
    table = np.round(rng.normal(0, 0.1, n), 6)
    disp = np.round(np.cumsum(rng.normal(0, 0.01, (n, 1 + n_floors)), axis=0), 6)
    names = ["Time", "aextx"] + [f"s{k}" for k in range(2, 3 + n_floors)]
    data = np.column_stack([np.round(t, 4), table, disp])
    text = "\t".join(names) + "\n" + "\n".join("\t".join(repr(float(v)) for v in r) for r in data) + "\n"
    m = read_steel_frame(_write("s.tsv", text), zero_start=False, lowpass_hz=None)
    np.testing.assert_allclose(m.ground_acc, table * G_MM_S2)
    np.testing.assert_allclose(m.floor_disp, (disp[:, 1:] - disp[:, :1]) * 25.4, atol=1e-9)
    assert m.dt == pytest.approx(1 / 256, rel=1e-4) and m.n_floors == n_floors
