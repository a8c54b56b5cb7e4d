"""Alpha and p by RBF kernel SVMs on half-cycle features (standardised, C and gamma cross-validated),
combined over a story's samples by vote; class bins as the paper's Tables 2-3."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import NotIdentifiableError
from ..svm import KernelSVC, fit_many, resolve_gamma
from .config import SVMConfig
from .training import TrainingSet


@dataclass(frozen=True)
class Bins:
    """Contiguous class bins ``[edges[i], edges[i+1])``."""

    edges: np.ndarray

    @classmethod
    def regular(cls, lo: float, hi: float, width: float) -> Bins:
        n = max(1, int(np.ceil((hi - lo) / width - 1e-9)))
        return cls(lo + width * np.arange(n + 1))

    @property
    def n(self) -> int:
        return int(self.edges.shape[0] - 1)

    @property
    def centers(self) -> np.ndarray:
        return 0.5 * (self.edges[:-1] + self.edges[1:])

    @property
    def range(self) -> tuple[float, float]:
        return float(self.edges[0]), float(self.edges[-1])

    def label(self, values: np.ndarray) -> np.ndarray:
        """Bin index of each value (values outside are put in the nearest end bin)."""
        return np.clip(np.searchsorted(self.edges, values, side="right") - 1, 0, self.n - 1)

    def refine(self, index: int, width: float, limits: tuple[float, float]) -> Bins:
        """Finer bins over bin ``index`` and its two neighbours (boundary crossing), within ``limits``."""
        lo = max(self.edges[max(index - 1, 0)], limits[0])
        hi = min(self.edges[min(index + 2, self.n)], limits[1])
        return Bins.regular(lo, hi, width)


@dataclass(frozen=True)
class PassResult:
    """One classifier pass for one parameter of one story.

    Attributes
    ----------
    param : ``"alpha"`` or ``"p"``; stage : ``"coarse"`` or ``"fine"``
    edges : the class bins; votes : (bin,) votes of the measured half cycles
    predicted : winning bin; value : its centre (the estimate)
    train_accuracy, test_accuracy : on the simulated half cycles (test: held-out simulations)
    confusion : (bin, bin) test confusion matrix (rows: true class)
    n_train, n_test, seconds, cached
    """

    param: str
    stage: str
    edges: np.ndarray
    votes: np.ndarray
    predicted: int
    value: float
    train_accuracy: float
    test_accuracy: float
    confusion: np.ndarray
    n_train: int
    n_test: int
    seconds: float
    cached: bool = False

    def to_dict(self) -> dict:
        return {"param": self.param, "stage": self.stage, "edges": self.edges.tolist(), "votes": self.votes.tolist(),
                "predicted": self.predicted, "value": self.value, "train_accuracy": self.train_accuracy,
                "test_accuracy": self.test_accuracy, "confusion": self.confusion.tolist(), "n_train": self.n_train,
                "n_test": self.n_test, "seconds": self.seconds, "cached": self.cached}


def make_svc(cfg: SVMConfig, C: float | None = None, gamma: float | str | None = None) -> KernelSVC:
    return KernelSVC(C=cfg.C if C is None else C, kernel=cfg.kernel, gamma=cfg.gamma if gamma is None else gamma,
                     multiclass=cfg.multiclass)


def split(train: TrainingSet, test_fraction: float) -> np.ndarray:
    """Test mask: every ``1/test_fraction``-th simulation is held out (no half cycle of a
    held-out response is seen in training)."""
    every = max(2, int(round(1.0 / test_fraction)))
    return train.sim % every == 0


def scaler_of(X: np.ndarray) -> dict:
    """Mean and scale of the training features (constant features get scale 1)."""
    sd = X.std(axis=0)
    return {"mean": X.mean(axis=0).tolist(), "scale": np.where(sd > 0, sd, 1.0).tolist()}


def apply_scaler(X: np.ndarray, scaler: dict | None) -> np.ndarray:
    if not scaler:
        return X
    return (X - np.asarray(scaler["mean"])) / np.asarray(scaler["scale"])


@dataclass(frozen=True)
class Hyper:
    """The C and gamma of a classifier's machines.

    Attributes
    ----------
    C : box constraint
    gamma : the kernel's gamma as given to the machines (a number, or ``cfg.gamma`` as is when
        there is no ``gamma_grid``)
    gamma_factor : the factor of ``cfg.gamma`` (resolved on the training features) it is
        (1.0 without ``gamma_grid``); a later pass reuses the factor, as its features differ
    cv_accuracy : ``[{"C", "gamma_factor", "accuracy"}]`` of every pair cross-validated
    """

    C: float
    gamma: float | str
    gamma_factor: float
    cv_accuracy: list


def choose_hyper(X: np.ndarray, y: np.ndarray, cfg: SVMConfig) -> Hyper:
    """C from ``cfg.C_grid`` and gamma from ``cfg.gamma_grid`` (factors of ``cfg.gamma``
    resolved on ``X``) by ``cfg.cv_folds``-fold cross-validated accuracy on at most
    ``cfg.cv_samples`` evenly spaced samples; on ties the smallest C, then the smallest gamma
    (the smoothest machine). Without grids, ``cfg.C`` and ``cfg.gamma``; a grid of one pair is
    taken without cross-validation."""
    if cfg.C_grid is None and cfg.gamma_grid is None:
        return Hyper(cfg.C, cfg.gamma, 1.0, [])
    base = resolve_gamma(cfg.gamma, X) if cfg.gamma_grid is not None else None
    pairs = [(float(C), float(g)) for C in (cfg.C_grid or (cfg.C,)) for g in (cfg.gamma_grid or (1.0,))]

    def gamma_of(factor):
        return cfg.gamma if base is None else factor * base

    if len(pairs) == 1:
        return Hyper(pairs[0][0], gamma_of(pairs[0][1]), pairs[0][1], [])
    if len(y) > cfg.cv_samples:  # every k-th sample: the cross-validation costs ~n^2
        keep = np.linspace(0, len(y) - 1, cfg.cv_samples).astype(int)
        X, y = X[keep], y[keep]
    folds = np.arange(len(y)) % cfg.cv_folds
    jobs = [(C, g, k) for C, g in pairs for k in range(cfg.cv_folds)
            if len(np.unique(y[folds != k])) >= 2 and (folds == k).any()]
    fitted = fit_many([make_svc(cfg, C, gamma_of(g)) for C, g, _ in jobs],  # all folds in one call
                      [X[folds != k] for *_, k in jobs], [y[folds != k] for *_, k in jobs])
    acc: dict = {}
    for (C, g, k), m in zip(jobs, fitted):
        acc.setdefault((C, g), []).append(float(np.mean(m.predict(X[folds == k]) == y[folds == k])))
    scores = [{"C": C, "gamma_factor": g, "accuracy": float(np.mean(acc[C, g])) if (C, g) in acc else 0.0}
              for C, g in pairs]
    best = max(r["accuracy"] for r in scores)
    C, g = min((r["C"], r["gamma_factor"]) for r in scores if r["accuracy"] >= best - 1e-12)
    return Hyper(C, gamma_of(g), g, scores)


def _hyper_stats(h: Hyper) -> dict:
    return {"C": h.C, "gamma": h.gamma, "gamma_factor": h.gamma_factor, "cv_accuracy": h.cv_accuracy}


def fit_machine(train: TrainingSet, param: str, bins: Bins, cfg: SVMConfig, test_fraction: float):
    """Train one classifier; returns ``(machine, stats)`` with accuracies and confusion
    (and the feature scaler and the cross-validated C and gamma when configured)."""
    t0 = time.perf_counter()
    if len(train) == 0:
        raise NotIdentifiableError(f"no simulated half cycle of this story yielded, so the {param} classifier has "
                                   "nothing to learn from; the record is too weakly nonlinear for the classifiers")
    y = bins.label(getattr(train, param))
    test = split(train, test_fraction)
    scaler = scaler_of(train.X[~test]) if cfg.standardize else None
    X = apply_scaler(train.X, scaler)
    extra: dict = {"scaler": scaler}
    if len(np.unique(y[~test])) < 2:  # a single class: nothing to learn
        machine = None
        acc_tr = acc_te = 1.0
        conf = np.zeros((bins.n, bins.n))
    else:
        h = choose_hyper(X[~test], y[~test], cfg)
        extra.update(_hyper_stats(h))
        machine = make_svc(cfg, h.C, h.gamma).fit(X[~test], y[~test])
        acc_tr = float(np.mean(machine.predict(X[~test]) == y[~test]))
        pred = machine.predict(X[test]) if test.any() else np.zeros(0, int)
        acc_te = float(np.mean(pred == y[test])) if test.any() else np.nan
        conf = np.zeros((bins.n, bins.n))
        np.add.at(conf, (y[test], pred.astype(int)), 1)
    stats = {"train_accuracy": acc_tr, "test_accuracy": acc_te, "confusion": conf, "n_train": int((~test).sum()),
             "n_test": int(test.sum()), "seconds": time.perf_counter() - t0,
             "single": int(y[0]) if machine is None else -1, **extra}
    return machine, stats


def fit_ensemble(train: TrainingSet, param: str, bins: Bins, cfg: SVMConfig, test_fraction: float,
                 seed: int = 0):
    """``cfg.n_bags`` machines, each on a random ``cfg.bag_fraction`` of the training samples,
    with the feature scaler and C chosen once on all of them (as :func:`fit_machine`); one
    machine on all samples when ``n_bags`` is 1. Returns ``(machines or None, stats)``; the
    accuracies are the ensemble's (majority of the bags)."""
    if cfg.n_bags <= 1:
        machine, stats = fit_machine(train, param, bins, cfg, test_fraction)
        return (None if machine is None else [machine]), stats
    t0 = time.perf_counter()
    if len(train) == 0:
        raise NotIdentifiableError(f"no training sample for the {param} classifier")
    y = bins.label(getattr(train, param))
    test = split(train, test_fraction)
    idx = np.flatnonzero(~test)
    scaler = scaler_of(train.X[idx]) if cfg.standardize else None
    X = apply_scaler(train.X, scaler)
    base = {"n_train": int(idx.size), "n_test": int(test.sum()), "scaler": scaler}
    if len(np.unique(y[idx])) < 2:
        return None, {**base, "train_accuracy": 1.0, "test_accuracy": 1.0, "confusion": np.zeros((bins.n, bins.n)),
                      "seconds": time.perf_counter() - t0, "single": int(y[0])}
    h = choose_hyper(X[idx], y[idx], cfg)
    rng = np.random.default_rng(seed)
    subs = [rng.choice(idx, size=max(int(cfg.bag_fraction * idx.size), 2), replace=False) for _ in range(cfg.n_bags)]
    subs = [sub for sub in subs if len(np.unique(y[sub])) >= 2]
    machines = fit_many([make_svc(cfg, h.C, h.gamma) for _ in subs], [X[sub] for sub in subs],  # one call
                        [y[sub] for sub in subs])

    def predict(rows):
        votes = np.stack([m.predict(X[rows]).astype(int) for m in machines])
        return np.array([np.bincount(v, minlength=bins.n).argmax() for v in votes.T], dtype=int)

    pred = predict(test) if test.any() else np.zeros(0, int)
    conf = np.zeros((bins.n, bins.n))
    np.add.at(conf, (y[test], pred), 1)
    tr = idx[:: max(1, idx.size // 300)]  # training accuracy on a subset (it costs predictions)
    return machines, {**base, "train_accuracy": float(np.mean(predict(tr) == y[tr])),
                      "test_accuracy": float(np.mean(pred == y[test])) if test.any() else np.nan, "confusion": conf,
                      **_hyper_stats(h), "bags": len(machines), "single": -1,
                      "seconds": time.perf_counter() - t0}


def vote(machine, X: np.ndarray, bins: Bins, single: int = -1, scaler: dict | None = None) -> np.ndarray:
    """Votes of the measured samples ``X`` ``(sample, feature)`` for every bin: one per
    sample and machine (``machine``: a :class:`KernelSVC`, a list of them, or None for a
    single class)."""
    if machine is None:
        v = np.zeros(bins.n)
        v[single] = X.shape[0]
        return v
    out = np.zeros(bins.n)
    for m in (machine if isinstance(machine, list) else [machine]):
        pred = m.predict(apply_scaler(X, scaler)).astype(int) if X.shape[0] else np.zeros(0, int)
        out += np.bincount(pred, minlength=bins.n)
    return out


def pass_result(param: str, stage: str, bins: Bins, votes: np.ndarray, stats: dict, cached: bool,
                aggregate: str = "mean") -> PassResult:
    """Combine the votes of the measured half cycles: ``"majority"`` takes the centre of the
    most voted bin (the paper); ``"mean"`` the vote-weighted mean of the bin centres (less
    sensitive to a few noisy half cycles); ``predicted`` is the bin holding the value."""
    if votes.sum() <= 0:
        value = float(bins.centers[bins.n // 2])
    elif aggregate == "majority":
        value = float(bins.centers[int(np.argmax(votes))])
    else:
        value = float(np.sum(votes * bins.centers) / votes.sum())
    win = int(bins.label(np.array([value]))[0])
    return PassResult(param=param, stage=stage, edges=bins.edges, votes=votes, predicted=win,
                      value=value, train_accuracy=stats["train_accuracy"],
                      test_accuracy=stats["test_accuracy"], confusion=np.asarray(stats["confusion"]),
                      n_train=stats["n_train"], n_test=stats["n_test"], seconds=stats["seconds"], cached=cached)
