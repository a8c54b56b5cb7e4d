"""``report.html``: a self-contained page (images embedded) built from a run folder.

``hlaid report RUN_DIR`` rebuilds it from the saved results: the typed run summary
(``summary.json``, :class:`~hlaid.run.summary.RunSummary`) and the figures (``figures/*.png``,
``ida/*.png``, ``loss/*.png``). The summary is checked when it is read and a figure the run wrote
must still be there: a tampered summary or a missing figure is an :class:`~hlaid.errors.InputError`
naming the field or file. The page is put together here; each section is a module of
:mod:`hlaid.run.sections`.
"""

from __future__ import annotations

import base64
import html
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from .._fileio import atomic_write
from .._inputs import read_bytes, read_text
from ..errors import InputError
from .sections import aftershock, assessment, decision, ida, identification
from .sections import loss as loss_section
from .sections.markup import figure
from .summary import RunSummary, read_summary

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;\
margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em;border-bottom:2px solid #2a6;padding-bottom:.2em}h2{font-size:1.25em;margin-top:1.6em;color:#175}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}\
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#eef6f0}td.l,th.l{text-align:left}.ok{color:#176d2c}.bad{color:#b3261e}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #ddd}figcaption{font-size:.9em;color:#555}
.kpi{display:inline-block;margin:.3em 1em .3em 0;padding:.5em .8em;background:#f4f8f5;border-radius:6px}
.kpi b{font-size:1.3em;display:block}
"""

FIGURES = [
    ("figures/loops.png", "Story restoring force against inter-story drift (HLA), each half cycle in its own colour."),
    ("figures/stiffness.png", "Stiffness evolution: HLA elastic stiffness ke(t) per half cycle against the clone's "
                              "(and the truth when the data were simulated)."),
    ("figures/replay.png", "Floor displacement relative to the ground: measured (doubly integrated, band-passed) "
                           "against the clone replayed on the measured ground motion, with R per floor."),
    ("ida/ida_curves.png", "IDA curves of the clone: each record, and the 16/50/84 % fractiles."),
    ("ida/fragility.png", "Collapse fragility: lognormal fit by maximum likelihood with its bootstrap band."),
    ("ida/exceedance.png", "Probability of exceeding drift-ratio limits against intensity."),
]
"""The figures of the identification and the IDA (relative path, caption), shown after the parameters."""

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


class Figures:
    """The PNG figures of a run folder, read to be embedded. ``loss_dir``: where the ``loss/`` figures
    are when not in the run folder (a loss folder not yet moved into place)."""

    def __init__(self, run_dir: Path, loss_dir: Path | None = None):
        self.run_dir, self.loss_dir = run_dir, loss_dir

    def path(self, rel: str) -> Path:
        if self.loss_dir is not None and rel.startswith("loss/"):
            return self.loss_dir / rel.removeprefix("loss/")
        return self.run_dir / rel

    def check(self, summary: RunSummary) -> None:
        """Every figure the run wrote is still there (an InputError naming the first one missing)."""
        for rel in required_figures(summary):
            if not self.path(rel).is_file():
                raise InputError(f"figure {rel} is missing; rerun hlaid run to recreate the folder",
                                 source=str(self.run_dir))

    def img(self, rel: str) -> str:
        """The ``<img>`` tag of figure ``rel``, the PNG embedded."""
        try:
            raw = read_bytes(self.path(rel))
        except InputError as err:
            raise InputError(f"cannot read figure {rel} ({err})", source=str(self.run_dir)) from None
        if not raw.startswith(_PNG_MAGIC):
            raise InputError(f"figure {rel} is not a PNG image", source=str(self.run_dir))
        data = base64.b64encode(raw).decode()
        return f'<img alt="{html.escape(Path(rel).name)}" src="data:image/png;base64,{data}">'

    def img_if_there(self, rel: str) -> str | None:
        return self.img(rel) if self.path(rel).exists() else None


def required_figures(summary: RunSummary) -> list[str]:
    """Figures (relative paths) a run folder must hold: those of :data:`FIGURES` under ``figures/``,
    those under ``ida/`` when the run made an IDA, and those of the sections it has (none when the
    run made no figures)."""
    if not summary.figures:
        return []
    out = [rel for rel, _ in FIGURES if rel.startswith("figures/") or summary.ida]
    out += loss_section.required_figures(summary.loss) if summary.loss else []
    out += [aftershock.FIGURE] if summary.ida and summary.ida_after else []
    return out + ([assessment.FIGURE] if summary.assessment else [])


def build_report(run_dir: str | os.PathLike) -> Path:
    """Write ``run_dir/report.html`` from the results saved there; returns its path."""
    d = Path(run_dir)
    summary = read_summary(d)
    figs = Figures(d)
    figs.check(summary)
    text = render_report(summary, figs)
    return atomic_write(d / "report.html", lambda tmp: tmp.write_text(text))


def render_report(s: RunSummary, figs: Figures) -> str:
    """The page of summary ``s`` with the figures of ``figs`` embedded."""
    e = html.escape
    source = (f"<p>Source: <code>{e(str(s.source))}</code>, {s.n_stories} stories"
              + (", masses unknown: mass-normalised clone" if s.mass_normalised else "")
              + (f", simulated with {s.noise_rms:.0%} RMS noise" if s.noise_rms else "")
              + f". hlaid {e(s.hlaid_version)}.</p>")
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{e(s.name)}</title>"
             f"<style>{_CSS}</style></head><body>",
             f"<h1>{e(s.name)}: digital clone and collapse risk</h1>", source,
             "<div>" + "".join(f"<span class='kpi'>{e(k)}<b>{v}</b></span>" for k, v in _key_figures(s)) + "</div>",
             decision.section(s), identification.section(s)]
    parts += [figure(figs.img(rel), cap) for rel, cap in FIGURES if figs.path(rel).exists()]
    if s.ida:
        parts.append(ida.section(s.ida))
    if s.ida and s.ida_after:
        parts.append(aftershock.section(s.ida, s.ida_after, figs.img_if_there(aftershock.FIGURE)))
    if s.assessment:
        parts.append(assessment.section(s.assessment, figs.img_if_there(assessment.FIGURE)))
    if s.loss:
        parts.append(loss_section.section(s.loss, figs.img_if_there))
    parts.append("<h2>Run</h2><p>" + ", ".join(f"{e(k)} {v:.1f} s" for k, v in s.timings.items()) +
                 ". Files: <code>clone.json</code>, <code>parameters.csv</code>, <code>hla/</code>, "
                 "<code>ida/</code>, <code>tensorboard/</code>.</p></body></html>")
    return "\n".join(parts)


def _key_figures(s: RunSummary) -> list[tuple[str, str]]:
    """The figures at the top of the page: replay correlation, parameter error, median collapse
    intensity, re-occupancy indicator."""
    r = s.replay
    kpis = [("min R, measured vs replayed", f"{min(r.r_measured):.3f}")]
    if r.r_true:
        kpis.append(("min R, true vs replayed", f"{min(r.r_true):.4f}"))
    errs = [row.error for row in s.parameters if row.error is not None and row.parameter != "k0"]
    if errs:
        kpis.append(("parameter error, mean / worst", f"{sum(errs) / len(errs):.1%} / {max(errs):.1%}"))
    cf = s.ida.collapse_fit if s.ida else None
    if s.ida and cf is not None and cf.median_g is not None:
        label = s.ida.intensity_measure.label or "IM"
        beta = f" (beta {cf.beta:.2f})" if cf.beta is not None else ""
        kpis.append((f"median collapse {label}", f"{cf.median_g:.3g} g{beta}"))
    a = s.assessment
    if a and a.indicator in assessment.INDICATOR_CSS:
        kpis.append(("re-occupancy indicator", f"<span style='color:{assessment.INDICATOR_CSS[a.indicator]}'>"
                                               f"{html.escape(a.indicator.upper())}</span>"))
    return kpis


_BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def embedded_figures(report: str | os.PathLike) -> list[tuple[str, int]]:
    """``(alt, bytes)`` of every PNG embedded in a report; raises if one is not a valid PNG."""
    text = read_text(report)
    out = []
    for alt, data in re.findall(r'<img alt="([^"]*)" src="data:image/png;base64,([^"]+)">', text):
        raw = base64.b64decode(data)
        if not raw.startswith(_PNG_MAGIC):
            raise InputError(f"figure {alt} is not a PNG", source=str(report))
        out.append((alt, len(raw)))
    return out


def screenshot(report: str | os.PathLike, png: str | os.PathLike, *, browser: str | None = None,
               width: int = 1200, height: int | None = None, timeout: float = 120.0) -> Path:
    """Render ``report`` in a headless Chromium and save a full-page screenshot to ``png``.

    ``height`` defaults to 900 px per embedded figure (the page is rendered in one tall window).
    Raises :class:`InputError` when no browser is found or it fails.
    """
    exe = shutil.which(browser) if browser else next((shutil.which(b) for b in _BROWSERS if shutil.which(b)), None)
    if exe is None:
        raise InputError("no headless browser found (install Debian's chromium package, or pass browser=)",
                         source=str(report))
    report, png = Path(report).resolve(), Path(png).resolve()
    height = height or 900 * max(read_text(report).count("<img "), 1) + 1200
    with tempfile.TemporaryDirectory() as profile:
        cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--user-data-dir={profile}",
               f"--window-size={width},{height}", f"--screenshot={png}", report.as_uri()]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0 or not png.exists():
        tail = (proc.stderr or "").strip().splitlines()[-1:] or [f"exit status {proc.returncode}"]
        raise InputError(f"{Path(exe).name} could not render the report: {tail[0]}", source=str(report))
    return png
