"""The C3 cut-off χ of the boundary-pair terms (remarks 5.2.10, 5.3.4)."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray

__all__ = ["cutoff"]


def _smoothstep7(t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """C3 smoothstep ``σ(t) = 35t⁴ − 84t⁵ + 70t⁶ − 20t⁷`` on [0, 1] (clamped outside).

    ``σ(0) = 0``, ``σ(1) = 1`` and ``σ', σ'', σ'''`` vanish at both ends. Returns
    ``(σ, σ', σ'')``.
    """
    t = np.clip(t, 0.0, 1.0)
    t2 = t * t
    t3 = t2 * t
    s = t3 * t * (35.0 + t * (-84.0 + t * (70.0 - 20.0 * t)))
    ds = t3 * (140.0 + t * (-420.0 + t * (420.0 - 140.0 * t)))
    d2s = t2 * (420.0 + t * (-1680.0 + t * (2100.0 - 840.0 * t)))
    return s, ds, d2s


def cutoff(s: FloatArray, s_lo: float, s_hi: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The C3 cut-off ``χ(s) = s σ((s − s_lo)/(s_hi − s_lo))`` and its derivatives.

    ``χ = 0`` for ``s ≤ s_lo`` and ``χ = s`` for ``s ≥ s_hi`` (remarks 5.2.10, 5.3.4);
    ``σ`` is the degree-7 smoothstep whose first three derivatives vanish at 0 and 1, so
    ``χ`` is C3 at both breakpoints (``χ'''`` involves σ', σ'', σ''' only, all zero
    there). For ``s ≥ 0``, ``0 ≤ χ(s) ≤ s`` and ``χ' ≥ 0``.

    Parameters
    ----------
    s : (K,) float array
    s_lo, s_hi : float, ``0 ≤ s_lo < s_hi``

    Returns
    -------
    (χ, χ', χ'') : three (K,) arrays
    """
    w = s_hi - s_lo
    sig, dsig, d2sig = _smoothstep7((s - s_lo) / w)
    chi = s * sig
    dchi = sig + s * dsig / w
    d2chi = 2.0 * dsig / w + s * d2sig / (w * w)
    return chi, dchi, d2chi


def _check_cutoff(cut) -> tuple[float, float] | None:
    if cut is None:
        return None
    try:
        lo, hi = (float(c) for c in cut)
    except (TypeError, ValueError):
        raise ValueError(f"cutoff must be a pair (s_lo, s_hi), got {cut!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo < hi):
        raise ValueError(f"cutoff needs 0 <= s_lo < s_hi, got ({lo}, {hi})")
    return lo, hi
