"""Helpers of the data-reader tests (``test_io_*.py``): data paths and signal checks.

The checks are written here with numpy/scipy only, independently of hlaid's readers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import DATA, skip_or_fail
from scipy import signal

STRUCT = DATA / "structural_response"


def data_path(*parts: str) -> Path:
    """A path under ``../shared/data/structural_response``; skips the test when it is absent
    (fails under ``CI=true``)."""
    p = STRUCT.joinpath(*parts)
    if not p.exists():
        skip_or_fail(f"shared data not available: {p}")
    return p


def transfer(x: np.ndarray, y: np.ndarray, dt: float, lo: float, hi: float, nperseg: int = 2048
             ) -> tuple[float, float, float]:
    """Mean gain, phase [deg] and coherence of the transfer function y/x over [lo, hi] Hz (Welch)."""
    fs = 1.0 / dt
    n = min(nperseg, len(x))
    f, pxy = signal.csd(x, y, fs=fs, nperseg=n)
    _, pxx = signal.welch(x, fs=fs, nperseg=n)
    _, coh = signal.coherence(x, y, fs=fs, nperseg=n)
    band = (f >= lo) & (f <= hi)
    h = pxy[band] / pxx[band]
    return float(np.mean(np.abs(h))), float(np.degrees(np.angle(np.mean(h)))), float(np.mean(coh[band]))


def peak_transfer(x: np.ndarray, y: np.ndarray, dt: float, lo: float, hi: float, nperseg: int = 512
                  ) -> tuple[float, float]:
    """(frequency [Hz], gain) of the largest |y/x| between lo and hi Hz."""
    fs = 1.0 / dt
    f, pxy = signal.csd(x, y, fs=fs, nperseg=nperseg)
    _, pxx = signal.welch(x, fs=fs, nperseg=nperseg)
    band = (f >= lo) & (f <= hi)
    h = np.abs(pxy[band] / pxx[band])
    k = int(np.argmax(h))
    return float(f[band][k]), float(h[k])


def bandpass(x: np.ndarray, dt: float, lo: float, hi: float) -> np.ndarray:
    sos = signal.butter(4, [lo, hi], btype="band", fs=1.0 / dt, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0)


def integrate_twice_fft(a: np.ndarray, dt: float) -> np.ndarray:
    """Displacement from acceleration by division by -(2 pi f)^2 (mean removed)."""
    n = len(a)
    spec = np.fft.rfft(a - a.mean())
    w = 2 * np.pi * np.fft.rfftfreq(n, dt)
    w[0] = np.inf
    return np.fft.irfft(-spec / w**2, n)


def smc_text(values, *, rate=100.0, npts=None, az=90, label="Roof, center", kind="2 CORRECTED ACCELEROGRAM"):
    """A minimal SMC file written from the layout in hlaid/io/smc.py's docstring."""
    npts = len(values) if npts is None else npts
    text = [kind, "*", "TEST", "  2020", "Mag", "station = TEST  component= 90", "x", "y", "*", "*", "*"]
    ints = [-32768] * 48
    ints[12], ints[13], ints[15], ints[16] = 90, az, 2, npts
    reals = [1.7e38] * 50
    reals[1] = rate
    lines = text + ["".join(f"{v:10d}" for v in ints[i:i + 8]) for i in range(0, 48, 8)]
    lines += ["".join(f"{v:15.7E}" for v in reals[i:i + 5]) for i in range(0, 50, 5)]
    lines += ["|<SCNL>TEST.HN2.XX.RC", f"|<loclbl=>{label}<end>"]
    lines += ["".join(e10(v) for v in values[i:i + 8]) for i in range(0, len(values), 8)]
    return "\n".join(lines) + "\n"


def e10(v: float) -> str:
    """A value as the NSMP files print it: 10 characters, one-digit exponent (-1.5289E-2)."""
    mant, exp = f"{v:.4E}".split("E")
    return f"{mant}E{int(exp)}".rjust(10)


def v2_text(values, *, az="360 DEG", sta=7, dt=0.02, npts=None, loc="DECK"):
    """A CSMIP V2 channel in the layout described in hlaid/io/csmip.py."""
    npts = len(values) if npts is None else npts
    head = ["CORRECTED ACCELEROGRAM   TEST", "UNCORRECTED ACCELEROGRAM DATA", "QUAKE", "DATE", "ID",
            "STATION NO. 1", "TEST BRIDGE", f"CHAN  1: {az}  (STA CHN: {sta:2d})     LOCATION: {loc}"]
    head += ["x"] * 7
    data = [f"{npts:5d} POINTS OF ACCEL DATA EQUALLY SPACED AT  {dt:.3f} SEC.  (UNITS: CM/SEC/SEC)"]
    data += ["".join(f"{v:10.3f}" for v in values[i:i + 8]) for i in range(0, len(values), 8)]
    data += [f"{npts:5d} POINTS OF VELOC DATA EQUALLY SPACED AT  {dt:.3f} SEC.  (UNITS: CM/SEC)"]
    data += ["/&  ----------  END OF DATA FOR CHANNEL  1  ----------"]
    return "\n".join(head + data) + "\n"
