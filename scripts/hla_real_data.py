"""Hysteresis loop analysis of the real shake-table data (prints markdown; writes the figures of docs/hla.md).

1. The 3-story steel moment frame, runs ``fbgm152s1..s4`` (the same ground motion at increasing
   scale; masses unknown, so mass-normalised with equal floor masses; measured floor
   displacements): k0 per story and run with the default config and with
   ``configs/hla_steel_frame.yaml`` (first-mode band, regression damping), against an
   independent reference: the first-mode apparent story stiffness ``Re(F/X)`` from Welch
   cross-spectra (averaged over 0.85-1.15 x the dominant frequency), which uses no half cycles.
   The shear-building frequencies implied by k0 (equal masses) are compared with the measured
   dominant frequency.
2. The mini shake-table 3-story models (flexible and stiff; Northridge and 1.5 Hz sine): k0,
   yield flags, and the first-mode frequency implied by k0 against the peak of the measured
   roof/ground transfer function.

Usage: python scripts/hla_real_data.py [--data DIR] [--figures docs/figures/hla] [--force]
       (``--figures ''`` skips the figures)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy import signal

REPO = Path(__file__).resolve().parents[1]

from hlaid.config import load_config  # noqa: E402
from hlaid.errors import InputError  # noqa: E402
from hlaid.hla import HLAConfig, run_hla  # noqa: E402
from hlaid.hla.analysis import story_force  # noqa: E402
from hlaid.hla.plots import plot_loops, plot_stiffness, wide_band  # noqa: E402
from hlaid.hla.preprocess import dominant_frequency  # noqa: E402
from hlaid.io import read_mini_shake_table, read_steel_frame  # noqa: E402
from hlaid.plots import plt, save_figure  # noqa: E402

DATA = REPO.parent / "shared" / "data" / "structural_response"
STEEL = "shake_table_3story_steel_mrf_fixedbase/filtered_fbgm152s{}_denoised.tsv.gz"
MINI = "mini_shake_table_3story_model/{}.csv"
MINI_RUNS = ("flexible_3story_northridge", "flexible_3story_sine1p5", "stiff_3story_northridge", "stiff_3story_sine1p5")
STEEL_CONFIG = REPO / "configs" / "hla_steel_frame.yaml"
FIGURES = ("steel_s1_loops.png", "steel_s4_loops.png", "steel_s4_stiffness.png", "steel_k0_by_run.png",
           "mini_flexible_northridge_loops.png")


def shear_frequencies(k: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Natural frequencies [Hz] of a shear building with story stiffnesses ``k`` [N/mm] and floor
    masses ``m`` [t] (or k/M and mass fractions: 1 N/mm/t = 1 s^-2)."""
    n = len(k)
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    w2 = np.linalg.eigvals(K / np.asarray(m)[:, None])
    return np.sort(np.sqrt(np.abs(w2.real)))[:n] / (2 * np.pi)


def apparent_stiffness(meas, mass: np.ndarray, f_lo: float, f_hi: float, nperseg: int = 2048) -> np.ndarray:
    """Per story, the mean of ``Re(F/X)`` (Welch cross-spectrum over auto-spectrum) between
    ``f_lo`` and ``f_hi`` [Hz]: an equivalent linear story stiffness, no half cycles involved."""
    fs = 1.0 / meas.dt
    x = np.diff(np.asarray(meas.floor_disp), axis=1, prepend=0.0)
    f = story_force(np.asarray(meas.floor_acc), mass)
    out = []
    for i in range(x.shape[1]):
        fr, pxf = signal.csd(x[:, i], f[:, i], fs=fs, nperseg=nperseg)
        _, pxx = signal.welch(x[:, i], fs=fs, nperseg=nperseg)
        sel = (fr >= f_lo) & (fr <= f_hi)
        out.append(float(np.mean((pxf[sel] / pxx[sel]).real)))
    return np.array(out)


def transfer_peak(meas, f_lo: float, f_hi: float, nperseg: int = 2048) -> float:
    """Frequency [Hz] of the largest |roof / ground| (H1 estimate) between ``f_lo`` and ``f_hi``."""
    fs = 1.0 / meas.dt
    fr, pgr = signal.csd(meas.ground_acc, meas.floor_acc[:, -1], fs=fs, nperseg=nperseg)
    _, pgg = signal.welch(meas.ground_acc, fs=fs, nperseg=nperseg)
    sel = (fr >= f_lo) & (fr <= f_hi)
    return float(fr[sel][np.argmax(np.abs(pgr[sel] / pgg[sel]))])


def _row(cells) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def steel_frame(data: Path, figures: Path | None, force: bool) -> None:
    runs = [read_steel_frame(data / STEEL.format(s)) for s in (1, 2, 3, 4)]
    configs = {"default (`configs/hla.yaml`)": HLAConfig(), "first-mode band (`configs/hla_steel_frame.yaml`)":
               load_config(STEEL_CONFIG, HLAConfig)}
    results = {label: [run_hla(m, c) for m in runs] for label, c in configs.items()}
    f1 = np.array([dominant_frequency(m.ground_acc, m.floor_acc[:, -1], m.dt) for m in runs])
    mass = next(iter(results.values()))[0].mass
    frf = np.array([apparent_stiffness(m, mass, 0.85 * f, 1.15 * f) for m, f in zip(runs, f1)])
    print("## Steel moment frame, runs s1..s4 (k/M [N/mm/t], equal floor masses)\n")
    print(_row(["run", "PGA [g]", "f1 measured [Hz]"] + [f"{lab}: k0 story {i}" for lab in ("default", "first-mode")
                                                          for i in (1, 2, 3)]
               + [f"Re(F/X) at f1, story {i}" for i in (1, 2, 3)] + ["f1 from first-mode k0 [Hz]", "yielded"]))
    print("|" + "---|" * 15)
    res_d, res_f = results.values()
    for j, m in enumerate(runs):
        freq = shear_frequencies(res_f[j].k0, res_f[j].mass)[0]
        print(_row([f"s{j + 1}", f"{np.max(np.abs(m.ground_acc)) / 9806.65:.3f}", f"{f1[j]:.2f}"]
                   + [f"{v:.1f}" for v in res_d[j].k0] + [f"{v:.1f}" for v in res_f[j].k0]
                   + [f"{v:.1f}" for v in frf[j]] + [f"{freq:.2f}",
                                                     "".join("Y" if s.yielded else "-" for s in res_f[j].stories)]))
    print()
    for label, rs in results.items():
        k0 = np.array([r.k0 for r in rs])
        ok = np.all(np.diff(k0, axis=0) <= 0, axis=0)
        rise = np.max(np.diff(k0, axis=0) / k0[:-1], axis=0)
        print(f"- {label}: k0 non-increasing s1->s4 per story: {', '.join('yes' if o else 'NO' for o in ok)}; "
              f"largest run-to-run rise {', '.join(f'{100 * r:+.1f} %' for r in rise)}; "
              f"s4/s1 {', '.join(f'{v:.2f}' for v in k0[-1] / k0[0])}")
    ok = np.all(np.diff(frf, axis=0) < 0, axis=0)
    print("- reference Re(F/X) at f1 strictly decreasing s1->s4 per story: "
          f"{', '.join('yes' if o else 'NO' for o in ok)}")
    if figures is None:
        return
    best = res_f
    for j in (0, 3):
        fig = plot_loops(best[j], wide=wide_band(runs[j], best[j]))
        fig.suptitle(f"steel frame run s{j + 1}: story force / total mass against drift, first-mode band (top) "
                     "and the wide band (bottom)")
        save_figure(fig, figures / f"steel_s{j + 1}_loops.png", dpi=80)
    fig = plot_stiffness(best[3])
    fig.suptitle("steel frame run s4, first-mode band: stiffness evolution (k/M)")
    save_figure(fig, figures / "steel_s4_stiffness.png", dpi=80)
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.2), layout="constrained")
    for i, ax in enumerate(axes):
        for (label, rs), mk in zip(results.items(), ("o--", "s-")):
            ax.plot([1, 2, 3, 4], [r.k0[i] for r in rs], mk, label=label.split(" (")[0])
        ax.plot([1, 2, 3, 4], frf[:, i], "k^:", label="Re(F/X) at f1 (reference)")
        ax.set_title(f"story {i + 1}")
        ax.set_xticks([1, 2, 3, 4], ["s1", "s2", "s3", "s4"])
        ax.set_ylabel("k0 / M [N/mm/t]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("steel frame: k0 per story by run (damage accumulates: k0 should not rise)")
    save_figure(fig, figures / "steel_k0_by_run.png", dpi=80)


def mini_shake_table(data: Path, figures: Path | None) -> None:
    print("\n## Mini shake table, 3-story models (k/M [N/mm/t], equal floor masses), default config\n")
    print(_row(["run", "band [Hz]", "k0 story 1", "k0 story 2", "k0 story 3", "yielded", "half cycles",
                "peak drift [mm]", "f1 from k0 [Hz]", "f1 measured (|roof/ground| peak) [Hz]"]))
    print("|" + "---|" * 10)
    for name in MINI_RUNS:
        m = read_mini_shake_table(data / MINI.format(name))
        r = run_hla(m)
        f_k0 = shear_frequencies(r.k0, r.mass)[0]
        f_meas = transfer_peak(m, 2.0, 15.0)
        print(_row([name, f"{r.band_hz[0]:.2f}-{r.band_hz[1]:.1f}"] + [f"{v:.0f}" for v in r.k0]
                   + ["".join("Y" if s.yielded else "-" for s in r.stories),
                      ", ".join(str(len(s.half_cycles)) for s in r.stories),
                      ", ".join(f"{np.max(np.abs(s.drift)):.1f}" for s in r.stories), f"{f_k0:.2f}", f"{f_meas:.2f}"]))
        if figures is not None and name == "flexible_3story_northridge":
            fig = plot_loops(r)
            fig.suptitle("mini shake table, flexible model, Northridge: story force / total mass against drift")
            save_figure(fig, figures / "mini_flexible_northridge_loops.png", dpi=80)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=str(DATA), help="the structural_response folder of ../shared/data")
    ap.add_argument("--figures", default=str(REPO / "docs" / "figures" / "hla"), help="figure folder ('' for none)")
    ap.add_argument("--force", action="store_true", help="overwrite existing figures")
    a = ap.parse_args(argv)
    data = Path(a.data)
    figures = Path(a.figures) if a.figures else None
    try:
        if not data.is_dir():
            raise InputError("data folder not found", source=str(data))
        if figures is not None:
            figures.mkdir(parents=True, exist_ok=True)
            existing = [n for n in FIGURES if (figures / n).exists()]
            if existing and not a.force:
                raise InputError(f"holds figures ({', '.join(existing)}); use --force to overwrite",
                                 source=str(figures))
        steel_frame(data, figures, a.force)
        mini_shake_table(data, figures)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
