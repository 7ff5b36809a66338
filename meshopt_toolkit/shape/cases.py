"""gmsh meshes of the domains users optimize, with named boundary groups.

Each function writes a Gmsh 4.1 ``.msh`` file whose boundary curves carry named
physical groups (and the surface the group ``"domain"``), as a user's gmsh script would,
and returns its path: the tests and ``benchmarks/bench_optimize.py --users`` read them
back through :func:`meshopt_toolkit.io.load` like any user file.

==================  ===================================================  =================
case                domain                                               boundary groups
==================  ===================================================  =================
``plate``           6 × 2 plate with two circular holes                  outer, hole1, hole2
``lshape``          L-shape ``[0, 2]² \\ [1, 2]²``                          outer, reentrant
``airfoil``         NACA 0012 in a 4 × 2 box                             box, airfoil
``channel``         3 × 1 channel with a disc and a square obstacle      inlet, outlet,
                                                                         walls, disc, square
``rectangle``       ``[0, 2] × [0, 1]``                                    left, right, bottom,
                                                                         top
``holed_square``    ``[−1.5, 1.5]²`` with a centred disc hole of         outer, hole
                    radius ½ (area π/4): elasticity
``disc_in_box``     ``[−2, 2] × [−1.5, 1.5]`` around a disc of radius    box, body
                    ½ at the origin: Stokes
==================  ===================================================  =================

:func:`ellipse_in_box` meshes an elliptic hole or body centred in a box (the 2D
benchmarks' discs and the ellipses they are compared with).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..gmsh_session import gmsh_session

CASES = ("plate", "lshape", "airfoil", "channel", "rectangle", "holed_square", "disc_in_box")


def _naca0012(n: int = 40) -> np.ndarray:
    """Points of the closed NACA 0012 contour (chord 1), trailing edge first, ccw."""
    x = 0.5 * (1 - np.cos(np.linspace(0, np.pi, n)))
    t = 0.6 * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4)
    upper = np.column_stack([x[::-1], t[::-1]])[:-1]  # trailing edge -> leading edge
    lower = np.column_stack([x, -t])[:-1]  # leading edge -> trailing edge (excluded)
    return np.vstack([upper, lower])


def _group_curves(gmsh, tag_of) -> dict[str, list[int]]:
    """Boundary curves grouped by ``tag_of(center of mass) -> name``."""
    groups: dict[str, list[int]] = {}
    for dim, c in gmsh.model.getEntities(1):
        x, y, _ = gmsh.model.occ.getCenterOfMass(dim, c)
        groups.setdefault(tag_of(x, y), []).append(c)
    return groups


def _cut_and_group(gmsh, body: int, tools: list[int], tag_of) -> dict[str, list[int]]:
    """Cut the surfaces ``tools`` out of the surface ``body``, synchronize the model and
    group the boundary curves by ``tag_of`` (:func:`_group_curves`)."""
    gmsh.model.occ.cut([(2, body)], [(2, t) for t in tools])
    gmsh.model.occ.synchronize()
    return _group_curves(gmsh, tag_of)


def _build(gmsh, case: str, size: float) -> dict[str, list[int]]:
    occ = gmsh.model.occ
    if case == "plate":
        r = occ.addRectangle(0, 0, 0, 6, 2)
        h1 = occ.addDisk(1.8, 1.0, 0, 0.45, 0.45)
        h2 = occ.addDisk(4.2, 1.0, 0, 0.45, 0.45)
        return _cut_and_group(gmsh, r, [h1, h2], lambda x, y: "hole1" if abs(x - 1.8) < 0.5
                              and abs(y - 1) < 0.5 else "hole2" if abs(x - 4.2) < 0.5
                              and abs(y - 1) < 0.5 else "outer")
    if case == "lshape":
        a = occ.addRectangle(0, 0, 0, 2, 2)
        b = occ.addRectangle(1, 1, 0, 1, 1)
        return _cut_and_group(gmsh, a, [b], lambda x, y: "reentrant"
                              if x >= 1 - 1e-9 and y >= 1 - 1e-9 else "outer")
    if case == "airfoil":
        box = occ.addRectangle(-1.5, -1.0, 0, 4.0, 2.0)
        pts = [occ.addPoint(px + 0.0, py, 0, size / 4) for px, py in _naca0012()]
        spline = occ.addBSpline(pts + [pts[0]])
        loop = occ.addCurveLoop([spline])
        foil = occ.addPlaneSurface([loop])
        occ.rotate([(2, foil)], 0.25, 0, 0, 0, 0, 1, -np.radians(4.0))
        return _cut_and_group(gmsh, box, [foil], lambda x, y: "airfoil"
                              if -0.2 < x < 1.2 and abs(y) < 0.3 else "box")
    if case == "channel":
        ch = occ.addRectangle(0, 0, 0, 3, 1)
        d = occ.addDisk(0.8, 0.5, 0, 0.15, 0.15)
        s = occ.addRectangle(1.8, 0.35, 0, 0.3, 0.3)
        occ.rotate([(2, s)], 1.95, 0.5, 0, 0, 0, 1, np.radians(30))

        def name(x, y):
            if abs(x) < 1e-9:
                return "inlet"
            if abs(x - 3) < 1e-9:
                return "outlet"
            if abs(y) < 1e-9 or abs(y - 1) < 1e-9:
                return "walls"
            return "disc" if x < 1.3 else "square"

        return _cut_and_group(gmsh, ch, [d, s], name)
    if case == "rectangle":
        occ.addRectangle(0, 0, 0, 2, 1)
        occ.synchronize()
        return _group_curves(gmsh, lambda x, y: "left" if x < 0.5 else "right" if x > 1.5
                             else "bottom" if y < 0.5 else "top")
    if case in ("holed_square", "disc_in_box"):
        a, b = (1.5, 1.5) if case == "holed_square" else (2.0, 1.5)
        box = occ.addRectangle(-a, -b, 0, 2 * a, 2 * b)
        inner = "hole" if case == "holed_square" else "body"
        return _cut_and_group(gmsh, box, [occ.addDisk(0, 0, 0, 0.5, 0.5)],
                              lambda x, y: inner if abs(x) < 1 and abs(y) < 1
                              else ("outer" if case == "holed_square" else "box"))
    raise ValueError(f"unknown case {case!r}; choose one of {', '.join(CASES)}")


def ellipse_in_box(path: str | os.PathLike, half_axes: tuple[float, float],
                   box: tuple[float, float], size: float = 0.5, *, refine_near: float = 0.1,
                   inner: str = "hole", outer: str = "outer") -> Path:
    """Mesh the box ``[−box/2, box/2]`` minus the ellipse of ``half_axes`` ``(a, b)`` (along
    x, y) centred at the origin into ``path``: element size ``refine_near`` on the ellipse,
    graded to ``size`` within ``10 · size``; groups ``inner`` (the ellipse) and ``outer``.

    Returns
    -------
    Path
    """
    a, b = (float(v) for v in half_axes)
    w, h = (float(v) for v in box)

    def build(gmsh):
        occ = gmsh.model.occ
        r = occ.addRectangle(-w / 2, -h / 2, 0, w, h)
        e = occ.addDisk(0, 0, 0, max(a, b), min(a, b))
        if b > a:  # gmsh wants the x radius the larger one
            occ.rotate([(2, e)], 0, 0, 0, 0, 0, 1, np.pi / 2)
        return _cut_and_group(gmsh, r, [e], lambda x, y: inner if abs(x) < w / 2 - 1e-6
                              and abs(y) < h / 2 - 1e-6 else outer)

    return _mesh(path, "ellipse_in_box", build, size, refine_near, (inner,))


def user_mesh(case: str, path: str | os.PathLike, size: float = 0.1, *,
              refine_near: float | None = None) -> Path:
    """Mesh ``case`` (one of :data:`CASES`) with element size ``size`` into ``path``.

    Parameters
    ----------
    case : str
    path : where the ``.msh`` (format 4.1) goes
    size : target element size (the meshes span 2 to 6 units)
    refine_near : element size on the holes / obstacles / airfoil / re-entrant corner
        (default ``size``), graded to ``size`` within ``10 · size``

    Returns
    -------
    Path
    """
    return _mesh(path, case, lambda gmsh: _build(gmsh, case, size), size, refine_near,
                 ("hole1", "hole2", "hole", "body", "reentrant", "airfoil", "disc", "square"))


def _mesh(path, name: str, build, size: float, refine_near: float | None,
          refined: tuple) -> Path:
    """Build the model ``name`` (``build(gmsh) -> {group: curves}``), mesh it (size
    ``refine_near`` on the ``refined`` groups' curves) and write it to ``path``."""
    path = Path(path)
    with gmsh_session(deterministic=True) as gmsh:
        gmsh.model.add(name)
        groups = build(gmsh)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        if refine_near is not None:
            inner = [c for n, cs in groups.items() if n in refined for c in cs]
            graded_sizes(gmsh, 1, inner, refine_near, size, 10 * size, sampling=100)
        for name, curves in sorted(groups.items()):
            gmsh.model.addPhysicalGroup(1, curves, name=name)
        surfaces = [s for _, s in gmsh.model.getEntities(2)]
        gmsh.model.addPhysicalGroup(2, surfaces, name="domain")
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        path.parent.mkdir(parents=True, exist_ok=True)
        gmsh.write(str(path))
    return path


#: the 3D Stokes case: an 8 × 6 × 6 box around a body at the origin, its elements graded
#: from the body's size to the box's within this distance of the body
BOX_3D = (8.0, 6.0, 6.0)
BODY_REACH = 2.5


def graded_sizes(gmsh, dim: int, tags, fine: float, coarse: float, reach: float, *,
                 sampling: int = 100) -> None:
    """Element sizes ``fine`` on the entities ``tags`` of dimension ``dim`` (curves 1,
    surfaces 2), graded to ``coarse`` at distance ``reach``: gmsh's background mesh, not
    extended from the boundary."""
    f = gmsh.model.mesh.field
    dist = f.add("Distance")
    f.setNumbers(dist, "CurvesList" if dim == 1 else "SurfacesList", list(tags))
    f.setNumber(dist, "Sampling", sampling)
    thr = f.add("Threshold")
    for key, value in (("InField", dist), ("SizeMin", fine), ("SizeMax", coarse),
                       ("DistMin", 0.0), ("DistMax", reach)):
        f.setNumber(thr, key, value)
    f.setAsBackgroundMesh(thr)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)


def body_in_box(path: str | os.PathLike, size: float = 1.0, body_size: float = 0.15, *,
                aspect: float = 1.0, radius: float = 0.5) -> Path:
    """Tetrahedra of the ``8 × 6 × 6`` box centred at the origin around a prolate spheroid
    with the volume of the sphere of ``radius`` (``aspect`` = its axis along ``x`` over
    the other two; 1: the sphere), surface groups ``"body"`` and ``"outer"``, the volume
    ``"domain"``: the 3D Stokes case (drag of the body moving along ``x``).

    Parameters
    ----------
    path : where the ``.msh`` (format 4.1) goes
    size : element size at the box
    body_size : element size on the body, graded to ``size`` away from it
    aspect : the spheroid's axis ratio
    radius : the radius of the sphere of equal volume

    Returns
    -------
    Path
    """
    b = radius * aspect ** (-1.0 / 3.0)  # a b² = r³ with a = aspect · b

    def spheroid(occ) -> list[tuple[int, int]]:
        ball = occ.addSphere(0, 0, 0, b)
        if aspect != 1.0:
            occ.dilate([(3, ball)], 0, 0, 0, aspect, 1.0, 1.0)
        return [(3, ball)]

    return solid_in_box(path, spheroid, size, body_size)


def solid_in_box(path: str | os.PathLike, add_body, size: float = 1.0,
                 body_size: float = 0.15) -> Path:
    """Tetrahedra of the ``8 × 6 × 6`` box centred at the origin around the solid that
    ``add_body(occ)`` adds to gmsh's OpenCASCADE model, meshed by
    :func:`mesh_body_in_box`.

    Parameters
    ----------
    path : where the ``.msh`` (format 4.1) goes
    add_body : callable
        ``add_body(gmsh.model.occ)`` adds the body inside the box and returns its
        ``(3, tag)`` pairs
    size : element size at the box
    body_size : element size on the body, graded to ``size`` away from it

    Returns
    -------
    Path
    """
    path = Path(path)
    with gmsh_session(deterministic=True) as gmsh:
        gmsh.model.add("body_in_box")
        occ = gmsh.model.occ
        lx, ly, lz = BOX_3D
        box = occ.addBox(-lx / 2, -ly / 2, -lz / 2, lx, ly, lz)
        occ.cut([(3, box)], add_body(occ))
        occ.synchronize()
        body, outer = [], []
        for _, s in gmsh.model.getEntities(2):
            on_box = np.isclose(np.abs(occ.getCenterOfMass(2, s)), np.divide(BOX_3D, 2))
            (outer if on_box.any() else body).append(s)
        mesh_body_in_box(gmsh, body, outer, path, size, body_size)
    return path


def mesh_body_in_box(gmsh, body, outer, path: Path, size: float, body_size: float) -> None:
    """Mesh the current gmsh model, a volume between the surfaces ``outer`` and ``body``,
    with :func:`body_in_box`'s sizes and groups and write it to ``path`` (format 4.1)."""
    graded_sizes(gmsh, 2, body, body_size, size, BODY_REACH, sampling=60)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.model.addPhysicalGroup(2, list(body), name="body")
    gmsh.model.addPhysicalGroup(2, list(outer), name="outer")
    gmsh.model.addPhysicalGroup(3, [v for _, v in gmsh.model.getEntities(3)], name="domain")
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    gmsh.write(str(path))
