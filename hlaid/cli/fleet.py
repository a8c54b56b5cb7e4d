"""``hlaid fleet``: a building portfolio on dask.distributed."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ..errors import InputError
from .app import subcommand


def register(sub) -> None:
    p = subcommand(sub, "fleet", help="identify, assess and rank many buildings and events on a dask cluster",
                   example="hlaid fleet configs/fleet_example.yaml -o fleet-out --workers 2")
    p.add_argument("config", help="fleet config YAML (buildings, events, records, identify, ida, cluster)")
    p.add_argument("-o", "--out", required=True,
                   help="output folder; an existing fleet output is resumed (finished buildings are kept)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of an existing dask scheduler (e.g. tcp://10.0.0.5:8786); default: an embedded "
                        "LocalCluster. The workers must see the config's files at the same paths")
    p.add_argument("--workers", type=int, metavar="N",
                   help="workers of the embedded cluster (config: cluster.n_workers)")
    p.add_argument("--threads", type=int, metavar="N",
                   help="threads per worker of the embedded cluster (config: cluster.threads_per_worker)")
    p.add_argument("--cache", metavar="DIR", help="classifier cache folder (default ~/.cache/hlaid/svm)")
    p.add_argument("--force", action="store_true",
                   help="recompute buildings whose stored result came from other inputs (a folder that is not a "
                        "fleet output is never written into)")
    p.set_defaults(func=run_fleet_cli)


def _check_config_inputs(cfg, base: Path) -> None:
    """What the engine checks before a cluster starts, checked before dask and torch load: the
    measurement files exist and are regular files, the IDA records can be read and are enough for
    the ensemble's collapse fragility (2)."""
    from ..io import read

    records = read(cfg.record_specs(base), kind="records", units=cfg.ida.units)
    if cfg.n_ensemble > 0 and len(records) < 2:
        raise InputError(f"the assessment fits a collapse fragility and needs at least 2 IDA records; the config "
                         f"names {len(records)} (records:)")
    cfg.check_measurement_files(base)


def run_fleet_cli(args) -> int:
    from ..fleet.address import parse_address, probe

    if args.scheduler:
        parse_address(args.scheduler)  # at once, before the config is read
        probe(args.scheduler)  # nothing listening, no scheduler, no TLS settings: before anything heavy loads
    from ..fleet.config import load_fleet_config
    from ..fleet.output import check_output

    check_output(Path(args.out), force=args.force)
    cfg = load_fleet_config(args.config)
    changes = {}
    for opt, key in (("workers", "n_workers"), ("threads", "threads_per_worker")):
        v = getattr(args, opt)
        if v is not None:
            if v < 1:
                raise InputError(f"--{opt} {v}: expected an integer >= 1")
            changes[key] = v
    if changes:
        cfg = dataclasses.replace(cfg, cluster=dataclasses.replace(cfg.cluster, **changes))
    _check_config_inputs(cfg, Path(args.config).parent)
    from ..fleet.engine import run_fleet  # dask, torch: once the config is known to be good
    summary = run_fleet(cfg, args.out, base_dir=Path(args.config).parent, scheduler=args.scheduler,
                        force=args.force, cache_dir=args.cache)
    if summary.failed and not (summary.computed or summary.skipped):
        raise InputError(f"all {len(summary.failed)} unit(s) failed; the reasons are in {summary.out / 'results.csv'}")
    from .. import _progress

    ok = [r for r in summary.rows if r.get("status") == "ok"]
    _progress.info(f"highest risk first ({len(ok)} of {len(summary.rows)} units ok; all in "
                   f"{summary.out / 'results.csv'}):")
    for r in ok[:5]:
        p = r.get("p_collapse")
        flags = [f for f in str(r.get("basis_flags") or "").split(" | ") if f]
        _progress.info(f"  {r.get('rank')}. {r['building']}@{r['event']}: "
                       + (f"P(collapse) {p:.1%}, " if isinstance(p, (int, float)) else "")
                       + f"indicator {r.get('indicator', '-')}"
                       + (f"; rests on {len(flags)} flag(s) (column basis_flags)" if flags else ""))
    for r in ok:
        for f in str(r.get("basis_flags") or "").split(" | "):
            if f.startswith("P(collapse)"):  # survival contradicted: said for every unit
                _progress.warn(f"flag: {r['building']}@{r['event']}: {f}")
    return 0
