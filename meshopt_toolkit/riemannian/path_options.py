"""How :func:`~meshopt_toolkit.riemannian.discrete_geodesic.discrete_geodesic` minimizes
the path energy: its two methods and one settings object per method (every field has a
default)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


#: the minimizers of the path energy ("auto": Levenberg–Marquardt where the metric provides
#: a least-squares path model, else Newton–CG)
METHODS = ("auto", "newton-cg", "levenberg-marquardt")

#: relative size below which a change of the energy is rounding (its evaluation sums
#: thousands of rounded terms)
ENERGY_RESOLUTION = 100 * np.finfo(float).eps
#: the damping's factor after a step whose decrease the model predicted well (ρ > 0.75).
#: The paths have soft directions (a frame sliding along itself) that a damped step
#: barely moves along; with the usual 1/3 the last iterations wait for λ to fall.
LAMBDA_DECREASE = 0.1
#: damping below which a step is the model's own (Gauss–Newton or Newton) step. Such a
#: step that promises less than ``ENERGY_RESOLUTION · E`` cannot be judged by E (its
#: change is rounding, ~1e-16·E, either sign): it is taken if it lowers |∇E| (one
#: assembly at the trial, reused as the next iteration's), and where it does not, the
#: path is converged to machine precision. The ratio test alone would reject such steps
#: on E's rounding and raise λ each time, so a target changed by rounding could take
#: more iterations.
UNDAMPED = 1e-6


@dataclass(frozen=True)
class NewtonCGOptions:
    """Settings of the Newton–CG minimizer (the complete metric ``I + ∇f∇fᵀ``).

    Attributes
    ----------
    tolerance : stop when ``√(∇E·H_GN⁻¹∇E) ≤ tolerance·√E`` (status "converged")
    energy_rtol, window : also stop when ``E`` fell by less than ``energy_rtol·E`` per
        iteration on average over the last ``window`` iterations (status "stationary").
        Near the minimizer the frames hold nearly degenerate triangles whose barrier
        makes the quadratic model valid only in a tiny region: Newton then creeps, so the
        stagnation test saves most of the work at no visible cost (0 disables it)
    max_iterations, max_cg : Newton iterations and CG iterations per Newton step
    """

    tolerance: float = 1e-9
    energy_rtol: float = 1e-7
    window: int = 20
    max_iterations: int = 500
    max_cg: int = 200


@dataclass(frozen=True)
class LevenbergMarquardtOptions:
    """Settings of the Levenberg–Marquardt minimizer (metrics with a least-squares path
    model, e.g. the per-triangle distortion metric).

    Attributes
    ----------
    gtol : stop when ``|∇E| ≤ gtol · max(1, √E)``; also reported "converged" when no step
        can lower ``E`` by more than its floating-point resolution (``ENERGY_RESOLUTION``
        relative): the minimum to machine precision, which a tight ``gtol`` on a large
        energy may not reach.
    rtol : or when ``|∇E| ≤ rtol · |∇E₀|`` (the first gradient): enough for a relaxation
        whose start is already close (the Gauss–Newton steps then converge fast).
    max_iterations : iterations
    cg_rtol : relative residual of the conjugate-gradient solve of each step. An inexact
        step is fine (the ratio test judges it): a looser residual takes the same
        iterations to the same frames in less time; move's relaxations and quality rounds
        and the morph use 0.1 (see where they say so).
    newton : steps from the Hessian of the energy (True) or from its Gauss–Newton part
        ``JᵀJ`` (False). Where the residual is not small (a frame pulled towards strains
        it cannot reach: move's relaxations and quality step), Gauss–Newton converges only
        linearly and Newton's steps save iterations. On the morph's paths from a cold
        start they save none; from the refined frames of a coarser level they do
        (``motion.planar.morph.REFINED_CG_RTOL``). The Hessian may be indefinite: a step on which
        conjugate gradients meet non-positive curvature is rejected like one that raises
        the energy (the damping ``λ·diag(JᵀJ)`` grows until the matrix is positive
        definite).
    lambda_decrease : the damping's factor after a step whose decrease the model predicted
        well (``ρ > 0.75``; :data:`LAMBDA_DECREASE`). Newton steps from a start close to
        the minimizer converge quadratically only once the damping is gone: there a
        smaller factor gets there sooner (``motion.planar.morph.REFINED_LAMBDA_DECREASE``).
    factors : the step solver's kept state (for the distortion metric a ``FrameBlocks``,
        the preconditioner's frame factorizations), shared with the caller: a sequence of
        close problems with the same free coordinates (the frames of a continuation)
        factorizes only when conjugate gradients slow down, not once per problem. None:
        a fresh one per call.
    """

    gtol: float = 1e-7
    rtol: float = 0.0
    max_iterations: int = 200
    cg_rtol: float = 1e-2
    newton: bool = False
    lambda_decrease: float = LAMBDA_DECREASE
    factors: object | None = None


#: the settings class of each method
OPTIONS = {"newton-cg": NewtonCGOptions, "levenberg-marquardt": LevenbergMarquardtOptions}


def options_for(method: str, options=None):
    """The settings of ``method`` from ``options``: None (the defaults), a mapping of
    fields, or an instance of the method's class. A field or class of another method is a
    TypeError naming it."""
    cls = OPTIONS[method]
    if options is None:
        return cls()
    if isinstance(options, Mapping):
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise TypeError(f"unknown {method} setting(s) {', '.join(unknown)}; "
                            f"known: {', '.join(sorted(known))}")
        return cls(**options)
    if not isinstance(options, cls):
        raise TypeError(f"method {method!r} takes {cls.__name__} settings, "
                        f"got {type(options).__name__}")
    return options
