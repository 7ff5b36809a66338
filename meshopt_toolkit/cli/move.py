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

A file of tetrahedra moves in 3D (:mod:`._move_space`): ``--targets`` rows
``index,x,y,z`` (.npy k × 4), ``--map "X_EXPR; Y_EXPR; Z_EXPR"`` in ``x, y, z``, the
candidates the boundary vertices or a physical group's nodes; the file is written back
with only its points replaced.

A triangle surface in 3D (:mod:`._move_space` too) takes the same forms, but a map's
candidates are all its vertices (a closed surface has no boundary); the selected ones move,
an open surface's boundary stays, every other vertex is free.
"""

from __future__ import annotations

import argparse
from .. import strict_json

from ..bounds import MAX_FRAMES
from ..filters.apply_coord_prescribed_motion import PrescribedMotion
from ._common import (add_output_flags, checked_paths, csv_table, frame_names, load_workpiece,
                      save_moved, save_moved_frames, warn_dropped, write_text)
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
    p.add_argument("-o", "--output", required=True,
                   help="output mesh file, or a directory with --frames")
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
    p.add_argument("--contact", choices=("on", "off"), default="on",
                   help="a surface in 3D, or the free parts of a tet mesh's boundary, "
                        "never passes through itself along the motion (where its rest is "
                        "free of self-intersections; default on)")
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


def run(args: argparse.Namespace) -> int:
    from ..io import load_cells
    from ..motion.engine.handles import handles_in_space
    from ..motion.move import move
    from ..progress import ProgressBar
    from ..mesh.kinds import SURFACE, TETS, cells_kind
    from ._move_space import run_in_space

    _check_choices(args)
    src, out = checked_paths(args, PrescribedMotion, OPTIONS)
    frames = args.frames
    cells = load_cells(src)  # what it cannot keep named once the motion is done
    kind = cells_kind(cells)
    if kind in (TETS, SURFACE):  # handles in x, y, z; the file written back, new points
        return run_in_space(args, cells, kind)
    # the plane's coordinates at the file's scale (mt.move works at unit size); every
    # block, tag and datum written back
    wp = load_workpiece(src, "move", cells=cells)
    mesh = wp.mesh
    handles, targets = handles_in_space(
        mesh, targets=args.targets, mapping=args.map, where=args.where,
        group=args.group, selection=args.selection, point_data=wp.cells.point_data,
        free_boundary=args.free_boundary, source=str(src))
    with ProgressBar(1000, "move") as bar:
        result = move(mesh, handles, targets, frames=frames, steps=args.steps,
                      weight=args.weight, progress=bar.to_fraction)
    warn_dropped(cells, src)
    if frames is None:
        save_moved(wp, result.mesh, out, force=args.force)
        written = str(out)
    else:
        save_moved_frames(wp, result.frames, out, frame_names(frames, args.format, src),
                          force=args.force)
        write_text(out / "quality.csv", csv_table({
            "frame": range(frames), "min_aspect_ratio": result.min_aspect_ratio,
            "mean_quality": result.mean_quality, "strain_bound": result.strain_bound}))
        written = f"{out}/ ({frames} frames, quality.csv)"
    summary = result.summary()
    if args.json:
        print(strict_json.dumps({"output": str(out), **summary}, indent=2))
    else:
        print(f"wrote {written}: {len(handles)} handles exact, inverted 0, min aspect ratio "
              f"{result.min_aspect_ratio[0]:.4f} -> {result.min_aspect_ratio[-1]:.4f}, "
              f"mean Λ {result.mean_quality[-1]:.4f} ({result.seconds:.2f} s)")
    return 0
