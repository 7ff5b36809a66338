"""P1 vector linear elasticity + mass assembly and its SPD solvers (SPEC §4, thesis (6.24)).

The elasticity metric of the thesis is ``(U, V) = vec U · (K + δM) vec V`` with ``K`` the
P1 vector stiffness matrix of ``2μ ε(u):ε(v) + λ tr ε(u) tr ε(v)`` and ``M`` the consistent
P1 vector mass matrix, both on the *current* node positions ``Q``.

Degree-of-freedom ordering is ``vec(Q) = Q.ravel()``: component ``c`` of vertex ``i`` is dof
``2 i + c``. The matrix is therefore naturally a block matrix with 2×2 blocks (one per pair
of vertices sharing a triangle). Connectivity never changes while ``Q`` moves, so the block
sparsity pattern and the scatter map from element blocks to stored blocks are computed once
(:class:`BlockPattern`, one sort); re-assembly at a new ``Q`` is a few vectorized passes
over the triangles plus one sparse "summation" product, about half the time of a plain
COO → CSR assembly of the same element matrices (``benchmarks/bench_metrics.py``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp

from .._options import require_positive
from .._typing import FloatArray, IntArray
from ..errors import NotAdmissibleError
from ..kernels.triangles import areas_from_edges, edge_vectors
from ..solvers import (SOLVERS, amg_pcg_solve, cholmod_available, choose_method, factorize_spd,
                       import_pyamg, nested_dissection, refined_spd_solve)

__all__ = [
    "lame_parameters",
    "p1_gradients",
    "element_blocks",
    "BlockPattern",
    "assemble",
    "rigid_modes",
    "SPDSolve",
    "factorize",
    "solver_method",
    "kept_ordering",
    "SOLVERS",
]

logger = logging.getLogger(__name__)

#: Dofs from which ``"auto"`` switches from SuperLU to AMG-PCG (SuperLU grows like
#: dofs^1.5, AMG like dofs^0.9; ``benchmarks/bench_metrics.py``).
AUTO_AMG_MIN_DOFS = 2_000_000
#: The same switch where the direct method is CHOLMOD's Cholesky (which grows like
#: dofs^1.35; the limit is its memory; ``benchmarks/bench_solvers.py``).
CHOLMOD_AMG_MIN_DOFS = 4_000_000
#: Without CHOLMOD, from this many dofs SuperLU factorizes in float32 and CG refines
#: (:func:`.solvers.refined_spd_solve`): less memory and time; below, a double-precision
#: factor solves exactly in one triangular solve.
SINGLE_PRECISION_MIN_DOFS = 100_000


def lame_parameters(E: float, nu: float) -> tuple[float, float]:
    """Lamé parameters ``(λ, μ)`` from Young's modulus and Poisson ratio (plane strain).

    ``μ = E / (2(1 + ν))``, ``λ = E ν / ((1 + ν)(1 − 2ν))``, thesis (6.24).
    """
    require_positive("Young's modulus E", E, error=ValueError)
    if not -1.0 < nu < 0.5:
        raise ValueError(f"Poisson ratio nu must lie in (-1, 0.5), got {nu}")
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def p1_gradients(points: FloatArray, triangles: IntArray) -> tuple[FloatArray, FloatArray]:
    """Gradients of the three P1 hat functions on every triangle, and the signed areas.

    For a counter-clockwise triangle the gradient of the hat function of local vertex ``a``
    is the left normal of the opposite edge ``e_a = q_{a+2} − q_{a+1}`` divided by ``2A``:
    ``∇φ_a = (−e_a,y, e_a,x) / (2A)``; it points towards vertex ``a`` with length ``1/h_a``.

    Parameters
    ----------
    points, triangles : (N, 2) float and (T, 3) int arrays

    Returns
    -------
    grads : (T, 3, 2) float array, ``grads[t, a]`` = ``∇φ_a`` on triangle ``t``
    areas : (T,) float array of signed areas (4.2)
    """
    e = edge_vectors(points, triangles)  # edge a opposite vertex a, (T, 3, 2)
    areas = areas_from_edges(e[..., 0].T, e[..., 1].T)
    grads = np.empty_like(e)
    inv2a = 0.5 / areas
    grads[..., 0] = -e[..., 1] * inv2a[:, None]
    grads[..., 1] = e[..., 0] * inv2a[:, None]
    return grads, areas


def element_blocks(
    points: FloatArray, triangles: IntArray, lam: float, mu: float, delta: float,
    out: FloatArray | None = None,
) -> FloatArray:
    """Element matrices of ``K + δM`` as 2×2 blocks, all triangles at once.

    With ``g_a = ∇φ_a`` and area ``A``, the block coupling local vertex ``a`` (component
    ``c``) to local vertex ``b`` (component ``d``) is

    ``A [μ δ_cd g_a·g_b + μ g_a,d g_b,c + λ g_a,c g_b,d] + δ δ_cd A (1 + δ_ab) / 12``

    (stiffness of ``2μ ε:ε + λ tr ε tr ε`` plus the exact P1 mass, thesis (6.24)).

    Parameters
    ----------
    points : (N, 2) float array, current node positions ``Q``
    triangles : (T, 3) int array, counter-clockwise
    lam, mu : Lamé parameters
    delta : weight of the mass term
    out : (T, 3, 3, 2, 2) float array, optional
        Written in place and returned: a caller that assembles at many positions keeps
        one buffer (at 1.7M triangles a fresh 0.5 GB array costs 1–2.5 s of page faults
        per assembly, against about 1 s for the whole assembly into a kept one).

    Returns
    -------
    (T, 3, 3, 2, 2) float array ``B[t, a, b, c, d]``

    Raises
    ------
    NotAdmissibleError
        If a triangle has non-positive signed area (the metric lives on ``M+``).
    """
    g, areas = p1_gradients(points, triangles)
    if not np.all(areas > 0):
        bad = int(np.flatnonzero(~(areas > 0))[0])
        raise NotAdmissibleError(
            f"elasticity metric needs positive triangle areas; triangle {bad} has "
            f"signed area {areas[bad]:.3e}"
        )
    if out is None:
        out = np.empty((len(areas), 3, 3, 2, 2))
    root_area_g = g * np.sqrt(areas)[:, None, None]
    # out[t, a, b, c, d] = A g_a,c g_b,d, then combined in place (few temporaries)
    np.einsum("tac,tbd->tabcd", root_area_g, root_area_g, out=out)
    xx, xy, yx, yy = out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1]
    shared = xx + yy  # A μ g_a·g_b plus the P1 mass, on both diagonal components
    shared *= mu
    mass = (delta / 12.0) * areas
    shared += mass[:, None, None]
    shared[:, [0, 1, 2], [0, 1, 2]] += mass[:, None]
    xy_copy = xy.copy()
    xy *= lam / mu  # (0, 1): λ A g_a,x g_b,y + μ A g_a,y g_b,x
    xy += yx
    xy *= mu
    yx *= lam / mu  # (1, 0): λ A g_a,y g_b,x + μ A g_a,x g_b,y
    yx += xy_copy
    yx *= mu
    xx *= lam + mu
    xx += shared
    yy *= lam + mu
    yy += shared
    return out


@dataclass(frozen=True)
class BlockPattern:
    """Block sparsity pattern of a P1 vector operator on fixed connectivity.

    Attributes
    ----------
    n_vertices : N
    indptr : (N + 1,) int array, block CSR row pointers
    indices : (nnzb,) int array, block column indices (sorted within each row)
    scatter : (9 T,) int array, stored block receiving element block ``(t, a, b)``
        (flattened in C order)
    summation : (nnzb, 9 T) CSR matrix of ones, ``summation[scatter[k], k] = 1``: one
        sparse product sums all element blocks into the stored blocks
    """

    n_vertices: int
    indptr: IntArray
    indices: IntArray
    scatter: IntArray
    summation: sp.csr_matrix

    @classmethod
    def from_triangles(cls, triangles: IntArray, n_vertices: int) -> "BlockPattern":
        """Build the pattern of all vertex pairs sharing a triangle (incl. the diagonal).

        Parameters
        ----------
        triangles : (T, 3) int array
        n_vertices : N
        """
        tri = np.asarray(triangles, dtype=np.int64)
        keys = (tri[:, :, None] * n_vertices + tri[:, None, :]).ravel()  # (t, a, b), C order
        order = np.argsort(keys)
        sorted_keys = keys[order]
        first = np.empty(keys.size, dtype=bool)
        first[:1] = True
        np.not_equal(sorted_keys[1:], sorted_keys[:-1], out=first[1:])
        scatter = np.empty(keys.size, dtype=np.int64)
        scatter[order] = np.cumsum(first) - 1  # rank among the distinct sorted keys
        unique = sorted_keys[first]  # row-major: rows ascending, columns sorted in each row
        rows, indices = np.divmod(unique, n_vertices)
        indptr = np.zeros(n_vertices + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=n_vertices), out=indptr[1:])
        # CSR of the summation matrix directly: row r holds the entries k with scatter = r
        summation = sp.csr_matrix(
            (np.ones(keys.size), order.astype(np.int64), np.flatnonzero(np.append(first, True))),
            shape=(unique.size, keys.size),
        )
        return cls(n_vertices, indptr, indices, scatter, summation)

    @property
    def n_blocks(self) -> int:
        """Number of stored 2×2 blocks."""
        return int(self.indices.size)

    def assemble(self, blocks: FloatArray) -> sp.bsr_matrix:
        """Sum element blocks into a block sparse matrix.

        Parameters
        ----------
        blocks : (T, 3, 3, 2, 2) float array of element blocks

        Returns
        -------
        (2N, 2N) ``scipy.sparse.bsr_matrix`` with blocksize (2, 2)
        """
        flat = np.ascontiguousarray(blocks).reshape(-1, 4)
        data = (self.summation @ flat).reshape(-1, 2, 2)
        n = 2 * self.n_vertices
        return sp.bsr_matrix((data, self.indices, self.indptr), shape=(n, n))


def assemble(points: FloatArray, triangles: IntArray, E: float = 1.0, nu: float = 0.4,
             delta: float = 0.2, pattern: BlockPattern | None = None,
             out: FloatArray | None = None) -> sp.bsr_matrix:
    """Assemble ``K + δM`` (thesis (6.24)) at node positions ``points``.

    Parameters
    ----------
    points : (N, 2) float array
    triangles : (T, 3) int array, counter-clockwise
    E, nu : Young's modulus and Poisson ratio
    delta : mass weight ``δ`` (the thesis uses ``δ = 0.2 E``)
    pattern : optional precomputed :class:`BlockPattern` of ``triangles``
    out : optional (T, 3, 3, 2, 2) buffer for the element blocks (:func:`element_blocks`)

    Returns
    -------
    (2N, 2N) ``bsr_matrix`` with 2×2 blocks, dof ``2 i + c`` = vertex ``i`` component ``c``.
    """
    points = np.asarray(points, dtype=float)
    if pattern is None:
        pattern = BlockPattern.from_triangles(triangles, points.shape[0])
    lam, mu = lame_parameters(E, nu)
    return pattern.assemble(element_blocks(points, triangles, lam, mu, delta, out))


def rigid_modes(points: FloatArray) -> FloatArray:
    """Rigid velocities in vec ordering: in the plane two translations and the rotation
    about the centroid, in space three translations and three rotations.

    Parameters
    ----------
    points : (N, d) float array, d = 2 or 3

    Returns
    -------
    (d N, 3) or (3 N, 6) float array; column ``k`` is ``vec`` of an ``(N, d)`` rigid
    velocity field.
    """
    n, d = points.shape
    c = points - points.mean(axis=0)
    if d == 2:
        B = np.zeros((n, 2, 3))
        B[:, 0, 0] = 1.0
        B[:, 1, 1] = 1.0
        B[:, 0, 2] = -c[:, 1]
        B[:, 1, 2] = c[:, 0]
        return B.reshape(2 * n, 3)
    B = np.zeros((n, 3, 6))
    B[:, [0, 1, 2], [0, 1, 2]] = 1.0
    for k in range(3):  # e_k × c
        B[:, :, 3 + k] = np.cross(np.eye(3)[k], c)
    return B.reshape(3 * n, 6)


@dataclass
class SPDSolve:
    """A reusable solver for one SPD matrix: ``solve(b)`` returns ``A⁻¹ b``.

    Attributes
    ----------
    method : "direct" or "amg"
    solve : callable ``(2N,) -> (2N,)``
    matrix : the sparse matrix that was factorized
    precondition : callable ``(2N,) -> (2N,)``, optional
        The direct method's factor itself (float32 from ``SINGLE_PRECISION_MIN_DOFS``
        dofs, where ``solve`` refines it by CG), to precondition CG on nearby matrices;
        ``None``: use ``solve``.
    """

    method: str
    solve: Callable[[FloatArray], FloatArray]
    matrix: sp.spmatrix
    precondition: Callable[[FloatArray], FloatArray] | None = None


def _factorize_amg(
    A: sp.bsr_matrix, points: FloatArray, rtol: float, max_iterations: int
) -> Callable[[FloatArray], FloatArray]:
    ml = import_pyamg().smoothed_aggregation_solver(
        A,
        B=rigid_modes(points),  # rigid motions: near-null space of K
        symmetry="symmetric",
        strength=("symmetric", {"theta": 0.05}),
    )
    return amg_pcg_solve(A, ml, rtol, max_iterations)


def solver_method(method: str, n_dofs: int) -> str:
    """The elasticity matrix's "auto" rule: ``"direct"`` below ``CHOLMOD_AMG_MIN_DOFS``
    dofs with CHOLMOD (``AUTO_AMG_MIN_DOFS`` without), ``"amg"`` above when pyamg is
    importable (:func:`.solvers.choose_method`)."""
    amg_from = CHOLMOD_AMG_MIN_DOFS if cholmod_available() else AUTO_AMG_MIN_DOFS
    return choose_method(method, n_dofs, amg_from)


def kept_ordering(orderings: dict, key, A: sp.spmatrix, points: FloatArray,
                  method: str) -> IntArray | None:
    """The direct method's nested-dissection ordering of ``A``, computed at the first call
    for ``key`` and kept in ``orderings`` (a caller that refactorizes one pattern along a
    path: the first positions' ordering stays good as the mesh moves); None for AMG."""
    if method != "direct":
        return None
    if key not in orderings:
        orderings[key] = nested_dissection(points, A, block=2)
    return orderings[key]


def factorize(
    A: sp.spmatrix,
    points: FloatArray,
    method: str = "auto",
    rtol: float = 1e-10,
    max_iterations: int = 500,
    ordering: IntArray | None = None,
) -> SPDSolve:
    """Prepare a reusable solver for the SPD matrix ``A = K + δM``.

    Parameters
    ----------
    A : (dN, dN) sparse SPD matrix (BSR with d×d blocks preferred for AMG)
    points : (N, d) node positions, d = 2 or 3 (rigid modes for the AMG near-null space,
        the geometric nested-dissection ordering of the direct method)
    method : "direct" (nested-dissection ordering; CHOLMOD's Cholesky where installed,
        else SuperLU in symmetric mode, from ``SINGLE_PRECISION_MIN_DOFS`` dofs in
        float32 as the preconditioner of CG to ``rtol``:
        :func:`.solvers.refined_spd_solve`), "amg" (pyamg smoothed
        aggregation preconditioned CG to ``rtol``) or "auto"
        (:func:`solver_method`: direct below ``CHOLMOD_AMG_MIN_DOFS`` dofs with CHOLMOD,
        ``AUTO_AMG_MIN_DOFS`` without, AMG above when pyamg is importable)
    rtol, max_iterations : relative residual of the solve; AMG-PCG's iteration cap
    ordering : (2N,) int array, optional
        The direct method's fill-reducing ordering (new → old); default
        ``nested_dissection(points, A, block=2)``. A moving mesh keeps a good ordering,
        so callers that refactorize along a path may compute it once.

    Returns
    -------
    SPDSolve
    """
    method = solver_method(method, A.shape[0])
    if method == "direct":
        if ordering is None:
            ordering = nested_dissection(points, A, block=points.shape[1])
        if A.shape[0] < SINGLE_PRECISION_MIN_DOFS or cholmod_available():
            exact = factorize_spd(A, ordering)
            return SPDSolve("direct", exact, A, exact)
        solve, precondition = refined_spd_solve(A, ordering, rtol)
        return SPDSolve("direct", solve, A, precondition)
    d = points.shape[1]
    bsr = A if A.format == "bsr" else sp.bsr_matrix(A, blocksize=(d, d))
    return SPDSolve("amg", _factorize_amg(bsr, points, rtol, max_iterations), bsr)
