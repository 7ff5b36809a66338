"""What a :class:`~.document.Document` needs of ``pymeshlab`` objects: the meshes of a
``MeshSet`` in order, custom attributes in and out, and what an entry loses when a MeshLab
step changes its faces."""

from __future__ import annotations

import logging

import numpy as np

logger = logging.getLogger(__name__)

__all__ = ["add_custom", "lost_extras", "mesh_ids", "read_custom"]


def lost_extras(old, new) -> list[str]:
    """What the :class:`~.document.MeshEntry` ``old`` held that ``new`` (its mesh after a
    change of faces) does not: its file's groups and data, its attributes."""
    wp = old.source_workpiece
    cells = old.source_cells if old.keeps_source_cells else None
    cells = cells if cells is not None else (None if wp is None else wp.cells)
    out = []
    if cells is not None:
        other = sorted({t for t, c in cells.cells if t != "triangle" and len(c)})
        out += [f"{', '.join(other)} cells"] if other else []
        out += [f"point data {k!r}" for k in cells.point_data]
        out += [f"cell data {k!r}" for k in cells.cell_data if k != "gmsh:geometrical"]
        out += [f"physical names {', '.join(map(repr, sorted(cells.field_data)))}"
                if cells.field_data else ""]
    elif old.mesh.tag_names:
        out.append(f"physical names {', '.join(map(repr, sorted(old.mesh.tag_names)))}")
    for where, attrs, kept in (("vertex", old.vertex_attributes, new.vertex_attributes),
                               ("face", old.face_attributes, new.face_attributes)):
        out += [f"{where} attribute {k!r}" for k in attrs if k not in kept]
    return [x for x in out if x]


def mesh_ids(ms) -> list[int]:
    """Ids of the meshes in a MeshSet, in insertion order."""
    ids, i = [], 0
    n = ms.mesh_number()
    while len(ids) < n and i < 100 * (n + 1):
        if ms.mesh_id_exists(i):
            ids.append(i)
        i += 1
    return ids


def add_custom(m, where: str, name: str, arr) -> None:
    a = np.asarray(arr, np.float64)
    if a.ndim == 1:
        getattr(m, f"add_{where}_custom_scalar_attribute")(a, name)
    elif a.ndim == 2 and a.shape[1] == 3:
        getattr(m, f"add_{where}_custom_point_attribute")(a, name)
    else:
        logger.info("attribute %r of shape %s has no MeshLab equivalent; not passed on", name, a.shape)


def read_custom(m, where: str, name: str, old):
    try:
        if np.ndim(old) == 1:
            return np.array(getattr(m, f"{where}_custom_scalar_attribute_array")(name))
        return np.array(getattr(m, f"{where}_custom_point_attribute_matrix")(name))
    except Exception:  # the MeshLab step dropped it
        return np.asarray(old)
