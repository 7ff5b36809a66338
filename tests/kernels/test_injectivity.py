"""Global injectivity in admissibility: boundary loops nest as the boundary of an embedded
region; exact boundary tests on gmsh meshes; admissibility judged at any scale."""

from __future__ import annotations

import json
from fractions import Fraction as F

import numpy as np
import pytest
from cli_helpers import one_line

import meshopt_toolkit.motion.move as move_module
from meshopt_toolkit.cli import main
from meshopt_toolkit.io import load, save
from meshopt_toolkit.kernels.admissibility import loop_message, target_loop_problem
from meshopt_toolkit.kernels.boundary import boundary_loops, loop_nesting
from meshopt_toolkit.mesh import PlanarMesh, check_mesh
from meshopt_toolkit.motion.move import NoAdmissiblePathError, move

HOLE = "(x-3)**2+(y-1)**2<0.2"  # the hole at (3, 1) of the plate


def _gmsh_mesh(build, size: float) -> PlanarMesh:
    gmsh_session = pytest.importorskip("meshopt_toolkit.gmsh_session").gmsh_session
    pytest.importorskip("gmsh")
    with gmsh_session(deterministic=True) as gmsh:
        build(gmsh)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, _, nodes = gmsh.model.mesh.getElements(2)
    index = np.zeros(int(tags.max()) + 1, np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    tri = index[np.concatenate(nodes).astype(np.int64).reshape(-1, 3)]
    used = np.unique(tri)
    remap = np.full(len(tags), -1)
    remap[used] = np.arange(len(used))
    pts, tri = coords.reshape(-1, 3)[used, :2], remap[tri]
    e1, e2 = pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    tri[cw] = tri[cw][:, ::-1]
    return PlanarMesh(pts, tri)


def plate(size: float = 0.15) -> PlanarMesh:
    """The 6 × 2 plate with two holes of radius 0.35 at (1.5, 1) and (3, 1)."""
    def build(gmsh):
        occ = gmsh.model.occ
        r = occ.addRectangle(0, 0, 0, 6, 2)
        holes = [(2, occ.addDisk(x, 1, 0, 0.35, 0.35)) for x in (1.5, 3.0)]
        occ.cut([(2, r)], holes)
        occ.synchronize()
    return _gmsh_mesh(build, size)


def naca0012(n: int = 20) -> np.ndarray:
    beta = np.linspace(0, np.pi, n)
    x = 0.5 * (1 - np.cos(beta))
    y = 0.6 * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3
               - 0.1015 * x**4)
    return np.concatenate([np.stack([x, y], 1)[::-1], np.stack([x, -y], 1)[1:-1]])


def airfoil_in_box(degrees: float, box_size: float = 0.02) -> PlanarMesh:
    """A NACA 0012 in a box turned by ``degrees`` (angle of attack): the box's slanted
    sides are split into many nearly collinear edges, the airfoil's edges are longer."""
    a = np.radians(degrees)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    box = np.array([[-0.5, -0.5], [1.5, -0.5], [1.5, 0.5], [-0.5, 0.5]]) @ R.T

    def build(gmsh):
        geo = gmsh.model.geo

        def loop(P, lc):
            t = [geo.addPoint(x, y, 0, lc) for x, y in P]
            return geo.addCurveLoop([geo.addLine(t[i], t[(i + 1) % len(t)])
                                     for i in range(len(t))])
        geo.addPlaneSurface([loop(box, box_size), loop(naca0012(), 1.0)])
        geo.synchronize()
    return _gmsh_mesh(build, 1.0)


def rounded_touching_pairs(P, be) -> int:
    """Non-adjacent boundary edge pairs the rounded orientation test calls touching."""
    a, b = P[be[:, 0]], P[be[:, 1]]
    i, j = np.triu_indices(len(be), 1)
    share = (be[i][:, :, None] == be[j][:, None, :]).any((1, 2))
    i, j = i[~share], j[~share]

    def o(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    d1, d2 = o(a[i], b[i], a[j]), o(a[i], b[i], b[j])
    d3, d4 = o(a[j], b[j], a[i]), o(a[j], b[j], b[i])
    return int(((d1 * d2 <= 0) & (d3 * d4 <= 0) & ~((d1 == 0) & (d2 == 0))).sum())


def coverage(mesh: PlanarMesh, samples: np.ndarray) -> np.ndarray:
    """How many triangles contain each sample point (strictly inside)."""
    P = mesh.points[mesh.triangles]  # (T, 3, 2)
    count = np.zeros(len(samples), int)
    a, b, c = P[:, 0], P[:, 1], P[:, 2]
    for chunk in np.array_split(np.arange(len(samples)), max(1, len(samples) // 200)):
        s = samples[chunk][:, None, :]

        def side(p, q):
            return (q[..., 0] - p[..., 0]) * (s[..., 1] - p[..., 1]) \
                - (q[..., 1] - p[..., 1]) * (s[..., 0] - p[..., 0])
        inside = (side(a, b) > 0) & (side(b, c) > 0) & (side(c, a) > 0)
        count[chunk] = inside.sum(1)
    return count


def shoelace(P) -> F:
    x, y = [F(float(v)) for v in P[:, 0]], [F(float(v)) for v in P[:, 1]]
    n = len(x)
    return sum(x[k] * y[(k + 1) % n] - x[(k + 1) % n] * y[k] for k in range(n)) / 2


# -- the nesting rule on polygons -----------------------------------------------------

def _polygon_edges(polys):
    pts, edges, start = [], [], 0
    for P in polys:
        n = len(P)
        pts.append(P)
        edges.append(np.stack([np.arange(n), np.roll(np.arange(n), -1)], 1) + start)
        start += n
    return np.concatenate(pts), np.concatenate(edges)


def test_loop_nesting_of_concentric_polygons(rng):
    # two groups of concentric polygons, radii known: depth = larger radii of the group
    polys, depth_want, sign_want = [], [], []
    for centre, radii in (((0.0, 0.0), [4.0, 3.0, 2.0, 1.0]), ((20.0, 1.0), [2.0, 0.5])):
        for d, r in enumerate(radii):
            n = int(rng.integers(3, 9))
            t = np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(0, 1)
            P = np.stack([centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)], 1)
            s = int(rng.choice([-1, 1]))
            polys.append(P if s > 0 else P[::-1])
            depth_want.append(d)
            sign_want.append(s)
    order = rng.permutation(len(polys))
    polys = [polys[k] for k in order]
    pts, edges = _polygon_edges(polys)
    loops, sign, depth, vertex = loop_nesting(pts, edges)
    # loops are numbered by their smallest edge: here the order of the polygons
    assert depth.tolist() == [depth_want[k] for k in order]
    assert sign.tolist() == [sign_want[k] for k in order]
    ok = all(sign_want[k] == (-1) ** depth_want[k] for k in range(len(polys)))
    assert (loop_message(pts, edges) is None) == ok


def test_loop_rule_messages():
    outer = np.array([[0.0, 0], [6, 0], [6, 2], [0, 2]])
    hole = np.array([[2.0, 0.5], [2, 1.5], [4, 1.5], [4, 0.5]])  # clockwise
    island = np.array([[2.5, 0.75], [3.5, 0.75], [3.5, 1.25], [2.5, 1.25]])  # ccw
    pts, edges = _polygon_edges([outer, hole, island])
    assert loop_message(pts, edges) is None
    pts, edges = _polygon_edges([outer, hole[::-1], island])
    msg = loop_message(pts, edges)
    assert msg.startswith("boundary loop 1 (through vertex 7) is a hole (inside 1 other "
                          "loop) but runs counter-clockwise (it must run clockwise)")
    pts, edges = _polygon_edges([outer, hole, island[::-1]])
    assert "boundary loop 2 (through vertex 11) is an island (inside 2 other loops)" in \
        loop_message(pts, edges)
    # the enclosed area is Σ (−1)^depth |area|: 12 − 2 + 0.5
    loops, sign, depth, _ = loop_nesting(*_polygon_edges([outer, hole, island]))
    areas = [abs(shoelace(P)) for P in (outer, hole, island)]
    assert sum((-1) ** int(d) * a for d, a in zip(depth, areas)) == F(21, 2)


def test_boundary_loops_labels_cycles():
    pts, edges = _polygon_edges([np.zeros((3, 2)), np.zeros((5, 2)), np.zeros((4, 2))])
    perm = np.random.default_rng(1).permutation(len(edges))
    labels = boundary_loops(edges[perm])
    want = np.repeat([0, 1, 2], [3, 5, 4])[perm]
    # the same partition (numbered by smallest edge index)
    assert len(set(zip(labels.tolist(), want.tolist()))) == 3 and len(set(labels)) == 3


# -- meshes -----------------------------------------------------------------------------

def test_plate_with_two_holes_is_admissible():
    m = plate()
    r = check_mesh(m)
    assert r.admissible, r.problems
    loops, sign, depth, _ = loop_nesting(m.points, m.boundary_edges)
    assert sorted(zip(depth.tolist(), sign.tolist())) == [(0, 1), (1, -1), (1, -1)]


def test_mirrored_hole_is_refused_before_any_work(tmp_path, capsys):
    src = tmp_path / "plate.msh"
    save(plate(), src)
    out = tmp_path / "out.msh"
    assert main(["move", str(src), "-o", str(out), "--where", HOLE, "--map", "6-x; y"]) == 1
    assert "reverse boundary loop" in one_line(capsys)
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["plate.msh"]
    # a shift of the same hole moves
    assert main(["move", str(src), "-o", str(out), "--where", HOLE, "--map", "x+0.3; y"]) == 0
    assert check_mesh(load(out)).admissible


def double_cover(monkeypatch) -> tuple[PlanarMesh, PlanarMesh]:
    """The plate with its hole mirrored, computed by ``move`` with the up-front refusal and
    the final check switched off: positive triangles, a simple boundary, a double cover."""
    m = plate()
    h = np.unique(m.boundary_edges)
    P = m.points[h]
    hole = (P[:, 0] - 3) ** 2 + (P[:, 1] - 1) ** 2 < 0.2
    targets = P.copy()
    targets[hole, 0] = 6 - P[hole, 0]
    monkeypatch.setattr(move_module, "target_loop_problem", lambda *a: None)
    with pytest.raises(NoAdmissiblePathError, match="boundary loop"):
        move(m, h, targets)  # the final check catches it
    monkeypatch.setattr(move_module, "BoundaryCheck", _NoCheck)
    return m, move(m, h, targets).mesh


class _NoCheck:
    def __init__(self, *args):
        pass

    def test(self, Q):
        return None


def test_double_cover_is_not_admissible(monkeypatch, tmp_path, capsys):
    src, dc = double_cover(monkeypatch)
    monkeypatch.undo()
    assert (dc.signed_areas() > 0).all()
    # independently: some points are covered twice
    rng = np.random.default_rng(0)
    cover = coverage(dc, rng.uniform([0, 0], [6, 2], (4000, 2)))
    assert cover.max() == 2 and (cover == 2).sum() > 20
    # the triangles' area exceeds the enclosed area Σ (−1)^depth |loop area|
    loops, sign, depth, _ = loop_nesting(dc.points, dc.boundary_edges)
    be = dc.boundary_edges
    enclosed = 0.0
    for k in range(len(sign)):
        e = be[loops == k]
        x, y = dc.points[e[:, 0]].T, dc.points[e[:, 1]].T
        enclosed += (-1) ** int(depth[k]) * abs(0.5 * np.sum(x[0] * y[1] - x[1] * y[0]))
    assert dc.signed_areas().sum() > enclosed + 0.1
    r = check_mesh(dc)
    assert r.manifold and not r.admissible
    assert "is a hole (inside 1 other loop) but runs counter-clockwise" in r.problems[0]
    # the command line: info names the loop, morph refuses the target
    path = tmp_path / "dc.msh"
    save(dc, path)
    save(src, tmp_path / "src.msh")
    assert main(["info", "--json", str(path)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["admissible"] is False and "boundary loop" in info["problems"][0]
    assert main(["morph", str(tmp_path / "src.msh"), str(path), "-o",
                 str(tmp_path / "morph"), "--no-plots"]) == 1
    cap = capsys.readouterr()
    assert "all admissible" not in cap.out and "boundary loop" in cap.err


def test_target_loop_problem_names_the_loop():
    m = plate(0.3)
    be = m.boundary_edges
    h = np.unique(be)
    P = m.points.copy()
    assert target_loop_problem(m.points, P, be, h) is None
    hole = (P[:, 0] - 3) ** 2 + (P[:, 1] - 1) ** 2 < 0.2
    P[hole, 0] = 6 - P[hole, 0]
    msg = target_loop_problem(m.points, P, be, h)
    k = int(boundary_loops(be)[np.flatnonzero(hole[be[:, 0]])[0]])
    assert msg.startswith(f"reverse boundary loop {k} (through vertex ")
    # only some of the hole's vertices as handles: nothing fixed, nothing to say
    partial = h[~np.isin(h, np.flatnonzero(hole)[:3])]
    assert target_loop_problem(m.points, P, be, partial) is None
    # a loop crossing another
    Q = m.points.copy()
    Q[hole, 0] -= 1.5
    assert "cross" in target_loop_problem(m.points, Q, be, h)


def test_airfoil_in_turned_box_is_admissible(tmp_path):
    trapped = 0
    for degrees in (8, 14, 25):
        m = airfoil_in_box(degrees)
        trapped += rounded_touching_pairs(m.points, m.boundary_edges)
        r = check_mesh(m)
        assert r.admissible, (degrees, r.problems)
    assert trapped > 0  # rounding calls some of these boundaries self-touching


def test_airfoil_commands(tmp_path, capsys):
    # the rounded test refused this mesh for info, move and optimize
    m = airfoil_in_box(8)
    assert rounded_touching_pairs(m.points, m.boundary_edges) > 0
    path = tmp_path / "airfoil.msh"
    save(m, path)
    assert main(["info", "--json", str(path)]) == 0
    assert json.loads(capsys.readouterr().out)["admissible"] is True
    assert main(["optimize", str(path), "-o", str(tmp_path / "opt"), "--max-iter", "1",
                 "--no-plots"]) in (0, 1)
    assert "admissible" not in capsys.readouterr().err
    assert check_mesh(load(tmp_path / "opt" / "optimized.msh")).admissible
    out = tmp_path / "turned.msh"
    # turn the airfoil by 2 degrees about its quarter chord
    expr = ("0.25 + (x-0.25)*cos(pi/90) - y*sin(pi/90); "
            "(x-0.25)*sin(pi/90) + y*cos(pi/90)")
    assert main(["move", str(path), "-o", str(out), "--where",
                 "(x-0.5)**2 + 25*y**2 < 0.27", "--map", expr]) == 0
    assert check_mesh(load(out)).admissible


@pytest.mark.parametrize("factor", [1e300, 1e-300, 3.3e299, 2.0 ** -1000])
def test_scaled_meshes_are_admissible(tmp_path, capsys, factor):
    m = plate(0.3)
    scaled = PlanarMesh(m.points * factor, m.triangles)
    r = check_mesh(scaled)
    assert r.admissible, r.problems
    path = tmp_path / "scaled.msh"
    save(scaled, path)
    capsys.readouterr()
    assert main(["info", "--json", str(path)]) == 0
    cap = capsys.readouterr()
    info = json.loads(cap.out)
    assert info["admissible"] is True and info["n_inverted"] == 0 and cap.err == ""
    assert info["min_aspect_ratio"] == pytest.approx(m.quality().min_aspect_ratio)


@pytest.mark.parametrize("batch", [1 << 21, 64])
def test_loop_nesting_of_many_holes_with_islands(monkeypatch, batch):
    import meshopt_toolkit.kernels.boundary as boundary_module

    monkeypatch.setattr(boundary_module, "_BATCH", batch)
    polys, depth_want = [np.array([[0.0, 0], [40, 0], [40, 40], [0, 40]])], [0]
    for i in range(12):
        for j in range(12):
            c = np.array([i * 3 + 2, j * 3 + 2.0])
            polys.append(c + np.array([[-1.0, -1], [-1, 1], [1, 1], [1, -1]]))  # cw hole
            polys.append(c + 0.5 * np.array([[-1.0, -1], [1, -1], [1, 1], [-1, 1]]))  # island
            depth_want += [1, 2]
    pts, edges = _polygon_edges(polys)
    loops, sign, depth, _ = loop_nesting(pts, edges)
    assert depth.tolist() == depth_want
    assert (sign == np.where(np.array(depth_want) % 2, -1, 1)).all()
    assert loop_message(pts, edges) is None
    polys[77] = polys[77][::-1]  # one island reversed
    assert loop_message(*_polygon_edges(polys)).startswith("boundary loop 77 ")


def test_a_refused_motion_into_frames_leaves_no_directory(tmp_path, capsys):
    src = tmp_path / "plate.msh"
    save(plate(), src)
    out = tmp_path / "frames"
    assert main(["move", str(src), "-o", str(out), "--frames", "3", "--where", HOLE,
                 "--map", "6-x; y"]) == 1
    assert "reverse boundary loop" in capsys.readouterr().err
    assert not out.exists()
