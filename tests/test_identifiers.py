"""Alternative identifiers behind one interface.

Default run, on a short case (a 2-story building, an 8 s window of a real record at 0.62 g,
200 Hz, small settings): the scikit-learn contract of every identifier; recovery of the true
parameters of noise-free data within 1 % by the gradient identifier, the UKF and HLA+SVM with
its replay refinement; the forward-mode Jacobian against finite differences (truncated at
segment starts, and the full-trajectory one once the carried sensitivities have crossed every
segment); the segmented response against the compiled simulator; the unscented transform
against the exact moments of a linear map; the comparison study end to end on a tiny config.

Slow (``-m slow``): the acceptance test, every identifier on noise-free Table 1 data
from three records, within 1 % (HLA+SVM alone is held to its bin resolution instead).
"""

from __future__ import annotations

import importlib.util
import inspect

import numpy as np
import pytest
import torch
from conftest import RECORDS, REPO, paper_record, window
from scipy import signal

from hlaid.baselines import IDENTIFIERS, get_identifier
from hlaid.baselines import _space as sp
from hlaid.baselines.gradient import (
    GradientIdentifier,
    OutputErrorProblem,
    arias_window,
    filtered,
    zero_phase_gain,
)
from hlaid.baselines.ukf import UKFIdentifier, sigma_weights
from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.estimators import HLASVMIdentifier, NotFittedError
from hlaid.identify import IdentifyConfig, OuterConfig, TrainingConfig
from hlaid.model import Building, Damping
from hlaid.simulate import simulate_response
from hlaid.studies import compare
from hlaid.synthetic import simulate_measurement

TWO_STORY = {"mass": [20.0, 15.0], "k0": [2.0e4, 1.5e4], "alpha": [0.2, 0.15], "p": [2.0, 1.6], "dy": [6.0, 4.0],
                 "delta_eta": [0.8, 1.0]}
SMALL_HLA = IdentifyConfig(training=TrainingConfig(samples=60, n_segments=8),
                           outer=OuterConfig(max_iterations=1))


def factories(cache: str) -> dict:
    """Every identifier with small settings for the short case."""
    return {
        "hlasvm": lambda: HLASVMIdentifier(config=SMALL_HLA, refine="none", cache_dir=cache),
        "hlasvm_replay": lambda: HLASVMIdentifier(config=SMALL_HLA, refine=None, cache_dir=cache),
        "gradient": lambda: GradientIdentifier(n_candidates=64, n_starts=2, max_iterations=15, segment_s=0.25),
        "ukf": lambda: UKFIdentifier(n_passes=1),
    }


NAMES = ("hlasvm", "hlasvm_replay", "gradient", "ukf")
EXACT = ("hlasvm_replay", "gradient", "ukf")
"""Identifiers whose fixed point is the truth on noise-free data."""


@pytest.fixture(scope="module")
def two_story() -> Building:
    return Building(**TWO_STORY, name="two-story")


@pytest.fixture(scope="module")
def short_meas(two_story):
    return simulate_measurement(two_story, window(paper_record("kocaeli-1999-dzc180"), 8.0, before_peak=3.0),
                                noise_rms=0.0)


@pytest.fixture(scope="module")
def fitted(short_meas, tmp_path_factory):
    """Every identifier fitted once on the short case (``fit`` must return the identifier)."""
    make = factories(str(tmp_path_factory.mktemp("svm-cache")))
    out = {}
    for name in NAMES:
        est = make[name]()
        assert est.fit(short_meas) is est
        out[name] = est
    return out


def max_error(b: Building, truth: Building) -> float:
    return max(float(np.max(np.abs(np.asarray(getattr(b, k)) / np.asarray(getattr(truth, k)) - 1)))
               for k in sp.FIELDS)


# ---------------------------------------------------------------------- the interface
@pytest.mark.parametrize("name", NAMES)
def test_unfitted_and_params(name, short_meas):
    from sklearn.base import clone as sk_clone

    est = factories("")[name]()
    with pytest.raises(NotFittedError, match="not fitted"):
        est.predict(paper_record("elcentro-1940-ns"))
    with pytest.raises(NotFittedError):
        est.score(short_meas)
    params = est.get_params()
    assert list(params) == [p for p in inspect.signature(type(est).__init__).parameters if p != "self"]
    twin = sk_clone(est)
    assert type(twin) is type(est) and twin.get_params().keys() == params.keys() and not hasattr(twin, "clone_")
    key = next(iter(params))
    assert est.set_params(**{key: params[key]}) is est
    with pytest.raises(ValueError, match="no parameter"):
        est.set_params(not_a_setting=1)
    assert repr(est).startswith(type(est).__name__ + "(")


@pytest.mark.parametrize("name", NAMES)
def test_identifiers_are_sklearn_estimators(name, fitted):
    """``BaseEstimator`` subclasses: a clone with changed parameters keeps them and is unfitted;
    scikit-learn's ``check_is_fitted`` follows ``clone_``."""
    from sklearn.base import BaseEstimator
    from sklearn.base import clone as sk_clone
    from sklearn.exceptions import NotFittedError as SkNotFittedError
    from sklearn.utils.validation import check_is_fitted

    est = factories("")[name]()
    assert isinstance(est, BaseEstimator) and issubclass(NotFittedError, SkNotFittedError)
    key = "tensorboard"
    est.set_params(**{key: "runs/x"})
    twin = sk_clone(est)
    assert twin.get_params()[key] == "runs/x" and twin.get_params().keys() == est.get_params().keys()
    with pytest.raises(SkNotFittedError):
        check_is_fitted(twin)
    check_is_fitted(fitted[name])
    assert not any(k.endswith("_") for k in vars(twin))
    assert all(k.endswith("_") for k in set(vars(fitted[name])) - set(est.get_params()))


def test_registry_names_every_identifier():
    from hlaid.cli.identify import METHODS

    assert set(IDENTIFIERS) == set(NAMES)
    assert set(METHODS) <= set(IDENTIFIERS)  # the CLI's --method choices are registered identifiers
    ukf = get_identifier("ukf", n_passes=2)
    assert isinstance(ukf, UKFIdentifier) and ukf.n_passes == 2
    assert get_identifier("hlasvm").refine == "none" and get_identifier("hlasvm_replay").refine is None
    with pytest.raises(InputError, match="unknown identifier 'svm'; expected one of .*'hlasvm'.*'gradient'.*'ukf'"):
        get_identifier("svm")


@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_cli_identify_method(two_story, short_meas, tmp_path, capsys):
    """``hlaid identify --method ukf`` writes a clone file like the default method's."""
    from hlaid.cli.app import main

    meas = short_meas.save(tmp_path / "m.npz")
    out = tmp_path / "clone.json"
    assert main(["identify", str(meas), "-o", str(out), "--method", "ukf", "-q"]) == 0
    clone = Clone.load(out)
    assert clone.building.n_stories == 2 and clone.provenance["identifier"].startswith("UKFIdentifier(")
    assert max_error(clone.building, two_story) < 0.05
    assert main(["identify", str(meas), "-o", str(out), "--method", "ukf", "-q"]) == 2  # no overwrite
    assert "--force" in capsys.readouterr().err
    assert main(["identify", str(meas), "-o", str(tmp_path / "c2.json"), "--method", "ukf",
                 "--config", str(REPO / "configs" / "identify.yaml")]) == 2
    assert "--config configures --method hlasvm" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["identify", str(meas), "-o", str(tmp_path / "c3.json"), "--method", "svm"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "hlasvm" in err and "gradient" in err and "ukf" in err
    assert not (tmp_path / "c2.json").exists() and not (tmp_path / "c3.json").exists()


@pytest.mark.parametrize("name", NAMES)
def test_fitted_contract(name, fitted, short_meas, two_story):
    est = fitted[name]
    assert isinstance(est.clone_, Clone) and est.fit_seconds_ > 0
    b = est.clone_.building
    assert b.n_stories == 2 and np.allclose(b.mass, short_meas.mass) and not est.clone_.mass_normalised
    unseen = window(paper_record("elcentro-1940-ns"), 6.0)
    r = est.predict(unseen)
    assert r.acc.shape == (1, unseen.npts, 2) and r.status[0] == 0
    assert est.score(short_meas) > (0.999 if name in EXACT else 0.9)
    Clone.from_dict(est.clone_.to_dict())  # the clone file round-trips


@pytest.mark.parametrize("name", EXACT)
def test_recovers_noise_free_short_case(name, fitted, two_story):
    """The fixed point is the truth: within 1 % on every story parameter (measured: < 0.1 %)."""
    assert max_error(fitted[name].clone_.building, two_story) < 0.01


def test_bad_settings_are_one_line_errors(short_meas):
    with pytest.raises(InputError, match="init = 'nope'"):
        GradientIdentifier(init="nope").fit(short_meas)
    with pytest.raises(InputError, match="n_starts = 9"):
        GradientIdentifier(n_starts=9, n_candidates=4).fit(short_meas)
    with pytest.raises(InputError, match="prior_std"):
        UKFIdentifier(prior_std=(1.0, 1.0)).fit(short_meas)


# ---------------------------------------------------------------------- gradient internals
def test_reparameterisation_keeps_every_coordinate_valid():
    rng = np.random.default_rng(0)
    k0_ref, dy_ref = np.array([1e4, 2e4]), np.array([5.0, 3.0])
    theta = torch.as_tensor(rng.normal(0, 4, size=(200, 5, 2)))
    v = sp.values_numpy(sp.from_unconstrained(theta, k0_ref, dy_ref))
    assert np.all((v["alpha"] > 0) & (v["alpha"] < 1)) and np.all(v["p"] > 1)
    assert np.all(v["k0"] > 0) and np.all(v["dy"] > 0) and np.all(v["delta_eta"] > 0)
    known = sp.KnownPart(mass=np.array([10.0, 10.0]), mass_normalised=False, height=None, pdelta=None,
                         damping=Damping(), kg=np.zeros(2), name="")
    known.building({k: x[0] for k, x in v.items()})  # a valid Building
    mild = theta.clamp(-3, 3)
    back = sp.to_unconstrained(sp.values_numpy(sp.from_unconstrained(mild, k0_ref, dy_ref)), k0_ref, dy_ref)
    assert np.allclose(back, mild.numpy(), atol=1e-8)


@pytest.fixture(scope="module")
def problem(short_meas, two_story):
    """The first 2 s of the short case (from rest) in 4 segments, coordinates 10 % off the truth."""
    known = sp.known_part(short_meas)
    prob = OutputErrorProblem(short_meas, known, (0.1, 20.0), (0, 400), segment_s=0.5)
    truth = {k: np.asarray(getattr(two_story, k))[None] for k in sp.FIELDS}
    off = {k: v * (1.1 if k != "alpha" else 0.9) for k, v in truth.items()}
    return prob, torch.as_tensor(sp.to_unconstrained(off, two_story.k0, two_story.dy)), two_story


def test_segments_reproduce_the_compiled_simulator(problem):
    prob, theta, b = problem
    values = sp.from_unconstrained(theta, b.k0, b.dy)
    y0, ok = prob.start_states(sp.values_numpy(values))
    with torch.no_grad():
        acc, _ = prob.accelerations(values, torch.as_tensor(y0))
    ref = simulate_response(prob.known.building({k: v[0] for k, v in sp.values_numpy(values).items()}),
                            prob.ground, substeps=prob.substeps)
    want = ref.acc[0, prob.i0:prob.i1]
    assert ok.all() and np.max(np.abs(acc[0].numpy() - want)) < 1e-8 * np.max(np.abs(want))


def _full_residuals(prob, theta, b):
    """Residuals of the whole window at ``theta`` (start states from the simulator)."""
    values = sp.from_unconstrained(theta, b.k0, b.dy)
    y0, _ = prob.start_states(sp.values_numpy(values))
    with torch.no_grad():
        return prob.residuals(prob.accelerations(values, torch.as_tensor(y0))[0])[0]


@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_forward_mode_jacobian_truncated_then_full(problem):
    """Zero seeds give the Jacobian with segment starts held fixed (finite differences with
    fixed starts); after one pass per segment the carried seeds give the full-trajectory
    Jacobian (finite differences through the simulator), which differs from the truncated one."""
    prob, theta, b = problem
    P = theta[0].numel()
    carried = torch.zeros(1, P, prob.n_segments, 4 * 2, dtype=torch.float64)
    r, J_trunc, ok, carried = prob.jacobian(theta, b.k0, b.dy, carried)
    values = sp.from_unconstrained(theta, b.k0, b.dy)
    y0 = torch.as_tensor(prob.start_states(sp.values_numpy(values))[0])
    h = 1e-6
    fd_trunc, fd_full = [], []
    cols = [f * 2 + f % 2 for f in range(5)]  # one column per parameter kind, stories alternating
    for j in cols:
        e = torch.zeros_like(theta).reshape(-1)
        e[j] = h
        e = e.reshape(theta.shape)
        with torch.no_grad():
            rp = prob.residuals(prob.accelerations(sp.from_unconstrained(theta + e, b.k0, b.dy), y0)[0])[0]
            rm = prob.residuals(prob.accelerations(sp.from_unconstrained(theta - e, b.k0, b.dy), y0)[0])[0]
        fd_trunc.append((rp - rm) / (2 * h))
        fd_full.append((_full_residuals(prob, theta + e, b) - _full_residuals(prob, theta - e, b)) / (2 * h))
    fd_trunc, fd_full = torch.stack(fd_trunc, dim=1), torch.stack(fd_full, dim=1)
    scale = fd_full.abs().max()
    assert ok.all() and float((J_trunc[0][:, cols] - fd_trunc).abs().max() / scale) < 1e-5
    for _ in range(prob.n_segments - 1):
        r2, J, ok, carried = prob.jacobian(theta, b.k0, b.dy, carried)
    assert torch.allclose(r2, r)
    assert float((J[0][:, cols] - fd_full).abs().max() / scale) < 1e-4
    assert float((J_trunc[0][:, cols] - fd_full).abs().max() / scale) > 1e-2


def test_frequency_domain_filter_is_forward_backward_butterworth():
    """``|H|^2`` in the frequency domain equals sosfiltfilt away from the record's ends."""
    dt = 0.005
    x = np.random.default_rng(1).standard_normal(4000)
    gain = torch.as_tensor(zero_phase_gain(8192, dt, (0.1, 20.0)))
    y = filtered(torch.as_tensor(x)[None, :, None], gain)[0, :, 0].numpy()
    from hlaid.signal import butter_sos
    ref = signal.sosfiltfilt(butter_sos((0.1, 20.0), dt, 4), x, padtype=None)
    mid = slice(1500, 2500)
    assert np.sqrt(np.mean((y[mid] - ref[mid]) ** 2)) < 0.02 * np.sqrt(np.mean(ref[mid] ** 2))


def test_arias_window_brackets_the_strong_motion():
    gm = paper_record("elcentro-1940-ns")
    i0, i1 = arias_window(gm.acc, gm.dt, (0.05, 0.95))
    e = np.cumsum(gm.acc**2) / np.sum(gm.acc**2)
    assert e[i0] < 0.05 and e[min(i1, gm.npts - 1) - 1] > 0.95 and i1 - i0 < gm.npts


# ---------------------------------------------------------------------- UKF internals
@pytest.mark.parametrize("alpha,kappa", [(1.0, 0.0), (0.5, 0.0), (0.1, 1.0)])
def test_unscented_transform_is_exact_for_linear_maps(alpha, kappa):
    rng = np.random.default_rng(2)
    L = 6
    m = torch.as_tensor(rng.normal(size=L))
    A0 = rng.normal(size=(L, L))
    P = torch.as_tensor(A0 @ A0.T + 0.1 * np.eye(L))
    gamma, Wm, Wc = sigma_weights(L, alpha, 2.0, kappa)
    S = torch.linalg.cholesky(P).T
    X = m[None] + gamma * torch.cat([torch.zeros(1, L, dtype=m.dtype), S, -S])
    A = torch.as_tensor(rng.normal(size=(3, L)))
    Y = X @ A.T
    yb = Wm @ Y
    assert torch.allclose(Wm.sum(), torch.tensor(1.0, dtype=Wm.dtype))
    assert torch.allclose(yb, A @ m) and torch.allclose(((Y - yb).T * Wc) @ (Y - yb), A @ P @ A.T)


# ---------------------------------------------------------------------- the study
def _script():
    spec = importlib.util.spec_from_file_location("compare_identifiers", REPO / "scripts" / "compare_identifiers.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_an_identifier_that_raises_is_a_failure_with_its_reason(monkeypatch, two_story):
    class Broken(HLASVMIdentifier):
        def fit(self, measurement):
            raise RuntimeError("boom\nsecond line")

    monkeypatch.setitem(IDENTIFIERS, "broken", Broken)
    gm = window(paper_record("kocaeli-1999-dzc180"), 4.0)
    case = compare.Case(name="c", structure="two", building=two_story, motion=gm, noise=0.0, seed=0)
    (o,) = compare.run_case(case, ["broken"], {}, window(paper_record("elcentro-1940-ns"), 4.0))
    assert o.failed and o.reason == "RuntimeError: boom second line" and o.errors is None


@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_comparison_study_end_to_end(tmp_path, capsys):
    cfg = tmp_path / "study.yaml"
    cfg.write_text(f"""identifiers: [ukf]
settings: {{ukf: {{n_passes: 1}}}}
table1: {REPO / 'configs' / 'poc_3story.yaml'}
unseen_record: builtin:elcentro-1940-ns
window_s: 7.0
groups:
  - {{structure: table1, records: [builtin:kocaeli-1999-dzc180], noise: [0.05], seeds: [3]}}
""")
    script = _script()
    out = tmp_path / "out"
    assert script.main(["--config", str(cfg), "-o", str(out), "-q"]) == 0
    md = (out / "summary.md").read_text()
    assert "### Noise 5 % RMS" in md and "| UKF | 1 | 0 |" in md
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[0].startswith("case,identifier")
    assert {f.name for f in (out / "figures").iterdir()} == set(script.FIGURES)
    assert any(p.name.startswith("events.out.tfevents") for p in (out / "tensorboard").iterdir())
    assert script.main(["--config", str(cfg), "-o", str(out), "-q"]) == 2  # no overwrite without --force
    assert "--force" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text("identifiers: [ukf]\nsettings: {ukf: {n_pases: 1}}\ngroups: [{records: [builtin:x]}]\n")
    assert script.main(["--config", str(bad), "-o", str(tmp_path / "o2")]) == 2
    assert "n_pases" in capsys.readouterr().err
    bad.write_text("identifiers: [ukf, svm]\ngroups: [{records: [builtin:x]}]\n")
    assert script.main(["--config", str(bad), "-o", str(tmp_path / "o2")]) == 2
    err = capsys.readouterr().err
    assert "bad.yaml" in err and "svm" in err and "Traceback" not in err


def test_default_study_config_loads():
    cfg = compare.load_compare_config(REPO / "configs" / "compare.yaml")
    assert cfg.identifiers == list(IDENTIFIERS) and {0.0, 0.05, 0.10, 0.20} <= {
        n for g in cfg.groups for n in g.noise}
    for name in cfg.identifiers:
        compare.make_identifier(name, cfg.settings.get(name), base_dir=REPO / "configs")


# ---------------------------------------------------------------------- acceptance (slow)
@pytest.mark.slow
@pytest.mark.parametrize("record", RECORDS)
def test_acceptance_noise_free_table1(record, table1, tmp_path):
    """The identifiers recover noise-free Table 1 parameters within 1 % (a 14 s window
    of each record at 0.62 g, 200 Hz, default settings).

    The paper's method alone (HLA+SVM without the replay refinement) does not: its classes
    are bins of 0.01 (alpha) and 0.1 (p) and delta_eta, dy follow from HLA's k0 and
    regressions (measured: 27-52 % worst, 9-13 % mean over the 15 parameters). It is held to
    a mean error below 15 %, enough for the refinement that starts from it to reach 1 %."""
    meas = simulate_measurement(table1, window(paper_record(record), 14.0, before_peak=4.0), noise_rms=0.0)
    cache = str(tmp_path / "cache")
    ests = {"hlasvm": HLASVMIdentifier(refine="none", cache_dir=cache),
            "hlasvm_replay": HLASVMIdentifier(refine=None, cache_dir=cache),
            "gradient": GradientIdentifier(), "ukf": UKFIdentifier()}
    worst, mean = {}, {}
    for name, est in ests.items():
        b = est.fit(meas).clone_.building
        e = np.concatenate([np.abs(np.asarray(getattr(b, k)) / np.asarray(getattr(table1, k)) - 1) for k in sp.FIELDS])
        worst[name], mean[name] = float(e.max()), float(e.mean())
        print(f"{record} {name}: max |error| {100 * worst[name]:.3f} %, mean {100 * mean[name]:.3f} % "
              f"in {est.fit_seconds_:.1f} s")
    for name in EXACT:
        assert worst[name] < 0.01, (name, worst[name])
    assert mean["hlasvm"] < 0.15
