"""``meshopt morph SOURCE TARGET -o OUTDIR``: an inversion-free geodesic morph.

The default metric is the per-triangle distortion metric ``M + JᵀJ``
(:mod:`meshopt_toolkit.motion`): no triangle's distortion changes by more than the path
length, so frames stay as healthy as their ends; ``--metric scalar`` uses the complete
metric ``I + ∇f∇fᵀ`` of f2 (thesis §5) instead, which only keeps frames non-inverted.
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
    p.add_argument("--metric", choices=("distortion", "scalar"), default="distortion",
                   help="per-triangle distortion metric (frames as healthy as their ends) or "
                        "the complete metric of the scalar penalty f2 (default: %(default)s)")
    p.add_argument("--weight", type=float, default=1.0,
                   help="with --metric distortion: w of M + w² JᵀJ (default: %(default)s)")
    p.add_argument("--beta", type=float_list(4), metavar="b1,b2,b3,b4",
                   default=DEFAULT_BETA,
                   help="--metric scalar: f2 coefficients of the complete metric, β4 unscaled "
                        f"(default: {','.join(f'{b:g}' for b in DEFAULT_BETA)})")
    p.add_argument("--no-normalize", action="store_true",
                   help="use the plain complete metric of f2 instead of that of √N·f2 "
                        "(which keeps the balance between motion and quality on fine meshes)")
    p.add_argument("--method", choices=("discrete", "shooting", "auto"), default="discrete",
                   help="frames from the discrete geodesic, the shooting geodesic, or shooting "
                        "with a fallback (default: %(default)s)")
    p.add_argument("--max-iter", type=int, default=None,
                   help="iterations of the discrete geodesic (default: 200 Levenberg–Marquardt "
                        "for the distortion metric, 500 Newton for the scalar one)")
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
    if args.max_iter is not None and args.max_iter < 1:
        raise MeshoptError("--max-iter must be at least 1")
    if not args.weight > 0 or args.weight == float("inf"):
        raise MeshoptError(f"--weight must be a positive number, got {args.weight}")
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
    if args.metric == "distortion":
        from ..motion.morph import distortion_morph

        max_iter = args.max_iter or 200
        with ProgressBar(max_iter, "morph") as bar:
            result = distortion_morph(source.as_planar(), target.as_planar(), frames=args.frames,
                                      weight=args.weight, max_iter=max_iter,
                                      callback=lambda nit, E, g: bar.update(status=f"E={E:.8g}"))
    else:
        # the Newton iteration usually stops well before --max-iter (energy stationary)
        max_iter = args.max_iter or 500
        with ProgressBar(max_iter, "morph") as bar:
            result = geodesic_morph(source, target, frames=args.frames, beta=args.beta,
                                    normalize=not args.no_normalize,
                                    method=args.method, max_iter=max_iter,
                                    callback=lambda nit, E, g: bar.update(status=f"E={E:.8g}"))
    base = source.as_planar()
    for name, mesh in zip(names, result.meshes(like=base)):
        io.save(mesh, outdir / name, overwrite=True)
    summary = result.summary()
    summary.update(source=str(src_path), target=str(tgt_path), files=names)
    if args.metric == "scalar":
        summary["beta"] = list(args.beta)
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
        converged = summary.get("converged", summary.get("discrete_converged"))
        state = "" if converged in (None, True) else (
            f"; NOT converged ({summary.get('status') or summary.get('discrete_status')}: "
            "frames admissible, the path is not yet a minimizer)")
        print(f"{result.n_frames} frames ({args.metric} metric), all admissible: "
              f"{summary['admissible']}, min aspect ratio {summary['min_aspect_ratio']:.4g}; "
              f"linear interpolation {lin}{state}")
        print(f"wrote {outdir}/ ({names[0]} … {names[-1]}, summary.json"
              + ("" if args.no_plots else ", " + ", ".join(PLOTS)) + ")")
    return 0
