"""``hlaid hla``."""

from __future__ import annotations

from pathlib import Path

from .. import _progress
from .app import add_plots, add_read, deprecated, reader_options, subcommand


def register(sub) -> None:
    p = subcommand(sub, "hla", help="hysteresis loop analysis: story force-drift loops, half cycles, k0, ke(t), k(t)",
                   example="hlaid hla meas.npz -o hla-out")
    p.add_argument("measurement", help="measurement file (.npz, .csv, or a format hlaid reads)")
    p.add_argument("-o", "--out", required=True, help="output folder (hla.npz, hla.json, plots)")
    p.add_argument("--config", help="HLA config YAML (see configs/hla.yaml)")
    add_read(p)
    add_plots(p)
    deprecated(p, "--plot", "plot", "figures are written unless --no-plots is given", nargs=0)
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.set_defaults(func=run_hla)


def run_hla(args) -> int:
    from .._fileio import atomic_directory, check_output_folder
    from .._inputs import check_input
    from ..config import load_config
    from ..hla.config import HLAConfig

    inputs = [args.measurement, args.config]
    check_output_folder(args.out, force=args.force, inputs=inputs)  # fail before the analysis, not after it
    cfg = load_config(args.config, HLAConfig) if args.config else HLAConfig()
    check_input(args.measurement)
    from ..io import read
    from ..measurement import check_band
    meas = read(args.measurement, "measurement", **reader_options(args))
    from ..measurement import check_moving

    check_moving(meas)
    check_output_folder(args.out, force=args.force, inputs=inputs)  # and the files it named (a columns YAML's table)
    check_band(meas, cfg.preprocess.band_hz, f"preprocess.band_hz (in {args.config})")
    from ..hla import run_hla  # the heavy libraries, once the inputs are known to be good
    from ..hla.plots import plot_loops, plot_stiffness, wide_band
    from ..plots import save_figure
    _progress.info(f"HLA of {meas.n_floors} stories, {meas.n_samples} samples at {1 / meas.dt:g} Hz")
    res = run_hla(meas, cfg)
    with atomic_directory(args.out, force=args.force, inputs=inputs) as tmp:
        res.save(tmp)
        if not args.no_plots:
            save_figure(plot_loops(res, wide=wide_band(meas, res)), Path(tmp) / "loops.png")
            save_figure(plot_stiffness(res, meas.truth), Path(tmp) / "stiffness.png")
    for s in res.stories:
        hc = s.half_cycles
        state = f"ke/k0 final {hc.ke[-1] / s.k0:.3f}" if s.yielded else "elastic (no yielding)"
        _progress.info(f"story {s.story}: k0 = {s.k0:.5g} {res.units['stiffness']}, {len(hc)} half cycles, {state}")
    _progress.info(f"wrote {args.out}/")
    return 0
