"""The drag of a body moving through Stokes fluid in a box, optimized on tetrahedra,
against the best prolate spheroid of the same volume (docs/shape-optimization.md,
"Shape optimization on tetrahedra").

The case (:func:`meshopt_toolkit.shape.cases.body_in_box`): a sphere of radius ½ at the
origin of the 8 × 6 × 6 box, the body moving at unit speed along ``x`` (``u = (1, 0, 0)``
on ``body``, ``u = 0`` on ``outer``), viscosity 1; the drag is the dissipation
``∫ 2μ|ε(u)|²`` (Taylor–Hood P2–P1). ``meshopt optimize``'s problem: ``--move body
--keep-volume --keep-barycenter``, every other default.

Rows, all with the same solver and the same element sizes (``--size`` at the box,
``--body-size`` on the body):

* prolate spheroids of the sphere's volume, axis ratio ``a/b`` scanned, each meshed by
  gmsh from its exact geometry;
* with ``--anchors pironneau``, bodies of the sphere's volume with the 60° conical ends of
  Pironneau's optimum in unbounded flow (``_bodies3d.py``), length over width and shoulder
  scanned (``--anchor-aspects``, ``--anchor-shoulders``), meshed the same way;
* the optimized body on the optimizer's own mesh (which it has also adapted to the flow).

Every body is also *remeshed* (:func:`remesh`: its surface triangles reparametrized, the
domain meshed afresh by gmsh at the same sizes), the spheroids from their gmsh meshes and
the optimized body from its final mesh: the remeshed drags compare shapes through one
meshing path, not the mesh the optimizer adapted.

Every remeshed drag is also computed independently (``--peer``): scikit-fem's Taylor–Hood
assembly on the written ``.msh`` (``_peers3d.py``).

Speed: the seconds per iteration over the seconds of one state solve (the objective at
the initial mesh, a fresh solver), printed at every iteration.

Usage: python benchmarks/bench_shape3d.py [--size 1.0] [--body-size 0.15] [--remesh 0.8,0.1]
       [--max-iterations 40] [--aspects 1,1.5,1.75,2,2.25,2.5] [--peer] [--write]
       python benchmarks/bench_shape3d.py --aspects 1,2.1 --anchors pironneau --no-optimize
       (the spheroids and anchors only; ``--write`` puts them in their own block)
       python benchmarks/bench_shape3d.py --large   (about 26,000 tets: --size 0.6
       --body-size 0.07 --aspects 2.1 --max-iterations 10)
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _bodies3d import conical_body_in_box, conical_profile
from _peers3d import dissipation_skfem3d
from meshopt_toolkit.gmsh_session import gmsh_session
from meshopt_toolkit.io import load_cells
from meshopt_toolkit.kernels.tetrahedra import mean_ratios
from meshopt_toolkit.optimize import optimize
from meshopt_toolkit.shape.cases import BOX_3D, body_in_box, mesh_body_in_box
from meshopt_toolkit.shape.constraints import barycenter, enclosed_measure
from meshopt_toolkit.shape.spec import spec_from_options

SPEC = dict(pde="stokes", dirichlet=["body=1,0,0", "outer=0,0,0"], objective="dissipation",
            move=["body"])
DOC = Path(__file__).resolve().parents[1] / "docs" / "shape-optimization.md"
BLOCKS = {True: "bench_shape3d", False: "bench_shape3d anchors"}  # by --optimize


def drag(mesh) -> tuple[float, float]:
    """``(dissipation, seconds)`` of a fresh solver on ``mesh``."""
    j = spec_from_options(**SPEC).make_objective(mesh)
    t0 = time.perf_counter()
    value = float(j.value(mesh.points))
    return value, time.perf_counter() - t0


def tets(path):
    return load_cells(path).to_tet_mesh("bench")


def remesh(mesh, path: Path, size: float, body_size: float) -> Path:
    """The domain of ``mesh`` (groups ``body``, ``outer``) meshed afresh by gmsh: its
    boundary triangles reparametrized (``classifySurfaces``, ``createGeometry``), the
    volume meshed with :func:`body_in_box`'s sizes."""
    P = np.asarray(mesh.points)
    names = mesh.tag_names
    with gmsh_session() as gmsh:
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add("remesh")
        done: set[int] = set()
        for name in ("body", "outer"):
            tris = mesh.triangles[mesh.triangle_tags == names[name][0]]
            s = gmsh.model.addDiscreteEntity(2)
            new = np.array([n for n in np.unique(tris) if n not in done], dtype=np.int64)
            done.update(new.tolist())
            gmsh.model.mesh.addNodes(2, s, (new + 1).tolist(), P[new].ravel().tolist())
            gmsh.model.mesh.addElementsByType(s, 2, [], (tris + 1).ravel().tolist())
        gmsh.model.mesh.classifySurfaces(np.radians(40), True, True, np.pi)
        gmsh.model.mesh.createGeometry()
        body, outer = [], []
        for _, t in gmsh.model.getEntities(2):
            box = gmsh.model.getBoundingBox(2, t)
            (body if max(map(abs, box)) < 0.25 * min(BOX_3D) else outer).append(t)
        gmsh.model.geo.addVolume([gmsh.model.geo.addSurfaceLoop(outer),
                                  gmsh.model.geo.addSurfaceLoop(body)])
        gmsh.model.geo.synchronize()
        mesh_body_in_box(gmsh, body, outer, path, size, body_size)
    return path


def body_extent(mesh, Q) -> tuple[float, float]:
    """The body's length along ``x`` and its largest width across."""
    body = np.unique(mesh.triangles[mesh.triangle_tags == mesh.tag_names["body"][0]])
    X = Q[body]
    width = 2 * np.linalg.norm(X[:, 1:] - X[:, 1:].mean(axis=0), axis=1).max()
    return float(np.ptp(X[:, 0])), float(width)


def peer(path: Path, enabled: bool) -> float:
    """The independent drag of the mesh in ``path`` (nan when not asked for)."""
    return dissipation_skfem3d(path) if enabled else float("nan")


def tip_angles(mesh, Q, reach: float = 0.1) -> tuple[float, float]:
    """Full cone angles in degrees of the body's front (``−x``) and back ends: the slope of
    the distance from the axis against the distance from the tip, fitted through the tip
    over the vertices within ``reach`` times the length of it."""
    body = np.unique(mesh.triangles[mesh.triangle_tags == mesh.tag_names["body"][0]])
    X = Q[body]
    r = np.linalg.norm(X[:, 1:] - X[:, 1:].mean(axis=0), axis=1)
    length = np.ptp(X[:, 0])
    angles = []
    for s in (X[:, 0] - X[:, 0].min(), X[:, 0].max() - X[:, 0]):
        near = s <= reach * length
        slope = (s[near] @ r[near]) / (s[near] @ s[near])
        angles.append(float(np.degrees(2 * np.arctan(slope))))
    return angles[0], angles[1]


def body_row(name: str, path: Path, work: Path, args) -> tuple:
    """``(name, tets, drag, tets remeshed, drag remeshed, scikit-fem remeshed)`` of the gmsh
    mesh in ``path``, printed."""
    m = tets(path)
    remeshed = remesh(m, work / f"{path.stem}_remeshed.msh", *args.remesh)
    r = tets(remeshed)
    (j, s), jr, jp = drag(m), drag(r)[0], peer(remeshed, args.peer)
    print(f"{name}: {m.n_tets} tets, drag {j:.5f} ({s:.1f} s), remeshed {jr:.5f}"
          f" (scikit-fem {jp:.5f})", flush=True)
    return name, m.n_tets, j, r.n_tets, jr, jp


def anchor_rows(work: Path, args) -> list[tuple]:
    """The anchor bodies of ``--anchors``: Pironneau's ends (``_bodies3d.py``), length over
    width and shoulder scanned over ``--anchor-aspects`` × ``--anchor-shoulders``."""
    rows = []
    if "pironneau" in args.anchors:
        for a in args.anchor_aspects:
            for m in args.anchor_shoulders:
                path = conical_body_in_box(work / f"conical_{a}_{m}.msh",
                                           conical_profile(a, m), args.size, args.body_size)
                rows.append(body_row(f"60° conical ends, length/width {a:g}"
                                     + (f", shoulder {m:g}" if m else ""), path, work, args))
    return rows


def table(rows: list[tuple], spheroids: list[tuple]) -> list[str]:
    """The rows as a markdown table, every drag also over the best spheroid's."""
    best, best_remeshed, best_peer = (min(r[k] for r in spheroids) for k in (2, 4, 5))
    lines = ["| body | tets | drag | / best spheroid | tets, remeshed | drag, remeshed | "
             "/ best spheroid, remeshed | scikit-fem, remeshed | / best spheroid |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    return lines + [f"| {name} | {n} | {j:.5f} | {j / best:.4f} | {nr} | {jr:.5f} | "
                    f"{jr / best_remeshed:.4f} | {jp:.5f} | {jp / best_peer:.4f} |"
                    for name, n, j, nr, jr, jp in rows]


def run(args) -> str:
    work = Path(tempfile.mkdtemp(prefix="bench_shape3d-"))
    spheroids = [body_row(f"prolate spheroid a/b = {a:g}",
                          body_in_box(work / f"spheroid_{a}.msh", args.size, args.body_size,
                                      aspect=a), work, args)
                 for a in args.aspects]
    anchors = anchor_rows(work, args)
    if not args.optimize:
        return "\n".join(table(spheroids + anchors, spheroids))
    sphere = tets(body_in_box(work / "sphere.msh", args.size, args.body_size))
    j0, solve = drag(sphere)
    print(f"sphere: {sphere.n_tets} tets, drag {j0:.5f}, one state solve {solve:.1f} s",
          flush=True)
    spec = spec_from_options(**SPEC, keep="volume,barycenter", scale="auto")
    clock = [time.perf_counter()] * 2

    def progress(r) -> None:
        now = time.perf_counter()
        print(f"  iteration {r.iteration}: objective {r.j:.7f} (scaled), worst mean ratio "
              f"{r.min_aspect_ratio:.3f}, {now - clock[1]:.1f} s = "
              f"{(now - clock[1]) / solve:.2f} state solves", flush=True)
        clock[1] = now

    result = optimize(sphere, problem=spec, max_iterations=args.max_iterations,
                      callback=progress)
    seconds = time.perf_counter() - clock[0]
    Q0, Q1 = sphere.points, result.x
    facets = spec.body_facets(sphere)
    dv = abs(enclosed_measure(Q1, facets) / enclosed_measure(Q0, facets) - 1)
    db = float(np.abs(barycenter(Q1, facets) - barycenter(Q0, facets)).max()) / 0.5
    q0, q1 = mean_ratios(Q0, sphere.tets).min(), mean_ratios(Q1, sphere.tets).min()
    stay = spec.fixed_mask(sphere)
    box_moved = float(np.abs(Q1[stay] - Q0[stay]).max())
    path = remesh(sphere.with_points(Q1), work / "optimized.msh", *args.remesh)
    fresh = tets(path)
    j_fresh, j_peer = drag(fresh)[0], peer(path, args.peer)
    length, width = body_extent(sphere, Q1)
    front, back = tip_angles(sphere, Q1)
    optimized = (f"optimized body (length/width {length / width:.2f}, ends {front:.0f}° / "
                 f"{back:.0f}°)", sphere.n_tets, result.j, fresh.n_tets, j_fresh, j_peer)
    lines = table(spheroids + anchors + [optimized], spheroids)
    per_iteration = seconds / max(result.nit, 1)
    lines += [
        "",
        f"Optimization of the sphere's mesh ({sphere.n_tets} tets, {sphere.n_vertices} "
        f"vertices; `--size {args.size:g} --body-size {args.body_size:g} --remesh "
        f"{args.remesh[0]:g},{args.remesh[1]:g}`): {result.status} "
        f"after {result.nit} iterations in {seconds:.0f} s; drag {j0:.5f} → {result.j:.5f} on "
        f"the optimizer's own mesh, {j_fresh:.5f} remeshed. Volume kept to {dv:.1e} "
        f"(relative), barycenter to {db:.1e} (of the radius); worst mean ratio "
        f"{q0:.3f} → {q1:.3f} ({q1 / q0:.2f}× its start), no inverted tet "
        f"({int((mean_ratios(Q1, sphere.tets) <= 0).sum())}); the box moved by "
        f"{box_moved:g}. One iteration: {per_iteration:.1f} s = "
        f"{per_iteration / solve:.2f} state solves ({solve:.1f} s each).",
    ]
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=float, default=1.0)
    p.add_argument("--body-size", type=float, default=0.15)
    p.add_argument("--remesh", type=lambda s: [float(x) for x in s.split(",")],
                   metavar="SIZE,BODY_SIZE", help="the element sizes of the remeshed bodies "
                   "(default: --size, --body-size)")
    p.add_argument("--max-iterations", type=int, default=40)
    p.add_argument("--aspects", type=lambda s: [float(x) for x in s.split(",")],
                   default=[1.0, 1.5, 1.75, 2.0, 2.25, 2.5])
    p.add_argument("--anchors", choices=["pironneau"], action="append", default=[],
                   help="anchor bodies besides the spheroids: Pironneau's 60° conical ends "
                   "(_bodies3d.py)")
    p.add_argument("--anchor-aspects", type=lambda s: [float(x) for x in s.split(",")],
                   default=[1.8, 2.0, 2.2], help="length over width of the anchor bodies")
    p.add_argument("--anchor-shoulders", type=lambda s: [float(x) for x in s.split(",")],
                   default=[0.0], help="their shoulder, c2 / (c0 + c1 + c2) (_bodies3d.py; "
                   "a list starting with a minus sign as --anchor-shoulders=-0.3,0)")
    p.add_argument("--no-optimize", dest="optimize", action="store_false",
                   help="the spheroids and anchors only (--write: their own block)")
    p.add_argument("--peer", action="store_true",
                   help="also the remeshed drags by scikit-fem's assembly (_peers3d.py)")
    p.add_argument("--large", action="store_true", help="the ~26,000-tet case in one "
                   "command: --size 0.6 --body-size 0.07 --aspects 2.1 --max-iterations 10 "
                   "unless given")
    p.add_argument("--write", action="store_true",
                   help="put the table into docs/shape-optimization.md's 3D section")
    args = p.parse_args()
    if args.large:
        given = set(sys.argv[1:])
        for flag, value in (("--size", 0.6), ("--body-size", 0.07), ("--aspects", [2.1]),
                            ("--max-iterations", 10)):
            if flag not in given:
                setattr(args, flag[2:].replace("-", "_"), value)
    args.remesh = args.remesh or [args.size, args.body_size]
    result = run(args)
    print(result)
    if args.write:
        text = DOC.read_text(encoding="utf-8")
        begin, end = (f"<!-- {BLOCKS[args.optimize]}: {m} -->" for m in ("begin", "end"))
        block = f"{begin}\n{result}\n{end}"
        if begin not in text:
            raise SystemExit(f"{DOC} has no {begin} block")
        text = re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda _: block, text,
                      flags=re.S)
        DOC.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
