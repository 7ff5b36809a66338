"""A file's mesh as the planar operations work on it, and back: :class:`Workpiece`.

``move``, ``deform``, ``optimize``, ``morph`` and the pipeline filters work on a
:class:`~meshopt_toolkit.mesh.PlanarMesh` at the file's scale (the operations work at unit
size themselves, :mod:`meshopt_toolkit.scaling`); the file holds a
:class:`~meshopt_toolkit.io.cells.CellMesh` (every block, tag, name and datum). A
workpiece is the one way between the two:

* **the plane**: 2D points, or 3D points with one constant z, are worked on as their
  x, y themselves (bit for bit; z is kept, never scaled); points on any other plane
  (within :data:`~meshopt_toolkit.orientation.PLANE_RTOL`) in the coordinates of an
  orthonormal frame of it. Written back, a vertex the operation did not move keeps its
  original coordinates bit for bit; a moved one is mapped into the plane.
* **the rest**: every cell block in order with its data (``gmsh:physical``,
  ``gmsh:geometrical``, anything else), vertex cells, point data (it travels with its
  vertex) and field data (physical names) are written back unchanged; what an operation
  computes is added as cell or point data (:meth:`Workpiece.to_cells`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ..errors import FileWriteError, InvalidMeshError, WriteError
from ..mesh import PlanarMesh, TriangleMesh
from ..mesh.topology import new_points
from ..orientation import PLANE_RTOL, PlaneEmbedding, plane_embedding
from .cells import PHYSICAL, TRIANGLE_KINDS, CellMesh

logger = logging.getLogger(__name__)

__all__ = ["Workpiece", "save_workpiece", "cells_with_attributes"]


@dataclass(frozen=True, eq=False)
class Workpiece:
    """The planar mesh of a :class:`CellMesh`, with the way back.

    Attributes
    ----------
    cells : CellMesh
        What the file holds, in file coordinates.
    plane : (N, 2) float array
        Plane coordinates of ``cells.points`` at the file's scale.
    frame : PlaneEmbedding or None
        None: the plane coordinates are x, y themselves (2D points, or z constant).
    """

    cells: CellMesh
    plane: np.ndarray
    frame: PlaneEmbedding | None

    # -- in ---------------------------------------------------------------------------
    @classmethod
    def from_cells(cls, cells: CellMesh) -> "Workpiece":
        """The workpiece of ``cells``.

        Raises
        ------
        InvalidMeshError
            The points are not on one plane (naming the file and the distance), or
            :meth:`CellMesh.to_triangle_mesh` refuses the cells.
        """
        cells.require_cell_types(TRIANGLE_KINDS, "triangles")  # before the plane's check
        plane, frame = _plane_coordinates(cells)
        wp = cls(cells, plane, frame)
        wp.mesh  # noqa: B018 - the cells are checked now, not at first use
        return wp

    @classmethod
    def from_mesh(cls, mesh: TriangleMesh) -> "Workpiece":
        """The workpiece of a triangle mesh (its points, lines, triangles and tags)."""
        return cls.from_cells(CellMesh.from_triangle_mesh(mesh))

    def admissible(self, what: str = "this operation") -> "Workpiece":
        """This workpiece with its mesh checked (and oriented) by
        :func:`~meshopt_toolkit.mesh.require_admissible`."""
        from ..mesh import require_admissible

        mesh = require_admissible(self.mesh, what)
        new = replace(self)
        new.__dict__["mesh"] = mesh
        return new

    def target(self, cells: CellMesh) -> "Workpiece":
        """The workpiece of ``cells`` (the same vertices, in this plane: a morph's target)
        in this frame."""
        plane = self.plane_coordinates(cells.points, cells.source or "the target")
        return Workpiece(cells, plane, self.frame)

    def with_file_points(self, points) -> "Workpiece":
        """The workpiece with its file's vertices at ``points`` (the same vertices, moved
        in file coordinates, e.g. by a MeshLab step): plane coordinates derived, bit for
        bit where a vertex did not move.

        Raises
        ------
        InvalidMeshError
            A vertex left the plane.
        """
        p = _pad(np.asarray(points, dtype=np.float64), self.cells.points.shape[1])
        plane = self.plane_coordinates(p)
        return Workpiece(replace(self.cells, points=p), plane, self.frame)

    # -- the working mesh -------------------------------------------------------------
    @cached_property
    def mesh(self) -> PlanarMesh:
        """The triangles, lines and physical tags in plane coordinates."""
        cm = self.cells
        # the vertex cells and data stay in ``cells`` (the working mesh has no place for them)
        keep = [i for i, (t, _) in enumerate(cm.cells) if t != "vertex"]
        phys = cm.cell_data.get(PHYSICAL)
        data = {} if phys is None else {PHYSICAL: [phys[i] for i in keep]}
        flat = CellMesh(self.plane, [cm.cells[i] for i in keep],
                        cell_data=data, field_data=cm.field_data, source=cm.source)
        mesh = flat.to_triangle_mesh()
        assert isinstance(mesh, PlanarMesh)  # 2D points
        return mesh

    def file_mesh(self) -> TriangleMesh:
        """The triangle mesh in file coordinates (a PlanarMesh where z is dropped exactly)."""
        m = self.mesh
        pts = self.cells.points
        kw = m._tag_kwargs()
        if pts.shape[1] == 2 or not np.any(pts[:, 2]):
            return PlanarMesh(pts[:, :2], m.triangles, **kw)
        return TriangleMesh(pts, m.triangles, **kw)

    # -- out --------------------------------------------------------------------------
    def moved(self, points) -> "Workpiece":
        """The workpiece with the working mesh's vertices at ``points``.

        A vertex whose plane coordinates come back bit for bit keeps its file
        coordinates; the others are mapped into the plane.
        """
        q = new_points(points, self.plane.shape)
        moved = ~(q == self.plane).all(axis=1)
        plane = np.array(self.plane, copy=True)
        pts = np.array(self.cells.points, dtype=np.float64, copy=True)
        if moved.any():
            plane[moved] = q[moved]
            pts[moved] = self._to_file(plane[moved])
        new = replace(self, cells=replace(self.cells, points=pts), plane=plane)
        new.__dict__["mesh"] = self.mesh.with_points(q)
        return new

    def to_cells(self, *, cell_data: dict | None = None,
                 point_data: dict | None = None) -> CellMesh:
        """The file's cells at the current points, with ``cell_data`` (per triangle of
        :attr:`mesh`, ``(T, ...)``) and ``point_data`` (``(N, ...)``) added.

        Computed cell data goes to the triangle blocks; other blocks get NaN (float) or
        zeros. A name the file already holds is replaced (the operation changed it).
        """
        return cells_with_attributes(self.cells, cell_data or {}, point_data or {})

    def _to_file(self, plane: np.ndarray) -> np.ndarray:
        pts = self.cells.points
        if self.frame is not None:
            return self.frame.to_3d(plane)
        if pts.shape[1] == 2:
            return plane
        z = pts[0, 2] if len(pts) else 0.0
        return np.column_stack([plane, np.full(len(plane), z)])

    def plane_coordinates(self, points, source: str = "the mesh") -> np.ndarray:
        """Another file's ``points`` (same vertices) in this workpiece's plane, file scale.

        Rows equal to this workpiece's file points get its plane coordinates bit for bit.

        Raises
        ------
        InvalidMeshError
            A point is off the plane (beyond :data:`PLANE_RTOL`), or the shape differs.
        """
        p = np.asarray(points, dtype=np.float64)
        own = self.cells.points
        if p.ndim != 2 or len(p) != len(own):
            raise InvalidMeshError(f"{source}: {len(p)} vertices, the mesh has {len(own)} "
                                   "(the same vertices are needed)")
        if p.shape[1] != own.shape[1]:
            p = _pad(p, own.shape[1])
        same = (p == own).all(axis=1)
        out = np.array(self.plane, copy=True)
        rest = ~same
        if rest.any():
            q = p[rest]
            if self.frame is not None:
                out[rest] = self.frame.to_2d(q)
                off = np.abs((q - self.frame.origin) @ np.cross(*self.frame.basis))
            else:
                out[rest] = q[:, :2]
                off = np.abs(q[:, 2] - own[0, 2]) if q.shape[1] == 3 else np.zeros(len(q))
            size = float(np.ptp(np.vstack([own, q]), axis=0).max()) or 1.0
            if off.max() > PLANE_RTOL * size:
                raise InvalidMeshError(f"{source}: a vertex is off the plane of the mesh "
                                       f"({off.max() / size:.3g} × its size away)")
        return out

    def refined(self) -> "Workpiece":
        """Uniform refinement of every block (:meth:`PlanarMesh.refine`).

        Each triangle is split into four (its cell data copied to the children), each line
        element that is a mesh edge into two at the edge's midpoint (both halves keep its
        tags and cell data), vertex cells and field data are kept. Float point data is
        interpolated at the new midpoints; other point data cannot be, and is dropped with
        a warning naming it.
        """
        fine = self.mesh.refine()
        n = self.mesh.n_vertices
        plane = np.vstack([self.plane, fine.points[n:]])
        pts = np.vstack([self.cells.points, self._to_file(plane[n:])])
        return Workpiece(_refine_cells(self.cells, self.mesh, pts), plane, self.frame)


def _refine_cells(cm: CellMesh, mesh: PlanarMesh, points: np.ndarray) -> CellMesh:
    """The blocks and data of ``cm`` refined as ``mesh.refine()`` refines ``mesh``."""
    edges = mesh.edges
    n = mesh.n_vertices
    fine_tri = mesh.refine().triangles
    blocks, repeats, start = [], [], 0
    for t, c in cm.cells:
        if t == "triangle":
            blocks.append((t, fine_tri[4 * start:4 * (start + len(c))]))
            repeats.append(np.full(len(c), 4))
            start += len(c)
        elif t == "line" and len(c):
            idx = mesh.edge_ids(c)
            split = idx >= 0
            m = n + idx
            halves = np.stack([np.stack([c[:, 0], m], 1), np.stack([m, c[:, 1]], 1)], 1)
            counts = np.where(split, 2, 1)
            rows = np.where(split[:, None, None], halves, np.stack([c, c], 1))
            keep = np.repeat(np.arange(len(c)), counts) * 2 + _ranks(counts)
            blocks.append((t, rows.reshape(-1, 2)[keep]))
            repeats.append(counts)
            if not split.all():
                logger.warning("%s%d line elements are not mesh edges: kept unsplit",
                               f"{cm.source}: " if cm.source else "", int((~split).sum()))
        else:
            blocks.append((t, c))
            repeats.append(np.ones(len(c), np.int64))
    cell_data = {k: [np.repeat(np.asarray(a), r, axis=0) for a, r in zip(v, repeats)]
                 for k, v in cm.cell_data.items()}
    point_data = {}
    for k, a in cm.point_data.items():
        a = np.asarray(a)
        if np.issubdtype(a.dtype, np.inexact):
            point_data[k] = np.concatenate([a, 0.5 * (a[edges[:, 0]] + a[edges[:, 1]])])
        else:
            logger.warning("%spoint data %r (%s) cannot be interpolated at the new vertices of "
                           "the refinement: not kept", f"{cm.source}: " if cm.source else "",
                           k, a.dtype)
    return replace(cm, points=points, cells=blocks, cell_data=cell_data,
                   point_data=point_data)


def _ranks(counts: np.ndarray) -> np.ndarray:
    """0, 1, …, c−1 for each count c, concatenated."""
    total = int(counts.sum())
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    return np.arange(total) - starts


def _pad(p: np.ndarray, d: int) -> np.ndarray:
    if d == 3 and p.shape[1] == 2:
        return np.column_stack([p, np.zeros(len(p))])
    if d == 2 and p.shape[1] == 3 and not np.any(p[:, 2]):
        return p[:, :2]
    return p


def _plane_coordinates(cells: CellMesh) -> tuple[np.ndarray, PlaneEmbedding | None]:
    pts = np.asarray(cells.points, dtype=np.float64)
    where = f"{cells.source}: " if cells.source else ""
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise InvalidMeshError(f"{where}points must have 2 or 3 coordinates")
    if pts.shape[1] == 2 or len(pts) == 0 or (pts[:, 2] == pts[0, 2]).all():
        return np.array(pts[:, :2], copy=True), None
    tri = [c for t, c in cells.cells if t == "triangle"]
    if not tri:
        cells.to_triangle_mesh()  # raises: no triangles
    frame = plane_embedding(pts, np.concatenate(tri), cells.source)
    return frame.to_2d(pts), frame


def cells_with_attributes(cm: CellMesh, cell_data: dict, point_data: dict) -> CellMesh:
    """``cm`` with per-triangle ``cell_data`` spread over its blocks and ``point_data``
    added (replacing data of the same names)."""
    if not cell_data and not point_data:
        return cm
    sizes = [len(c) for _, c in cm.cells]
    is_tri = [t == "triangle" for t, _ in cm.cells]
    n_tri = sum(s for s, t in zip(sizes, is_tri) if t)
    cdata = {k: list(v) for k, v in cm.cell_data.items()}
    for name, values in cell_data.items():
        a = np.asarray(values)
        if len(a) != n_tri:
            raise InvalidMeshError(f"cell data {name!r} has {len(a)} rows for {n_tri} "
                                   "triangles")
        fill = np.nan if np.issubdtype(a.dtype, np.inexact) else 0
        blocks, start = [], 0
        for s, t in zip(sizes, is_tri):
            if t:
                blocks.append(a[start:start + s])
                start += s
            else:
                blocks.append(np.full((s,) + a.shape[1:], fill, dtype=a.dtype))
        cdata[str(name)] = blocks
    pdata = dict(cm.point_data)
    for name, values in point_data.items():
        a = np.asarray(values)
        if len(a) != len(cm.points):
            raise InvalidMeshError(f"point data {name!r} has {len(a)} rows for "
                                   f"{len(cm.points)} points")
        pdata[str(name)] = a
    return replace(cm, cell_data=cdata, point_data=pdata)


def save_workpiece(cells: CellMesh, path, *, computed: tuple[str, ...] = (),
                   overwrite: bool = True, **kwargs):
    """Write ``cells`` with :func:`~meshopt_toolkit.io.save_cells`; where the format
    cannot hold all of it, write less and say so in one warning line naming the file.

    First without the ``computed`` data names (what the operation added), then the
    triangle mesh alone (its points, triangles and, where the format has them, lines and
    physical tags). Only the format's refusal leads to a smaller try: a file that cannot
    be written at all (:class:`~meshopt_toolkit.errors.FileWriteError`: it exists, its
    folder is missing, the file system refused) is raised as it is, and so is the
    format's refusal when the cells are no triangle mesh (tetrahedra for a surface
    format).
    """
    from . import save_cells

    tries = [cells]
    if computed:
        tries.append(replace(
            cells, cell_data={k: v for k, v in cells.cell_data.items() if k not in computed},
            point_data={k: v for k, v in cells.point_data.items() if k not in computed}))
    first = None
    for k, cm in enumerate(tries):
        try:
            out = save_cells(cm, path, overwrite=overwrite, **kwargs)
        except FileWriteError:
            raise
        except WriteError as exc:
            first = first or exc
            continue
        if k:
            logger.warning("%s (written without them)", first)
        return out
    from . import save

    try:
        mesh = cells.to_triangle_mesh()
    except InvalidMeshError:  # other cells than triangles: the format's refusal says it
        raise first from None
    out = save(mesh, path, overwrite=overwrite, **kwargs)
    logger.warning("%s (only the triangle mesh was written)", first)
    return out
