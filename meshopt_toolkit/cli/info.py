"""``meshopt info MESH... [--json]``: counts, planarity, admissibility, quality summary.

Tetrahedral meshes, triangle surfaces not on one plane and files with other cells
(quads, hexahedra, wedges, pyramids, polygons: counts per cell type, bounding box, the
quality of their tetrahedra and triangles) are described by :mod:`._info_cells` (cell
kind, admissibility and mean ratios; closedness, manifold, orientation, genus and aspect
ratios).

Planar means all points on one plane (any plane: the mesh is checked and measured in the
plane's coordinates). Each edge-connected component is oriented by propagation and the
number of flipped triangles reported ("reoriented N triangles"); coincident vertices are
counted, and ``--merge-tolerance TOL`` merges vertices closer than TOL before checking.
Only this command's own modules are imported: no scipy, pymeshlab, gmsh or matplotlib
for a small clean mesh.
"""

from __future__ import annotations

from .. import strict_json
import sys
from pathlib import Path

from ..errors import MeshoptError
from ._common import add_inputs, add_recursive_flag

HELP = "show counts, planarity, admissibility and quality of mesh files"


def add_args(parser) -> None:
    add_inputs(parser, metavar="MESH")
    parser.add_argument("--json", action="store_true",
                        help="one JSON object per file and line (JSON Lines)")
    parser.add_argument("--merge-tolerance", type=float, default=None, metavar="TOL",
                        help="merge vertices closer than TOL (0: equal positions) first")
    add_recursive_flag(parser)


def mesh_info(path: str | Path, merge_tolerance: float | None = None) -> dict:
    """Load ``path`` and describe it: counts, checks of ``check_mesh`` and, for planar meshes
    (on any plane), the quality summary (else null quality fields).

    Parameters
    ----------
    path : str or Path
    merge_tolerance : float, optional
        Merge vertices closer than this before the checks (``n_merged`` says how many).

    Raises
    ------
    ReadError
        The file cannot be read.
    """
    import numpy as np

    from ..io import load
    from ..io.cells import triangle_mesh
    from ..mesh import check_mesh
    from ..mesh.kinds import mesh_kind
    from ._info_cells import PLANAR, cells_info, info_kind, read_kind

    kind, cells = read_kind(path)
    kind = kind if cells is None else info_kind(cells)
    if kind != PLANAR:  # tetrahedra, or triangles not on one plane
        return cells_info(cells, kind, path, merge_tolerance)
    mesh = load(path) if cells is None else triangle_mesh(cells)
    n_merged = 0
    if merge_tolerance is not None:
        mesh, n_merged = merged(mesh, merge_tolerance)
    keys = ["min_aspect_ratio", "mean_shape_quality", "min_angle_deg", "max_angle_deg",
            "min_area", "total_area", "n_inverted"]
    quality = None
    # the checks are exact and scale-free; the quality is measured at unit size (an
    # exact power of two: no overflow or underflow at 1e±300) and its areas scaled back
    scale = _unit_scale(mesh)
    if mesh_kind(mesh) == PLANAR:
        # the summary's smallest signed area tells the check whether it may skip its own
        # area pass (all areas > 0: nothing to re-orient, nothing inverted)
        pm = mesh.as_planar()
        quality = scale.mesh_down(pm).quality()
        report = check_mesh(pm, positive_areas=quality.min_area > 0)
        if report.reoriented:
            quality = scale.mesh_down(report.mesh).quality()
    else:
        report = check_mesh(mesh)
        if report.planar:
            quality = scale.mesh_down(report.mesh).quality()
    info = {
        "path": str(path),
        "cell_kind": PLANAR,
        "n_vertices": mesh.n_vertices,
        "n_triangles": mesh.n_triangles,
        "n_boundary_vertices": int(len(mesh.boundary_vertices)),
        "dim": mesh.dim,
        "planar": report.planar,
        "manifold": report.manifold,
        "admissible": report.admissible,
        "reoriented": bool(report.reoriented),
        "n_reoriented": int(report.n_reoriented),
        "problems": list(report.problems),
        "n_tagged_lines": 0 if mesh.lines is None else int(len(mesh.lines)),
        "physical_names": {k: list(v) for k, v in mesh.tag_names.items()},
    }
    if merge_tolerance is not None:
        info["n_merged"] = n_merged
    if quality is not None:
        q = quality.as_dict()
        with np.errstate(over="ignore", under="ignore"):  # beyond the float range: inf / 0
            for k in ("min_area", "total_area"):
                q[k] = float(np.ldexp(q[k], 2 * scale.exponent))
        info.update(strict_json.strict({k: q[k] for k in keys}))  # JSON: NaN/inf as null
    else:
        info.update({k: None for k in keys})
    return info


def _unit_scale(mesh):
    """The mesh's :class:`~meshopt_toolkit.scaling.UnitScale` (identity if a coordinate is
    not finite: the checks report that)."""
    import numpy as np

    from ..scaling import UnitScale, unit_scale

    return unit_scale(mesh) if np.isfinite(mesh.points).all() else UnitScale(0)


def merged(mesh, tolerance: float):
    """``(mesh with vertices closer than tolerance merged, number merged)``; tags are kept."""
    from ..io.cells import CellMesh
    from ._info_cells import merged_cells

    cells, n = merged_cells(CellMesh.from_triangle_mesh(mesh), tolerance)
    return (cells.to_triangle_mesh(), n) if n else (mesh, 0)


def _fmt(value, key: str = "", info: dict | None = None) -> str:
    if key == "reoriented" and value and info is not None:
        return f"{info.get('n_reoriented', 0)} triangles"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, dict)):
        return ", ".join(map(str, value)) if isinstance(value, list) else \
            ", ".join(f"{k}={v[0]} (dim {v[1]})" for k, v in value.items())
    return str(value)


def _text(info: dict) -> str:
    from ._info_cells import info_text

    rows = [(k.replace("_", " "), _fmt(v, k, info)) for k, v in info.items()
            if k not in ("path", "problems", "n_reoriented")]
    return info_text(info, rows)


def run(args) -> int:
    from ._common import expand_inputs
    from ._errors import naming
    from ._info_cells import PLANAR, cells_text

    status = 0
    first = True
    for item in args.inputs:
        try:
            paths = expand_inputs([item], recursive=args.recursive)
        except MeshoptError as exc:
            print(f"meshopt info: error: {naming(str(exc), [item])}", file=sys.stderr)
            status = 1
            continue
        for path in paths:
            try:
                info = mesh_info(path, args.merge_tolerance)
            except MeshoptError as exc:
                print(f"meshopt info: error: {naming(str(exc), [str(path)])}",
                      file=sys.stderr)
                status = 1
                continue
            if args.json:
                print(strict_json.dumps(info), flush=True)
            else:
                if not first:
                    print()
                print(_text(info) if info.get("cell_kind") == PLANAR else cells_text(info),
                      flush=True)
                first = False
    return status
