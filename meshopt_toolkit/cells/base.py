"""The cell-kind interface: what every operation asks of a kind of simplex.

A cell kind (:class:`CellKind`) answers for arrays of points ``(N, d)`` and cells
``(C, k)`` (``k`` corners each): their measures, quality, the affine maps' Jacobians
against a rest shape, the per-cell distortion with its derivatives, the lumped mass, the
boundary facets, exact admissibility and the fold test against a rest shape, and the
default metric of a motion. Every answer is delegated to the one owner of the concept
(``kernels/``, ``mesh/``, the distortions of ``motion/``); :class:`SimplexKind` holds the
parts that are the same formula for every kind (Jacobians from the rest corners, the
lumped mass from the measures, the distortion's vertex gradient).

Which kind a mesh object is, is decided in one place, :func:`.registry.kind_of`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np

from .._typing import FloatArray, IntArray
from ..kernels.cell_maps import affine_maps, barycentric_gradients, coordinate_columns
from ..kernels.surface import areas
from ..kernels.tetrahedra import signed_volumes
from ..kernels.triangles import signed_areas

__all__ = ["CellDistortion", "CellKind", "SimplexKind", "lumped_mass", "scale_free_mass"]


@runtime_checkable
class CellDistortion(Protocol):
    """A per-cell distortion ``φ(Q)`` (C, m) relative to a reference, with its Jacobian
    blocks (C, m, k·d): block ``[c, i, d·j + a]`` is ``∂φ_ci / ∂Q[cells[c, j], a]``.

    Every distortion is made as ``Distortion(reference, cells)`` from the node positions
    ``reference`` (N, d) float at which ``φ = 0`` and the cells (C, k) int; each one names
    what its reference cells must be (a :class:`CellKind`'s ``distortion`` makes it)."""

    n_components: int

    def values(self, Q: FloatArray) -> FloatArray: ...

    def values_and_jacobian(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]: ...


class KindSizes(Protocol):
    """The name and sizes of a kind of simplicial cell: points are
    ``(N, point_dimension)``, cells ``(C, simplex_size)`` ints of dimension
    ``cell_dimension``."""

    name: str
    point_dimension: int
    cell_dimension: int
    simplex_size: int


@runtime_checkable
class CellKind(KindSizes, Protocol):
    """A kind of simplicial cell (triangles in the plane, triangles in space,
    tetrahedra)."""

    def measures(self, points: FloatArray, cells: IntArray) -> FloatArray: ...

    def quality(self, points: FloatArray, cells: IntArray) -> FloatArray: ...

    def jacobians(self, points: FloatArray, cells: IntArray, rest: FloatArray) -> FloatArray: ...

    def distortion(self, reference: FloatArray, cells: IntArray) -> CellDistortion: ...

    def distortion_gradient(self, points: FloatArray, cells: IntArray, reference: FloatArray,
                            weights: FloatArray) -> tuple[FloatArray, FloatArray]: ...

    def lumped_mass(self, points: FloatArray, cells: IntArray) -> FloatArray: ...

    def boundary_facets(self, points: FloatArray, cells: IntArray) -> IntArray: ...

    def admissibility_problem(self, points: FloatArray, cells: IntArray) -> str | None: ...

    def fold_test(self, points: FloatArray, cells: IntArray, rest: FloatArray) -> np.ndarray: ...

    def default_metric(self, reference: FloatArray, cells: IntArray): ...


def scale_free_mass(points: FloatArray, cells: IntArray, measures: FloatArray) -> FloatArray:
    """Vertex weights ``m_i`` with ``Σ m_i |v_i|²`` the measure-weighted mean of ``|v|²``
    divided by the mean squared distance from the centroid: a dimensionless, size- and
    resolution-independent norm of a displacement field (the mass ``M`` of the motions'
    metrics ``M + w² JᵀJ``).

    Parameters
    ----------
    points : (N, d) float array
    cells : (C, k) int array
    measures : (C,) float array
        Unsigned measures of the cells (areas, volumes).

    Returns
    -------
    (N,) float array
    """
    k = cells.shape[1]
    m = np.bincount(np.asarray(cells).ravel(), np.repeat(measures / float(k), k),
                    minlength=len(points))
    m /= m.sum()
    centroid = m @ points
    spread = float(m @ np.sum((points - centroid) ** 2, axis=1))
    return m / spread


def lumped_mass(points: FloatArray, cells: IntArray) -> FloatArray:
    """The motions' one lumped mass, :func:`scale_free_mass` of the cells' unsigned
    measures: areas of triangles ``(T, 3)`` in the plane ``(N, 2)`` or in space ``(N, 3)``,
    volumes of tets ``(C, 4)``; what every :class:`CellKind`'s ``lumped_mass`` returns.

    Returns
    -------
    (N,) float array
    """
    points, cells = np.asarray(points, dtype=float), np.asarray(cells)
    if cells.shape[1] == 4:
        measures = np.abs(signed_volumes(points, cells))
    elif points.shape[1] == 2:
        measures = np.abs(signed_areas(points, cells))
    else:
        measures = areas(points, cells)
    return scale_free_mass(points, cells, measures)


class SimplexKind(KindSizes):
    """What every simplicial kind computes the same way from its own measures and rest
    coordinates (a kind subclasses it, sets its sizes, names its kernels and distortion,
    and supplies the rest of :class:`CellKind`)."""

    #: ``(points, cells) -> (C,)``: the kind's measure and quality kernels
    measure_kernel: Callable[[FloatArray, IntArray], FloatArray]
    quality_kernel: Callable[[FloatArray, IntArray], FloatArray]
    #: ``(reference, cells) ->`` the kind's :class:`CellDistortion`
    distortion_class: type

    def __repr__(self) -> str:
        return f"<cell kind {self.name}>"

    def measures(self, points: FloatArray, cells: IntArray) -> FloatArray:
        """The cells' measures (C,) (:attr:`measure_kernel`): signed where the kind has an
        orientation (areas in the plane, volumes), else unsigned areas."""
        return self.measure_kernel(np.asarray(points, dtype=float), np.asarray(cells))

    def quality(self, points: FloatArray, cells: IntArray) -> FloatArray:
        """The cells' quality (C,) (:attr:`quality_kernel`), 1 for a regular cell."""
        return self.quality_kernel(np.asarray(points, dtype=float), np.asarray(cells))

    def distortion(self, reference: FloatArray, cells: IntArray) -> CellDistortion:
        """The per-cell distortion relative to ``reference`` (:attr:`distortion_class`)."""
        return self.distortion_class(reference, cells)

    def rest_coordinates(self, rest: FloatArray, cells: IntArray) -> FloatArray:
        """Corners of each rest cell in coordinates of its own dimension:
        ``(C, k, cell_dimension)``."""
        return np.asarray(rest, dtype=float)[cells]

    def jacobians(self, points: FloatArray, cells: IntArray, rest: FloatArray) -> FloatArray:
        """Linear parts ``A`` (C, point_dimension, cell_dimension) of the affine maps from
        the rest cells (``rest`` (N, point_dimension), non-degenerate) to the cells at
        ``points``."""
        gradients = barycentric_gradients(self.rest_coordinates(rest, cells))
        return affine_maps(points, cells, gradients)

    def lumped_mass(self, points: FloatArray, cells: IntArray) -> FloatArray:
        """The motions' dimensionless lumped mass (:func:`lumped_mass`) (N,)."""
        return lumped_mass(points, cells)

    def distortion_gradient(self, points: FloatArray, cells: IntArray, reference: FloatArray,
                            weights: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``φ(points)`` (C, m) relative to ``reference`` and the vertex gradient
        ``∇_Q Σ_c ρ_c · φ_c`` (N, point_dimension) of the weights ``ρ = weights`` (C, m)."""
        phi, blocks = self.distortion(reference, cells).values_and_jacobian(points)
        per_cell = np.einsum("cm,cmj->cj", np.asarray(weights, dtype=float), blocks)
        d = self.point_dimension
        cols = coordinate_columns(cells, d)
        out = np.bincount(cols.ravel(), per_cell.ravel(), minlength=d * len(points))
        return phi, out.reshape(len(points), d)
