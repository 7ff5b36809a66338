"""``meshopt deform``: move a mesh along a complete-metric geodesic (quality preserving).

The initial velocity (``--displacement``) is an (N, 2) array in a ``.npy`` or ``.csv``
file, or a mesh with the same connectivity (velocity = its points − the input's points).
Without ``--frames`` the final mesh is written to ``-o OUT`` (a mesh file). With
``--frames K`` OUT is a directory receiving ``frame_000.<ext>`` … (K meshes along the
path), ``snapshots.png``, ``aspect_ratio.png`` (mesh aspect ratio over time, like thesis
fig. 5.26) and ``quality.csv``. Existing outputs are never overwritten without ``--force``;
outputs are checked before the integration starts, which shows a progress bar on a
terminal.

The mesh is deformed at unit size (``mt.deform`` divides it by its size, see
:mod:`meshopt_toolkit.scaling`) and scaled back, so the result does not depend on the
units of the file, and coordinates near 1e300 or 1e-300 work; the ``penalty`` and
``energy`` columns of ``quality.csv`` are those of the unit-size problem.
"""

from __future__ import annotations

import argparse
import logging

from ..bounds import MAX_FRAMES
from ._common import (add_mesh_output, add_output_flags, checked_paths, csv_table, float_list,
                      frame_names, load_workpiece, save_moved, save_moved_frames, write_text)
from ..filters.apply_coord_quality_preserving_deformation import QualityPreservingDeformation
from ._params import add_options
from ._validate import check_number, check_numbers

#: accepted range of --rtol (tighter stalls in round-off, looser is not an integration)
MIN_RTOL, MAX_RTOL = 1e-14, 0.1

HELP = "deform a mesh along a complete-metric geodesic, keeping it admissible"
EPILOG = (
    "Default penalty: f1 with alpha = 1,0,1 (thesis section 5.5), Qref = the input mesh.\n"
    "Example: meshopt deform disc.msh --displacement v.npy --frames 9 -o out/"
)
#: options generated from the filter's parameters (one schema: cli/_params.py)
OPTIONS = {"time": "--time"}

logger = logging.getLogger(__name__)


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("mesh", help="input mesh (admissible, planar)")
    add_mesh_output(p)
    p.add_argument("--displacement", required=True, metavar="D",
                   help="initial velocity: .npy or .csv (N, 2) array, or a mesh with the same "
                        "connectivity")
    add_options(p, QualityPreservingDeformation, OPTIONS)
    group = p.add_mutually_exclusive_group()
    group.add_argument("--alpha", type=float_list(3), metavar="a1,a2,a3",
                       help="f1 parameters (default: 1,0,1)")
    group.add_argument("--penalty", "--beta", type=float_list(4),
                       metavar="b1,b2,b3,b4",
                       help="use f2 with these parameters instead (β4 unscaled)")
    p.add_argument("--euclidean", action="store_true",
                   help="follow the Euclidean geodesic Q + tV instead (for comparison)")
    p.add_argument("--rtol", type=float,
                   help=f"integrator tolerance rtol = atol, in [{MIN_RTOL:g}, {MAX_RTOL:g}] "
                        "(default: 1e-6)")
    add_output_flags(p, json=False, plots=True, frames=MAX_FRAMES, frame_format="the input's")


def _check_numbers(args: argparse.Namespace) -> None:
    check_numbers("--alpha", args.alpha)
    check_numbers("--penalty", args.penalty)
    check_number("--rtol", args.rtol, low=MIN_RTOL, high=MAX_RTOL)


def run(args: argparse.Namespace) -> int:
    from ..deform import deform, load_displacement
    from ..riemannian.geodesic_options import GeodesicOptions
    from ..progress import ProgressBar

    _check_numbers(args)
    src, out = checked_paths(args, QualityPreservingDeformation, OPTIONS)
    frames = args.frames
    # the plane's coordinates at the file's scale (mt.deform works at unit size); every
    # block, tag and datum written back
    wp = load_workpiece(src, "deform")
    mesh = wp.mesh
    V = load_displacement(args.displacement, mesh, wp.plane_coordinates)
    with ProgressBar(1000, "deform") as bar:
        res = deform(
            mesh, V, time=args.time, frames=frames, alpha=args.alpha, penalty=args.penalty,
            metric="euclidean" if args.euclidean else "complete",
            options=GeodesicOptions(rtol=args.rtol, atol=args.rtol), progress=bar.to_fraction,
        )
    if frames is None:
        save_moved(wp, res.mesh, out, force=args.force)
        print(f"{out}: t = {args.time:g}, mesh aspect ratio {res.aspect_ratio[0]:.4f} -> "
              f"{res.aspect_ratio[-1]:.4f}")
        return 0

    save_moved_frames(wp, res.meshes(), out, frame_names(frames, args.format, src),
                      force=args.force)
    g = res.geodesic
    write_text(out / "quality.csv", csv_table({
        "t": res.times, "min_aspect_ratio": res.aspect_ratio, "penalty": g.penalty,
        "energy": g.energy}))
    if not args.no_plots:
        from ..plotting import save_quality_plot, save_snapshot_strip

        titles = [f"t = {t:.3g}" for t in res.times]
        save_snapshot_strip(out / "snapshots.png", res.points, mesh.triangles, titles=titles)
        label = "Euclidean" if args.euclidean else "complete metric"
        save_quality_plot(out / "aspect_ratio.png", res.times, {label: res.aspect_ratio},
                          title="mesh aspect ratio along the path")
    print(f"{out}: {frames} frames on [0, {args.time:g}], mesh aspect ratio "
          f"min {res.aspect_ratio.min():.4f}, final {res.aspect_ratio[-1]:.4f}")
    return 0
