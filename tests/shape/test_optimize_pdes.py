"""Shape optimization of elasticity compliance and Stokes dissipation on planar meshes,
end to end: ``meshopt optimize`` and :func:`meshopt_toolkit.optimize.optimize`, checked
against an independent scikit-fem assembly on the written mesh."""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest
import scipy.sparse as sp

from meshopt_toolkit.cli import main
from meshopt_toolkit.kernels.triangles import aspect_ratios, signed_areas
from meshopt_toolkit.shape.cases import user_mesh

skfem = pytest.importorskip("skfem")

STRESS = np.array([[2.0, 0.0], [0.0, 1.0]])


def _read(path):
    m = meshio.read(path)
    return m, m.points[:, :2].astype(float), m.cells_dict["triangle"].astype(np.int64)


def _skfem_mesh(P, T):
    return skfem.MeshTri(P.T.copy(), T.T.copy())


def _facets_where(mesh, inside):
    mid = mesh.p[:, mesh.facets].mean(axis=1)
    return mesh.boundary_facets()[inside(*mid[:, mesh.boundary_facets()])]


def reference_compliance(P, T, E=1.0, nu=0.3):
    """∫_Γ (σ n)·u on the plate's outer square, plane stress P1, rigid motions pinned
    at three dofs (the compliance does not depend on which: the load balances)."""
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    m = _skfem_mesh(P, T)
    e = skfem.ElementVector(skfem.ElementTriP1())
    basis = skfem.Basis(m, e)
    lam, mu = E * nu / (1 - nu ** 2), E / (2 * (1 + nu))
    K = linear_elasticity(lam, mu).assemble(basis)
    outer = _facets_where(m, lambda x, y: np.maximum(abs(x), abs(y)) > 1.4)
    fb = skfem.FacetBasis(m, e, facets=outer)

    @skfem.LinearForm
    def traction(v, w):
        return dot(np.einsum("ij,j...->i...", STRESS, w.n), v)

    f = traction.assemble(fb)
    a = int(np.argmin(np.linalg.norm(P - P.mean(axis=0), axis=1)))
    b = int(np.argmax(np.abs(P[:, 0] - P[a, 0])))
    nodal = basis.nodal_dofs  # (2, N)
    pins = np.array([nodal[0, a], nodal[1, a], nodal[1, b]])
    u = skfem.solve(*skfem.condense(K, f, D=pins))
    return float(f @ u)


def reference_dissipation(P, T, body_speed=(1.0, 0.0)):
    """∫ 2|ε(u)|² of Taylor–Hood P2–P1 Stokes flow, u = body_speed on the disc, 0 on the
    box, one pressure dof pinned."""
    from skfem.helpers import ddot, div, sym_grad

    m = _skfem_mesh(P, T)
    eu = skfem.ElementVector(skfem.ElementTriP2())
    ub, pb = skfem.Basis(m, eu, intorder=4), skfem.Basis(m, skfem.ElementTriP1(), intorder=4)

    @skfem.BilinearForm
    def visc(u, v, w):
        return 2.0 * ddot(sym_grad(u), sym_grad(v))

    @skfem.BilinearForm
    def bdiv(u, q, w):
        return -div(u) * q

    A = visc.assemble(ub)
    B = bdiv.assemble(ub, pb)
    K = sp.bmat([[A, B.T], [B, None]], format="csr")
    n_u = A.shape[0]
    x = np.zeros(K.shape[0])
    body = ub.get_dofs(_facets_where(m, lambda X, Y: np.maximum(abs(X), abs(Y)) < 1.0))
    box = ub.get_dofs(_facets_where(m, lambda X, Y: np.maximum(abs(X), abs(Y)) >= 1.0))
    x[body.nodal["u^1"]], x[body.facet["u^1"]] = body_speed[0], body_speed[0]
    x[body.nodal["u^2"]], x[body.facet["u^2"]] = body_speed[1], body_speed[1]
    D = np.concatenate([body.all(), box.all(), [n_u]])
    x = skfem.solve(*skfem.condense(K, np.zeros(K.shape[0]), x=x, D=D))
    u = x[:n_u]
    return float(u @ A @ u)


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    return user_mesh("holed_square", tmp_path_factory.mktemp("plate") / "plate.msh",
                     size=0.5, refine_near=0.15)


@pytest.fixture(scope="module")
def body(tmp_path_factory):
    return user_mesh("disc_in_box", tmp_path_factory.mktemp("body") / "body.msh",
                     size=0.6, refine_near=0.2)


def _shoelace(P, T):
    return float(signed_areas(P, T).sum())


def test_elasticity_hole_becomes_an_ellipse_along_the_larger_stress(plate, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["optimize", str(plate), "--pde", "elasticity", "--stress", "outer=2,1,0",
                 "--objective", "compliance", "--move", "hole", "--keep-area", "--no-plots",
                 "-o", str(out), "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0, summary["message"]
    m0, P0, T0 = _read(plate)
    m1, P1, T1 = _read(out / "optimized.msh")
    assert np.array_equal(T0, T1)
    # groups and their elements kept
    assert m1.field_data.keys() == m0.field_data.keys()
    assert [c.type for c in m1.cells] == [c.type for c in m0.cells]
    j0, j1 = reference_compliance(P0, T0), reference_compliance(P1, T1)
    assert j1 < j0 - 0.02 * abs(j0)
    assert summary["j"] == pytest.approx(j1, rel=1e-8)  # our compliance is scikit-fem's
    assert _shoelace(P1, T1) == pytest.approx(_shoelace(P0, T0), rel=1e-9)
    assert signed_areas(P1, T1).min() > 0
    assert aspect_ratios(P1, T1).min() >= 0.3 * aspect_ratios(P0, T0).min()
    hole = np.linalg.norm(P0, axis=1) < 0.51
    extent = np.ptp(P1[hole], axis=0)
    assert extent[0] > 1.2 * extent[1]  # elongated along x, the larger stress
    outer = ~hole & (np.maximum(abs(P0[:, 0]), abs(P0[:, 1])) > 1.5 - 1e-9)
    assert np.array_equal(P1[outer], P0[outer])


def test_stokes_body_drag_decreases_with_area_and_barycenter_kept(body):
    from meshopt_toolkit.cli._common import load_workpiece
    from meshopt_toolkit.optimize import optimize
    from meshopt_toolkit.shape.constraints import barycenter, enclosed_measure
    from meshopt_toolkit.shape.spec import spec_from_options

    mesh = load_workpiece(body, "optimize").mesh
    spec = spec_from_options(pde="stokes", dirichlet=["body=1,0", "box=0,0"],
                             objective="dissipation", move="body", keep="area,barycenter")
    result = optimize(mesh, problem=spec, max_iterations=12)
    P0, P1, T = mesh.points, result.x, mesh.triangles
    d0, d1 = reference_dissipation(P0, T), reference_dissipation(P1, T)
    assert d1 < 0.9 * d0
    assert result.j == pytest.approx(d1, rel=1e-8)
    facets = spec.body_facets(mesh)
    assert enclosed_measure(P1, facets) == pytest.approx(enclosed_measure(P0, facets), rel=1e-9)
    assert np.allclose(barycenter(P1, facets), barycenter(P0, facets), rtol=0, atol=1e-9)
    assert _shoelace(P1, T) == pytest.approx(_shoelace(P0, T), rel=1e-9)
    box = np.maximum(abs(P0[:, 0]) / 2.0, abs(P0[:, 1]) / 1.5) > 1 - 1e-9
    assert box.any() and np.array_equal(P1[box], P0[box])
    assert signed_areas(P1, T).min() > 0


@pytest.mark.parametrize("case, args, words", [
    ("body", ["--pde", "stokes", "--move", "body"], "--dirichlet"),
    ("body", ["--pde", "stokes", "--dirichlet", "nobody=1,0"], "nobody"),
    ("body", ["--pde", "stokes", "--dirichlet", "body=1,0,0"], "2 components"),
    ("plate", ["--pde", "elasticity", "--stress", "outer=2,1"], "3 components"),
    ("plate", ["--pde", "elasticity", "--stress", "outer=2,1,0", "--move", "nohole"], "nohole"),
    ("plate", ["--pde", "elasticity", "--stress", "outer=2,1,0", "--fixed", "outer,hole",
               "--keep-volume"], "cannot hold"),
    ("plate", ["--pde", "elasticity", "--stress", "outer=2,1,0", "--keep-barycenter"],
     "--move"),
    ("plate", ["--pde", "elasticity", "--stress", "outer=2,1,0", "--move", "hole",
               "--keep-area", "--method", "steepest"], "--method"),
    ("plate", ["--pde", "stokes", "--stress", "hole=2,1,0"], "--stress"),
    ("plate", ["--objective", "dissipation", "--pde", "elasticity"], "--objective"),
])
def test_bad_input_is_one_line_before_any_output(case, args, words, plate, body, tmp_path,
                                                 capsys):
    path = {"plate": plate, "body": body}[case]
    out = tmp_path / "out"
    assert main(["optimize", str(path), *args, "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and path.name in err, err
    assert "Traceback" not in err and not out.exists()


def test_unbalanced_load_on_a_floating_body_is_refused_in_2d_and_3d(tmp_path, capsys):
    from meshopt_toolkit.gmsh_session import gmsh_session

    rect = user_mesh("rectangle", tmp_path / "rect.msh", size=0.5)
    out = tmp_path / "out"
    assert main(["optimize", str(rect), "--pde", "elasticity", "--stress", "left=2,1,0",
                 "--move", "top", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "equilibrium" in err and not out.exists()
    with gmsh_session() as gmsh:
        gmsh.model.add("cube")
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [1], name="left")
        gmsh.model.addPhysicalGroup(3, [1], name="v")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(tmp_path / "cube.msh"))
    assert main(["optimize", str(tmp_path / "cube.msh"), "--pde", "elasticity", "--stress",
                 "left=1,0,0,0,0,0", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "equilibrium" in err and not out.exists()


def test_filter_runs_the_same_problem_as_the_library(plate):
    from meshopt_toolkit.io import load
    from meshopt_toolkit.optimize import optimize
    from meshopt_toolkit.pipeline import Document, registry
    from meshopt_toolkit.shape.spec import spec_from_options

    mesh = load(plate).as_planar()
    doc = Document([mesh])
    registry.get("apply_coord_shape_optimization")()(
        doc, pde="elasticity", stress="outer=2,1,0", move="hole", keep_area=True,
        poisson_ratio=0.25, max_iterations=3, tolerance=0)
    spec = spec_from_options(pde="elasticity", stress="outer=2,1,0", move="hole",
                             keep="area", material={"poisson_ratio": 0.25})
    expected = optimize(mesh, problem=spec, max_iterations=3, options=dict(tolerance=None))
    moved = doc.current_entry.workpiece("test").mesh.points
    assert np.allclose(moved, expected.x, rtol=0, atol=1e-12)
    assert not np.allclose(moved, mesh.points)
