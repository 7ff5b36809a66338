"""Vertex–edge distance ``D`` (4.13), its C2 regularization ``D^μ`` (appendix B) with exact
first and second derivatives. The boundary (vertex, edge) pairs, their search and the edge
frame live in :mod:`.pairs` (its public names are re-exported here).

Frame and notation
------------------
A *pair* is a row ``[i0, j0, j1]``: boundary vertex ``p = q_i0`` and boundary edge
``[a, b] = [q_j0, q_j1]``. In the edge-aligned frame (origin ``a``, unit tangent
``t = (b − a)/L``, ``L = |b − a|``, normal ``n = J t``, ``J`` the rotation by +90°)

    x̃ = (p − a)·t,        ỹ = (p − a)·n,

and (4.13, B.1)

    D   = g(x̃; [0, L]) + |ỹ|,
    D^μ = g_μ(−x̃) + g_μ(x̃ − L) + h_μ(ỹ)                                      (B.3)

where ``g_μ(d) = 0`` for ``d ≤ 0`` and, with ``u = μ d``, ``μ g_μ = 32u⁶ − 48u⁵ + 20u⁴`` for
``0 ≤ u ≤ ½``, ``μ g_μ = u − ¼`` for ``u ≥ ½`` (B.4); with ``u = μ|x|``,
``μ h_μ = 40u⁶ − 64u⁵ + 32u⁴ − 4u³ + u²/2`` for ``u ≤ ½`` and ``u − ¼`` beyond (B.5).
At most one of ``−x̃``, ``x̃ − L`` is positive (their sum is ``−L``), so the sum of the two
``g_μ`` terms is exactly the two-sided ``g_μ(x̃; [0, L])`` of (B.4).

Remarks on appendix B
---------------------
- The thesis prints the right branch of (B.4) as ``32μ⁵d⁶ + 48μ⁴d⁵ + 20μ³d⁴``; with the
  ``+`` it is neither continuous nor C1 at ``d = 1/(2μ)``. The left branch's ``−48`` (used
  here on both sides, as in SPEC §2) makes ``g_μ`` C3: value, first, second and third
  derivatives match at ``d = 0`` and ``d = 1/(2μ)`` (checked in the tests).
- ``h_μ`` is C2 with a Lipschitz second derivative, *not* C3 as the thesis claims: the
  ``−4μ²|x|³`` term gives ``h_μ'''(0±) = ∓24μ²``. At ``|x| = 1/(2μ)`` it is C3. C2 is what
  the geodesic equation needs (it uses ``∇²f``), and the Hessian is continuous everywhere.
- (B.3) writes ``h_μ(q̃²_i0 − q̃²_j1)``; in the rotated frame ``q̃²_j0 = q̃²_j1``, so it is
  ``h_μ(ỹ)`` either way.
- Both pieces are convex: ``g_μ'' = 240μu²(2u − 1)² ≥ 0`` and
  ``h_μ'' = μ(2u − 1)²(300u² − 20u + 1) > 0`` on the polynomial zones.
- Scaling: ``g_μ(d) = g_1(μd)/μ`` and ``h_μ(x) = h_1(μx)/μ``, so every property
  (``0 ≤ D^μ ≤ D``, ``D − D^μ ≤ 1/(2μ)``) holds for any ``μ > 0``; the thesis restricts to
  ``μ ≥ 1``. ``μ`` has units of 1/length: the smoothing zone has width ``1/(2μ)``.
- Default ``μ = 1``: the only value the thesis uses (figures B.1, B.5). Its experiments
  switch the boundary-pair term off (``α2``/``β3`` cut off or 0) and never state another.

Degenerate input
----------------
A zero-length edge (``L = 0``) has no frame: every function taking ``pairs`` raises
:class:`~meshopt_toolkit.errors.NotAdmissibleError` naming the edge instead of returning
NaN. (Admissible meshes never have one.) A vertex coinciding with an edge point is fine:
``D = D^μ = 0`` there, with finite (zero-normal-slope) derivatives; a caller dividing by
``D^μ`` must guard against that itself.

Derivatives
-----------
With ``v = (v_p, v_a, v_b)``, ``v_w = v_p − v_a``, ``v_e = v_b − v_a``, ``σ = n·v_e/L``,
``ρ = t·v_e/L``: ``δt = σn``, ``δn = −σt``, ``δL = Lρ``, ``δx̃ = v_w·t + ỹσ``,
``δỹ = v_w·n − x̃σ``, ``∇x̃ = (t, −t − (ỹ/L)n, (ỹ/L)n)``, ``∇ỹ = (n, −(1 − x̃/L)n,
−(x̃/L)n)``, ``∇L = (0, −t, t)``. The Hessian-vector product differentiates these gradients
along ``v``; it is computed in (t, n) components per pair, never as a 6×6 matrix. The
``a``-block is minus the sum of the ``p``- and ``b``-blocks (translation invariance).

Implementation
--------------
Points are gathered as complex numbers ``x + iy`` (one 16-byte load per vertex, and the
``(K, 3, 2)`` outputs are filled through ``(K, 3)`` complex views), all arithmetic is real in
(t, n) components, the piecewise pieces are evaluated without branches, and pairs are
processed in cache-sized blocks of ``_BLOCK`` pairs; no Python code runs per pair. Non-finite input propagates (NaN in, NaN out), except a
NaN edge length, which is reported like a zero one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray
from .pairs import (  # noqa: F401 (the pairs' public names are re-exported here)
    _as_complex,
    _blocks,
    _frame,
    _inputs,
    _map_blocks,
    boundary_pairs,
    iter_boundary_pairs,
    segment_distance,
    vertex_edge_distance,
)

__all__ = [
    "DEFAULT_MU",
    "DistanceEval",
    "boundary_pairs",
    "g_mu",
    "h_mu",
    "iter_boundary_pairs",
    "regularized_distance",
    "regularized_distance_value",
    "segment_distance",
    "vertex_edge_distance",
]

DEFAULT_MU: float = 1.0
"""Default regularization parameter (thesis figures B.1, B.5; see module docstring)."""


# --------------------------------------------------------------------------- 1D pieces


def _check_mu(mu: float) -> float:
    mu = float(mu)
    if not (np.isfinite(mu) and mu > 0):
        raise ValueError(f"mu must be a positive number, got {mu}")
    return mu


def g_mu(d: FloatArray, mu: float = DEFAULT_MU, nderiv: int = 0) -> FloatArray:
    """One-sided regularized distance ``g_μ(d)`` (B.4) and its derivatives in ``d``.

    ``0`` for ``d ≤ 0``; ``32μ⁵d⁶ − 48μ⁴d⁵ + 20μ³d⁴`` for ``0 ≤ d ≤ 1/(2μ)``;
    ``d − 1/(4μ)`` beyond. C3 everywhere.

    Parameters
    ----------
    d : (...) float, signed distance outside the interval (``−x̃`` or ``x̃ − L``)
    mu : μ > 0
    nderiv : 0, 1, 2 or 3 — which derivative to return

    Returns
    -------
    (...) float
    """
    mu = _check_mu(mu)
    u = np.clip(np.asarray(d, dtype=float) * mu, 0.0, None)
    poly = u <= 0.5
    if nderiv == 0:
        return np.where(poly, u**4 * ((32 * u - 48) * u + 20), u - 0.25) / mu
    if nderiv == 1:
        return np.where(poly, 16 * u**3 * ((12 * u - 15) * u + 5), 1.0)
    if nderiv == 2:
        return np.where(poly, 240 * mu * u * u * (2 * u - 1) ** 2, 0.0)
    if nderiv == 3:
        return np.where(poly, 480 * mu * mu * u * (2 * u - 1) * (4 * u - 1), 0.0)
    raise ValueError(f"nderiv must be 0..3, got {nderiv}")


def h_mu(x: FloatArray, mu: float = DEFAULT_MU, nderiv: int = 0) -> FloatArray:
    """Regularized absolute value ``h_μ(x)`` (B.5) and its derivatives.

    ``|x| − 1/(4μ)`` for ``|x| ≥ 1/(2μ)``, else
    ``40μ⁵|x|⁶ − 64μ⁴|x|⁵ + 32μ³|x|⁴ − 4μ²|x|³ + (μ/2)x²``. C2 everywhere, C3 except at
    ``x = 0`` where the third derivative jumps from ``+24μ²`` to ``−24μ²``.

    Parameters
    ----------
    x : (...) float
    mu : μ > 0
    nderiv : 0, 1, 2 or 3 (the third derivative at exactly 0 is returned as 0)

    Returns
    -------
    (...) float
    """
    mu = _check_mu(mu)
    x = np.asarray(x, dtype=float)
    u = np.abs(x) * mu
    s = np.sign(x)
    poly = u < 0.5
    if nderiv == 0:
        p = u * u * ((((40 * u - 64) * u + 32) * u - 4) * u + 0.5)
        return np.where(poly, p, u - 0.25) / mu
    if nderiv == 1:
        p = u * ((((240 * u - 320) * u + 128) * u - 12) * u + 1)
        return s * np.where(poly, p, 1.0)
    if nderiv == 2:
        return np.where(poly, mu * (2 * u - 1) ** 2 * ((300 * u - 20) * u + 1), 0.0)
    if nderiv == 3:
        p = 24 * mu * mu * (((200 * u - 160) * u + 32) * u - 1)
        return s * np.where(poly, p, 0.0)
    raise ValueError(f"nderiv must be 0..3, got {nderiv}")


# The fast pieces avoid branches: the polynomials meet the linear parts at u = ½ with value
# ¼, slope 1 and curvature 0, all exact in binary floating point, so evaluating them at
# min(u, ½) and adding max(u − ½, 0) to the value gives both zones.


def _g_value(d: FloatArray, mu: float) -> FloatArray:
    u = d * mu
    uc = np.clip(u, 0.0, 0.5)
    u2 = uc * uc
    return (u2 * u2 * ((32 * uc - 48) * uc + 20) + np.maximum(u - 0.5, 0.0)) / mu


def _h_value(x: FloatArray, mu: float) -> FloatArray:
    u = np.abs(x) * mu
    uc = np.minimum(u, 0.5)
    return (
        uc * uc * ((((40 * uc - 64) * uc + 32) * uc - 4) * uc + 0.5) + np.maximum(u - 0.5, 0.0)
    ) / mu


def _g_parts(d: FloatArray, mu: float):
    """``g_μ, g_μ', g_μ''`` at once (d may be any sign)."""
    u = d * mu
    uc = np.clip(u, 0.0, 0.5)
    u2 = uc * uc
    v0 = (u2 * u2 * ((32 * uc - 48) * uc + 20) + np.maximum(u - 0.5, 0.0)) / mu
    v1 = 16 * u2 * uc * ((12 * uc - 15) * uc + 5)
    w = 2 * uc - 1
    v2 = (240 * mu) * u2 * (w * w)
    return v0, v1, v2


def _h_parts(x: FloatArray, mu: float):
    """``h_μ, h_μ', h_μ''`` at once."""
    u = np.abs(x) * mu
    uc = np.minimum(u, 0.5)
    v0 = (
        uc * uc * ((((40 * uc - 64) * uc + 32) * uc - 4) * uc + 0.5) + np.maximum(u - 0.5, 0.0)
    ) / mu
    v1 = np.copysign(uc * ((((240 * uc - 320) * uc + 128) * uc - 12) * uc + 1), x)
    w = 2 * uc - 1
    v2 = mu * (w * w) * ((300 * uc - 20) * uc + 1)
    return v0, v1, v2


# --------------------------------------------------------------------------- D^μ


@dataclass(frozen=True)
class DistanceEval:
    """Regularized distances and their derivatives for ``K`` pairs.

    Attributes
    ----------
    value : (K,) ``D^μ``
    gradient : (K, 3, 2) ``∂D^μ/∂(q_i0, q_j0, q_j1)``
    hess_dir : (K, 3, 2) or None, ``∇²D^μ · v_k`` with ``v_k = direction[pairs[k]]``
    curvature : (K,) or None, ``v_k · ∇²D^μ v_k``
    """

    value: FloatArray
    gradient: FloatArray
    hess_dir: FloatArray | None = None
    curvature: FloatArray | None = None


def regularized_distance_value(
    points: FloatArray, pairs: IntArray, mu: float = DEFAULT_MU
) -> FloatArray:
    """``D^μ`` (B.3) only, shape ``(K,)``; see :func:`regularized_distance`."""
    mu = _check_mu(mu)

    def kernel(L, xt, yt):
        d = np.maximum(-xt, xt - L)
        return _g_value(d, mu) + _h_value(yt, mu)

    return _map_blocks(kernel, points, pairs)


def regularized_distance(
    points: FloatArray,
    pairs: IntArray,
    mu: float = DEFAULT_MU,
    direction: FloatArray | None = None,
) -> DistanceEval:
    """Regularized vertex–edge distance ``D^μ`` (B.3) with exact derivatives.

    Parameters
    ----------
    points : (N, 2) float, node positions ``Q``
    pairs : (K, 3) int rows ``[i0, j0, j1]``
    mu : regularization parameter μ > 0 (thesis: μ ≥ 1); smoothing width ``1/(2μ)``
    direction : (N, 2) float or None; when given, also the Hessian-vector products
        ``∇²D^μ v_k`` and curvatures ``v_k·∇²D^μ v_k`` with ``v_k = direction[pairs[k]]``

    Returns
    -------
    DistanceEval
        ``value (K,)``, ``gradient (K, 3, 2)`` w.r.t. ``(q_i0, q_j0, q_j1)``, and
        ``hess_dir (K, 3, 2)``, ``curvature (K,)`` when ``direction`` is given.

    Raises
    ------
    NotAdmissibleError
        if an edge of ``pairs`` has zero length.
    """
    mu = _check_mu(mu)
    Z, pairs = _inputs(points, pairs)
    K = pairs.shape[0]
    value = np.empty(K)
    grad = np.empty((K, 3, 2))
    gz = grad.view(np.complex128)[..., 0]  # (K, 3) complex view: x + iy per vertex
    if direction is None:
        for blk in _blocks(K):
            _kernel(Z, pairs[blk], mu, None, value[blk], gz[blk], None, None)
        return DistanceEval(value, grad)
    V = np.asarray(direction, dtype=float)
    if V.shape != (Z.size, 2):
        raise ValueError(f"direction must have shape {(Z.size, 2)}, got {V.shape}")
    VZ = _as_complex(V)
    hv = np.empty((K, 3, 2))
    hz = hv.view(np.complex128)[..., 0]
    curv = np.empty(K)
    for blk in _blocks(K):
        _kernel(Z, pairs[blk], mu, VZ, value[blk], gz[blk], hz[blk], curv[blk])
    return DistanceEval(value, grad, hv, curv)


def _kernel(Z, pairs, mu, VZ, value, grad, hv, curv) -> None:
    """Evaluate one block of pairs into the given output views (see module docstring).

    ``grad`` and ``hv`` are ``(k, 3)`` complex views (``x + iy`` per vertex); quantities are
    real arrays in edge-frame components, written out by :func:`_put`.
    """
    tx, ty, L, xt, yt = _frame(Z, pairs)
    # d = max(−x̃, x̃ − L): the side that can be positive; s = ∂d/∂x̃, r = 1 on the right.
    # (At x̃ = L/2 either choice is fine: d = −L/2 < 0 and g' = g'' = 0.)
    d = np.maximum(-xt, xt - L)
    s = np.copysign(1.0, xt - 0.5 * L)
    r = 0.5 * s + 0.5
    g0, g1, g2 = _g_parts(d, mu)
    h0, h1, h2 = _h_parts(yt, mu)
    np.add(g0, h0, out=value)
    inv_L = 1.0 / L
    c = yt * inv_L
    m = xt * inv_L

    # gradient: ∇_p = (g's) t + h' n ;  ∇_b = (−g'r) t + (g's c − h'm) n ;  ∇_a = −∇_p − ∇_b
    g1s = g1 * s
    bt = -g1 * r
    bn = g1s * c - h1 * m
    _put(grad[:, 0], g1s, h1, tx, ty)
    _put(grad[:, 2], bt, bn, tx, ty)
    _put(grad[:, 1], -(g1s + bt), -(h1 + bn), tx, ty)
    if VZ is None:
        return

    # direction in the edge frame: v_w = v_p − v_a, v_e = v_b − v_a
    va = VZ[pairs[:, 1]]
    vw = VZ[pairs[:, 0]] - va
    ve = VZ[pairs[:, 2]] - va
    vwx, vwy, vex, vey = vw.real, vw.imag, ve.real, ve.imag
    vw_t = vwx * tx + vwy * ty
    vw_n = vwy * tx - vwx * ty
    ve_t = vex * tx + vey * ty
    ve_n = vey * tx - vex * ty
    sigma = ve_n * inv_L
    rho = ve_t * inv_L
    dxt = vw_t + yt * sigma
    dyt = vw_n - xt * sigma
    g2dd = g2 * (s * dxt - r * ve_t)  # g'' δd
    h2dy = h2 * dyt
    dc = (dyt - yt * rho) * inv_L
    dm = (dxt - xt * rho) * inv_L

    # Hessian·v in (t, n) components for the p- and b-blocks
    ap = g2dd * s - h1 * sigma
    bp = g1s * sigma + h2dy
    ab = -g2dd * r + (m * h1 - c * g1s) * sigma
    bb = g2dd * s * c + g1 * (s * dc - r * sigma) - h2dy * m - h1 * dm
    _put(hv[:, 0], ap, bp, tx, ty)
    _put(hv[:, 2], ab, bb, tx, ty)
    _put(hv[:, 1], -(ap + ab), -(bp + bb), tx, ty)
    curv[:] = vw_t * ap + vw_n * bp + ve_t * ab + ve_n * bb


def _put(
    out: np.ndarray, alpha: FloatArray, beta: FloatArray, tx: FloatArray, ty: FloatArray
) -> None:
    """``out = α t + β n`` for complex ``out`` (a strided view), ``t = tx + i ty``, ``n = i t``."""
    np.subtract(alpha * tx, beta * ty, out=out.real)
    np.add(alpha * ty, beta * tx, out=out.imag)
