"""The per-triangle graph metric ``g = M + w² JᵀJ`` of the triangle distortion ``φ``
(:mod:`.distortion`) and the lumped vertex weights of ``M``: the metric whose length bounds
every triangle's change of distortion (``|Δφ_t| ≤ ℓ/w``). It implements the layer's
:class:`~meshopt_toolkit.riemannian.metrics.Metric` protocol and provides its discrete path
energy (:mod:`.path`) to :func:`~meshopt_toolkit.riemannian.discrete_geodesic.discrete_geodesic`
(Levenberg–Marquardt)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...cells.base import lumped_mass
from ...errors import NotAdmissibleError
from ...kernels.cell_maps import coordinate_columns
from ...riemannian.assembled import AssembledMetric
from .distortion import TriangleDistortion
from .path import GraphPath


@dataclass
class GraphMetric(AssembledMetric):
    """``g = M + w² JᵀJ`` of the triangle distortion ``φ`` relative to ``reference``.

    Parameters
    ----------
    reference : (N, 2) float array
        The mesh at which ``φ = 0`` (and whose areas define ``M``).
    triangles : (T, 3) int array
    weight : float
        ``w``; the bound ``|Δφ_t| ≤ ℓ/w`` (every triangle) and the balance between moving
        vertices (``M``) and straining triangles (``JᵀJ``).
    triangle_weights : (T,) float array, optional
        Extra weights ``c_t ≥ 1`` of the triangles' rows (default 1): they only add to the
        metric, so every bound of the unweighted metric still holds.
    """

    reference: FloatArray
    triangles: IntArray
    weight: float = 1.0
    triangle_weights: FloatArray | None = None
    strain: TriangleDistortion = field(init=False)
    mass: FloatArray = field(init=False)

    def __post_init__(self) -> None:
        self.reference = np.asarray(self.reference, dtype=float)
        self.strain = TriangleDistortion(self.reference, self.triangles)
        self.mass = lumped_mass(self.reference, self.triangles)
        if self.triangle_weights is not None:
            c = np.asarray(self.triangle_weights, float)
            if c.shape != (len(self.triangles),) or not (c >= 1).all():
                raise ValueError("triangle_weights must be T values ≥ 1")
            self.triangle_weights = c

    @property
    def row_weights(self) -> FloatArray:
        """``w·c_t`` repeated over the 3 components of each triangle, (3T,)."""
        c = np.ones(len(self.triangles)) if self.triangle_weights is None else self.triangle_weights
        return self.weight * np.repeat(c, 3)

    def embed(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(m^½ ⊙ Q, w φ(Q))`` flattened; ``inf`` in the second part where inverted."""
        return (np.sqrt(self.mass)[:, None] * Q).ravel(), self.row_weights * self.strain.values(Q).ravel()

    def apply(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """``g_Q V = (M + w² JᵀJ) V`` for a displacement ``V`` (N, 2), triangle by
        triangle (no matrix)."""
        _, jb = self.strain.values_and_jacobian(Q)
        tri_cols = coordinate_columns(self.triangles, 2)
        v = V.ravel()[tri_cols]  # (T, 6)
        w2 = self.row_weights.reshape(-1, 3) ** 2
        strain = np.matmul(jb, v[:, :, None])[:, :, 0] * w2  # W² J V per triangle (T, 3)
        back = np.matmul(strain[:, None, :], jb)[:, 0]  # Jᵀ(...) per triangle (T, 6)
        out = np.bincount(tri_cols.ravel(), back.ravel(), minlength=V.size)
        return out.reshape(V.shape) + self.mass[:, None] * V

    # -- the Metric protocol (riemannian.metrics) -------------------------------------------

    def matrix(self, Q: FloatArray) -> sp.csr_matrix:
        """``M + w² JᵀJ`` at ``Q`` (N, 2) as a (2N, 2N) CSR matrix, dof ``2i + c`` the
        component ``c`` of vertex ``i``.

        Raises
        ------
        NotAdmissibleError
            A triangle of ``Q`` is inverted or degenerate (``φ`` is not defined there).
        """
        Q = np.asarray(Q, dtype=float)
        bad = int(np.sum(~(self.strain.determinants(Q) > 0)))
        if bad:
            raise NotAdmissibleError(f"the distortion metric is not defined at a mesh with "
                                     f"{bad} inverted or degenerate triangle(s)")
        _, jb = self.strain.values_and_jacobian(Q)
        J = self.strain.jacobian_matrix(jb)
        JW = sp.diags(self.row_weights) @ J
        return (sp.diags(np.repeat(self.mass, 2)) + JW.T @ JW).tocsr()

    # -- the discrete path energy (riemannian.levenberg_marquardt.PathModelMetric) ----------

    def path_model(self, frames: FloatArray, free: np.ndarray,
                   boundary_edges: IntArray | None = None,
                   anchor: FloatArray | None = None) -> GraphPath:
        """The path energy of ``frames`` (K+1, N, 2) in the coordinates ``free`` (K+1, N)
        marks (:class:`.GraphPath`); ``anchor`` (T, 3) replaces ``φ(Q_0)``."""
        return GraphPath(self, frames, free, boundary_edges, anchor)
