"""``hlaid update`` and ``hlaid predict``: a clone carried from one event to the next."""

from __future__ import annotations

import math
from pathlib import Path

from .. import _progress
from ..uncertainty.config import N_ENSEMBLE
from .app import add_ensemble, add_plots, add_read, add_seed, reader_options, subcommand


def register(sub) -> None:
    p = subcommand(sub, "update", help="add one event to a clone (its posterior the prior, its state the start)",
                   example="hlaid update clone.json s4.tsv.gz -o clone-s4.json "
                           "--config configs/identify_steel_frame.yaml")
    p.add_argument("clone", help="the clone so far (hlaid-clone JSON)")
    p.add_argument("measurement", help="the new event, recorded after the clone's last one")
    p.add_argument("-o", "--out", required=True, help="the updated clone JSON to write")
    p.add_argument("--config", help="identification config YAML (its refine section and system; "
                   "default: configs/identify.yaml's, with the clone's own system)")
    add_read(p)
    p.add_argument("--widen", type=float, default=1.0,
                   help="multiply the clone's posterior standard deviations by this before the update (default 1)")
    p.add_argument("--force", action="store_true", help="overwrite an existing clone file")
    p.set_defaults(func=run_update)

    q = subcommand(sub, "predict", help="replay a clone under an event's recorded ground motion and compare with "
                   "what the building recorded",
                   example="hlaid predict clone.json s4.tsv.gz -o pred-s4 --band 0.3 2.5")
    q.add_argument("clone", help="clone file (hlaid-clone JSON)")
    q.add_argument("measurement", help="the event (ground and floor records of the clone's building)")
    q.add_argument("-o", "--out", required=True, help="output folder: prediction.json, prediction.npz, prediction.png")
    q.add_argument("--band", nargs=2, type=float, metavar=("LO", "HI"),
                   help="band of the compared displacements [Hz] (default: the band the event's floor records hold, "
                        "with HLA's band of the event beside it)")
    add_read(q)
    q.add_argument("--start", choices=["auto", "carried", "undamaged"], default=None,
                   help="carried: from the state the clone's last event left it in; undamaged: at rest; auto "
                        "(default): the clone's start rule (carried only where it predicted the events already "
                        "seen better than from rest)")
    add_ensemble(q, "for the predictive band")
    add_seed(q, "the ensemble's draws")
    add_plots(q)
    q.add_argument("--force", action="store_true", help="replace an existing output folder written by hlaid")
    q.set_defaults(func=run_predict)


def run_update(args) -> int:
    from .._fileio import check_output_file
    from .._inputs import check_input
    from ..config import load_config
    from ..errors import InputError
    from ..identify.config import IdentifyConfig  # light: no torch, numba or scipy

    inputs = [args.clone, args.measurement, args.config]
    out = check_output_file(args.out, force=args.force, inputs=inputs)
    if not 0 < args.widen < 100:
        raise InputError(f"--widen {args.widen}; expected a factor in (0, 100), 1 for none")
    cfg = load_config(args.config, IdentifyConfig) if args.config else IdentifyConfig()
    check_input(args.clone)
    check_input(args.measurement)
    from .._inputs import file_sha256
    from ..clone import Clone
    from ..io import read
    from ..measurement import check_not_learnt, check_of_building

    clone = Clone.load(args.clone)
    if Path(args.measurement).is_file():  # the clone's own file again: refused from its bytes
        check_not_learnt(clone.events, sha256=file_sha256(args.measurement), source=args.measurement)
    meas = read(args.measurement, "measurement", **reader_options(args))
    from ..measurement import check_moving

    check_moving(meas)
    check_output_file(args.out, force=args.force, inputs=inputs)  # and the files it named
    check_of_building(meas, clone.building, mass_normalised=clone.mass_normalised)
    check_not_learnt(clone.events, meas)
    from .identify import check_identify_bands

    check_identify_bands(meas, cfg, args.config)
    from ..events.update import update_clone  # the heavy libraries, once the inputs are good
    from .identify import print_summary

    res = update_clone(clone, meas, cfg, widen=args.widen)
    res.clone.save(out, force=args.force)
    print_summary(res.clone, before=clone)
    seconds = res.timings.get("total")
    _progress.info(f"wrote {out}" + (f" (updated in {seconds:.1f} s)" if seconds is not None else ""))
    return 0


def run_predict(args) -> int:
    from .._fileio import atomic_directory, check_output_folder
    from .._inputs import check_input
    from ..errors import InputError
    from ..limits import check_count

    inputs = [args.clone, args.measurement]
    check_output_folder(args.out, force=args.force, inputs=inputs)
    if args.band is not None and not (0 <= args.band[0] < args.band[1] and math.isfinite(args.band[1])):
        raise InputError(f"--band {args.band[0]:g} {args.band[1]:g}; expected LO HI with 0 <= LO < HI [Hz], finite")
    if args.ensemble is not None and args.ensemble < 0:
        raise InputError(f"--ensemble {args.ensemble}; expected a number of clones >= 0")
    if args.ensemble is not None:
        check_count(args.ensemble, "BOOTSTRAP", "--ensemble")
    check_input(args.clone)
    check_input(args.measurement)
    from ..clone import Clone
    from ..io import read
    from ..measurement import check_band, check_of_building

    clone = Clone.load(args.clone)
    if args.start == "carried" and clone.state is None:
        raise InputError("--start carried: the clone carries no state (identified by an older hlaid?); use "
                         "--start undamaged", source=args.clone)
    meas = read(args.measurement, "measurement", **reader_options(args))
    from ..measurement import check_moving

    check_moving(meas)
    check_output_folder(args.out, force=args.force, inputs=inputs)  # and the files it named
    check_of_building(meas, clone.building, mass_normalised=clone.mass_normalised)
    if args.band is not None:
        check_band(meas, tuple(args.band), "--band")
    n = (N_ENSEMBLE if args.ensemble is None else args.ensemble) if clone.uncertainty is not None else 0
    if args.ensemble and clone.uncertainty is None:
        _progress.warn("the clone has no uncertainty: no predictive band")
    import numpy as np

    from .._fileio import write_json, write_npz  # the heavy libraries, once the inputs are good
    from ..events.predict import predict_event

    p = predict_event(clone, meas, band_hz=args.band, start=args.start or "auto", n_ensemble=n,
                      seed=args.seed or 0)
    with atomic_directory(args.out, force=args.force, inputs=inputs) as tmp:
        write_json(Path(tmp) / "prediction.json", {**p.to_dict(), "clone": str(args.clone)})
        write_npz(Path(tmp) / "prediction.npz", p.arrays())
        if not args.no_plots:
            from ..plots import plot_prediction, save_figure

            save_figure(plot_prediction(p, title=f"{Path(args.clone).name} predicting {meas.name or 'the event'}"),
                        Path(tmp) / "prediction.png")
    cov = "" if p.band is None else (
        f", {100 * float(p.band.coverage.mean()):.0f} % inside the {n}-clone band (its width "
        f"{float(p.band.width.mean()):.2f} x twice the measured RMS)")
    pde = (100 * p.peak_drift_error).round(1).tolist()
    which = {"records": "the band the records hold", "given": "the band given"}.get(p.band_name, p.band_name)
    res = p.residual_drift_error
    resid = "" if res is None else f", residual drift error {np.round(res, 1).tolist()} mm"
    _progress.info(f"{meas.name or args.measurement} in {which} {p.band_hz[0]:.2g}-{p.band_hz[1]:.3g} Hz: R "
                   f"{p.r.round(3).tolist()} (mean {p.r_mean:.3f}), story drift "
                   f"R {p.drift_r.round(3).tolist()}, peak drift error {pde} % "
                   f"(mean |error| {100 * p.peak_drift_error_mean_abs:.1f} %, roof {100 * p.roof_error:+.1f} %; "
                   f"drifts compared in {p.band_hz[0]:.2g}-{p.band_hz[1]:.3g} Hz, hlaid demands gives the full "
                   f"replay's){resid}{cov}; from the {p.start} state ({p.start_reason})")
    for name, f in p.other_bands.items():
        what = {"hla": "HLA's band", "records": "the band the records hold"}.get(name, name)
        _progress.info(f"  in {what} {f.band_hz[0]:.2g}-{f.band_hz[1]:.3g} Hz (same replay): R {f.r.round(3).tolist()} "
                       f"(mean {float(np.mean(f.r)):.3f}), story drift R {f.drift_r.round(3).tolist()}, peak drift "
                       f"error {(100 * f.peak_drift_error).round(1).tolist()} %")
    _progress.info(f"wrote {args.out}")
    return 0
