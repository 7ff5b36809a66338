"""Filter ``apply_coord_shape_optimization``: minimize a PDE objective + f2 over admissible
meshes."""

from __future__ import annotations

from meshopt_toolkit.expressions import DEFAULT_RHS
from meshopt_toolkit.optimize import (DEFAULT_METHOD, DEFAULT_RETRACTION, DEFAULT_VARIANT, METHODS,
                                      RETRACTIONS, VARIANTS)
from meshopt_toolkit.pipeline.filter import PLANAR, TETS, Filter, register
from meshopt_toolkit.shape.spec import PDES
from meshopt_toolkit.shape.preconditioners import DEFAULT_PRECONDITIONER, PRECONDITIONERS
from meshopt_toolkit.pipeline.params import (
    BoolParam,
    EnumParam,
    ExpressionParam,
    FloatParam,
    IntParam,
    NumberListParam,
    StringParam,
    number_list,
)


@register
class ShapeOptimization(Filter):
    """PDE-constrained shape optimization of the current planar or tet mesh (thesis ch. 6).

    Minimizes ``w j(Q) + f2(Q; Q0)`` with ``j = ∫ y`` (or ``½∫(y − y_d)²``), ``−Δy = r``,
    ``y = 0`` on the boundary unless Dirichlet/Neumann data per physical group say otherwise
    (P1, centroid quadrature); or the compliance of a linear elastic body (plane stress)
    under boundary stresses; or the dissipation of Stokes flow around moved bodies;
    optionally with some groups fixed, only some moving and the area and the moving
    body's barycenter kept exactly (:class:`meshopt_toolkit.shape.spec.ProblemSpec`); ``w`` is scaled to
    the mesh by default. By Riemannian L-BFGS (default), nonlinear CG or the thesis'
    steepest descent (:func:`meshopt_toolkit.optimize.optimize`). ``r`` is parsed by the safe expression
    evaluator (never ``eval``). β4 is unscaled (f2 divides it by 2N). Empty β strings mean
    the defaults: β^penalty = (0.1, 0.01, 0.01, 0.146), thesis parameter set 2 at 146 vertices
    with β4 fixed on every mesh (:data:`meshopt_toolkit.optimize.DEFAULT_PENALTY_BETA`),
    β^metric = (10, 1, 0, 0.01·N). A tet mesh is optimized in 3D
    (:mod:`meshopt_toolkit.shape.tets`: the tet motion's metric, a distortion penalty with
    β = β1). The optimized mesh replaces the current one; the summary holds status,
    iterations, j, j + f2 and the quality (Λ and AR; the mean ratios on tets).
    """

    name = "apply_coord_shape_optimization"
    label = "Shape Optimization (meshopt)"
    #: the former name, still accepted in saved pipelines
    aliases = ("compute_shape_optimization",)
    description = ("Minimize a PDE objective (Poisson, elasticity compliance, Stokes dissipation) "
                   "plus a mesh-quality penalty, keeping the mesh admissible.")
    kinds = (PLANAR, TETS)
    parameters = (
        EnumParam("variant", DEFAULT_VARIANT, "gradient metric and retraction",
                  label="Variant", choices=VARIANTS),
        EnumParam("method", DEFAULT_METHOD, "lbfgs: Riemannian L-BFGS, cg: nonlinear CG "
                  "(Hestenes-Stiefel+), steepest: the thesis' steepest descent",
                  label="Method", choices=METHODS),
        EnumParam("retraction", DEFAULT_RETRACTION, "complete-complete only: second-order "
                  "(Q + s d + s²A/2, one Hessian product per iteration) or exp (the thesis' "
                  "exponential map)", label="Retraction", choices=RETRACTIONS),
        EnumParam("lbfgs_preconditioner", DEFAULT_PRECONDITIONER, "lbfgs only: initial "
                  "inverse Hessian B⁻¹ of the two-loop recursion; penalty: f2's Hessian, "
                  "elasticity: K + δM, none: the metric, auto: penalty for complete-* variants",
                  label="L-BFGS preconditioner", choices=PRECONDITIONERS),
        IntParam("memory", 10, "L-BFGS memory (curvature pairs kept)", label="L-BFGS memory",
                 min=1, max=1000),
        ExpressionParam("rhs", DEFAULT_RHS, "right-hand side r(x1, x2) of -Δy = r; numbers, "
                        "+ - * / **, x/y/x1/x2, pi, e, sin, cos, tan, exp, log, sqrt, abs, min, max",
                    label="Right-hand side"),
        NumberListParam("penalty", "", "beta^penalty b1,b2,b3,b4 (b4 unscaled); empty = 0.1,0.01,0.01,0.146",
                    label="Penalty beta", count=4),
        NumberListParam("metric_penalty", "", "beta^metric b1,b2,b3,b4; empty = 10,1,0,0.01*N",
                    label="Metric beta", count=4),
        IntParam("max_iterations", 1000, "maximum number of iterations", label="Max iterations",
                 min=1, max=100000),
        FloatParam("tolerance", 1e-6, "stopping tolerance of (6.26) (relative for lbfgs/cg); "
                   "0 = off",
                   label="Tolerance", min=0.0),
        StringParam("fixed", "", "physical groups (names or numbers, comma-separated) whose "
                    "vertices stay", label="Fixed groups"),
        StringParam("move", "", "only these boundary groups move (comma-separated); empty = "
                    "the whole boundary", label="Moving groups"),
        EnumParam("pde", "auto", "the state equation; auto: the objective's",
                  label="PDE", choices=("auto",) + tuple(PDES)),
        StringParam("dirichlet", "", "GROUP=VALUE,...: Poisson y = VALUE on the group (y = 0 on "
                    "the rest of the boundary); Stokes GROUP=VX,VY: the velocity (u = 0 on the "
                    "rest)", label="Dirichlet data"),
        StringParam("neumann", "", "GROUP=VALUE,...: dy/dn = VALUE on the group",
                    label="Neumann data"),
        StringParam("stress", "", "GROUP=SXX,SYY,SXY,...: elasticity traction sigma n on the "
                    "group (the rest of the boundary is free)", label="Boundary stress"),
        StringParam("clamped", "", "elasticity: groups with u = 0 (none: the body floats "
                    "and its loads must balance)", label="Clamped groups"),
        FloatParam("young", 1.0, "elasticity: Young's modulus E", label="Young's modulus",
                   min=0.0, exclusive_min=True),
        FloatParam("poisson_ratio", 0.3, "elasticity: Poisson ratio nu (plane stress), "
                   "-1 < nu < 0.5", label="Poisson ratio", min=-1.0, max=0.5,
                   exclusive_min=True),
        FloatParam("viscosity", 1.0, "Stokes: viscosity mu", label="Viscosity", min=0.0,
                   exclusive_min=True),
        BoolParam("keep_area", False, "keep the domain's area exactly (lbfgs, cg)",
                  label="Keep area"),
        BoolParam("keep_barycenter", False, "keep the barycenter of the region the moving "
                  "groups enclose exactly (lbfgs, cg)", label="Keep barycenter"),
        StringParam("objective", "", "integral (the integral of y), 'tracking: EXPR' (half "
                    "the integral of (y - EXPR)^2), compliance or dissipation; empty: the "
                    "PDE's first (integral)", label="Objective"),
        StringParam("objective_scale", "auto", "weight w of F = w j + f2: a number, or auto "
                    "(scaled to the mesh, guarding the worst triangle)", label="Objective scale"),
    )

    def apply(self, document, *, variant: str = DEFAULT_VARIANT, method: str = DEFAULT_METHOD,
              retraction: str = DEFAULT_RETRACTION,
              lbfgs_preconditioner: str = DEFAULT_PRECONDITIONER, memory: int = 10,
              rhs: str = DEFAULT_RHS,
              penalty: str = "", metric_penalty: str = "", max_iterations: int = 1000,
              tolerance: float = 1e-6, fixed: str = "", move: str = "", dirichlet: str = "",
              neumann: str = "", keep_area: bool = False, objective: str = "",
              objective_scale: str = "auto", pde: str = "auto", stress: str = "",
              clamped: str = "", young: float = 1.0, poisson_ratio: float = 0.3,
              viscosity: float = 1.0, keep_barycenter: bool = False) -> dict:
        from meshopt_toolkit.optimize import DEFAULT_PENALTY_BETA, OptimizeOptions, optimize
        from meshopt_toolkit.shape.spec import kept_constraints, spec_from_options

        entry = document.current_entry
        # the plane's coordinates at the file's scale (r is given in them); None: tets
        wp = entry.workpiece(self.name, required=False)
        mesh = entry.mesh.require_admissible() if wp is None else wp.mesh
        beta = number_list(penalty, 4, "penalty") or DEFAULT_PENALTY_BETA
        spec = spec_from_options(fixed=fixed, move=move, dirichlet=dirichlet, neumann=neumann,
                                 keep=kept_constraints(keep_area, keep_barycenter),
                                 objective=objective, rhs=rhs, scale=objective_scale,
                                 pde=pde, stress=stress, clamped=clamped,
                                 material=dict(young=young, poisson_ratio=poisson_ratio,
                                               viscosity=viscosity))
        result = optimize(
            mesh, None, problem=spec, variant=variant, method=method,
            penalty=beta, metric_beta=number_list(metric_penalty, 4, "metric_penalty"),
            max_iterations=max_iterations,
            options=OptimizeOptions(retraction=retraction, memory=memory,
                                    lbfgs_preconditioner=lbfgs_preconditioner,
                                    tolerance=tolerance or None),
        )
        if wp is None:  # the same tets at new points: the file's groups and data kept
            entry.replace_mesh(entry.mesh.with_points(result.x))
        else:
            entry.set_workpiece(wp.moved(result.mesh.points))
        return result.summary()
