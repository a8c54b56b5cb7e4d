"""What the commands say: one line per message (no escaped line break), short blocks, every
alarming line with what to do, parameters labelled by where they come from, implausible clones
flagged with their evidence."""

from __future__ import annotations

import dataclasses
import logging
import types

import numpy as np
import pytest

from hlaid import _progress
from hlaid.clone import Clone
from hlaid.hla.auto import Choice
from hlaid.record import ParameterFlag
from hlaid.run.decision import identification_flags, parameter_flags, plausibility_flags


@pytest.fixture()
def logged(caplog):
    """caplog's handler on the ``hlaid`` logger itself at DEBUG (a command run before may have
    stopped its propagation to the root)."""
    log = logging.getLogger("hlaid")
    level = log.level
    log.addHandler(caplog.handler)
    log.setLevel(logging.DEBUG)
    yield caplog
    log.removeHandler(caplog.handler)
    log.setLevel(level)


@pytest.fixture()
def said(logged):
    """The hlaid messages logged (progress and details), one string each."""
    return lambda: list(dict.fromkeys(r.getMessage() for r in logged.records if r.name.startswith("hlaid")))


def test_the_chosen_settings_are_a_short_block_without_escaped_breaks(said, monkeypatch):
    """The steel frame's ten choices (a 1.3-2.1k character line with escaped breaks before): a
    header and one wrapped line per config section, no escaped break, the advice of a setting left
    unchosen kept; the evidence in full at --verbose."""
    from hlaid.events import identify as ei

    long = "first-mode band, 0.25 x f1 to sqrt(f1 f2): not a shear building above its first mode (" + "x" * 400 + ")"
    choices = (Choice("hla.preprocess.band_hz", [0.34, 2.62], long),
               Choice("hla.preprocess.displacement", "measured", "the file has floor displacements: ..."),
               Choice("hla.stiffness.yield_ratio", 0.8, "the band's high corner ..."),
               Choice("hla.force.damping", "regression", "the assumed 5 % Rayleigh damping over-corrects: ..."),
               Choice("refine.method", "least_squares", "HLA's first-mode band: ..."),
               Choice("refine.band_hz", [0.34, 2.62], "HLA's band"),
               Choice("refine.parameters", ["alpha", "p", "dy", "delta_eta"], "the floor masses are unknown: ..."),
               Choice("refine.damping", True, "HLA's damping is regression: ..."),
               Choice("refine.compare", "acc+drift", "the records' floor displacements resolve every story's drift"),
               Choice("system", None, "not in the data (the records cannot tell a steel frame from a concrete one): "
                                      "the generic prior holds what they say little about; name it where known"))
    monkeypatch.setattr(_progress, "verbosity", lambda: 1)
    ei.announce(types.SimpleNamespace(choices=choices))
    lines = said()
    assert len(lines) <= 6 and all("\n" not in line and "\\x0a" not in line for line in lines)
    assert all(len(line) <= ei.CHOICE_WIDTH for line in lines[1:])
    assert lines[1] == "  hla: band_hz = [0.34, 2.62], displacement = measured, yield_ratio = 0.8, damping = regression"
    assert lines[-1] == "  system = null (not in the data; name it where known)"
    assert "--verbose gives the evidence" in lines[0]
    monkeypatch.setattr(_progress, "verbosity", lambda: 2)
    ei.announce(types.SimpleNamespace(choices=choices))
    assert any(long in m for m in said())  # the evidence, in full, with --verbose


def test_a_replay_that_misses_its_noise_says_what_to_do(said, table1):
    from hlaid.identify.refiners import LeastSquares

    class Fit(LeastSquares):
        def _replay(self, building, problem, **kw):
            return types.SimpleNamespace(cost_final=1.0, nfev=3, building=building)

    problem = types.SimpleNamespace(noise_ratio=lambda rr: 229.0, neutral_start=lambda: table1, stories=None)
    Fit(restart_ratio=1.0)._fit(table1, problem, {})
    line = next(m for m in said() if "229.0x its noise level" in m)
    assert "Judge the clone by its replay R" in line and "refine.band_hz" in line


def _with_rows(clone: Clone, source: str) -> Clone:
    rows = tuple(ParameterFlag(name=n, story=i + 1, value=float(getattr(clone.building, n)[i]), source=source,
                               informed=0.1) for n in ("alpha", "p", "dy", "delta_eta") for i in range(3))
    return dataclasses.replace(clone, parameters=rows)


def test_after_an_update_a_parameter_that_moved_is_not_labelled_carried(said, table1):
    from hlaid.cli.identify import print_summary

    p = table1.p.copy()
    before = _with_rows(Clone(building=table1.replace(p=np.array([5.57, p[1], p[2]]))), "earlier events")
    after = dataclasses.replace(before, building=table1.replace(p=np.array([2.10, p[1], p[2]])))
    print_summary(after, before=before)
    story1 = next(m for m in said() if m.lstrip().startswith("1 "))
    assert "moved by this event: p 5.57 -> 2.1" in story1
    assert "little from this one: alpha, dy, delta_eta)" in story1  # p is not among them
    flags = parameter_flags(after)
    assert not any("the prior's" in f for f in flags)
    assert any("the last event hardly informed" in f for f in flags)


def test_implausible_parameters_are_flagged_with_the_evidence(table1):
    c = Clone(building=table1.replace(height=np.full(3, 3000.0)))
    assert plausibility_flags(c) == []  # the paper's building: alpha 0.12-0.23, p 1.5-2.5
    hotel = c.building.replace(alpha=np.array([0.12, 0.779, 0.2]), dy=np.array([20.0, 0.215, 15.0]))
    flags = plausibility_flags(dataclasses.replace(c, building=hotel))
    assert any("story 2 dy 0.215 mm = 0.00717 % of its 3000 mm height" in f and "read that story as linear" in f
               for f in flags)
    assert any("story 2 alpha 0.779" in f and "name the structural system (--system)" in f for f in flags)
    generic = plausibility_flags(dataclasses.replace(c, building=hotel, system="generic"))  # named by no one
    assert any("under the generic prior (no structural system named;" in f and "(--system)" in f for f in generic)
    steel = dataclasses.replace(c, building=c.building.replace(p=np.array([5.57, 2.0, 2.0])),
                                system="steel-moment-frame")
    f = plausibility_flags(steel)
    assert len(f) == 1 and "story 1 p 5.57 (+2.2 sd)" in f[0] and "steel moment-resisting frame" in f[0]
    assert f[0] in identification_flags(steel)  # printed by identify and in the run's summary and report


def test_the_ensembles_p_collapse_is_said_one_way():
    """The demo's P(collapse) at the record: the ensemble's mean with its 5th-95th percentile band;
    the indicator's figure named as the 90th percentile, not a second P(collapse)."""
    from hlaid.cli.run import p_collapse_text
    from hlaid.ida.assessment import ReoccupancyThresholds, _indicator

    a = types.SimpleNamespace(p_collapse=0.044, p_collapse_band=(0.003, 0.104), ci=0.9)
    assert p_collapse_text(a) == ("P(collapse | another record of this intensity) 4.4% (mean of the ensemble, 90% "
                                  "band 0.3%-10.4% (its 5th to 95th percentile over members and record resamples))")
    p = np.linspace(0.0, 0.0878, 100)
    _, reasons = _indicator(p, np.full(5, 1e-4), ReoccupancyThresholds())
    assert reasons[0].startswith("P(collapse) at the experienced intensity, its 90th percentile over the ensemble")
    assert "the figure reported is their mean" in reasons[0] and "90 % of the ensemble" not in reasons[0]


def test_a_run_says_one_line_per_step(logged):
    """Each step of a run is a stage: what its work says as steps is a detail (DEBUG), the step's
    own closing line the progress (INFO)."""
    from hlaid.run.runner import _Steps

    caplog = logged
    step = _Steps(types.SimpleNamespace(ida=None, assess=None, loss=None))
    step("measurement")
    _progress.step("[identify] outer iteration 1: ...")
    step("identification")
    _progress.step("[identify] joint fit over 3 event(s), round 1: ...")
    step.close()
    _progress.step("after the steps: progress again")
    got = list(dict.fromkeys((r.levelno, r.getMessage().split(":")[0]) for r in caplog.records
                             if r.name.startswith("hlaid")))
    assert got == [(logging.DEBUG, "[identify] outer iteration 1"), (logging.INFO, "[1/3] measurement"),
                   (logging.DEBUG, "[identify] joint fit over 3 event(s), round 1"),
                   (logging.INFO, "[2/3] identification"), (logging.INFO, "after the steps")]
