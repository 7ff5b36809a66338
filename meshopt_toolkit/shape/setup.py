"""Set-up pieces of :func:`meshopt_toolkit.optimize.optimize`: the metric, the retraction,
f2's area-relative β2 and the contact barrier's defaults."""

from __future__ import annotations

import numpy as np

from .._options import check_choice
from ..errors import OptionError
from ..kernels.triangles import signed_areas
from ..mesh import PlanarMesh
from ..scaling import size_scale

#: the contact barrier (β3 of f2): ``μ`` and the cut-off in units of the shortest boundary
#: edge ``h``: ``D^μ`` is smoothed over ``h/4`` and the barrier acts only where a boundary
#: vertex comes within about ``⅔ h`` of a boundary edge it does not belong to (closer than
#: any pair of an admissible, unsqueezed boundary): it keeps holes and notches from
#: closing, and adds exactly 0 elsewhere
CONTACT_MU = 2.0
CONTACT_CUTOFF = (1.5, 3.0)


#: variant -> (gradient metric, retraction along a curve of the complete metric?), the
#: table of :mod:`meshopt_toolkit.optimize` (False: the straight line ``Q + s d``)
VARIANT_PARTS: dict[str, tuple[str, bool]] = {
    "euclidean-euclidean": ("euclidean", False),
    "elasticity-euclidean": ("elasticity", False),
    "complete-euclidean": ("complete", False),
    "complete-complete": ("complete", True),
}
VARIANTS = tuple(VARIANT_PARTS)

#: complete-complete's retractions: second order (the default) or the exponential map
RETRACTIONS = ("second-order", "exp")
DEFAULT_RETRACTION = "second-order"

#: default ``exp_options`` of ``retraction="exp"``: the geodesic's
#: line-search mode (:data:`meshopt_toolkit.riemannian.geodesics.LINE_SEARCH_OPTIONS`;
#: Bogacki–Shampine 3(2) at rtol 5e-2 with energy projection, positions only). Every trial
#: point is still a point of an (approximate) geodesic, admissible and checked exactly; pass
#: ``exp_options={"method": "auto"}`` (with ``retraction="exp"``) for the 1e-6-accurate map.
EXP_DEFAULTS = {"method": "line-search"}


def default_metric_beta(n_vertices: int) -> tuple[float, float, float, float]:
    """β^metric of thesis §6.4.3, (10, 1, 0, 1.46) for 146 vertices, i.e. β4 = 0.01·N."""
    return (10.0, 1.0, 0.0, 0.01 * n_vertices)


def area_relative_beta(beta, mesh: PlanarMesh) -> tuple[float, float, float, float]:
    """β^penalty of :func:`~meshopt_toolkit.optimize.optimize` on ``mesh``: β2 times
    ``(A0 / πR²)²``, the square of the mesh's area over that of the disc of its size ``R``
    (:func:`~meshopt_toolkit.scaling.size_scale`; ``R = 1`` at unit size).

    f2's area term ``β2/ΣA`` then pushes the initial boundary outwards as the thesis' term
    does on the unit disc (``A0 = π``): its derivative with respect to the area at unit
    size is ``−β2/π²`` on a domain of any size and proportions, as ``scale="auto"``
    weighs the objective by its gradient. Without the factor a 6 × 2 plate's pushes
    ``(π/A0)² ≈ 7`` times harder than the unit disc's: against the objective it leaves
    fine meshes without a step at the quality floor of ``scale="auto"``, and once the
    floor's restarts have shrunk the objective's weight it inflates the domain.
    """
    b1, b2, b3, b4 = (float(b) for b in beta)
    if b2:
        area = float(signed_areas(mesh.points, mesh.triangles).sum())
        b2 *= (area / (np.pi * size_scale(mesh).factor ** 2)) ** 2
    return (b1, b2, b3, b4)


def contact_options(mesh: PlanarMesh) -> dict:
    """``mu`` and ``cutoff`` of :class:`~meshopt_toolkit.penalties.QualityPenalty` for the
    contact barrier on ``mesh`` (:data:`CONTACT_MU`, :data:`CONTACT_CUTOFF`)."""
    be = mesh.boundary_edges
    h = float(np.linalg.norm(mesh.points[be[:, 1]] - mesh.points[be[:, 0]], axis=1).min())
    return {"mu": CONTACT_MU / h, "cutoff": (CONTACT_CUTOFF[0] / h, CONTACT_CUTOFF[1] / h)}


def _retraction_options(exp_options: dict | None):
    """The complete-complete retraction's
    :class:`~meshopt_toolkit.riemannian.geodesics.GeodesicOptions`: ``exp_options`` on top
    of :data:`EXP_DEFAULTS`; an ``"options"`` entry (a ``GeodesicOptions``) replaces the
    defaults, the other entries override its fields."""
    from ..riemannian.geodesic_options import GeodesicOptions

    user = dict(exp_options or {})
    base = user.pop("options", None)
    return GeodesicOptions.of(GeodesicOptions.of(EXP_DEFAULTS) if base is None else base, **user)


def _retraction_kind(variant: str, retraction: str, exp_options: dict | None) -> str | None:
    """The retraction asked for, checked against the variant (None: the straight line;
    the default retraction names no request, so it passes with every variant)."""
    check_choice(retraction, RETRACTIONS, "retraction", error=OptionError)
    if not VARIANT_PARTS[variant][1]:
        if retraction != DEFAULT_RETRACTION or exp_options is not None:
            raise OptionError(f"{variant} moves along straight lines; a retraction and "
                              "exp_options apply to complete-complete only")
        return None
    if retraction != "exp" and exp_options is not None:
        raise OptionError("exp_options apply to retraction='exp' only")
    return retraction


def _make_retraction(kind: str, metric, exp_options: dict | None, free):
    from ..riemannian.retractions import ExponentialRetraction, SecondOrderRetraction

    if kind == "exp":
        return ExponentialRetraction(metric, _retraction_options(exp_options), free)
    return SecondOrderRetraction(metric, free)


def _make_metric(variant: str, mesh: PlanarMesh, metric_beta, metric_options: dict):
    from ..riemannian.metrics import CompleteMetric, ElasticityMetric, EuclideanMetric

    kind = VARIANT_PARTS[variant][0]
    if kind == "euclidean":
        return EuclideanMetric()
    if kind == "elasticity":
        return ElasticityMetric(mesh, **metric_options)
    from ..penalties import QualityPenalty

    beta = default_metric_beta(mesh.n_vertices) if metric_beta is None else tuple(metric_beta)
    return CompleteMetric(QualityPenalty(mesh, beta=beta, **metric_options))
