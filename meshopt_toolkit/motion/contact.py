"""Contact of a surface with itself (Incremental Potential Contact, Li et al. 2020), over
``ipctk``: the barrier on point–triangle and edge–edge distances below ``d̂`` and the
continuous collision detection (CCD) that caps a step so that no point of the straight
path from one configuration to the next passes through the surface.

The barrier is IPC's ``b(d) = −(d − d̂)² log(d/d̂)`` summed over the pairs of primitives
closer than ``d̂`` that share no vertex; it is zero where every such pair is at least
``d̂`` apart and tends to +∞ as a pair touches. ``d̂`` is a fraction of the rest's mean
edge length, lowered below half the rest's smallest distance between such pairs, so the
rest's own energy is zero (a rest that already touches itself has no barrier:
:attr:`SurfaceContact.usable` is False).

A tet mesh's contact is that of its boundary faces: the points are all the mesh's points
(interior ones are in no face, so in no pair).

IPC has no pair for an edge and a triangle that share a vertex: two triangles of one fan
can come to intersect with every pair of it apart. :meth:`SurfaceContact.neighbours_meet`
tests those triangle pairs exactly (:mod:`..kernels.intersections3d`).
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from .._typing import FloatArray, IntArray
from ..kernels.intersections3d import intersecting_pairs, self_intersections
from ..kernels.predicates import exactly_scaled

__all__ = ["DHAT_FRACTION", "ContactTerm", "ContactWarning", "SurfaceContact", "contact_term"]

#: ``d̂`` over the rest's mean edge length
DHAT_FRACTION = 0.1


def _ipctk():
    import ipctk

    return ipctk


class SurfaceContact:
    """The barrier and the CCD of one surface (its triangles fixed, its points moving).

    Parameters
    ----------
    points : (N, 3) float array
        The rest, free of self-intersections for the barrier to be usable.
    triangles : (T, 3) int array
        The faces that must not pass through each other.
    dhat_fraction : float
        ``d̂`` over the mean edge length (module docstring).
    """

    def __init__(self, points: FloatArray, triangles: IntArray,
                 dhat_fraction: float = DHAT_FRACTION) -> None:
        ipctk = _ipctk()
        V = np.asfortranarray(points, dtype=float)
        F = np.asfortranarray(triangles, dtype=np.int32)
        self.n = len(V)
        E = np.asfortranarray(ipctk.edges(F), dtype=np.int32)
        self.mesh = ipctk.CollisionMesh(V, E, F)
        lengths = np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1)
        dhat = dhat_fraction * float(lengths.mean()) if len(lengths) else 0.0
        self.usable = dhat > 0 and not ipctk.has_intersections(self.mesh, V)
        if self.usable:  # d̂ below half the rest's closest pair: no barrier at rest
            rest = ipctk.NormalCollisions()
            rest.build(self.mesh, V, dhat)
            if len(rest):
                nearest = float(np.sqrt(rest.compute_minimum_distance(self.mesh, V)))
                self.usable = nearest > 0
                dhat = min(dhat, 0.5 * nearest)
        self.dhat = dhat
        self.potential = ipctk.BarrierPotential(max(dhat, 1e-300), 1.0)
        self.bbox_diagonal = float(np.linalg.norm(V.max(0) - V.min(0))) if len(V) else 0.0
        self.triangles = np.asarray(triangles, np.int64)
        # the pairs of triangles sharing a vertex (the nonzeros of the incidence product)
        T = len(self.triangles)
        incidence = sp.csr_matrix((np.ones(3 * T), (np.repeat(np.arange(T), 3),
                                                    self.triangles.ravel())),
                                  shape=(T, self.n))
        shared = sp.triu(incidence @ incidence.T, k=1).tocoo()
        self.neighbours = np.stack([shared.row, shared.col], axis=1).astype(np.int64)

    def neighbours_meet(self, Q: FloatArray) -> bool:
        """Whether two triangles sharing a vertex intersect improperly at ``Q`` (exact)."""
        if not len(self.neighbours):
            return False
        return bool(intersecting_pairs(exactly_scaled(np.asarray(Q, float))[0],
                                       self.triangles, self.neighbours).any())

    def collisions(self, Q: FloatArray):
        """The pairs closer than ``d̂`` at ``Q`` (an ``ipctk.NormalCollisions``)."""
        c = _ipctk().NormalCollisions()
        c.build(self.mesh, np.asfortranarray(Q, dtype=float), self.dhat)
        return c

    def value(self, Q: FloatArray, collisions=None) -> float:
        """The barrier's sum at ``Q`` (unit stiffness); +inf where a pair touches. (A
        configuration through itself need have no touching pair: the CCD keeps it out.)"""
        Q = np.asfortranarray(Q, dtype=float)
        c = self.collisions(Q) if collisions is None else collisions
        if len(c) and c.compute_minimum_distance(self.mesh, Q) <= 0.0:
            return np.inf
        return float(self.potential(c, self.mesh, Q))

    def gradient(self, Q: FloatArray, collisions=None) -> FloatArray:
        """The barrier's gradient (N, 3)."""
        Q = np.asfortranarray(Q, dtype=float)
        c = self.collisions(Q) if collisions is None else collisions
        return np.asarray(self.potential.gradient(c, self.mesh, Q)).reshape(self.n, 3)

    def hessian(self, Q: FloatArray, collisions=None, project: bool = True) -> sp.csr_matrix:
        """The barrier's Hessian (3N, 3N) in the point-major order of ``Q.ravel()``; each
        pair's block projected onto the positive semidefinite cone where ``project``."""
        ipctk = _ipctk()
        Q = np.asfortranarray(Q, dtype=float)
        c = self.collisions(Q) if collisions is None else collisions
        method = ipctk.PSDProjectionMethod.CLAMP if project else ipctk.PSDProjectionMethod.NONE
        return sp.csr_matrix(self.potential.hessian(c, self.mesh, Q, method))

    def stepsize(self, Q0: FloatArray, Q1: FloatArray) -> float:
        """The fraction in [0, 1] of the straight path from ``Q0`` (clean) to ``Q1`` that
        is free of contact (additive CCD, Li et al. 2021: conservative, 0.9 of the first
        time of impact; tight-inclusion CCD takes seconds on pairs sliding along each
        other; 1: the whole path)."""
        ipctk = _ipctk()
        return float(ipctk.compute_collision_free_stepsize(
            self.mesh, np.asfortranarray(Q0, dtype=float), np.asfortranarray(Q1, dtype=float),
            0.0, None, ipctk.AdditiveCCD()))

    def stiffness(self, energy_gradient: FloatArray, Q: FloatArray, mass: float) -> float:
        """IPC's initial barrier stiffness ``κ`` at ``Q`` against an energy's gradient
        (N, 3) (``ipctk.initial_barrier_stiffness``; ``mass``: the mean vertex mass)."""
        ipctk = _ipctk()
        kappa, _ = ipctk.initial_barrier_stiffness(
            self.bbox_diagonal, self.potential.barrier, self.dhat, float(mass),
            np.asarray(energy_gradient, float).ravel(), self.gradient(Q).ravel())
        return float(kappa)


class ContactTerm:
    """``κ B(Q)`` of a :class:`SurfaceContact` on a solver's free coordinates (a boolean
    mask over ``Q.ravel()``): its value, gradient and PSD-projected Hessian there, the
    collisions kept for the last ``Q`` asked, and the CCD cap of a step.

    ``κ`` is IPC's initial stiffness (:meth:`SurfaceContact.stiffness`), set against the
    solver energy's gradient the first time a pair comes within ``d̂`` and kept.
    """

    def __init__(self, contact: SurfaceContact, free: np.ndarray, mean_mass: float) -> None:
        self.contact, self.free, self.mean_mass = contact, free, float(mean_mass)
        self.kappa: float | None = None
        self._key: np.ndarray | None = None
        self._collisions = None

    def collisions(self, Q: FloatArray):
        if self._key is None or not np.array_equal(self._key, Q):
            self._key, self._collisions = np.array(Q), self.contact.collisions(Q)
        return self._collisions

    def active(self, Q: FloatArray) -> bool:
        """Whether a pair is within ``d̂`` at ``Q``."""
        return len(self.collisions(Q)) > 0

    def set_stiffness(self, Q: FloatArray, energy_gradient: FloatArray) -> bool:
        """Set ``κ`` at ``Q`` against the energy's gradient on the free coordinates, once,
        where a pair is within ``d̂``; whether it was set now."""
        if self.kappa is not None or not self.active(Q):
            return False
        g = np.zeros(self.free.size)
        g[self.free] = energy_gradient
        self.kappa = self.contact.stiffness(g.reshape(-1, 3), Q, self.mean_mass)
        return True

    def energy(self, Q: FloatArray) -> float:
        """``κ B(Q)``; before ``κ`` is set 0, or +inf where a pair touches."""
        if not self.active(Q):
            return 0.0
        value = self.contact.value(Q, self.collisions(Q))
        if self.kappa is None:
            return np.inf if value == np.inf else 0.0
        return self.kappa * value

    def gradient(self, Q: FloatArray) -> FloatArray:
        """On the free coordinates (0 before ``κ`` is set)."""
        if self.kappa is None or not self.active(Q):
            return np.zeros(int(self.free.sum()))
        return self.kappa * self.contact.gradient(Q, self.collisions(Q)).ravel()[self.free]

    def hessian(self, Q: FloatArray) -> sp.csr_matrix | None:
        """The projected Hessian on the free coordinates, None where no pair is active."""
        if self.kappa is None or not self.active(Q):
            return None
        H = self.contact.hessian(Q, self.collisions(Q))
        return self.kappa * H[self.free][:, self.free]

    def cap(self, Q0: FloatArray, Q1: FloatArray) -> float:
        """The CCD fraction of the straight step from ``Q0`` to ``Q1``; 1 without CCD
        where no pair is within ``d̂`` at ``Q0`` and no point moves by ``d̂/2`` (a pair's
        distance falls by at most twice the largest displacement)."""
        step = float(np.sqrt(np.max(np.sum((Q1 - Q0) ** 2, axis=1)))) if len(Q0) else 0.0
        if 2.0 * step < self.contact.dhat and not self.active(Q0):
            return 1.0
        return self.contact.stepsize(Q0, Q1)


class ContactWarning(UserWarning):
    """A surface moved without contact: its rest already intersects itself."""


def contact_term(points: FloatArray, triangles: IntArray, free: np.ndarray,
                 mass: FloatArray) -> ContactTerm | None:
    """The contact term of a motion from ``points`` (the rest) over the ``free``
    coordinates, ``mass`` the vertex masses; None, with a :class:`ContactWarning` giving
    the count, where the rest intersects itself (exact, :mod:`..kernels.intersections3d`)."""
    if len(triangles) < 2 or not free.any():
        return None
    contact = SurfaceContact(points, triangles)
    if not contact.usable:
        pairs = len(self_intersections(points, triangles))
        if pairs:
            warnings.warn(f"the surface intersects itself at rest ({pairs} pairs of "
                          "triangles): moved without contact", ContactWarning, stacklevel=3)
        return None
    return ContactTerm(contact, free, float(np.mean(mass)))
