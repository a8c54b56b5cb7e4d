"""IDA from the state a clone's last event left it in (the aftershock fragility) and the collapse
law chosen by the clone's structural system."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import paper_record, window

from hlaid.clone import Clone
from hlaid.errors import InputError
from hlaid.ida import IDAConfig, prepare_building, run_ida
from hlaid.model.state import BuildingState


@pytest.fixture(scope="module")
def short_records():
    return [window(paper_record(n), 4.0) for n in ("elcentro-1940-ns", "kocaeli-1999-dzc180")]


def _state(b, drift) -> BuildingState:
    """A building at rest with residual ``drift``: no restoring force, alpha k0 d + (1 - alpha) k0 z = 0."""
    d = np.asarray(drift, dtype=float)
    return BuildingState(drift=d, z=-b.alpha * d / (1 - b.alpha), work=np.full(b.n_stories, 400.0),
                         peak_positive=np.abs(d) + 5, peak_negative=np.abs(d) + 5, events=("e1",))


def test_ida_from_a_carried_state(table1, short_records):
    b = table1.replace(height=[3000.0] * 3)
    cfg = IDAConfig(levels=[0.01, 0.02], refine=False, pdelta=False)
    clone = Clone(building=b)
    rest = run_ida(clone, short_records, cfg)
    zero = BuildingState(drift=np.zeros(3), z=np.zeros(3), work=np.zeros(3), peak_positive=np.zeros(3),
                         peak_negative=np.zeros(3))
    same = run_ida(clone.with_state(zero), short_records, cfg.replace(start="carried"))
    np.testing.assert_array_equal(same.peak_drift, rest.peak_drift)  # a state at rest is the undamaged start
    assert any("start: undamaged" in n for n in rest.notes)

    st = _state(b, [4.0, -3.0, 2.0])
    after = run_ida(clone.with_state(st), short_records, cfg.replace(start="carried"))
    assert any(n.startswith("start: carried, the state after e1") for n in after.notes)
    # weak shaking leaves the residual drift where it was, and the peaks start from it
    grid = after.point_stage == "grid"
    np.testing.assert_allclose(after.residual_drift[grid], np.broadcast_to(st.drift, (grid.sum(), 3)), atol=0.3)
    assert np.all(after.peak_drift[grid] >= np.abs(st.drift) - 1e-9)
    assert not np.allclose(after.elastic_slope, rest.elastic_slope, rtol=1e-3)  # the probe sees the degradation
    with pytest.raises(InputError, match="carries the state"):
        run_ida(Clone(building=b), short_records, cfg.replace(start="carried"))


def test_the_structural_system_chooses_the_collapse_law(table1):
    b = table1.replace(height=[3000.0] * 3)
    steel, notes = prepare_building(Clone(building=b, system="steel-moment-frame"))
    assert steel.collapse is not None and steel.collapse.name == "steel-mrf"
    assert any("chosen for the clone's structural system 'steel-moment-frame'" in n for n in notes)
    assert prepare_building(Clone(building=b, system="rc-frame"))[0].collapse.name == "rc-frame"
    assert prepare_building(Clone(building=b, system="generic"))[0].collapse is None  # no law for it
    assert prepare_building(Clone(building=b, system="steel-moment-frame"), collapse="none")[0].collapse is None
