"""Similarities ``z ↦ a z + b`` (complex ``a = s·e^{iθ}``): fitting, interpolation, paths.

Every motion is factored as a similarity (closed form) composed with a residual deformation;
the strain ``φ`` does not see the similarity, so a motion that IS a similarity is followed
exactly (every triangle keeps its shape) and costs no strain at all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .._typing import FloatArray, IntArray
from ..scaling import UnitScale


def _c(P: FloatArray) -> np.ndarray:
    return P[:, 0] + 1j * P[:, 1]


def _r(z: np.ndarray) -> FloatArray:
    return np.column_stack([z.real, z.imag])


@dataclass(frozen=True)
class Similarity:
    """``z ↦ center + shift + a (z − center)`` with ``a = exp(log_scale + i·angle)``."""

    center: complex
    shift: complex
    log_scale: float
    angle: float

    @property
    def a(self) -> complex:
        return complex(np.exp(self.log_scale + 1j * self.angle))

    def __call__(self, P: FloatArray) -> FloatArray:
        return _r(self.center + self.shift + self.a * (_c(P) - self.center))

    def inverse(self, P: FloatArray) -> FloatArray:
        return _r(self.center + (_c(P) - self.center - self.shift) / self.a)

    def at(self, s: float) -> Similarity:
        """The similarity a fraction ``s`` of the way (angle, log-scale, shift linear)."""
        return Similarity(self.center, s * self.shift, s * self.log_scale, s * self.angle)

    @property
    def is_identity(self) -> bool:
        return self.shift == 0 and self.log_scale == 0 and self.angle == 0

    def scaled_up(self, scale: UnitScale) -> Similarity:
        """This similarity of unit-size coordinates in the user's (centre and shift
        multiplied by ``scale.factor``; the angle and scale are the same)."""
        (cx, sx), (cy, sy) = scale.up([[self.center.real, self.shift.real],
                                       [self.center.imag, self.shift.imag]])
        return Similarity(complex(cx, cy), complex(sx, sy), self.log_scale, self.angle)


def fit_similarity(source: FloatArray, target: FloatArray,
                   weights: FloatArray | None = None) -> Similarity:
    """Least-squares similarity taking ``source`` points to ``target`` points (Procrustes
    with scale, about the weighted centroid of ``source``); the angle in (−π, π]."""
    zs, zt = _c(np.asarray(source, float)), _c(np.asarray(target, float))
    w = np.ones(len(zs)) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    cs, ct = w @ zs, w @ zt
    ds, dt = zs - cs, zt - ct
    denom = float(w @ np.abs(ds) ** 2)
    if len(zs) < 2 or denom == 0.0:
        return Similarity(complex(cs), complex(ct - cs), 0.0, 0.0)
    a = complex(w @ (np.conj(ds) * dt)) / denom
    if a == 0:
        return Similarity(complex(cs), complex(ct - cs), 0.0, 0.0)
    return Similarity(complex(cs), complex(ct - cs), float(np.log(abs(a))), float(np.angle(a)))


def handle_labels(handles: IntArray, edges: IntArray, n_vertices: int) -> IntArray:
    """A label per handle (0, 1, …): its connected piece through the edges (vertex pairs
    ``(E, 2)``) whose both ends are handles."""
    is_handle = np.full(n_vertices, -1)
    is_handle[handles] = np.arange(len(handles))
    e = edges
    both = (is_handle[e[:, 0]] >= 0) & (is_handle[e[:, 1]] >= 0)
    i, j = is_handle[e[both, 0]], is_handle[e[both, 1]]
    graph = sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(len(handles), len(handles)))
    return connected_components(graph, directed=False)[1]


def handle_groups(handles: IntArray, boundary_edges: IntArray, n_vertices: int) -> list[IntArray]:
    """Positions (into ``handles``) of the handles grouped by connected boundary pieces:
    handles joined by boundary edges (vertex pairs ``(E, 2)``) whose both ends are handles
    form one group (:func:`handle_labels`)."""
    labels = handle_labels(handles, boundary_edges, n_vertices)
    return [np.flatnonzero(labels == c) for c in range(int(labels.max()) + 1 if len(labels)
                                                        else 0)]


class HandlePath:
    """Default path of the handles from their positions to their targets.

    Each group of handles (a connected piece of boundary) follows the similarity that fits
    it best (so a turning hole turns instead of collapsing through its centre), plus the
    straight-line remainder that takes it exactly to the targets at ``s = 1``.
    """

    #: the similarity that fits a group best, ``fit(start, targets)``
    fit = staticmethod(fit_similarity)

    def __init__(self, start: FloatArray, targets: FloatArray, groups: list[IntArray]) -> None:
        self.start = np.asarray(start, float)
        self.targets = np.asarray(targets, float)
        self.pieces = []
        for g in groups:
            S = self.fit(self.start[g], self.targets[g]) if self.turns(self.start[g]) else None
            rest = self.targets[g] - (S(self.start[g]) if S is not None else self.start[g])
            self.pieces.append((g, S, rest))

    @staticmethod
    def turns(points: FloatArray) -> bool:
        """Whether a group at ``points`` has a similarity of its own (else it moves
        linearly): three points at least."""
        return len(points) >= 3

    def along(self, S, s: float):
        """The similarity ``S`` a fraction ``s`` of the way (:meth:`Similarity.at`)."""
        return S.at(s)

    @property
    def similarities(self) -> list:
        """Each group's similarity (None: the group moves linearly)."""
        return [S for _, S, _ in self.pieces]

    def __call__(self, s: float) -> FloatArray:
        if s >= 1.0:
            return self.targets.copy()  # bitwise the targets
        out = np.empty_like(self.start)
        for g, S, rest in self.pieces:
            base = self.along(S, s)(self.start[g]) if S is not None else self.start[g]
            out[g] = base + s * rest
        return out
