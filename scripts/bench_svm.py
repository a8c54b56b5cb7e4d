#!/usr/bin/env python
"""Benchmark :class:`hlaid.svm.KernelSVC` against :class:`sklearn.svm.SVC`.

Default: ``make_classification`` with 15 classes and 20 features
(15 informative, 2 redundant, one cluster per class, ``class_sep=2.0``,
``random_state=0``); the first ``n`` samples train, the next ``--n-test``
(default 2000) are the held-out set.  Both libraries get the same ``C`` and
``gamma="scale"``, float64.  Times are the best of ``--repeat`` runs, after
one warm-up fit; both libraries run in the same process, one after the other.

``--pipeline``: problems like the identification pipeline's training sets:
11 features in ``[-0.2, 1.2]``, 12 classes whose centres lie along a smooth
curve, Gaussian noise (``--noise``, default 0.2) so that the classes overlap
heavily (held-out accuracy about 40 %), ``C = 10``, ``gamma="scale"``; one
table row per size and seed, then the mean and worst fit ratio.

The machine's load average is printed before and after (other jobs on the cores move
the absolute times; compare the ratios, taken in the same run). ``--json PATH`` also writes
the rows as JSON.

Usage::

    python scripts/bench_svm.py                       # 1500, 3000, 5000, 10000, 15000 samples
    python scripts/bench_svm.py --sizes 1500 --repeat 5
    python scripts/bench_svm.py --pipeline            # the same sizes, seeds 0 1 2
    python scripts/bench_svm.py --parity              # parity table (tests' datasets)
"""

from __future__ import annotations

import argparse
import json
import os
import time
from functools import partial

import numba
import numpy as np
import torch
from sklearn.datasets import make_classification
from sklearn.svm import SVC

from hlaid.svm import KernelSVC


def best_time(fn, repeat: int):
    """Best wall time of ``repeat`` calls and the last result."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def make_problem(n_train: int, n_test: int, n_classes: int, n_features: int, seed: int = 0):
    X, y = make_classification(n_samples=n_train + n_test, n_features=n_features,
                               n_informative=15, n_redundant=2, n_classes=n_classes,
                               n_clusters_per_class=1, class_sep=2.0, random_state=seed)
    return X[:n_train], y[:n_train], X[n_train:], y[n_train:]


def pipeline_problem(n_train: int, n_test: int, seed: int, noise: float = 0.2,
                     n_classes: int = 12, n_features: int = 11):
    """Heavily overlapping classes like the pipeline's: centres along a curve plus noise."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, n_classes)
    phase = rng.uniform(0.0, 2.0 * np.pi, n_features)
    freq = rng.uniform(0.5, 1.5, n_features)
    centres = 0.5 + 0.35 * np.sin(np.pi * freq[None] * s[:, None] + phase[None])
    y = rng.integers(0, n_classes, n_train + n_test)
    X = np.clip(centres[y] + noise * rng.standard_normal((y.size, n_features)), -0.2, 1.2)
    return X[:n_train], y[:n_train], X[n_train:], y[n_train:]


def run_size(Xtr, ytr, Xte, yte, C: float, args) -> dict:
    """Fit and predict times of both libraries on one problem, and how their machines agree."""
    t_fit, me = best_time(partial(KernelSVC(C=C, device=args.device).fit, Xtr, ytr), args.repeat)
    t_sk, sk = best_time(partial(SVC(C=C).fit, Xtr, ytr), args.repeat)
    t_dd, p_dd = best_time(partial(me.set_params(multiclass="ddag").predict, Xte), args.repeat)
    t_ovo, p_ovo = best_time(partial(me.set_params(multiclass="ovo").predict, Xte), args.repeat)
    t_psk, p_sk = best_time(partial(sk.predict, Xte), args.repeat)
    return {"n": len(ytr), "fit_hlaid_s": t_fit, "fit_sklearn_s": t_sk, "fit_ratio": t_fit / t_sk,
            "predict_ddag_s": t_dd, "predict_ovo_s": t_ovo, "predict_sklearn_s": t_psk,
            "predict_ratio_ddag": t_dd / t_psk, "acc_ddag": float(np.mean(p_dd == yte)),
            "acc_ovo": float(np.mean(p_ovo == yte)), "acc_sklearn": float(np.mean(p_sk == yte)),
            "ovo_equals_sklearn": float(np.mean(p_ovo == p_sk)),
            "same_iterations": float(np.mean(me.n_iter_ == sk.n_iter_)),
            "n_sv": [int(me.support_.size), int(sk.support_.size)]}


def table(rows: list[dict], keys: list[tuple[str, str]]) -> None:
    print("| " + " | ".join(h for h, _ in keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        cells = []
        for _, k in keys:
            v = r[k]
            cells.append(f"{v[0]} / {v[1]}" if isinstance(v, list) else
                         f"{v:.4f}" if isinstance(v, float) and k.startswith(("acc", "ovo", "same", "predict_"))
                         and not k.endswith("ratio_ddag") else f"{v:.3f}" if isinstance(v, float) and
                         k.endswith("_s") else f"{v:.2f}" if isinstance(v, float) else str(v))
        print("| " + " | ".join(cells) + " |", flush=True)


COLUMNS = [("n", "n"), ("fit hlaid [s]", "fit_hlaid_s"), ("fit sklearn [s]", "fit_sklearn_s"),
           ("fit ratio", "fit_ratio"), ("predict hlaid ddag [s]", "predict_ddag_s"),
           ("predict hlaid ovo [s]", "predict_ovo_s"), ("predict sklearn [s]", "predict_sklearn_s"),
           ("predict ratio (ddag)", "predict_ratio_ddag"), ("acc hlaid ddag", "acc_ddag"),
           ("acc hlaid ovo", "acc_ovo"), ("acc sklearn", "acc_sklearn"), ("ovo = sklearn", "ovo_equals_sklearn"),
           ("machines with libsvm's iterations", "same_iterations"), ("n_SV hlaid / sklearn", "n_sv")]


def header(args, what: str) -> None:
    print(f"# {what}; held-out set {args.n_test} samples, best of {args.repeat}; torch "
          f"{torch.__version__} ({torch.get_num_threads()} threads), numba {numba.__version__} "
          f"({numba.get_num_threads()} threads), {os.cpu_count()} CPUs, device {args.device or 'cpu'}; "
          f"load average {os.getloadavg()[0]:.1f}")


def pipeline(args) -> list[dict]:
    """Fit/predict times on pipeline-like problems, several seeds."""
    Xw, yw, _, _ = pipeline_problem(300, 10, 0, args.noise)
    KernelSVC(C=10.0, device=args.device).fit(Xw, yw)      # warm-up: compiled code, allocator
    SVC(C=10.0).fit(Xw, yw)
    header(args, f"pipeline-like: 12 classes, 11 features, noise {args.noise}, C=10, gamma='scale'")
    rows = []
    for n in args.sizes:
        for seed in args.seeds:
            rows.append({"seed": seed, **run_size(*pipeline_problem(n, args.n_test, seed, args.noise), 10.0, args)})
    table(rows, COLUMNS[:1] + [("seed", "seed")] + COLUMNS[1:])
    for n in args.sizes:
        r = [row["fit_ratio"] for row in rows if row["n"] == n]
        print(f"# n={n}: fit ratio mean {np.mean(r):.2f}, worst {np.max(r):.2f} over seeds {list(args.seeds)}")
    return rows


def bench(args) -> list[dict]:
    Xw, yw, _, _ = make_problem(300, 10, args.classes, args.features)
    KernelSVC(C=args.C, device=args.device).fit(Xw, yw)    # warm-up: compiled code, allocator
    SVC(C=args.C).fit(Xw, yw)
    header(args, f"{args.classes} classes, {args.features} features, C={args.C}, gamma='scale'")
    rows = [run_size(*make_problem(n, args.n_test, args.classes, args.features), args.C, args)
            for n in args.sizes]
    table(rows, COLUMNS)
    return rows


def parity(args) -> None:
    """Parity figures on the datasets of tests/test_svm_parity.py."""
    from sklearn.datasets import (
        load_breast_cancer,
        load_digits,
        load_iris,
        load_wine,
        make_moons,
    )
    from sklearn.metrics.pairwise import rbf_kernel
    from sklearn.model_selection import train_test_split
    from sklearn.preprocessing import StandardScaler

    def pair_objectives(est):
        m = len(est.classes_)
        starts = np.r_[0, np.cumsum(est.n_support_)]
        out = []
        for a in range(m):
            for b in range(a + 1, m):
                A = np.arange(starts[a], starts[a + 1])
                B = np.arange(starts[b], starts[b + 1])
                beta = np.r_[est._dual_coef_[b - 1, A], est._dual_coef_[a, B]]
                sv = est.support_vectors_[np.r_[A, B]]
                out.append(0.5 * beta @ rbf_kernel(sv, sv, gamma=est._gamma) @ beta
                           - np.abs(beta).sum())
        return np.array(out)

    def jaccard(a, b):
        a, b = set(a.tolist()), set(b.tolist())
        return len(a & b) / len(a | b)

    def same(sk, me):
        """Machines with libsvm's iteration count, and the largest coefficient and intercept
        differences (when the support sets are equal)."""
        it = f"{int(np.sum(me.n_iter_ == sk.n_iter_))} / {sk.n_iter_.size}"
        if not np.array_equal(me.support_, sk.support_):
            return f"{it} | - | -"
        return (f"{it} | {np.abs(me.dual_coef_ - sk.dual_coef_).max():.1e} | "
                f"{np.abs(me.intercept_ - sk.intercept_).max():.1e}")

    print("## binary (training set), RBF, gamma='scale'")
    print("| problem | C | obj rel. diff | max dec diff / range | SV Jaccard | n_SV sklearn / hlaid | "
          "machines with libsvm's iterations | max coef diff | max intercept diff |")
    print("|---|---|---|---|---|---|---|---|---|")
    bc = load_breast_cancer()
    binary = {"classification": make_classification(400, 8, random_state=0),
              "moons": make_moons(300, noise=0.3, random_state=0),
              "breast_cancer": (StandardScaler().fit_transform(bc.data), bc.target)}
    for name, (X, y) in binary.items():
        for C in (0.5, 1.0, 10.0):
            sk, me = SVC(C=C).fit(X, y), KernelSVC(C=C).fit(X, y)
            o = pair_objectives(sk)[0]
            d_sk, d_me = sk.decision_function(X), me.decision_function(X)
            print(f"| {name} | {C} | {abs(me.dual_objective_[0] - o) / abs(o):.1e} | "
                  f"{np.abs(d_me - d_sk).max() / np.ptp(d_sk):.1e} | "
                  f"{jaccard(sk.support_, me.support_):.4f} | {sk.support_.size} / "
                  f"{me.support_.size} | {same(sk, me)} |")
    print()
    print("## multi-class (held-out set), RBF, C=1, gamma='scale'")
    print("| dataset | n train / test | OvO = sklearn | acc sklearn | acc hlaid ovo | "
          "acc hlaid ddag | max obj rel. diff | max ovo dec diff / range | SV Jaccard | "
          "machines with libsvm's iterations | max coef diff | max intercept diff |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    Xs, ys = make_classification(n_samples=2000, n_features=20, n_informative=15,
                                 n_redundant=2, n_classes=15, n_clusters_per_class=1,
                                 class_sep=2.0, random_state=0)
    Xw, yw = load_wine(return_X_y=True)
    sets = {"iris": (load_iris(return_X_y=True), 0.3),
            "wine (standardised)": ((StandardScaler().fit_transform(Xw), yw), 0.3),
            "digits": (load_digits(return_X_y=True), 0.3),
            "synthetic 15 x 20": ((Xs, ys), 0.25)}
    for name, ((X, y), test) in sets.items():
        Xtr, Xte, ytr, yte = train_test_split(X, y, test_size=test, random_state=0, stratify=y)
        sk = SVC(decision_function_shape="ovo").fit(Xtr, ytr)
        me = KernelSVC(multiclass="ovo", decision_function_shape="ovo").fit(Xtr, ytr)
        p_sk, p_ovo = sk.predict(Xte), me.predict(Xte)
        p_dd = me.set_params(multiclass="ddag").predict(Xte)
        o = pair_objectives(sk)
        d_sk, d_me = sk.decision_function(Xte), me.decision_function(Xte)
        print(f"| {name} | {len(ytr)} / {len(yte)} | {np.mean(p_ovo == p_sk):.4f} | "
              f"{np.mean(p_sk == yte):.4f} | {np.mean(p_ovo == yte):.4f} | "
              f"{np.mean(p_dd == yte):.4f} | "
              f"{np.max(np.abs(me.dual_objective_ - o) / np.abs(o)):.1e} | "
              f"{np.abs(d_me - d_sk).max() / np.ptp(d_sk):.1e} | "
              f"{jaccard(sk.support_, me.support_):.4f} | {same(sk, me)} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1500, 3000, 5000, 10000, 15000],
                    help="training set sizes (default: 1500 3000 5000 10000 15000)")
    ap.add_argument("--pipeline", action="store_true",
                    help="pipeline-like problems (overlapping classes, C=10) instead")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2],
                    help="--pipeline: problem seeds (default 0 1 2)")
    ap.add_argument("--noise", type=float, default=0.2,
                    help="--pipeline: noise around the class centres (default 0.2)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per timing, best kept")
    ap.add_argument("--n-test", type=int, default=2000, help="held-out samples (default 2000)")
    ap.add_argument("--classes", type=int, default=15)
    ap.add_argument("--features", type=int, default=20)
    ap.add_argument("--C", type=float, default=1.0)
    ap.add_argument("--device", default=None, help="torch device for hlaid (default cpu)")
    ap.add_argument("--threads", type=int, default=None,
                    help="torch and numba threads for this run (default: theirs)")
    ap.add_argument("--json", default=None, help="also write the timing rows to this JSON file")
    ap.add_argument("--parity", action="store_true",
                    help="print the parity table instead of timings")
    args = ap.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
        numba.set_num_threads(args.threads)
    if args.parity:
        parity(args)
        return
    rows = pipeline(args) if args.pipeline else bench(args)
    print(f"# load average after the run {os.getloadavg()[0]:.1f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"set": "pipeline" if args.pipeline else "default", "rows": rows,
                       "load_average": os.getloadavg()[0]}, fh, indent=1)


if __name__ == "__main__":
    main()
