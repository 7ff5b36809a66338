"""A file's mesh as :func:`~.move.move` moves it, and back: :class:`MovedFile`.

The front ends of ``move`` (``meshopt move``, the move filter) hand over what they read
(a file's cells, a pipeline's mesh) and get back the mesh to choose handles on and move,
and the way back to what they write; the kind is decided here, once
(:func:`~..mesh.kinds.cells_kind` of a file's cells, :func:`~..mesh.kinds.mesh_kind` of a
pipeline's mesh):

* **planar triangles** (any one plane) through their
  :class:`~..io.workpiece.Workpiece`: the plane's coordinates at the file's scale, every
  block, tag and datum written back, what the format cannot hold left out with a warning
  (:func:`~..io.workpiece.save_workpiece`);
* **tetrahedra** and **triangle surfaces in 3D** as a ``TetMesh`` or ``SurfaceMesh`` in
  the file's coordinates, the file's cells written back with only their points replaced
  (:func:`~..io.save_cells`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..io.cells import CellMesh
from ..io.workpiece import Workpiece, save_workpiece
from ..mesh import SurfaceMesh, TriangleMesh
from ..mesh.kinds import PLANAR, SURFACE, TETS, cells_kind, mesh_kind

__all__ = ["MovedFile"]


@dataclass(frozen=True, eq=False)
class MovedFile:
    """What ``move`` moves of a file or a pipeline's mesh, and the way back.

    Attributes
    ----------
    kind : str
        :data:`~..mesh.kinds.PLANAR`, :data:`~..mesh.kinds.SURFACE` or
        :data:`~..mesh.kinds.TETS`.
    mesh : PlanarMesh, SurfaceMesh or TetMesh
        What :func:`~.move.move` moves and the handles are chosen on (a planar mesh in its
        plane's coordinates), admissible where ``move`` needs it before any work.
    cells : CellMesh or None
        The file's cells (None: a pipeline's mesh).
    workpiece : Workpiece or None
        A planar mesh's way to and from its file (None in space).
    source : TriangleMesh, TetMesh or None
        A pipeline's mesh in space as it was given (None otherwise).
    """

    kind: str
    mesh: Any
    cells: CellMesh | None = None
    workpiece: Workpiece | None = None
    source: Any = None

    @classmethod
    def of_cells(cls, cells: CellMesh, what: str = "move") -> MovedFile:
        """The mesh of a file's ``cells`` (``what`` names the operation in refusals).

        Raises
        ------
        InvalidMeshError
            Cells no kind takes, or a mesh that is not admissible (a planar mesh with an
            inverted triangle, a tet mesh with an inverted tet).
        """
        kind = cells_kind(cells)
        if kind == TETS:
            return cls(kind, cells.to_tet_mesh(what).require_admissible(), cells)
        if kind == SURFACE:
            return cls(kind, cells.to_surface_mesh(what), cells)
        wp = Workpiece.from_cells(cells).admissible(what)
        return cls(kind, wp.mesh, cells, wp)

    @classmethod
    def of_mesh(cls, mesh, workpiece: Callable[[], Workpiece | None],
                what: str = "move") -> MovedFile:
        """A pipeline's ``mesh`` (file coordinates), ``workpiece`` giving its planar view
        with its file's extras (None where the mesh is on no plane it can keep)."""
        if mesh_kind(mesh) == TETS:
            return cls(TETS, mesh.require_admissible(), source=mesh)
        wp = workpiece()
        if wp is None:  # triangles in space: moved as a surface, given back as triangles
            return cls(SURFACE, SurfaceMesh(mesh.points, mesh.triangles, **mesh._tag_kwargs()),
                       source=mesh)
        wp = wp.admissible(what)
        return cls(PLANAR, wp.mesh, workpiece=wp)

    def moved(self, moved) -> MovedFile:
        """This file with the vertices where the mesh ``moved`` (of :attr:`mesh`'s
        kind, e.g. a result's) has them."""
        if self.workpiece is not None:
            wp = self.workpiece.moved(moved.points)
            return replace(self, mesh=wp.mesh, cells=None if self.cells is None else wp.cells,
                           workpiece=wp)
        points = np.array(moved.points, dtype=float)
        source = self.source
        if source is not None:
            source = (source.with_points(points) if self.kind == TETS
                      else TriangleMesh(points, source.triangles, **source._tag_kwargs()))
        cells = None if self.cells is None else replace(self.cells, points=points)
        return replace(self, mesh=moved, cells=cells, source=source)

    @property
    def file_mesh(self):
        """The mesh in file coordinates (what a pipeline holds)."""
        return self.workpiece.file_mesh() if self.workpiece is not None else self.source

    def save(self, path, *, overwrite: bool = True):
        """Write :attr:`cells` (every block, tag and datum) to ``path``."""
        if self.workpiece is not None:
            return save_workpiece(self.workpiece.to_cells(), path, overwrite=overwrite)
        from ..io import save_cells

        return save_cells(self.cells, path, overwrite=overwrite)

    def summary(self, result, handles) -> dict:
        """``result``'s summary, led by the count of distinct ``handles`` in space (whose
        results do not count them)."""
        if self.kind == PLANAR:
            return result.summary()
        return {"handles": int(len(np.unique(handles))), **result.summary()}
