"""``meshopt move``: move chosen vertices exactly, keep every triangle healthy.

Handles are given by ``--targets FILE`` (CSV rows ``index,x,y`` or a ``.npy`` k × 3 array;
the boundary vertices it does not list stay, unless ``--free-boundary``) or by
``--map "X_EXPR; Y_EXPR"`` (new positions of the boundary vertices, or with ``--group NAME``
of a physical group's nodes, or with ``--selection NAME`` of the vertices where the point
datum NAME is nonzero, where ``--where`` holds; the other boundary vertices stay).
Without ``--frames`` the moved mesh is written to ``-o OUT``; with ``--frames K``, OUT is a
directory with ``frame_000.<ext>`` … and ``quality.csv``. ``--json`` prints a summary
(inverted count, min aspect ratio, mean Λ, handle error, seconds). Existing outputs are
never overwritten without ``--force``; they are checked before the mesh is read.

The mesh moves in its plane (x, y for z = const; ``--map`` and ``--targets`` in the file's
units and the plane's coordinates), at unit size (``mt.move`` divides it by its size, see
:mod:`meshopt_toolkit.scaling`) and scaled back, so coordinates near 1e300 or 1e-300
work; the summary's lengths (handle error, the similarity's shift) are in the file's
units, its other numbers free of scale.

A file of tetrahedra moves in 3D: ``--targets`` rows
``index,x,y,z`` (.npy k × 4), ``--map "X_EXPR; Y_EXPR; Z_EXPR"`` in ``x, y, z``, the
candidates the boundary vertices or a physical group's nodes; the file is written back
with only its points replaced.

A triangle surface in 3D takes the same forms, but a map's
candidates are all its vertices (a closed surface has no boundary); the selected ones move,
an open surface's boundary stays, every other vertex is free.

The kind of the file's mesh is decided by ``mt.move``'s
:class:`~meshopt_toolkit.motion.moved_file.MovedFile`, which also writes it back; the
command parses, calls and prints.
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np

from .. import strict_json
from ..bounds import MAX_FRAMES
from ..filters.apply_coord_prescribed_motion import PrescribedMotion
from ..mesh.kinds import PLANAR, SURFACE, TETS
from ._common import (add_contact_flag, add_mesh_output, add_output_flags, checked_paths,
                      csv_table, frame_names, prepare_output_dir, warn_dropped, write_text)
from ._params import add_options
from ._validate import OptionError

HELP = "move chosen vertices exactly to targets; the rest follows, no triangle inverts"
EPILOG = (
    "Examples:\n"
    "  meshopt move annulus.msh -o turned.msh --where 'x**2 + y**2 < 0.25' \\\n"
    "      --map 'x*cos(pi/2) - y*sin(pi/2); x*sin(pi/2) + y*cos(pi/2)'\n"
    "  meshopt move mesh.msh --targets handles.csv --frames 9 -o motion/\n"
    "  meshopt move part.msh -o moved.msh --group hole --map 'x + 0.1; y'\n"
    "  meshopt move box.msh -o turned.msh --where 'x**2 + y**2 + z**2 < 0.2' \\\n"
    "      --map 'x*cos(pi/4) - y*sin(pi/4); x*sin(pi/4) + y*cos(pi/4); z'\n"
    "Use 'meshopt deform' instead to follow an initial velocity (a geodesic) rather than\n"
    "to reach prescribed positions."
)
#: options generated from the filter's parameters (one schema: cli/_params.py)
OPTIONS = {"steps": "--steps", "weight": "--weight"}


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("mesh", help="input mesh (admissible; planar triangles, tetrahedra or a "
                   "triangle surface in 3D)")
    add_mesh_output(p)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--targets", metavar="FILE", help="CSV 'index,x,y' rows or .npy (k, 3); "
                     "'index,x,y,z' or (k, 4) for tetrahedra")
    src.add_argument("--map", metavar="'X_EXPR; Y_EXPR'",
                     help="new positions of the selected boundary vertices, in x and y "
                          "('X_EXPR; Y_EXPR; Z_EXPR' in x, y, z for tetrahedra; for a "
                          "3D surface any of its vertices)")
    p.add_argument("--where", metavar="EXPR",
                   help="with --map: which boundary vertices move, e.g. 'x < 0.5' "
                        "(default: all; the others stay fixed)")
    p.add_argument("--group", metavar="NAME",
                   help="with --map: move the nodes of this physical group (name or number) "
                        "instead of the boundary; the other boundary vertices stay fixed")
    p.add_argument("--selection", metavar="NAME",
                   help="with --map: move the vertices whose point datum NAME is nonzero "
                        "(a .ply vertex property such as MeshLab's 'quality', or 'flags' "
                        "with the selection bit; .msh/.vtu point data) instead of the "
                        "boundary; the other boundary vertices stay fixed")
    p.add_argument("--free-boundary", action="store_true",
                   help="with --targets: the boundary vertices the file does not list move "
                        "freely (default: they stay fixed)")
    add_contact_flag(p, "a surface in 3D, or the free parts of a tet mesh's boundary,")
    add_options(p, PrescribedMotion, OPTIONS)
    add_output_flags(p, frames=MAX_FRAMES, frame_format="the input's")


def _check_choices(args: argparse.Namespace) -> None:
    for option, given in (("--where", args.where), ("--group", args.group),
                          ("--selection", args.selection)):
        if given is not None and args.map is None:
            raise OptionError(f"{option} needs --map")
    if args.free_boundary and args.targets is None:
        raise OptionError("--free-boundary is for --targets (--map keeps the boundary "
                          "vertices it does not move)")
    if args.group is not None and args.selection is not None:
        raise OptionError("give one of --group and --selection")


def _planar_table(result, frames: int) -> tuple[str, dict]:
    return "quality.csv", {"frame": range(frames), "min_aspect_ratio": result.min_aspect_ratio,
                           "mean_quality": result.mean_quality,
                           "strain_bound": result.strain_bound}


def _planar_line(mesh, result) -> str:
    return (f"inverted 0, min aspect ratio {result.min_aspect_ratio[0]:.4f} -> "
            f"{result.min_aspect_ratio[-1]:.4f}, mean Λ {result.mean_quality[-1]:.4f}")


def _tet_table(result, frames: int) -> tuple[str, dict]:
    return "quality.csv", {"frame": range(len(result.min_mean_ratio)),
                           "min_mean_ratio": result.min_mean_ratio}


def _tet_line(mesh, result) -> str:
    return (f"inverted 0, min mean ratio {float(mesh.mean_ratios().min()):.4f} -> "
            f"{result.min_mean_ratio[-1]:.4f}")


def _surface_table(result, frames: int) -> tuple[str, dict]:
    times = np.asarray(result.motion.times)
    picked = [times[int(np.argmin(np.abs(times - s)))] for s in np.linspace(0, 1, frames)]
    return "frames.csv", {"frame": range(frames), "path_fraction": picked}


def _surface_line(mesh, result) -> str:
    summary = result.summary()
    return (f"folds {summary['folds']}, worst relative quality "
            f"{summary['worst_relative_quality']:.4f}")


#: how each kind's result is written (the kind is mt.move's: MovedFile.kind): the frames'
#: table and the console line's middle
WRITTEN = {PLANAR: (_planar_table, _planar_line), TETS: (_tet_table, _tet_line),
           SURFACE: (_surface_table, _surface_line)}


def run(args: argparse.Namespace) -> int:
    from ..io import load_cells
    from ..motion.engine.contact import ContactWarning
    from ..motion.engine.handles import handles_in_space
    from ..motion.move import move
    from ..motion.moved_file import MovedFile
    from ..progress import ProgressBar

    _check_choices(args)
    src, out = checked_paths(args, PrescribedMotion, OPTIONS)
    frames = args.frames
    cells = load_cells(src)  # what it cannot keep named once the motion is done
    # the mesh mt.move moves (a planar one in its plane's coordinates) at the file's
    # scale (mt.move works at unit size), and the way back to every block, tag and datum
    moving = MovedFile.of_cells(cells, "move")
    handles, targets = handles_in_space(
        moving.mesh, targets=args.targets, mapping=args.map, where=args.where,
        group=args.group, selection=args.selection, point_data=cells.point_data,
        free_boundary=args.free_boundary, source=str(src))
    with warnings.catch_warnings(record=True) as caught, \
            ProgressBar(1000, "move") as bar:  # each warning one line naming the file
        warnings.simplefilter("always", ContactWarning)
        result = move(moving.mesh, handles, targets, frames=frames, steps=args.steps,
                      weight=args.weight, progress=bar.to_fraction,
                      contact=getattr(args, "contact", "on") == "on")
    for w in caught:
        print(f"meshopt move: warning: {src}: {w.message}", file=sys.stderr)
    warn_dropped(cells, src)  # a refused motion is its one error line alone
    table, line = WRITTEN[moving.kind]
    if frames is None:
        moving.moved(result.mesh).save(out, overwrite=args.force)
        written = str(out)
    else:  # created only now: a refused motion leaves nothing behind
        prepare_output_dir(out, force=args.force)
        for name, m in zip(frame_names(frames, args.format, src), result.frames):
            moving.moved(m).save(out / name)
        name, columns = table(result, frames)
        write_text(out / name, csv_table(columns))
        written = f"{out}/ ({frames} frames, {name})"
    summary = moving.summary(result, handles)
    if args.json:
        print(strict_json.dumps({"output": str(out), **summary}, indent=2))
    else:
        print(f"wrote {written}: {summary.get('handles', len(handles))} handles exact, "
              f"{line(moving.mesh, result)} ({result.seconds:.2f} s)")
    return 0
