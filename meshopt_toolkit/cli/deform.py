"""``meshopt deform``: move a mesh along a complete-metric geodesic (quality preserving).

The initial velocity (``--displacement``) is an (N, 2) array in a ``.npy`` or ``.csv``
file, or a mesh with the same connectivity (velocity = its points − the input's points).
Without ``--frames`` the final mesh is written to ``-o OUT`` (a mesh file). With
``--frames K`` OUT is a directory receiving ``frame_000.<ext>`` … (K meshes along the
path), ``snapshots.png``, ``aspect_ratio.png`` (mesh aspect ratio over time, like thesis
fig. 5.26) and ``quality.csv``. Existing outputs are never overwritten without ``--force``.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from ..errors import InvalidMeshError, WriteError
from ._common import float_list

HELP = "deform a mesh along a complete-metric geodesic, keeping it admissible"

logger = logging.getLogger(__name__)


def add_args(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = (
        "Default penalty: f1 with alpha = 1,0,1 (thesis section 5.5), Qref = the input mesh.\n"
        "Example: meshopt deform disc.msh --displacement v.npy --frames 9 -o out/"
    )
    p.add_argument("mesh", help="input mesh (admissible, planar)")
    p.add_argument("-o", "--output", required=True,
                   help="output mesh file, or a directory with --frames")
    p.add_argument("--displacement", required=True, metavar="D",
                   help="initial velocity: .npy or .csv (N, 2) array, or a mesh with the same "
                        "connectivity")
    p.add_argument("--time", type=float, default=1.0, help="final time T (default: %(default)s)")
    p.add_argument("--frames", type=int, help="write K frames on [0, T] into the OUT directory")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--alpha", type=float_list(3), metavar="a1,a2,a3",
                       help="f1 parameters (default: 1,0,1)")
    group.add_argument("--beta", type=float_list(4), metavar="b1,b2,b3,b4",
                       help="use f2 with these parameters instead (β4 unscaled)")
    p.add_argument("--euclidean", action="store_true",
                   help="follow the Euclidean geodesic Q + tV instead (for comparison)")
    p.add_argument("--rtol", type=float, help="integrator tolerance rtol = atol (default: 1e-6)")
    p.add_argument("--format", default=None, metavar="EXT",
                   help="frame file extension with --frames (default: the input's)")
    p.add_argument("--no-png", action="store_true", help="with --frames: skip the PNG figures")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")


def run(args: argparse.Namespace) -> int:
    from ..deform import deform, load_displacement
    from ..io import load, save
    from ..mesh import require_admissible

    src = Path(args.mesh)
    mesh = require_admissible(load(src), "deform")
    V = load_displacement(args.displacement, mesh)
    out = Path(args.output)
    frames = args.frames
    if frames is not None and frames < 2:
        raise InvalidMeshError(f"--frames must be at least 2, got {frames}")
    ext = (args.format or src.suffix).lower()
    if not ext.startswith("."):
        ext = "." + ext
    if frames is None:
        if out.exists() and not args.force:
            raise WriteError(f"{out}: exists (use --force to overwrite)")
        if out.is_dir():
            raise WriteError(f"{out}: is a directory (give a file name, or use --frames)")
        if out.resolve() == src.resolve():
            raise WriteError(f"{out}: refusing to overwrite the input mesh")
    else:
        if out.exists() and not out.is_dir():
            raise WriteError(f"{out}: exists and is not a directory (--frames writes a directory)")
        if out.is_dir() and any(out.iterdir()) and not args.force:
            raise WriteError(f"{out}: directory is not empty (use --force to overwrite)")

    res = deform(
        mesh, V, t=args.time, frames=frames, alpha=args.alpha, beta=args.beta,
        metric="euclidean" if args.euclidean else "complete", rtol=args.rtol,
        atol=None if args.rtol is None else args.rtol,
    )
    if frames is None:
        save(res.mesh, out, overwrite=True)
        print(f"{out}: t = {args.time:g}, mesh aspect ratio {res.aspect_ratio[0]:.4f} -> "
              f"{res.aspect_ratio[-1]:.4f}")
        return 0

    out.mkdir(parents=True, exist_ok=True)
    width = max(3, len(str(frames - 1)))
    for k, m in enumerate(res.meshes()):
        save(m, out / f"frame_{k:0{width}d}{ext}", overwrite=True)
    with open(out / "quality.csv", "w", encoding="utf-8") as fh:
        fh.write("t,min_aspect_ratio,penalty,energy\n")
        g = res.geodesic
        fh.writelines(f"{t:.10g},{ar:.10g},{f:.10g},{e:.10g}\n" for t, ar, f, e in zip(res.times, res.aspect_ratio, g.penalty, g.energy))
    if not args.no_png:
        from ..plotting import save_quality_plot, save_snapshot_strip

        titles = [f"t = {t:.3g}" for t in res.times]
        save_snapshot_strip(out / "snapshots.png", res.points, mesh.triangles, titles=titles)
        label = "Euclidean" if args.euclidean else "complete metric"
        save_quality_plot(out / "aspect_ratio.png", res.times, {label: res.aspect_ratio},
                          title="mesh aspect ratio along the path")
    print(f"{out}: {frames} frames on [0, {args.time:g}], mesh aspect ratio "
          f"min {res.aspect_ratio.min():.4f}, final {res.aspect_ratio[-1]:.4f}")
    return 0
