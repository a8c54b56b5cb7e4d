"""The PhyCNN 6-story hotel data: what its variables are, checked on all 21 earthquakes.

The source documents neither units nor what ``input_tf`` is; these tests hold the evidence
that ``docs/data.md`` reports (input = ground displacement, targets = absolute motion of two
upper levels, one length unit for all).
"""

from __future__ import annotations

import struct
import subprocess
import sys

import numpy as np
import pytest
from io_checks import data_path, peak_transfer, transfer
from scipy import io as sio
from scipy import signal

from hlaid.errors import InputError
from hlaid.io import hotel_events, read, read_hotel
from hlaid.io._common import spectral_second_derivative

MAT = ("phycnn_6story_hotel", "data_exp.mat")


@pytest.fixture(scope="module")
def events():
    path = data_path(*MAT)
    return {e: read_hotel(path, e) for e in hotel_events(path)}


def _absolute_disp(m):
    return m.floor_disp + m.extra["ground_disp_mm"][:, None]


def test_21_events_trimmed_and_converted(events):
    assert sorted(events) == list(range(1, 22))
    raw = sio.loadmat(data_path(*MAT))
    ids = list(raw["Ind_TV"].ravel())
    e = int(ids[0])
    m = events[e]
    n = m.n_samples
    assert 2800 <= n <= 3600 and m.dt == 0.02
    assert np.all(raw["input_tf"][0, n:] == 0) and raw["input_tf"][0, n - 1] != 0     # zero padding removed
    np.testing.assert_allclose(m.floor_acc, 10 * raw["target_Xdd_tf"][0, :n])           # cm/s^2 -> mm/s^2
    np.testing.assert_allclose(m.floor_disp, 10 * (raw["target_X_tf"][0, :n] - raw["input_tf"][0, :n, None]))


def test_input_is_ground_displacement_and_targets_are_absolute(events):
    """Below the first mode an absolute displacement equals the ground's: gain 1, phase 0.

    Checked on every event whose low-frequency band is coherent (> 0.95): a ground
    *acceleration* input would give a gain that falls as f^-2 and phase 180 degrees.
    """
    checked = 0
    for e, m in events.items():
        u, x = m.extra["ground_disp_mm"], _absolute_disp(m)
        for j in range(2):
            gain, phase, coh = transfer(u, x[:, j], m.dt, 0.2, 0.5, nperseg=512)
            if coh < 0.95:
                continue
            checked += 1
            assert gain == pytest.approx(1.0, abs=0.06) and abs(phase) < 5, (e, j, gain, phase)
            # and Xdd is the absolute acceleration: it follows the ground acceleration there too
            gain, phase, _ = transfer(m.ground_acc, m.floor_acc[:, j], m.dt, 0.2, 0.5, nperseg=512)
            assert gain == pytest.approx(1.0, abs=0.06) and abs(phase) < 5, (e, j, gain, phase)
    assert checked >= 20


def test_acceleration_is_the_second_derivative_of_displacement_at_dt_0_02(events):
    corr = []
    for m in events.values():
        a = spectral_second_derivative(_absolute_disp(m), m.dt)
        corr += [np.corrcoef(a[:, j], m.floor_acc[:, j])[0, 1] for j in range(2)]
        scale = np.std(m.floor_acc, axis=0) / np.std(a, axis=0)
        # RMS ratio 1.02-1.18 (Xdd keeps some high-frequency content the displacement lacks);
        # another unit (x10) or a time step off by 2 (x4) would be far outside
        assert np.all(np.abs(scale - 1) < 0.25)
    assert min(corr) > 0.94 and np.median(corr) > 0.99


def test_first_mode_and_shape_ratio_are_the_same_in_every_event(events):
    for e, m in events.items():
        f1, gain = peak_transfer(m.ground_acc, m.floor_acc[:, 1], m.dt, 1.0, 10.0)
        assert 4.0 < f1 < 5.0 and gain > 5, (e, f1, gain)
        f, p01 = signal.csd(m.floor_disp[:, 0], m.floor_disp[:, 1], fs=1 / m.dt, nperseg=512)
        _, p00 = signal.welch(m.floor_disp[:, 0], fs=1 / m.dt, nperseg=512)
        k = int(np.argmin(np.abs(f - f1)))
        ratio = p01[k] / p00[k]
        assert 3.1 < abs(ratio) < 3.6 and abs(np.angle(ratio, deg=True)) < 10, (e, ratio)


def test_errors(tmp_path):
    path = data_path(*MAT)
    with pytest.raises(InputError, match=r"read\(path, event=N\)"):
        read(path, "measurement")
    with pytest.raises(InputError, match="no event 22"):
        read_hotel(path, 22)
    with pytest.raises(InputError, match="unknown length unit"):
        read_hotel(path, 13, units="furlong")
    bad = tmp_path / "x.mat"
    bad.write_bytes(b"MATLAB 5.0 MAT-file" + bytes(range(256)) * 3)
    with pytest.raises(InputError, match="not a readable"):
        read_hotel(bad, 1)
    other = tmp_path / "y.mat"
    sio.savemat(other, {"a": np.ones(3)})
    with pytest.raises(InputError, match="missing variable"):
        read_hotel(other, 1)


def test_damaged_type_code_is_an_error_not_a_crash(tmp_path):
    """scipy's MAT-5 reader segfaults on a bad numeric type code; hlaid checks the file first.

    Run in a child process so that a regression cannot take the test session down with it.
    """
    good = tmp_path / "good.mat"
    sio.savemat(good, {"input_tf": np.ones((2, 50))}, do_compression=False)
    raw = bytearray(good.read_bytes())
    tag = struct.pack("<II", 9, 800)                     # miDOUBLE, 2 x 50 x 8 bytes
    assert raw.count(tag) == 1
    i = raw.index(tag)
    raw[i] = 97
    bad = tmp_path / "bad.mat"
    bad.write_bytes(bytes(raw))
    code = ("import sys\nfrom hlaid.io import read_hotel\nfrom hlaid.errors import InputError\n"
            f"try:\n    read_hotel({str(bad)!r}, 1)\nexcept InputError as e:\n    print('INPUTERROR', e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-500:]
    assert "INPUTERROR" in out.stdout and "type code 97" in out.stdout
