"""The clone's record as types: a clone file of the format before it (version 3) reads into the
typed fields, writes back as version 4 unchanged, and replays as it did when it was written.

``tests/data/clone_v3_poc.json`` is the clone ``hlaid identify`` wrote of ``hlaid simulate
configs/poc_3story.yaml`` with ``--system steel-moment-frame`` in the version-3 format (its
diagnostics' nested single-event block left out to keep it small, its source renamed)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.record import STORY_LAWS, EventRecord, LawChoice, StartRule, StoryLaw

DATA = Path(__file__).parent / "data"
REPO = Path(__file__).resolve().parents[1]
V3 = DATA / "clone_v3_poc.json"


@pytest.fixture(scope="module")
def raw() -> dict:
    return json.loads(V3.read_text())


def test_a_version_3_file_reads_into_the_typed_record(raw):
    c = Clone.load(V3)
    diag, prov = raw["diagnostics"], raw["provenance"]
    assert c.laws is not None and c.laws.chosen == tuple(diag["laws"]["chosen"]) == ("degrading",) * 3
    assert c.story_laws() == ("degrading",) * 3 and c.laws.reason == diag["laws"]["reason"]
    assert c.start_rule is not None and diag["start_rule"]["choice"] == "rest" and c.start_rule.choice == "undamaged"
    assert c.parameters is not None and [f.to_dict() for f in c.parameters] == [
        {**r, "implausible": False} for r in diag["parameters"]]
    assert [r.r_measured for r in c.fit_replays] == [tuple(e["r_measured"]) for e in diag["joint"]["events"]]
    assert c.fit_replays[-1].stiffness_error == tuple(diag["replay"]["stiffness_error"])
    assert c.settings is not None and c.settings.config == prov["config"]
    assert [ch.to_dict() for ch in c.settings.choices] == prov["choices"]
    assert c.settings.value("refine.band_hz") == prov["config"]["refine"]["band_hz"]
    assert c.paper is None and c.update_check is None and c.fallbacks == ()
    e = c.events[0]
    assert isinstance(e, EventRecord) and e.to_dict() == raw["events"][0]
    assert e.replay is not None and e.replay.peak_drift_error == tuple(raw["events"][0]["replay"]["peak_drift_error"])
    # what was converted is not kept twice; what is left is the reader's
    assert not {"laws", "start_rule", "parameters", "fallbacks"} & set(c.diagnostics)
    assert not {"config", "choices"} & set(c.provenance) and c.provenance["hlaid_version"]


def test_a_converted_file_writes_version_4_and_reads_back_the_same(raw, tmp_path):
    c = Clone.load(V3)
    d = c.to_dict()
    assert d["version"] == 4 and d["identification"]["start_rule"]["choice"] == "undamaged"
    back = Clone.load(c.save(tmp_path / "c.json"))
    assert back.to_dict() == d
    for key in ("k0", "alpha", "p", "dy", "delta_eta"):
        np.testing.assert_array_equal(getattr(back.building, key), [s[key] for s in raw["stories"]])
    bad = json.loads(json.dumps(d))
    bad["identification"]["start_rule"]["choice"] = "rest-ish"
    with pytest.raises(InputError, match="start rule choice"):
        Clone.from_dict(bad)
    bad = json.loads(json.dumps(d))
    bad["identification"]["lawz"] = {}
    with pytest.raises(InputError, match="unknown field 'identification.lawz'"):
        Clone.from_dict(bad)
    with pytest.raises(InputError, match="identification"):
        Clone.from_dict({**d, "identification": {"parameters": [{"story": 1}]}})


def test_a_version_3_clone_replays_as_when_it_was_written(raw):
    """The clone's full replay of its own event, from the start its rule names, gives the
    record it kept when the code before the typed record wrote it."""
    from hlaid.events.predict import predict_event
    from hlaid.events.replay import own_replay
    from hlaid.measurement import ground_digest
    from hlaid.specs import load_simulation_config
    from hlaid.synthetic import measurement_from_config

    poc = REPO / "configs" / "poc_3story.yaml"
    meas = measurement_from_config(load_simulation_config(poc), base_dir=poc.parent, source=str(poc))
    c = Clone.load(V3)
    assert ground_digest(meas) == c.events[0].ground_sha256  # the record it was identified from
    r = own_replay(c.building, meas, None, mass_normalised=c.mass_normalised)
    kept = raw["events"][0]["replay"]
    assert r is not None and list(r.band_hz) == kept["band_hz"]
    np.testing.assert_allclose(r.peak_drift_error, kept["peak_drift_error"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r.drift_r, kept["drift_r"], rtol=1e-9, atol=1e-12)
    auto = predict_event(c, meas)  # start auto: the rule says from rest, as the replay kept
    np.testing.assert_allclose(auto.peak_drift_error, kept["peak_drift_error"], rtol=1e-9, atol=1e-12)


def test_an_older_clone_whose_last_update_started_undamaged_keeps_that_start(raw):
    from hlaid.events.start import resolve_start

    d = json.loads(json.dumps(raw))
    d["diagnostics"].pop("start_rule")
    d["events"][0]["start"] = "undamaged"
    c = Clone.from_dict(d)
    assert c.start_rule == StartRule("undamaged", c.start_rule.reason, rule="last event")
    assert resolve_start(c, "auto").state is None and resolve_start(c, "carried").state is not None
    d["events"][0]["start"] = "carried"
    assert Clone.from_dict(d).start_rule is None and resolve_start(Clone.from_dict(d), "auto").name == "carried"


def test_one_registry_of_story_laws():
    assert list(STORY_LAWS) == ["elastic", "nondegrading", "degrading"]
    free = [law.free for law in STORY_LAWS.values()]
    assert all(all(a <= b for a, b in zip(lo, hi)) for lo, hi in zip(free, free[1:]))  # nested
    assert all(isinstance(law, StoryLaw) and law.free[0] for law in STORY_LAWS.values())  # k0 always moves
    assert LawChoice(chosen=("elastic", "degrading")).laws(3) is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        STORY_LAWS["elastic"].held = ()  # type: ignore[misc]


def test_the_stages_read_resolved_settings_with_no_auto_left():
    from hlaid.identify.config import IdentifyConfig, RefineConfig, ResolvedSettings

    with pytest.raises(InputError, match=r"is 'auto': it is chosen from the record\(s\) first"):
        IdentifyConfig().resolved()
    cfg = IdentifyConfig(refine=RefineConfig(method="eiv", parameters=("k0", "alpha"), damping=False,
                                             band_hz=(0.2, 15.0), compare="acc"))
    cfg = dataclasses.replace(cfg, hla=dataclasses.replace(cfg.hla, stiffness=dataclasses.replace(
        cfg.hla.stiffness, yield_ratio=0.6)))
    r = cfg.resolved()
    assert isinstance(r, ResolvedSettings) and r.band_hz == (0.2, 15.0) and r.damping is False
    assert (r.method, r.parameters, r.compare, r.yield_ratio) == ("eiv", ("k0", "alpha"), "acc", 0.6)


@pytest.mark.parametrize("bad, expect", [
    ({"start_rule": {"choice": "carried", "n": float("inf")}}, "identification"),
    ({"parameters": [{"name": "k0", "story": "one"}]}, "identification"),
    ({"fit_replays": "abc"}, "fit_replays"),
    ({"paper": [1]}, "paper"),
    ({"laws": {"chosen": "degrading"}}, "identification"),
])
def test_a_broken_record_is_a_clear_error_naming_the_file(bad, expect, tmp_path):
    d = Clone.load(V3).to_dict()
    d["identification"] = {**d["identification"], **bad}
    path = tmp_path / "c.json"
    path.write_text(json.dumps(d))
    with pytest.raises(InputError, match=expect) as err:
        Clone.load(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_a_parameter_at_a_bound_of_the_search_is_flagged_against_that_bound():
    from hlaid.joint.vector import RATIO_BOUNDS, _ratio_of, at_limit

    assert _ratio_of(10.0) == RATIO_BOUNDS[1] and _ratio_of(-100.0) == RATIO_BOUNDS[0]  # the clip the search uses
    assert at_limit("damping2", _ratio_of(10.0)) and at_limit("damping", _ratio_of(-100.0))
    assert not at_limit("damping", 0.025) and not at_limit("k0", 1e9)
    assert at_limit("alpha", 0.9495) and at_limit("alpha", 1e-4) and not at_limit("alpha", 0.2)
    assert at_limit("p", 1.001) and not at_limit("p", 2.0) and at_limit("delta_eta", 1e-7)
