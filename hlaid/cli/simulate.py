"""``hlaid simulate`` and ``hlaid records``."""

from __future__ import annotations

from pathlib import Path

from .. import _progress
from .app import add_seed, subcommand


def register(sub) -> None:
    p = subcommand(sub, "simulate", help="simulate accelerometer records of a building (a measurement file)",
                   example="hlaid simulate configs/poc_3story.yaml -o meas.npz --seed 1")
    p.add_argument("config", help="YAML config: building, motion, measurement, seed")
    p.add_argument("-o", "--out", required=True, help="output measurement file (.npz or .csv)")
    add_seed(p, "the noise", default="the config's")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.set_defaults(func=run_simulate)

    r = subcommand(sub, "records", help="list the ground motion records shipped with hlaid",
                   example="hlaid records")
    r.set_defaults(func=run_records)


def run_simulate(args) -> int:
    from .._fileio import check_output_file
    from ..bounds import SEED
    from ..specs import load_simulation_config

    out = check_output_file(args.out, force=args.force, inputs=[args.config])  # before the simulation, not after it
    if args.seed is not None:
        SEED.check("--seed", args.seed)
    cfg = load_simulation_config(args.config)
    check_output_file(args.out, force=args.force, inputs=[args.config, cfg.motion.path(Path(args.config).parent)])
    from ..synthetic import measurement_from_config  # the heavy libraries, once the inputs are known to be good
    _progress.info(f"simulating {cfg.building.name or 'building'} under {cfg.motion.file}")
    meas = measurement_from_config(cfg, base_dir=Path(args.config).parent, seed=args.seed, source=args.config)
    meas.save(out, force=args.force)
    _progress.info(f"wrote {out} ({meas.n_samples} samples, {meas.n_floors} floors, dt = {meas.dt:g} s)")
    return 0


def run_records(args) -> int:
    from ..motions import builtin_records, load_builtin

    for name, rec in builtin_records().items():
        gm = load_builtin(name)
        suite = " [suite]" if rec.suite else ""
        print(f"builtin:{name:28s} dt={gm.dt:<6g} {gm.duration:6.1f} s  PGA {gm.pga_g:5.3f} g  "
              f"{rec.description}{suite}")
    return 0
