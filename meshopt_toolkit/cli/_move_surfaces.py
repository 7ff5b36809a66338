"""``meshopt move`` for a triangle surface in 3D: handles in ``x, y, z`` (a map's
candidates are all the vertices; an open surface's boundary stays), the file written back
with only its points replaced (every block, tag, name and datum kept)."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import strict_json
from ._common import prepare_output_dir, write_text


def run_surfaces(args: argparse.Namespace, cells) -> int:
    """Move the surface of ``cells`` (read from ``args.mesh``) as ``args`` ask, write it.

    The output checks (:func:`~._common.check_output_target`) are done by the caller.
    """
    from ..io import save_cells
    from ..motion.move import move
    from ..motion.targets import handles_of

    src, out, frames = Path(args.mesh), Path(args.output), args.frames
    mesh = cells.to_surface_mesh("move")
    handles, targets = handles_of(mesh, targets=args.targets, mapping=args.map,
                                  where=args.where, group=args.group,
                                  free_boundary=args.free_boundary)
    result = move(mesh, handles, targets, frames=frames, steps=args.steps, weight=args.weight)

    def written(m):
        """The input's cells and data at the points of ``m``."""
        return replace(cells, points=np.array(m.points, dtype=float))

    if frames is None:
        save_cells(written(result.mesh), out, overwrite=args.force)
        shown = str(out)
    else:  # created only now: a refused motion leaves nothing behind
        prepare_output_dir(out, force=args.force)
        ext = (args.format or src.suffix).lower()
        ext = ext if ext.startswith(".") else "." + ext
        width = max(3, len(str(frames - 1)))
        for k, m in enumerate(result.frames):
            save_cells(written(m), out / f"frame_{k:0{width}d}{ext}")
        times = result.motion.times
        write_text(out / "frames.csv", "frame,path_fraction\n" + "".join(
            f"{k},{s:.10g}\n" for k, s in enumerate(
                [times[int(np.argmin(np.abs(np.asarray(times) - s)))]
                 for s in np.linspace(0, 1, frames)])))
        shown = f"{out}/ ({frames} frames, frames.csv)"
    summary = result.summary()
    n = len(np.unique(handles))
    if args.json:
        print(strict_json.dumps({"output": str(out), "handles": n, **summary}, indent=2))
    else:
        print(f"wrote {shown}: {n} handles exact, folds {summary['folds']}, worst relative "
              f"quality {summary['worst relative quality']:.4f} ({result.seconds:.2f} s)")
    return 0
