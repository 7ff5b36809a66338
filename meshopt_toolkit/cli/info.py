"""``meshopt info MESH... [--json]``: counts, planarity, admissibility, quality summary."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from ..errors import MeshoptError

HELP = "show counts, planarity, admissibility and quality of mesh files"


def add_args(parser) -> None:
    parser.add_argument("meshes", nargs="+", metavar="MESH",
                        help="mesh files, globs or directories")
    parser.add_argument("--json", action="store_true",
                        help="one JSON object per file and line (JSON Lines)")


def _clean(value):
    """JSON has no NaN/inf: non-finite floats become null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def mesh_info(path: str | Path) -> dict:
    """Load ``path`` and describe it: counts, checks of ``check_mesh`` and, for planar meshes,
    the quality summary (else null quality fields).

    Raises
    ------
    ReadError
        The file cannot be read.
    """
    from ..io import load
    from ..mesh import _check_mesh

    mesh = load(path)
    keys = ["min_aspect_ratio", "mean_shape_quality", "min_angle_deg", "max_angle_deg",
            "min_area", "total_area", "n_inverted"]
    quality = None
    if mesh.is_planar:
        # the summary's smallest signed area tells the check whether it may skip its own
        # area pass (all areas > 0: nothing to re-orient, nothing inverted)
        pm = mesh.as_planar()
        quality = pm.quality()
        report = _check_mesh(pm, positive_areas=quality.min_area > 0)
        if report.reoriented:
            quality = report.mesh.quality()
    else:
        report = _check_mesh(mesh)
    info = {
        "path": str(path),
        "n_vertices": mesh.n_vertices,
        "n_triangles": mesh.n_triangles,
        "n_boundary_vertices": int(len(mesh.boundary_vertices)),
        "dim": mesh.dim,
        "planar": report.planar,
        "manifold": report.manifold,
        "admissible": report.admissible,
        "reoriented": report.reoriented,
        "problems": list(report.problems),
        "n_tagged_lines": 0 if mesh.lines is None else int(len(mesh.lines)),
        "physical_names": {k: list(v) for k, v in mesh.tag_names.items()},
    }
    if quality is not None:
        q = quality.as_dict()
        info.update({k: _clean(q[k]) for k in keys})
    else:
        info.update({k: None for k in keys})
    return info


def _fmt(value) -> str:
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
    rows = [(k.replace("_", " "), _fmt(v)) for k, v in info.items()
            if k not in ("path", "problems")]
    width = max(len(k) for k, _ in rows)
    lines = [info["path"]] + [f"  {k:<{width}}  {v}" for k, v in rows]
    lines += [f"  problem: {p}" for p in info["problems"]]
    return "\n".join(lines)


def run(args) -> int:
    from ._common import expand_inputs

    status = 0
    first = True
    for item in args.meshes:
        try:
            paths = expand_inputs([item])
        except MeshoptError as exc:
            print(f"meshopt info: error: {exc}", file=sys.stderr)
            status = 1
            continue
        for path in paths:
            try:
                info = mesh_info(path)
            except MeshoptError as exc:
                print(f"meshopt info: error: {exc}", file=sys.stderr)
                status = 1
                continue
            if args.json:
                print(json.dumps(info), flush=True)
            else:
                if not first:
                    print()
                print(_text(info), flush=True)
                first = False
    return status
