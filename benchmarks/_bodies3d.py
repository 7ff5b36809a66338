"""Bodies of revolution with the ends of Pironneau's optimum, for ``bench_shape3d.py``.

Among bodies of a given volume in unbounded Stokes flow, the one of least drag has a
constant vorticity on its surface and conical ends of 120° (a half-angle of 60° with the
axis; Pironneau, *J. Fluid Mech.* 59 (1973) 117–128); Bourot (*J. Fluid Mech.* 65, 1974)
computed its profile, drag about 0.954 of the sphere's of the same volume. The
profile itself is not tabulated here. The anchor is instead the family

    r(x) = (1 − u²)(c₀ + c₁ u² + c₂ u⁴),   u = x / h,   −h ≤ x ≤ h,

whose tips are exact cones of half-angle 60° (``r'(∓h) = ±√3``, i.e. ``c₀ + c₁ + c₂ =
√3 h/2``) and whose volume, ``π h Σ c_i c_j 16/((2m+1)(2m+3)(2m+5))`` with ``m = i + j``,
is the sphere's: two free parameters, the length over the largest width and the share of
``c₂`` (0: a quartic), scanned by the benchmark for the least drag. The profile, a
polynomial in ``u``, is an exact Bézier curve: gmsh revolves it about the ``x`` axis
without approximation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.polynomial import Polynomial
from scipy.optimize import brentq

from meshopt_toolkit.shape.cases import solid_in_box

TIP_HALF_ANGLE = 60.0  # degrees, Pironneau's ends


@dataclass(frozen=True)
class ConicalProfile:
    """``r(x) = (1 − u²) Σ_j c_j u^{2j}``, ``u = x / half_length``."""

    half_length: float
    c: tuple[float, ...]

    def radius(self, x) -> np.ndarray:
        """The distance from the axis at ``x`` (zero outside ``[−h, h]``)."""
        u = np.clip(np.asarray(x, float) / self.half_length, -1.0, 1.0)
        return (1 - u * u) * Polynomial(self.c)(u * u)

    @property
    def volume(self) -> float:
        """``π ∫ r² dx`` in closed form."""
        c = np.asarray(self.c)
        return math.pi * self.half_length * float(c @ _gram(len(c)) @ c)

    @property
    def width(self) -> float:
        """The largest diameter, ``2 max r``: the stationary point in ``s = u²`` next to
        the largest of ``r`` on a grid, by bisection (the roots of a polynomial whose top
        coefficient is negligible are not to be trusted)."""
        r = Polynomial([1.0, -1.0]) * Polynomial(self.c)  # r as a polynomial in s = u²
        s = np.linspace(0.0, 1.0, 1001)
        i = int(np.argmax(r(s)))
        if i == 0:
            return 2 * float(r(0.0))
        return 2 * float(r(brentq(r.deriv(), s[i - 1], s[i + 1], xtol=1e-15)))

    @property
    def aspect(self) -> float:
        """Length over the largest width."""
        return 2 * self.half_length / self.width

    def bezier_poles(self) -> np.ndarray:
        """The control points ``(x, r)`` (D + 1, 2) of the profile as a Bézier curve of
        degree ``D = 2 len(c)``, from the front tip ``(−h, 0)`` to the back tip ``(h, 0)``."""
        degree = 2 * len(self.c)
        r = Polynomial([1.0, 0.0, -1.0]) * Polynomial(np.ravel(
            [[cj, 0.0] for cj in self.c])[:-1])  # in u
        a = np.pad(r(Polynomial([-1.0, 2.0])).coef, (0, degree + 1))  # u = 2t − 1
        b = [sum(math.comb(i, j) / math.comb(degree, j) * a[j] for j in range(i + 1))
             for i in range(degree + 1)]  # power to Bernstein basis
        x = self.half_length * (2 * np.arange(degree + 1) / degree - 1)  # x = h(2t − 1)
        return np.column_stack([x, b])


def _gram(n: int) -> np.ndarray:
    """``∫₋₁¹ (1 − u²)² u^{2(i+j)} du = 16 / ((2m+1)(2m+3)(2m+5))``, ``m = i + j``."""
    m = np.add.outer(np.arange(n), np.arange(n))
    return 16.0 / ((2 * m + 1) * (2 * m + 3) * (2 * m + 5))


def _profile_of_half_length(h: float, shoulder: float, volume: float) -> ConicalProfile:
    """The family's member of half-length ``h``, ``c2 = shoulder (c0 + c1 + c2)`` and
    ``volume``: the volume is a quadratic in ``c0``, whose larger root is taken."""
    k = math.tan(math.radians(TIP_HALF_ANGLE)) * h / 2  # Σ c_j: |r'(±h)| = √3
    fixed = np.array([0.0, k * (1 - shoulder), k * shoulder])
    d = np.array([1.0, -1.0, 0.0])  # c = fixed + c0 d
    G = _gram(3)
    qa, qb, qc = d @ G @ d, 2 * d @ G @ fixed, fixed @ G @ fixed - volume / (math.pi * h)
    c0 = (-qb + math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
    c = fixed + c0 * d
    return ConicalProfile(h, tuple(float(v) for v in (c if shoulder else c[:2])))


def conical_profile(aspect: float, shoulder: float = 0.0,
                    radius: float = 0.5) -> ConicalProfile:
    """The member of the family with length over width ``aspect``, the share
    ``shoulder`` of ``c2`` in ``c0 + c1 + c2`` (0: the quartic ``(1 − u²)(c0 + c1u²)``)
    and the volume of the sphere of ``radius``.

    Parameters
    ----------
    aspect : length over the largest width, in [1.4, 2.8]
    shoulder : ``c2 / (c0 + c1 + c2)``, in [−0.3, 0.6]; larger is fuller in the middle
        and slimmer towards the tips
    radius : the radius of the sphere of equal volume

    Returns
    -------
    ConicalProfile
    """
    volume = 4 * math.pi * radius ** 3 / 3
    h = brentq(lambda h: _profile_of_half_length(h, shoulder, volume).aspect - aspect,
               0.8 * radius, 2.5 * radius, xtol=1e-14)
    return _profile_of_half_length(h, shoulder, volume)


def conical_body_in_box(path, profile: ConicalProfile, size: float = 1.0,
                        body_size: float = 0.15) -> Path:
    """Tetrahedra of the ``8 × 6 × 6`` box around the body of revolution of ``profile``
    (axis ``x``, centred at the origin), meshed by
    :func:`meshopt_toolkit.shape.cases.solid_in_box` as the spheroids are: the same sizes
    and groups (``"body"``, ``"outer"``, ``"domain"``)."""

    def revolved(occ) -> list[tuple[int, int]]:
        poles = [occ.addPoint(x, r, 0.0) for x, r in profile.bezier_poles()]
        arc = occ.addBezier(poles)
        axis = occ.addLine(poles[-1], poles[0])
        face = occ.addPlaneSurface([occ.addCurveLoop([arc, axis])])
        body = [e for e in occ.revolve([(2, face)], 0, 0, 0, 1, 0, 0, 2 * math.pi)
                if e[0] == 3]
        occ.remove([(2, face)], recursive=True)  # the generating face stays otherwise
        occ.remove([(0, p) for p in poles[1:-1]])  # the inner control points
        return body

    return solid_in_box(path, revolved, size, body_size)
