"""A clean start for a surface morph whose interpolations cross (:mod:`.morph`), by
IPC's incremental-potential homotopy towards a guide path (the as-rigid-as-possible
interpolation the short way round, else the long way, else the linear one).

From the source, each increment minimizes over ``Q``

    ½ |X(Q) − X(Q_prev)|² + ½ k |Q − P(t)|²_M + κ B(Q)

(the morph's segment energy from the last increment, an attraction of stiffness ``k``
towards the guide frame ``P(t)`` in the lumped mass, IPC's barrier) by Newton steps,
each capped by CCD, so the polyline of iterates passes through no contact. At ``t = 1``
the attraction is raised tenfold until the iterate is within ``REACH_TOLERANCE`` of the
target; where it stalls before (the barrier holds it), there is no start
(:class:`SelfIntersectionError`, saying how far short). The last straight piece onto the
target must be clear: the segment test lets a pair close in by at most fivefold below a
floor (:meth:`..engine.contact.SurfaceContact.segment_free`), so a target whose pairs
lie far closer than that is not reached in one piece from where the barrier holds them;
the barrier is then thinned (``THINNER`` at a time, down to the morph's ``d̂``) and the
attraction pulls on, the iterates closing in on those pairs step by step, until the
piece is clear. No step brings a pair within ``KEEP`` times the morph's ``d̂`` (at most
half either end's closest pair): an iterate pressed closer by the raised attraction has
stalled against the contact, and tight-inclusion CCD grinds on the steps and chords from
it. For the same reason the last piece is first sampled for a pair closer than the
segment test lets one come (:func:`_piece_clear`). The frames are the iterates joined by
the longest chords clear by the morph's segment test (a step is taken only where that
test passes it), the longest chords then split where there are frames to spare, at their
middle iterate (a midpoint of two frames of a turning part shrinks it), at their
midpoint where they join two consecutive iterates; where more are needed than asked, the
refusal gives the count (the fewest over the guides and ``d̂``). The barrier is
``STIFFER`` times IPC's initial stiffness: the iterates keep further from contact and
the clear chords between them are longer. Its ``d̂`` is the surface's own (a fraction of
the mean edge), not the morph's, which ends close to contact lower to below half their
closest pair: a barrier that thin tells Newton nothing of the contact until a step has
passed it, CCD cuts such steps to a sliver of their length, and the iterates pressed
onto the contact creep behind the guide. The ends' pairs within the wider ``d̂`` are
pushed apart by the first increments and come back in the last; every step and chord is
still cleared by the morph's CCD. Where the clean path needs more frames than asked, the
homotopy is run again with ``d̂`` twice and four times the surface's own (``WIDER``):
its iterates keep further from contact and its clear chords are longer. """

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from ..._typing import FloatArray
from ...errors import SelfIntersectionError
from ...solvers import factorize_spd
from ..engine.contact import ContactTerm
from .interpolation import arap_interpolation, fold_crossings
from .morph_contact import chord_picks

__all__ = ["homotopy_path", "homotopy_start"]

logger = logging.getLogger(__name__)

#: the start of the homotopy's refusals
CROSSING = ("the morph finds no path free of self-contact: the interpolations of the ends "
            "pass through the surface")
#: the increments along the guide (whatever the frames asked), Newton steps per increment
#: at most
INCREMENTS, NEWTON_STEPS = 32, 12
#: the attraction's stiffness ``k`` (against the segment energy's mass term, 1), and its
#: tenfold raises at most at the end
ATTRACTION, RAISES = 1.0, 8
#: the barrier's stiffness over IPC's initial one: the further the iterates keep from
#: contact, the longer the clear chords between them
STIFFER = 100.0
#: the largest point distance to the target, over d̂, from which the last piece is taken
REACH_TOLERANCE = 0.5
#: the barrier's d̂ over the surface's own, in turn while the clean path needs more frames
#: than asked: the wider, the further the iterates keep from contact and the longer the
#: clear chords between them
WIDER = (1.0, 2.0, 4.0)
#: the closest an iterate's pair may come, over the morph's d̂ (module docstring)
KEEP = 0.5
#: the points of the last piece onto the target at which it is first sampled for a pair
#: too close (:func:`_piece_clear`)
DIP_SAMPLES = 15
#: the barrier's d̂ over the next one, in turn from the surface's own towards the morph's
#: while the last piece onto the target is not clear
THINNER = 4.0


class _TooFewFrames(SelfIntersectionError):
    """The homotopy's clean path needs more frames than asked (``frames``)."""

    def __init__(self, message: str, frames: int) -> None:
        super().__init__(message)
        self.frames = frames


def _newton(problem, term: ContactTerm, clear, Q: FloatArray, Xprev, P: FloatArray,
            k: float, mass: FloatArray) -> list:
    """The iterates of Newton's method on one increment's energy from ``Q``, each step
    CCD-capped and taken only where ``clear`` (the path's segment test) passes it."""
    def energy(Qt):
        X = problem.embed(Qt)
        if X is None:
            return np.inf
        r = problem.segment(Xprev, X)
        d = (Qt - P).ravel()
        return 0.5 * float(r @ r) + 0.5 * k * float(d @ (mass * d)) + term.energy(Qt)

    out, E = [], energy(Q)
    for _ in range(NEWTON_STEPS):
        J = problem.jacobian(Q)
        r = problem.segment(Xprev, problem.embed(Q))
        g = J.T @ r + k * mass * (Q - P).ravel()
        unset = term.kappa is None
        if term.set_stiffness(Q, g):
            if unset:  # stiffer than IPC's: the iterates keep further from contact
                term.kappa *= STIFFER
                term.max_kappa *= STIFFER
            E = energy(Q)
        g = g + term.gradient(Q)
        H = (J.T @ J + sp.diags(k * mass)).tocsr()
        B = term.hessian(Q)
        if B is not None:
            H = H + B
        step = -factorize_spd(sp.csc_matrix(H))(g)
        cap = term.step_cap(Q, -step)
        for alpha in cap * 0.5 ** np.arange(10):
            trial = Q + alpha * step.reshape(-1, 3)
            E_trial = energy(trial)
            if E_trial < E and clear(Q, trial):
                break
        else:
            break
        decrease, Q, E = E - E_trial, trial, E_trial
        out.append(Q)
        if decrease <= 1e-10 * max(E, 1e-300):
            break
    return out


def _pull(problem, term: ContactTerm, clear, poly: list, P: FloatArray, k: float,
          mass: FloatArray, tolerance: float, raises: int) -> float:
    """One increment towards ``P`` from the last of ``poly`` (:func:`_newton`, its iterates
    appended to ``poly``), the attraction ``k`` raised tenfold, up to ``raises`` times in
    all, until the iterate is within ``tolerance`` of ``P``; the last ``k``."""
    for _ in range(raises):
        poly += _newton(problem, term, clear, poly[-1], problem.embed(poly[-1]), P, k, mass)
        if np.abs(poly[-1] - P).max() <= tolerance:
            break
        k *= 10.0
    return k


def _piece_clear(contact, Q: FloatArray, V1: FloatArray) -> bool:
    """Whether the straight piece from ``Q`` to the target ``V1`` is clear
    (:meth:`.morph_contact.PathContact.segment_clear`); not where a point of it at one of
    ``DIP_SAMPLES`` even times has a pair closer than the test lets one come
    (:meth:`..engine.contact.SurfaceContact.segment_bound`): the test grinds on pieces
    that dip that close."""
    bound = contact.contact.segment_bound(Q)
    near = contact.contact.with_dhat(bound)
    if any(near.minimum_distance((1.0 - t) * Q + t * V1) < bound
           for t in np.linspace(0.0, 1.0, DIP_SAMPLES + 2)[1:-1]):
        return False
    return contact.segment_clear(Q, V1)


def homotopy_path(problem, contact, V0: FloatArray, V1: FloatArray, guide,
                  segments: int, wider: float = 1.0) -> list:
    """A clean path of ``segments + 1`` frames from ``V0`` to ``V1`` (module docstring),
    pulled along ``guide`` (a callable of the times, its frames from ``V0`` to ``V1``),
    the barrier's d̂ ``wider`` times the surface's own; :class:`SelfIntersectionError`
    where the attraction stalls or the iterates need more chords than ``segments``.

    ``problem`` is the morph's path problem (``embed``, ``segment``, ``jacobian``,
    ``sqrt_m``), ``contact`` its :class:`.morph_contact.PathContact`."""
    mass = problem.sqrt_m ** 2
    free, mean_mass = np.ones(V0.size, bool), float(np.mean(mass))
    wide = contact.contact.with_dhat(wider * contact.contact.edge_dhat)
    term = ContactTerm(wide, free, mean_mass)
    dhat = wide.dhat
    times = np.linspace(0.0, 1.0, INCREMENTS + 1)
    P = list(guide(times))
    P[-1] = V1
    keep = KEEP * contact.contact.dhat

    def clear(Q0, Q1):  # a step that keeps every pair apart, on a clear segment
        return contact.contact.minimum_distance(Q1) > keep and contact.segment_clear(Q0, Q1)

    poly = [V0]
    for j in range(1, len(times)):
        logger.debug("start path: the homotopy, increment %d of %d", j, INCREMENTS)
        k = _pull(problem, term, clear, poly, P[j], ATTRACTION, mass,
                  REACH_TOLERANCE * dhat, RAISES if j == len(times) - 1 else 1)

    def reached():  # the last iterate within reach of the target
        return np.abs(poly[-1] - V1).max() <= REACH_TOLERANCE * dhat

    # reached, but the target's pairs end closer than the last piece clears (a pair below
    # the segment test's floor closes in by fivefold at most): the barrier thinner in turn
    done = reached() and _piece_clear(contact, poly[-1], V1)
    while not done and reached() and dhat > contact.contact.dhat:
        dhat = max(dhat / THINNER, contact.contact.dhat)
        logger.debug("start path: the homotopy closing in on the target, d̂ %.3g", dhat)
        term = ContactTerm(contact.contact.with_dhat(dhat), free, mean_mass)
        k = _pull(problem, term, clear, poly, V1, k, mass,
                  REACH_TOLERANCE * dhat, RAISES)
        done = reached() and _piece_clear(contact, poly[-1], V1)
    if not done:
        raise SelfIntersectionError(
            f"{CROSSING}; pulled towards the target through contact, the surface stalls "
            f"{float(np.abs(poly[-1] - V1).max()):.3g} short of it")
    poly.append(V1)
    logger.debug("start path: the homotopy's frames among its %d iterates", len(poly))
    picks = chord_picks(contact, poly)
    frames = [poly[i] for i in picks]
    if len(frames) - 1 > segments:
        raise _TooFewFrames(
            f"{CROSSING}; the clean path found around the contact needs {len(frames)} "
            f"frames, {segments + 1} asked", len(frames))
    while len(frames) - 1 < segments:  # split the longest chord whose halves CCD clears
        gaps = [np.abs(q - p).max() for p, q in zip(frames[:-1], frames[1:])]
        for i in np.argsort(gaps)[::-1]:
            # at its middle iterate, else its midpoint
            a, b = picks[i], picks[i + 1]
            half, m = (poly[(a + b) // 2], (a + b) // 2) if b - a > 1 else (
                0.5 * (frames[i] + frames[i + 1]), a)
            if contact.segment_clear(frames[i], half) and contact.segment_clear(
                    half, frames[i + 1]):
                frames.insert(i + 1, half)
                picks.insert(i + 1, m)
                break
        else:
            raise SelfIntersectionError(f"{CROSSING}; no chord of the clean path found "
                                        "around the contact halves clear")
    return frames


def homotopy_start(problem, contact, V0: FloatArray, V1: FloatArray, triangles,
                   segments: int) -> list:
    """:func:`homotopy_path` pulled along the as-rigid-as-possible interpolation, else
    along the one that turns the neighbours whose short way passes the fold the long way
    round (where there are such, :func:`.interpolation.fold_crossings`), else along the
    linear one; where one of them needs more frames than asked, all again with the
    barrier's d̂ wider (``WIDER``); the refusal with the fewest frames (at once where two
    are asked and one needs three), else the last."""
    guides = [lambda ts: arap_interpolation(V0, V1, triangles, ts)]
    if fold_crossings(V0, V1, triangles).nnz:
        guides.append(lambda ts: arap_interpolation(V0, V1, triangles, ts, long_way=True))
    guides.append(lambda ts: [(1.0 - t) * V0 + t * V1 for t in ts])
    fewest = None
    for wider in WIDER:
        short = False
        for n, guide in enumerate(guides, 1):
            logger.info("start path: the homotopy along guide %d of %d, d̂ %g times the "
                        "surface's own", n, len(guides), wider)
            try:
                return homotopy_path(problem, contact, V0, V1, guide, segments, wider)
            except _TooFewFrames as error:
                short = True
                if fewest is None or error.frames < fewest.frames:
                    fewest = error
                if segments == 1 and fewest.frames == 3:  # the straight motion is not
                    raise fewest  # clear, so no path has 2 frames or needs fewer than 3
            except SelfIntersectionError as error:
                refusal = error
        if not short:
            break
    raise fewest if fewest is not None else refusal
