"""The steel moment-frame shake-table reader on the four real runs and on malformed files."""

from __future__ import annotations

import gzip

import numpy as np
import pytest
from io_checks import bandpass, data_path, integrate_twice_fft, transfer

from hlaid.errors import InputError
from hlaid.io import read_steel_frame
from hlaid.units import G_MM_S2, INCH_MM

RUNS = [f"filtered_fbgm152s{s}_denoised.tsv.gz" for s in (1, 2, 3, 4)]
FOLDER = "shake_table_3story_steel_mrf_fixedbase"


@pytest.fixture(scope="module", params=RUNS)
def run(request):
    path = data_path(FOLDER, request.param)
    raw = np.loadtxt(path, comments="#", skiprows=2)  # independent parse: Time aextx s2 s3 s4 s5 ...
    assert gzip.open(path, "rt").read(2000).splitlines()[1].split("\t")[:6] == ["Time", "aextx", "s2", "s3", "s4", "s5"]
    return path, raw, read_steel_frame(path)


def test_shapes_units_and_uniform_256hz(run):
    path, raw, m = run
    assert m.n_samples == raw.shape[0] and m.n_floors == 3
    assert m.dt == pytest.approx(1 / 256, rel=1e-5)
    # the stamps are i/256 rounded to 0.1 ms, so no interpolation is needed
    assert np.max(np.abs(raw[:, 0] - raw[0, 0] - np.arange(len(raw)) / 256)) <= 5.1e-5
    assert not m.extra["resampled"]
    np.testing.assert_allclose(m.ground_acc, raw[:, 1] * G_MM_S2)
    assert m.mass is None and m.source == str(path)


def test_floor_disp_is_relative_to_the_table(run):
    _, raw, m = run
    rel = (raw[:, 3:6] - raw[:, 2:3]) * INCH_MM
    np.testing.assert_allclose(m.floor_disp + m.extra["initial_offset_mm"], rel, atol=1e-9)
    n0 = int(round(2.0 / m.dt))
    assert np.all(np.abs(m.floor_disp[:n0].mean(axis=0)) < 1e-9)   # starts from rest
    np.testing.assert_allclose(m.extra["table_disp_mm"], raw[:, 2] * INCH_MM)


def test_s2_is_the_table_double_integrated_acceleration_matches(run):
    """s2 [in] against the double integral of aextx [g], band 0.2-10 Hz: same motion, same units."""
    _, _, m = run
    x_acc = bandpass(integrate_twice_fft(m.ground_acc, m.dt), m.dt, 0.2, 10.0)
    x_lvdt = bandpass(m.extra["table_disp_mm"], m.dt, 0.2, 10.0)
    assert np.corrcoef(x_acc, x_lvdt)[0, 1] > 0.99
    assert np.std(x_lvdt) / np.std(x_acc) == pytest.approx(1.0, abs=0.05)


def test_floors_are_ordered_bottom_to_top(run):
    _, _, m = run
    peaks = np.max(np.abs(m.floor_disp), axis=0)
    assert peaks[0] < peaks[1] < peaks[2]
    # relative motion grows up the frame in the first mode too (1-1.5 Hz)
    gains = [transfer(m.ground_acc, m.floor_acc[:, j] - m.ground_acc, m.dt, 1.0, 1.5)[0] for j in range(3)]
    assert gains[0] < gains[1] < gains[2]


def test_derived_floor_acceleration_is_absolute(run):
    """Well below the first mode (about 1.2 Hz) an absolute floor acceleration follows the table.

    Gain about 1 (up to 1.4 from the first mode's amplification and the drift ratcheting of the
    yielding runs) and phase near 0; a sign error would give 180 degrees, a unit error a gain
    of 25.
    """
    _, _, m = run
    for j in range(3):
        gain, phase, coh = transfer(m.ground_acc, m.floor_acc[:, j], m.dt, 0.25, 0.5, nperseg=4096)
        assert 0.9 < gain < 1.5 and abs(phase) < 25 and coh > 0.95, (j, gain, phase, coh)
    # and the derivative of the table displacement reproduces the accelerometer up to 8 Hz
    from hlaid.io._common import second_derivative
    from hlaid.signal import lowpass
    a_table = second_derivative(lowpass(m.extra["table_disp_mm"], m.dt, 10.0), m.dt)
    gain, phase, coh = transfer(m.ground_acc, a_table, m.dt, 0.5, 8.0)
    assert gain == pytest.approx(1.0, abs=0.1) and abs(phase) < 10 and coh > 0.95


def _write(tmp_path, text, name="run.tsv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _good(n=64):
    t = np.arange(n) / 256
    rows = "\n".join("\t".join(f"{v:.6g}" for v in (ti, 0.01 * np.sin(9 * ti), 0.0, 0.1 * np.sin(ti), 0.2, 0.3))
                     for ti in t)
    return "# test\nTime\taextx\ts2\ts3\ts4\ts5\n" + rows + "\n"


def test_good_synthetic_file_reads(tmp_path):
    m = read_steel_frame(_write(tmp_path, _good()), pre_event_s=0.05, lowpass_hz=None)
    assert m.n_floors == 3 and m.dt == pytest.approx(1 / 256, rel=1e-5)


@pytest.mark.parametrize("mutate, message", [
    (lambda s: s.replace("aextx", "accel"), "aextx"),
    (lambda s: s.replace("\ts3\ts4\ts5", "\tx3\tx4\tx5"), "floor column"),
    (lambda s: s.replace("0.1", "0.1x", 1), "non-numeric"),
    (lambda s: s[: s.rfind("\t")], "fields"),
    (lambda s: "# only a comment\n", "no data"),
])
def test_malformed_files_give_one_line_errors(tmp_path, mutate, message):
    p = _write(tmp_path, mutate(_good()))
    with pytest.raises(InputError) as err:
        read_steel_frame(p, pre_event_s=0.05, lowpass_hz=None)
    text = str(err.value)
    assert "\n" not in text and str(p) in text and message in text


def test_time_going_backwards_and_truncated_gzip(tmp_path):
    lines = _good().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    with pytest.raises(InputError, match="does not increase"):
        read_steel_frame(_write(tmp_path, "\n".join(lines)), pre_event_s=0.05)
    gz = tmp_path / "cut.tsv.gz"
    gz.write_bytes(gzip.compress(_good().encode())[:-20])
    with pytest.raises(InputError, match="cannot read"):
        read_steel_frame(gz)
