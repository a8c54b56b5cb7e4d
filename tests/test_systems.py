"""One object per structural system: the registry and the tables by name derived from it."""

from __future__ import annotations

import dataclasses

import pytest

from hlaid.errors import InputError
from hlaid.joint.laws import default_laws
from hlaid.joint.priors import PRIORS, get_prior
from hlaid.loss.inventory import INVENTORIES, get_inventory
from hlaid.model.collapse import COLLAPSE_MODELS
from hlaid.record import STORY_LAWS
from hlaid.systems import SYSTEMS, StructuralPrior, StructuralSystem, get_system


def test_every_system_holds_its_parts_under_its_own_name():
    assert list(SYSTEMS) == ["rc-frame", "steel-moment-frame", "generic"]  # one per module, generic last
    for name, s in SYSTEMS.items():
        assert isinstance(s, StructuralSystem) and s.name == name == s.prior.name
        assert s.law is STORY_LAWS[s.law.name]
        assert s.collapse is None or s.collapse is COLLAPSE_MODELS[s.collapse_name]
        assert s.inventory is None or s.inventory.name == name
        assert s.sources and all(isinstance(x, str) and x for x in s.sources)
        with pytest.raises(dataclasses.FrozenInstanceError):
            s.law = STORY_LAWS["elastic"]  # type: ignore[misc]


def test_the_tables_by_name_are_views_of_the_registry():
    assert list(PRIORS) == list(SYSTEMS)
    for name, s in SYSTEMS.items():
        assert PRIORS[name] is s.prior is get_prior(name)
        assert default_laws(name, 2) == (s.law.name,) * 2 == default_laws(s.prior, 2)
        if s.inventory is not None:
            assert INVENTORIES[name] is s.inventory is get_inventory(name)
    assert set(INVENTORIES) == {n for n, s in SYSTEMS.items() if s.inventory is not None} == {"steel-moment-frame",
                                                                                              "rc-frame"}


def test_the_figures_of_the_steel_frame():
    """The steel frame's numbers as documented (docs/identification.md, docs/loss.md)."""
    s = get_system("steel-moment-frame")
    assert (s.collapse_name, s.law.name) == ("steel-mrf", "degrading")
    assert (s.prior.cy.median, s.prior.damping.median) == (0.3, 0.025)
    assert s.inventory is not None and s.inventory.areal_mass_t_m2 == 0.5
    assert [c.id for c in s.inventory.components[:2]] == ["B.10.35.021", "B.10.35.031"]


def test_an_unknown_name_says_the_known_ones():
    with pytest.raises(InputError, match=r"'steal-moment-frame' is unknown \(did you mean 'steel-moment-frame'\?\); "
                                         r"expected one of 'rc-frame', 'steel-moment-frame', 'generic'"):
        get_system("steal-moment-frame")
    with pytest.raises(InputError, match="expected one of"):
        get_system(["not", "a", "name"])  # type: ignore[arg-type]
    with pytest.raises(InputError, match="'generic' has no default inventory"):
        get_inventory("generic")


def test_a_system_whose_parts_name_another_is_refused():
    prior = SYSTEMS["generic"].prior
    with pytest.raises(ValueError, match="its prior is named 'generic'"):
        StructuralSystem(name="timber", title="timber frame", collapse="none", prior=prior)
    timber = StructuralSystem(name="timber", title="timber frame", collapse="none",
                              prior=dataclasses.replace(prior, name="timber"))
    assert isinstance(timber.prior, StructuralPrior) and timber.inventory is None


def test_a_clone_records_its_prior_with_its_system():
    from hlaid.joint.priors import prior_record

    rec = prior_record(PRIORS["rc-frame"])
    assert list(rec) == ["name", "title", "collapse", "story_spread", "k0_beta", "cy", "alpha", "p", "delta_eta",
                         "damping"]
    assert (rec["title"], rec["collapse"], rec["damping"]) == ("reinforced-concrete moment frame", "rc-frame",
                                                               {"median": 0.05, "beta": 0.5})
