"""The clone's linear part, chosen by the data: the shear chain, or the story springs with a
flexural coupling and per-mode damping (:mod:`hlaid.model.coupling`) where the records' modes
need it.

The records' modes come from the lowest-amplitude record (:func:`hlaid.identify.modal.fit_linear`,
the clone's masses). The coupled candidate starts from the shear clone's story laws and yield
drifts, with the linear fit's story springs, coupling and per-mode damping; its joint fit moves
the story parameters, the first two modes' damping ratios and holds the coupling and the higher
modes' damping at the records' (its prior's stiffness centred on the linear fit's springs). It is
fitted only where the shear chain's own best linear model of the record misses one of the records'
modes by more than :data:`~hlaid.model.modes.FREQUENCY_TOLERANCE` (elsewhere the shear chain
suffices), and replaces the shear chain only where its Laplace log evidence (the same criterion
that chooses the story laws, :func:`hlaid.joint.laws.choose_laws`) is higher by more than
:data:`~hlaid.joint.laws.TIE_LOG_UNITS` per coupling term it adds.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..identify.config import IdentifyConfig
from ..joint.fit import JointFit, joint_fit
from ..joint.laws import TIE_LOG_UNITS
from ..joint.priors import StructuralPrior
from ..measurement import Measurement
from ..model import Building, Damping
from ..model.coupling import Coupling
from ..model.modes import FREQUENCY_TOLERANCE
from ..record import FORMS, LinearPart


def coupled_start(shear: Building, lin) -> Building:
    """The coupled candidate's start: ``shear``'s story laws and yield drifts, the linear fit
    ``lin``'s story springs, coupling and per-mode damping (modes 1-2 free, the higher held)."""
    z = lin.ratios
    damping = Damping(kind="modal", ratio=float(z[0]), ratio2=float(z[1]) if len(z) > 1 else None,
                      higher=tuple(float(v) for v in z[2:]))
    return shear.replace(k0=np.asarray(lin.k), coupling=Coupling(tuple(lin.flexural)), damping=damping)


def fit_coupled(shear_fit: JointFit, lin, meas: Sequence[Measurement], system: StructuralPrior, cfg: IdentifyConfig,
                *, names: Sequence[str], y0=None) -> JointFit:
    """The joint fit of the coupled candidate (see the module's doc), under the shear fit's laws."""
    start = coupled_start(shear_fit.building, lin)
    return joint_fit(start, meas, system, cfg, names=names, k0_ref=np.asarray(lin.k), laws=shear_fit.laws, y0=y0)


def choose_form(shear_fit: JointFit, coupled_fit: JointFit | None, n_terms: int, record: str) -> tuple[str, LinearPart]:
    """The form kept and its record: the coupled one where its log evidence beats the shear
    chain's by more than :data:`TIE_LOG_UNITS` per coupling term."""
    if coupled_fit is None:
        return "shear", LinearPart("shear", (("shear", None), ("coupled", None)),
                                   "the coupled candidate could not be fitted: the shear chain", record)
    n_eff = np.mean([shear_fit.n_eff, coupled_fit.n_eff], axis=0)
    zs, zc = shear_fit.log_evidence(n_eff), coupled_fit.log_evidence(n_eff)
    margin = TIE_LOG_UNITS * max(n_terms, 1)
    ev = (("shear", zs if np.isfinite(zs) else None), ("coupled", zc if np.isfinite(zc) else None))
    if np.isfinite(zc) and (not np.isfinite(zs) or zc - zs > margin):
        return "coupled", LinearPart("coupled", ev, f"the records' modes need the coupling: log evidence "
                                                    f"{zc - zs:+.1f} over the shear chain (more than {margin:g})",
                                     record)
    return "shear", LinearPart("shear", ev, f"the shear chain suffices: the coupling's log evidence {zc - zs:+.1f} "
                                            f"is not above {margin:g}", record)


def linear_record(meas: Sequence[Measurement], building: Building, band_hz: tuple[float, float], *,
                  coupling: bool = True):
    """The records' linear model: :func:`hlaid.identify.modal.fit_linear` of the lowest-amplitude
    record with ``building``'s masses and story stiffnesses as the start (``coupling`` False: the
    shear chain's)."""
    from ..identify.modal import fit_linear, lowest_amplitude

    k = lowest_amplitude(meas)
    m = meas[k]
    return fit_linear(m.ground_acc, m.floor_acc, m.dt, k_start=building.k0, mass=building.mass,
                      band_hz=band_hz, record=m.name or f"event {k + 1}", coupling=coupling)


def in_band(lin) -> tuple:
    """The modes of the linear fit ``lin`` within its compared band (the ones the record identifies)."""
    return tuple(m for m in lin.modes if m.frequency_hz <= lin.band_hz[1])


def shear_reaches(lin, shear_lin, tolerance: float = FREQUENCY_TOLERANCE) -> bool:
    """Whether the shear chain's best linear model of the record (``shear_lin``) has every mode
    the record identifies (:func:`in_band`) within ``tolerance`` of the records' (``lin``, the
    coupled model's) in frequency."""
    return all(abs(a.frequency_hz / b.frequency_hz - 1.0) <= tolerance
               for a, b in zip(shear_lin.modes, in_band(lin)))


MODAL_BAND_HZ = (0.5, 20.0)
"""The band of the records' modal identification (its top kept within the compared band)."""


def choose_linear_part(fit: JointFit, meas: Sequence[Measurement], system: StructuralPrior, cfg: IdentifyConfig, *,
                       names: Sequence[str], notes: list[dict]):
    """The records' modes, the coupled candidate's fit and the form chosen: ``(fit kept,
    LinearPart, LinearFit or None)``; a numerical failure of either stage keeps the shear chain
    (with a note)."""
    from ..errors import NotIdentifiableError
    from ..joint.fallback import run_stage

    n = fit.building.n_stories
    if n < 2:
        return fit, LinearPart("shear", reason="one story: no coupling to choose"), None
    if any(np.shape(m.floor_acc)[-1] != n for m in meas):
        return fit, LinearPart("shear", reason="the records do not measure every floor: the shear chain"), None
    top = (cfg.refine.band_hz or MODAL_BAND_HZ)[1]
    band = (MODAL_BAND_HZ[0], min(MODAL_BAND_HZ[1], float(top)))
    lin = run_stage("the records' modal identification", lambda: linear_record(meas, fit.building, band), None, notes,
                    used="the shear chain is kept")
    if lin is None:
        return fit, LinearPart("shear", reason="the records' modes could not be identified: the shear chain"), None
    shear_lin = run_stage("the shear chain's modal fit",
                          lambda: linear_record(meas, fit.building, band, coupling=False), None, notes,
                          used="the coupled candidate is fitted")
    if shear_lin is not None and shear_reaches(lin, shear_lin):
        shown = " / ".join(f"{m.frequency_hz:.2f}" for m in shear_lin.modes)
        return fit, LinearPart("shear", reason=f"the shear chain suffices: its modes of the record ({shown} Hz) are "
                                              f"within {100 * FREQUENCY_TOLERANCE:g} % of the records'",
                               record=lin.record), lin
    coupled = run_stage("the coupled candidate's fit",
                        lambda: fit_coupled(fit, lin, meas, system, cfg, names=names), None, notes,
                        used="the shear chain is kept", extra=(NotIdentifiableError,))
    form, part = choose_form(fit, coupled, n - 1, lin.record)
    return (coupled if form == "coupled" and coupled is not None else fit), part, lin


__all__ = ["FORMS", "MODAL_BAND_HZ", "LinearPart", "choose_form", "choose_linear_part", "coupled_start",
           "fit_coupled", "in_band", "linear_record", "shear_reaches"]
