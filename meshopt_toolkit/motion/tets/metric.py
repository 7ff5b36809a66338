"""The graph metric ``g = M + w² JᵀJ`` of the tet distortion ``φ`` (:mod:`.distortion`)
and the lumped vertex weights of ``M``: the 3D counterpart of :mod:`..planar.metric`, whose
length bounds every tet's change of distortion (``|Δφ_c| ≤ ℓ/w``). It implements the
:class:`~meshopt_toolkit.riemannian.metrics.Metric` protocol on ``(N, 3)`` points
(:class:`~meshopt_toolkit.riemannian.assembled.AssembledMetric`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...cells.base import lumped_mass
from ...errors import NotAdmissibleError
from ...kernels.intersections3d import self_intersections
from ...riemannian.assembled import AssembledMetric
from ...riemannian.levenberg_marquardt import require_interior_frames
from .distortion import TetDistortion
from .path import TetPath


@dataclass
class TetGraphMetric(AssembledMetric):
    """``g = M + w² JᵀJ`` of the tet distortion relative to ``reference``.

    Parameters
    ----------
    reference : (N, 3) float array
        The mesh at which ``φ = 0`` (and whose volumes define ``M``).
    tets : (C, 4) int array
    weight : float
        ``w``: ``|Δφ_c| ≤ ℓ/w`` for every tet along a path of length ℓ.
    """

    reference: FloatArray
    tets: IntArray
    weight: float = 1.0
    strain: TetDistortion = field(init=False)
    mass: FloatArray = field(init=False)
    #: the points' columns (the discrete geodesic's frames are (K+1, N, 3))
    dimension: ClassVar[int] = 3

    def __post_init__(self) -> None:
        self.reference = np.asarray(self.reference, dtype=float)
        self.strain = TetDistortion(self.reference, self.tets)
        self.mass = lumped_mass(self.reference, self.strain.tets)

    def embed(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(m^½ ⊙ Q, w φ(Q))`` flattened; ``inf`` in the second part where inverted."""
        strain = self.weight * self.strain.values(Q).ravel()
        return (np.sqrt(self.mass)[:, None] * Q).ravel(), strain

    def jacobian(self, Q: FloatArray) -> sp.csr_matrix:
        """The sparse ``J = ∂φ/∂Q`` (7C × 3N) at ``Q``."""
        return self.strain.jacobian_matrix(self.strain.values_and_jacobian(Q)[1])

    def matrix(self, Q: FloatArray) -> sp.csr_matrix:
        """The assembled ``M + w² JᵀJ`` (3N × 3N) at ``Q``.

        Raises
        ------
        NotAdmissibleError
            A tet of ``Q`` is inverted or flat (``φ`` is not defined there).
        """
        bad = int(np.sum(~(self.strain.determinants(np.asarray(Q, dtype=float)) > 0)))
        if bad:
            raise NotAdmissibleError(f"the tet distortion metric is not defined at a mesh "
                                     f"with {bad} inverted or flat tetrahedra")
        J = self.jacobian(Q)
        return (sp.diags(np.repeat(self.mass, 3)) + self.weight**2 * (J.T @ J)).tocsr()

    def apply(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """``g_Q V = (M + w² JᵀJ) V`` for a displacement ``V`` (N, 3), tet by tet."""
        _, jb = self.strain.values_and_jacobian(Q)
        cols = self.strain.columns()
        strain = np.matmul(jb, V.ravel()[cols][:, :, None])  # J V per tet (C, 7, 1)
        back = np.matmul(np.swapaxes(jb, 1, 2), strain)[:, :, 0] * self.weight**2
        out = np.bincount(cols.ravel(), back.ravel(), minlength=V.size)
        return out.reshape(V.shape) + self.mass[:, None] * V

    # -- the discrete path energy (riemannian.levenberg_marquardt.PathModelMetric) ----------

    def path_model(self, frames: FloatArray, free: np.ndarray,
                   boundary_faces: IntArray | None = None,
                   anchor: FloatArray | None = None) -> TetPath:
        """The path energy of ``frames`` (K+1, N, 3) in every coordinate of the interior
        frames (:class:`.path.TetPath`; ``free`` must say so, and no ``anchor``:
        :class:`OptionError` else); with ``boundary_faces`` (F, 3) a frame whose faces
        intersect is not admissible."""
        require_interior_frames(free, anchor, "tet")
        faces = boundary_faces
        return TetPath(self, frames, None if faces is None else
                       lambda Q: bool(len(self_intersections(Q, faces))))
