"""hlaid's own measurement files: NPZ and CSV, as :meth:`hlaid.measurement.Measurement.save` writes them.

File layouts (units mm/s^2, t, mm, N, s):

- **NPZ**: ``dt`` (s), ``ground_acc`` (T,), ``floor_acc`` (T, n) absolute accelerations,
  ``mass`` (n,) [t] (optional: absent or NaN means unknown), optionally ``height`` (n,)
  [mm], and for simulated data the noise-free truth ``true_disp`` (relative floor
  displacement), ``true_drift``, ``true_force`` (story spring force), ``true_z``,
  ``true_eta`` (each (T, n)) and ``true_params`` (JSON text of the building).
  Optionally ``floor_disp`` (T, n): measured floor displacements relative to the ground [mm].
- **CSV**: ``#`` header lines ``# dt_s: ...``, ``# mass_t: m1, m2, ...``, optionally
  ``# height_mm: ...`` and ``# true_params: {json}``; a header row
  ``time_s,ground_acc,floor_acc_1..n[,floor_disp_1..n][,true_disp_1..n,...]``; one row per sample.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .._inputs import DATA_LINES, load_npz, loads_json, read_text
from ..errors import InputError, column_label
from ..measurement import TRUTH_FIELDS, Measurement, Truth
from ..model import Building

__all__ = ["read_native"]


def read_native(path: str | os.PathLike) -> Measurement:
    """Read a measurement from hlaid's NPZ or CSV layout (by extension; see the module docstring)."""
    p = Path(path)
    if p.name.lower().endswith((".csv", ".csv.gz")):  # read_text gunzips
        return _read_csv(p)
    return _read_npz(p)


def _read_npz(p: Path) -> Measurement:
    src = str(p)
    # every member checked against its header before it is allocated; never unpickled
    d = load_npz(p, not_npz="not a readable NPZ measurement file (not a zip archive of named arrays); give a .npz "
                            "written by hlaid or numpy.savez, a .csv measurement, or format= for another layout",
                 max_rows=DATA_LINES)
    for key in ("dt", "ground_acc", "floor_acc"):
        if key not in d:
            raise InputError(f"missing field {key!r}; a measurement needs dt, ground_acc and floor_acc", source=src)
    truth = None
    if "true_params" in d and all(f"true_{k}" in d for k in TRUTH_FIELDS):
        try:
            b = Building.from_dict(loads_json(str(d["true_params"]), src), source=src)
        except (ValueError, KeyError, TypeError) as err:
            raise InputError(f"true_params is not a valid building ({err})", source=src) from None
        truth = Truth(building=b, **{k: d[f"true_{k}"] for k in TRUTH_FIELDS})
    try:
        dt = float(d["dt"])
    except (TypeError, ValueError):
        raise InputError(f"dt must be one number, got an array of shape {np.shape(d['dt'])} and type "
                         f"{np.asarray(d['dt']).dtype.kind!r}", source=src) from None
    known = {"dt", "ground_acc", "floor_acc", "mass", "height", "noise_rms", "pdelta", "floor_disp", "true_params",
             "recorded"}
    extra = {k: v for k, v in d.items() if k not in known and not k.startswith("true_")}
    return Measurement(dt=dt, ground_acc=d["ground_acc"], floor_acc=d["floor_acc"], mass=d.get("mass"),
                       height=d.get("height"), pdelta=bool(d["pdelta"]) if "pdelta" in d else None, truth=truth,
                       floor_disp=d.get("floor_disp"),
                       noise_rms=float(d["noise_rms"]) if "noise_rms" in d else None, source=src,
                       name=p.stem, extra=extra, recorded=_recorded(d.get("recorded"), src))


def _recorded(value, src: str) -> str | None:
    """The ``recorded`` start time (ISO 8601), checked; None where absent."""
    if value is None:
        return None
    import datetime

    text = str(np.asarray(value)).strip()
    try:
        datetime.datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        raise InputError("recorded: expected the record's start time in ISO 8601, e.g. 2018-01-04T10:39:37Z",
                         source=src) from None
    return text


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _header_numbers(value: str, key: str, src: str) -> np.ndarray:
    try:
        out = np.array([float(x) for x in value.replace(";", ",").split(",") if x.strip()])
    except ValueError:
        out = np.empty(0)
    if out.size == 0:
        raise InputError(f"header '{key}' must be a comma-separated list of numbers", source=src)
    return out


def _read_csv(p: Path) -> Measurement:
    src = str(p)
    text = read_text(p, max_lines=DATA_LINES)
    meta: dict[str, str] = {}
    rows: list[str] = []
    linenos: list[int] = []  # file line of each row, for messages
    for k, ln in enumerate(text.splitlines()):
        s = ln.strip()
        if not s:
            continue
        if s.startswith("#"):
            m = re.match(r"#\s*([A-Za-z_]+)\s*:\s*(.*)", s)
            if m:
                meta[m.group(1)] = m.group(2)
        else:
            rows.append(s)
            linenos.append(k + 1)
    if len(rows) < 2:
        raise InputError("holds no data rows", source=src)
    names = [c.strip() for c in rows[0].split(",")]
    fields = [r.split(",") for r in rows[1:]]
    for i, r in enumerate(fields):
        if len(r) != len(names):
            raise InputError(f"data row {i + 1} has {len(r)} values but the header names {len(names)} columns "
                             f"(line {linenos[i + 1]})", source=src)
    try:
        data = np.array([[float(x) for x in r] for r in fields])
    except ValueError:
        i, j = next((i, j) for i, r in enumerate(fields) for j, x in enumerate(r) if not _is_float(x))
        raise InputError(f"has a non-numeric value in data row {i + 1} (line {linenos[i + 1]}), "
                         f"{column_label(names, j)}", source=src) from None
    col = {n: i for i, n in enumerate(names)}
    floors = sorted((n for n in names if re.fullmatch(r"floor_acc_\d+", n)), key=lambda n: int(n.rsplit("_", 1)[1]))
    if "ground_acc" not in col or not floors:
        raise InputError("header must name ground_acc and floor_acc_1..n columns", source=src)
    if "dt_s" in meta:
        dt = float(_header_numbers(meta["dt_s"], "dt_s", src)[0])
    elif "time_s" in col:
        t = data[:, col["time_s"]]
        dt = float((t[-1] - t[0]) / (len(t) - 1))
    else:
        raise InputError("no '# dt_s:' header line and no time_s column", source=src)
    n = len(floors)
    mass = _header_numbers(meta["mass_t"], "mass_t", src) if "mass_t" in meta else None
    height = _header_numbers(meta["height_mm"], "height_mm", src) if "height_mm" in meta else None
    disp_cols = [f"floor_disp_{j + 1}" for j in range(n)]
    floor_disp = data[:, [col[c] for c in disp_cols]] if all(c in col for c in disp_cols) else None
    truth = None
    if "true_params" in meta and all(f"true_{k}_1" in col for k in TRUTH_FIELDS):
        try:
            b = Building.from_dict(loads_json(meta["true_params"], src), source=src)
        except (ValueError, KeyError, TypeError) as err:  # InputError is a ValueError too
            raise InputError(f"'# true_params:' is not a valid building ({err})", source=src) from None
        truth = Truth(building=b, **{k: data[:, [col[f"true_{k}_{j + 1}"] for j in range(n)]] for k in TRUTH_FIELDS})
    noise_rms = float(_header_numbers(meta["noise_rms"], "noise_rms", src)[0]) if "noise_rms" in meta else None
    return Measurement(dt=dt, ground_acc=data[:, col["ground_acc"]], floor_acc=data[:, [col[f] for f in floors]],
                       mass=mass, height=height, truth=truth, floor_disp=floor_disp,
                       pdelta={"true": True, "false": False}.get(meta.get("pdelta", "").strip().lower()),
                       noise_rms=noise_rms, source=src, name=p.stem, recorded=_recorded(meta.get("recorded"), src))
