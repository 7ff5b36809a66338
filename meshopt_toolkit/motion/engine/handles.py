"""Handles and targets of a mesh in space as the 3D solvers take them: the checks, each
handle once, and the vertices a solver sees (those in some cell; a file may hold others)."""

from __future__ import annotations

import numpy as np

from ..._typing import FloatArray, IntArray
from ...cells.registry import cells_of
from ...errors import InvalidMeshError, SelfIntersectionError
from ...kernels.admissibility import first_non_finite_row
from ...kernels.intersections3d import self_intersections


def check_handle_indices(handles, n_vertices: int) -> IntArray:
    """``handles`` as an int64 array after the checks: a non-empty 1-D integer array of
    vertex indices in range.

    Raises
    ------
    InvalidMeshError
        One line naming the first bad entry by its position ``k`` in ``handles``
        (``handles[k] = 200 is out of range ...``).
    """
    h = np.asarray(handles)
    if h.ndim != 1 or h.size == 0 or not np.issubdtype(h.dtype, np.integer):
        raise InvalidMeshError("handles must be a non-empty 1-D array of vertex indices")
    bad = np.flatnonzero((h < 0) | (h >= n_vertices))
    if bad.size:
        raise InvalidMeshError(f"handles[{bad[0]}] = {h[bad[0]]} is out of range (the mesh "
                               f"has {n_vertices} vertices, 0 to {n_vertices - 1})")
    return h.astype(np.int64)


def check_handles(handles, targets, n_vertices: int,
                  dim: int = 3) -> tuple[IntArray, FloatArray]:
    """``(handles, targets)`` as arrays after the shape checks: the handles as
    :func:`check_handle_indices` takes them, and finite targets ``(k, dim)``.

    Raises
    ------
    InvalidMeshError
        One line naming what is wrong: the first bad entry by its position ``k`` in
        ``handles`` (``handles[k] = 200 is out of range ...``), its vertex and target.
    """
    h = check_handle_indices(handles, n_vertices)
    tg = np.asarray(targets, dtype=float)
    if tg.shape != (h.size, dim):
        raise InvalidMeshError(f"targets must have shape ({h.size}, {dim}), got {tg.shape}")
    if (k := first_non_finite_row(tg)) is not None:
        raise InvalidMeshError(f"targets[{k}] (of vertex {h[k]}) is not finite: "
                               f"{tg[k].tolist()}")
    return h, tg


def distinct_handles(handles: IntArray, targets: FloatArray) -> tuple[IntArray, FloatArray]:
    """Each handle once, in increasing order, with its (first) target.

    Raises
    ------
    InvalidMeshError
        A vertex is a handle twice with different targets (the vertex named).
    """
    order = np.argsort(handles, kind="stable")
    hs, ts = handles[order], targets[order]
    same = hs[1:] == hs[:-1]
    clash = np.flatnonzero(same & np.any(ts[1:] != ts[:-1], axis=1))
    if clash.size:
        raise InvalidMeshError(f"vertex {hs[clash[0]]} is a handle twice with different "
                               "targets")
    keep = np.concatenate([[True], ~same])
    return hs[keep], ts[keep]


class SolvedVertices:
    """The vertices that lie in some cell, renumbered for a solver, which sees only them;
    the others stay where they are, or go to their targets where they are handles.

    Attributes
    ----------
    points : (n, 3) the solved vertices' points
    cells : (M, k) the cells in the solved numbering
    handles, targets : the handles among the solved vertices (solved numbering), targets
    """

    def __init__(self, points: FloatArray, cells: IntArray, handles: IntArray,
                 targets: FloatArray) -> None:
        self._all = np.asarray(points, dtype=float)
        self._used = np.unique(cells)
        local = np.full(len(self._all), -1, np.int64)
        local[self._used] = np.arange(len(self._used))
        keep = local[handles] >= 0
        self.points = self._all[self._used]
        self.cells = local[cells]
        self.handles, self.targets = local[handles[keep]], targets[keep]
        self._loose = handles[~keep], targets[~keep]

    def full(self, Q: FloatArray) -> FloatArray:
        """All the mesh's points: ``Q`` at the solved vertices, the rest as described."""
        out = np.array(self._all)
        out[self._used] = Q
        out[self._loose[0]] = self._loose[1]
        return out


#: MeshLab's vertex flag bit of a selected vertex (VCG's ``SELECTED``): a ``.ply`` saved
#: by pymeshlab with ``save_vertex_flag=True`` holds it in the integer property ``flags``
MESHLAB_SELECTED_BIT = 32


def selected_vertices(point_data: dict, name: str, *, option: str = "--selection",
                      source: str | None = None) -> IntArray:
    """The vertices whose point datum ``name`` is nonzero (any nonzero component of a
    vector datum); for MeshLab's integer ``flags``, those with the selection bit
    :data:`MESHLAB_SELECTED_BIT`.

    Parameters
    ----------
    point_data : dict of str to (N,) or (N, k) array
        A file's point data (a ``.ply``'s vertex properties, a ``.msh``'s or ``.vtu``'s
        point data) or a pipeline's vertex attributes.
    name : str
        The datum.
    option, source : str
        For the messages: the option or parameter, the file.

    Raises
    ------
    InvalidMeshError
        No such datum (the message lists those there are), a non-numeric one, or no
        vertex selected.
    """
    where = f"{source} has " if source else "the mesh has "
    if name not in point_data:
        names = ", ".join(sorted(map(str, point_data))) or "none"
        raise InvalidMeshError(f"{option} {name!r}: {where}no such point data; point data: "
                               f"{names}")
    values = np.asarray(point_data[name])
    if values.dtype.kind not in "biuf":
        raise InvalidMeshError(f"{option} {name!r}: not numbers ({values.dtype})")
    values = values.reshape(len(values), -1)
    if name == "flags" and values.dtype.kind in "iu" and values.shape[1] == 1:
        chosen = (values[:, 0] & MESHLAB_SELECTED_BIT) != 0
    else:
        chosen = np.any(values != 0, axis=1)
    if not chosen.any():
        raise InvalidMeshError(f"{option} {name!r}: no vertex is selected (all zero)")
    return np.flatnonzero(chosen).astype(np.int64)


def handles_in_space(mesh, *, targets=None, mapping: str | None = None,
                     where: str | None = None, group: str | None = None,
                     selection: str | None = None, point_data: dict | None = None,
                     free_boundary: bool = False, source: str | None = None,
                     options: dict | None = None) -> tuple[IntArray, FloatArray]:
    """Handles and targets of a move, as ``meshopt move`` and the move filter choose them
    (for a tet mesh, a surface in 3D or a planar mesh alike).

    ``targets`` (a table, :func:`~.targets.read_target_table`) or ``mapping`` (with
    ``where``) on the candidates: a physical group's nodes (``group``), the vertices
    selected in the point datum ``selection`` (:func:`selected_vertices`), or by default
    the boundary vertices (a surface: all its vertices); see
    :func:`~.targets.targets_from_map` for which vertices stay.

    Parameters
    ----------
    mesh : TetMesh, SurfaceMesh or PlanarMesh
        In the units of the table and the expressions.
    point_data : dict, optional
        Where ``selection`` is looked up (the file's point data, the pipeline's vertex
        attributes).
    options : dict, optional
        How the messages name ``group``/``selection``/``map``/``targets``
        (default: the command line's ``--group`` …; a filter gives its parameter names).

    Raises
    ------
    OptionError
        Not exactly one of ``targets`` and ``mapping``; ``where``, ``group`` or
        ``selection`` without ``mapping``; both ``group`` and ``selection``.
    InvalidMeshError, ExpressionError, ReadError
        As the functions named.
    """
    from ...errors import OptionError
    from .targets import group_vertices, handles_of, targets_from_map

    opt = {"group": "--group", "selection": "--selection", "map": "--map",
           "targets": "--targets", "where": "--where", **(options or {})}
    if (targets is None) == (mapping is None):
        raise OptionError(f"give exactly one of {opt['targets']} and {opt['map']}")
    for key, given in (("where", where), ("group", group), ("selection", selection)):
        if given is not None and mapping is None:
            raise OptionError(f"{opt[key]} needs {opt['map']}")
    if group is not None and selection is not None:
        raise OptionError(f"give one of {opt['group']} and {opt['selection']}")
    if selection is None:
        if group is not None:
            vertices = group_vertices(mesh, group, opt["group"])
            return targets_from_map(mesh, mapping, where, vertices=vertices)
        return handles_of(mesh, targets=targets, mapping=mapping, where=where,
                          free_boundary=free_boundary)
    vertices = selected_vertices(point_data or {}, selection, option=opt["selection"],
                                 source=source or getattr(mesh, "source", None))
    return targets_from_map(mesh, mapping, where, vertices=vertices)


def _points(mesh) -> FloatArray:
    """The points of a mesh in space (:func:`..cells.registry.cells_of`)."""
    return cells_of(mesh, "move")[1]


class SelfIntersectionGuard:
    """The embedding checks of a motion in space: a tet mesh's boundary and a surface
    must not pass through themselves (exact, :mod:`~..kernels.intersections3d`).

    Made before the solve, it refuses a tet mesh whose boundary already intersects
    itself, and targets that fix two intersecting triangles (every vertex of both a
    handle); :meth:`check` refuses a motion with a frame that intersects itself. A surface
    that intersects itself before the motion is not checked at all. A morph's guard is
    :meth:`of_morph`.

    Raises
    ------
    SelfIntersectionError
        One line: how many pairs, and one pair by its vertices.
    """

    def __init__(self, mesh, handles, targets) -> None:
        points = self._start(mesh)
        if not self.active:
            return  # the solver names what is wrong (inverted tets: a boundary of no use)
        if found := self._pairs(points, self.triangles):
            if self.what == "the surface":
                self.active = False  # not ours to keep
                return
            raise SelfIntersectionError(f"{self.what} intersects itself: {found}")
        h, tg = distinct_handles(*check_handles(handles, targets, len(points)))
        if not np.isfinite(tg).all():
            return
        fixed = self.triangles[np.isin(self.triangles, h).all(axis=1)]
        moved = np.array(points)
        moved[h] = tg
        if found := self._pairs(moved, fixed):
            raise SelfIntersectionError(
                f"the targets make {self.what} intersect itself: {found}")

    def _start(self, mesh) -> FloatArray:
        """Set the triangles, their name and whether to check; ``mesh``'s points."""
        kind, points, cells = cells_of(mesh, "move")
        solid = kind.cell_dimension == 3  # a tet mesh: its boundary faces must not meet
        finite = bool(np.isfinite(points).all())
        self.triangles = cells
        if solid:
            self.triangles = (kind.boundary_facets(points, cells) if finite
                              else np.zeros((0, 3), np.int64))
        self.what = "the boundary" if solid else "the surface"
        self.active = (finite and len(self.triangles) > 1
                       and getattr(mesh, "is_admissible", True))
        return points

    @classmethod
    def of_morph(cls, source, target) -> SelfIntersectionGuard:
        """The guard of a morph from ``source`` to ``target`` (the same triangles): it
        refuses a tet mesh end whose boundary intersects itself, naming the end; a surface
        morph with an end that intersects itself is not checked (as a move's source).

        Raises
        ------
        SelfIntersectionError
            ``"<end>: the boundary intersects itself: …"``, the end by its file or as
            "the morph's source"/"the morph's target".
        """
        guard = cls.__new__(cls)
        guard._start(source)
        for name, mesh in (("source", source), ("target", target)):
            points = _points(mesh)
            if not guard.active or not np.isfinite(points).all():
                guard.active = False
                return guard
            if found := cls._pairs(points, guard.triangles):
                if guard.what == "the surface":
                    guard.active = False  # not ours to keep
                    return guard
                end = getattr(mesh, "source", None) or f"the morph's {name}"
                raise SelfIntersectionError(f"{end}: {guard.what} intersects itself: {found}")
        return guard

    @staticmethod
    def _pairs(points: FloatArray, triangles: IntArray) -> str:
        """``""`` or the intersecting pairs of ``triangles`` in words."""
        pairs = self_intersections(points, triangles) if len(triangles) > 1 else []
        if not len(pairs):
            return ""
        a, b = (tuple(int(v) for v in triangles[i]) for i in pairs[0])
        return (f"{len(pairs)} pair{'s' if len(pairs) > 1 else ''} of triangles "
                f"(e.g. on vertices {a} and {b})")

    def check(self, frames, *, motion: str = "the motion", last: bool = True) -> None:
        """Refuse the motion if a frame after the first intersects itself.

        Parameters
        ----------
        frames : sequence of meshes or of (N, 3) point arrays
            The first is not checked.
        motion : str
            How the message names the motion ("the motion", "the morph").
        last : bool
            Check the last frame too (False: a morph's target, checked already).
        """
        if not self.active:
            return
        stop = len(frames) if last else len(frames) - 1
        for k in range(1, stop):
            frame = frames[k]
            points = (np.asarray(frame, float) if isinstance(frame, np.ndarray)
                      else _points(frame))
            if found := self._pairs(points, self.triangles):
                where = "the result" if k == len(frames) - 1 else f"frame {k}"
                raise SelfIntersectionError(
                    f"{motion} makes {self.what} intersect itself at {where}: {found}")
