"""Station data through ObsPy (miniSEED, SAC) mapped onto floors: a simulated
measurement written with ObsPy and read back through the mapping gives the same accelerations;
a bad mapping is one line naming the file and the channel."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import import_optional

obspy = import_optional("obspy")

from hlaid.errors import InputError  # noqa: E402
from hlaid.io import read  # noqa: E402
from hlaid.io.station import StationChannel, StationConfig, read_station  # noqa: E402
from hlaid.synthetic import simulate_measurement  # noqa: E402
from hlaid.units import G_MM_S2  # noqa: E402

T0 = obspy.UTCDateTime(2026, 11, 24, 10, 0, 0)
IDS = ["XX.B001.00.HNE", "XX.B001.01.HNE", "XX.B001.02.HNE", "XX.B001.03.HNE"]


@pytest.fixture(scope="module")
def meas(table1, records):
    return simulate_measurement(table1, records["elcentro-1940-ns"], noise_rms=0.05, seed=3)


def _traces(meas, *, scale, dtype, shift_s=(0, 0, 0, 0)):
    """One trace per channel (ground first), samples = acceleration [mm/s^2] * scale."""
    cols = np.column_stack([meas.ground_acc, meas.floor_acc])
    out = []
    for j, sid in enumerate(IDS):
        net, sta, loc, cha = sid.split(".")
        k = int(round(shift_s[j] / meas.dt))
        data = (cols[k:, j] * scale).astype(dtype) if dtype != np.int32 else np.round(cols[k:, j] * scale).astype(dtype)
        out.append(obspy.Trace(data=data, header={"network": net, "station": sta, "location": loc, "channel": cha,
                                                  "sampling_rate": 1.0 / meas.dt, "starttime": T0 + k * meas.dt}))
    return out


def _config(files, *, units="m/s^2", gain=1.0, offset="none", floors=IDS[1:], **kw):
    return StationConfig(files=[str(f) for f in files], ground=StationChannel(channel=IDS[0], units=units, gain=gain),
                         floors=[StationChannel(channel=c, units=units, gain=gain) for c in floors], offset=offset,
                         **kw)


def test_miniseed_round_trip_float64(meas, tmp_path):
    f = tmp_path / "b001.mseed"
    obspy.Stream(_traces(meas, scale=1e-3, dtype=np.float64)).write(str(f), format="MSEED", encoding="FLOAT64")
    got = read_station(_config([f]), mass_t=meas.mass, height_mm=[3000.0] * 3)
    assert got.dt == pytest.approx(meas.dt, rel=1e-12) and got.n_samples == meas.n_samples
    np.testing.assert_allclose(got.ground_acc, meas.ground_acc, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(got.floor_acc, meas.floor_acc, rtol=1e-12, atol=1e-9)
    assert list(got.mass) == list(meas.mass) and got.extra["channels"] == IDS


def test_miniseed_counts_with_gain_and_mean_offset(meas, tmp_path):
    """Integer counts (STEIM2) with 1e5 counts per g: values back to the quantisation step."""
    gain = 1e5
    f = tmp_path / "counts.mseed"
    obspy.Stream(_traces(meas, scale=gain / G_MM_S2, dtype=np.int32)).write(str(f), format="MSEED", encoding="STEIM2")
    got = read_station(_config([f], units="g", gain=gain, offset="mean"))
    step = G_MM_S2 / gain
    cols = np.column_stack([meas.ground_acc, meas.floor_acc])
    want = cols - cols.mean(axis=0)  # the mean offset removed, as configured
    have = np.column_stack([got.ground_acc, got.floor_acc])
    assert np.abs(have - want).max() <= step  # half a step of rounding plus the mean's rounding


def test_sac_one_file_per_channel_and_a_late_channel(meas, tmp_path):
    """SAC (float32), the top floor starting 0.5 s later: the common window, aligned."""
    files = []
    for tr in _traces(meas, scale=1.0, dtype=np.float32, shift_s=(0, 0, 0, 0.5)):
        files.append(tmp_path / f"{tr.id}.sac")
        tr.write(str(files[-1]), format="SAC")
    got = read_station(_config(files, units="mm/s^2"))
    k = int(round(0.5 / meas.dt))
    assert got.n_samples == meas.n_samples - k
    np.testing.assert_allclose(got.ground_acc, meas.ground_acc[k:], rtol=1e-6, atol=1e-3)
    np.testing.assert_allclose(got.floor_acc, meas.floor_acc[k:], rtol=1e-6, atol=1e-3)


def test_yaml_mapping_through_read(meas, tmp_path):
    f = tmp_path / "b001.mseed"
    obspy.Stream(_traces(meas, scale=1e-3, dtype=np.float64)).write(str(f), format="MSEED", encoding="FLOAT64")
    (tmp_path / "b001.yaml").write_text(
        "files: [b001.mseed]\nground: {channel: '*.B001.00.HN?', units: m/s^2}\n"
        "floors:\n  - {channel: XX.B001.01.HNE}\n  - {channel: XX.B001.02.HNE}\n  - {channel: XX.B001.03.HNE}\n"
        "offset: none\nheight_mm: [3000, 3000, 3000]\n")
    got = read(tmp_path / "b001.yaml", "measurement", format="station")
    np.testing.assert_allclose(got.floor_acc, meas.floor_acc, rtol=1e-12, atol=1e-9)
    assert list(got.height) == [3000.0] * 3


@pytest.mark.parametrize("change, match", [
    ({"floors": IDS[1:3] + ["XX.B001.09.HNE"]}, "floors\\[2\\]: channel 'XX.B001.09.HNE' is not in the file"),
    ({"floors": ["XX.B001.0?.HNE"]}, "floors\\[0\\]: channel 'XX.B001.0\\?.HNE' matches 4 channels"),
])
def test_bad_mapping_names_file_and_channel(meas, tmp_path, change, match):
    f = tmp_path / "b001.mseed"
    obspy.Stream(_traces(meas, scale=1e-3, dtype=np.float64)).write(str(f), format="MSEED", encoding="FLOAT64")
    with pytest.raises(InputError, match=match) as e:
        read_station(_config([f], **change))
    assert str(e.value).startswith(str(f)) and "\n" not in str(e.value)


def test_other_rate_gap_and_unreadable_file(meas, tmp_path):
    trs = _traces(meas, scale=1e-3, dtype=np.float64)
    trs[2].stats.sampling_rate = 100.0
    f = tmp_path / "rate.mseed"
    obspy.Stream(trs).write(str(f), format="MSEED", encoding="FLOAT64")
    with pytest.raises(InputError, match=f"{f}: floors\\[1\\]: channel XX.B001.02.HNE is sampled at 100 Hz"):
        read_station(_config([f]))
    trs = _traces(meas, scale=1e-3, dtype=np.float64)
    a, b = trs[1].copy(), trs[1].copy()
    a.trim(T0, T0 + 5)
    b.trim(T0 + 6, None)
    g = tmp_path / "gap.mseed"
    obspy.Stream([trs[0], a, b, trs[2], trs[3]]).write(str(g), format="MSEED", encoding="FLOAT64")
    with pytest.raises(InputError, match="floors\\[0\\]: channel XX.B001.01.HNE has a gap"):
        read_station(_config([g]))
    bad = tmp_path / "bad.mseed"
    bad.write_text("not seismic data\n")
    with pytest.raises(InputError, match=f"{bad}: ObsPy cannot read it"):
        read_station(_config([bad]))


def test_config_errors_are_one_line(tmp_path):
    (tmp_path / "s.yaml").write_text("files: [a.mseed]\nground: {channel: X, units: furlongs}\nfloors: []\n")
    with pytest.raises(InputError, match=r"s.yaml:2: ground: .*unknown acceleration unit 'furlongs'"):
        read_station(tmp_path / "s.yaml")
    (tmp_path / "s.yaml").write_text("files: [a.mseed]\nground: {channel: X}\nfloors: [{channel: Y, gian: 2}]\n")
    with pytest.raises(InputError, match=r"s.yaml:3: unknown key 'floors\[0\].gian'"):
        read_station(tmp_path / "s.yaml")


def test_a_fleet_building_from_station_data(meas, tmp_path):
    """The fleet config's ``station:`` block reads the same measurement (masses from the building)."""
    from hlaid.fleet import load_fleet_config, make_jobs
    from hlaid.fleet.task import load_unit_measurement
    f = tmp_path / "b001.mseed"
    obspy.Stream(_traces(meas, scale=1e-3, dtype=np.float64)).write(str(f), format="MSEED", encoding="FLOAT64")
    (tmp_path / "fleet.yaml").write_text(
        "records: builtin-suite\nbuildings:\n  - name: B001\n    mass_t: [17.5, 17.5, 9.2]\n"
        "    measurements:\n      ev1:\n        station:\n          files: [b001.mseed]\n          offset: none\n"
        f"          ground: {{channel: {IDS[0]}}}\n          floors:\n"
        + "".join(f"            - {{channel: {c}}}\n" for c in IDS[1:]))
    cfg = load_fleet_config(tmp_path / "fleet.yaml")
    job, = make_jobs(cfg, tmp_path, "records-sha", "fake")
    got = load_unit_measurement(job)
    np.testing.assert_allclose(got.floor_acc, meas.floor_acc, rtol=1e-12, atol=1e-9)
    assert list(got.mass) == [17.5, 17.5, 9.2]
    # the digest covers the station file's contents
    f.write_bytes(f.read_bytes()[:-512])
    job2, = make_jobs(cfg, tmp_path, "records-sha", "fake")
    assert job2.digest != job.digest


def test_a_bare_station_file_asks_for_the_mapping(tmp_path):
    f = tmp_path / "b001.mseed"
    f.write_bytes(b"\0" * 512)
    with pytest.raises(InputError, match=f"{f}: is seismic station data .*format 'station'"):
        read(f, "measurement")
