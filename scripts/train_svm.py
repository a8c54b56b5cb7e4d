"""Train the alpha and p kernel machines on simulated half cycles (the identification's
classifier pass, on its own).

    python scripts/train_svm.py --config configs/svm.yaml --out runs/svm
    tensorboard --logdir runs/svm/tensorboard
"""

from __future__ import annotations

import argparse
import sys

from hlaid.errors import InputError
from hlaid.identify.svmtrain import train_from_config


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/svm.yaml")
    ap.add_argument("--out", default="runs/svm")
    args = ap.parse_args(argv)
    try:
        tp, bins = train_from_config(args.config, args.out)
    except InputError as err:
        print(f"train_svm: error: {err}", file=sys.stderr)
        return 2
    print(f"{'machine':16s} {'classes':>7s} {'n_train':>7s} {'train acc':>9s} {'test acc':>8s} {'fit s':>6s}")
    for name, st in tp.stats.items():
        n_cls = len(st["confusion"])
        print(f"{name:16s} {n_cls:7d} {st['n_train']:7d} {st['train_accuracy']:9.3f} {st['test_accuracy']:8.3f} "
              f"{st['seconds']:6.2f}")
    print(f"simulation {tp.seconds_simulate:.1f} s; outputs in {args.out}/ (summary.json, machines/, tensorboard/)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
