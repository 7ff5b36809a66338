"""Bodies of revolution with the ends of Pironneau's optimum, for ``bench_shape3d.py``.

Among bodies of a given volume in unbounded Stokes flow, the one of least drag has a
constant vorticity on its surface and conical ends of 120° (a half-angle of 60° with the
axis; Pironneau, *J. Fluid Mech.* 59 (1973) 117–128); Bourot (*J. Fluid Mech.* 65 (1974)
513–515) computed its profile, drag about 0.954 of the sphere's of the same volume. The
profile itself is not tabulated here. The anchor is instead the family

    r(x) = (1 − u²)(c₀ + c₁ u²),   u = x / h,   −h ≤ x ≤ h,

whose tips are exact cones of half-angle 60° (``r'(∓h) = ±√3``, i.e. ``c₀ + c₁ = √3 h/2``)
and whose volume ``π h (16/15 c₀² + 32/105 c₀c₁ + 16/315 c₁²)`` is the sphere's: one free
parameter, the length over the largest width, scanned by the benchmark for the least drag.
The profile, a quartic in ``u``, is an exact Bézier curve of degree 4: gmsh revolves it
about the ``x`` axis without approximation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.polynomial import Polynomial
from scipy.optimize import brentq

from meshopt_toolkit.gmsh_session import gmsh_session
from meshopt_toolkit.shape.cases import BOX_3D, mesh_body_in_box

TIP_HALF_ANGLE = 60.0  # degrees, Pironneau's ends


@dataclass(frozen=True)
class ConicalProfile:
    """``r(x) = (1 − u²)(c0 + c1 u²)``, ``u = x / half_length``."""

    half_length: float
    c0: float
    c1: float

    def radius(self, x) -> np.ndarray:
        """The distance from the axis at ``x`` (zero outside ``[−h, h]``)."""
        u = np.clip(np.asarray(x, float) / self.half_length, -1.0, 1.0)
        return (1 - u * u) * (self.c0 + self.c1 * u * u)

    @property
    def volume(self) -> float:
        """``π ∫ r² dx`` in closed form."""
        c0, c1 = self.c0, self.c1
        return math.pi * self.half_length * 16 * (c0 * c0 / 15 + 2 * c0 * c1 / 105
                                                  + c1 * c1 / 315)

    @property
    def width(self) -> float:
        """The largest diameter, ``2 max r``: at ``u² = (c1 − c0)/(2 c1)`` when in (0, 1)."""
        s = (self.c1 - self.c0) / (2 * self.c1) if self.c1 > 0 else 0.0
        s = min(max(s, 0.0), 1.0)
        return 2 * (1 - s) * (self.c0 + self.c1 * s)

    @property
    def aspect(self) -> float:
        """Length over the largest width."""
        return 2 * self.half_length / self.width

    def bezier_poles(self) -> np.ndarray:
        """The five control points ``(x, r)`` (5, 2) of the profile as a Bézier curve
        from the front tip ``(−h, 0)`` to the back tip ``(h, 0)``."""
        r = Polynomial([self.c0, 0.0, self.c1 - self.c0, 0.0, -self.c1])
        a = r(Polynomial([-1.0, 2.0])).coef  # u = 2t − 1: power coefficients in t
        a = np.pad(a, (0, 5 - len(a)))
        b = [sum(math.comb(i, j) / math.comb(4, j) * a[j] for j in range(i + 1))
             for i in range(5)]  # power to Bernstein basis
        x = self.half_length * (np.arange(5) / 2 - 1)  # x(t) = h(2t − 1), degree raised
        return np.column_stack([x, b])


def _profile_of_half_length(h: float, volume: float) -> ConicalProfile:
    """The family's member of half-length ``h`` and ``volume`` (``c0 > 0``)."""
    k = math.tan(math.radians(TIP_HALF_ANGLE)) * h / 2  # c0 + c1: |r'(±h)| = √3
    # volume / (16 π h) = c0²/15 + 2 c0 c1/105 + c1²/315 with c1 = k − c0
    qa, qb = 1 / 15 - 2 / 105 + 1 / 315, 2 * k / 105 - 2 * k / 315
    qc = k * k / 315 - volume / (16 * math.pi * h)
    c0 = (-qb + math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
    return ConicalProfile(h, c0, k - c0)


def conical_profile(aspect: float, radius: float = 0.5) -> ConicalProfile:
    """The member of the family with length over width ``aspect`` and the volume of the
    sphere of ``radius``.

    Parameters
    ----------
    aspect : length over the largest width, in [1.3, 3]
    radius : the radius of the sphere of equal volume

    Returns
    -------
    ConicalProfile
    """
    volume = 4 * math.pi * radius ** 3 / 3
    h = brentq(lambda h: _profile_of_half_length(h, volume).aspect - aspect,
               0.8 * radius, 2.5 * radius, xtol=1e-14)
    return _profile_of_half_length(h, volume)


def conical_body_in_box(path, profile: ConicalProfile, size: float = 1.0,
                        body_size: float = 0.15) -> Path:
    """Tetrahedra of the ``8 × 6 × 6`` box around the body of revolution of ``profile``
    (axis ``x``, centred at the origin), meshed by
    :func:`meshopt_toolkit.shape.cases.mesh_body_in_box` with the spheroids' sizes and
    groups (``"body"``, ``"outer"``, ``"domain"``)."""
    path = Path(path)
    with gmsh_session() as gmsh:
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add("conical_body_in_box")
        occ = gmsh.model.occ
        lx, ly, lz = BOX_3D
        box = occ.addBox(-lx / 2, -ly / 2, -lz / 2, lx, ly, lz)
        poles = [occ.addPoint(x, r, 0.0) for x, r in profile.bezier_poles()]
        arc = occ.addBezier(poles)
        axis = occ.addLine(poles[-1], poles[0])
        face = occ.addPlaneSurface([occ.addCurveLoop([arc, axis])])
        body = [e for e in occ.revolve([(2, face)], 0, 0, 0, 1, 0, 0, 2 * math.pi)
                if e[0] == 3]
        occ.remove([(2, face)], recursive=True)  # the generating face stays otherwise
        occ.remove([(0, p) for p in poles[1:-1]])  # the inner control points
        occ.cut([(3, box)], body)
        occ.synchronize()
        inner, outer = [], []
        for _, s in gmsh.model.getEntities(2):
            centre = occ.getCenterOfMass(2, s)
            (inner if max(map(abs, centre)) < 0.25 * min(BOX_3D) else outer).append(s)
        mesh_body_in_box(gmsh, inner, outer, path, size, body_size)
    return path
