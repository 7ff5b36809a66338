"""``meshopt move`` for a file of tetrahedra: handles in ``x, y, z``, the file written back
with only its points replaced (every block, tag, name and datum kept)."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import strict_json
from ._common import prepare_output_dir, write_text


def run_tets(args: argparse.Namespace, cells) -> int:
    """Move the tet mesh of ``cells`` (read from ``args.mesh``) as ``args`` ask, write it.

    The output checks (:func:`~._common.check_output_target`) are done by the caller.
    """
    from ..io import save_cells
    from ..motion.move import move
    from ..motion.targets import handles_of

    src, out, frames = Path(args.mesh), Path(args.output), args.frames
    mesh = cells.to_tet_mesh("move").require_admissible()
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
        write_text(out / "quality.csv", "frame,min_mean_ratio\n" + "".join(
            f"{k},{q:.10g}\n" for k, q in enumerate(result.min_mean_ratio)))
        shown = f"{out}/ ({frames} frames, quality.csv)"
    summary = result.summary()
    if args.json:
        print(strict_json.dumps({"output": str(out), "handles": int(len(np.unique(handles))),
                                 **summary}, indent=2))
    else:
        q = result.min_mean_ratio
        print(f"wrote {shown}: {len(np.unique(handles))} handles exact, inverted 0, "
              f"min mean ratio {float(mesh.mean_ratios().min()):.4f} -> {q[-1]:.4f} "
              f"({result.seconds:.2f} s)")
    return 0
