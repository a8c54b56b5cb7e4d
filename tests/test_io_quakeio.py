"""hlaid's record readers against quakeio, the field's ground-motion parser (an optional test
dependency): every PEER AT2, COSMOS/SMC and CSMIP (zipped V2) file of ../shared/data and of the
package gives the same samples, time step and units.

Where quakeio 0.1.21 is wrong the test checks hlaid against what is right and pins quakeio's fault:

* AT2: quakeio reads the data with ``skip_footer=1`` and so drops the last data line; the file's
  ``NPTS`` header is right (hlaid returns NPTS samples; quakeio's are its first ones, all equal);
* AT2 gzipped (the package's records): quakeio cannot open them; they are compared unzipped;
* SMC: ``quakeio.parse.smc.read_series`` fails (``str.decode`` under Python 3); its parser
  ``_read_smc`` underneath is compared (samples in cm/s^2, rate in the real header);
* CSMIP zip of zips (an event holding ``Structure.zip`` and ``Free Field.zip``): quakeio's
  ``read_event`` finds no V2 file at the top and fails; each inner archive is compared.
"""

from __future__ import annotations

import gzip
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA, import_optional, requires_data

from hlaid.io.csmip import read_csmip_channels
from hlaid.io.motion import read_at2
from hlaid.io.smc import read_smc_channel
from hlaid.units import G_MM_S2

quakeio = import_optional("quakeio", "pip install --no-deps quakeio==0.1.21")

PACKAGE_RECORDS = Path(__file__).resolve().parents[1] / "hlaid" / "data" / "records"


def _files(pattern: str) -> list[Path]:
    return sorted(p for p in DATA.rglob(pattern) if p.is_file())


def _same(hlaid_acc: np.ndarray, other: np.ndarray) -> None:
    """Equal to the last digit the files hold (both parse the same decimal text)."""
    np.testing.assert_allclose(hlaid_acc, other, rtol=1e-12, atol=1e-12 * np.abs(other).max())


def _at2_vs_quakeio(path: Path, text: str, tmp: Path) -> None:
    plain = tmp / path.name.removesuffix(".gz")
    plain.write_text(text)
    q = quakeio.read(str(plain), "nga.at2")
    assert q["units"] == "g"
    h = read_at2(path)
    npts = int(re.search(r"NPTS\s*=\s*(\d+)", text.splitlines()[3]).group(1))
    last = len([v for v in text.strip().splitlines()[-1].split() if v])
    qa = np.asarray(q.data, dtype=float) * G_MM_S2
    assert h.npts == npts, "hlaid returns the header's NPTS samples"
    assert qa.size == npts - last, "quakeio drops the last data line (skip_footer=1)"
    assert h.dt == pytest.approx(float(q["time_step"]), rel=1e-12)
    _same(h.acc[:qa.size], qa)


@requires_data
def test_at2_of_the_shared_data_equal_quakeio(tmp_path):
    files = _files("*.AT2")
    assert len(files) >= 50
    for p in files:
        _at2_vs_quakeio(p, p.read_text(), tmp_path)


def test_gzipped_at2_of_the_package_equal_quakeio(tmp_path):
    files = sorted(PACKAGE_RECORDS.glob("*.AT2.gz"))
    assert len(files) >= 10
    for p in files:
        _at2_vs_quakeio(p, gzip.decompress(p.read_bytes()).decode(), tmp_path)


@requires_data
def test_smc_of_the_shared_data_equal_quakeio():
    from quakeio.parse import smc as qsmc

    files = _files("*.smc")
    assert len(files) >= 10
    for p in files:
        txt, ihdr, rhdr, _, data = qsmc._read_smc(str(p))
        h = read_smc_channel(p)
        assert h.dt == pytest.approx(1.0 / float(rhdr[1]), rel=1e-12)
        assert h.acc.size == int(ihdr[16]) == data.size
        _same(h.acc, np.asarray(data, dtype=float) * 10.0)  # SMC: cm/s^2


@requires_data
def test_csmip_zipped_event_equals_quakeio(tmp_path):
    files = _files("*.zip")
    assert files
    n = 0
    for p in files:
        chans = {(c.key.split("/")[0], c.station_channel): c for c in read_csmip_channels(p)}
        with zipfile.ZipFile(p) as z:
            inner = [m for m in z.namelist() if m.lower().endswith(".zip")]
            assert inner, "an event archive of station archives"
            for m in inner:
                (tmp_path / m).write_bytes(z.read(m))
                ev = quakeio.read(str(tmp_path / m), "csmip.zip")
                for motion in ev.motions.values():
                    for comp in motion.components.values():
                        a = comp.accel
                        assert a["units"].lower() in ("cm/sec/sec", "cm/s/s")
                        h = chans[(m, int(comp["station_channel"]))]
                        assert h.dt == pytest.approx(float(a["time_step"]), rel=1e-12)
                        assert h.npts == len(a.data)
                        _same(h.acc, np.asarray(a.data, dtype=float) * 10.0)
                        n += 1
        assert n == len(chans), "every channel hlaid reads is one quakeio reads"

