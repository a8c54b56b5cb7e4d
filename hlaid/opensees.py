"""Export a clone as a standalone OpenSeesPy script, and run that script in-process.

:func:`export_opensees` writes a runnable Python file that builds the clone in OpenSees
(``zeroLength`` elements with ``uniaxialMaterial BoucWen``, floor masses, Rayleigh damping
applied with ``-doRayleigh 1``, the parameter mapping of DESIGN.md section 3) and, run as a
program, analyses a record given on the command line and writes the peak drifts.
:func:`run_opensees` executes *the same generated code* in-process (tests and benchmarks
therefore check exactly what users get). Strings (the clone's name, which ``hlaid identify``
takes from a file name, the damping kind, the version) enter the script only as ``repr()``
literals on data lines, never in its docstring or comments, so no name can add code.

P-Delta (a shear model has no columns to carry a P-Delta transformation): each story gets
a parallel ``zeroLength`` with ``uniaxialMaterial Elastic`` of stiffness ``-P_i/h_i``, the
same linearised geometric stiffness hlaid subtracts from the story force, with
``-doRayleigh 0`` because hlaid's damping ``C = a0 M + a1 K0`` uses K0 without it.

A collapse model (:mod:`hlaid.model.collapse`) adds its gap springs to that parallel element:
``uniaxialMaterial Parallel`` of ``Elastic`` (sum of the slope changes, minus ``P_i/h_i``) and, per
kink, two ``ElasticPPGap`` of unit stiffness yielding at ``+-x_j`` with ``damage`` (the gap grows
with the plastic deformation), with factors ``-dk_j``: exactly the gap springs of hlaid's law.

openseespy is optional (``pip install openseespy==3.5.1.12`` on Python 3.11); without it,
exporting works and running raises :class:`OpenSeesUnavailable`.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._fileio import atomic_write
from .errors import InputError
from .model import Building
from .motions import GroundMotion
from .units import G_MM_S2

__all__ = [
    "OpenSeesResult",
    "OpenSeesUnavailable",
    "export_opensees",
    "import_opensees",
    "opensees_script",
    "run_opensees",
    "run_opensees_batch",
]


class OpenSeesUnavailable(InputError):
    """openseespy cannot be imported (not installed, or its native libraries are missing)."""


def import_opensees():
    """``openseespy.opensees``, or :class:`OpenSeesUnavailable` with the reason."""
    try:
        import openseespy.opensees as ops
    except (ImportError, RuntimeError, OSError) as err:
        raise OpenSeesUnavailable(f"openseespy is not usable ({type(err).__name__}: {err}); install it with "
                                  "pip install openseespy==3.5.1.12 (Python 3.11)") from None
    return ops


def _building(model) -> Building:
    from .clone import Clone
    if isinstance(model, (str, os.PathLike)):
        model = Clone.load(model)
    if isinstance(model, Clone):
        return model.building
    if isinstance(model, Building):
        return model
    raise InputError(f"expected a Clone, a Building or a clone file, got {type(model).__name__}")


def _list(a) -> str:
    return "[" + ", ".join(repr(float(v)) for v in a) + "]"


def _collapse_list(b: Building) -> str:
    if b.collapse is None:
        return "None"
    from .model.collapse import NO_CAP
    v = b.collapse_values()
    return "[" + ", ".join("[" + ", ".join(f"({float(v[i, 2 * j])!r}, {float(v[i, 2 * j + 1])!r})"
                                           for j in range(v.shape[1] // 2) if v[i, 2 * j] < NO_CAP) + "]"
                           for i in range(b.n_stories)) + "]"


def opensees_script(model) -> str:
    """The text of the standalone OpenSeesPy script of a clone or building (see module doc)."""
    from . import __version__
    b = _building(model)
    a0, a1 = b.rayleigh()
    # Strings enter the script only as repr() literals on data lines (NAME, HLAID_VERSION,
    # DAMPING): never inside the docstring or a comment, where a name holding quotes, a
    # newline or '"""' would end them and become code.
    head = _HEADER.format(n=int(b.n_stories), pdelta="on" if b.pdelta_active else "off")
    params = "\n".join([
        f"NAME = {str(b.name or 'clone')!r}  # the clone's name",
        f"HLAID_VERSION = {str(__version__)!r}  # hlaid version that exported this script",
        f"MASS = {_list(b.mass)}  # floor masses [t]",
        f"K0 = {_list(b.k0)}  # initial story stiffness [N/mm]",
        f"ALPHA = {_list(b.alpha)}  # post-yield stiffness ratio",
        f"P_EXP = {_list(b.p)}  # smoothness p (OpenSees n)",
        f"DY = {_list(b.dy)}  # yield displacement [mm]",
        f"DELTA_ETA = {_list(b.delta_eta)}  # hlaid degradation [s^2/m^2]",
        f"HEIGHT = {_list(b.height) if b.height is not None else None}  # story heights [mm]",
        f"PDELTA_K = {_list(b.geometric_stiffness())}  # P_i/h_i [N/mm], zeros when P-Delta is off",
        f"COLLAPSE = {_collapse_list(b)}  # per story [(x_j [mm], dk_j [N/mm]), ...] gap springs, or None",
        f"RAYLEIGH = ({float(a0)!r}, {float(a1)!r})  # C = a0*M + a1*K0",
        (f"DAMPING = {{'kind': {str(b.damping.kind)!r}, 'ratio': {float(b.damping.ratio)!r}, "
         f"'modes': {[int(m) for m in b.damping.modes]!r}}}  # what RAYLEIGH was computed from"),
    ])
    return head + "\n" + params + "\n" + _BODY


def export_opensees(model, path: str | os.PathLike, *, force: bool = False) -> Path:
    """Write the standalone OpenSeesPy script of a clone (atomically; an existing file is
    replaced only with ``force``)."""
    text = opensees_script(model)

    def write(tmp: Path):
        tmp.write_text(text, encoding="utf-8")
        tmp.chmod(0o755)
    return atomic_write(path, write, force=force)


@dataclass(frozen=True, eq=False)
class OpenSeesResult:
    """Response of one OpenSees run.

    Attributes
    ----------
    peak_drift : (story,) peak |drift| over every analysis step [mm]
    residual_drift : (story,) drift at the end [mm]
    ok : the analysis converged to the end of the record
    time_reached : analysis time reached [s]
    drift : (time, story) drift at the record's samples [mm], with ``histories=True``
    dt : sample interval of ``drift`` [s]
    """

    peak_drift: np.ndarray
    residual_drift: np.ndarray
    ok: bool
    time_reached: float
    drift: np.ndarray | None
    dt: float


_NAMESPACES: dict[str, dict] = {}


def _namespace(text: str) -> dict:
    key = hashlib.sha1(text.encode()).hexdigest()
    if key not in _NAMESPACES:
        ns = {"__name__": "hlaid_opensees_model"}
        exec(compile(text, f"<hlaid opensees script {key[:8]}>", "exec"), ns)  # noqa: S102 - our own generated script
        _NAMESPACES[key] = ns
    return _NAMESPACES[key]


def run_opensees(model, motion: GroundMotion, *, scale: float = 1.0, dt_factor: int = 10,
                 histories: bool = False) -> OpenSeesResult:
    """Run the exported script's model in-process under ``motion`` x ``scale``.

    Parameters
    ----------
    model : Clone, Building or clone file
    motion : ground acceleration [mm/s^2]
    dt_factor : analysis steps per record sample (``dt / dt_factor``)
    histories : also return the drift at every record sample (slower: steps in Python)
    """
    if int(dt_factor) < 1:
        raise InputError(f"dt_factor = {dt_factor}; expected an integer >= 1")
    ops = import_opensees()
    ns = _namespace(opensees_script(model))
    out = ns["analyze"](ops, np.asarray(motion.acc) * float(scale), motion.dt, int(dt_factor), histories)
    return OpenSeesResult(peak_drift=np.asarray(out["peak_drift"]), residual_drift=np.asarray(out["residual_drift"]),
                          ok=bool(out["ok"]), time_reached=float(out["time"]),
                          drift=None if out.get("drift") is None else np.asarray(out["drift"]), dt=motion.dt)


def _opensees_chunk(args):
    building, jobs, dt_factor = args
    out = []
    for gm, s in jobs:
        r = run_opensees(building, gm, scale=s, dt_factor=dt_factor)
        out.append(r.peak_drift if r.ok else np.full(len(r.peak_drift), np.nan))
    return out


def run_opensees_batch(model, jobs, *, dt_factor: int = 10, workers: int = 2):
    """Run ``jobs`` (``(motion, scale)`` pairs) in OpenSees on ``workers`` processes (benchmarks).

    Returns ``(wall [s], CPU of the worker processes [s], peak drifts (job, story))``; NaN rows
    where OpenSees failed to converge.
    """
    import resource
    import time
    from concurrent.futures import ProcessPoolExecutor

    def children_cpu():
        r = resource.getrusage(resource.RUSAGE_CHILDREN)
        return r.ru_utime + r.ru_stime

    import_opensees()
    chunks = [jobs[i::workers] for i in range(workers)]
    t0, c0 = time.perf_counter(), children_cpu()
    with ProcessPoolExecutor(workers) as ex:
        parts = list(ex.map(_opensees_chunk, [(model, c, dt_factor) for c in chunks]))
    wall, cpu = time.perf_counter() - t0, children_cpu() - c0
    out = [None] * len(jobs)
    for w, part in enumerate(parts):
        for k, pk in enumerate(part):
            out[w + k * workers] = pk
    return wall, cpu, np.array(out)


_HEADER = '''#!/usr/bin/env python3
"""OpenSeesPy model of an hlaid clone (NAME below): a {n}-story degrading Bouc-Wen shear building.

Exported by hlaid (HLAID_VERSION below). Standalone: needs only openseespy and numpy. P-Delta: {pdelta}.
Units: N, mm, t (tonne), s (1 t * 1 mm/s^2 = 1 N); accelerations in mm/s^2 inside.

Model (hlaid docs/DESIGN section 3):
  node 0 is the fixed ground, node i floor i (one lateral DOF), with mass MASS[i-1];
  story i: zeroLength element i (node i-1 -> i, -doRayleigh 1) with
    uniaxialMaterial BoucWen alpha ko n gamma beta Ao deltaA deltaNu deltaEta
      = ALPHA, K0, P_EXP, 0.5/DY**P_EXP, 0.5/DY**P_EXP, 1, 0, 0, DELTA_ETA*1e-6/MASS
    (OpenSees' energy is (1-alpha)*ko*integral(z dx) in N*mm, hence deltaEta = delta_eta*1e-6/m);
  P-Delta: a parallel zeroLength (-doRayleigh 0) with uniaxialMaterial Elastic -PDELTA_K[i]
    (P_i/h_i: gravity load carried by story i over its height; linearised leaning column);
  strength loss (COLLAPSE, hlaid's collapse model): in that parallel element, per kink j of the
    story's backbone an ElasticPPGap pair (unit stiffness, yield at +-x_j, damage) with factor
    -dk_j, and dk_j added to the Elastic stiffness: the spring force is dk_j * (x - h_j);
  damping: rayleigh a0 0 a1 0, i.e. C = a0*M + a1*K0 (initial stiffness of the Bouc-Wen springs);
  ground motion: timeSeries Path (linear between samples), pattern UniformExcitation;
  analysis: Newmark average acceleration, Newton, NormDispIncr 1e-8 mm, step dt/dt_factor.

Usage:
  python {{this file}} RECORD [--units g] [--dt DT] [--scale S | --pga-g A] [--dt-factor 10] [--out peaks.json]
RECORD is a PEER .AT2 file (units g), or a text file: two columns (time, acceleration) or one
column (give --dt); --units is the acceleration unit of a text file (g, m/s^2, cm/s^2, mm/s^2).
Prints (and with --out writes as JSON) the peak and residual drift of every story.
"""
import argparse
import json
import os
import re
import shutil
import sys
import tempfile

import numpy as np
'''

_BODY = f'''
G_MM_S2 = {G_MM_S2!r}
''' + '''UNITS = {"g": G_MM_S2, "m/s^2": 1000.0, "m/s2": 1000.0, "cm/s^2": 10.0, "cm/s2": 10.0, "gal": 10.0,
         "mm/s^2": 1.0, "mm/s2": 1.0}


def build(ops):
    """Create the model in OpenSees (after wiping any existing one)."""
    n = len(MASS)
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    ops.node(0, 0.0)
    ops.fix(0, 1)
    for i in range(n):
        ops.node(i + 1, 0.0)
        ops.mass(i + 1, MASS[i])
        g = 0.5 / DY[i] ** P_EXP[i]
        ops.uniaxialMaterial("BoucWen", i + 1, ALPHA[i], K0[i], P_EXP[i], g, g, 1.0, 0.0, 0.0,
                             DELTA_ETA[i] * 1e-6 / MASS[i])
        ops.element("zeroLength", i + 1, i, i + 1, "-mat", i + 1, "-dir", 1, "-doRayleigh", 1)
        springs = COLLAPSE[i] if COLLAPSE else []
        if springs:  # strength loss: gap springs dk*(x - h), with P-Delta, in one parallel material
            tag = 10000 * (i + 1)
            ops.uniaxialMaterial("Elastic", tag, sum(dk for _, dk in springs) - PDELTA_K[i])
            tags, factors = [tag], [1.0]
            for j, (xj, dk) in enumerate(springs):
                for side, sign in enumerate((1.0, -1.0)):
                    t = tag + 2 * j + side + 1
                    ops.uniaxialMaterial("ElasticPPGap", t, 1.0, sign * xj, 0.0, 0.0, "damage")
                    tags.append(t)
                    factors.append(-dk)
            ops.uniaxialMaterial("Parallel", 1000 + i + 1, *tags, "-factors", *factors)
            ops.element("zeroLength", 1000 + i + 1, i, i + 1, "-mat", 1000 + i + 1, "-dir", 1, "-doRayleigh", 0)
        elif PDELTA_K[i] != 0.0:
            ops.uniaxialMaterial("Elastic", 1000 + i + 1, -PDELTA_K[i])
            ops.element("zeroLength", 1000 + i + 1, i, i + 1, "-mat", 1000 + i + 1, "-dir", 1, "-doRayleigh", 0)
    ops.rayleigh(RAYLEIGH[0], 0.0, RAYLEIGH[1], 0.0)


def _drifts(ops, n):
    return [ops.eleResponse(i + 1, "deformation")[0] for i in range(n)]


def analyze(ops, ag, dt, dt_factor=10, histories=False):
    """Run the model under ground acceleration ``ag`` [mm/s^2] sampled at ``dt`` [s].

    Returns a dict: peak_drift, residual_drift [mm] per story, ok, time reached, and with
    ``histories`` the drift at every record sample (time, story).
    """
    n = len(MASS)
    ag = [float(v) for v in ag]
    build(ops)
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
    peak = [0.0] * n
    drift = None
    ok = True
    if histories:
        drift = [[0.0] * n]
        for k in range(steps):
            if ops.analyze(1, h) != 0:
                ok = False
                break
            d = _drifts(ops, n)
            peak = [max(p, abs(x)) for p, x in zip(peak, d)]
            if (k + 1) % dt_factor == 0:
                drift.append(d)
    else:
        tmp = tempfile.mkdtemp(prefix="hlaid-opensees-")
        env = os.path.join(tmp, "envelope.out")
        try:
            ops.recorder("EnvelopeElement", "-file", env, "-precision", 12, "-ele", *range(1, n + 1), "deformation")
            ok = ops.analyze(steps, h) == 0
            residual = _drifts(ops, n)
            t_end = ops.getTime()
            ops.remove("recorders")
            rows = np.loadtxt(env, ndmin=2)
            peak = [float(v) for v in rows[-1][:n]]  # rows: min, max, abs max
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        out = {"peak_drift": peak, "residual_drift": residual, "ok": ok, "time": t_end, "drift": None}
        ops.wipe()
        return out
    out = {"peak_drift": peak, "residual_drift": _drifts(ops, n), "ok": ok, "time": ops.getTime(),
           "drift": drift}
    ops.wipe()
    return out


def read_record(path, units=None, dt=None):
    """(dt [s], acceleration [mm/s^2]) of a PEER .AT2 file or a one/two-column text file."""
    with open(path) as fh:
        lines = fh.read().splitlines()
    if path.lower().endswith(".at2"):
        m = re.search(r"NPTS\\s*=\\s*(\\d+).*?DT\\s*=\\s*([-+0-9.eE]+)", lines[3], re.I)
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


def main(argv=None):
    import openseespy.opensees as ops
    p = argparse.ArgumentParser(description=f"Run the hlaid clone {NAME!r} in OpenSees under a ground motion.")
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
    res = analyze(ops, ag * scale, dt, a.dt_factor)
    out = {"model": NAME, "record": a.record, "scale": scale, "dt_factor": a.dt_factor, "converged": res["ok"],
           "peak_drift_mm": res["peak_drift"], "residual_drift_mm": res["residual_drift"]}
    if HEIGHT is not None:
        out["peak_drift_ratio"] = [d / h for d, h in zip(res["peak_drift"], HEIGHT)]
    for i, d in enumerate(res["peak_drift"]):
        print(f"story {i + 1}: peak drift {d:.4f} mm" + (f" ({100 * d / HEIGHT[i]:.3f} %)" if HEIGHT else ""))
    if a.out:
        tmp = a.out + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(out, fh, indent=2)
        os.replace(tmp, a.out)
    return 0 if res["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
'''
