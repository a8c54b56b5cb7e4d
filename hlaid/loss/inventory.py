"""Component inventories for the FEMA P-58 assessment: defaults per structural system, or the user's.

Each structural system's default is its :attr:`hlaid.systems.StructuralSystem.inventory`
(:data:`INVENTORIES` by name; the components are :mod:`hlaid.systems.parts`).

An inventory is pelicun's component assignment table (``ID, Units, Location, Direction, Theta_0``
and optionally ``Blocks, Family, Theta_1, Comment``): every row puts ``Theta_0`` of a FEMA P-58
component on each listed story and direction. :func:`default_inventory` builds one from a
:class:`Inventory`'s densities (quantity per m2 of floor area on every story, per direction
for directional components) and the floor areas; :func:`read_inventory` reads and checks the
user's CSV against the FEMA P-58 library shipped with pelicun (simcenter-dlml).

Sources of the defaults (docs/loss.md has the tables):

* non-structural components (office occupancy) and their densities: the component set of
  pelicun's shipped FEMA P-58 example (``pelicun/examples/001``: a 4-story office of 15 000 ft2
  per floor, i.e. 1393.5 m2) divided by its floor area, with the suspended ceiling over the whole
  floor area and one traction elevator per 5574 m2 of total floor area (that building's);
* structural components: the frame joints of that example (per story and direction, 2 beam-one-
  side and 3 beams-both-sides joints per 1393.5 m2) as FEMA P-58 fragility groups: ACI 318 SMF
  beam-column joints (B.10.41.001a/b) and post-tensioned slab-column connections (B.10.49.031)
  for ``rc-frame``, post-Northridge welded unreinforced flange moment connections (B.10.35.021,
  B.10.35.031) for ``steel-moment-frame``;
* replacement cost 2243 USD_2011/m2 and replacement time 2.69 worker-days/m2: the same example's
  12.5 M USD_2011 and 15 000 worker-days over its 5574 m2.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re

from ..bounds import Bounds, show
from ..errors import InputError, quotable
from ..limits import limit
from ..systems import SYSTEMS, Component, Inventory, unknown_system

INVENTORIES: dict[str, Inventory] = {name: s.inventory for name, s in SYSTEMS.items() if s.inventory is not None}
"""Default inventories by structural system (:data:`hlaid.systems.SYSTEMS`)."""


def get_inventory(name: str) -> Inventory:
    """The default inventory of the structural system called ``name``; a system without one, or
    an unknown name, is an InputError listing those with one."""
    if isinstance(name, str) and name in INVENTORIES:
        return INVENTORIES[name]
    if isinstance(name, str) and name in SYSTEMS:
        raise InputError(f"structural system {name!r} has no default inventory; give your own inventory CSV or "
                         f"use one of {', '.join(map(repr, INVENTORIES))}")
    raise InputError(unknown_system(name, INVENTORIES) + " (or give your own inventory CSV)")


COLUMNS = ("ID", "Units", "Location", "Direction", "Theta_0", "Blocks", "Comment")


def default_inventory(system: str | Inventory, floor_area_m2) -> str:
    """The default inventory CSV text of ``system`` for stories of ``floor_area_m2`` [m2] each
    (bottom to top), one row per component and story."""
    s = system if isinstance(system, Inventory) else get_inventory(system)
    area = [float(a) for a in floor_area_m2]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for c in s.components:
        if c.building:
            w.writerow([c.id, c.units, 1, c.direction, f"{c.per_m2 * sum(area):.6g}", "", c.what])
            continue
        for k, a in enumerate(area):
            w.writerow([c.id, c.units, k + 1, c.direction, f"{c.per_m2 * a:.6g}", "", c.what])
    return buf.getvalue()


_LOC = re.compile(r"(all|roof|top|bottom|\d+(--\d+)?)(,(all|roof|top|bottom|\d+(--\d+)?))*")
_DIR = re.compile(r"[0-9](,[0-9])*")


def _component_library() -> tuple[set[str], set[str], set[str]]:
    """``(complete fragility IDs, incomplete fragility IDs, IDs with repair consequences)`` of
    pelicun's FEMA P-58 library."""
    from .fema_p58 import library_file

    with open(library_file("fragility.csv"), newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    complete = {r["ID"] for r in rows if str(r.get("Incomplete", "0")).strip() in ("0", "0.0", "")}
    incomplete = {r["ID"] for r in rows} - complete
    with open(library_file("consequence_repair.csv"), newline="", encoding="utf-8") as fh:
        cons = {r["ID"].rsplit("-", 1)[0] for r in csv.DictReader(fh)}
    return complete, incomplete, cons


QUANTITY = Bounds(0.0, 1e6, lo_open=True)
"""Bounds of an inventory row's quantity ``Theta_0`` (per story and direction, in its unit)."""

BLOCKS = Bounds(1, 10_000)
"""Bounds of an inventory row's ``Blocks`` (where given)."""


def check_inventory(text: str, n_stories: int, source: str) -> int:
    """Check an inventory CSV (pelicun's component assignment format); returns its number of rows.

    Every row must name a component of the FEMA P-58 library with a complete fragility and repair
    consequences, a length/area/count unit pelicun knows, stories within ``1..n_stories + 1``
    (``roof`` is story ``n + 1``), directions 0, 1 or 2, a quantity within :data:`QUANTITY` and
    ``Blocks`` within :data:`BLOCKS`; at most ``HLAID_MAX_INVENTORY`` rows. The rows are checked
    before pelicun's library is read. Errors name the file, line and column (component IDs are
    quoted only when they are plain labels).
    """
    from .fema_p58 import UNITS

    reader = csv.reader(io.StringIO(text))
    first = next(reader, None)
    if first is None:
        raise InputError("inventory is empty; expected a header ID,Units,Location,Direction,Theta_0", source=source)
    head = [h.strip() for h in first]
    head[0] = head[0] or "ID"
    need = ["ID", "Units", "Location", "Direction", "Theta_0"]
    missing = [c for c in need if c not in head]
    if missing:
        raise InputError(f"line 1: column(s) {', '.join(missing)} missing; expected the header "
                         "ID,Units,Location,Direction,Theta_0[,Blocks,Comment] (pelicun's component assignment)",
                         source=source)
    col = {c: head.index(c) for c in need}
    body, top_rows = [], limit("INVENTORY")
    for ln, row in enumerate(reader, start=2):  # a huge file is refused at its first row over the limit
        if any(c.strip() for c in row):
            body.append((ln, row + [""] * (len(head) - len(row))))
            if len(body) > top_rows:
                raise InputError(f"more than {top_rows:.0f} component rows (line {ln}), over the limit of "
                                 f"{top_rows:.0f} (set HLAID_MAX_INVENTORY to raise it)", source=source)
    for ln, row in body:
        if row[col["Units"]].strip() not in UNITS:
            raise InputError(f"line {ln}: column Units: unknown unit; expected one of ea, m, m2, ft, ft2, in, in2",
                             source=source)
        loc = row[col["Location"]].replace(" ", "")
        if not _LOC.fullmatch(loc):
            raise InputError(f"line {ln}: column Location: expected story numbers (1, 2--4, 1,3), all or roof",
                             source=source)
        top = max((int(v) for v in re.findall(r"\d+", loc)), default=0)
        if top > n_stories + 1:
            raise InputError(f"line {ln}: column Location: story {top} is above the roof (the building has "
                             f"{n_stories} stories; roof = {n_stories + 1})", source=source)
        if not _DIR.fullmatch(row[col["Direction"]].replace(" ", "")) or \
                any(d not in "012" for d in row[col["Direction"]].replace(" ", "").split(",")):
            raise InputError(f"line {ln}: column Direction: expected 0 (non-directional), 1, 2 or 1,2", source=source)
        for name, b in (("Theta_0", QUANTITY), ("Blocks", BLOCKS)):
            cell = row[head.index(name)].strip() if name in head else ""
            if name == "Blocks" and not cell:
                continue
            try:
                q = float(cell)
            except ValueError:
                q = math.nan
            if not b.contains(q) or (name == "Blocks" and not q.is_integer()):
                raise InputError(f"line {ln}: column {name}: {show(q) if math.isfinite(q) else 'no number'}; expected "
                                 f"{b.text(name)}" + (", a whole number" if name == "Blocks" else ""), source=source)
    if not body:
        raise InputError("inventory has no component rows", source=source)
    complete, incomplete, conseq = _component_library()
    for ln, row in body:
        cid = row[col["ID"]].strip()
        name = f"component {cid!r}" if quotable(cid) else "the component"
        if cid not in complete:
            why = ("has an incomplete fragility in the FEMA P-58 library (pelicun would skip it)" if cid in incomplete
                   else "is not in the FEMA P-58 component library shipped with pelicun (simcenter-dlml)")
            raise InputError(f"line {ln}: {name} {why}; expected a FEMA P-58 ID such as B.10.35.021", source=source)
        if cid not in conseq:
            raise InputError(f"line {ln}: {name} has no repair consequences in the FEMA P-58 library", source=source)
    return len(body)


DENSITY_MAX = 100.0
"""Largest quantity of one inventory row per m2 of the largest floor, in the row's unit (100 ea, m or
ft2 per m2 of floor is far beyond any building: FEMA P-58's densities are below 1; a row beyond it is
a typing slip whose cost would be thousands of replacement costs)."""


def check_density(text: str, area_m2, source: str) -> None:
    """Refuse an inventory row whose quantity is more than :data:`DENSITY_MAX` per m2 of the largest
    floor area ``area_m2`` [m2] (per story)."""
    top = max(float(a) for a in area_m2)
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return
    head = [h.strip() for h in rows[0]]
    if "Theta_0" not in head:
        return
    k = head.index("Theta_0")
    for ln, row in enumerate(rows[1:], start=2):
        try:
            q = float(row[k])
        except (IndexError, ValueError):
            continue
        if q > DENSITY_MAX * top:
            raise InputError(f"line {ln}: column Theta_0: {show(q)} is {q / top:.3g} per m2 of the largest floor "
                             f"({show(top)} m2); at most {DENSITY_MAX:g} per m2 describes a building: check the "
                             "quantity (and the floor area)", source=source)


def read_inventory(path: str | os.PathLike, n_stories: int, area_m2=None) -> str:
    """The text of the user's inventory CSV, checked (:func:`check_inventory`; with the floor areas
    ``area_m2`` [m2] also :func:`check_density`)."""
    from .._inputs import read_text

    text = read_text(path)
    check_inventory(text, n_stories, str(path))
    if area_m2 is not None:
        check_density(text, area_m2, str(path))
    return text


__all__ = ["Component", "Inventory", "INVENTORIES", "get_inventory", "default_inventory", "check_inventory",
           "read_inventory", "check_density", "DENSITY_MAX"]
