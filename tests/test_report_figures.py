"""The report's figures: units on every axis and legend, a value per story in that story's panel,
nothing clipped, no legend over the curves (figure-level checks; the page itself by
scripts/screenshot_report.py where a browser is installed)."""

from __future__ import annotations

import types

from hlaid.run.sections.identification import parameter_table
from hlaid.run.summary import ParameterRow


def _loss(name, level, median, im=None):
    s = {"level_g": level, "im": im if im is not None else level, "im_label": "Sa(T1, 5%)", "ci": 0.9,
         "repair_cost_ratio_band": [0.5 * median, min(1.0, 2 * median)], "repair_cost_ratio_median": median,
         "repair_cost_ratio_mean": median, "p_collapse": min(1.0, median), "p_irreparable": 0.0,
         "p_replacement": min(1.0, median)}
    return types.SimpleNamespace(name=name, summary=s)


def test_loss_curve_keeps_the_event_whole_and_its_legends_off_the_curves():
    from hlaid.loss.plots import plot_loss_curve

    stripes = [_loss(f"stripe-{k}", lv, m) for k, (lv, m) in enumerate([(0.5, 0.01), (1.0, 0.2), (2.0, 1.0)])]
    own = _loss("recorded", None, 1.0, im=2.0)  # at the replacement cost and the highest level: the corner
    fig = plot_loss_curve(stripes, own)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    ax, ax2 = fig.axes[:2]
    for a in (ax, ax2):
        x0, x1 = a.get_xlim()
        y0, y1 = a.get_ylim()
        assert x0 <= 2.0 < x1 and y0 <= 1.0 < y1  # the marker's centre inside the view
        box, leg = a.get_window_extent(r), a.get_legend().get_window_extent(r)
        assert not box.overlaps(leg), "a legend over the curves"
        assert all(u in a.get_ylabel() for u in ("[", "]")) and "[g]" in a.get_xlabel()
    marker = next(line for line in ax.get_lines() if line.get_marker() == "D")
    assert not marker.get_clip_on()
    # the marker is whole: its extent lies inside the figure
    bb = marker.get_window_extent(r)
    fb = fig.bbox
    assert bb.x0 >= fb.x0 and bb.x1 <= fb.x1 and bb.y0 >= fb.y0 and bb.y1 <= fb.y1


def test_parameter_table_has_units():
    rows = tuple(ParameterRow(parameter=n, story=1, identified=1.0) for n in ("k0", "alpha", "p", "dy", "delta_eta"))
    html = parameter_table(rows, ())
    assert "<th class='l'>unit</th>" in html
    for unit in ("N/mm", "mm", "s<sup>2</sup>/m<sup>2</sup>"):
        assert f"<td class='l'>{unit}</td>" in html
    assert "<td class='l'>N/mm/t</td>" in parameter_table(rows, (), mass_normalised=True)


def test_stiffness_figure_gives_each_story_its_own_k0_with_a_unit(table1):
    from hlaid.hla import run_hla
    from hlaid.hla.plots import _force_unit, plot_stiffness
    from hlaid.motions import GroundMotion, load_builtin
    from hlaid.synthetic import simulate_measurement

    quake = load_builtin("elcentro-1940-ns").scaled_to_pga(0.62)
    quake = GroundMotion(dt=quake.dt, acc=quake.acc[: int(8 / quake.dt)], name="elcentro")
    res = run_hla(simulate_measurement(table1, quake, rate_hz=100.0, noise_rms=0.02, seed=0))
    fig = plot_stiffness(res)
    for i, ax in enumerate(fig.axes[: res.n_stories]):
        want = f"story {i + 1}: k0 = {res.stories[i].k0 * 1e-3:.4g} kN/mm"
        assert want in [t.get_text() for t in ax.texts]
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert not any(lb.startswith("k0 = ") for lb in labels)  # no number without a unit, not story 1's for all
    # a mass-normalised analysis says what N/t is
    assert "(floor masses unknown)" in _force_unit(types.SimpleNamespace(mass_normalised=True))[1]


def test_fleet_table_headers_carry_units():
    from hlaid.fleet.report import header

    assert header("own_im") == "own_im [g]" and header("collapse_median") == "collapse_median [g]"
    assert header("T1_s") == "T1_s [s]" and header("p_collapse") == "p_collapse"


def test_the_reports_first_section_says_what_the_figures_rest_on():
    from hlaid.ida.basis import AtEvent, DecisionBasis
    from hlaid.run.sections.decision import section

    b = DecisionBasis(events=(AtEvent("s4", 1.2, 0.574, source="IDA of the identified clone"),),
                      heights_mm=(1000.0,) * 3, heights_assumed=True, survived_mm=(38.0, 47.4, 51.6))
    s = types.SimpleNamespace(flags=tuple(b.flags()), events=(types.SimpleNamespace(
        name="s4", im=1.2, p_collapse=0.574, p_collapse_band=None, source="IDA of the identified clone"),),
        basis=b.to_dict(), survival=None)
    page = section(s)
    assert "P(collapse) 57% for another record of s4&#x27;s intensity (1.2 g), an event the building survived" \
        in page
    assert "largest drift survived (measured): 38.0, 47.4, 51.6 mm (up to 5.16% of the story height, assumed)" \
        in page
    assert "1000, 1000, 1000 mm, assumed (given, not measured)" in page
    assert "not assessed (no replay record kept with its events)" in page
    assert page.count("57.4%") == 1  # in the events' table only
