"""Reader for the PhyCNN 6-story hotel records (``data_exp.mat``, 21 earthquakes).

What the variables are (evidence in ``docs/data.md``; the source does not document units):

- ``dt = 0.02 s``; each record is zero-padded to 3600 samples after its end.
- ``input_tf`` / ``input_pred_tf`` (event, time) are the **ground displacement**, not
  acceleration: they are 0.88-1.00 correlated with the floor displacements and the
  low-frequency (0.2-0.5 Hz) transfer ``X / input`` is 1.0 with phase 0.
- ``target_X_tf`` (event, time, 2) are **absolute** displacements of two upper levels;
  ``target_Xd_tf`` and ``target_Xdd_tf`` their velocity and **absolute** acceleration
  (``Xdd`` tends to the second derivative of ``input`` at low frequency, gain 1.0, phase 0;
  a relative acceleration would vanish there).
- All share one length unit, taken as **cm** (CSMIP processed data are in cm, cm/s,
  cm/s^2): the strongest event then has ground 0.085 g and upper-level 0.22 g.
- The two levels are not identified in the source; DOF 1 moves 3.3 times DOF 0 (relative to
  the ground) in the first mode (4.2-4.8 Hz), in every event.

The ground acceleration is the FFT second derivative of the ground displacement.
"""

from __future__ import annotations

import io
import os
import zlib
from pathlib import Path

import numpy as np

from .._inputs import read_bytes
from ..errors import InputError
from ..measurement import Measurement
from ..units import length_factor
from ._common import spectral_second_derivative
from ._matfile import check_mat5, is_mat5

DT = 0.02
"""Sample interval of the records [s] (from the source's ``PhyCNN_exp_ag2utt.py``)."""

_SETS = (("Ind_TV", "input_tf", "target_X_tf", "target_Xdd_tf"),
         ("Ind_P", "input_pred_tf", "target_pred_X_tf", "target_pred_Xdd_tf"))


def _load(path: str | os.PathLike) -> dict:
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    src = str(path)
    if not Path(src).is_file():
        raise InputError("file not found", source=src)
    raw = read_bytes(src)
    if is_mat5(raw):
        check_mat5(raw, src)         # scipy's reader can crash on a damaged level-5 file
    try:
        return loadmat(io.BytesIO(raw))
    except (MatReadError, ValueError, OSError, TypeError, KeyError, IndexError, EOFError, zlib.error,
            UnicodeDecodeError, NotImplementedError, OverflowError, MemoryError) as err:
        raise InputError(f"not a readable MATLAB .mat file ({str(err).splitlines()[0][:80] if str(err) else err!r})",
                         source=src) from None


def hotel_events(path: str | os.PathLike) -> list[int]:
    """The earthquake IDs (1..21) held in the file, sorted."""
    return sorted(_index(_load(path), str(path)))


def _index(mat: dict, src: str) -> dict[int, tuple[str, int]]:
    out = {}
    for ids, inp, x, xdd in _SETS:
        missing = [k for k in (ids, inp, x, xdd) if k not in mat]
        if missing:
            raise InputError(f"missing variable(s) {', '.join(missing)}; expected the PhyCNN data_exp.mat layout",
                             source=src)
        ev = np.asarray(mat[ids]).reshape(-1)
        n = np.asarray(mat[inp]).shape[0]
        if ev.size != n:
            raise InputError(f"{ids} lists {ev.size} events but {inp} holds {n} records", source=src)
        for i, e in enumerate(ev):
            out[int(e)] = (inp, i)
    return out


def read_hotel(path: str | os.PathLike, event: int, *, units: str = "cm", name: str | None = None) -> Measurement:
    """One earthquake of the 6-story hotel data as a two-level :class:`~hlaid.measurement.Measurement`.

    Parameters
    ----------
    path : ``data_exp.mat``
    event : earthquake ID, 1..21 (``Ind_TV`` and ``Ind_P`` of the file)
    units : the file's length unit (default ``"cm"``, see the module docstring)

    Returns
    -------
    Measurement
        ``ground_acc`` (time,) [mm/s^2] from the ground displacement; ``floor_acc`` (time, 2)
        absolute accelerations of the two measured levels [mm/s^2]; ``floor_disp`` (time, 2)
        their displacements relative to the ground [mm]; trailing zero padding removed;
        ``mass`` None. ``extra["ground_disp_mm"]`` holds the ground displacement. The two
        levels are two upper levels of a 6-story building, not consecutive stories.
    """
    src = str(path)
    mat = _load(path)
    idx = _index(mat, src)
    try:
        event = int(event)
    except (TypeError, ValueError):
        raise InputError(f"event must be an earthquake ID, one of {sorted(idx)}; got {event!r}", source=src) from None
    if event not in idx:
        raise InputError(f"no event {event}; the file holds events {sorted(idx)}", source=src)
    inp, i = idx[event]
    xkey, akey = {s[1]: (s[2], s[3]) for s in _SETS}[inp]
    try:
        scale = length_factor(units)
    except ValueError as err:
        raise InputError(str(err), source=src) from None
    u = np.asarray(mat[inp], dtype=np.float64)[i]
    x = np.asarray(mat[xkey], dtype=np.float64)[i]
    xdd = np.asarray(mat[akey], dtype=np.float64)[i]
    if x.ndim != 2 or x.shape[0] != u.shape[0] or xdd.shape != x.shape:
        raise InputError(f"{xkey} and {akey} must be (event, time, level) like {inp} (event, time)", source=src)
    live = np.flatnonzero((u != 0) | np.any(x != 0, axis=1) | np.any(xdd != 0, axis=1))
    if live.size == 0:
        raise InputError(f"event {event} holds only zeros", source=src)
    n = int(live[-1]) + 1
    u, x, xdd = u[:n] * scale, x[:n] * scale, xdd[:n] * scale
    ground = spectral_second_derivative(u, DT)
    return Measurement(dt=DT, ground_acc=ground, floor_acc=xdd, floor_disp=x - u[:, None], source=src,
                       name=name or f"hotel-eq{event:02d}",
                       extra={"ground_disp_mm": u, "event": event, "units_assumed": units,
                              "levels": ["upper level A (DOF 0)", "upper level B (DOF 1)"]})
