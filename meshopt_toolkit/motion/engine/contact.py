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

Every point must be in some triangle (``ipctk`` would take a lone point for a codimensional
one): a surface's motion solves for exactly those.

IPC has no pair for an edge and a triangle that share a vertex: two triangles of one fan
can come to intersect with every pair of it apart. :meth:`SurfaceContact.neighbours_meet`
tests those triangle pairs exactly (:mod:`..kernels.intersections3d`).
"""

from __future__ import annotations

import copy
import warnings

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ...kernels.intersections3d import intersecting_pairs, self_intersections
from ...kernels.predicates import exactly_scaled

__all__ = ["DHAT_FRACTION", "ContactTerm", "ContactWarning", "NoContact", "SurfaceContact",
           "contact_term", "pair_contact"]

#: ``d̂`` over the rest's mean edge length
DHAT_FRACTION = 0.1
#: the largest coordinate move, over ``d̂``, of the steps from one start whose CCD runs on
#: candidates kept around it (:meth:`ContactTerm.cap`; a polish's trials move ~2 d̂)
REACH = 4.0
#: the growth, over ``d̂``, of the boxes of a step's swept broad phase
#: (:meth:`SurfaceContact.swept`): its pairs serve the collisions at points within
#: ``(SWEPT − 1) d̂ / 2`` of the step's path
SWEPT = 1.02
#: the most swept candidates per triangle kept for the pairs at a step's trials (more:
#: a broad phase at each trial costs less than the narrow phase over them)
SWEPT_PAIRS = 1.0
#: the iterations of tight-inclusion CCD per pair: past them it returns the start of the
#: time interval it has not yet cleared, a conservative time of impact however few (pairs
#: nearly touching at a step's start reach the bound, each iteration costing alike)
TIGHT_ITERATIONS = 10**4
#: that bound in :meth:`SurfaceContact.segment_free`: higher, since a pair it leaves
#: uncleared fails the segment, and a morph ending close to contact then needs more frames
#: (and where the first run stops at a time below 10⁻⁶, ipctk reruns it without a bound)
SEGMENT_ITERATIONS = 10**6
#: the separation, over the rest's bounding-box diagonal, within which
#: :meth:`SurfaceContact.segment_free` takes a pair for touching (where it starts more than
#: five times as far); ipctk's step check puts it at 10⁻⁴ in any unit
SEGMENT_FLOOR = 1e-4
#: that separation in ipctk's step check, in the coordinates' unit
IPCTK_FLOOR = 1e-4


def _ipctk():
    """``ipctk``, run on one thread: its parallel sums would otherwise make the barrier's
    gradient, and so the motion, differ from run to run in the last bits."""
    import ipctk

    if ipctk.get_num_threads() != 1:
        ipctk.set_num_threads(1)
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
        #: ``d̂`` of the edges alone, before it is lowered below a closest pair
        self.edge_dhat = dhat
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

    def with_dhat(self, dhat: float) -> SurfaceContact:
        """A copy whose barrier reaches ``dhat`` (the same mesh, pairs and CCD)."""
        out = copy.copy(self)
        out.dhat = float(dhat)
        out.potential = _ipctk().BarrierPotential(max(out.dhat, 1e-300), 1.0)
        return out

    def neighbours_meet(self, Q: FloatArray) -> bool:
        """Whether two triangles sharing a vertex intersect improperly at ``Q`` (exact)."""
        if not len(self.neighbours):
            return False
        return bool(intersecting_pairs(exactly_scaled(np.asarray(Q, float))[0],
                                       self.triangles, self.neighbours).any())

    def collisions(self, Q: FloatArray, candidates=None):
        """The pairs closer than ``d̂`` at ``Q`` (an ``ipctk.NormalCollisions``), from
        ``candidates`` where given (a superset of those pairs, e.g. :meth:`swept`'s of a
        path through ``Q``), else from a broad phase of the whole surface."""
        c = _ipctk().NormalCollisions()
        Q = np.asfortranarray(Q, dtype=float)
        if candidates is None:
            c.build(self.mesh, Q, self.dhat)
        else:
            c.build(candidates, self.mesh, Q, self.dhat)
        return c

    def swept(self, Q0: FloatArray, Q1: FloatArray):
        """The pairs whose boxes swept along the straight path from ``Q0`` to ``Q1``, each
        grown by ``SWEPT d̂``, meet (an ``ipctk.Candidates``): every pair that the path can
        bring into contact, and every pair within ``d̂`` of each other at a point within
        ``(SWEPT − 1) d̂ / 2`` of the path (:meth:`ContactTerm.collisions`)."""
        c = _ipctk().Candidates()
        c.build(self.mesh, np.asfortranarray(Q0, dtype=float),
                np.asfortranarray(Q1, dtype=float), SWEPT * self.dhat)
        return c

    @staticmethod
    def signature(collisions) -> frozenset:
        """The pairs in ``collisions`` by kind and primitive ids, each pair of one kind
        once whatever its order (the active set)."""
        return frozenset(
            [(0, *sorted((p.vertex0_id, p.vertex1_id))) for p in collisions.vv_collisions]
            + [(1, p.edge_id, p.vertex_id) for p in collisions.ev_collisions]
            + [(2, *sorted((p.edge0_id, p.edge1_id))) for p in collisions.ee_collisions]
            + [(3, p.face_id, p.vertex_id) for p in collisions.fv_collisions])

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

    def minimum_distance(self, Q: FloatArray, collisions=None) -> float:
        """The smallest distance of a pair at ``Q`` (``d̂`` where none is closer)."""
        Q = np.asfortranarray(Q, dtype=float)
        c = self.collisions(Q) if collisions is None else collisions
        return float(np.sqrt(c.compute_minimum_distance(self.mesh, Q))) if len(c) else self.dhat

    def candidates(self, Q: FloatArray, reach: float):
        """The pairs whose boxes at ``Q``, each grown by ``reach``, meet (an
        ``ipctk.Candidates``): every pair that can touch along a straight path from ``Q``
        on which no coordinate moves by more than ``reach``."""
        c = _ipctk().Candidates()
        Q = np.asfortranarray(Q, dtype=float)
        c.build(self.mesh, Q, Q, float(reach))
        return c

    def stepsize(self, Q0: FloatArray, Q1: FloatArray, collisions=None,
                 candidates=None) -> float:
        """The fraction in [0, 1] of the straight path from ``Q0`` (clean) to ``Q1`` that
        is free of contact (1: the whole path). Additive CCD (Li et al. 2021; 0.9 of the
        first time of impact) where every pair at ``Q0`` is at least ``10⁻³ d̂`` apart;
        closer, its squared distances lose the gap to rounding and tight-inclusion CCD
        (intervals, conservative) decides. ``collisions``: those at ``Q0`` where known;
        ``candidates``: a superset of the pairs the path can bring into contact (e.g.
        :meth:`candidates`), else the path's own broad phase."""
        ipctk = _ipctk()
        Q0 = np.asfortranarray(Q0, dtype=float)
        Q1 = np.asfortranarray(Q1, dtype=float)
        close = self.minimum_distance(Q0, collisions) < 1e-3 * self.dhat
        ccd = (ipctk.TightInclusionCCD(1e-6, TIGHT_ITERATIONS) if close
               else ipctk.AdditiveCCD())
        if candidates is not None:
            return float(candidates.compute_collision_free_stepsize(self.mesh, Q0, Q1, 0.0, ccd))
        return float(ipctk.compute_collision_free_stepsize(self.mesh, Q0, Q1, 0.0, None, ccd))

    def segment_free(self, Q0: FloatArray, Q1: FloatArray) -> bool:
        """Whether the straight path from the clean ``Q0`` to ``Q1`` brings no pair within
        ``min(d₀/5, SEGMENT_FLOOR × the rest's diagonal)`` of touching, ``d₀`` its distance
        at ``Q0`` (a pair whose boxes swept along the path do not meet cannot touch and is
        not tested): ipctk's step check (tight-inclusion CCD, conservative: its tolerance
        makes both bounds up to about twice as strict, and a pair it cannot clear in
        ``SEGMENT_ITERATIONS`` counts as touching) on coordinates scaled so that its floor
        (``IPCTK_FLOOR`` in any unit) is ``SEGMENT_FLOOR`` of the diagonal. Unlike a capped
        step's CCD it bounds no ratio above the floor: a pair may close from any distance
        down to it in one segment. Scale covariant, and at least as strict as ipctk's own
        check at the user's scale wherever the diagonal is at least
        ``IPCTK_FLOOR / SEGMENT_FLOOR``."""
        ipctk = _ipctk()
        k = IPCTK_FLOOR / (SEGMENT_FLOOR * self.bbox_diagonal)
        return bool(ipctk.is_step_collision_free(
            self.mesh, np.asfortranarray(k * np.asarray(Q0, float)),
            np.asfortranarray(k * np.asarray(Q1, float)), 0.0, None,
            ipctk.TightInclusionCCD(ipctk.TightInclusionCCD.DEFAULT_TOLERANCE,
                                    SEGMENT_ITERATIONS)))

    def segment_bound(self, Q0: FloatArray) -> float:
        """The distance below which no pair may come along a segment from the clean ``Q0``
        that :meth:`segment_free` passes: a fifth of ``Q0``'s closest pair or of the floor
        (``SEGMENT_FLOOR`` of the diagonal), the least of the pairs' own bounds."""
        floor = SEGMENT_FLOOR * self.bbox_diagonal
        return min(self.with_dhat(floor).minimum_distance(Q0), floor) / 5.0

    def stiffness(self, energy_gradient: FloatArray, Q: FloatArray,
                  mass: float) -> tuple[float, float]:
        """IPC's initial barrier stiffness ``κ`` at ``Q`` against an energy's gradient
        (N, 3), and its largest (``ipctk.initial_barrier_stiffness``; ``mass``: the mean
        vertex mass)."""
        ipctk = _ipctk()
        kappa, largest = ipctk.initial_barrier_stiffness(
            self.bbox_diagonal, self.potential.barrier, self.dhat, float(mass),
            np.asarray(energy_gradient, float).ravel(), self.gradient(Q).ravel())
        return float(kappa), float(largest)


class ContactTerm:
    """``κ B(Q)`` of a :class:`SurfaceContact` on a solver's free coordinates (a boolean
    mask over ``Q.ravel()``): its value, gradient and PSD-projected Hessian there, the
    collisions kept for the last ``Q`` asked, and the CCD cap of a step.

    ``κ`` is IPC's initial stiffness (:meth:`SurfaceContact.stiffness`), set against the
    solver energy's gradient the first time a pair comes within ``d̂``, and doubled (up to
    IPC's largest) whenever the closest pair is nearer than ``10⁻² d̂`` and nearer than at
    the last update (IPC's rule, its threshold relative to ``d̂``).
    """

    def __init__(self, contact: SurfaceContact, free: np.ndarray, mean_mass: float) -> None:
        self.contact, self.free, self.mean_mass = contact, free, float(mean_mass)
        self.kappa: float | None = None
        self.max_kappa, self.closest = np.inf, np.inf
        self._key: np.ndarray | None = None
        self._collisions = None
        #: the start of the last short CCD steps, their largest move, and candidates
        #: within a reach (and the reach) around it
        self._start, self._move, self._reach = None, 0.0, None
        #: the start, the move and the swept candidates of the last step given its own
        #: broad phase
        self._path = None

    def collisions(self, Q: FloatArray):
        """The pairs within ``d̂`` at ``Q``, kept for the last ``Q`` asked; from the
        candidates of the last step capped where ``Q`` is on its path (a line search's
        trials), else from a broad phase of the whole surface."""
        if self._key is None or not np.array_equal(self._key, Q):
            self._key = np.array(Q)
            self._collisions = self.contact.collisions(Q, self._on_path(Q))
        return self._collisions

    def _on_path(self, Q: FloatArray):
        """The swept candidates of the last capped step where ``Q`` lies on its path (no
        coordinate off it by more than ``(SWEPT − 1) d̂ / 2``), else None."""
        if self._path is None:
            return None
        start, D, candidates = self._path
        Y = Q - start
        dd = float(np.vdot(D, D))
        a = float(np.vdot(Y, D)) / dd if dd > 0 else 0.0
        if not -1e-9 <= a <= 1.0 + 1e-9:
            return None
        off = float(np.max(np.abs(Y - a * D))) if Y.size else 0.0
        return candidates if off <= 0.5 * (SWEPT - 1.0) * self.contact.dhat else None

    def signature(self, Q: FloatArray) -> tuple:
        """``κ`` and the pairs within ``d̂`` at ``Q``: where both are those of a factor's
        point, the factor holds the barrier's Hessian of the same pairs."""
        pairs = self.contact.signature(self.collisions(Q)) if self.active(Q) else frozenset()
        return self.kappa, pairs

    def active(self, Q: FloatArray) -> bool:
        """Whether a pair is within ``d̂`` at ``Q``."""
        return len(self.collisions(Q)) > 0

    def set_stiffness(self, Q: FloatArray, energy_gradient: FloatArray) -> bool:
        """Set ``κ`` at ``Q`` against the energy's gradient on the free coordinates where a
        pair is within ``d̂`` (once), or double it (class docstring); whether it changed."""
        if not self.active(Q):
            return False
        if self.kappa is None:
            g = np.zeros(self.free.size)
            g[self.free] = energy_gradient
            self.kappa, self.max_kappa = self.contact.stiffness(g.reshape(-1, 3), Q,
                                                                self.mean_mass)
            return True
        d = self.contact.minimum_distance(Q, self.collisions(Q))
        if d < 1e-2 * self.contact.dhat and d < self.closest and self.kappa < self.max_kappa:
            self.closest, self.kappa = d, min(2.0 * self.kappa, self.max_kappa)
            return True
        return False

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

    def clear(self, Q0: FloatArray, Q1: FloatArray) -> bool:
        """Whether the straight step from ``Q0`` to ``Q1`` passes through no contact."""
        return self.cap(Q0, Q1) >= 1.0

    def embedded(self, Q: FloatArray) -> bool:
        """Whether no two triangles sharing a vertex intersect at ``Q`` (exact)."""
        return not self.contact.neighbours_meet(Q)

    def step_cap(self, Q: FloatArray, step: FloatArray) -> float:
        """:meth:`cap` of the step from ``Q`` to ``Q`` less ``step`` on the free
        coordinates."""
        end = Q.copy()
        end.ravel()[self.free] -= step
        return self.cap(Q, end)

    def cap(self, Q0: FloatArray, Q1: FloatArray) -> float:
        """The CCD fraction of the straight step from ``Q0`` to ``Q1``; 1 without CCD
        where no pair is within ``d̂`` at ``Q0`` and no point moves by ``d̂/2`` (a pair's
        distance falls by at most twice the largest displacement)."""
        step = float(np.sqrt(np.max(np.sum((Q1 - Q0) ** 2, axis=1)))) if len(Q0) else 0.0
        if 2.0 * step < self.contact.dhat and not self.active(Q0):
            return 1.0
        collisions = self.collisions(Q0)
        candidates = self._candidates(Q0, Q1)
        if candidates is None:  # the step's own broad phase, kept for its trials' pairs
            candidates = self.contact.swept(Q0, Q1)
            # unless a long step's many pairs cost more than a broad phase at each trial
            few = len(candidates) <= SWEPT_PAIRS * len(self.contact.triangles)
            self._path = (np.array(Q0), Q1 - Q0, candidates) if few else None
        return self.contact.stepsize(Q0, Q1, collisions, candidates)

    def _candidates(self, Q0: FloatArray, Q1: FloatArray):
        """Candidates for the CCD of the short step from ``Q0`` to ``Q1`` kept across steps
        from one start (a line search's trials), from the second step from it on where no
        coordinate moves by more than ``REACH d̂``: those within 1.5 times the largest such
        move so far (at most ``REACH d̂``), rebuilt when a step moves further; None (the
        path's own broad phase) otherwise."""
        move = float(np.max(np.abs(Q1 - Q0)))
        if move > REACH * self.contact.dhat:
            return None
        if self._start is None or not np.array_equal(self._start, Q0):
            self._start, self._move, self._reach = np.array(Q0), move, None
            return None
        if self._reach is None or move > self._reach[0]:
            self._move = max(move, self._move)
            reach = min(1.5 * self._move, REACH * self.contact.dhat)
            self._reach = (reach, self.contact.candidates(Q0, reach))
        return self._reach[1]


class NoContact:
    """The contact term of a motion without contact: no energy, every step clear."""

    kappa = None

    def energy(self, Q):
        return 0.0

    def gradient(self, Q):
        return 0.0

    def hessian(self, Q):
        return None

    def active(self, Q):
        return False

    def set_stiffness(self, Q, energy_gradient):
        return False

    def clear(self, Q0, Q1):
        return True

    def embedded(self, Q):
        return True

    def step_cap(self, Q, step):
        return 1.0

    def signature(self, Q):
        return None


class ContactWarning(UserWarning):
    """A surface moved without contact: its rest already intersects itself."""


def contact_term(points: FloatArray, triangles: IntArray, free: np.ndarray,
                 mass: FloatArray, on: bool = True, *, contact=None,
                 what: str = "surface") -> ContactTerm | NoContact:
    """The contact term of a motion from ``points`` (the rest) over the ``free``
    coordinates, ``mass`` the vertex masses; :class:`NoContact` where ``on`` is False, and,
    with a :class:`ContactWarning` giving the count, where the rest intersects itself
    (exact, :mod:`...kernels.intersections3d`). ``contact``: the triangles' contact where
    not a :class:`SurfaceContact` of ``points`` (a tet mesh's boundary), ``what`` they are
    in the warning."""
    free = np.asarray(free, bool)
    if not on or len(triangles) < 2 or not free.any():
        return NoContact()
    contact = SurfaceContact(points, triangles) if contact is None else contact
    if not contact.usable:
        pairs = len(self_intersections(points, triangles))
        if pairs:
            warnings.warn(f"the {what} intersects itself at rest ({pairs} pairs of "
                          "triangles): moved without contact", ContactWarning, stacklevel=3)
        return NoContact()
    return ContactTerm(contact, free, float(np.mean(mass)))


def pair_contact(source: FloatArray, target: FloatArray, triangles: IntArray,
                 dhat_fraction: float = DHAT_FRACTION) -> SurfaceContact | None:
    """The :class:`SurfaceContact` of a motion between two poses of one surface (a
    morph's ends): ``d̂`` also below half the target's closest pair, so neither end has
    barrier energy; None where either end intersects itself or touches itself."""
    contact = SurfaceContact(source, triangles, dhat_fraction)
    if not contact.usable:
        return None
    ipctk = _ipctk()
    V = np.asfortranarray(target, dtype=float)
    if ipctk.has_intersections(contact.mesh, V):
        return None
    nearest = contact.minimum_distance(V)
    if nearest <= 0.0:
        return None
    if nearest < 2.0 * contact.dhat:
        contact.dhat = 0.5 * nearest
        contact.potential = ipctk.BarrierPotential(contact.dhat, 1.0)
    return contact
