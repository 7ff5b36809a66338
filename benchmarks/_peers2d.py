"""scikit-fem's independent assembly of the 2D shape benchmarks' state problems, on a
mesh file as written (gmsh ``.msh`` with named line groups), and measures of a body's
shape that use nothing of the package: the second moments of the region a group
encloses (the axes of an ellipse) and the angles at its front and back tips.

``compliance_skfem``: plane-stress P1 elasticity, traction ``σ n`` of a constant stress on
one group, the rest free, the rigid motions pinned at three dofs (the load balances, so
the compliance does not depend on which). ``dissipation_skfem``: Taylor–Hood P2–P1 Stokes
flow, ``u = velocity`` on one group and 0 on the rest of the boundary, one pressure dof
pinned; the dissipation ``∫ 2μ|ε(u)|²`` (the drag of a body moved at unit speed).
"""

from __future__ import annotations

import contextlib
import io

import meshio
import numpy as np
import scipy.sparse as sp


def read_groups(path, cell: str = "triangle", facet: str = "line"):
    """``(points (N, d), cells, {group name: facets})`` of a gmsh file: triangles with
    their line groups in the plane (``d = 2``), or ``cell="tetra", facet="triangle"`` in
    space (``d = 3``)."""
    d = 2 if cell == "triangle" else 3
    with contextlib.redirect_stdout(io.StringIO()):  # meshio's empty line on gmsh files
        m = meshio.read(path)
    P = np.asarray(m.points[:, :d], dtype=float)
    T = np.asarray(m.cells_dict[cell], dtype=np.int64)
    facets = np.concatenate([c.data for c in m.cells if c.type == facet])
    tags = np.concatenate([t for c, t in zip(m.cells, m.cell_data["gmsh:physical"])
                           if c.type == facet])
    groups = {name: facets[tags == tag].astype(np.int64)
              for name, (tag, dim) in m.field_data.items() if dim == d - 1}
    return P, T, groups


def _facets_of(mesh, lines):
    """skfem facet indices of the line elements ``(E, 2)``."""
    index = {tuple(f): i for i, f in enumerate(np.sort(mesh.facets.T, axis=1).tolist())}
    return np.array([index[tuple(e)] for e in np.sort(lines, axis=1).tolist()])


def compliance_skfem(path, group: str, stress, E: float = 1.0, nu: float = 0.3) -> float:
    """``∫_Γ (σ n)·u`` of the plate in ``path`` loaded by ``stress`` ``(SXX, SYY, SXY)``
    on ``group``."""
    import skfem
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    P, T, groups = read_groups(path)
    s = np.array([[stress[0], stress[2]], [stress[2], stress[1]]], dtype=float)
    m = skfem.MeshTri(P.T.copy(), T.T.copy())
    e = skfem.ElementVector(skfem.ElementTriP1())
    basis = skfem.Basis(m, e)
    K = linear_elasticity(E * nu / (1 - nu ** 2), E / (2 * (1 + nu))).assemble(basis)
    fb = skfem.FacetBasis(m, e, facets=_facets_of(m, groups[group]))

    @skfem.LinearForm
    def traction(v, w):
        return dot(np.einsum("ij,j...->i...", s, w.n), v)

    f = traction.assemble(fb)
    a = int(np.argmin(np.linalg.norm(P - P.mean(axis=0), axis=1)))
    b = int(np.argmax(np.abs(P[:, 0] - P[a, 0])))
    nodal = basis.nodal_dofs
    u = skfem.solve(*skfem.condense(K, f, D=np.array([nodal[0, a], nodal[1, a], nodal[1, b]])))
    return float(f @ u)


def taylor_hood_forms(mu: float):
    """scikit-fem's forms of Stokes flow: the viscous ``2μ ε(u):ε(v)`` and the
    divergence ``−div(u) q``."""
    import skfem
    from skfem.helpers import ddot, div, sym_grad

    @skfem.BilinearForm
    def visc(u, v, w):
        return 2.0 * mu * ddot(sym_grad(u), sym_grad(v))

    @skfem.BilinearForm
    def bdiv(u, q, w):
        return -div(u) * q

    return visc, bdiv


def dissipation_skfem(path, group: str, velocity=(1.0, 0.0), mu: float = 1.0) -> float:
    """``∫ 2μ|ε(u)|²`` of the Stokes flow in ``path``, ``u = velocity`` on ``group``, 0 on
    the rest of the boundary."""
    import skfem
    P, T, groups = read_groups(path)
    m = skfem.MeshTri(P.T.copy(), T.T.copy())
    ub = skfem.Basis(m, skfem.ElementVector(skfem.ElementTriP2()), intorder=4)
    pb = skfem.Basis(m, skfem.ElementTriP1(), intorder=4)

    visc, bdiv = taylor_hood_forms(mu)

    A, B = visc.assemble(ub), bdiv.assemble(ub, pb)
    K = sp.bmat([[A, B.T], [B, None]], format="csr")
    n_u = A.shape[0]
    x = np.zeros(K.shape[0])
    body = ub.get_dofs(_facets_of(m, groups[group]))
    for c, v in enumerate(velocity, start=1):
        x[body.nodal[f"u^{c}"]] = x[body.facet[f"u^{c}"]] = v
    walls = ub.get_dofs(m.boundary_facets())
    x = skfem.solve(*skfem.condense(K, np.zeros(K.shape[0]), x=x,
                                    D=np.concatenate([walls.all(), [n_u]])))
    u = x[:n_u]
    return float(u @ A @ u)


def loop_of(lines):
    """The vertices of a closed loop of line elements ``(E, 2)`` in order."""
    nxt = {}
    for a, b in lines.tolist():
        nxt.setdefault(a, []).append(b)
        nxt.setdefault(b, []).append(a)
    order, prev = [int(lines[0, 0])], None
    while len(order) < len(lines):
        here = order[-1]
        step = [v for v in nxt[here] if v != prev][0]
        prev = here
        order.append(step)
    return np.array(order)


def moment_axes(P, loop) -> tuple[float, float, float]:
    """``(a, b, angle)`` of the ellipse with the area and second moments of the polygon
    ``P[loop]``: half axes ``a ≥ b`` and the direction of ``a`` (degrees from x)."""
    x, y = P[loop, 0], P[loop, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    c = x * y1 - x1 * y
    A = c.sum() / 2
    cx, cy = ((x + x1) * c).sum() / (6 * A), ((y + y1) * c).sum() / (6 * A)
    ixx = (c * (y * y + y * y1 + y1 * y1)).sum() / 12 - A * cy * cy
    iyy = (c * (x * x + x * x1 + x1 * x1)).sum() / 12 - A * cx * cx
    ixy = (c * (x * y1 + 2 * x * y + 2 * x1 * y1 + x1 * y)).sum() / 24 - A * cx * cy
    lam, vec = np.linalg.eigh(np.array([[iyy, ixy], [ixy, ixx]]))  # ∫x², ∫xy, ∫y²
    # an ellipse: ∫x² = A a²/4 along its axis
    b, a = 2 * np.sqrt(lam / abs(A))
    return float(a), float(b), float(np.degrees(np.arctan2(vec[1, 1], vec[0, 1])) % 180)


def tip_angles(P, loop, reach: float) -> tuple[float, float]:
    """Interior angles (degrees) of the body at its front (largest x) and back (smallest
    x) vertices between the chords to the boundary points ``reach`` away along the loop."""
    Q = P[loop]
    arc = np.r_[0, np.cumsum(np.linalg.norm(np.diff(np.vstack([Q, Q[:1]]), axis=0), axis=1))]
    total = arc[-1]

    def angle(i):
        s = arc[i]
        ahead = np.interp((s + reach) % total, arc, np.vstack([Q, Q[:1]])[:, 0]), \
            np.interp((s + reach) % total, arc, np.vstack([Q, Q[:1]])[:, 1])
        behind = np.interp((s - reach) % total, arc, np.vstack([Q, Q[:1]])[:, 0]), \
            np.interp((s - reach) % total, arc, np.vstack([Q, Q[:1]])[:, 1])
        u, v = np.subtract(ahead, Q[i]), np.subtract(behind, Q[i])
        return float(np.degrees(np.arccos(u @ v / np.linalg.norm(u) / np.linalg.norm(v))))

    return angle(int(np.argmax(Q[:, 0]))), angle(int(np.argmin(Q[:, 0])))
