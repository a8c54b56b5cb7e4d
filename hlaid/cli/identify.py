"""``hlaid identify``."""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import TYPE_CHECKING

from .. import _progress
from .app import add_read, reader_options, subcommand

if TYPE_CHECKING:
    from ..identify import IdentifyConfig

METHODS = ("hlasvm", "gradient", "ukf")
"""``--method`` choices: names of :data:`hlaid.baselines.IDENTIFIERS` (kept here so that ``--help``
imports no identifier; a test checks the two agree)."""


def register(sub) -> None:
    p = subcommand(sub, "identify", help="identify a digital clone (degrading Bouc-Wen per story) from one "
                   "measurement, or from several of one building in time order",
                   example="hlaid identify meas.npz -o clone.json --tensorboard runs/id1\n"
                           "  hlaid identify s1.tsv.gz s2.tsv.gz s3.tsv.gz -o clone.json "
                           "--config configs/identify_steel_frame.yaml")
    p.add_argument("measurement", nargs="+", help="measurement file(s) (.npz, .csv, or a format hlaid reads); "
                   "several: records of one building, oldest first (one set of parameters for all, the state "
                   "carried from each into the next)")
    p.add_argument("-o", "--out", required=True, help="clone JSON to write")
    p.add_argument("--method", choices=METHODS, default="hlasvm",
                   help="hlasvm (default): the paper's HLA + SVM identification, refined as --config says; "
                        "gradient: least squares through the differentiable model; ukf: unscented Kalman filter. "
                        "Every method writes the same clone file format")
    p.add_argument("--config", help="identification config YAML of --method hlasvm (see configs/identify.yaml)")
    p.add_argument("--system", metavar="NAME",
                   help="structural system (steel-moment-frame, rc-frame, generic): its prior holds what the data "
                        "say little about, its collapse law is the IDA's (default: the config's, else none)")
    add_read(p)
    p.add_argument("--tensorboard", metavar="DIR", help="write TensorBoard logs here")
    p.add_argument("--cache", metavar="DIR", help="classifier cache folder (default ~/.cache/hlaid/svm)")
    p.add_argument("--no-cache", action="store_true", help="train every classifier afresh and cache nothing")
    p.add_argument("--force", action="store_true", help="overwrite an existing clone file")
    p.set_defaults(func=run_identify)


def run_identify(args) -> int:
    from .._fileio import check_name, check_output_file
    from .._inputs import check_input
    from ..config import load_config
    from ..errors import InputError

    out = check_output_file(args.out, force=args.force, inputs=[*args.measurement, args.config])  # before the work
    if args.config and args.method != "hlasvm":
        raise InputError(f"--config configures --method hlasvm, not {args.method}")
    if len(args.measurement) > 1 and args.method != "hlasvm":
        raise InputError(f"--method {args.method} identifies from one measurement; several need --method hlasvm")
    tb = Path(args.tensorboard) if args.tensorboard else None
    if tb is not None:
        check_name(tb)
        if tb.exists() and not tb.is_dir():
            raise InputError("exists and is not a folder; --tensorboard writes a folder of logs", source=str(tb))
    from ..identify.config import IdentifyConfig  # light: no torch, numba or scipy

    cfg = load_config(args.config, IdentifyConfig) if args.config else IdentifyConfig()
    if args.system is not None:
        if args.method != "hlasvm":
            raise InputError(f"--system configures --method hlasvm, not {args.method}")
        import dataclasses

        cfg = dataclasses.replace(cfg, system=args.system)  # an unknown name is refused, listing the known ones
    for path in args.measurement:
        check_input(path)
    check_distinct(args.measurement)
    from ..io import read
    from ..measurement import check_band, check_series
    options = reader_options(args)
    records = [read(path, "measurement", **options) for path in args.measurement]
    from ..measurement import check_moving

    for m in records:
        check_moving(m)
    check_output_file(args.out, force=args.force, inputs=[*args.measurement, args.config])  # and the files they named
    if len(records) > 1:
        check_series(records)
    if args.method == "hlasvm":
        for m in records:
            check_identify_bands(m, cfg, args.config)
    meas = records[0] if len(records) == 1 else records
    from ..baselines.registry import get_identifier  # the heavy libraries, once the inputs are good
    from ..estimators import HLASVMIdentifier
    if args.method == "hlasvm":
        cache = "" if args.no_cache else args.cache
        est = HLASVMIdentifier(config=cfg, refine=None, cache_dir=cache, tensorboard=args.tensorboard)
    else:
        est = get_identifier(args.method, tensorboard=args.tensorboard)
        check_band(records[0], est.band_hz, f"band_hz (--method {args.method})")
    new_tb = tb is not None and not os.path.lexists(tb)
    try:
        est.fit(meas)
        est.clone_.save(out, force=args.force)
    except BaseException:  # Ctrl-C, SIGTERM, an error: no half-written TensorBoard folder either
        if new_tb and tb is not None:
            shutil.rmtree(tb, ignore_errors=True)
        raise
    if args.method == "hlasvm":
        print_summary(est.result_.clone)
        seconds = est.result_.timings.get("total")
        _progress.info(f"wrote {out}" + (f" (identified in {seconds:.1f} s)" if seconds is not None else ""))
    else:
        print_parameters(est, records[0])
        _progress.info(f"wrote {out}")
    return 0


def check_identify_bands(meas, cfg: IdentifyConfig, config: str | None) -> None:
    """The band-pass corners of an identification config must suit the measurement's sample rate
    (the default corners are capped at 0.9 x its Nyquist frequency, given ones refused above it)."""
    from ..identify.config import RefineConfig
    from ..measurement import check_band

    where = f" (in {config})" if config else " (default)"
    check_band(meas, cfg.hla.preprocess.band_hz, "hla.preprocess.band_hz" + where)
    check_band(meas, cfg.refine.band_hz, "refine.band_hz" + where, default=RefineConfig().band_hz)


def check_distinct(paths) -> None:
    """Refuse one measurement file given twice (the same file, or the same bytes under two names),
    from their raw bytes, before any is parsed: each event once."""
    from .._inputs import file_sha256
    from ..errors import InputError

    if len(paths) < 2:
        return
    seen: dict[str, str] = {}
    for path in paths:
        key = file_sha256(path) if Path(path).is_file() else None
        if key is not None and key in seen:
            raise InputError(f"the same file as {seen[key]}: each event once", source=str(path))
        if key is not None:
            seen[key] = str(path)


def parameter_lines(b, mass_normalised: bool) -> list[str]:
    """The story parameters as a table with units (k0 per tonne of relative mass for a
    mass-normalised clone)."""
    k0 = "N/mm/t" if mass_normalised else "N/mm"
    head = f"story {'k0 [' + k0 + ']':>13} {'alpha':>6} {'p':>5} {'dy [mm]':>8} {'delta_eta [s2/m2]':>18}"
    return [head] + [f"{i + 1:5d} {b.k0[i]:13.5g} {b.alpha[i]:6.3f} {b.p[i]:5.2f} {b.dy[i]:8.3f} "
                     f"{b.delta_eta[i]:18.3f}" for i in range(b.n_stories)]


def modal_line(b, k0_hla=None) -> str:
    """The clone's elastic modes (periods and Rayleigh damping ratio of each) and, with ``k0_hla``,
    the first-mode period HLA's stiffnesses alone give (the same masses)."""
    import numpy as np

    from ..model.modes import clone_modes

    T = np.asarray(b.periods())
    xi = [m.damping_ratio for m in clone_modes(b)]
    line = ("elastic modes: T " + " / ".join(f"{v:.3f}" for v in T) + " s, damping "
            + " / ".join(f"{100 * v:.1f}" for v in xi) + " %")
    if k0_hla is not None and len(k0_hla) == b.n_stories and all(v and v > 0 for v in k0_hla):
        line += f"; HLA's k0 alone: T1 {float(b.replace(k0=np.asarray(k0_hla, float)).periods()[0]):.3f} s"
    return line


MOVED = 0.10
"""An update's parameter that changed by more than this fraction is said to have moved (not
labelled as the earlier events' or the prior's)."""


def print_summary(clone, before=None) -> None:
    """The clone's story parameters, where each comes from, its replay of its events and its
    state; ``before``: the clone an update started from (parameters that moved are said so)."""
    import numpy as np

    b = clone.building
    flags = {(f.name, f.story): f for f in clone.parameters or ()}
    table = parameter_lines(b, bool(clone.mass_normalised))
    lines = table[:1]

    def moved(n: str, i: int) -> bool:
        if before is None or before.building.n_stories != b.n_stories:
            return False
        old, new = float(getattr(before.building, n)[i]), float(getattr(b, n)[i])
        return abs(new - old) > MOVED * max(abs(old), 1e-12)
    for i in range(b.n_stories):
        mark = ""
        for source in ("prior", "earlier events"):
            names = [n for n in ("alpha", "p", "dy", "delta_eta")
                     if (n, i + 1) in flags and flags[(n, i + 1)].source == source and not moved(n, i)]
            if names:
                mark += f"  (from the {source}: {', '.join(names)})" if source == "prior" else \
                    f"  (from {source}, little from this one: {', '.join(names)})"
        shifts = [f"{n} {float(getattr(before.building, n)[i]):.3g} -> {float(getattr(b, n)[i]):.3g}"
                  for n in ("alpha", "p", "dy", "delta_eta") if moved(n, i)]
        if shifts:
            mark += f"  (moved by this event: {', '.join(shifts)})"
        limit = [n for n in ("alpha", "p", "dy", "delta_eta") if (n, i + 1) in flags and flags[(n, i + 1)].at_limit]
        if limit:
            mark += f"  (at a limit: {', '.join(limit)})"
        if clone.paper is not None and i < len(clone.paper.stories) and not clone.paper.stories[i].identifiable:
            mark += "  (not identifiable: see the clone file's identification.paper)"
        lines.append(table[i + 1] + mark)
    stories = () if clone.paper is None else clone.paper.stories
    lines.append(modal_line(b, [s.k0_hla for s in stories] if len(stories) == b.n_stories else None))
    if clone.modes is not None:
        lines += clone.modes.lines()
    if clone.linear is not None:
        lines.append(f"linear part: {clone.linear.form} ({clone.linear.reason})")
    fits = clone.fit_replays
    if fits and clone.paper is None:  # one line: R per floor of each event's replay
        lines.append("replay R (floors bottom to top): " + "; ".join(
            f"{e.name or 'event'} " + "/".join(f"{v:.3f}" for v in e.r_measured) for e in fits))
    elif fits:
        lines.append(f"replay: R {np.round(fits[-1].r_measured, 3).tolist()}")
    from ..events.replay import summary_line

    full = summary_line(clone.events)
    if full:
        lines.append(full)
    if clone.state is not None:
        drift, eta = np.round(clone.state.drift, 2).tolist(), np.round(clone.state.eta(b), 3).tolist()
        lines.append(f"state after {len(clone.events)} event(s): residual drift {drift} mm, eta {eta}")
    laws = clone.laws
    system = f" ({clone.system})" if clone.system else ""
    if laws is not None and laws.chosen:
        lines.append(f"story laws{system}: {' / '.join(laws.chosen)} ({laws.kept or laws.reason})")
    elif clone.system:
        lines.append(f"structural system: {clone.system}")
    rule = clone.start_rule
    if rule is not None:
        where = "from the carried state" if rule.choice == "carried" else "from rest"
        lines.append(f"next prediction starts {where} (start auto): {rule.reason}")
    check = clone.update_check
    if check is not None and check.refit:
        gauss = float("nan") if check.gaussian is None else check.gaussian
        lines.append("the update forgot the earlier events (their misfit grew by "
                     f"{check.misfit_change or float('nan'):.1f} where the posterior predicted "
                     f"{gauss:.1f}): fitted jointly again from their records")
    elif check is not None and check.note:
        lines.append(f"check of the update: {check.note}")
    for note in clone.fallbacks:
        lines.append(f"fallback: {note.stage} failed numerically ({note.error}); {note.used}")
    from ..run.decision import identification_flags

    lines += [f"flag: {f}" for f in identification_flags(clone)]
    lines += [f"flag: {f}" for f in (clone.modes.flags() if clone.modes is not None else [])]
    for line in lines:
        _progress.info(line)


def print_parameters(est, meas) -> None:
    """The clone's story parameters, its modes, its replay of the record (R of the floor
    displacements, as for HLA+SVM) and the fit time of an identifier other than HLA+SVM."""
    import numpy as np

    from ..hla import run_hla
    from ..identify.replaycheck import replay_check

    b = est.clone_.building
    lines = parameter_lines(b, bool(est.clone_.mass_normalised))
    hla = run_hla(meas)
    lines.append(modal_line(b, list(hla.k0)))
    r = np.round(replay_check(b, meas, hla).r_measured, 3).tolist()
    lines.append(f"replay of {meas.name or 'the record'}: R {r}")
    lines.append(f"{type(est).__name__}, wall time {est.fit_seconds_:.1f} s")
    for line in lines:
        _progress.info(line)
