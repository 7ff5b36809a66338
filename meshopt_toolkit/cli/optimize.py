"""``meshopt optimize``: PDE-constrained shape optimization (the main job).

Without a mesh it solves the thesis' model problem (SPEC §6) on the bundled 146-vertex
disc by Riemannian L-BFGS on variant elasticity-euclidean (the defaults are chosen in
``benchmarks/bench_optimize.py``: :data:`~meshopt_toolkit.optimize.DEFAULT_VARIANT`,
``DEFAULT_METHOD``) with the thesis' parameter set 2 (table 6.3), whose β4 stays at its
146-vertex value on other meshes (:data:`~meshopt_toolkit.optimize.DEFAULT_PENALTY_BETA`).
"""

from __future__ import annotations

import argparse
import csv
from .. import strict_json
import logging
import os
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import ExpressionError, MeshoptError, WriteError
from ._common import (add_output_flags, check_output_dir, exclusive_output_dir, float_list,
                      load_workpiece, print_json, save_moved, warn_dropped,
                      write_summary, write_text)
from ._params import add_options, check_options
from ._validate import OptionError

HELP = ("shape optimization: minimize a Poisson, elasticity-compliance or Stokes-dissipation "
        "objective + f2 over admissible meshes")
EPILOG = (
    "β4 is given unscaled: f2 divides it by 2N (thesis table 6.3 lists β4/N_V).\n"
    "β2 is weighed by (A0/πR²)² (A0 the mesh's area, R half the largest side of its\n"
    "bounding box): f2's β2/ΣA pushes the boundary outwards as on the unit disc.\n"
    "Default (no MESH): bundled disc_146.msh, elasticity-euclidean, β^penalty =\n"
    "(0.1, 0.01, 0.01, 0.146) = thesis parameter set 2 at 146 vertices, with β4 fixed on\n"
    "every mesh (set 2 scales it with N, which squeezes fine meshes' boundary\n"
    "triangles; --penalty 0.1,0.01,0,0.001·N gives set 2) and β3 a contact barrier that\n"
    "acts only where a hole or notch is about to close, β^metric = (10, 1, 0, 0.01·N).\n"
    "With a MESH, j is weighed to the mesh (--objective-scale auto). Physical groups\n"
    "(--fixed, --move, --dirichlet, --neumann, --stress, --clamped) are gmsh physical\n"
    "groups of boundary lines (of boundary triangles on a tet mesh), by name or number.\n"
    "--pde stokes --objective dissipation: --dirichlet GROUP=VX,VY sets the velocity, u = 0\n"
    "on the rest of the boundary. --pde elasticity --objective compliance: --stress\n"
    "GROUP=SXX,SYY,SXY loads the group by the traction σn (plane stress); without\n"
    "--clamped the body floats and the loads must balance.\n"
    "A tet mesh: --dirichlet GROUP=VX,VY,VZ, --stress GROUP=SXX,SYY,SZZ,SYZ,SXZ,SXY,\n"
    "--rhs in x, y, z; the tet motion's metric and a distortion penalty (β1 of --penalty)\n"
    "keep the worst mean ratio at least 0.3 times its initial value.\n"
    "Exit status 1 when the run does not converge (max iterations, step too small);\n"
    "its (admissible) last mesh is still written."
)

DEFAULT_MESH = "disc_146.msh"
#: options generated from the filter's parameters (one schema: cli/_params.py)
OPTIONS = {"variant": "--variant", "method": "--method", "retraction": "--retraction",
           "lbfgs_preconditioner": "--lbfgs-preconditioner", "memory": "--memory",
           "rhs": "--rhs", "max_iterations": ("--max-iterations", "--max-iter"),
           "tolerance": ("--tolerance", "--tol"), "pde": "--pde", "young": "--young",
           "poisson_ratio": "--poisson-ratio", "viscosity": "--viscosity"}
#: the options naming physical groups (repeatable): metavar and help
GROUP_OPTIONS = {
    "--fixed": ("GROUP", "keep the vertices of this physical group (name or number) fixed"),
    "--move": ("GROUP", "only this boundary group moves, the rest of the boundary stays"),
    "--dirichlet": ("GROUP=VALUE", "poisson: y = VALUE on the group (default y = 0 on the "
                    "whole boundary, kept on the parts no option names); stokes: "
                    "GROUP=VX,VY, the velocity there (u = 0 on the rest)"),
    "--neumann": ("GROUP=VALUE", "poisson: dy/dn = VALUE on the group"),
    "--stress": ("GROUP=SXX,SYY,SXY", "elasticity: the traction σn of this stress on the "
                 "group (the rest of the boundary is free)"),
    "--clamped": ("GROUP", "elasticity: u = 0 on the group (none: the body floats)"),
}
OUTPUT_NAMES = ("history.csv", "history.json", "summary.json", "mesh.png", "history.png")

logger = logging.getLogger(__name__)


def add_args(p: argparse.ArgumentParser) -> None:
    from ..filters.apply_coord_shape_optimization import ShapeOptimization

    p.add_argument("mesh", nargs="?", help=f"input mesh (default: the bundled {DEFAULT_MESH})")
    p.add_argument("-o", "--output", default="meshopt-optimize",
                   help="output directory (default: %(default)s)")
    add_options(p, ShapeOptimization, OPTIONS)
    p.add_argument("--penalty", type=float_list(4), metavar="b1,b2,b3,b4",
                   help="β^penalty of f2 added to j; 0,0,0,0 = unpenalized "
                        "(default: 0.1,0.01,0.01,0.146, thesis set 2 with β4 fixed and a "
                        "contact barrier β3)")
    p.add_argument("--metric-penalty", type=float_list(4), metavar="b1,b2,b3,b4",
                   help="β^metric of the complete metric, complete-* variants only "
                        "(default: 10,1,0,0.01·N)")
    for flag, (metavar, text) in GROUP_OPTIONS.items():
        p.add_argument(flag, metavar=metavar, action="append", default=[],
                       help=f"{text} (repeatable)")
    p.add_argument("--keep-area", "--keep-volume", dest="keep_area", action="store_true",
                   help="the domain's area is an exact constraint (lbfgs, cg)")
    p.add_argument("--keep-barycenter", action="store_true",
                   help="the barycenter of the region the --move groups enclose is an exact "
                        "constraint (lbfgs, cg); with --keep-area that region's area is kept")
    p.add_argument("--objective", default="", metavar="OBJECTIVE",
                   help="poisson: 'integral' (∫y, the default) or 'tracking: EXPR' "
                        "(½∫(y − EXPR)²); elasticity: 'compliance'; stokes: 'dissipation' "
                        "(default: the PDE's first)")
    p.add_argument("--objective-scale", metavar="auto|W",
                   help="weight W of F = W·j + f2; auto (the default with a MESH) scales j to "
                        "the mesh, refuses steps that take the worst triangle below half its "
                        "initial aspect ratio and restarts with a smaller W if a run finds no "
                        "step (default without MESH: 1, the thesis' problem)")
    p.add_argument("--gtol", type=float, default=1e-5,
                   help="stop when the Riemannian gradient norm falls to GTOL times its first "
                        "value; 0 = off (default: %(default)s)")
    add_output_flags(p, plots=True)


def _prepare_outdir(outdir: Path, mesh_name: str, force: bool, input_path: Path) -> None:
    """Check (before the run) that ``outdir`` can take this run's files.

    Without ``force`` any existing output file (a previous run's included) is refused; with
    it the previous run's files are removed first, so a directory never mixes two runs.
    The directory is created and probed for writing, so a permission problem is reported
    as one line before hours of work.
    """
    names = (mesh_name,) + OUTPUT_NAMES
    if (outdir / mesh_name).resolve() == input_path.resolve():
        raise WriteError(f"{outdir / mesh_name}: refusing to overwrite the input mesh")
    clash = [n for n in names if (outdir / n).exists()]
    if clash and not force:
        raise WriteError(f"{outdir / clash[0]}: exists (use --force to overwrite)")
    try:
        outdir.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".meshopt-probe-", dir=outdir)
        os.close(fd)
        os.unlink(probe)
        for name in clash:
            (outdir / name).unlink()
    except OSError as exc:
        raise WriteError(f"{outdir}: cannot write the results there ({exc.strerror or exc})") from None


def run(args: argparse.Namespace) -> int:
    from ..datasets import data_path
    from ..expressions import quoted
    from ..filters.apply_coord_shape_optimization import ShapeOptimization
    from ..io import save_cells
    from ..optimize import (DEFAULT_PENALTY_BETA, DEFAULT_RETRACTION, VARIANT_PARTS,
                            OptimizeOptions, optimize)
    from ..progress import ProgressBar
    from ..shape.spec import kept_constraints, parse_objective, spec_from_options

    check_options(args, ShapeOptimization, OPTIONS)
    if args.metric_penalty is not None and VARIANT_PARTS[args.variant][0] != "complete":
        raise OptionError(f"--metric-penalty sets the complete metric's β: it has no effect "
                          f"with --variant {args.variant}")
    if args.retraction != DEFAULT_RETRACTION and not VARIANT_PARTS[args.variant][1]:
        raise OptionError(f"--retraction applies to complete-complete; --variant {args.variant} "
                          "moves along straight lines")
    input_path = Path(args.mesh) if args.mesh else data_path(DEFAULT_MESH)
    check_output_dir(Path(args.output), force=args.force,  # before any work
                     names=("optimized" + input_path.suffix.lower(),) + OUTPUT_NAMES)
    wp, cells, mesh = _load(input_path)
    penalty = args.penalty if args.penalty is not None else DEFAULT_PENALTY_BETA
    spec = spec_from_options(
        fixed=args.fixed, move=args.move, dirichlet=args.dirichlet, neumann=args.neumann,
        keep=kept_constraints(args.keep_area, args.keep_barycenter), objective=args.objective,
        rhs=args.rhs, scale=args.objective_scale or ("auto" if args.mesh else 1.0),
        pde=args.pde, stress=args.stress, clamped=args.clamped,
        material=dict(young=args.young, poisson_ratio=args.poisson_ratio,
                      viscosity=args.viscosity))
    try:
        objective = spec.make_objective(mesh)
    except ExpressionError as exc:
        if parse_objective(spec.objective) is None:
            raise ExpressionError(f"--rhs {quoted(args.rhs)}: {exc}") from None
        raise ExpressionError(f"--rhs {quoted(args.rhs)} / --objective {quoted(args.objective)}: "
                              f"{exc}") from None
    _check_problem(spec, mesh, args)
    outdir = Path(args.output)
    mesh_name = "optimized" + input_path.suffix.lower()
    _prepare_outdir(outdir, mesh_name, args.force, input_path)
    with exclusive_output_dir(outdir):
        _prepare_outdir(outdir, mesh_name, args.force, input_path)  # again, under the lock

        bar = ProgressBar(args.max_iterations, "optimize")

        def callback(record):
            bar.update(status=f"j={record.j:.5f} q={record.mean_shape_quality:.4f}")

        with bar:
            result = optimize(
                mesh, objective, variant=args.variant, method=args.method,
                penalty=penalty, metric_beta=args.metric_penalty, problem=spec,
                max_iterations=args.max_iterations, callback=callback,
                options=OptimizeOptions(
                    retraction=args.retraction, tolerance=args.tolerance or None,
                    gtol=args.gtol if args.gtol > 0 else None,
                    memory=args.memory, lbfgs_preconditioner=args.lbfgs_preconditioner),
            )
        summary = result.summary()
        summary.update(input=str(input_path), output=str(outdir / mesh_name),
                       penalty_weights=list(penalty), rhs=args.rhs, functional=spec.objective,
                       fixed=args.fixed, move=args.move, dirichlet=args.dirichlet,
                       neumann=args.neumann, keep_area=args.keep_area, pde=spec.pde,
                       stress=args.stress, clamped=args.clamped,
                       keep_barycenter=args.keep_barycenter)
        written = [mesh_name, "history.csv", "history.json", "summary.json"]
        try:
            if wp is None:  # tets: the file's cells, tags and data at the new points
                save_cells(replace(cells, points=np.array(result.x, dtype=float)),
                           outdir / mesh_name, overwrite=True)
            else:
                save_moved(wp, result.mesh, outdir / mesh_name)
            _write_history(outdir, result)
            write_summary(outdir, summary)
            if wp is not None and not args.no_plots and _write_plots(outdir, mesh, result,
                                                 args.rhs if spec.pde == "poisson" else None):
                written += ["mesh.png", "history.png"]
        except OSError as exc:
            raise WriteError(f"{outdir}: cannot write the results ({exc.strerror or exc})") from None
    if args.json:
        print_json(summary)
    else:
        print(f"{result.status}: {result.message}")
        F = "j + f2" if result.objective_weight == 1.0 else f"{result.objective_weight:.3g}·j + f2"
        print(f"iterations {result.nit}  j = {result.j:.6f}  {F} = {result.fun:.6f}  "
              f"{_quality_text(summary)}  "
              f"({result.seconds:.2f} s)")
        print(f"wrote {outdir}/ ({', '.join(written)})")
    if not result.success:
        print(f"meshopt optimize: error: {input_path}: not converged ({result.status}): "
              f"{result.message}; the last iterate was written to {outdir / mesh_name}",
              file=sys.stderr)
    return 0 if result.success else 1


def _quality_text(summary: dict) -> str:
    if "min_mean_ratio" in summary:
        return f"mean ratio {summary['mean_mean_ratio']:.4f}, worst {summary['min_mean_ratio']:.4f}"
    return f"Λ = {summary['mean_shape_quality']:.4f}  AR = {summary['min_aspect_ratio']:.4f}"


def _load(path: Path):
    """``(workpiece, cells, mesh)``: a planar file's workpiece (the plane's coordinates at
    the file's scale, in which ``--rhs`` is given; every block, tag and datum written
    back) and its mesh, or a tet file's cells and admissible ``TetMesh`` (workpiece None)."""
    from ..errors import InvalidMeshError
    from ..io import load_cells
    from ..mesh.kinds import cells_kind
    from ._info_cells import SURFACE, TETS

    cells = load_cells(path)
    warn_dropped(cells, path)
    kind = cells_kind(cells)
    if kind == TETS:
        return None, cells, cells.to_tet_mesh("optimize").require_admissible()
    if kind == SURFACE:
        raise InvalidMeshError(f"{path}: optimize supports planar triangle and tetrahedral "
                               "meshes; this is a triangle surface in 3D (its points are not "
                               "on one plane)")
    wp = load_workpiece(path, "optimize", cells=cells)
    return wp, cells, wp.mesh


def _check_problem(spec, mesh, args) -> None:
    """What :func:`~meshopt_toolkit.optimize.optimize` would refuse of the groups, the
    constraints and the options a tet mesh does not take, before the output directory
    is made."""
    from ..mesh.kinds import is_tets

    method = args.method
    if is_tets(mesh):
        from ..shape.tets import check_tet_options

        check_tet_options(args.variant, args.lbfgs_preconditioner)
    free = spec.fixed_mask(mesh)
    if (spec.keep_area or spec.keep_barycenter) and method == "steepest":
        raise OptionError("--keep-area and --keep-barycenter need --method lbfgs or cg")
    spec.constraint(mesh, None, None if free is None else ~free)


def _write_history(outdir: Path, result) -> None:
    from ..io import atomic_path

    rows = [r.as_row() for r in result.history]
    with atomic_path(outdir / "history.csv") as tmp, open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    write_text(outdir / "history.json", strict_json.dumps(rows, indent=1) + "\n")


def _write_plots(outdir: Path, mesh, result, rhs_text: str | None) -> bool:
    """Write mesh.png and history.png (the Poisson rhs ``rhs_text`` shaded, if given);
    False (with a warning) when they cannot be made."""
    from ..expressions import parse_expression
    from ..plotting import save_optimization_plots

    try:
        save_optimization_plots(outdir / "mesh.png", outdir / "history.png", mesh.points,
                                result.x, mesh.triangles, result.history_columns(),
                                None if rhs_text is None else parse_expression(rhs_text))
    except MeshoptError as exc:  # e.g. matplotlib missing: the run itself succeeded
        logger.warning("figures not written: %s", exc)
        return False
    return True
