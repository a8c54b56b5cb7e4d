"""The collapse-capable story law (hlaid.model.collapse) against independent references.

The references below are written here, independently of hlaid.model._equations: the modified-IMK
backbone as straight lines (np.where), the Bouc-Wen ODE and the peak memory integrated by scipy's
solve_ivp at tight tolerance (the memory as ``xi' = xd`` while ``x >= xi`` and moving outwards).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import paper_record
from scipy.integrate import solve_ivp

from hlaid.errors import InputError
from hlaid.model import BoucWenBuilding, Building, BuildingTensors
from hlaid.model.collapse import COLLAPSE_MODELS, CollapseModel, get_collapse_model
from hlaid.simulate import simulate_response
from hlaid.simulate.path import drive_story

H = 3000.0
STORY = {"mass_t": 17.524, "k0": 1.94e4, "alpha": 0.05, "p": 2.5, "dy": 7.0, "delta_eta": 0.7, "height_mm": H}
MODEL = CollapseModel(theta_p=0.02, theta_pc=0.06, kappa=0.3, theta_u=0.07)


def backbone(xi, s=STORY, c=MODEL):
    """The modified-IMK backbone [N] written as straight lines: cap, post-cap slope, residual, drop."""
    k0, a, dy, h = s["k0"], s["alpha"], s["dy"], s["height_mm"]
    xc = dy + c.theta_p * h
    fc = (1 - a) * k0 * dy + a * k0 * xc
    kpc = -fc / (c.theta_pc * h)
    fr, xu = c.kappa * k0 * dy, c.theta_u * h
    post = np.maximum(fc + kpc * (xi - xc), np.where(xi <= xu, fr, np.maximum(fr + kpc * (xi - xu), 0.0)))
    return np.where(xi <= xc, np.inf, post), xc, fc, kpc, fr, xu


def kinks(s=STORY, c=MODEL):
    """(drift, slope change) of the backbone's kinks, found numerically from the lines above."""
    x = np.linspace(0.0, 2000.0, 2_000_001)
    b, xc, fc, *_ = backbone(x, s, c)
    b = np.where(x <= xc, fc + s["alpha"] * s["k0"] * (x - xc), b)  # the yielded Bouc-Wen line before
    slope = np.diff(b) / np.diff(x)
    j = np.flatnonzero(np.abs(np.diff(slope)) > 1e-6)
    out = []
    for i in j:
        x0 = x[i + 1]
        if out and x0 - out[-1][0] < 1e-2:
            continue
        out.append((x0, slope[i + 5] - slope[i - 5]))
    return out


class Gap:
    """Elastic-perfectly-plastic gap of unit stiffness yielding at ``xj`` both ways; the gap grows
    with the plastic deformation (OpenSees ElasticPPGap with damage), by return mapping."""

    def __init__(self, xj):
        self.xj, self.gp, self.gn = xj, 0.0, 0.0

    def __call__(self, x):
        h = 0.0
        if x - self.gp > 0:
            h = min(x - self.gp, self.xj)
            if x - self.gp > self.xj:
                self.gp = x - self.xj
        if -x - self.gn > 0:
            h = -min(-x - self.gn, self.xj)
            if -x - self.gn > self.xj:
                self.gn = -x - self.xj
        return h


def collapse_part(x, s=STORY, c=MODEL):
    """Force of the gap springs along a sampled drift path [N]."""
    springs = [(Gap(xj), dk) for xj, dk in kinks(s, c)]
    return np.array([sum(dk * (xi - g(xi)) for g, dk in springs) for xi in x])


def ref_path_force(x_of_t, xd_of_t, t, s=STORY):
    """solve_ivp of z, e along a drift path, then the gap springs along the sampled path."""
    k0, a, p, dy, de, m = s["k0"], s["alpha"], s["p"], s["dy"], s["delta_eta"], s["mass_t"]

    def rhs(tt, y):
        z, e = y
        xd = xd_of_t(tt)
        eta = 1 + de * 1e-6 * (1 - a) * k0 / m * e
        load = 1.0 if xd * z > 0 else 0.0
        return [xd * (1 - load * abs(z / dy) ** p) / eta, z * xd]

    sol = solve_ivp(rhs, (t[0], t[-1]), [0.0, 0.0], t_eval=t, rtol=1e-11, atol=1e-11, max_step=t[1] - t[0],
                    method="DOP853")
    z = sol.y[0]
    x = x_of_t(t)
    fbw = a * k0 * x + (1 - a) * k0 * z
    return fbw + collapse_part(x, s), fbw


def _building(s=STORY, c=MODEL, pdelta=True):
    return Building.from_stories([s], pdelta=pdelta, collapse=c)


# ------------------------------------------------------------------ registry and validation
def test_registry_names_and_errors():
    assert set(COLLAPSE_MODELS) >= {"none", "steel-mrf", "rc-frame"}
    assert get_collapse_model("none") is None and get_collapse_model(None) is None
    for name, m in COLLAPSE_MODELS.items():
        assert m is None or (m.name == name and m.source)
    with pytest.raises(InputError, match="unknown collapse model 'steel'.*steel-mrf"):
        get_collapse_model("steel")
    user = get_collapse_model({"theta_p": 0.03, "theta_pc": 0.1, "kappa": 0.2, "theta_u": 0.08})
    assert user == CollapseModel(theta_p=0.03, theta_pc=0.1, kappa=0.2, theta_u=0.08)
    for bad, match in (({"theta_p": 0.03}, "missing"), ({**user.to_dict(), "cap": 1}, "unknown field"),
                       ({**user.to_dict(), "kappa": 1.2}, "kappa"), ({**user.to_dict(), "theta_pc": -0.1}, "theta_pc"),
                       ({**user.to_dict(), "theta_u": 0.01}, "theta_u")):
        with pytest.raises(InputError, match=match):
            get_collapse_model(bad)
    with pytest.raises(InputError, match="needs story heights"):
        Building.from_stories([{k: v for k, v in STORY.items() if k != "height_mm"}], collapse="steel-mrf")
    with pytest.raises(InputError, match="below the capping drift"):  # theta_u inside dy/h + theta_p
        _building(c=CollapseModel(theta_p=0.02, theta_pc=0.06, kappa=0.3, theta_u=0.021))
    b = _building()
    assert Building.from_dict(b.to_dict()).collapse == MODEL


# ------------------------------------------------------------------ "none" is the paper's law
@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_none_keeps_the_paper_law(table1):
    b = table1.replace(height=[H] * 3, pdelta=True)
    gm = paper_record("elcentro-1940-ns")
    r0 = simulate_response(b, gm, [0.5, 1.0])
    assert r0.final_state.shape == (2, 12)  # no collapse memory: the 4*story state of the paper's law
    # a collapse model whose cap is never reached gives the same response, to rounding
    far = CollapseModel(theta_p=0.9, theta_pc=1.0, kappa=0.5, theta_u=0.95)
    r1 = simulate_response(b.replace(collapse=far), gm, [0.5, 1.0])
    assert r1.final_state.shape == (2, 18)
    np.testing.assert_allclose(r1.drift, r0.drift, rtol=0, atol=1e-9 * np.abs(r0.drift).max())
    np.testing.assert_array_equal(r1.final_state[:, 12:15], np.abs(r1.final_state[:, 12:15]))


# ------------------------------------------------------------------ pushover (monotonic)
def test_pushover_backbone_matches_solve_ivp_and_the_imk_lines():
    T, rate = 600.0, 0.5  # push to 300 mm (10 %) at 0.5 mm/s
    t = np.linspace(0.0, T, 6001)
    r = drive_story(rate * t, velocity=np.full_like(t, rate), dt=t[1] - t[0], mass=STORY["mass_t"],
                    k0=STORY["k0"], alpha=STORY["alpha"], p=STORY["p"], dy=STORY["dy"],
                    delta_eta=STORY["delta_eta"], collapse=_building().collapse_values()[0])
    f_ref, fbw = ref_path_force(lambda tt: rate * tt, lambda tt: rate + 0 * tt, t)
    fc = backbone(0.0)[2]
    np.testing.assert_allclose(r.force[0], f_ref, rtol=0, atol=1e-7 * fc)
    # the straight lines of the backbone, where z has saturated (x > 10 dy)
    x = rate * t
    b, xc, fc, kpc, fr, xu = backbone(x)
    sat = x > 10 * STORY["dy"]
    post = sat & (x > xc)
    assert abs(r.force[0][post] - b[post]).max() < 1e-3 * fc
    pre = x <= xc
    assert abs(r.force[0][pre] - fbw[pre]).max() < 1e-7 * fc  # untouched before the cap
    assert r.force[0][np.argmin(abs(x - xc))] == pytest.approx(fc, rel=1e-3)
    i = np.flatnonzero(x > xu + fr / -kpc + 1.0)
    assert i.size and np.abs(r.force[0][i]).max() < 1e-6 * fc  # no strength left beyond the ultimate drop


# ------------------------------------------------------------------ cyclic path
def test_cyclic_path_memory_matches_solve_ivp():
    """Growing cycles past the cap: reloading does not regain the lost strength."""
    T, w = 40.0, 2 * np.pi / 8.0
    amp = lambda tt: 5.0 + 5.0 * tt  # noqa: E731  up to 205 mm
    x_of = lambda tt: amp(tt) * np.sin(w * tt)  # noqa: E731
    xd_of = lambda tt: 5.0 * np.sin(w * tt) + amp(tt) * w * np.cos(w * tt)  # noqa: E731
    t = np.linspace(0.0, T, 8001)
    r = drive_story(x_of(t), velocity=xd_of(t), dt=t[1] - t[0], mass=STORY["mass_t"], k0=STORY["k0"],
                    alpha=STORY["alpha"], p=STORY["p"], dy=STORY["dy"], delta_eta=STORY["delta_eta"],
                    substeps=4, collapse=_building().collapse_values()[0])
    f_ref, fbw = ref_path_force(x_of, xd_of, t)
    scale = np.abs(f_ref).max()
    err = np.abs(r.force[0] - f_ref).max() / scale
    assert err < 1e-5, err
    # memory: after the first excursion past the cap, reloading to smaller positive drifts does
    # not regain the Bouc-Wen strength
    x = x_of(t)
    _, xc, fc, *_ = backbone(0.0)
    first = np.argmax(x > 1.5 * xc)
    later = np.flatnonzero((np.arange(t.size) > first + 200) & (x > 0.5 * xc) & (x < 1.2 * xc) & (fbw > 0))
    assert later.size and np.all(r.force[0][later] < fbw[later] - 0.01 * fc)


# ------------------------------------------------------------------ dynamic, with P-Delta
def _ref_sdof(b: Building, gm, scale: float, t_end: float):
    s = STORY
    k0, a, p, dy, de, m = s["k0"], s["alpha"], s["p"], s["dy"], s["delta_eta"], s["mass_t"]
    kg = b.geometric_stiffness()[0]
    c = b.damping_matrix()[0, 0]
    tg = np.arange(gm.npts) * gm.dt
    ag = gm.acc * scale
    springs = kinks()

    def rhs(t, y):
        u, v, z, e, xp, xn = y
        eta = 1 + de * 1e-6 * (1 - a) * k0 / m * e
        load = 1.0 if v * z > 0 else 0.0
        f = a * k0 * u + (1 - a) * k0 * z - kg * u
        for xj, dk in springs:  # elastic-plastic gaps whose gaps are the plastic parts of the peaks
            h = np.clip(u - max(xp - xj, 0.0), 0.0, xj) - np.clip(-u - max(xn - xj, 0.0), 0.0, xj)
            f += dk * (u - h)
        return [v, -(f + c * v) / m - np.interp(t, tg, ag), v * (1 - load * abs(z / dy) ** p) / eta, z * v,
                max(v, 0.0) if u >= xp else 0.0, max(-v, 0.0) if -u >= xn else 0.0]

    t_eval = tg[tg <= t_end]
    sol = solve_ivp(rhs, (0.0, t_eval[-1]), np.zeros(6), t_eval=t_eval, method="DOP853", rtol=1e-10,
                    atol=1e-9, max_step=gm.dt)
    return sol.y[0]


@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
@pytest.mark.parametrize("scale", [2.5, 3.0])
def test_dynamic_response_matches_solve_ivp(scale):
    """One story with P-Delta under El Centro: past the cap (2.5) and into the
    residual strength, still moving (3.0)."""
    b = _building()
    gm = paper_record("elcentro-1940-ns")
    t_end = 12.0
    gm = gm.__class__(acc=gm.acc[: int(t_end / gm.dt) + 1], dt=gm.dt, name=gm.name)
    ours = simulate_response(b, gm, scale, substeps=8)
    u_ref = _ref_sdof(b, gm, scale, t_end)
    u = ours.disp[0, : u_ref.size, 0]
    peak = np.abs(u_ref).max()
    xc = backbone(0.0)[1]
    if scale > 2:
        assert peak > xc  # the case goes past the cap
    assert np.abs(u - u_ref).max() < 2e-4 * peak, (np.abs(u - u_ref).max(), peak)


# ------------------------------------------------------------------ torch module = kernel
def test_torch_module_equals_kernel(table1):
    b = table1.replace(height=[H] * 3, pdelta=True, collapse="steel-mrf")
    gm = paper_record("kocaeli-1999-dzc180")
    gm = gm.__class__(acc=gm.acc[:2000], dt=gm.dt, name=gm.name)
    a = simulate_response(b, gm, [1.0, 2.5], substeps=2)
    t = simulate_response(b, gm, [1.0, 2.5], substeps=2, backend="torch")
    assert a.final_state.shape[1] == 18
    assert np.abs(a.drift).max() > 1.2 * b.collapse_values()[:, 0].min()  # past a cap
    np.testing.assert_allclose(t.drift, a.drift, rtol=0, atol=1e-8 * np.abs(a.drift).max())
    np.testing.assert_allclose(t.force, a.force, rtol=0, atol=1e-8 * np.abs(a.force).max())
    # rates of the module are differentiable in the parameters
    P = BuildingTensors.stack([b])
    k0 = P.k0.clone().requires_grad_(True)
    m = BoucWenBuilding(BuildingTensors(**{**vars(P), "k0": k0}))
    y = torch.as_tensor(a.final_state[:1])
    m.rates(y, torch.zeros(1)).sum().backward()
    assert torch.isfinite(k0.grad).all()


# ------------------------------------------------------------------ clone file, IDA, command line
def test_clone_file_collapse_block(table1, tmp_path):
    import json

    from hlaid.clone import VERSION, Clone
    b = table1.replace(height=[H] * 3, collapse="rc-frame")
    path = Clone(building=b).save(tmp_path / "c.json")
    d = json.loads(path.read_text())
    assert d["version"] == VERSION and d["collapse"]["name"] == "rc-frame"
    assert Clone.load(path).building.collapse == COLLAPSE_MODELS["rc-frame"]
    no = Clone(building=table1.replace(height=[H] * 3)).to_dict()
    assert "collapse" not in no  # additive: files without a collapse model are unchanged
    for bad, match in (("steel", "collapse' must be a mapping"), ({**d["collapse"], "kappa": "x"}, "collapse.kappa"),
                       ({**d["collapse"], "kappa": 2.0}, "kappa")):
        path.write_text(json.dumps({**d, "collapse": bad}))
        with pytest.raises(InputError, match=match) as err:
            Clone.load(path)
        assert str(path) in str(err.value)


def test_ida_flatlines_at_a_lower_intensity_with_a_collapse_model(table1):
    from hlaid.ida import IDAConfig, run_ida
    b = table1.replace(height=[H] * 3)
    recs = ["builtin:elcentro-1940-ns", "builtin:kocaeli-1999-dzc180", "builtin:northridge-1994-mul009"]
    cfg = IDAConfig(levels=[0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0], tolerance=0.05)
    none = run_ida(b, recs, cfg)
    steel = run_ida(b, recs, cfg.replace(collapse="steel-mrf"))
    assert any("collapse model 'none'" in n for n in none.notes)
    assert any("steel-mrf" in n for n in steel.notes)
    m0 = none.collapse_fragility().median
    m1 = steel.collapse_fragility().median
    assert m1 < 0.8 * m0
    with pytest.raises(InputError, match="unknown collapse model"):
        run_ida(b, recs, cfg.replace(collapse="steel"))


def test_ida_command_collapse_flag(table1, tmp_path, capsys):
    import json

    from hlaid.cli import main
    from hlaid.clone import Clone
    path = Clone(building=table1.replace(height=[H] * 3)).save(tmp_path / "c.json")
    assert main(["ida", str(path), "--records", "builtin:elcentro-1940-ns", "--collapse", "bogus",
                 "-o", str(tmp_path / "o1")]) == 2
    assert "unknown collapse model 'bogus'" in capsys.readouterr().err
    out = tmp_path / "o2"
    assert main(["ida", str(path), "--records", "builtin:elcentro-1940-ns", "--collapse", "rc-frame",
                 "--levels", "1:3:1", "--bootstrap", "0", "--no-plots", "-o", str(out), "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["building"]["collapse"]["name"] == "rc-frame"
