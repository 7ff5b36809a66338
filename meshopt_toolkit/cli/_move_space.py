"""``meshopt move`` for meshes in space — tetrahedra and triangle surfaces: handles in
``x, y, z``, the file written back with only its points replaced (every block, tag, name
and datum kept). A surface map's candidates are all its vertices (an open surface's
boundary stays); a tet map's are the boundary vertices, a physical group's nodes or the
vertices a point datum selects (``--selection``, :func:`~..motion.engine.handles.handles_in_space`,
which the move filter shares)."""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import strict_json
from ..motion.engine.contact import ContactWarning
from ._common import csv_table, frame_names, prepare_output_dir, warn_dropped, write_text
from ._info_cells import SURFACE, TETS


def _tet_mesh(cells):
    return cells.to_tet_mesh("move").require_admissible()


def _tet_table(result, frames: int) -> tuple[str, str]:
    return "quality.csv", csv_table({"frame": range(len(result.min_mean_ratio)),
                                     "min_mean_ratio": result.min_mean_ratio})


def _tet_line(mesh, result, summary: dict) -> str:
    return (f"inverted 0, min mean ratio {float(mesh.mean_ratios().min()):.4f} -> "
            f"{result.min_mean_ratio[-1]:.4f}")


def _surface_table(result, frames: int) -> tuple[str, str]:
    times = np.asarray(result.motion.times)
    picked = [times[int(np.argmin(np.abs(times - s)))] for s in np.linspace(0, 1, frames)]
    return "frames.csv", csv_table({"frame": range(frames), "path_fraction": picked})


def _surface_line(mesh, result, summary: dict) -> str:
    return (f"folds {summary['folds']}, worst relative quality "
            f"{summary['worst_relative_quality']:.4f}")


#: per cell kind: the mesh of the file's cells, the frames' table, the console line's middle
KINDS = {
    TETS: (_tet_mesh, _tet_table, _tet_line),
    SURFACE: (lambda cells: cells.to_surface_mesh("move"), _surface_table, _surface_line),
}


def run_in_space(args: argparse.Namespace, cells, kind: str) -> int:
    """Move the mesh of ``cells`` (read from ``args.mesh``; ``kind`` its
    :func:`~..mesh.kinds.cells_kind`, a key of :data:`KINDS`) as ``args`` ask, and write it.

    The output checks (:func:`~._common.check_output_target`) are done by the caller.
    """
    from ..io import save_cells
    from ..motion.engine.handles import handles_in_space
    from ..motion.move import move

    as_mesh, table, line = KINDS[kind]
    src, out, frames = Path(args.mesh), Path(args.output), args.frames
    mesh = as_mesh(cells)
    handles, targets = handles_in_space(
        mesh, targets=args.targets, mapping=args.map, where=args.where, group=args.group,
        selection=args.selection, point_data=cells.point_data,
        free_boundary=args.free_boundary, source=str(src))
    with warnings.catch_warnings(record=True) as caught:  # each one line naming the file
        warnings.simplefilter("always", ContactWarning)
        result = move(mesh, handles, targets, frames=frames, steps=args.steps,
                      weight=args.weight, contact=getattr(args, "contact", "on") == "on")
    for w in caught:
        print(f"meshopt move: warning: {src}: {w.message}", file=sys.stderr)
    warn_dropped(cells, src)  # a refused motion is its one error line alone

    def written(m):
        """The input's cells and data at the points of ``m``."""
        return replace(cells, points=np.array(m.points, dtype=float))

    if frames is None:
        save_cells(written(result.mesh), out, overwrite=args.force)
        shown = str(out)
    else:  # created only now: a refused motion leaves nothing behind
        prepare_output_dir(out, force=args.force)
        for name, m in zip(frame_names(frames, args.format, src), result.frames):
            save_cells(written(m), out / name)
        name, text = table(result, frames)
        write_text(out / name, text)
        shown = f"{out}/ ({frames} frames, {name})"
    summary = result.summary()
    n = int(len(np.unique(handles)))
    if args.json:
        print(strict_json.dumps({"output": str(out), "handles": n, **summary}, indent=2))
    else:
        print(f"wrote {shown}: {n} handles exact, {line(mesh, result, summary)} "
              f"({result.seconds:.2f} s)")
    return 0
