"""``meshopt info`` for tetrahedral meshes, triangle surfaces in 3D and any other cells.

:func:`info_kind` sorts a file's cells: cells other than tetrahedra, triangles, lines
and points (quads, hexahedra, wedges, pyramids, polygons, higher order) make it ``"mixed
cells"``, described by counts per cell type, the bounding box and the quality of the
types that have one here (tetrahedra, triangles); else
(:func:`~..mesh.kinds.cells_kind`, which the operations use too) any tetrahedron makes
it ``"tetrahedra"``; triangles whose points are not on one plane are ``"surface
triangles"``; the rest (``"planar triangles"``) takes the planar path of :mod:`.info`.
The dicts here have the same ``path``/``problems`` keys as the planar one, and print the
same way.
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels.surface import pad3
from ..mesh.kinds import PLANAR, SURFACE, TETS, cells_kind

MIXED = "mixed cells"
#: the cell types of the kinds above; any other makes a file's kind MIXED
SIMPLICES = ("tetra", "triangle", "line", "vertex")


def other_cells(cm) -> set[str]:
    """The cell types of ``cm`` (with cells) outside :data:`SIMPLICES`."""
    return {t for t, c in cm.cells if t not in SIMPLICES and len(c)}


def info_kind(cm) -> str:
    """What ``meshopt info`` describes: :data:`MIXED` where :func:`other_cells` has a
    type, else :func:`~..mesh.kinds.cells_kind`."""
    return MIXED if other_cells(cm) else cells_kind(cm)


def read_kind(path):
    """``(cell kind, CellMesh)`` of a file; ``(PLANAR, None)`` for a format registered with
    a triangle-mesh reader only (it is read by ``io.load``)."""
    from pathlib import Path

    from ..io import CELL_READERS, load_cells

    if Path(path).suffix.lower() not in CELL_READERS:
        return PLANAR, None
    cells = load_cells(path)
    return cells_kind(cells), cells


def _float(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def merged_cells(cm, tolerance: float):
    """``(cells with vertices closer than tolerance merged, number merged)``."""
    from ..errors import MeshoptError
    from ..io.cells import CellMesh
    from ..orientation import merge_vertices

    if tolerance < 0 or tolerance != tolerance:
        raise MeshoptError(f"--merge-tolerance {tolerance}: must be a number >= 0")
    keep, cells, n = merge_vertices(cm.points, cm.cells, tolerance)
    if not n:
        return cm, 0
    return CellMesh(cm.points[keep], cells, cell_data=cm.cell_data, field_data=cm.field_data,
                    source=cm.source), n


def tet_info(mesh) -> dict:
    """Counts, admissibility and quality of a :class:`~meshopt_toolkit.mesh.TetMesh`."""
    q = mesh.quality()
    boundary = mesh.boundary_surface()
    n_crossing, crossing = _self_intersections(mesh.points, mesh.boundary_faces, "boundary ")
    return {
        "n_vertices": mesh.n_vertices,
        "n_tets": mesh.n_tets,
        "n_boundary_faces": int(len(mesh.boundary_faces)),
        "n_boundary_vertices": int(len(mesh.boundary_vertices)),
        "admissible": mesh.is_admissible,
        "n_inverted": int(len(mesh.inverted)),
        "inverted": mesh.inverted[:10].tolist(),
        "min_mean_ratio": _float(q.min_mean_ratio),
        "mean_mean_ratio": _float(q.mean_mean_ratio),
        "min_dihedral_deg": _float(q.min_dihedral_deg),
        "max_dihedral_deg": _float(q.max_dihedral_deg),
        "min_volume": _float(q.min_volume),
        "total_volume": _float(q.total_volume),
        "boundary_closed": boundary.is_closed,
        "boundary_manifold": boundary.is_manifold,
        "boundary_components": boundary.n_components,
        "self_intersecting": n_crossing,  # pairs of boundary triangles
        "n_tagged_triangles": 0 if mesh.triangles is None else int(len(mesh.triangles)),
        "physical_names": {k: list(v) for k, v in mesh.tag_names.items()},
        "problems": list(mesh.problems) + crossing,
    }


def _self_intersections(points, triangles, which: str = "") -> tuple[int, list[str]]:
    """How many pairs of ``which`` triangles intersect (exactly), and the problem line
    naming one pair (by triangle number, or by vertices for a tet mesh's boundary)."""
    from ..kernels.intersections3d import self_intersections

    pairs = self_intersections(points, triangles)
    if not len(pairs):
        return 0, []
    i, j = ((int(t) for t in pairs[0]) if not which else
            (tuple(int(v) for v in triangles[t]) for t in pairs[0]))
    name = "on vertices " if which else "triangles "
    many = f"{len(pairs)} pairs of {which}triangles intersect (e.g. " if len(pairs) > 1 \
        else f"two {which}triangles intersect ("
    return len(pairs), [f"{many}{name}{i} and {j})"]


def surface_info(mesh) -> dict:
    """Counts, topology and quality of a :class:`~meshopt_toolkit.mesh.SurfaceMesh`."""
    ar = mesh.aspect_ratios()
    closed = mesh.is_closed
    n_crossing, crossing = _self_intersections(mesh.points, mesh.triangles)
    return {
        "n_vertices": mesh.n_vertices,
        "n_triangles": mesh.n_triangles,
        "planar": False,
        "n_edges": int(len(mesh.edges)),
        "n_boundary_edges": int(len(mesh.boundary_edges)),
        "closed": closed,
        "boundary_loops": mesh.n_boundary_loops,
        "components": mesh.n_components,
        "euler_characteristic": [int(x) for x in mesh.euler_characteristics],
        "genus": mesh.genera,
        "manifold": mesh.is_manifold,
        "orientable": mesh.is_orientable,
        "oriented": mesh.is_oriented,
        "n_degenerate": int(len(mesh.degenerate_triangles)),
        "self_intersecting": n_crossing,
        "min_aspect_ratio": _float(ar.min()),
        "mean_aspect_ratio": _float(ar.mean()),
        "enclosed_volume": _float(mesh.enclosed_volume()) if closed and mesh.is_oriented
        and mesh.is_manifold and not n_crossing else None,
        "n_tagged_lines": 0 if mesh.lines is None else int(len(mesh.lines)),
        "physical_names": {k: list(v) for k, v in mesh.tag_names.items()},
        "problems": list(mesh.problems) + crossing,
    }


def mixed_info(cm) -> dict:
    """Counts per cell type (``n_<type>``), the bounding box, and the quality of the
    tetrahedra (mean ratios, dihedral angles, volumes) and triangles (aspect ratios 2r/R)
    among them; the other types are counted only."""
    from ..kernels.surface import aspect_ratios, degenerate_triangles
    from ..kernels.tetrahedra import tet_quality_summary

    pts = np.asarray(cm.points, np.float64)
    used = np.unique(np.concatenate([np.asarray(c).ravel() for _, c in cm.cells] or
                                    [np.zeros(0, np.int64)]))
    box = pts[used] if len(used) else pts
    info = {"n_vertices": cm.n_points, "n_cells": cm.n_cells, "dim": int(pts.shape[1])}
    info.update({f"n_{t}": n for t, n in cm.cell_counts().items()})
    info["bounding_box_min"] = [_float(x) for x in box.min(axis=0)] if len(box) else None
    info["bounding_box_max"] = [_float(x) for x in box.max(axis=0)] if len(box) else None
    p3 = pad3(pts)
    tets = [c for t, c in cm.cells if t == "tetra" and len(c)]
    if tets:
        q = tet_quality_summary(p3, np.concatenate(tets)).as_dict()
        info.update({f"tetra_{k}": (v if k == "n_inverted" else _float(v)) for k, v in q.items()})
    tris = [c for t, c in cm.cells if t == "triangle" and len(c)]
    if tris:
        tri = np.concatenate(tris)
        ar = aspect_ratios(p3, tri)
        info.update({"triangle_min_aspect_ratio": _float(ar.min()),
                     "triangle_mean_aspect_ratio": _float(ar.mean()),
                     "triangle_n_degenerate": int(len(degenerate_triangles(p3, tri)))})
    from ..io.cells import tag_names

    info["physical_names"] = {k: list(v) for k, v in tag_names(cm).items()}
    other = cm.describe_cells(other_cells(cm))
    info["operations"] = (f"convert and info only: move, morph, deform and optimize work on "
                          f"triangles and tetrahedra, not {other} cells")
    info["problems"] = []
    return info


def cells_info(cm, kind: str, path, merge_tolerance: float | None = None) -> dict:
    """The info dict of a tetrahedral mesh, a 3D surface or mixed cells read into ``cm``.

    Raises
    ------
    ReadError
        The cells do not make a valid mesh of that kind (message names the file).
    """
    from ..errors import InvalidMeshError, ReadError

    n_merged = 0
    if merge_tolerance is not None:
        cm, n_merged = merged_cells(cm, merge_tolerance)
    if kind == MIXED:
        info = {"path": str(path), "cell_kind": kind, **mixed_info(cm)}
        if merge_tolerance is not None:
            info["n_merged"] = n_merged
        return info
    try:
        mesh = cm.to_tet_mesh("meshopt info") if kind == TETS else \
            cm.to_surface_mesh("meshopt info")
    except InvalidMeshError as exc:
        raise ReadError(str(exc)) from exc
    info = {"path": str(path), "cell_kind": kind}
    info.update(tet_info(mesh) if kind == TETS else surface_info(mesh))
    if merge_tolerance is not None:
        info["n_merged"] = n_merged
    return info


def _fmt(value) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if value is None or (isinstance(value, (list, dict)) and not value):
        return "-"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, dict):
        return ", ".join(f"{k}={v[0]} (dim {v[1]})" for k, v in value.items())
    if isinstance(value, list):
        return ", ".join("-" if v is None else str(v) for v in value)
    return str(value)


def cells_text(info: dict) -> str:
    """The info dict as indented ``key  value`` lines under the path."""
    rows = [(k.replace("_", " "), _fmt(v)) for k, v in info.items()
            if k not in ("path", "problems")]
    if "self_intersecting" in info:  # a count of pairs of triangles, or "no"
        n = info["self_intersecting"]
        rows = [("self-intersecting", f"{n} triangle pair{'s' * (n > 1)}" if n else "no")
                if k == "self intersecting" else (k, v) for k, v in rows]
    return info_text(info, rows)


def info_text(info: dict, rows: list[tuple[str, str]]) -> str:
    """``rows`` as indented ``key  value`` lines under ``info``'s path, then its problems."""
    width = max(len(k) for k, _ in rows)
    lines = [info["path"]] + [f"  {k:<{width}}  {v}" for k, v in rows]
    lines += [f"  problem: {p}" for p in info["problems"]]
    return "\n".join(lines)
