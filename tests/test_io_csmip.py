"""The CSMIP V2 reader on the Painter Street Overpass archive (Petrolia 1992) and on written files."""

from __future__ import annotations

import re
import zipfile

import numpy as np
import pytest
from io_checks import data_path, transfer, v2_text

from hlaid.errors import InputError
from hlaid.io import csmip_measurement, read_csmip, read_csmip_channels

ARCHIVE = ("painter_street_overpass_petrolia1992", "petrolia_25apr1992_ce89324p.zip")


@pytest.fixture(scope="module")
def channels():
    return read_csmip_channels(data_path(*ARCHIVE))


def test_archive_read_in_memory_without_extracting(monkeypatch, tmp_path):
    def refuse(*a, **k):
        raise AssertionError("the reader must not extract to disk")
    monkeypatch.setattr(zipfile.ZipFile, "extract", refuse)
    monkeypatch.setattr(zipfile.ZipFile, "extractall", refuse)
    monkeypatch.chdir(tmp_path)
    chans = read_csmip_channels(data_path(*ARCHIVE))
    assert len(chans) == 23 and list(tmp_path.iterdir()) == []
    assert {c.key.split("/")[0] for c in chans} == {"Structure.zip", "Free Field.zip"}


def test_every_channel_3000_points_at_0_02s_and_header_peaks(channels):
    for c in channels:
        assert c.npts == 3000 and c.dt == 0.02, c.describe()
        line = next(ln for ln in c.header if "PEAK ACCELERATION" in ln)
        peak = float(re.search(r"=\s*([-\d.]+)", line).group(1))           # cm/s^2, printed in the header
        i = int(np.argmax(np.abs(c.acc)))
        assert c.acc[i] / 10 == pytest.approx(peak, abs=0.001), c.describe()


def test_free_field_pga_538(channels):
    g = read_csmip(data_path(*ARCHIVE), "Free Field.zip/CHAN014.V2")
    assert g.pga / 10 == pytest.approx(538.5, abs=0.1) and g.npts == 3000 and g.dt == 0.02
    ff = [c for c in channels if c.location == "FREE FIELD" and c.azimuth is not None]
    assert max(np.abs(c.acc).max() for c in ff) / 10 == pytest.approx(538.5, abs=0.1)


def test_ambiguous_and_unknown_channels(channels):
    path = data_path(*ARCHIVE)
    with pytest.raises(InputError, match="ambiguous"):
        read_csmip(path, 14)                      # the free field is in both inner archives
    with pytest.raises(InputError, match="no channel 99"):
        read_csmip(path, 99)
    with pytest.raises(InputError, match="channel="):
        read_csmip(path)


def test_bridge_measurement_transverse(channels):
    """Base of the centre bent (ch 3) -> girder at the centre bent (ch 7), both 360 deg."""
    m = csmip_measurement(data_path(*ARCHIVE), ground=3, floors=[7])
    assert m.extra["signs"] == [1.0] and m.n_floors == 1
    gain, phase, coh = transfer(m.ground_acc, m.floor_acc[:, 0], m.dt, 0.3, 1.0, nperseg=512)
    assert abs(phase) < 15 and 0.8 < gain < 1.3 and coh > 0.9
    with pytest.raises(InputError, match="not along"):
        csmip_measurement(data_path(*ARCHIVE), ground=3, floors=[11])     # 270 deg is the other axis


def test_written_v2_round_trips_and_opposite_azimuth_is_negated(tmp_path):
    rng = np.random.default_rng(3)
    a, b = np.round(rng.normal(0, 50, 43), 3), np.round(rng.normal(0, 50, 43), 3)
    p = tmp_path / "two.v2"
    p.write_text(v2_text(a, az="90 DEG", sta=1, loc="GROUND") + v2_text(b, az="270 DEG", sta=2))
    chans = read_csmip_channels(p)
    assert [c.station_channel for c in chans] == [1, 2]
    np.testing.assert_allclose(chans[0].acc, 10 * a)
    m = csmip_measurement(p, ground=1, floors=[2])
    np.testing.assert_allclose(m.floor_acc[:, 0], -10 * b)
    assert m.extra["signs"] == [-1.0]


@pytest.mark.parametrize("edit, message", [
    (lambda s: "\n".join(s.splitlines()[:-5]) + "\n", "truncated"),
    (lambda s: s.replace("CORRECTED ACCELEROGRAM   TEST", "SOMETHING ELSE"), "line 1"),
    (lambda s: s.replace("(STA CHN:", "(STATION"), "STA CHN"),
    (lambda s: s.replace("POINTS OF ACCEL", "POINTS OF ACCELERATION VALUES"), "POINTS OF ACCEL"),
    (lambda s: _spoil_first_value(s), "expected a number"),
])
def test_malformed_v2_gives_one_line_errors(tmp_path, edit, message):
    p = tmp_path / "bad.v2"
    p.write_text(edit(v2_text(np.round(np.sin(np.arange(43)), 3) * 100)))
    with pytest.raises(InputError) as err:
        read_csmip_channels(p)
    assert "\n" not in str(err.value) and str(p) in str(err.value) and message in str(err.value)


def _spoil_first_value(text: str) -> str:
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if "POINTS OF ACCEL" in ln) + 1
    lines[i] = "   1.0x000" + lines[i][10:]
    return "\n".join(lines) + "\n"


def test_broken_and_empty_archives(tmp_path):
    p = tmp_path / "x.zip"
    p.write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(InputError, match="zip"):
        read_csmip_channels(p)
    q = tmp_path / "empty.zip"
    with zipfile.ZipFile(q, "w") as zf:
        zf.writestr("readme.txt", "nothing")
    with pytest.raises(InputError, match="no .V2"):
        read_csmip_channels(q)
