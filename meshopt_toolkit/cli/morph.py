"""``meshopt morph SOURCE TARGET -o OUTDIR``: an inversion-free geodesic morph (issue #7).

Writes ``frame_000.<ext>`` … (frame 0 the source, the last the target), ``strip.png`` (a
strip of snapshots), ``quality.png`` (minimum aspect ratio per frame of the geodesic and
of linear interpolation, with the linear path's inverted frames marked) and
``summary.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..errors import MeshoptError, WriteError
from ._common import float_list

HELP = "geodesic morph between two meshes of the same connectivity (never inverts)"

PLOTS = ("strip.png", "quality.png")


def add_args(p: argparse.ArgumentParser) -> None:
    from ..morph import DEFAULT_BETA

    p.add_argument("source", help="source mesh (frame 0)")
    p.add_argument("target", help="target mesh (last frame), same vertices and triangles")
    p.add_argument("-o", "--output", required=True, help="output directory")
    p.add_argument("--frames", type=int, default=9, help="number of frames K >= 2 (default: %(default)s)")
    p.add_argument("--beta", type=float_list(4), metavar="b1,b2,b3,b4",
                   default=DEFAULT_BETA,
                   help="f2 coefficients of the complete metric, β4 unscaled "
                        f"(default: {','.join(f'{b:g}' for b in DEFAULT_BETA)})")
    p.add_argument("--no-normalize", action="store_true",
                   help="use the plain complete metric of f2 instead of that of √N·f2 "
                        "(which keeps the balance between motion and quality on fine meshes)")
    p.add_argument("--method", choices=("discrete", "shooting", "auto"), default="discrete",
                   help="frames from the discrete geodesic, the shooting geodesic, or shooting "
                        "with a fallback (default: %(default)s)")
    p.add_argument("--max-iter", type=int, default=500,
                   help="Newton iterations of the discrete geodesic (default: %(default)s)")
    p.add_argument("--format", default=None,
                   help="extension of the frame files, e.g. msh, vtk, obj (default: the source's)")
    p.add_argument("--no-plots", action="store_true", help="do not write PNG figures")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")


def run(args: argparse.Namespace) -> int:
    from .. import io
    from ..morph import geodesic_morph
    from ..plotting import save_morph_figures
    from ..progress import ProgressBar

    if args.frames < 2:
        raise MeshoptError("--frames must be at least 2")
    if args.max_iter < 1:
        raise MeshoptError("--max-iter must be at least 1")
    src_path, tgt_path = Path(args.source), Path(args.target)
    source = io.load(src_path)
    target = io.load(tgt_path)
    ext = (args.format or src_path.suffix.lstrip(".") or "msh").lower().lstrip(".")
    outdir = Path(args.output)
    width = max(3, len(str(args.frames - 1)))
    names = [f"frame_{k:0{width}d}.{ext}" for k in range(args.frames)]
    outdir.mkdir(parents=True, exist_ok=True)
    clash = [n for n in names + list(PLOTS) + ["summary.json"] if (outdir / n).exists()]
    if clash and not args.force:
        raise WriteError(f"{outdir / clash[0]}: exists (use --force to overwrite)")
    # the Newton iteration usually stops well before --max-iter (energy stationary)
    with ProgressBar(args.max_iter, "morph") as bar:
        result = geodesic_morph(source, target, frames=args.frames, beta=args.beta,
                                normalize=not args.no_normalize,
                                method=args.method, max_iter=args.max_iter,
                                callback=lambda nit, E, g: bar.update(status=f"E={E:.8g}"))
    base = source.as_planar()
    for name, mesh in zip(names, result.meshes(like=base)):
        io.save(mesh, outdir / name, overwrite=True)
    summary = result.summary()
    summary.update(source=str(src_path), target=str(tgt_path), beta=list(args.beta),
                   files=names)
    from ..io import atomic_path

    with atomic_path(outdir / "summary.json") as tmp:
        tmp.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    if not args.no_plots:
        save_morph_figures(result, outdir / "strip.png", outdir / "quality.png")
    if args.json:
        json.dump(summary, sys.stdout)
        sys.stdout.write("\n")
    else:
        lin = "inverts" if summary["linear_inverts"] else "does not invert"
        print(f"{result.n_frames} frames ({result.method}), all admissible: {summary['admissible']}, "
              f"min aspect ratio {summary['min_aspect_ratio']:.4g}, target error "
              f"{summary['target_error']:.3g}; linear interpolation {lin} "
              f"(min area {summary['linear_min_area']:.3g})")
        print(f"wrote {outdir}/ ({names[0]} … {names[-1]}, summary.json"
              + ("" if args.no_plots else ", " + ", ".join(PLOTS)) + ")")
    return 0
