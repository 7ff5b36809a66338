"""Contact along a surface morph (:mod:`.morph`): no frame passes through itself,
and no surface point passes through the surface between consecutive frames.

Each interior frame carries IPC's barrier (:class:`..engine.contact.ContactTerm`, its own
stiffness ``κ``) on the pairs closer than ``d̂``, ``d̂`` below half of either end's
closest pair (:func:`..engine.contact.pair_contact`), added to the path energy. A path is *clean*
where the straight segment between every two consecutive frames is free of contact
(:meth:`..engine.contact.SurfaceContact.segment_free`: ipctk's step check, tight-inclusion
CCD) and no two triangles sharing a vertex meet in a frame (exact): from the clean source,
every frame is then clean too. The start path must be clean; a Levenberg–Marquardt step is
capped by the CCD of each frame's move and accepted only on a clean path, so every iterate
is clean.

Where neither interpolation of the ends is clean, :func:`detour_path` builds a clean start
for a surface of several components: the components that move are shifted along an axis
until their boxes clear the others', moved to the target there, and shifted back.
:func:`graded_path` picks the frames of a path given at any time (an interpolation) where
those at even times are not clean, among samples that approach either end geometrically.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..._typing import FloatArray, IntArray
from ..engine.contact import ContactTerm, SurfaceContact

__all__ = ["PathContact", "chord_picks", "detour_path", "graded_path"]

#: samples per segment at even times, and the halvings of the first sample's time towards
#: either end, among which :func:`graded_path` picks the frames
SAMPLES, HALVINGS = 4, 40


class PathContact:
    """The barrier of a path's interior frames and the CCD of its steps and segments.

    Parameters
    ----------
    contact : SurfaceContact
        The surface's contact (:func:`..engine.contact.pair_contact` of the ends).
    frames : int
        The frames of the path, both ends included.
    mass : (3N,) float array
        The path energy's mass per coordinate (its mean sets IPC's stiffness floor).
    """

    def __init__(self, contact: SurfaceContact, frames: int, mass: FloatArray) -> None:
        free = np.ones(3 * contact.n, bool)
        mean = float(np.mean(mass))
        self.contact = contact
        self.terms = [ContactTerm(contact, free, mean) for _ in range(frames - 2)]

    def energy(self, path: list) -> float:
        """``Σ κ_j B(Q_j)`` over the interior frames (+inf where a pair touches)."""
        return float(sum(t.energy(Q) for t, Q in zip(self.terms, path[1:-1])))

    def gradient(self, path: list) -> FloatArray:
        """The barriers' gradient over the interior frames' coordinates."""
        return np.concatenate([t.gradient(Q) for t, Q in zip(self.terms, path[1:-1])])

    def hessians(self, path: list) -> list:
        """Per interior frame the barrier's projected Hessian, None where none is active."""
        return [t.hessian(Q) for t, Q in zip(self.terms, path[1:-1])]

    def set_stiffness(self, path: list, gradient: FloatArray) -> bool:
        """Set or raise each frame's ``κ`` against the path energy's ``gradient`` (over
        the interior frames' coordinates); whether one changed."""
        g = gradient.reshape(len(self.terms), -1)
        return any([t.set_stiffness(Q, gj) for t, Q, gj in zip(self.terms, path[1:-1], g)])

    def cap(self, path: list, step: FloatArray) -> float:
        """The largest fraction in [0, 1] of ``step`` (over the interior frames'
        coordinates) that moves no frame through contact (CCD)."""
        s = step.reshape(len(self.terms), -1)
        return min([1.0] + [t.step_cap(Q, -sj) for t, Q, sj in zip(self.terms, path[1:-1], s)])

    def segment_clear(self, Q0: FloatArray, Q1: FloatArray) -> bool:
        """Whether the straight segment from the clean ``Q0`` to ``Q1`` is free of
        contact (:meth:`..engine.contact.SurfaceContact.segment_free`)."""
        return self.contact.segment_free(Q0, Q1)

    def embedded(self, Q: FloatArray) -> bool:
        """Whether no two triangles sharing a vertex meet at ``Q`` (exact)."""
        return not self.contact.neighbours_meet(Q)

    def clean(self, path: list) -> bool:
        """Whether every segment between consecutive frames is free of contact and no
        interior frame has two triangles sharing a vertex that meet (module docstring)."""
        return all(self.segment_clear(a, b) for a, b in zip(path[:-1], path[1:])) and all(
            self.embedded(Q) for Q in path[1:-1])


def _components(n: int, triangles: IntArray) -> IntArray:
    """The connected component of each point (through the triangles' edges)."""
    F = np.asarray(triangles)
    rows = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    cols = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    graph = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def _shifts(V0: FloatArray, V1: FloatArray, moving: np.ndarray, margin: float) -> list:
    """The six axis shifts that carry the ``moving`` points' box (over both ends) clear of
    the other points' box (over both ends) by ``margin``, shortest first."""
    both, mask = np.vstack([V0, V1]), np.concatenate([moving, moving])
    lo_m, hi_m = both[mask].min(0), both[mask].max(0)
    lo_r, hi_r = both[~mask].min(0), both[~mask].max(0)
    out = []
    for axis in range(3):
        for sign, length in ((1.0, hi_r[axis] - lo_m[axis]), (-1.0, hi_m[axis] - lo_r[axis])):
            d = np.zeros(3)
            d[axis] = sign * (max(length, 0.0) + margin)
            out.append(d)
    return sorted(out, key=lambda d: float(np.abs(d).max()))


def _frames_on(legs: list, segments: int) -> list | None:
    """``segments + 1`` frames on the polygon of configurations ``legs``, every corner a
    frame, each leg's share of the segments proportional to its largest point move (at
    least one); None where there are fewer segments than legs."""
    legs = [legs[0]] + [b for a, b in zip(legs[:-1], legs[1:]) if not np.array_equal(a, b)]
    n = len(legs) - 1
    if segments < n:
        return None
    lengths = np.array([np.abs(b - a).max() for a, b in zip(legs[:-1], legs[1:])])
    share = np.ones(n, int)
    for _ in range(segments - n):  # the next segment to the leg with the longest pieces
        share[int(np.argmax(lengths / share))] += 1
    frames = [legs[0]]
    for (a, b), m in zip(zip(legs[:-1], legs[1:]), share):
        frames += [(1.0 - t) * a + t * b for t in np.arange(1, m + 1) / m]
    frames[-1] = legs[-1]
    return frames


def detour_path(contact: PathContact, V0: FloatArray, V1: FloatArray, triangles: IntArray,
                segments: int) -> list | None:
    """A clean path of ``segments + 1`` frames from ``V0`` to ``V1`` around the other
    components (module docstring), the shortest shift first; None where none is clean.

    The components that move between the ends are shifted together where some component
    stays; where all move, each alone (the others moving straight)."""
    comp = _components(len(V0), triangles)
    labels = np.unique(comp)
    moves = [c for c in labels if not np.array_equal(V0[comp == c], V1[comp == c])]
    if len(labels) < 2 or not moves:
        return None
    groups = [np.isin(comp, moves)] if len(moves) < len(labels) else [comp == c for c in labels]
    margin = 2.0 * contact.contact.dhat + 0.05 * float(np.abs(V0.max(0) - V0.min(0)).max())
    for moving in groups:
        for d in _shifts(V0, V1, moving, margin):
            shift = np.where(moving[:, None], d, 0.0)
            legs = [V0, V0 + shift, V1 + shift, V1]
            frames = _frames_on(legs, segments)
            if frames is not None and contact.clean(frames):
                return frames
    return None


def chord_picks(contact: PathContact, poly: list) -> list:
    """Indices of frames on the clear polyline ``poly``, its ends included: from each, the
    farthest point of ``poly`` up to which the chord is clear (CCD)."""
    picks, a = [0], 0
    while a < len(poly) - 1:
        b = a + 1
        while b + 1 < len(poly) and contact.segment_clear(poly[a], poly[b + 1]):
            b += 1
        picks.append(b)
        a = b
    return picks


def graded_path(contact: PathContact, frames_at, segments: int) -> list | None:
    """``segments + 1`` frames of the path ``frames_at`` (a callable of times in [0, 1],
    its frames) from its first to its last: those at even times where every segment
    between them is clear; else picked among samples at ``SAMPLES`` times as many even
    times and at times halving towards either end (``HALVINGS`` of them, none whose points
    all lie within ``d̂/2`` of that end), the longest clear chords (:func:`chord_picks`),
    the chords over the most samples then split at their middle sample while there are
    frames to spare; None where the samples are not clear or the chords need more
    frames.

    The halvings approach an end close to contact geometrically: below the step check's
    floor a segment may close a pair by fivefold at most
    (:meth:`..engine.contact.SurfaceContact.segment_free`), which even times cannot do."""
    frames = frames_at(np.linspace(0.0, 1.0, segments + 1))
    if all(contact.segment_clear(a, b) for a, b in zip(frames[:-1], frames[1:])):
        return frames
    even = np.linspace(0.0, 1.0, SAMPLES * segments + 1)
    halved = even[1] * 0.5 ** np.arange(1, HALVINGS + 1)
    poly = frames_at(np.unique(np.concatenate([even, halved, 1.0 - halved])))
    # none within d̂/2 of an end (d̂ is below half its closest pair): the segment onto the
    # end from the next one keeps that pair's distance within twice itself, clear
    near = 0.5 * contact.contact.dhat
    poly = [poly[0]] + [Q for Q in poly[1:-1] if min(
        np.abs(Q - poly[0]).max(), np.abs(Q - poly[-1]).max()) > near] + [poly[-1]]
    if not all(contact.segment_clear(a, b) for a, b in zip(poly[:-1], poly[1:])):
        return None
    picks = chord_picks(contact, poly)
    while len(picks) - 1 < segments:
        spans = np.diff(picks)
        for i in np.argsort(-spans, kind="stable"):
            a, m, b = picks[i], (picks[i] + picks[i + 1]) // 2, picks[i + 1]
            if m > a and contact.segment_clear(poly[a], poly[m]) and contact.segment_clear(
                    poly[m], poly[b]):
                picks.insert(i + 1, m)
                break
        else:
            return None
    return [poly[i] for i in picks] if len(picks) - 1 == segments else None
