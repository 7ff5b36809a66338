"""``meshopt morph SOURCE TARGET -o OUTDIR``: an inversion-free geodesic morph.

The default metric is the per-triangle distortion metric ``M + JᵀJ``
(:mod:`meshopt_toolkit.motion`): no triangle's distortion changes by more than the path
length, so frames stay as healthy as their ends; ``--metric scalar`` uses the complete
metric ``I + ∇f∇fᵀ`` of f2 (thesis §5) instead, which only keeps frames non-inverted.
Writes ``frame_000.<ext>`` … (frame 0 the source, the last the target), ``strip.png`` (a
strip of snapshots), ``quality.png`` (minimum aspect ratio per frame of the geodesic and
of linear interpolation, with the linear path's inverted frames marked) and
``summary.json``.

Both meshes are morphed at unit size (divided by one power of two nearest their size, see
:mod:`meshopt_toolkit.scaling`) and the frames scaled back, so coordinates near 1e300 or
1e-300 work and the frames do not depend on the units; the numbers in ``summary.json`` are
those of the unit-size problem (lengths, areas, energies), with the factor as
``unit_scale``.
"""

from __future__ import annotations

import argparse
from .. import strict_json
import sys
from pathlib import Path

from ..bounds import MAX_ITERATIONS
from ..filters.generate_geodesic_morph import GenerateGeodesicMorph
from ._common import (add_output_flags, check_mesh_format, check_output_dir, float_list,
                      frame_names, prepare_output_dir, save_moved, write_text)
from ._params import add_options, check_options
from ._validate import check_int, check_numbers

HELP = "geodesic morph between two meshes of the same connectivity (never inverts)"
#: options generated from the filter's parameters (one schema: cli/_params.py)
OPTIONS = {"frames": "--frames", "metric": "--metric", "weight": "--weight",
           "method": "--method"}

PLOTS = ("strip.png", "quality.png")


def add_args(p: argparse.ArgumentParser) -> None:
    from ..motion.scalar_morph import DEFAULT_BETA

    p.add_argument("source", help="source mesh (frame 0)")
    p.add_argument("target", help="target mesh (last frame), same vertices and triangles")
    p.add_argument("-o", "--output", required=True, help="output directory")
    add_options(p, GenerateGeodesicMorph, OPTIONS)
    p.add_argument("--penalty", "--beta", dest="beta", type=float_list(4),
                   metavar="b1,b2,b3,b4", default=None,
                   help="--metric scalar: f2 coefficients of the complete metric, β4 unscaled "
                        f"(default: {','.join(f'{b:g}' for b in DEFAULT_BETA)})")
    p.add_argument("--no-normalize", action="store_true",
                   help="use the plain complete metric of f2 instead of that of √N·f2 "
                        "(which keeps the balance between motion and quality on fine meshes)")
    p.add_argument("--max-iterations", "--max-iter", dest="max_iter", type=int, default=None,
                   help="iterations of the discrete geodesic (default: 200 Levenberg–Marquardt "
                        "for the distortion metric, 500 Newton for the scalar one)")
    add_output_flags(p, plots=True, frame_format="the source's")


def _check_numbers(args: argparse.Namespace) -> None:
    check_options(args, GenerateGeodesicMorph, OPTIONS)
    check_int("--max-iterations", args.max_iter, 1, MAX_ITERATIONS)
    check_numbers("--penalty", args.beta)


def _check_outputs(args: argparse.Namespace) -> None:
    """Before any work: the frame format is one we write and OUTDIR can take the files."""
    if args.format:
        check_mesh_format(args.format, "--format")
    else:
        check_mesh_format(args.source)
    names = frame_names(args.frames, args.format, args.source)
    check_output_dir(Path(args.output), force=args.force,
                     names=names + list(PLOTS) + ["summary.json"])


def run(args: argparse.Namespace) -> int:
    from .. import io
    from ..io.workpiece import Workpiece
    from ..motion.scalar_morph import DEFAULT_BETA
    from ..operations import DEFAULT_MAX_ITER, METRIC_ALIASES, morph
    from ..plotting import save_morph_figures
    from ..progress import ProgressBar

    _check_numbers(args)
    _check_outputs(args)
    src_path, tgt_path = Path(args.source), Path(args.target)
    # the source's plane at unit size (one power of two for both ends); the frames are
    # written with every block, tag and datum of the source
    wp, twp = Workpiece.from_cells(io.load_cells(src_path)).with_target(io.load_cells(tgt_path))
    source, target = wp.mesh, twp.mesh
    outdir = Path(args.output)
    names = frame_names(args.frames, args.format, src_path)
    prepare_output_dir(outdir, force=args.force, names=names + list(PLOTS) + ["summary.json"])
    max_iter = args.max_iter or DEFAULT_MAX_ITER[METRIC_ALIASES.get(args.metric, args.metric)]
    with ProgressBar(max_iter, "morph") as bar:
        result = morph(source, target, args.frames, metric=args.metric, weight=args.weight,
                       beta=args.beta, normalize=not args.no_normalize, method=args.method,
                       max_iterations=max_iter,
                       callback=lambda it: bar.update(status=f"E={it.energy:.8g}"))
    for name, mesh in zip(names, result.frames):
        save_moved(wp, mesh, outdir / name, what=name)
    summary = result.summary()
    summary.update(source=str(src_path), target=str(tgt_path), files=names,
                   unit_scale=wp.scale.factor)
    if args.metric == "scalar":
        summary["beta"] = list(args.beta or DEFAULT_BETA)
    write_text(outdir / "summary.json", strict_json.dumps(summary, indent=2) + "\n")
    if not args.no_plots:
        save_morph_figures(result, outdir / "strip.png", outdir / "quality.png")
    if args.json:
        strict_json.dump(summary, sys.stdout)
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
