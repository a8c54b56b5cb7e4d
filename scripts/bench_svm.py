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

Usage::

    python scripts/bench_svm.py                       # 1500, 5000, 15000 samples
    python scripts/bench_svm.py --sizes 1500 --repeat 5
    python scripts/bench_svm.py --pipeline            # 1500 and 3000 samples, seeds 0 1 2
    python scripts/bench_svm.py --parity              # parity table (tests' datasets)
"""

from __future__ import annotations

import argparse
import time
from functools import partial

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


def pipeline(args) -> None:
    """Fit/predict times on pipeline-like problems, several seeds."""
    dev = args.device
    Xw, yw, _, _ = pipeline_problem(300, 10, 0, args.noise)
    KernelSVC(C=10.0, device=dev).fit(Xw, yw)
    SVC(C=10.0).fit(Xw, yw)
    print(f"# pipeline-like: 12 classes, 11 features, noise {args.noise}, C=10, gamma='scale', "
          f"held-out set {args.n_test} samples, best of {args.repeat}; torch {torch.__version__} "
          f"({torch.get_num_threads()} threads, device {dev or 'cpu'})")
    head = ("| n | seed | fit hlaid [s] | fit sklearn [s] | fit ratio | predict hlaid ddag [s] | "
            "predict sklearn [s] | acc hlaid ddag | acc sklearn | ovo = sklearn | n_SV hlaid / sklearn |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    ratios = {}
    for n in args.sizes:
        for seed in args.seeds:
            Xtr, ytr, Xte, yte = pipeline_problem(n, args.n_test, seed, args.noise)
            t_fit, me = best_time(partial(KernelSVC(C=10.0, device=dev).fit, Xtr, ytr), args.repeat)
            t_sk, sk = best_time(partial(SVC(C=10.0).fit, Xtr, ytr), args.repeat)
            t_dd, p_dd = best_time(partial(me.predict, Xte), args.repeat)
            t_psk, p_sk = best_time(partial(sk.predict, Xte), args.repeat)
            p_ovo = me.set_params(multiclass="ovo").predict(Xte)
            ratios.setdefault(n, []).append(t_fit / t_sk)
            print(f"| {n} | {seed} | {t_fit:.3f} | {t_sk:.3f} | {t_fit / t_sk:.2f} | {t_dd:.4f} | "
                  f"{t_psk:.4f} | {np.mean(p_dd == yte):.4f} | {np.mean(p_sk == yte):.4f} | "
                  f"{np.mean(p_ovo == p_sk):.4f} | {me.support_.size} / {sk.support_.size} |",
                  flush=True)
    for n, r in ratios.items():
        print(f"# n={n}: fit ratio mean {np.mean(r):.2f}, worst {np.max(r):.2f} "
              f"over seeds {list(args.seeds)}")


def bench(args) -> None:
    dev = args.device
    # warm-up (first torch calls, allocator)
    Xw, yw, _, _ = make_problem(300, 10, args.classes, args.features)
    KernelSVC(C=args.C, device=dev).fit(Xw, yw)
    SVC(C=args.C).fit(Xw, yw)
    print(f"# {args.classes} classes, {args.features} features, C={args.C}, gamma='scale', "
          f"held-out set {args.n_test} samples, best of {args.repeat}; "
          f"torch {torch.__version__} ({torch.get_num_threads()} threads, device {dev or 'cpu'})")
    head = ("| n | fit hlaid [s] | fit sklearn [s] | fit ratio | predict hlaid ddag [s] | "
            "predict hlaid ovo [s] | predict sklearn [s] | predict ratio (ddag) | "
            "acc hlaid ddag | acc hlaid ovo | acc sklearn | ovo = sklearn |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for n in args.sizes:
        Xtr, ytr, Xte, yte = make_problem(n, args.n_test, args.classes, args.features)
        t_fit, me = best_time(partial(KernelSVC(C=args.C, device=dev).fit, Xtr, ytr), args.repeat)
        t_sk, sk = best_time(partial(SVC(C=args.C).fit, Xtr, ytr), args.repeat)
        me.set_params(multiclass="ddag")
        t_dd, p_dd = best_time(partial(me.predict, Xte), args.repeat)
        me.set_params(multiclass="ovo")
        t_ovo, p_ovo = best_time(partial(me.predict, Xte), args.repeat)
        t_psk, p_sk = best_time(partial(sk.predict, Xte), args.repeat)
        acc = [np.mean(p == yte) for p in (p_dd, p_ovo, p_sk)]
        print(f"| {n} | {t_fit:.3f} | {t_sk:.3f} | {t_fit / t_sk:.2f} | {t_dd:.4f} | "
              f"{t_ovo:.4f} | {t_psk:.4f} | {t_dd / t_psk:.2f} | {acc[0]:.4f} | {acc[1]:.4f} | "
              f"{acc[2]:.4f} | {np.mean(p_ovo == p_sk):.4f} |", flush=True)


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

    print("## binary (training set), RBF, gamma='scale'")
    print("| problem | C | obj rel. diff | max dec diff / range | SV Jaccard | n_SV sklearn / hlaid |")
    print("|---|---|---|---|---|---|")
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
                  f"{me.support_.size} |")
    print()
    print("## multi-class (held-out set), RBF, C=1, gamma='scale'")
    print("| dataset | n train / test | OvO = sklearn | acc sklearn | acc hlaid ovo | "
          "acc hlaid ddag | max obj rel. diff | max ovo dec diff / range | SV Jaccard |")
    print("|---|---|---|---|---|---|---|---|---|")
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
              f"{jaccard(sk.support_, me.support_):.4f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=None,
                    help="training set sizes (default: 1500 5000 15000; --pipeline: 1500 3000)")
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
                    help="torch.set_num_threads for this run (default: torch's default)")
    ap.add_argument("--parity", action="store_true",
                    help="print the parity table instead of timings")
    args = ap.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.sizes is None:
        args.sizes = [1500, 3000] if args.pipeline else [1500, 5000, 15000]
    if args.parity:
        parity(args)
    elif args.pipeline:
        pipeline(args)
    else:
        bench(args)


if __name__ == "__main__":
    main()
