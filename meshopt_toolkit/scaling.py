"""Work at unit size: scale meshes down by their size on the way in, and back out.

Coordinates near ``1e300`` overflow in areas and quality measures, coordinates near
``1e-300`` underflow (every area is 0), and penalties that are not scale invariant (f1,
the β4 distance term of f2) behave differently in millimetres and in metres. Every
operation (``mt.move``, ``mt.morph``, ``mt.deform``, ``mt.optimize``) therefore runs
through :func:`at_unit_size`: the mesh and every length-valued input (targets, the other
end of a morph, a velocity; an objective is read at the user's scale) divided by the
mesh's own size ``R`` (:func:`size_scale`), the results multiplied by it again (only the
meshes and lengths: the numbers of a summary are those of the unit-size problem). The
results are *scale covariant*: for a mesh scaled by ``s`` the unit problems differ by
rounding only, so do the results, and for ``s`` a power of two they are the same numbers
scaled by ``s`` (a mesh of size 1 is not changed at all; a vertex an operation leaves
alone stays bitwise, :meth:`UnitScale.points_up`).

Only the operations scale: the commands and filters hand them the file's mesh at its own
scale, and their results are the library calls' bit for bit. Where a whole mesh is to be
measured at unit size without rounding (``meshopt info``, a filter's face quality),
:func:`unit_scale` gives a power of two ``2**k`` close to its size, exact in floating point
apart from subnormal numbers (of a planar mesh only x and y: z is never scaled).
The per-cell measures (mean ratios, aspect ratios, angles) go further: :func:`unit_cells`
scales each cell by a power of two of its own size, so they are the same numbers at every
scale.

The size is ``R``, half the largest side of the bounding box (1 for the unit disc); for
:func:`unit_scale` ``k = round(log2 R)``, at unit scale ``R`` lies in
``[2**-0.5, 2**0.5)``. Translation is left alone (every penalty and metric here is
translation invariant).

Examples
--------
>>> import numpy as np
>>> s = unit_scale(np.array([[0.0, 0.0], [3e300, 1e300]]))
>>> s.exponent, float(s.down([[3e300, 0.0]]).max()) < 4
(997, True)
>>> s.up(s.down([[3e300, 1e300]])).tolist()
[[3e+300, 1e+300]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._typing import FloatArray, IntArray
from .errors import InvalidMeshError

__all__ = ["UnitScale", "at_unit_size", "size_scale", "unit_cells", "unit_scale"]


@dataclass(frozen=True)
class UnitScale:
    """The factor ``factor = mantissa * 2**exponent`` between user and unit coordinates.

    ``user = factor * unit``; :meth:`down` goes to unit coordinates, :meth:`up` back.
    With ``mantissa = 1`` (:func:`unit_scale`) both are exact (``numpy.ldexp``), except
    for subnormal numbers; with another mantissa in ``(1, 2)`` (:func:`size_scale`) they
    are one rounding each, and exact for meshes that differ by a power of two.
    """

    exponent: int = 0
    mantissa: float = 1.0

    @property
    def factor(self) -> float:
        """``mantissa * 2**exponent`` (may be ``inf``/0 for extreme exponents; use up/down
        to scale)."""
        return float(np.ldexp(self.mantissa, self.exponent))

    @property
    def is_identity(self) -> bool:
        return self.exponent == 0 and self.mantissa == 1.0

    def describe(self) -> str:
        """``"2^-997 (about 1e-300)"``, for messages and summaries."""
        if self.mantissa != 1.0:
            return f"{self.mantissa!r}·2^{self.exponent} (about {self.factor:.3g})"
        return f"2^{self.exponent} (about {self.factor:.3g})"

    def down(self, values, power: int = 1) -> FloatArray:
        """User → unit coordinates: ``values / factor**power`` (``power=2`` for areas)."""
        with np.errstate(over="ignore", under="ignore"):
            out = np.ldexp(np.asarray(values, dtype=float), -power * self.exponent)
            return out if self.mantissa == 1.0 else out / self.mantissa**power

    def lengths_down(self, value):
        """:meth:`down` of a length-valued input of an operation, whatever its form: an
        array, a mesh (its points), a path ``t ↦ points`` or None (left as it is)."""
        if value is None:
            return None
        if hasattr(value, "points"):
            return _with_points(value, self.down(value.points))
        if callable(value):
            return lambda *args: self.down(value(*args))
        return self.down(value)

    def up(self, values, power: int = 1, what: str = "the result") -> FloatArray:
        """Unit → user coordinates: ``values * factor**power``.

        Raises
        ------
        InvalidMeshError
            A finite value becomes infinite: ``what`` leaves the floating-point range at
            this scale (the message names the scale).
        """
        a = np.asarray(values, dtype=float)
        with np.errstate(over="ignore", under="ignore"):
            m = a if self.mantissa == 1.0 else a * self.mantissa**power
            out = np.ldexp(m, power * self.exponent)
        if np.isinf(out).any() and not np.isinf(a[np.isinf(out)]).all():
            raise InvalidMeshError(
                f"{what} does not fit in floating point at the input's scale "
                f"{self.describe()}: some value exceeds {np.finfo(float).max:.3g}"
            )
        return out

    def points_up(self, points, rest) -> FloatArray:
        """:meth:`up` of unit-size ``points`` (one pose ``(N, d)`` or frames ``(K, N, d)``)
        of a mesh whose user-scale points are ``rest``: a coordinate still at its rest's
        unit value is the rest's own, bitwise (what an operation leaves alone stays)."""
        rest = np.asarray(rest, dtype=float)
        points = np.asarray(points, dtype=float)
        return np.where(points == self.down(rest), rest, self.up(points))

    def mesh_down(self, mesh):
        """The planar mesh at unit size, same connectivity and tags.

        Raises
        ------
        InvalidMeshError
            3D points off z = 0 (a plane is scaled in its own coordinates, see
            :mod:`meshopt_toolkit.io.workpiece`; z is never scaled).
        """
        return _with_points(mesh, self.down(_planar_points(mesh)))

    def mesh_up(self, mesh, what: str = "the result"):
        """The unit-size planar mesh back at the user's scale."""
        return _with_points(mesh, self.up(_planar_points(mesh), what=what))


def _planar_points(mesh):
    pts = np.asarray(mesh.points)
    if pts.shape[1] == 3 and np.any(pts[:, 2]):
        raise InvalidMeshError("unit scaling takes planar coordinates; a mesh off z = 0 is "
                               "scaled in its plane's coordinates (io.workpiece.Workpiece)")
    return pts


def _with_points(mesh, points):
    if hasattr(mesh, "with_points"):
        return mesh.with_points(points)
    return type(mesh)(points, mesh.triangles, **mesh._tag_kwargs())


def unit_scale(*point_sets, columns: int = 2) -> UnitScale:
    """The power-of-two :class:`UnitScale` of one or more point arrays ``(N, d)`` (or
    meshes) together: ``2**k`` nearest their size.

    Parameters
    ----------
    *point_sets : arrays of shape (N, 2) or (N, 3), or objects with ``.points``
        Every set is scaled by the same factor (e.g. the source and target of a morph, a
        mesh and its handle targets).
    columns : int
        How many leading columns set the size: 2 (x and y, a planar mesh whose z is never
        scaled) or 3 (a mesh in space).

    Returns
    -------
    UnitScale
        Exponent 0 when every set is empty, or all points coincide.

    Raises
    ------
    InvalidMeshError
        A coordinate is not finite.
    """
    extent = _extent(point_sets, columns)
    if extent == 0.0:
        return UnitScale(0)
    mantissa, exponent = np.frexp(extent)  # extent = mantissa * 2**exponent, 0.5 <= m < 1
    return UnitScale(int(exponent) if mantissa >= np.sqrt(0.5) else int(exponent) - 1)


def size_scale(*point_sets, columns: int = 2) -> UnitScale:
    """The :class:`UnitScale` whose factor is the size ``R`` of the point sets itself.

    What the operations work at: every mesh is divided by its own size, so a mesh and
    the same mesh scaled by any ``s`` give unit problems that differ by rounding only
    (exactly the same for ``s`` a power of two), and the operation's results differ by
    rounding too. A mesh of size 1 is left as it is. Parameters and errors as
    :func:`unit_scale`.
    """
    extent = _extent(point_sets, columns)
    if extent == 0.0:
        return UnitScale(0)
    mantissa, exponent = np.frexp(extent)
    return UnitScale(int(exponent) - 1, 2.0 * float(mantissa))  # mantissa in [1, 2)


def _extent(point_sets, columns: int) -> float:
    """Half the largest side of the point sets' common bounding box (0.0 for none)."""
    lo, hi = np.inf, -np.inf
    for pts in point_sets:
        pts = np.asarray(getattr(pts, "points", pts), dtype=float)
        if pts.size == 0:
            continue
        if not np.isfinite(pts).all():
            raise InvalidMeshError("a coordinate is not finite (nan or inf)")
        xy = pts.reshape(len(pts), -1)[:, :columns]
        lo = np.minimum(lo, xy.min(axis=0))
        hi = np.maximum(hi, xy.max(axis=0))
    if np.ndim(lo) == 0:
        return 0.0
    # half the largest side, without overflow (hi - lo may exceed the float range)
    return float(np.max(0.5 * hi - 0.5 * lo))


def at_unit_size(operation, scale: UnitScale, lengths, up):
    """An operation run at unit size and its result brought back: the one way every
    operation (``move``, ``morph``, ``deform``, ``optimize``) is made scale covariant.

    Parameters
    ----------
    operation : callable
        Called with the length-valued inputs ``lengths`` at unit size
        (:meth:`UnitScale.lengths_down`: meshes, point arrays, paths ``t ↦ points``).
    scale : UnitScale
        Usually :func:`size_scale` of the operation's mesh (and its other end).
    lengths : sequence
        The inputs that are lengths, in ``operation``'s order.
    up : callable ``(result, scale) -> result``
        The unit-size result at the user's scale (its meshes and every length in it).

    Returns
    -------
    The operation's result; ``operation(*lengths)`` itself when ``scale`` is 1.
    """
    if scale.is_identity:
        return operation(*lengths)
    return up(operation(*(scale.lengths_down(x) for x in lengths)), scale)


def unit_cells(vectors: FloatArray, axis: int = 0) -> tuple[FloatArray, IntArray]:
    """Each cell's vectors divided by a power of two of their own size, and its exponent.

    A per-cell measure that is a ratio of lengths, areas or volumes (a mean ratio, an
    aspect ratio, an angle) formed from the returned vectors is the same number at every
    scale, 1e±300 included: no square or cube of them overflows or underflows. A
    dimensional one (a volume) is scaled back by ``numpy.ldexp(value, power * exponent)``,
    exact in the floating-point range.

    Parameters
    ----------
    vectors : float array
        Edge vectors of cells, ``axis`` the cell axis (e.g. ``(3, M, 3)`` with ``axis=1``).
    axis : int

    Returns
    -------
    unit : float array, same shape
        ``vectors / 2**e`` per cell, the largest absolute component in ``[0.5, 1)``
        (cells all zero, or not finite, unscaled).
    exponents : (M,) int array
        ``e`` per cell.
    """
    v = np.asarray(vectors, dtype=float)
    cells = np.moveaxis(np.abs(v), axis, -1)  # a view (..., M)
    largest = np.zeros(cells.shape[-1])
    for index in np.ndindex(cells.shape[:-1]):  # one slice at a time: faster than max()
        np.maximum(largest, cells[index], out=largest)  # over several axes
    _, e = np.frexp(np.where(np.isfinite(largest), largest, 0.0))
    shape = [1] * v.ndim
    shape[axis] = len(e)
    if np.abs(e).max(initial=0) < 1000:  # 2**-e a normal number: one exact product
        return v * np.ldexp(1.0, -e).reshape(shape), e
    return np.ldexp(v, -e.reshape(shape)), e
