"""Progress and summaries: one line per stage in a pipe, a bar on a terminal, summaries with units.

A stage (:class:`hlaid._progress.Stage`) logs one closing line with its count, unit and time; on
a terminal it draws a bar in place (counts, elapsed time) that other messages print above; inside
another stage its line is a detail. The identify summary gives units and the clone's modes; the
loss step says what it assumed.
"""

from __future__ import annotations

import io
import re
import sys

import numpy as np
import pytest

import hlaid
from hlaid import _progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture()
def shown():
    """Progress shown (as the command line shows it); the logger's level and propagation restored."""
    level, propagate = _progress.LOGGER.level, _progress.LOGGER.propagate
    _progress.set_verbosity(1)
    yield
    _progress.LOGGER.setLevel(level)
    _progress.LOGGER.propagate = propagate


def _stderr(monkeypatch, tty: bool) -> io.StringIO:
    buf = _Terminal() if tty else io.StringIO()
    monkeypatch.setattr(sys, "stderr", buf)
    return buf


def test_a_stage_is_one_closing_line_in_a_pipe(shown, monkeypatch):
    err = _stderr(monkeypatch, tty=False)
    with _progress.stage("[identify] replay fit", 40, unit="evaluations") as st:
        for k in range(7):
            st.update(1, note=f"cost {100 - k}")
        st.done("cost 100 -> 94")
    for _ in _progress.progress(range(3), desc="IDA grid", unit="levels"):
        pass
    lines = err.getvalue().splitlines()
    assert len(lines) == 2 and "\r" not in err.getvalue()
    assert re.fullmatch(r"\[identify\] replay fit: 7/40 evaluations in \d+\.\d s; cost 100 -> 94", lines[0])
    assert re.fullmatch(r"IDA grid: 3 levels in \d+\.\d s", lines[1])


def test_on_a_terminal_the_bar_is_redrawn_in_place_with_counts_and_time(shown, monkeypatch):
    err = _stderr(monkeypatch, tty=True)
    with _progress.stage("fit", 4, unit="steps") as st:
        for k in range(4):
            st._drawn_at = -1.0  # draw every update (drawing is throttled to 10 per second)
            st.update(1, note=f"step {k + 1}")
            if k == 1:
                _progress.info("a message in between")
    text = err.getvalue()
    assert "\rfit [----------" in text and "] 2/4 steps 00:00<00:00 step 2" in text
    assert "\r\x1b[Ka message in between\n" in text  # the bar erased, the message on a line of its own
    assert "] 4/4 steps" in text  # drawn again below it up to the end
    assert text.endswith("fit: 4 steps in 0.0 s; step 4\n")


def test_a_stage_inside_another_closes_as_a_detail(shown, monkeypatch):
    err = _stderr(monkeypatch, tty=False)
    with _progress.stage("ensemble IDA", 2, unit="clones") as outer:
        for _ in range(2):
            with _progress.stage("IDA grid", 5, unit="levels") as inner:
                inner.update(5)
            outer.update()
    assert [ln.split(":")[0] for ln in err.getvalue().splitlines()] == ["ensemble IDA"]
    _progress.set_verbosity(2)
    err = _stderr(monkeypatch, tty=False)
    with _progress.stage("outer"), _progress.stage("inner"):
        pass
    assert [ln.split(":")[0] for ln in err.getvalue().splitlines()] == ["inner", "outer"]


def test_a_stage_left_by_an_error_logs_nothing_and_ends_its_bar_line(shown, monkeypatch):
    err = _stderr(monkeypatch, tty=True)
    with pytest.raises(ValueError), _progress.stage("fit", 3) as st:
        st._drawn_at = -1.0
        st.update(1)
        raise ValueError("bad")
    text = err.getvalue()
    assert text.endswith("\n") and "fit:" not in text and "1/3" in text
    assert not _progress.nested()


def test_quiet_shows_nothing_and_the_library_is_silent_until_verbose(shown, monkeypatch):
    _progress.set_verbosity(0)
    err = _stderr(monkeypatch, tty=True)
    with _progress.stage("fit", 3) as st:
        st.update(3)
    _progress.info("progress")
    assert err.getvalue() == ""
    hlaid.verbose()  # the Python user's switch: the command line's messages on stderr
    with _progress.stage("fit", 3) as st:
        st.update(3)
    assert re.search(r"fit: \d\.\d s", err.getvalue())


# ----------------------------------------------------------------------------- summaries
def test_identify_summary_has_units_and_the_clones_modes(table1):
    """The modal line's periods are the building's and its damping that of 5 % Rayleigh damping
    on modes 1 and 2 (exactly 5.0 % there, more above); k0's unit follows the clone's masses."""
    from hlaid.cli.identify import modal_line, parameter_lines

    line = modal_line(table1, list(table1.k0 * 0.9))
    T = [float(v) for v in re.search(r"T ([\d. /]+) s", line).group(1).split(" / ")]
    xi = [float(v) for v in re.search(r"damping ([\d. /]+) %", line).group(1).split(" / ")]
    np.testing.assert_allclose(T, table1.periods(), atol=5e-4)
    assert xi[0] == xi[1] == 5.0 and xi[2] > 5.0
    t1_hla = float(re.search(r"HLA's k0 alone: T1 ([\d.]+) s", line).group(1))
    assert t1_hla == pytest.approx(table1.periods()[0] / np.sqrt(0.9), abs=5e-4)  # k0 x 0.9: T x 1/sqrt(0.9)
    assert "k0 [N/mm]" in parameter_lines(table1, False)[0] and "k0 [N/mm/t]" in parameter_lines(table1, True)[0]
    assert "dy [mm]" in parameter_lines(table1, False)[0]


def test_a_clone_is_named_after_its_building_not_its_first_event(tmp_path, table1):
    from hlaid.measurement import building_name

    quake = hlaid.read("builtin:elcentro-1940-ns").scaled_to_pga(0.1)
    m = hlaid.simulate_measurement(table1, quake, noise_rms=0.0, seed=0)
    assert m.name == "table1-elcentro-1940-ns" and building_name(m) == "table1"
    site = tmp_path / "frame-7"
    site.mkdir()
    anon = table1.replace(name="")
    m = hlaid.simulate_measurement(anon, quake, noise_rms=0.0, seed=0)
    m.save(site / "s1.npz")
    assert building_name(hlaid.read(site / "s1.npz")) == "frame-7"


def test_the_loss_step_says_what_it_assumed(shown, table1, capsys):
    """Floor areas from the masses (0.5 t/m2 for a steel moment frame), the default inventory's
    fractional quantities and the replacement values are printed, not only stored."""
    from hlaid.loss import LossConfig
    from hlaid.loss.assess import describe_building

    asset = describe_building(3, list(table1.mass), LossConfig(), None)
    err = capsys.readouterr().err
    np.testing.assert_allclose(asset.floor_area_m2, table1.mass / 0.5)
    shown = [float(v) for v in re.search(r"floor area \[([\d., ]+)\] m2", err).group(1).split(", ")]
    np.testing.assert_allclose(shown, table1.mass / 0.5, rtol=1e-3)
    assert "floor mass / 0.5 t/m2" in err and "fractional" in err and "replacement cost" in err
