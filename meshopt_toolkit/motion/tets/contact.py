"""Contact of a tet mesh's boundary with itself: the IPC barrier and CCD of
:mod:`..engine.contact` on the boundary triangles, read and written over all the mesh's vertices.

Every tet positively oriented does not keep two parts of the boundary apart (the arms of
a C-shaped solid bent onto each other double-cover space with every tet positive). The
boundary triangles make a :class:`..engine.contact.SurfaceContact` over the boundary vertices
alone (an interior vertex is in no triangle); :class:`BoundaryContact` maps a
configuration of all vertices to them and the barrier's gradient and Hessian back, so
that :class:`..engine.contact.ContactTerm` serves the tet solver's free coordinates unchanged.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray, IntArray
from ..engine.contact import (DHAT_FRACTION, ContactTerm, NoContact, SurfaceContact,
                              contact_term)
from ..engine.similarity_3d import tet_boundary_faces

__all__ = ["BoundaryContact", "tet_contact_term"]


class BoundaryContact:
    """The :class:`..engine.contact.SurfaceContact` of the boundary ``faces`` of a mesh of
    ``len(points)`` vertices, with the same methods taking and giving all the vertices
    (the barrier's derivatives are zero on the vertices in no face).

    Parameters
    ----------
    points : (N, 3) float array
        The rest.
    faces : (F, 3) int array
        The boundary triangles, vertex indices into ``points``.
    dhat_fraction : float
        ``d̂`` over the boundary's mean edge length.
    """

    def __init__(self, points: FloatArray, faces: IntArray,
                 dhat_fraction: float = DHAT_FRACTION) -> None:
        P = np.asarray(points, float)
        self.vertices, local = np.unique(np.asarray(faces, np.int64), return_inverse=True)
        self.n = len(P)
        self.surface = SurfaceContact(P[self.vertices], local.reshape(-1, 3), dhat_fraction)
        self.usable = self.surface.usable
        self._coordinates = (3 * self.vertices[:, None] + np.arange(3)).ravel()

    @property
    def dhat(self) -> float:
        return self.surface.dhat

    def _on(self, Q: FloatArray) -> FloatArray:
        return np.asarray(Q, float)[self.vertices]

    @property
    def triangles(self) -> IntArray:
        return self.surface.triangles

    signature = staticmethod(SurfaceContact.signature)

    def collisions(self, Q: FloatArray, candidates=None):
        return self.surface.collisions(self._on(Q), candidates)

    def swept(self, Q0: FloatArray, Q1: FloatArray):
        return self.surface.swept(self._on(Q0), self._on(Q1))

    def value(self, Q: FloatArray, collisions=None) -> float:
        return self.surface.value(self._on(Q), collisions)

    def gradient(self, Q: FloatArray, collisions=None) -> FloatArray:
        out = np.zeros((self.n, 3))
        out[self.vertices] = self.surface.gradient(self._on(Q), collisions)
        return out

    def hessian(self, Q: FloatArray, collisions=None, project: bool = True) -> sp.csr_matrix:
        H = self.surface.hessian(self._on(Q), collisions, project).tocoo()
        c = self._coordinates
        return sp.csr_matrix((H.data, (c[H.row], c[H.col])), shape=(3 * self.n, 3 * self.n))

    def minimum_distance(self, Q: FloatArray, collisions=None) -> float:
        return self.surface.minimum_distance(self._on(Q), collisions)

    def candidates(self, Q: FloatArray, reach: float):
        return self.surface.candidates(self._on(Q), reach)

    def stepsize(self, Q0: FloatArray, Q1: FloatArray, collisions=None,
                 candidates=None) -> float:
        return self.surface.stepsize(self._on(Q0), self._on(Q1), collisions, candidates)

    def stiffness(self, energy_gradient: FloatArray, Q: FloatArray,
                  mass: float) -> tuple[float, float]:
        # IPC's κ rests on inner products with the barrier's gradient, zero off the boundary
        return self.surface.stiffness(np.asarray(energy_gradient, float)[self.vertices],
                                      self._on(Q), mass)

    def neighbours_meet(self, Q: FloatArray) -> bool:
        return self.surface.neighbours_meet(self._on(Q))


def tet_contact_term(points: FloatArray, tets: IntArray, free: np.ndarray, mass: FloatArray,
                     on: bool = True) -> ContactTerm | NoContact:
    """:func:`..engine.contact.contact_term` of the boundary of a tet motion from ``points``
    (the rest) over the ``free`` coordinates (a mask over ``points.ravel()``), ``mass`` the
    vertex masses: no contact where no boundary vertex is free either (the boundary's
    path is prescribed)."""
    faces = tet_boundary_faces(tets)
    if not on or len(faces) < 2:
        return NoContact()
    if not np.asarray(free, bool).reshape(-1, 3)[np.unique(faces)].any():
        return NoContact()
    return contact_term(points, faces, free, mass, contact=BoundaryContact(points, faces),
                        what="boundary")
