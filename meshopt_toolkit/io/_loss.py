"""What a format cannot hold: the parts of a :class:`~.cells.CellMesh` a writer refuses.

A *part* is ``(kind, name)``: ``("cells", "line")`` (every cell of that type),
``("point", key)``, ``("cell", key)`` or ``("field", key)`` (one datum). Each writer lists
the parts it cannot hold (its ``unsupported(cm)``); :func:`refuse` names them in one
:class:`~meshopt_toolkit.errors.WriteError`, and :func:`without` makes the mesh that
``meshopt convert --allow-loss`` writes instead, :func:`describe` the line naming what was
dropped (``"gmsh:physical, gmsh:geometrical cell data; 6 line cells"``).
"""

from __future__ import annotations

import numpy as np

from ..errors import WriteError
from .cells import CellMesh

Part = tuple[str, str]

_DATA_KINDS = (("point", "point data"), ("cell", "cell data"), ("field", "field data"))


def cells_other_than(cm: CellMesh, allowed) -> list[Part]:
    """The cell types of ``cm`` (with cells) that are not in ``allowed``, in block order."""
    out: list[Part] = []
    for t, c in cm.cells:
        if t not in allowed and len(c) and ("cells", t) not in out:
            out.append(("cells", t))
    return out


def data_parts(cm: CellMesh, point: bool = True, cell: bool = True,
               fields: bool = True) -> list[Part]:
    """Every point, cell and field datum of ``cm`` (those selected)."""
    out: list[Part] = []
    if point:
        out += [("point", k) for k in cm.point_data]
    if cell:
        out += [("cell", k) for k in cm.cell_data]
    if fields:
        out += [("field", k) for k in cm.field_data]
    return out


def describe(cm: CellMesh, parts: list[Part]) -> str:
    """``"u, v point data; gmsh:physical cell data; 6 line cells"`` (empty for no part)."""
    groups = []
    for kind, label in _DATA_KINDS:
        names = [name for k, name in parts if k == kind]
        if names:
            groups.append(f"{', '.join(names)} {label}")
    counts = cm.cell_counts()
    cells = [f"{counts.get(name, 0)} {name} cells" for k, name in parts if k == "cells"]
    if cells:
        groups.append(", ".join(cells))
    return "; ".join(groups)


def refuse(path, fmt: str, cm: CellMesh, parts: list[Part], hint: str = "use .vtu") -> None:
    """Raise ``PATH: FMT files cannot hold WHAT (HINT)`` if there are ``parts``."""
    if parts:
        raise WriteError(f"{path}: {fmt} files cannot hold {describe(cm, parts)} ({hint})")


def without(cm: CellMesh, parts: list[Part]) -> CellMesh:
    """A copy of ``cm`` without ``parts`` (cell blocks of a dropped type leave the cell
    data lists too); ``dropped`` gains :func:`describe` of them."""
    if not parts:
        return cm
    gone = {name for k, name in parts if k == "cells"}
    keep = [i for i, (t, _) in enumerate(cm.cells) if t not in gone]
    drop = {kind: {name for k, name in parts if k == kind} for kind, _ in _DATA_KINDS}
    return CellMesh(
        points=cm.points,
        cells=[cm.cells[i] for i in keep],
        point_data={k: v for k, v in cm.point_data.items() if k not in drop["point"]},
        cell_data={k: [v[i] for i in keep] for k, v in cm.cell_data.items()
                   if k not in drop["cell"]},
        field_data={k: v for k, v in cm.field_data.items() if k not in drop["field"]},
        source=cm.source,
        dropped=list(cm.dropped) + [describe(cm, parts)],
        layout=cm.layout.without(parts) if hasattr(cm.layout, "without") else cm.layout,
    )


def numeric(a) -> bool:
    """Whether ``a`` is an array of booleans, integers or floats."""
    return np.asarray(a).dtype.kind in "biuf"
