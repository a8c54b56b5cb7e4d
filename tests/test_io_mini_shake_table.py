"""The mini shake-table (Xsens IMU) reader on the four real runs and on malformed files."""

from __future__ import annotations

import numpy as np
import pytest
from io_checks import data_path, peak_transfer, transfer

from hlaid.errors import InputError
from hlaid.io import read_mini_shake_table

FOLDER = "mini_shake_table_3story_model"
# peak |AccX - mean| ground / floor1 / floor2 / floor3 [m/s^2], from ../shared/data/README.md section 2c
README_PEAKS = {
    "flexible_3story_northridge.csv": (8.0, 15.0, 18.3, 23.8),
    "flexible_3story_sine1p5.csv": (6.6, 4.4, 5.0, 4.6),
    "stiff_3story_northridge.csv": (7.9, 15.5, 20.6, 27.4),
    "stiff_3story_sine1p5.csv": (6.8, 7.7, 7.0, 10.5),
}


@pytest.fixture(scope="module", params=sorted(README_PEAKS))
def run(request):
    path = data_path(FOLDER, request.param)
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    raw = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])    # independent parse
    return request.param, raw, read_mini_shake_table(path)


def test_timing_120hz_and_shapes(run):
    _, raw, m = run
    assert m.n_samples == raw.shape[0] and m.n_floors == 3
    assert 1 / m.dt == pytest.approx(120.0, rel=1e-3)
    assert m.dt == pytest.approx((raw[-1, 0] - raw[0, 0]) / (len(raw) - 1))
    assert not m.extra["resampled"]


def test_bias_removed_and_units_mm_s2(run):
    name, raw, m = run
    n0 = int(round(5.0 / m.dt))
    x = raw[:, [1, 3, 5, 7]]                       # ground, floor1..3 AccX [m/s^2]
    np.testing.assert_allclose(m.extra["bias_mm_s2"], 1000 * x[:n0].mean(axis=0))
    np.testing.assert_allclose(m.ground_acc, 1000 * (x[:, 0] - x[:n0, 0].mean()))
    assert np.all(np.abs(m.floor_acc[:n0].mean(axis=0)) < 1e-9)
    peaks = np.max(np.abs(np.column_stack([m.ground_acc, m.floor_acc])), axis=0) / 1000
    np.testing.assert_allclose(peaks, README_PEAKS[name], atol=0.06)


def test_every_floor_sensor_points_like_the_table_sensor(run):
    """0.3-1 Hz: the model moves with the table; a reversed sensor would show 180 degrees."""
    _, _, m = run
    for j in range(3):
        gain, phase, coh = transfer(m.ground_acc, m.floor_acc[:, j], m.dt, 0.3, 1.0, nperseg=1024)
        assert 0.9 < gain < 1.15 and abs(phase) < 10 and coh > 0.8, (j, gain, phase, coh)


def test_amplification_and_first_modes():
    flex = read_mini_shake_table(data_path(FOLDER, "flexible_3story_northridge.csv"))
    stiff = read_mini_shake_table(data_path(FOLDER, "stiff_3story_northridge.csv"))
    for m in (flex, stiff):
        assert np.abs(m.floor_acc[:, 2]).max() > 2.5 * np.abs(m.ground_acc).max()
    f_flex, g_flex = peak_transfer(flex.ground_acc, flex.floor_acc[:, 2], flex.dt, 1.0, 15.0, nperseg=1024)
    f_stiff, g_stiff = peak_transfer(stiff.ground_acc, stiff.floor_acc[:, 2], stiff.dt, 1.0, 15.0, nperseg=1024)
    assert f_flex < f_stiff and g_flex > 10 and g_stiff > 10


def test_signs_option_flips_channels():
    path = data_path(FOLDER, "stiff_3story_sine1p5.csv")
    a = read_mini_shake_table(path)
    b = read_mini_shake_table(path, signs=(1, -1, 1, -1))
    np.testing.assert_allclose(b.floor_acc[:, 0], -a.floor_acc[:, 0])
    np.testing.assert_allclose(b.floor_acc[:, 1], a.floor_acc[:, 1])


def _csv(n=1200, cols=("t_s", "ground_AccX", "ground_AccY", "floor1_AccX", "floor1_AccY")):
    t = 0.008333 * (1 + np.arange(n))
    data = np.column_stack([t] + [0.1 * np.sin(3 * t + k) for k in range(len(cols) - 1)])
    return "# header\n" + ",".join(cols) + "\n" + "\n".join(",".join(f"{v:.5f}" for v in r) for r in data) + "\n"


@pytest.mark.parametrize("text, kw, message", [
    (_csv(cols=("t_s", "base_AccX", "base_AccY", "floor1_AccX", "floor1_AccY")), {}, "ground_AccX"),
    (_csv(cols=("t_s", "ground_AccX", "ground_AccY", "floor2_AccX", "floor2_AccY")), {}, "without gaps"),
    (_csv().replace("0.0", "abc", 1), {}, "non-numeric"),
    (_csv(n=100), {}, "more than half"),
    (_csv(), {"signs": (1, 2)}, "signs"),
    (_csv(), {"axis": "W"}, "axis"),
])
def test_malformed_files_give_one_line_errors(tmp_path, text, kw, message):
    p = tmp_path / "run.csv"
    p.write_text(text)
    with pytest.raises(InputError) as err:
        read_mini_shake_table(p, **kw)
    assert "\n" not in str(err.value) and str(p) in str(err.value) and message in str(err.value)
