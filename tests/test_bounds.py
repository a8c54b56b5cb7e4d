"""Every numeric field of every config schema, of the clone file and every ``HLAID_MAX_*`` variable is
bounded from one place (:mod:`hlaid.bounds`: metadata on the dataclass fields), generated here from
the schemas themselves: each field gets the extremes 0, -1, NaN, +-inf, 1e-300, 1e300, 10^30 and a
5000-digit integer. A value outside the field's bounds (or of the wrong type) is exit status 2 with
one line naming the field; a value inside them loads, or is refused as bad input, never a crash.

A schema added without bounds on a numeric field, or not reachable by the sweep, fails
:func:`test_every_numeric_field_is_bounded`.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import types
import typing
from typing import Any, Literal, Union

import pytest
import yaml

from hlaid.bounds import bounds_of
from hlaid.cli import main
from hlaid.clone import Clone
from hlaid.config import load_config
from hlaid.errors import InputError
from hlaid.fleet.config import FleetConfig
from hlaid.hla.config import HLAConfig
from hlaid.ida.config import IDAConfig
from hlaid.identify.config import IdentifyConfig
from hlaid.io.columns import ColumnsConfig
from hlaid.io.station import StationConfig
from hlaid.limits import DEFAULTS
from hlaid.model.collapse import CollapseModel
from hlaid.model.params import Building
from hlaid.model.schema import Damping
from hlaid.run.config import RunConfig
from hlaid.specs import SimulationConfig

HUGE = "HUGE-INTEGER"
"""Stands for a 5000-digit integer (written into the file text; Python cannot print one)."""

EXTREMES: list[Any] = [0, -1, float("nan"), float("inf"), float("-inf"), 1e-300, 1e300, 10**30, HUGE]

PENDING: tuple[str, ...] = ()
"""Modules whose schemas do not declare their bounds yet (none)."""

STORY = {"mass_t": 1.0, "k0": 1000.0, "alpha": 0.1, "p": 2.0, "dy": 1.0, "delta_eta": 0.0}
SIM = {"building": {"stories": [dict(STORY)], "damping": {}}, "motion": {"file": "builtin:elcentro-1940-ns"},
       "measurement": {}}
STATION = {"files": ["a.mseed"], "ground": {"channel": "XX.A.00.HNE"}, "floors": [{"channel": "XX.A.01.HNE"}]}
FLEET = {"records": "builtin:elcentro-1940-ns", "cluster": {},
         "buildings": [{"name": "B1", "measurements": {"ev1": {"file": "b1.npz"}}},
                       {"name": "B2", "measurements": {"ev1": {"station": STATION}}}]}
COLUMNS = {"file": "data.csv", "ground": {"column": 0, "units": "g"}, "floors": [{"column": 1, "units": "g"}],
           "dt": 0.01}
COLLAPSE = {"theta_p": 0.02, "theta_pc": 0.1, "kappa": 0.2, "theta_u": 0.15}

# schema -> (top schema, its command line with {cfg} and {out}, the base config, where the schema sits in it)
CARRIERS: dict[type, tuple[type, list[str], dict, list]] = {}


def _carry(cls, top, argv, base, *where):
    CARRIERS[cls] = (top, argv, base, list(where))


_SIMULATE = ["simulate", "{cfg}", "-o", "{out}.npz"]
_HLA = ["hla", "missing.npz", "--config", "{cfg}", "-o", "{out}"]
_IDA = ["ida", "missing.json", "--config", "{cfg}", "-o", "{out}"]
_RUN = ["run", "{cfg}", "-o", "{out}"]
_FLEET = ["fleet", "{cfg}", "-o", "{out}"]
_COLUMNS = ["hla", "{cfg}", "-o", "{out}"]
_IDENTIFY = ["identify", "missing.npz", "--config", "{cfg}", "-o", "{out}"]


def _register() -> None:
    from hlaid.fleet.config import BuildingEntry, ClusterConfig, FleetMeasurement
    from hlaid.hla.config import ForceConfig, HalfCycleConfig, PreprocessConfig, StiffnessConfig
    from hlaid.identify.config import BinsConfig, OuterConfig, RefineConfig, SVMConfig, TrainingConfig
    from hlaid.io.columns import ChannelSpec
    from hlaid.io.station import StationChannel
    from hlaid.loss.config import LossConfig
    from hlaid.run.config import MeasurementSource
    from hlaid.specs import BuildingSpec, MeasurementSpec, MotionSpec, StorySpec
    from hlaid.uncertainty.config import AssessConfig
    _carry(SimulationConfig, SimulationConfig, _SIMULATE, SIM)
    _carry(BuildingSpec, SimulationConfig, _SIMULATE, SIM, "building")
    _carry(StorySpec, SimulationConfig, _SIMULATE, SIM, "building", "stories", 0)
    _carry(Damping, SimulationConfig, _SIMULATE, SIM, "building", "damping")
    _carry(MotionSpec, SimulationConfig, _SIMULATE, SIM, "motion")
    _carry(MeasurementSpec, SimulationConfig, _SIMULATE, SIM, "measurement")
    for cls, key in ((PreprocessConfig, "preprocess"), (ForceConfig, "force"), (HalfCycleConfig, "half_cycles"),
                     (StiffnessConfig, "stiffness")):
        _carry(cls, HLAConfig, _HLA, {key: {}}, key)
    _carry(HLAConfig, HLAConfig, _HLA, {})
    _carry(IDAConfig, IDAConfig, _IDA, {})
    _carry(IdentifyConfig, IdentifyConfig, _IDENTIFY, {})
    for cls, key in ((BinsConfig, "bins"), (TrainingConfig, "training"), (SVMConfig, "svm"), (OuterConfig, "outer"),
                     (RefineConfig, "refine")):
        _carry(cls, IdentifyConfig, _IDENTIFY, {key: {}}, key)
    _carry(CollapseModel, IDAConfig, _IDA, {"collapse": COLLAPSE}, "collapse")
    run = {"measurement": {"file": "m.npz"}, "ida": {}, "assess": {}, "loss": {}}
    _carry(RunConfig, RunConfig, _RUN, run)
    _carry(MeasurementSource, RunConfig, _RUN, run, "measurement")
    _carry(AssessConfig, RunConfig, _RUN, run, "assess")
    _carry(LossConfig, RunConfig, _RUN, run, "loss")
    _carry(FleetConfig, FleetConfig, _FLEET, FLEET)
    _carry(ClusterConfig, FleetConfig, _FLEET, FLEET, "cluster")
    _carry(BuildingEntry, FleetConfig, _FLEET, FLEET, "buildings", 0)
    _carry(FleetMeasurement, FleetConfig, _FLEET, FLEET, "buildings", 0, "measurements", "ev1")
    _carry(StationConfig, FleetConfig, _FLEET, FLEET, "buildings", 1, "measurements", "ev1", "station")
    _carry(StationChannel, FleetConfig, _FLEET, FLEET, "buildings", 1, "measurements", "ev1", "station", "ground")
    _carry(ColumnsConfig, ColumnsConfig, _COLUMNS, COLUMNS)
    _carry(ChannelSpec, ColumnsConfig, _COLUMNS, COLUMNS, "ground")


_register()


# ----------------------------------------------------------------------------- walking the schemas
def _args(tp) -> tuple:
    return typing.get_args(tp)


def _leaves(tp, dicts: bool = True) -> list:
    """The scalar types and dataclasses a field of type ``tp`` may hold (through unions, lists and,
    with ``dicts``, the values of mappings)."""
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType, list, tuple):
        return [leaf for a in _args(tp) if a is not Ellipsis for leaf in _leaves(a, dicts)]
    if origin is dict:
        return _leaves(_args(tp)[1], dicts) if _args(tp) and dicts else []
    if origin is Literal:
        return []
    return [tp]


def _numeric(tp) -> bool:
    """Whether a field holds numbers (not counting mappings: ``collapse``'s is a CollapseModel's,
    swept as such; a reader's ``options`` are that reader's arguments)."""
    return any(t in (int, float) for t in _leaves(tp, dicts=False))


def _schemas(root: type, seen: set | None = None) -> set[type]:
    seen = set() if seen is None else seen
    if root in seen:
        return seen
    seen.add(root)
    for tp in typing.get_type_hints(root).values():
        for leaf in _leaves(tp):
            if dataclasses.is_dataclass(leaf):
                _schemas(leaf, seen)
    return seen


def _pending(cls) -> bool:
    return cls.__module__.startswith(PENDING)


TOPS = (SimulationConfig, HLAConfig, IDAConfig, IdentifyConfig, RunConfig, FleetConfig, ColumnsConfig)


def _all_schemas() -> set[type]:
    out: set[type] = {CollapseModel}
    for top in TOPS:
        out |= _schemas(top)
    return out


def _numeric_fields(cls) -> list[tuple[str, Any]]:
    hints = typing.get_type_hints(cls)
    return [(f.name, hints[f.name]) for f in dataclasses.fields(cls) if f.init and _numeric(hints[f.name])]


def test_every_numeric_field_is_bounded():
    schemas = _all_schemas()
    unbounded = [f"{cls.__name__}.{name}" for cls in schemas if not _pending(cls)
                 for name, _ in _numeric_fields(cls)
                 if bounds_of({f.name: f for f in dataclasses.fields(cls)}[name]) is None]
    assert unbounded == []
    missing = [cls.__name__ for cls in schemas if not _pending(cls) and _numeric_fields(cls) and cls not in CARRIERS]
    assert missing == [], "schemas the sweep does not reach: add them to CARRIERS"
    for cls in (Building, Damping, CollapseModel):  # the clone file's fields
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if f.name in ("mass", "k0", "alpha", "p", "dy", "delta_eta", "height", "gravity_load") or \
                    _numeric(hints.get(f.name, str)):
                assert bounds_of(f) is not None, f"{cls.__name__}.{f.name}"


# ----------------------------------------------------------------------------- the sweep
def _value_for(tp, v):
    """``v`` shaped for a field of type ``tp`` (a list or pair of it where the field holds several)."""
    for t in (tp, *[a for a in _args(tp) if a is not type(None)]):
        origin = typing.get_origin(t)
        if origin is list:
            return [v]
        if origin is tuple:
            n = len(_args(t)) if Ellipsis not in _args(t) else 1
            return [v] * n
    return v


def _wants_int(tp) -> bool:
    leaves = [t for t in _leaves(tp) if t in (int, float)]
    return leaves == [int]


def _legal(cls, name, tp, v) -> bool:
    b = bounds_of({f.name: f for f in dataclasses.fields(cls)}[name])
    if v == HUGE:
        return False
    if _wants_int(tp) and not isinstance(v, int):
        return False
    return b is not None and b.contains(v)


def _dump(d: dict) -> str:
    return yaml.safe_dump(d, sort_keys=False).replace(f"'{HUGE}'", "9" * 5000).replace(HUGE, "9" * 5000)


def _set(d, where: list, name: str, value) -> dict:
    d = copy.deepcopy(d)
    node = d
    for k in where:
        node = node[k]
    node[name] = value
    return d


def _cases():
    for cls in sorted(CARRIERS, key=lambda c: c.__name__):
        for name, tp in _numeric_fields(cls):
            yield pytest.param(cls, name, tp, id=f"{cls.__name__}.{name}")


@pytest.mark.parametrize("cls, name, tp", list(_cases()))
def test_every_field_refuses_its_extremes_by_name(tmp_path, capsys, monkeypatch, cls, name, tp):
    top, argv, base, where = CARRIERS[cls]
    monkeypatch.chdir(tmp_path)
    cfg = tmp_path / ("cfg.yaml" if top is not ColumnsConfig else "mapping.yaml")
    for v in EXTREMES:
        cfg.write_text(_dump(_set(base, where, name, _value_for(tp, v))))
        if _legal(cls, name, tp, v):  # inside the bounds: it loads, or is refused as bad input (cross-checks)
            try:
                load_config(cfg, top)
            except InputError:
                pass
            continue
        rc = main([a.format(cfg=cfg, out=tmp_path / "out") for a in argv])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and "Traceback" not in err[0], (v, err)
        assert name in err[0], (v, err[0])
        assert not (tmp_path / "out").exists() and not (tmp_path / "out.npz").exists()


# ----------------------------------------------------------------------------- the clone file
CLONE_FIELDS = [("stories", 0, k) for k in ("mass", "k0", "alpha", "p", "dy", "delta_eta", "height", "gravity_load")]
CLONE_FIELDS += [("damping", "ratio"), ("damping", "modes"), ("collapse", "theta_p"), ("collapse", "theta_pc"),
                 ("collapse", "kappa"), ("collapse", "theta_u")]
_CLONE_BOUNDS = {"stories": Building, "damping": Damping, "collapse": CollapseModel}


def _clone_text(table1, path: tuple, v) -> str:
    d = Clone(building=table1.replace(height=[3000.0] * 3, collapse="steel-mrf")).to_dict()
    if path[0] == "stories":  # every story's (a value given for some stories only is refused as such)
        for s in d["stories"]:
            s[path[-1]] = v
    else:
        d[path[0]][path[-1]] = [v, 2] if path[-1] == "modes" else v
    return json.dumps(d).replace(f'"{HUGE}"', "9" * 5000)


@pytest.mark.parametrize("path", CLONE_FIELDS, ids=lambda p: ".".join(map(str, p)))
def test_clone_fields_refuse_their_extremes_by_name(tmp_path, capsys, table1, path):
    cls = _CLONE_BOUNDS[path[0]]
    b = bounds_of({f.name: f for f in dataclasses.fields(cls)}[path[-1]])
    assert b is not None
    clone = tmp_path / "clone.json"
    for v in EXTREMES:
        clone.write_text(_clone_text(table1, path, v))
        legal = v != HUGE and b.contains(v) and (path[-1] != "modes" or isinstance(v, int))
        if legal:
            try:
                Clone.load(clone)
            except InputError:
                pass
            continue
        rc = main(["export-opensees", str(clone), "-o", str(tmp_path / "m.py")])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and "Traceback" not in err[0], (v, err)
        assert path[-1] in err[0], (v, err[0])
        assert not (tmp_path / "m.py").exists()


# ----------------------------------------------------------------------------- the environment
@pytest.mark.parametrize("name", sorted(DEFAULTS))
def test_environment_limits_refuse_their_extremes_by_name(tmp_path, capsys, monkeypatch, name):
    for text in ("0", "-1", "nan", "inf", "-inf", "1e-300", "1e300", "9" * 5000, "lots", ""):
        monkeypatch.setenv(f"HLAID_MAX_{name}", text)
        rc = main(["hla", str(tmp_path / "missing.npz"), "-o", str(tmp_path / "out")])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1, (text[:20], err)
        if text:  # unset: the default applies, and the missing file is the error
            assert f"HLAID_MAX_{name}" in err[0], err[0]
        else:
            assert "file not found" in err[0]
    monkeypatch.setenv(f"HLAID_MAX_{name}", str(DEFAULTS[name]))
    assert main(["hla", str(tmp_path / "missing.npz"), "-o", str(tmp_path / "out")]) == 2
    assert "file not found" in capsys.readouterr().err


def test_bounds_are_finite():
    for cls in _all_schemas() | {Building, Damping, CollapseModel}:
        for f in dataclasses.fields(cls):
            b = bounds_of(f)
            if b is not None:
                assert math.isfinite(b.lo) and math.isfinite(b.upper()), f"{cls.__name__}.{f.name}"
