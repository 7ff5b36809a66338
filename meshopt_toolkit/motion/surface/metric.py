"""The metric of the surface morph: the pull-back ``g = JᵀJ`` of the embedding
``X(Q) = (m^½ Q, w φ(Q), √b √c θ(Q))`` of a triangle surface (the lumped mass ``m``, the
membrane distortion ``φ`` of :mod:`.distortion`, the dihedral angles ``θ`` of
:mod:`.bending` with their weights ``c``), whose discrete path energy
:mod:`.morph` minimizes. It implements the
:class:`~meshopt_toolkit.riemannian.metrics.Metric` protocol on ``(N, 3)`` points.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...cells.base import lumped_mass
from ...errors import NotAdmissibleError
from ...riemannian.assembled import AssembledMetric
from ...riemannian.levenberg_marquardt import require_interior_frames
from .bending import ShellBending
from .distortion import SurfaceDistortion
from .path import SurfacePath, SurfacePathProblem

__all__ = ["BENDING", "WEIGHT", "SurfaceGraphMetric"]

#: the embedding's default weights ``w`` (membrane) and ``b`` (bending), per triangle and
#: per edge unweighted by area (``move_surface`` weighs its membrane rows by rest area and
#: defaults to ``b = 0.3``: its increments and this path energy are separate definitions)
WEIGHT, BENDING = 1.0, 0.1


@dataclass
class SurfaceGraphMetric(AssembledMetric):
    """``g = JᵀJ`` of the embedding ``(m^½ Q, w φ, √b √c θ)`` relative to ``reference``.

    Parameters
    ----------
    reference : (N, 3) float array
        The rest surface (no degenerate triangle): ``φ = 0`` there, its areas define
        ``m`` and its edges the bending weights ``c``.
    triangles : (T, 3) int array
    weight : float
        ``w``, the membrane distortion's weight.
    bending : float
        ``b``, the bending's weight.
    """

    #: the points' columns (:func:`~meshopt_toolkit.riemannian.discrete_geodesic.discrete_geodesic`)
    dimension = 3

    reference: FloatArray
    triangles: IntArray
    weight: float = WEIGHT
    bending: float = BENDING
    membrane: SurfaceDistortion = field(init=False)
    shell: ShellBending = field(init=False)
    sqrt_m: FloatArray = field(init=False)
    sqrt_c: FloatArray = field(init=False)
    _path_problem: SurfacePathProblem | None = field(init=False, default=None, repr=False,
                                                     compare=False)

    def __post_init__(self) -> None:
        self.reference = np.asarray(self.reference, dtype=float)
        self.triangles = np.asarray(self.triangles)
        V0, F = self.reference, self.triangles
        self.membrane = SurfaceDistortion(V0, F)
        self.shell = ShellBending(V0, F)
        self.sqrt_c = np.sqrt(self.shell.weights) * np.sqrt(self.bending)
        self.sqrt_m = np.sqrt(np.repeat(lumped_mass(V0, F), 3))
        self.weight = float(self.weight)

    def jacobian(self, Q: FloatArray) -> sp.csr_matrix:
        """``∂X/∂Q`` (3N + 3T + E) × 3N."""
        _, blocks = self.membrane.values_and_jacobian(Q)
        Jb = self.shell.jacobian_matrix(Q)  # rows √c_e ∇θ_e
        Jb = sp.diags(self.sqrt_c / np.sqrt(self.shell.weights)) @ Jb
        return sp.vstack([sp.diags(self.sqrt_m), self.weight
                          * self.membrane.jacobian_matrix(blocks), Jb]).tocsr()

    def _checked_jacobian(self, Q: FloatArray) -> sp.csr_matrix:
        Q = np.asarray(Q, dtype=float)
        bad = int(np.sum(~np.isfinite(self.membrane.values(Q)).all(axis=1)))
        if bad:
            raise NotAdmissibleError(f"the surface metric is not defined at a surface with "
                                     f"{bad} degenerate triangle(s)")
        return self.jacobian(Q)

    def matrix(self, Q: FloatArray) -> sp.csr_matrix:
        """``JᵀJ`` (3N × 3N) at ``Q`` (N, 3).

        Raises
        ------
        NotAdmissibleError
            A triangle of ``Q`` is degenerate (``φ`` is not defined there).
        """
        J = self._checked_jacobian(Q)
        return (J.T @ J).tocsr()

    def apply(self, Q: FloatArray, V: FloatArray) -> FloatArray:
        """``g_Q V = Jᵀ(J V)`` for a displacement ``V`` (N, 3)."""
        J = self._checked_jacobian(Q)
        return (J.T @ (J @ np.ravel(V))).reshape(np.shape(V))

    # -- the discrete path energy (riemannian.levenberg_marquardt.PathModelMetric) ----------

    def path_problem(self, target: FloatArray) -> SurfacePathProblem:
        """The path energy's pieces of frames ending at ``target``
        (:class:`.path.SurfacePathProblem`; the last one kept for the same target, with
        what it measured)."""
        kept = self._path_problem
        if kept is None or not np.array_equal(kept.target, target):
            kept = self._path_problem = SurfacePathProblem(self, target)
        return kept

    def path_model(self, frames: FloatArray, free: np.ndarray, contact=None,
                   anchor: FloatArray | None = None):
        """The path energy of ``frames`` (K+1, N, 3) in every coordinate of the interior
        frames (:class:`.path.SurfacePath`; ``free`` must say so, and no ``anchor``:
        :class:`OptionError` else). ``contact`` (in the place of the boundaries kept
        simple, a :class:`.morph_contact.PathContact` of a clean start): no frame, nor
        the straight motion between two frames, passes through the surface."""
        require_interior_frames(free, anchor, "surface")
        return SurfacePath(self, frames, contact)
