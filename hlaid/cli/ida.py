"""``hlaid ida`` and ``hlaid export-opensees``."""

from __future__ import annotations

import shlex
from pathlib import Path

from .. import _progress
from ..errors import InputError
from ..limits import check_count
from .app import add_building, add_ensemble, add_plots, add_seed, subcommand


def _numbers(text: str, what: str) -> list[float]:
    """``"0.1,0.2 0.3"`` or ``"start:stop:step"`` -> floats."""
    text = text.strip()
    try:
        if text.count(":") == 2:
            import numpy as np
            a, b, s = (float(v) for v in text.split(":"))
            if not s > 0:
                raise ValueError
            check_count((b - a) / s + 1, "IDA_LEVELS", f"{what} {text}: number of values")
            return [float(f"{v:.10g}") for v in np.arange(a, b + 0.5 * s, s)]
        return [float(v) for v in text.replace(",", " ").split()]
    except InputError:
        raise
    except ValueError:
        raise InputError(f"{what} must be numbers such as 0.2,0.4,0.6 or start:stop:step, got {text!r}") from None


def register(sub) -> None:
    p = subcommand(sub, "ida", help="incremental dynamic analysis and collapse fragility of a clone",
                   example="hlaid ida clone.json --records builtin-suite -o ida-out")
    p.add_argument("clone", help="clone file (hlaid-clone JSON)")
    p.add_argument("--records", nargs="+", metavar="DIR|builtin-suite|FILE",
                   help="a folder of AT2/text records, builtin-suite, or record files (default: the config's)")
    p.add_argument("-o", "--out", required=True, help="output folder (written atomically)")
    p.add_argument("--config", help="IDA settings (YAML, see configs/ida.yaml); options below override it")
    p.add_argument("--im", choices=["sa_t1", "pga"], help="intensity measure (default sa_t1: Sa(T1, 5%%))")
    p.add_argument("--levels", nargs="+", metavar="G",
                   help="IM levels [g], strictly increasing: 0.2 0.4 ..., 0.2,0.4,... or start:stop:step")
    p.add_argument("--n-levels", type=int, help="number of automatic levels (default 20)")
    p.add_argument("--drift-limit", type=float, help="collapse drift ratio (default 0.10)")
    p.add_argument("--no-refine", action="store_true", help="skip the hunt-and-fill refinement of collapse")
    add_building(p)
    p.add_argument("--units", help="acceleration units of text records: g, m/s^2, cm/s^2, mm/s^2")
    p.add_argument("--period", type=float, help="period [s] of Sa instead of the clone's T1")
    p.add_argument("--collapse", metavar="MODEL",
                   help="strength loss of the stories beyond a capping drift: none, steel-mrf, rc-frame, "
                        "rc-frame-nonductile (docs/collapse.md); default: the clone's collapse block, else the law of "
                        "its structural system, else none (collapse only at the drift limit)")
    p.add_argument("--start", choices=["auto", "carried", "undamaged"], default=None,
                   help="undamaged (default): every run from rest; carried: from the state the clone's last event "
                        "left it in (the fragility after that event); auto: as the clone says")
    p.add_argument("--event", nargs="+", metavar="FILE", default=[],
                   help="recorded events of the building the clone was not identified from (measurement files, "
                        "later than its own): each is listed with its own-motion replay and the fragility at its "
                        "intensity, beside the clone's own events")
    add_ensemble(p, "replaying each recorded event's own motion")
    p.add_argument("--bootstrap", type=int, help="bootstrap resamples of the fragility interval (default 1000)")
    add_seed(p, "the bootstrap")
    add_plots(p)
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.set_defaults(func=run_ida)

    e = subcommand(sub, "export-opensees", help="write a runnable OpenSeesPy script of a clone",
                   example="hlaid export-opensees clone.json -o model.py && python model.py record.AT2")
    e.add_argument("clone", help="clone file (hlaid-clone JSON)")
    e.add_argument("-o", "--out", required=True, help="output script (.py)")
    add_building(e, pdelta_default="when story heights are known, as hlaid ida does")
    e.add_argument("--force", action="store_true", help="overwrite an existing file")
    e.set_defaults(func=run_export)


def run_ida(args) -> int:
    from .._fileio import check_output_folder
    from ..clone import load_clone
    from ..ida.config import IDAConfig, load_ida_config

    inputs = [args.clone, args.config, *(args.records or [])]
    out = check_output_folder(args.out, force=args.force, inputs=inputs)  # fail before the analysis, not after it
    cfg = load_ida_config(args.config) if args.config else IDAConfig()
    levels = _numbers(" ".join(args.levels), "--levels") if args.levels else None
    cfg = cfg.replace(im=args.im, levels=levels, n_levels=args.n_levels, drift_limit=args.drift_limit,
                      refine=False if args.no_refine else None, pdelta=args.pdelta,
                      heights_mm=_numbers(args.heights, "--heights") if args.heights else None,
                      gravity_kN=_numbers(args.gravity_kN, "--gravity-kN") if args.gravity_kN else None,
                      units=args.units, period=args.period, bootstrap=args.bootstrap, seed=args.seed,
                      collapse=args.collapse, start=args.start)
    base = Path(args.config).parent if args.config else None
    if args.records is None:
        inputs += cfg.record_specs(base) or []
        check_output_folder(args.out, force=args.force, inputs=inputs)
    clone = load_clone(args.clone)  # a bad clone file is refused before the heavy libraries load
    _check_heights(clone, cfg.heights_mm, str(args.clone))  # so are missing heights or a wrong count
    from ..io.records import as_motions

    specs = args.records if args.records is not None else cfg.record_specs(base)
    if specs is None:
        raise InputError("no records: give them with --records or in the config ('records:')")
    motions = as_motions(specs, units=cfg.units)  # missing or unreadable records: before the analysis
    from ..events.start import resolve_start

    resolve_start(clone, cfg.start)  # a start the clone cannot give is refused before the heavy libraries load
    from ..ida import ida_from_config, prepare_building

    # fail on a bad clone before reading records
    prepare_building(clone, pdelta=cfg.pdelta, heights=cfg.heights_mm, collapse=cfg.collapse,
                     gravity_load=cfg.gravity_load_n())
    res = ida_from_config(clone, cfg, records=motions, base_dir=base)  # the clone and records read once
    from ..run.decide import decide

    decision = decide(clone, res, cfg, extra=args.event, n_ensemble=args.ensemble, seed=args.seed or 0)
    basis = decision.basis
    res.save(out, force=args.force, plots=not args.no_plots, n_boot=cfg.bootstrap, ci=cfg.ci, seed=cfg.seed,
             inputs=inputs, basis={**basis.to_dict(), "identification_flags": list(decision.identification_flags)})
    s = res.summary(n_boot=0)
    f = s["collapse_fragility"]["capacities"]
    if "median_g" in f:
        _progress.info(f"collapse fragility ({res.im_label}): median {f['median_g']:.3g} g, beta {f['beta']:.2f} "
                       f"({res.n_records} records, {f['n_censored']} censored)")
    for note in res.notes:
        _progress.debug(f"note: {note}")
    print_basis(basis)
    for flag in decision.identification_flags:
        _progress.warn(f"flag: {flag}")
    _progress.info(f"wrote {out}/ (points.csv, summary.json, ida.npz"
                   + ("" if args.no_plots else ", ida_curves.png, fragility.png, exceedance.png") + ")")
    return 0


def print_basis(basis) -> None:
    """What a decision rests on (:class:`hlaid.ida.basis.DecisionBasis`): its block, then its
    flags as warnings."""
    for line in basis.lines():
        _progress.info(line)
    for flag in basis.flags():
        _progress.warn(f"flag: {flag}")


def _check_heights(clone, heights, source: str) -> None:
    """Refuse missing story heights (IDA reports drift ratios) or a count that is not the clone's
    number of stories, from the clone file alone."""
    n = clone.building.n_stories
    if heights is not None and len(heights) != n:
        raise InputError(f"--heights: height has {len(heights)} values but the building has {n} stories; give one "
                         "height in mm per story, bottom to top", source=source)
    if heights is None and clone.building.height is None:
        raise InputError("story heights are unknown; IDA reports drift ratios and needs them: give the heights in mm, "
                         "bottom to top: --heights MM,MM,...", source=source)


def run_export(args) -> int:
    from .._fileio import check_output_file
    from ..clone import load_clone
    from ..units import kn_to_n

    check_output_file(args.out, force=args.force, inputs=[args.clone])
    load_clone(args.clone)  # a bad clone file is refused before the heavy libraries load
    from ..ida import prepare_building
    from ..opensees import export_opensees

    b, _ = prepare_building(args.clone, pdelta=args.pdelta, require_heights=False,
                            heights=_numbers(args.heights, "--heights") if args.heights else None,
                            gravity_load=[kn_to_n(v) for v in _numbers(args.gravity_kN, "--gravity-kN")]
                            if args.gravity_kN else None)
    path = export_opensees(b, args.out, force=args.force)
    _progress.info(f"wrote {path} ({b.n_stories} stories, P-Delta {'on' if b.pdelta_active else 'off'}); "
                   f"run it with: python {shlex.quote(str(path))} RECORD.AT2 [--pga-g 0.5] [--out peaks.json]")
    return 0

