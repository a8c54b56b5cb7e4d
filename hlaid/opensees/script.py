"""The standalone OpenSeesPy script of a clone, generated from data.

The script is the source of :mod:`hlaid.opensees.standalone` (ordinary, linted code that builds
and analyses the model), followed by the clone's parameters as Python literals (``repr()`` of
floats, strings, lists, checked with :func:`ast.literal_eval`) and a fixed ``__main__`` guard.
Strings (the clone's name, which ``hlaid identify`` takes from a file name, the damping kind,
the version) are only ever such literals, so no name can add code.
"""

from __future__ import annotations

import ast
import inspect
import os
from pathlib import Path
from typing import Any

from .._fileio import atomic_write
from ..errors import InputError
from ..model import Building
from . import standalone

__all__ = ["building_of", "export_opensees", "model_data", "opensees_script"]

FIELDS: tuple[tuple[str, str], ...] = (
    ("NAME", "the clone's name"),
    ("HLAID_VERSION", "hlaid version that exported this script"),
    ("MASS", "floor masses [t]"),
    ("K0", "initial story stiffness [N/mm]"),
    ("ALPHA", "post-yield stiffness ratio"),
    ("P_EXP", "smoothness p (OpenSees n)"),
    ("DY", "yield displacement [mm]"),
    ("DELTA_ETA", "hlaid degradation [s^2/m^2]"),
    ("HEIGHT", "story heights [mm]"),
    ("PDELTA_K", "P_i/h_i [N/mm], zeros when P-Delta is off"),
    ("COLLAPSE", "per story [(x_j [mm], dk_j [N/mm]), ...] gap springs, or None"),
    ("RAYLEIGH", "C = a0*M + a1*K0"),
    ("DAMPING", "what RAYLEIGH was computed from"),
)
"""The script's data constants, in order, with their comments; ``MODEL`` maps their lower-case
names to them (the ``model`` argument of :func:`hlaid.opensees.standalone.analyze`)."""


def building_of(model) -> Building:
    """The :class:`~hlaid.model.Building` of a Clone, a Building or a clone file."""
    from ..clone import Clone
    if isinstance(model, (str, os.PathLike)):
        model = Clone.load(model)
    if isinstance(model, Clone):
        return model.building
    if isinstance(model, Building):
        return model
    raise InputError(f"expected a Clone, a Building or a clone file, got {type(model).__name__}")


def _floats(a) -> list[float]:
    return [float(v) for v in a]


def _collapse(b: Building) -> list[list[tuple[float, float]]] | None:
    if b.collapse is None:
        return None
    from ..model.collapse import NO_CAP
    v = b.collapse_values()
    return [[(float(v[i, 2 * j]), float(v[i, 2 * j + 1])) for j in range(v.shape[1] // 2) if v[i, 2 * j] < NO_CAP]
            for i in range(b.n_stories)]


def model_data(model) -> dict[str, Any]:
    """The parameters of the OpenSees model of a clone, as plain Python data.

    Parameters
    ----------
    model : Clone, Building or clone file

    Returns
    -------
    dict keyed by the lower-case names of :data:`FIELDS`: per-story lists of floats (``mass``
    (story,) [t], ``k0`` [N/mm], ...), ``collapse`` (per story ``[(x_j, dk_j), ...]`` or None),
    ``rayleigh`` ``(a0, a1)``, ``damping`` (kind, ratio, modes), ``name`` and ``hlaid_version``.
    """
    from .._version import __version__
    b = building_of(model)
    if b.coupling is not None or b.damping.kind == "modal":
        raise InputError("this clone has a linear floor coupling or per-mode damping (a frame that is no shear "
                         "chain), which the OpenSees export does not write yet; simulate it with hlaid",
                         source=b.source)
    a0, a1 = b.rayleigh()
    return {
        "name": str(b.name or "clone"),
        "hlaid_version": str(__version__),
        "mass": _floats(b.mass),
        "k0": _floats(b.k0),
        "alpha": _floats(b.alpha),
        "p_exp": _floats(b.p),
        "dy": _floats(b.dy),
        "delta_eta": _floats(b.delta_eta),
        "height": _floats(b.height) if b.height is not None else None,
        "pdelta_k": _floats(b.geometric_stiffness()),
        "collapse": _collapse(b),
        "rayleigh": (float(a0), float(a1)),
        "damping": {"kind": str(b.damping.kind), "ratio": float(b.damping.ratio),
                    "modes": [int(m) for m in b.damping.modes]},
    }


def _literal(value: Any) -> str:
    """``repr(value)``, refused unless it reads back as the same plain literal."""
    text = repr(value)
    try:
        same = ast.literal_eval(text) == value
    except (ValueError, SyntaxError):
        same = False
    if not same:
        raise InputError(f"cannot write {text[:80]} into the OpenSees script (not a finite literal)")
    return text


def opensees_script(model) -> str:
    """The text of the standalone OpenSeesPy script of a clone or building.

    Parameters
    ----------
    model : Clone, Building or clone file

    Returns
    -------
    Python source: :mod:`hlaid.opensees.standalone` verbatim, then one ``NAME = literal`` line
    per entry of :data:`FIELDS`, ``MODEL`` and ``if __name__ == "__main__": sys.exit(main(MODEL))``.
    """
    data = model_data(model)
    lines = ["#!/usr/bin/env python3", inspect.getsource(standalone).rstrip("\n"), "", "",
             "# The clone (data only)."]
    lines += [f"{key} = {_literal(data[key.lower()])}  # {comment}" for key, comment in FIELDS]
    lines.append("MODEL = {" + ", ".join(f"{key.lower()!r}: {key}" for key, _ in FIELDS) + "}")
    lines += ["", "", 'if __name__ == "__main__":', "    sys.exit(main(MODEL))", ""]
    return "\n".join(lines)


def export_opensees(model, path: str | os.PathLike, *, force: bool = False) -> Path:
    """Write the standalone OpenSeesPy script of a clone (atomically; an existing file is
    replaced only with ``force``)."""
    text = opensees_script(model)

    def write(tmp: Path):
        tmp.write_text(text, encoding="utf-8")
        tmp.chmod(0o755)
    return atomic_write(path, write, force=force)
