"""OpenSeesPy model of an hlaid clone: a degrading Bouc-Wen shear building.

Exported by hlaid (the clone's name, the hlaid version and its parameters are the constants
at the end of this file). Standalone: needs only openseespy and numpy.
Units: N, mm, t (tonne), s (1 t * 1 mm/s^2 = 1 N); accelerations in mm/s^2 inside.

Model (hlaid docs/DESIGN section 3):
  node 0 is the fixed ground, node i floor i (one lateral DOF), with mass MASS[i-1];
  story i: zeroLength element i (node i-1 -> i, -doRayleigh 1) with
    uniaxialMaterial BoucWen alpha ko n gamma beta Ao deltaA deltaNu deltaEta
      = ALPHA, K0, P_EXP, 0.5/DY**P_EXP, 0.5/DY**P_EXP, 1, 0, 0, DELTA_ETA*1e-6/MASS
    (OpenSees' energy is (1-alpha)*ko*integral(z dx) in N*mm, hence deltaEta = delta_eta*1e-6/m);
  P-Delta: a parallel zeroLength (-doRayleigh 0) with uniaxialMaterial Elastic -PDELTA_K[i]
    (P_i/h_i: gravity load carried by story i over its height; linearised leaning column;
    all zeros when P-Delta is off);
  strength loss (COLLAPSE, hlaid's collapse model): in that parallel element, per kink j of the
    story's backbone an ElasticPPGap pair (unit stiffness, yield at +-x_j, damage) with factor
    -dk_j, and dk_j added to the Elastic stiffness: the spring force is dk_j * (x - h_j);
  damping: rayleigh a0 0 a1 0, i.e. C = a0*M + a1*K0 (initial stiffness of the Bouc-Wen springs);
  ground motion: timeSeries Path (linear between samples), pattern UniformExcitation;
  analysis: Newmark average acceleration, Newton, NormDispIncr 1e-8 mm, step dt/dt_factor.

Usage:
  python THIS_FILE RECORD [--units g] [--dt DT] [--scale S | --pga-g A] [--dt-factor 10] [--out peaks.json]
RECORD is a PEER .AT2 file (units g), or a text file: two columns (time, acceleration) or one
column (give --dt); --units is the acceleration unit of a text file (g, m/s^2, cm/s^2, mm/s^2).
Prints (and with --out writes as JSON) the peak and residual drift of every story.

Imported (``import_module`` or ``runpy``), the file only defines the model; :func:`analyze`
runs it: ``analyze(openseespy.opensees, MODEL, ag, dt)``.
"""

import argparse
import json
import os
import re
import shutil
import sys
import tempfile

import numpy as np

G_MM_S2 = 9806.65
UNITS = {"g": G_MM_S2, "m/s^2": 1000.0, "m/s2": 1000.0, "cm/s^2": 10.0, "cm/s2": 10.0, "gal": 10.0,
         "mm/s^2": 1.0, "mm/s2": 1.0}
"""Acceleration units of a text record, in mm/s^2."""


def build(ops, model):
    """Create the model in OpenSees (after wiping any existing one).

    Parameters
    ----------
    ops : the ``openseespy.opensees`` module
    model : dict with the keys ``mass``, ``k0``, ``alpha``, ``p_exp``, ``dy``, ``delta_eta``,
        ``pdelta_k`` (each a list, one value per story), ``collapse`` (per story a list of
        ``(x_j [mm], dk_j [N/mm])`` gap springs, or None) and ``rayleigh`` (``(a0, a1)``)
    """
    mass, dy, p_exp = model["mass"], model["dy"], model["p_exp"]
    pdelta_k, collapse = model["pdelta_k"], model["collapse"]
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    ops.node(0, 0.0)
    ops.fix(0, 1)
    for i in range(len(mass)):
        ops.node(i + 1, 0.0)
        ops.mass(i + 1, mass[i])
        g = 0.5 / dy[i] ** p_exp[i]
        ops.uniaxialMaterial("BoucWen", i + 1, model["alpha"][i], model["k0"][i], p_exp[i], g, g, 1.0, 0.0, 0.0,
                             model["delta_eta"][i] * 1e-6 / mass[i])
        ops.element("zeroLength", i + 1, i, i + 1, "-mat", i + 1, "-dir", 1, "-doRayleigh", 1)
        springs = collapse[i] if collapse else []
        if springs:  # strength loss: gap springs dk*(x - h), with P-Delta, in one parallel material
            tag = 10000 * (i + 1)
            ops.uniaxialMaterial("Elastic", tag, sum(dk for _, dk in springs) - pdelta_k[i])
            tags, factors = [tag], [1.0]
            for j, (xj, dk) in enumerate(springs):
                for side, sign in enumerate((1.0, -1.0)):
                    t = tag + 2 * j + side + 1
                    ops.uniaxialMaterial("ElasticPPGap", t, 1.0, sign * xj, 0.0, 0.0, "damage")
                    tags.append(t)
                    factors.append(-dk)
            ops.uniaxialMaterial("Parallel", 1000 + i + 1, *tags, "-factors", *factors)
            ops.element("zeroLength", 1000 + i + 1, i, i + 1, "-mat", 1000 + i + 1, "-dir", 1, "-doRayleigh", 0)
        elif pdelta_k[i] != 0.0:
            ops.uniaxialMaterial("Elastic", 1000 + i + 1, -pdelta_k[i])
            ops.element("zeroLength", 1000 + i + 1, i, i + 1, "-mat", 1000 + i + 1, "-dir", 1, "-doRayleigh", 0)
    ops.rayleigh(model["rayleigh"][0], 0.0, model["rayleigh"][1], 0.0)


def story_drifts(ops, n):
    """Current drift of stories ``1..n`` [mm] (deformation of the Bouc-Wen elements)."""
    return [ops.eleResponse(i + 1, "deformation")[0] for i in range(n)]


def analyze(ops, model, ag, dt, dt_factor=10, histories=False):
    """Run the model under ground acceleration ``ag`` [mm/s^2] sampled at ``dt`` [s].

    Parameters
    ----------
    ops : the ``openseespy.opensees`` module
    model : the model's parameters (see :func:`build`)
    ag : (time,) ground acceleration [mm/s^2]
    dt : sample interval of ``ag`` [s]
    dt_factor : analysis steps per sample
    histories : also return the drift at every record sample (slower: steps in Python)

    Returns
    -------
    dict with ``peak_drift`` and ``residual_drift`` [mm] per story, ``ok`` (converged to the
    end), ``time`` reached [s] and ``drift`` (time, story) with ``histories``, else None.
    """
    n = len(model["mass"])
    ag = [float(v) for v in ag]
    build(ops, model)
    ops.timeSeries("Path", 1, "-dt", float(dt), "-values", *ag)
    ops.pattern("UniformExcitation", 1, 1, "-accel", 1)
    ops.constraints("Plain")
    ops.numberer("Plain")
    ops.system("BandGeneral")
    ops.test("NormDispIncr", 1e-8, 50)
    ops.algorithm("Newton")
    ops.integrator("Newmark", 0.5, 0.25)
    ops.analysis("Transient")
    h = float(dt) / dt_factor
    steps = (len(ag) - 1) * dt_factor
    if not histories:
        out = _analyze_envelope(ops, n, steps, h)
        ops.wipe()
        return out
    peak = [0.0] * n
    drift = [[0.0] * n]
    ok = True
    for k in range(steps):
        if ops.analyze(1, h) != 0:
            ok = False
            break
        d = story_drifts(ops, n)
        peak = [max(p, abs(x)) for p, x in zip(peak, d, strict=True)]
        if (k + 1) % dt_factor == 0:
            drift.append(d)
    out = {"peak_drift": peak, "residual_drift": story_drifts(ops, n), "ok": ok, "time": ops.getTime(),
           "drift": drift}
    ops.wipe()
    return out


def _analyze_envelope(ops, n, steps, h):
    """All ``steps`` at once; the peaks from an EnvelopeElement recorder (every analysis step)."""
    tmp = tempfile.mkdtemp(prefix="hlaid-opensees-")
    env = os.path.join(tmp, "envelope.out")
    try:
        ops.recorder("EnvelopeElement", "-file", env, "-precision", 12, "-ele", *range(1, n + 1), "deformation")
        ok = ops.analyze(steps, h) == 0
        residual = story_drifts(ops, n)
        t_end = ops.getTime()
        ops.remove("recorders")
        rows = np.loadtxt(env, ndmin=2)
        peak = [float(v) for v in rows[-1][:n]]  # rows: min, max, abs max
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {"peak_drift": peak, "residual_drift": residual, "ok": ok, "time": t_end, "drift": None}


def read_record(path, units=None, dt=None):
    """(dt [s], acceleration [mm/s^2]) of a PEER .AT2 file or a one/two-column text file."""
    with open(path) as fh:
        lines = fh.read().splitlines()
    if path.lower().endswith(".at2"):
        m = re.search(r"NPTS\s*=\s*(\d+).*?DT\s*=\s*([-+0-9.eE]+)", lines[3], re.I)
        if not m:
            sys.exit(f"{path}: line 4 should give NPTS and DT")
        values = np.array(" ".join(lines[4:]).split(), dtype=float)
        return float(m.group(2)), values * UNITS[(units or "g").lower()]
    rows = [ln.replace(",", " ").split() for ln in lines if ln.strip() and ln.strip()[0] not in "#%"]
    data = np.array(rows, dtype=float)
    if units is None:
        sys.exit(f"{path}: give the acceleration units with --units (g, m/s^2, cm/s^2, mm/s^2)")
    if data.ndim == 2 and data.shape[1] >= 2:
        return float(data[1, 0] - data[0, 0]), data[:, 1] * UNITS[units.lower()]
    if dt is None:
        sys.exit(f"{path}: one column of accelerations needs --dt")
    return float(dt), data.reshape(-1) * UNITS[units.lower()]


def main(model, argv=None):
    """Command line of the exported script: analyse a record, print (and write) the peak drifts."""
    import openseespy.opensees as ops
    name, height = model["name"], model["height"]
    p = argparse.ArgumentParser(description=f"Run the hlaid clone {name!r} in OpenSees under a ground motion.")
    p.add_argument("record")
    p.add_argument("--units", help="acceleration units of a text record (AT2 files are in g)")
    p.add_argument("--dt", type=float, help="sample interval of a one-column text record [s]")
    s = p.add_mutually_exclusive_group()
    s.add_argument("--scale", type=float, default=1.0, help="scale factor of the record")
    s.add_argument("--pga-g", type=float, help="scale the record to this PGA [g]")
    p.add_argument("--dt-factor", type=int, default=10, help="analysis steps per record sample (default 10)")
    p.add_argument("--out", help="write the peak drifts as JSON here")
    a = p.parse_args(argv)
    dt, ag = read_record(a.record, a.units, a.dt)
    scale = a.pga_g * G_MM_S2 / np.abs(ag).max() if a.pga_g else a.scale
    res = analyze(ops, model, ag * scale, dt, a.dt_factor)
    out = {"model": name, "record": a.record, "scale": scale, "dt_factor": a.dt_factor, "converged": res["ok"],
           "peak_drift_mm": res["peak_drift"], "residual_drift_mm": res["residual_drift"]}
    if height is not None:
        out["peak_drift_ratio"] = [d / h for d, h in zip(res["peak_drift"], height, strict=True)]
    for i, d in enumerate(res["peak_drift"]):
        print(f"story {i + 1}: peak drift {d:.4f} mm" + (f" ({100 * d / height[i]:.3f} %)" if height else ""))
    if a.out:
        tmp = a.out + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(out, fh, indent=2)
        os.replace(tmp, a.out)
    return 0 if res["ok"] else 1
