"""``meshopt move``: move chosen vertices exactly, keep every triangle healthy.

Handles are given by ``--targets FILE`` (CSV rows ``index,x,y`` or a ``.npy`` k × 3 array)
or by ``--map "X_EXPR; Y_EXPR"`` (new positions of the boundary vertices where ``--where``
holds; the other boundary vertices stay). Without ``--frames`` the moved mesh is written to
``-o OUT``; with ``--frames K``, OUT is a directory with ``frame_000.<ext>`` … and
``quality.csv``. ``--json`` prints a summary (inverted count, min aspect ratio, mean Λ,
handle error, seconds). Existing outputs are never overwritten without ``--force``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..errors import InvalidMeshError, WriteError

HELP = "move chosen vertices exactly to targets; the rest follows, no triangle inverts"


def add_args(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = (
        "Examples:\n"
        "  meshopt move annulus.msh -o turned.msh --where 'x**2 + y**2 < 0.25' \\\n"
        "      --map 'x*cos(pi/2) - y*sin(pi/2); x*sin(pi/2) + y*cos(pi/2)'\n"
        "  meshopt move mesh.msh --targets handles.csv --frames 9 -o motion/\n"
        "Use 'meshopt deform' instead to follow an initial velocity (a geodesic) rather than\n"
        "to reach prescribed positions."
    )
    p.add_argument("mesh", help="input mesh (admissible, planar)")
    p.add_argument("-o", "--output", required=True,
                   help="output mesh file, or a directory with --frames")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--targets", metavar="FILE", help="CSV 'index,x,y' rows or .npy (k, 3)")
    src.add_argument("--map", metavar="'X_EXPR; Y_EXPR'",
                     help="new positions of the selected boundary vertices, in x and y")
    p.add_argument("--where", metavar="EXPR",
                   help="with --map: which boundary vertices move, e.g. 'x < 0.5' "
                        "(default: all; the others stay fixed)")
    p.add_argument("--frames", type=int, help="write K frames of the motion into OUT/")
    p.add_argument("--steps", type=int, default=8,
                   help="continuation steps (default: %(default)s; split further when needed)")
    p.add_argument("--weight", type=float, default=1.0,
                   help="w of the metric M + w² JᵀJ (default: %(default)s)")
    p.add_argument("--format", default=None, metavar="EXT",
                   help="frame file extension with --frames (default: the input's)")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")


def _check_numbers(args: argparse.Namespace) -> None:
    import math

    if args.frames is not None and not 2 <= args.frames <= 1000:
        raise InvalidMeshError(f"--frames must be between 2 and 1000, got {args.frames}")
    if not 1 <= args.steps <= 1000:
        raise InvalidMeshError(f"--steps must be between 1 and 1000, got {args.steps}")
    if not (math.isfinite(args.weight) and args.weight > 0):
        raise InvalidMeshError(f"--weight must be a positive number, got {args.weight}")
    if args.where is not None and args.map is None:
        raise InvalidMeshError("--where needs --map")


def run(args: argparse.Namespace) -> int:
    from ..io import load, save
    from ..mesh import require_admissible
    from ..motion.move import move
    from ..motion.targets import read_target_table, targets_from_map
    from ..progress import ProgressBar

    _check_numbers(args)
    src = Path(args.mesh)
    out = Path(args.output)
    frames = args.frames
    if frames is None:
        if out.exists() and not args.force:
            raise WriteError(f"{out}: exists (use --force to overwrite)")
        if out.is_dir():
            raise WriteError(f"{out}: is a directory (give a file name, or use --frames)")
    else:
        if out.exists() and not out.is_dir():
            raise WriteError(f"{out}: exists and is not a directory (--frames writes a directory)")
        if out.is_dir() and any(out.iterdir()) and not args.force:
            raise WriteError(f"{out}: directory is not empty (use --force to overwrite)")
    mesh = require_admissible(load(src), "move")
    if args.targets is not None:
        handles, targets = read_target_table(args.targets)
    else:
        handles, targets = targets_from_map(mesh, args.map, args.where)
    with ProgressBar(1000, "move") as bar:
        def progress(s: float) -> None:
            bar.update(int(1000 * s) - bar.count)

        result = move(mesh, handles, targets, frames=frames, steps=args.steps,
                      weight=args.weight, progress=progress)
    if frames is None:
        if out.resolve() == src.resolve():
            raise WriteError(f"{out}: refusing to overwrite the input mesh")
        save(result.mesh, out, overwrite=args.force)
        written = str(out)
    else:
        ext = (args.format or src.suffix).lower()
        ext = ext if ext.startswith(".") else "." + ext
        out.mkdir(parents=True, exist_ok=True)
        width = max(3, len(str(frames - 1)))
        for k, m in enumerate(result.frames):
            save(m, out / f"frame_{k:0{width}d}{ext}", overwrite=True)
        with open(out / "quality.csv", "w", encoding="utf-8") as fh:
            fh.write("frame,min_aspect_ratio,mean_quality,strain_bound\n")
            fh.writelines(f"{k},{a:.10g},{q:.10g},{b:.10g}\n" for k, (a, q, b) in enumerate(
                zip(result.min_aspect_ratio, result.mean_quality, result.strain_bound)))
        written = f"{out}/ ({frames} frames, quality.csv)"
    summary = result.summary()
    if args.json:
        print(json.dumps({"output": str(out), **summary}, indent=2))
    else:
        print(f"wrote {written}: {len(handles)} handles exact, inverted 0, min aspect ratio "
              f"{result.min_aspect_ratio[0]:.4f} -> {result.min_aspect_ratio[-1]:.4f}, "
              f"mean Λ {result.mean_quality[-1]:.4f} ({result.seconds:.2f} s)")
    return 0
