"""The clone's modes beside the records', and how its replay follows the higher modes.

For a clone and the records it was identified from (oldest first): each mode of the clone at
small amplitude beside the records' (the clone file's ``modes``), and the replay of the records
in turn (each from the state the one before left) against the measured story drifts: R in the
band above the first mode (``--high-hz``, the higher modes) and over the compared band.

    python scripts/study_modes.py clone.json s1.tsv.gz s2.tsv.gz s3.tsv.gz
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import signal


def _band(x: np.ndarray, dt: float, lo: float, hi: float) -> np.ndarray:
    sos = signal.butter(4, [lo, min(hi, 0.45 / dt)], btype="bandpass", fs=1.0 / dt, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clone")
    ap.add_argument("records", nargs="+")
    ap.add_argument("--high-hz", type=float, default=2.5, help="lower edge of the higher modes' band [Hz]")
    ap.add_argument("--top-hz", type=float, default=12.5, help="upper edge of the compared band [Hz]")
    args = ap.parse_args(argv)

    import hlaid
    from hlaid.clone import Clone
    from hlaid.motions import GroundMotion
    from hlaid.simulate import simulate_response

    clone = Clone.load(args.clone)
    if clone.modes is not None:
        for line in clone.modes.lines():
            print(line)
        for flag in clone.modes.flags():
            print("flag:", flag)
    if clone.linear is not None:
        print(f"linear part: {clone.linear.form} ({clone.linear.reason})")
    b = clone.building
    y0 = None
    for path in args.records:
        m = hlaid.read(path)
        res = simulate_response(b, GroundMotion(acc=m.ground_acc, dt=m.dt), outputs="full", y0=y0)
        y0 = res.final_state
        if m.floor_disp is None:
            print(f"{m.name}: no measured displacements")
            continue
        u = np.asarray(m.floor_disp, dtype=float)
        meas = np.diff(np.concatenate([np.zeros((u.shape[0], 1)), u], axis=1), axis=1)
        sim = res.drift[0][: meas.shape[0]]
        out = []
        for lo in (0.1, args.high_hz):
            a, s = _band(meas, m.dt, lo, args.top_hz), _band(sim, m.dt, lo, args.top_hz)
            out.append([float(np.corrcoef(a[:, i], s[:, i])[0, 1]) for i in range(a.shape[1])])
        print(f"{m.name}: story drift R {args.high_hz:g}-{args.top_hz:g} Hz "
              + "/".join(f"{v:.3f}" for v in out[1]) + f" (0.1-{args.top_hz:g} Hz "
              + "/".join(f"{v:.3f}" for v in out[0]) + ")")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
