"""The USGS SMC reader and the building measurement on the Berkeley records (NSMP 1103, 2018)."""

from __future__ import annotations

import numpy as np
import pytest
from io_checks import STRUCT, data_path, smc_text, transfer

from hlaid.errors import InputError
from hlaid.io import read_smc, read_smc_channel, smc_measurement

FOLDER = "nsmp1103_berkeley_building_2018"
# location, azimuth, signed peak [cm/s^2], from ../shared/data/README.md section 2b
README = {
    "1103.HN2.NP.4E_a.smc": ("4th floor, east core", 171, -54.3),
    "1103.HN2.NP.4W_a.smc": ("4th floor, west core", 171, -44.7),
    "1103.HN2.NP.BE_a.smc": ("Basement, east side", 351, -42.2),
    "1103.HN2.NP.BW_a.smc": ("Basement, west core", 351, -47.0),
    "1103.HN2.NP.RC_a.smc": ("Roof, center of bldg", 171, -57.5),
    "1103.HN2.NP.RE_a.smc": ("Roof, east core", 171, -51.4),
    "1103.HN2.NP.RS_a.smc": ("Roof, SW corner", 171, 64.4),
    "1103.HN3.NP.BE_a.smc": ("Basement, east side", 261, -38.7),
    "1103.HN3.NP.BW_a.smc": ("Basement, west core", 261, -29.4),
    "1103.HN3.NP.RE_a.smc": ("Roof, east core", 261, -31.5),
    "1103.HN3.NP.RS_a.smc": ("Roof, SW corner", 81, 49.5),
    "1103.HN3.NP.RW_a.smc": ("Roof, west core", 81, 35.1),
    "1103.HNZ.NP.BE_a.smc": ("Basement, east side", None, 17.0),
    "1103.HNZ.NP.BW_a.smc": ("Basement, west core", None, 21.5),
}


@pytest.mark.parametrize("fname", sorted(README))
def test_every_channel_8200_samples_at_200sps_and_readme_peaks(fname):
    ch = read_smc_channel(data_path(FOLDER, fname))
    label, az, peak = README[fname]
    assert ch.npts == 8200 and ch.dt == pytest.approx(0.005)
    assert ch.location == label and ch.azimuth == az and ch.vertical == (az is None)
    i = int(np.argmax(np.abs(ch.acc)))
    assert ch.acc[i] / 10 == pytest.approx(peak, abs=0.051)          # mm/s^2 -> cm/s^2
    assert ch.scnl == fname.removesuffix("_a.smc")


def test_independent_parse_of_the_data_block():
    path = data_path(FOLDER, "1103.HN2.NP.RC_a.smc")
    lines = path.read_text().splitlines()
    nc = int(lines[12][70:80])                                          # integer header field 16
    vals = [float(ln[k:k + 10]) for ln in lines[27 + nc:] for k in range(0, 80, 10) if ln[k:k + 10].strip()]
    np.testing.assert_allclose(read_smc(path).acc, 10 * np.array(vals))


@pytest.fixture(scope="module")
def berkeley():
    return smc_measurement(data_path(FOLDER))


def test_building_measurement_levels_and_signs(berkeley):
    m = berkeley
    assert m.extra["levels"] == ["floor 4", "roof"] and m.extra["azimuth"] == 171.0
    files = {f: s for level in m.extra["channels"] for f, s in level}
    assert files == {"1103.HN2.NP.BE_a.smc": -1.0, "1103.HN2.NP.BW_a.smc": -1.0, "1103.HN2.NP.4E_a.smc": 1.0,
                     "1103.HN2.NP.4W_a.smc": 1.0, "1103.HN2.NP.RC_a.smc": 1.0}
    be, bw = (read_smc(data_path(FOLDER, f"1103.HN2.NP.B{s}_a.smc")).acc for s in "EW")
    np.testing.assert_allclose(m.ground_acc, -(be + bw) / 2)
    np.testing.assert_allclose(m.floor_acc[:, 1], read_smc(data_path(FOLDER, "1103.HN2.NP.RC_a.smc")).acc)


def test_alignment_by_azimuth_puts_floors_in_phase_with_the_basement(berkeley):
    """Below the first mode (1.27 Hz) the floors move with the basement: phase 0 after alignment."""
    m = berkeley
    for j in range(2):
        gain, phase, coh = transfer(m.ground_acc, m.floor_acc[:, j], m.dt, 0.2, 0.5, nperseg=4096)
        assert abs(phase) < 15 and 0.6 < gain < 1.6 and coh > 0.95, (j, gain, phase, coh)
    raw_basement = read_smc(data_path(FOLDER, "1103.HN2.NP.BW_a.smc")).acc   # azimuth 351, opposite
    _, phase, _ = transfer(raw_basement, m.floor_acc[:, 1], m.dt, 0.2, 0.5, nperseg=4096)
    assert abs(phase) > 165


def test_other_axis_and_explicit_files():
    m = smc_measurement(data_path(FOLDER), azimuth=81)
    assert m.extra["levels"] == ["roof"] and m.n_floors == 1
    _, phase, coh = transfer(m.ground_acc, m.floor_acc[:, 0], m.dt, 0.2, 0.5, nperseg=4096)
    assert abs(phase) < 15 and coh > 0.95
    two = smc_measurement([data_path(FOLDER, "1103.HN2.NP.BW_a.smc"), data_path(FOLDER, "1103.HN2.NP.RC_a.smc")])
    assert two.n_floors == 1 and two.extra["azimuth"] == 171.0


def test_written_file_round_trips(tmp_path):
    vals = np.round(np.sin(np.arange(37) * 0.3), 4)
    p = tmp_path / "a.smc"
    p.write_text(smc_text(vals))
    ch = read_smc_channel(p)
    np.testing.assert_allclose(ch.acc, 10 * vals, atol=1e-3)
    assert ch.dt == 0.01 and ch.location == "Roof, center" and ch.azimuth == 90


@pytest.mark.parametrize("edit, message", [
    (lambda s: "\n".join(s.splitlines()[:-2]) + "\n", "truncated"),
    (lambda s: s.replace("2 CORRECTED", "4 DISPLACEMENT", 1), "line 1"),
    (lambda s: s.replace("    -32768", "    -3x768", 1), "integer header"),
    (lambda s: s.replace("1.0000000E+02", "0.0000000E+00", 1), "samples per second"),
    (lambda s: "\n".join(s.splitlines()[:20]) + "\n", "lines"),
])
def test_malformed_files_give_one_line_errors(tmp_path, edit, message):
    p = tmp_path / "bad.smc"
    p.write_text(edit(smc_text(np.round(np.sin(np.arange(37) * 0.3), 4))))
    with pytest.raises(InputError) as err:
        read_smc_channel(p)
    assert "\n" not in str(err.value) and str(p) in str(err.value) and message in str(err.value)


def test_channels_on_different_time_axes_are_refused(tmp_path):
    (tmp_path / "b.smc").write_text(smc_text(np.zeros(16) + 0.5, label="Basement"))
    (tmp_path / "r.smc").write_text(smc_text(np.zeros(24) + 0.5))
    with pytest.raises(InputError, match="time axis"):
        smc_measurement(tmp_path)


def test_free_field_and_unknown_levels(tmp_path):
    (tmp_path / "b.smc").write_text(smc_text(np.zeros(16) + 50.0, label="Basement"))
    (tmp_path / "r.smc").write_text(smc_text(np.zeros(16) + 70.0, az=270))
    (tmp_path / "f.smc").write_text(smc_text(np.zeros(16) + 900.0, label="Free field, north"))
    m = smc_measurement(tmp_path)
    assert m.extra["levels"] == ["roof"] and m.extra["azimuth"] == 270.0
    np.testing.assert_allclose(m.ground_acc, -500.0)     # basement at 90 deg is negated (cm/s^2 -> mm/s^2)
    (tmp_path / "x.smc").write_text(smc_text(np.zeros(16) + 70.0, label="Parking structure"))
    with pytest.raises(InputError, match="cannot tell the level"):
        smc_measurement(tmp_path)


def test_data_folder_resolves_relative_to_the_repository():
    assert STRUCT.parts[-3:] == ("shared", "data", "structural_response")
