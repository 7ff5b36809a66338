"""Per-triangle kernels shared by the terms: edges, areas, the ``Re(a·conj b)`` products,
the scatter to vertices, and the accumulator of an evaluation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray


SQRT3 = np.sqrt(3.0)
_I_SQRT3_2 = 0.5j * SQRT3  # p = z0 − (z1 + z2)/2 + (i√3/2)(z1 − z2), m with −i√3/2
_OMEGA = np.exp(2j * np.pi / 3 * np.arange(3))  # ω^k, k = 0, 1, 2


# ---------------------------------------------------------------------------------------
# evaluation state
# ---------------------------------------------------------------------------------------


@dataclass
class _Want:
    """What to compute in one pass (``value=False``: the caller ignores the value, which
    terms may then skip)."""

    gradient: bool = False
    hvp: bool = False
    curvature: bool = False
    value: bool = True


class _Accumulator:
    """Collects the term contributions of one evaluation."""

    def __init__(self, n: int, want: _Want) -> None:
        self.want = want
        self.values: dict[str, float] = {}
        self.grad = np.zeros((n, 2)) if want.gradient else None
        self.hvp = np.zeros((n, 2)) if want.hvp else None
        self.curvature = 0.0


def _edges(qx: FloatArray, qy: FloatArray, tri_t: IntArray) -> tuple[FloatArray, FloatArray]:
    """Edge vectors of triangles ``tri_t (3, b)`` at coordinates ``qx, qy (N,)``.

    Component-major ``(3, b)`` x and y arrays: row ``l`` is edge ``l``,
    ``e_l = q_{i(l+2)} − q_{i(l+1)}`` (opposite vertex ``l``).
    """
    x = np.take(qx, tri_t)
    y = np.take(qy, tri_t)
    ex = np.empty_like(x)
    ey = np.empty_like(y)
    for k, (a, b) in enumerate(((2, 1), (0, 2), (1, 0))):  # 3 local edges, not triangles
        np.subtract(x[a], x[b], out=ex[k])
        np.subtract(y[a], y[b], out=ey[k])
    return ex, ey


def _re_dot(a: np.ndarray, b: np.ndarray, scale: float = 1.0) -> FloatArray:
    """``scale · Re(a · conj b)`` elementwise for complex arrays (one temporary)."""
    out = a.real * b.real
    out += a.imag * b.imag
    if scale != 1.0:
        out *= scale
    return out


def _area(ex: FloatArray, ey: FloatArray) -> FloatArray:
    """Signed areas ``A = ½ det[e2, e0]`` (e2 = q1 − q0, e0 = q2 − q1), (4.2). ``(b,)``."""
    return 0.5 * (ex[2] * ey[0] - ey[2] * ex[0])


_NEXT = [1, 2, 0]
_PREV = [2, 0, 1]


def _to_vertices(phi_x, phi_y, psi_x, psi_y, out_x: FloatArray, out_y: FloatArray) -> None:
    """Write vertex vectors ``Φ_{m+1} − Φ_{m+2} + ½ R Ψ_m`` into ``out_x, out_y (3, b)``.

    ``Φ`` is an edge-space field (a derivative w.r.t. the edge vectors ``e_l``; vertex
    ``m`` is the head of edge ``m+1`` and the tail of edge ``m+2``), ``Ψ`` a field whose
    quarter-turn ``R(a, b) = (−b, a)`` enters as in ``∇_m A = ½ R e_m``. ``psi_x`` and
    ``psi_y`` are overwritten.
    """
    for m in range(3):  # the 3 local vertices
        np.subtract(phi_x[_NEXT[m]], phi_x[_PREV[m]], out=out_x[m])
        np.subtract(phi_y[_NEXT[m]], phi_y[_PREV[m]], out=out_y[m])
    psi_x *= 0.5
    psi_y *= 0.5
    out_x -= psi_y
    out_y += psi_x


