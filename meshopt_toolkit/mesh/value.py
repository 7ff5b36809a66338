"""What every mesh class is as a value: its ``repr`` and its equality.

A mesh class names its cell array and cell count (:attr:`MeshValue._cells`,
:attr:`MeshValue._count`); two meshes are equal when they are of the same family (the
class that names them, or a subclass) with the same points and cells, bitwise. Meshes
are not hashable (their arrays are large and compared whole).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MeshValue"]


class MeshValue:
    """``repr`` and ``==`` of an immutable mesh (module docstring)."""

    #: the name of the cell array (``"triangles"``, ``"tets"``) and of the cell count
    _cells: str
    _count: str

    def __repr__(self) -> str:
        src = f", source={self.source!r}" if self.source else ""
        return (f"{type(self).__name__}(n_vertices={self.n_vertices}, "
                f"{self._count}={getattr(self, self._count)}{src})")

    def __eq__(self, other: object) -> bool:
        family = next(c for c in type(self).__mro__ if "_cells" in vars(c))
        if not isinstance(other, family):
            return NotImplemented
        return (self.points.shape == other.points.shape
                and np.array_equal(self.points, other.points)
                and np.array_equal(getattr(self, self._cells), getattr(other, self._cells)))

    __hash__ = None  # type: ignore[assignment]
