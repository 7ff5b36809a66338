"""``meshopt morph SOURCE TARGET -o OUTDIR``: an inversion-free geodesic morph.

The default metric is the per-triangle distortion metric ``M + JᵀJ``
(:mod:`meshopt_toolkit.motion`): no triangle's distortion changes by more than the path
length, so frames stay as healthy as their ends; ``--metric scalar`` uses the complete
metric ``I + ∇f∇fᵀ`` of f2 (thesis §5) instead, which only keeps frames non-inverted.
Writes ``frame_000.<ext>`` … (frame 0 the source, the last the target), ``strip.png`` (a
strip of snapshots), ``quality.png`` (minimum aspect ratio per frame of the geodesic and
of linear interpolation, with the linear path's inverted frames marked) and
``summary.json``.

Tetrahedral meshes (a file with any tetrahedron) are morphed with the tet distortion
metric (:func:`meshopt_toolkit.motion.tets.morph.morph_tets`): every frame has every tet
positively oriented; the frames are the source file with only its points replaced (every
block, physical group, name and datum kept), with ``quality.csv`` and ``summary.json``
beside them (no plots). An end whose boundary intersects itself, or a morph with a frame
whose boundary (or surface) does, is refused in one line and nothing is written.

Two poses of a triangle surface in 3D (same triangles) are morphed by
:mod:`meshopt_toolkit.motion.surface.morph` (membrane distortion and bending, every frame
fold-free): the frames are the source's file with new points, with ``quality.csv`` (per
frame the worst relative quality and the folds) and ``summary.json``. ``--stop healthy``
(their default, ``auto``) stops as soon as every interior frame is as healthy as the worse
end, ``--stop converged`` runs the energy tests alone; planar and tet morphs stop on those
only and refuse ``--stop healthy``. Where both poses are free of self-intersections no
frame passes through the surface, nor the motion between two frames (``--contact on``, the
default: :mod:`meshopt_toolkit.motion.surface.morph_contact`); a pose that intersects
itself is morphed without contact, with one warning line naming the file and the count;
``--contact off`` morphs without contact, a frame through the surface refused.

The meshes go to ``mt.morph`` at the file's scale; it morphs them at unit size (both
divided by their size, see :mod:`meshopt_toolkit.scaling`) and scales the frames back, so
coordinates near 1e300 or 1e-300 work and the frames do not depend on the units. The
lengths in ``summary.json`` are in the file's units, its areas and energies those of the
unit-size problem (``--metric scalar`` gives the size as ``unit_scale``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..bounds import MAX_ITERATIONS
from ..filters.generate_geodesic_morph import GenerateGeodesicMorph
from ._common import (add_contact_flag, add_output_flags, check_mesh_format, check_output_dir,
                      csv_table, float_list, frame_names, prepare_output_dir, print_json,
                      save_moved, warn_dropped, write_summary, write_text)
from ._params import add_options, check_options
from ._validate import check_int, check_numbers

HELP = "geodesic morph between two meshes of the same connectivity (never inverts)"
#: options generated from the filter's parameters (one schema: cli/_params.py)
OPTIONS = {"frames": "--frames", "metric": "--metric", "weight": "--weight",
           "method": "--method", "stop": "--stop"}

PLOTS = ("strip.png", "quality.png")


def add_args(p: argparse.ArgumentParser) -> None:
    from ..motion.planar.scalar_morph import DEFAULT_BETA

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
    p.add_argument("--max-iterations", "--max-iter", dest="max_iterations", type=int,
                   default=None,
                   help="iterations of the discrete geodesic (default: 200 Levenberg–Marquardt "
                        "for the distortion metric, 500 Newton for the scalar one)")
    add_contact_flag(p, "a surface in 3D")
    add_output_flags(p, plots=True, frame_format="the source's")


def _check_numbers(args: argparse.Namespace) -> None:
    check_options(args, GenerateGeodesicMorph, OPTIONS)
    check_int("--max-iterations", args.max_iterations, 1, MAX_ITERATIONS)
    check_numbers("--penalty", args.beta)


def _check_outputs(args: argparse.Namespace, others=PLOTS) -> None:
    """Before any work: the frame format is one we write and OUTDIR can take the files
    (the frames, ``summary.json`` and ``others``)."""
    if args.format:
        check_mesh_format(args.format, "--format")
    else:
        check_mesh_format(args.source)
    names = frame_names(args.frames, args.format, args.source)
    check_output_dir(Path(args.output), force=args.force,
                     names=names + list(others) + ["summary.json"])


def _metric_options(args: argparse.Namespace) -> dict:
    """The metric of a planar morph: its name, or the complete metric with its options."""
    from ..errors import OptionError
    from ..operations import METRIC_ALIASES, CompleteMorph

    if METRIC_ALIASES.get(args.metric, args.metric) == "complete":
        return dict(metric=CompleteMorph(beta=args.beta, normalize=not args.no_normalize,
                                         method=args.method))
    if args.beta is not None or args.no_normalize or args.method != "discrete":
        raise OptionError("--penalty, --no-normalize and --method apply to --metric scalar "
                          "only")
    return dict(metric=args.metric)


def _morph(args: argparse.Namespace, source, target, default_iterations: int, **options):
    """:func:`~meshopt_toolkit.operations.morph` of ``source`` to ``target`` with the
    shared options and a progress bar (``--max-iterations`` or ``default_iterations``)."""
    from ..operations import morph
    from ..progress import ProgressBar

    max_iterations = args.max_iterations or default_iterations
    # the stages before the first iteration (a surface's search for a clean start) as
    # the bar's status
    with ProgressBar(max_iterations, "morph") as bar, bar.showing_log("meshopt_toolkit.motion"):
        return morph(source, target, args.frames, weight=args.weight,
                     max_iterations=max_iterations, stop=args.stop,
                     callback=lambda it: bar.update(status=f"E={it.energy:.8g}"), **options)


def run(args: argparse.Namespace) -> int:
    from .. import io
    from ..io.workpiece import Workpiece
    from ..motion.planar.scalar_morph import DEFAULT_BETA
    from ..operations import DEFAULT_MAX_ITER, METRIC_ALIASES
    from ..plotting import save_morph_figures
    from ._info_cells import SURFACE, TETS, read_kind

    _check_numbers(args)
    _check_outputs(args, others=())  # the outputs of every kind, before reading
    kind, cells = read_kind(args.source)  # what it cannot keep named before the writes
    if args.stop == "healthy" and kind != SURFACE:
        from ..errors import OptionError

        raise OptionError(f"{args.source}: --stop healthy applies to surfaces in 3D only; "
                          f"{'tet' if kind == TETS else 'planar'} morphs stop on their energy "
                          "tests alone (--stop converged, their default)")
    if kind == TETS:
        return _run_tets(args, cells)
    if kind == SURFACE:  # poses of a triangle surface in 3D
        return _run_surface(args, cells)
    _check_outputs(args)
    src_path, tgt_path = Path(args.source), Path(args.target)
    # the source's plane at the file's scale (mt.morph works at unit size); the frames
    # are written with every block, tag and datum of the source
    wp = Workpiece.from_cells(cells if cells is not None else io.load_cells(src_path))
    source, target = wp.mesh, wp.target(io.load_cells(tgt_path)).mesh
    outdir = Path(args.output)
    names = frame_names(args.frames, args.format, src_path)
    prepare_output_dir(outdir, force=args.force, names=names + list(PLOTS) + ["summary.json"])
    warn_dropped(cells, args.source)
    result = _morph(args, source, target,
                    DEFAULT_MAX_ITER[METRIC_ALIASES.get(args.metric, args.metric)],
                    **_metric_options(args))
    for name, mesh in zip(names, result.frames):
        save_moved(wp, mesh, outdir / name)
    summary = result.summary()
    summary.update(source=str(src_path), target=str(tgt_path), files=names)
    if args.metric == "scalar":
        summary["beta"] = list(args.beta or DEFAULT_BETA)
    write_summary(outdir, summary)
    if not args.no_plots:
        save_morph_figures(result, outdir / "strip.png", outdir / "quality.png")
    if args.json:
        print_json(summary)
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


def _run_tets(args: argparse.Namespace, cells) -> int:
    """The morph of two tetrahedral files: the source's cells written with each frame's
    points (every block, tag, name and datum kept), ``quality.csv`` and ``summary.json``."""
    from ..errors import OptionError
    from ..io import load_cells
    from ..mesh.kinds import TETS, cells_kind

    src_path, tgt_path = Path(args.source), Path(args.target)
    if args.metric != "distortion" or args.beta is not None or args.no_normalize:
        raise OptionError("tetrahedral meshes are morphed with the distortion metric only "
                          "(--metric scalar, --penalty and --no-normalize do not apply)")
    _check_outputs(args, others=["quality.csv"])
    names = frame_names(args.frames, args.format, src_path)
    target_cells = load_cells(tgt_path)
    if cells_kind(target_cells) != TETS:
        raise OptionError(f"{tgt_path}: has no tetrahedra, {src_path} has (a tetrahedral "
                          "source needs a tetrahedral target)")
    source = cells.to_tet_mesh("morph").require_admissible()
    target = target_cells.to_tet_mesh("morph").require_admissible()
    result = _morph(args, source, target, 200)
    summary, stats, linear = result.summary(), result.stats, result.linear
    worst = int(linear.inverted.max())
    lin = f"inverts up to {worst} tets" if worst else "does not invert"
    state = "" if result.converged else (
        f"; NOT converged ({result.status}: frames admissible, the path is not yet a "
        "minimizer)")
    return _write_cell_frames(
        args, cells, result.points, names, summary,
        csv_table({"frame": range(len(names)), "min_mean_ratio": stats.min_mean_ratio,
                   "linear_min_mean_ratio": linear.min_mean_ratio,
                   "linear_inverted": linear.inverted}),
        f"{result.n_frames} frames (distortion metric, tetrahedra), all admissible: "
        f"{summary['admissible']}, worst mean ratio {summary['min_mean_ratio']:.4g} "
        f"(ends {stats.min_mean_ratio[0]:.4g}, {stats.min_mean_ratio[-1]:.4g}); "
        f"linear interpolation {lin}{state}")


def _run_surface(args: argparse.Namespace, cells) -> int:
    """Morph two poses of a triangle surface in 3D (:mod:`..motion.surface.morph`); the
    frames are the source's file (every block, tag and datum) with new points, plus
    ``quality.csv`` (per frame: worst relative quality, folds) and ``summary.json``."""
    import warnings

    from .. import io
    from ..errors import OptionError
    from ..motion.engine.contact import ContactWarning

    src_path, outdir = Path(args.source), Path(args.output)
    if (args.metric != "distortion" or args.beta is not None or args.no_normalize
            or args.method != "discrete"):
        raise OptionError("surfaces in 3D are morphed with the distortion metric only "
                          "(--metric scalar, --penalty, --no-normalize and --method do not "
                          "apply)")
    source = cells.to_surface_mesh("morph")
    target = io.load_cells(Path(args.target)).to_surface_mesh("morph")
    names = frame_names(args.frames, args.format, src_path)
    written = names + ["quality.csv", "summary.json"]
    check_output_dir(outdir, force=args.force, names=written)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ContactWarning)
        result = _morph(args, source, target, 10, contact=args.contact == "on")
    for w in caught:  # the poses named by their files
        if issubclass(w.category, ContactWarning):
            line = str(w.message).replace("the source", str(src_path), 1)
            print(f"meshopt morph: warning: {line.replace('the target', str(args.target), 1)}",
                  file=sys.stderr)
    summary, m = result.summary(), result.morph
    return _write_cell_frames(
        args, cells, [mesh.points for mesh in result.frames], names, summary,
        csv_table({"frame": range(len(names)), "worst_relative_quality": m.worst_quality,
                   "folds": m.folds}),
        f"{len(names)} frames (surface), folds {summary['folds']}, worst relative "
        f"quality {summary['worst_relative_quality']:.4g} (target "
        f"{summary['target_worst_relative_quality']:.4g}; linear interpolation "
        f"{summary['linear_worst_relative_quality']:.4g}, "
        f"{summary['linear_folds']} folds), {result.status}")


def _write_cell_frames(args: argparse.Namespace, cells, frames, names: list[str],
                       summary: dict, quality_csv: str, text: str) -> int:
    """Write a tet or surface morph into OUTDIR: the source's ``cells`` (every block, tag,
    name and datum) with each frame's points under ``names``, ``quality.csv`` and
    ``summary.json``; then the summary (``--json``) or ``text`` on stdout."""
    from dataclasses import replace

    import numpy as np

    from ..io import save_cells

    outdir = Path(args.output)
    prepare_output_dir(outdir, force=args.force, names=names + ["quality.csv", "summary.json"])
    warn_dropped(cells, args.source)
    for name, points in zip(names, frames):
        save_cells(replace(cells, points=np.array(points, dtype=float)), outdir / name)
    write_text(outdir / "quality.csv", quality_csv)
    summary.update(source=str(Path(args.source)), target=str(Path(args.target)), files=names)
    write_summary(outdir, summary)
    if args.json:
        print_json(summary)
    else:
        print(text)
        print(f"wrote {outdir}/ ({names[0]} … {names[-1]}, quality.csv, summary.json)")
    return 0
