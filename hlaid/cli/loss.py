"""``hlaid demands`` and ``hlaid loss``: demands in pelicun's format, FEMA P-58 losses through pelicun."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from .. import _progress
from ..errors import InputError
from ..uncertainty.config import N_ENSEMBLE
from .app import add_building, add_ensemble, add_read, add_seed, deprecated, reader_options, subcommand
from .ida import _numbers


def register(sub) -> None:
    d = subcommand(sub, "demands", help="peak drifts, floor accelerations and residual drifts of a clone in pelicun's "
                                        "demand format (and OUT.basis.json: what they rest on)",
                   example="hlaid demands clone.json --motion measurement.npz --ensemble 20 -o demands.csv")
    d.add_argument("clone", help="clone file (hlaid-clone JSON)")
    src = d.add_mutually_exclusive_group(required=True)
    src.add_argument("--motion", metavar="FILE",
                     help="the ground motion the building recorded (a record or measurement file), as recorded")
    src.add_argument("--records", nargs="+", metavar="DIR|builtin-suite|FILE",
                     help="records scaled to --level (an IDA stripe)")
    d.add_argument("--level", type=float, metavar="G", help="intensity of the stripe [g] (with --records)")
    add_read(d)
    add_ensemble(d, "")
    deprecated(d, "--n-ensemble", "ensemble", "use --ensemble", type=int)
    add_seed(d, "the ensemble's draws")
    add_building(d)
    d.add_argument("--config", help="IDA settings (YAML, configs/ida.yaml): intensity measure, drift limit, step, "
                                    "P-Delta, collapse model")
    d.add_argument("-o", "--out", required=True, help="demand CSV to write (pelicun's format)")
    d.add_argument("--force", action="store_true", help="overwrite an existing file")
    d.set_defaults(func=run_demands)

    p = subcommand(sub, "loss", help="FEMA P-58 repair cost, repair time, irreparable damage and collapse through "
                                     "pelicun (needs hlaid[loss])",
                   example="hlaid loss hlaid-demo --system steel-moment-frame")
    p.add_argument("source", help="a run folder (hlaid run / hlaid demo), or a demand CSV (hlaid demands) with -o")
    p.add_argument("-o", "--out", help="output folder of the losses (required for a demand CSV); for a run folder one "
                                       "outside it, the run folder left as it is (default: RUN_DIR/loss, with the "
                                       "run's summary.json and report.html updated, all or nothing)")
    p.add_argument("--system", help="default inventory: steel-moment-frame or rc-frame (default: the run "
                                    "config's, else steel-moment-frame)")
    p.add_argument("--inventory", metavar="CSV", help="your component inventory (pelicun's component assignment "
                                                      "CSV) instead of the system's")
    p.add_argument("--floor-area", metavar="M2", help="floor area per story [m2]: one value or one per story")
    p.add_argument("--realizations", type=int, help="pelicun's sample size (default 1000)")
    add_seed(p, "pelicun's sampling")
    p.add_argument("--levels", nargs="+", metavar="G", help="IM levels [g] of the loss curve (default: the IDA's)")
    p.add_argument("--no-curve", action="store_true", help="only the recorded event, no loss curve")
    p.add_argument("--records", nargs="+", metavar="DIR|builtin-suite|FILE",
                   help="records of the loss curve's stripes (default: the run's IDA records)")
    p.add_argument("--irreparable-median", type=float, help="median residual drift ratio of irreparable damage "
                                                            "(default 0.01)")
    p.add_argument("--irreparable-beta", type=float, help="its dispersion (default 0.3)")
    p.add_argument("--collapse-median", type=float, metavar="G", help="collapse fragility median [g] (demand CSV)")
    p.add_argument("--collapse-beta", type=float, help="collapse fragility dispersion (demand CSV)")
    p.add_argument("--collapse-from", metavar="IDA_DIR",
                   help="the collapse fragility of an hlaid ida output folder (the clone's own; demand CSV), instead "
                        "of --collapse-median/--collapse-beta")
    p.add_argument("--drift-limit", type=float,
                   help="peak drift ratio above which a realization of a demand CSV is a collapse (default 0.10)")
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.set_defaults(func=run_loss)


def _own_motion(path: str, options: dict):
    """The ground motion of a record file, or the ground channel of a measurement file, and the
    measurement (None for a record)."""
    from ..io import read
    from ..measurement import Measurement
    from ..motions import GroundMotion

    obj = read(path, **options)
    if isinstance(obj, Measurement):
        return obj.ground_motion(name=Path(path).stem, source=path), obj
    if isinstance(obj, GroundMotion):
        return obj, None
    raise InputError("expected one ground motion (a record or a measurement file), not a record set", source=path)


def measured_drift_ratios(meas, heights):
    """:func:`hlaid.ida.ownevent.measured_drift_ratios` (the one definition), imported when used."""
    from ..ida.ownevent import measured_drift_ratios as measured

    return measured(meas, heights)


def _check_level(args) -> None:
    """``--level`` with ``--records`` only, and within the IDA's levels (1e-6 to 100 g)."""
    if args.records and args.level is None:
        raise InputError("--records needs --level G (the stripe's intensity); for the recorded event use --motion")
    if args.motion and args.level is not None:
        raise InputError("--level scales --records; the recorded event (--motion) is taken as recorded")
    if args.level is not None:
        from ..bounds import bounds_of
        from ..ida.config import IDAConfig

        b = bounds_of(next(f for f in dataclasses.fields(IDAConfig) if f.name == "levels"))
        assert b is not None  # the IDA's levels are bounded
        b.check("--level", args.level)


def run_demands(args) -> int:
    from .._fileio import check_output_file
    from ..clone import Clone
    from ..ida import IDAConfig, load_ida_config
    from ..loss import clone_demands

    inputs = [args.clone, args.motion, args.config, *(args.records or [])]
    check_output_file(args.out, force=args.force, inputs=inputs)
    basis_file = Path(str(args.out) + ".basis.json")  # what the demands rest on, beside them
    check_output_file(basis_file, force=args.force, inputs=inputs)
    _check_level(args)
    clone = Clone.load(args.clone)
    n_ens = args.ensemble if args.ensemble is not None else (N_ENSEMBLE if clone.uncertainty is not None else 0)
    cfg = load_ida_config(args.config) if args.config else IDAConfig()
    cfg = cfg.replace(pdelta=args.pdelta, heights_mm=_numbers(args.heights, "--heights") if args.heights else None,
                      gravity_kN=_numbers(args.gravity_kN, "--gravity-kN") if args.gravity_kN else None)
    options = reader_options(args)
    if options and not args.motion:
        raise InputError("--read is for the measurement (--motion); records are read as they are")
    records, meas = _own_motion(args.motion, options) if args.motion else (args.records, None)
    check_output_file(args.out, force=args.force, inputs=inputs)  # and the files they named (a columns YAML's table)
    d = clone_demands(clone, records, level=args.level, n_ensemble=n_ens, seed=args.seed or 0, ida_config=cfg)
    from ..ida.basis import decision_basis
    from ..loss.demands import median_peak_ratio
    from .ida import print_basis

    heights = cfg.heights_mm if cfg.heights_mm is not None else clone.building.height
    measured = measured_drift_ratios(meas, heights)
    own: tuple = ()
    if args.motion:  # the recorded event's own motion: "did the clone survive it?"
        from ..ida.ownevent import check_of_demands

        sha = _sha(args.motion)
        own = (check_of_demands(Path(args.motion).name.split(".")[0], d if n_ens == 0 else None,
                                d if n_ens else None,
                                measured=measured, in_clone=any(e.sha256 == sha for e in clone.events),
                                heights_assumed=cfg.heights_mm is not None),)
    hr: tuple = ()
    if own and cfg.heights_mm is not None and meas is not None:  # assumed heights: the decision at 0.8 and 1.2 x
        from ..loss.ownmotion import height_range

        hr = height_range(clone, own[0].name, meas, ida_config=cfg, heights=cfg.heights_mm, in_clone=own[0].in_clone)
    basis = decision_basis(clone, heights=cfg.heights_mm, heights_assumed=cfg.heights_mm is not None,
                           demand_ratio=median_peak_ratio(d.pid[~d.collapsed]), drift_limit=cfg.drift_limit,
                           events_note="demands run no IDA (the fragility at an intensity); hlaid ida CLONE gives it",
                           own_motion=own, height_range=hr)
    d.write_csv(args.out, force=args.force)
    from .._fileio import write_json

    write_json(basis_file, {**basis.to_dict(), "demands": str(args.out), "flags_of_demands": list(d.flags)},
               force=args.force)
    s = d.summary()
    assumed = " [drift ratios over assumed story heights]" if cfg.heights_mm is not None else ""
    _progress.info(f"wrote {args.out}: {d.n_realizations} realizations ({s['n_collapsed']} collapsed), "
                   f"median peak drift ratio {max(s['pid_median'] or [0]):.2%}, median residual "
                   f"{max(s['rid_median'] or [0]):.2%}, {d.im_label} {float(d.im.max()):.3g} g"
                   + (" (the clones' full replay, unfiltered; hlaid predict compares drifts in a band, so its "
                      "errors differ)" if args.motion else "") + assumed)
    if measured is not None:
        pct = lambda a: " / ".join(f"{100 * v:.2f}" for v in a)  # noqa: E731
        _progress.info(f"measured (the record's floor displacements): peak drift ratio {pct(measured[0])} %, "
                       f"residual {pct(measured[1])} % per story; the nominal clone: {pct(d.pid[0])} %, "
                       f"{pct(d.rid[0])} %" + ("; the median over the realizations: " + pct(s["pid_median"]) + " %"
                                               if s["pid_median"] and d.n_realizations > 1 else "") + assumed)
    for note in d.notes:
        _progress.debug(f"note: {note}")
    for flag in d.flags:
        if not flag.startswith("demands extrapolated"):  # said once, by the basis
            _progress.warn(f"flag: {flag}")
    print_basis(basis)
    _progress.info(f"wrote {basis_file} (what the demands rest on)")
    return 0


def run_loss(args) -> int:
    from ..loss import LossConfig, loss_of_demand_file

    src = Path(args.source)
    levels = [] if args.no_curve else (_numbers(" ".join(args.levels), "--levels") if args.levels else None)
    area = _numbers(args.floor_area, "--floor-area") if args.floor_area else None
    over = dict(system=args.system, inventory=args.inventory, realizations=args.realizations, seed=args.seed,
                levels=levels, irreparable_median=args.irreparable_median, irreparable_beta=args.irreparable_beta,
                floor_area_m2=(area[0] if len(area) == 1 else area) if area else None)
    if (args.collapse_median is None) != (args.collapse_beta is None):
        raise InputError("give both --collapse-median and --collapse-beta, or neither")
    collapse = None if args.collapse_median is None else (args.collapse_median, args.collapse_beta)
    if args.collapse_from is not None:
        if collapse is not None:
            raise InputError("give --collapse-from or --collapse-median/--collapse-beta, not both")
        if not src.is_file():
            raise InputError("--collapse-from is for a demand CSV; a run folder has its own fragility")
        collapse = ida_fragility(args.collapse_from, src)
    if src.is_file():
        if not args.out:
            raise InputError("a demand CSV needs an output folder: -o DIR")
        if area is None:  # before pelicun loads: the file holds no floor masses to take the area from
            raise InputError("a demand CSV holds no floor masses to take the floor area from: give it, --floor-area "
                             "M2 (one value or one per story)", source=str(src))
        cfg = LossConfig().replace(**over)
        s = loss_of_demand_file(src, cfg, args.out, collapse=collapse,
                                drift_limit=0.10 if args.drift_limit is None else args.drift_limit, force=args.force)
        _report(s, args.out)
        side = Path(str(src) + ".basis.json")
        if side.is_file():
            _print_side_basis(side)
        else:
            _progress.info("what the decision rests on: not assessed (a demand CSV carries no clone: the events the "
                           "building survived, the drift survived and the heights are unknown here; hlaid demands "
                           "writes them beside its CSV, or run hlaid loss on a run folder)")
        return 0
    if collapse is not None:
        raise InputError("--collapse-median/--collapse-beta are for a demand CSV; a run folder has its own fragility")
    if area is None:
        _check_run_area(src)
    from .._inputs import rewrites
    from ..run.loss import loss_of_run

    with rewrites(src / "summary.json", src / "report.html"):  # without -o the run folder gets the losses
        block = loss_of_run(src, changes=over, records=args.records, out=args.out, force=args.force)
    folder = Path(args.out) if args.out else src / "loss"
    if block["recorded"]:
        _report(block["recorded"], folder)
    if block.get("basis"):
        from ..ida.basis import P_SURVIVED_FLAG, DecisionBasis
        from .ida import print_basis

        basis = DecisionBasis.from_dict(block["basis"])
        print_basis(basis)
        p = (block["recorded"] or {}).get("p_collapse")
        if p is not None and p >= P_SURVIVED_FLAG and not basis.contradicted:
            _progress.warn(f"flag: P(collapse | another record of the recorded event's intensity) {p:.0%} in the "
                           "losses, at an event the building survived: check the story heights, the collapse law "
                           "and the drift limit before acting on it")
    if block["stripes"]:
        _progress.info(f"loss curve at {len(block['stripes'])} intensities: {folder / 'loss_curve.csv'}")
    return 0


def _sha(path) -> str | None:
    """The SHA-256 of a file (None where it cannot be read)."""
    from .._inputs import file_sha256

    try:
        return file_sha256(path)
    except (OSError, InputError):
        return None


def _print_side_basis(side: Path) -> None:
    """Print what the demands of a CSV rest on, from the basis ``hlaid demands`` wrote beside it,
    with its flags (the same block and flags the demands printed)."""
    from .._inputs import read_json
    from ..ida.basis import DecisionBasis
    from .ida import print_basis

    d = read_json(side)
    _progress.info(f"what the decision rests on: the demands' own basis, {side}")
    print_basis(DecisionBasis.from_dict(d))
    for flag in d.get("flags_of_demands") or ():
        if not str(flag).startswith("demands extrapolated"):  # said once, by the basis
            _progress.warn(f"flag: {flag}")


def ida_fragility(folder: str, demands: Path) -> tuple[float, float]:
    """``(median [g], beta)`` of the collapse fragility in an ``hlaid ida`` output folder (its fit to the
    records' collapse capacities), checked to be in the intensity of the demand file ``demands``."""
    from .._inputs import read_json
    from ..loss.demands import read_demand_csv

    path = Path(folder) / "summary.json"
    if not Path(folder).is_dir() or not path.is_file():
        raise InputError("--collapse-from: expected an hlaid ida output folder (with summary.json)", source=folder)
    s = read_json(path)
    try:
        f = s["collapse_fragility"]["capacities"]
        median, beta = float(f["median_g"]), float(f["beta"])
        im, period = s["intensity_measure"]["name"], s["intensity_measure"].get("period_s")
    except (KeyError, TypeError, ValueError):
        raise InputError("--collapse-from: no fitted collapse fragility in summary.json (collapse_fragility."
                         "capacities.median_g, beta); raise the IDA's levels", source=str(path)) from None
    df = read_demand_csv(demands)
    want = "PGA" if im == "pga" else f"SA_{period:.3g}" if period else None
    have = df.im_type or "PGA"  # no SA column: the PGA is PFA-0 (hlaid demands writes no other; as the losses read it)
    if want is None or have != want:
        raise InputError(f"--collapse-from: the IDA's intensity ({want or im}) is not the demand file's "
                         f"({have}); run hlaid ida and hlaid demands on the same clone with the same "
                         "settings", source=str(path))
    return median, beta


def _check_run_area(run: Path) -> None:
    """Refuse, from the run folder's summary alone, losses of a mass-normalised clone without
    ``--floor-area`` (its floor masses are unknown), before pelicun or torch loads; anything else
    about the folder is left to the assessment's own checks."""
    from .._inputs import own_files, read_json

    try:
        with own_files():  # the run's own summary, rewritten by the losses: no input of the run
            s = read_json(run / "summary.json")
    except InputError:
        return
    if isinstance(s, dict) and s.get("mass_normalised") is True:
        raise InputError("the run's clone is mass-normalised, so its floor masses are unknown: give the floor area, "
                         "--floor-area M2 (one value or one per story)", source=str(run))


def _report(s: dict, out) -> None:
    lo, hi = s["repair_cost_band"]
    _progress.info(f"repair cost: median {s['repair_cost_median']:,.0f} {s['cost_unit']} "
                   f"({s['repair_cost_ratio_median']:.1%} of replacement), 90 % band {lo:,.0f} - {hi:,.0f}; "
                   f"repair time median {s['repair_time_parallel_median']:.0f} worker-days (parallel); "
                   + ("P(collapse | another record of this intensity) not assessed (no collapse fragility)"
                      if s['p_collapse'] is None else
                      f"P(collapse | another record of this intensity) {s['p_collapse']:.1%} (the IDA fragility at "
                      "the demands' intensity, pelicun's sample of it)")
                   + f", P(irreparable) {s['p_irreparable']:.1%}")
    _progress.info(f"wrote {out}/ (loss.json, pelicun's inputs: demands.csv, inventory.csv, config.json)")
