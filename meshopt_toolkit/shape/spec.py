"""The user's shape problem in one value: the PDE, which boundary moves, the boundary
conditions, the objective, the exact constraints and the objective's weight.

=============  ===========================  ===============================================
``pde``        objectives                   data by physical group
=============  ===========================  ===============================================
``poisson``    ``integral``, ``tracking``   ``dirichlet`` ``y`` values, ``neumann`` fluxes
``elasticity`` ``compliance``               ``stress`` (traction ``σ n``), ``clamped``
``stokes``     ``dissipation``              ``dirichlet`` velocity vectors (``u = 0`` on
                                            the rest of the boundary)
=============  ===========================  ===============================================

:class:`ProblemSpec` is what ``meshopt optimize``'s options, the
``apply_coord_shape_optimization`` filter's parameters and library callers fill in; physical
groups are gmsh physical groups of line elements (of triangles on a tet mesh), by name or number
(:func:`~meshopt_toolkit.fem.boundary_data.group_key`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .._options import check_choice
from .._typing import FloatArray
from ..errors import MeshoptError, OptimizationError, OptionError

__all__ = ["AUTO_GRADIENT_NORM", "GUARD_FACTOR", "GUARD_TRIES", "OBJECTIVES", "PDES",
           "KEEPS", "QUALITY_GUARD", "ProblemSpec", "ScaledObjective", "kept_constraints",
           "parse_assignment",
           "parse_objective", "parse_scale", "spec_from_options"]

#: objectives: ``integral`` (∫y), ``tracking: EXPR`` (½∫(y − y_d)², y_d = EXPR),
#: ``compliance`` (∫_Γ t·u), ``dissipation`` (∫2μ|ε(u)|²)
OBJECTIVES = ("integral", "tracking: EXPR", "compliance", "dissipation")

#: PDE → the objectives it defines (the first is its default)
PDES = {"poisson": ("integral", "tracking"), "elasticity": ("compliance",),
        "stokes": ("dissipation",)}

#: ``scale="auto"`` weighs j so that its gradient in the elasticity metric at the initial
#: mesh has this norm: the objective then moves the mesh as much as the default penalty
#: allows on every domain and every unit of the load (``benchmarks/bench_optimize.py
#: --users``: plates with holes, L-shapes, airfoils in boxes, channels with obstacles keep
#: their worst triangle ≥ ½ its initial aspect ratio)
AUTO_GRADIENT_NORM = 0.02

#: ``scale="auto"`` also guards the worst triangle: a trial configuration whose minimum
#: aspect ratio is below ``QUALITY_GUARD`` times the initial one is rejected like one
#: outside ``M+`` (the mean-quality term of f2 barely sees one triangle among thousands),
#: and a run that finds no step (``step_too_small``) restarts from the initial mesh with
#: the weight divided by ``GUARD_FACTOR``, at most ``GUARD_TRIES`` times (where none
#: goes on to the end, the attempt of least j is the result)
QUALITY_GUARD = 0.5
GUARD_FACTOR = 4.0
GUARD_TRIES = 4


def _objective_name(text: str) -> str:
    """The registered name of an objective text (``"tracking: EXPR"`` → ``"tracking"``)."""
    t = (text or "integral").strip()
    if t in ("integral", "int y", "∫y", "compliance", "dissipation"):
        return "integral" if t in ("int y", "∫y") else t
    head, sep, expr = t.partition(":")
    if sep and head.strip() == "tracking" and expr.strip():
        return "tracking"
    raise MeshoptError(f"unknown objective {text!r}; use 'integral', 'tracking: EXPR', "
                       "'compliance' or 'dissipation'")


def parse_objective(text: str) -> str | None:
    """The tracking target of ``"tracking: EXPR"`` (None for the other objectives)."""
    if _objective_name(text) != "tracking":
        return None
    return text.partition(":")[2].strip()


def parse_assignment(text: str, option: str, count: int | None = 1
                     ) -> tuple[str, float | tuple[float, ...]]:
    """``"GROUP=VALUE"`` → ``(GROUP, VALUE)``; ``"GROUP=V1,V2,…"`` → ``(GROUP, (V1, …))``
    when ``count`` is not 1 (None: any number of components, checked later)."""
    group, sep, value = str(text).partition("=")
    try:
        v = tuple(float(x) for x in value.split(","))
    except ValueError:
        v = (math.nan,)
    what = "a finite number" if count == 1 else (f"{count} finite numbers" if count
                                                 else "finite numbers")
    if not sep or not group.strip() or not all(map(math.isfinite, v)) or \
            (count is not None and len(v) != count):
        raise MeshoptError(f"{option} {text!r}: expected GROUP=VALUE with {what}")
    return group.strip(), (v[0] if count == 1 else v)


def _assignments(value) -> list[str]:
    """``GROUP=V[,V…]`` items of a comma-separated string or a sequence of them: a
    comma-separated token without ``=`` continues the previous item's value."""
    out: list[str] = []
    for x in _items(value):
        if "=" not in x and out:
            out[-1] += "," + x
        else:
            out.append(x)
    return out


def _items(value) -> list[str]:
    """A comma-separated string or a sequence of them, as a flat list of stripped items."""
    if value is None:
        return []
    parts = [value] if isinstance(value, str) else list(value)
    return [x.strip() for p in parts for x in str(p).split(",") if x.strip()]


def parse_scale(text) -> float | str:
    """``"auto"`` or a positive number."""
    if isinstance(text, str) and text.strip() == "auto":
        return "auto"
    try:
        v = float(text)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise OptimizationError(f"objective scale must be 'auto' or a positive number, not {text!r}")
    return v


#: the constraints ``spec_from_options`` holds exactly ("volume": the area's 3D name)
KEEPS = frozenset({"area", "volume", "barycenter"})


def kept_constraints(area: bool, barycenter: bool) -> tuple[str, ...]:
    """The ``keep`` of :func:`spec_from_options` from the two flags of the CLI and the filter."""
    return ("area",) * bool(area) + ("barycenter",) * bool(barycenter)


def spec_from_options(*, fixed=(), move=(), dirichlet=(), neumann=(), keep=(),
                      objective="", rhs="default", scale="auto", pde="", stress=(),
                      clamped=(), material=None) -> ProblemSpec:
    """A :class:`ProblemSpec` from option strings: groups and ``GROUP=VALUE`` items
    comma-separated (or repeated; a vector value ``GROUP=V1,V2``), ``keep`` the
    constraints held exactly (``"area"`` or its 3D name ``"volume"``, ``"barycenter"``),
    ``scale`` ``"auto"`` or a number, ``material`` ``{"young", "poisson_ratio",
    "viscosity"}`` (the defaults where missing). An empty (or ``"auto"``) ``pde`` is the
    objective's, an empty ``objective`` the PDE's first."""
    from ..fem.boundary_data import group_key

    pde = (pde or "").strip()
    pde = "" if pde == "auto" else pde
    if pde and pde not in PDES:
        raise OptionError(f"--pde {pde!r}: choose one of {', '.join(PDES)}")
    if not (objective or "").strip():
        objective = PDES[pde or "poisson"][0]
    scalar = (pde or "poisson") == "poisson"
    groups = [(g, "--dirichlet") for g in _assignments(dirichlet)]
    kept = set(_items(keep))
    if kept - KEEPS:
        raise OptionError(f"keep {', '.join(sorted(kept - KEEPS))!r}: choose from "
                          f"{', '.join(sorted(KEEPS))}")
    return ProblemSpec(
        fixed=tuple(group_key(g) for g in _items(fixed)),
        move=tuple(group_key(g) for g in _items(move)),
        dirichlet=dict(parse_assignment(a, o, 1 if scalar else None) for a, o in groups),
        neumann=dict(parse_assignment(a, "--neumann") for a in _assignments(neumann)),
        stress=dict(parse_assignment(a, "--stress", None) for a in _assignments(stress)),
        clamped=tuple(group_key(g) for g in _items(clamped)),
        keep_area=bool(kept & {"area", "volume"}), keep_barycenter="barycenter" in kept,
        objective=objective, pde=pde, rhs=rhs, material=dict(material or {}),
        scale=parse_scale(scale))


class ScaledObjective:
    """``w · j``: an objective weighed for the penalty (``value``, ``derivative``)."""

    def __init__(self, objective, weight: float) -> None:
        self.objective, self.weight = objective, float(weight)

    def value(self, Q: FloatArray) -> float:
        return self.weight * float(self.objective.value(Q))

    def derivative(self, Q: FloatArray) -> FloatArray:
        return self.weight * np.asarray(self.objective.derivative(Q), dtype=float)


#: stress components of ``--stress`` by dimension (Voigt order)
STRESS_COMPONENTS = {2: ("SXX", "SYY", "SXY"), 3: ("SXX", "SYY", "SZZ", "SYZ", "SXZ", "SXY")}

#: material constants and their defaults: Young's modulus, Poisson ratio (plane stress
#: in 2D), viscosity
MATERIAL = {"young": 1.0, "poisson_ratio": 0.3, "viscosity": 1.0}


def stress_tensor(components, d: int, group) -> np.ndarray:
    """The ``(d, d)`` symmetric stress of ``--stress GROUP=`` components
    (:data:`STRESS_COMPONENTS`)."""
    names = STRESS_COMPONENTS[d]
    c = np.atleast_1d(np.asarray(components, dtype=float))
    if c.shape != (len(names),):
        raise OptionError(f"--stress {group}: a stress in {d}D has {len(names)} components "
                          f"{','.join(names)}, not {c.size}")
    if d == 2:
        return np.array([[c[0], c[2]], [c[2], c[1]]])
    return np.array([[c[0], c[5], c[4]], [c[5], c[1], c[3]], [c[4], c[3], c[2]]])


def _boundary_facets(mesh) -> np.ndarray:
    """A mesh's oriented boundary facets: its boundary edges, or a tet mesh's outward faces."""
    return mesh.boundary_faces if np.shape(mesh.points)[1] == 3 else mesh.boundary_edges


def _closed(facets: np.ndarray) -> bool:
    """Whether oriented facets close around regions: every vertex (2D) or directed edge
    (3D) of a facet is met once, reversed, by another."""
    if facets.shape[1] == 2:
        starts, ends = np.sort(facets[:, 0]), np.sort(facets[:, 1])
        return bool(np.array_equal(starts, ends) and len(np.unique(starts)) == len(starts))
    edges = np.concatenate([facets[:, [0, 1]], facets[:, [1, 2]], facets[:, [2, 0]]])
    forward = {tuple(e) for e in edges.tolist()}
    return len(forward) == len(edges) and forward == {(b, a) for a, b in forward}


@dataclass(frozen=True)
class ProblemSpec:
    """A shape problem on a mesh with physical groups.

    Attributes
    ----------
    fixed : groups whose vertices do not move
    move : if given, only these boundary groups move: every other boundary vertex (a
        corner shared with a moving group included) stays; interior vertices move
    dirichlet : ``{group: value}``: Poisson ``y = value`` there (``y = 0`` on the rest of
        the boundary that is not Neumann); Stokes ``u = value`` (a vector; ``u = 0`` on
        the rest of the boundary)
    neumann : ``{group: value}``, ``∂y/∂n = value`` there (Poisson)
    stress : ``{group: components}``: elasticity traction ``σ n`` there
        (:data:`STRESS_COMPONENTS`; the rest of the boundary is traction-free)
    clamped : elasticity groups with ``u = 0`` (none: the body floats, its loads must be
        in equilibrium)
    keep_area : the domain's area is an exact constraint (lbfgs and cg only)
    keep_barycenter : the barycenter of the region the moving groups enclose is an exact
        constraint (lbfgs and cg only; with ``keep_area`` that region's area is kept,
        the domain's too since the rest of the boundary stays)
    objective : ``"integral"`` (``∫y``), ``"tracking: EXPR"`` (``½∫(y − y_d)²``),
        ``"compliance"`` or ``"dissipation"`` (:mod:`.objectives`)
    pde : ``"poisson"``, ``"elasticity"`` or ``"stokes"`` (:data:`PDES`); empty: the
        objective's
    rhs : right-hand side ``r`` of ``−Δy = r`` (``"default"``: the thesis' disc demo rhs)
    material : ``{"young", "poisson_ratio", "viscosity"}`` (:data:`MATERIAL` where missing)
    scale : weight ``w`` of ``F = w j + f2``: a number, or ``"auto"``
        (:data:`AUTO_GRADIENT_NORM`)
    """

    fixed: tuple = ()
    move: tuple = ()
    dirichlet: Mapping = field(default_factory=dict)
    neumann: Mapping = field(default_factory=dict)
    keep_area: bool = False
    objective: str = "integral"
    rhs: object = "default"
    scale: float | str = 1.0
    pde: str = ""
    stress: Mapping = field(default_factory=dict)
    clamped: tuple = ()
    keep_barycenter: bool = False
    material: Mapping = field(default_factory=dict)

    def __post_init__(self) -> None:
        name = _objective_name(self.objective)
        pde = self.pde or next(p for p, names in PDES.items() if name in names)
        check_choice(pde, PDES, "PDE", error=OptionError)
        if name not in PDES[pde]:
            raise OptionError(f"--objective {name} is not defined by --pde {pde} "
                              f"(it defines {', '.join(PDES[pde])})")
        object.__setattr__(self, "pde", pde)
        given = {"--neumann": self.neumann, "--stress": self.stress, "--clamped": self.clamped,
                 "--dirichlet": self.dirichlet}
        allowed = {"poisson": ("--neumann", "--dirichlet"), "elasticity": ("--stress", "--clamped"),
                   "stokes": ("--dirichlet",)}[pde]
        for flag, value in given.items():
            if value and flag not in allowed:
                raise OptionError(f"{flag} does not apply to --pde {pde}")
        unknown = set(self.material) - set(MATERIAL)
        if unknown:
            raise OptionError(f"unknown material constant {sorted(unknown)[0]!r}")
        if not (self.scale == "auto" or isinstance(self.scale, (int, float))
                and math.isfinite(self.scale) and self.scale > 0):
            raise OptimizationError(f"scale must be a positive number or 'auto', not {self.scale!r}")

    def constant(self, name: str) -> float:
        """A material constant (:data:`MATERIAL`)."""
        return float(self.material.get(name, MATERIAL[name]))

    def make_objective(self, mesh, **options):
        """The objective of this problem (unweighed) from the registry (:mod:`.objectives`);
        ``options`` (``solver``) go to its factory. Raises on bad data (an unknown group, a
        vector of the wrong size, Stokes without Dirichlet data) before any solve."""
        from .objectives import make_objective

        name = _objective_name(self.objective)
        d = np.shape(mesh.points)[1]
        if self.pde == "elasticity":
            if not self.stress:
                raise OptionError("--pde elasticity needs a load: --stress GROUP=" +
                                  ",".join(STRESS_COMPONENTS[d]))
            stress = {g: stress_tensor(c, d, g) for g, c in self.stress.items()}
            return make_objective(name, mesh, clamped=list(self.clamped), tractions=stress,
                                  E=self.constant("young"), nu=self.constant("poisson_ratio"),
                                  **options)
        if self.pde == "stokes":
            if not self.dirichlet:
                raise OptionError("--pde stokes needs the velocity of a group: "
                                  "--dirichlet GROUP=" + ",".join(["V"] * d))
            for g, v in self.dirichlet.items():
                if np.size(v) != d:
                    raise OptionError(f"--dirichlet {g}: a velocity in {d}D has {d} "
                                      f"components, not {np.size(v)}")
            if not any(np.any(np.asarray(v) != 0) for v in self.dirichlet.values()):
                raise OptionError("--pde stokes: every --dirichlet velocity is 0, so the "
                                  "flow and its dissipation vanish: give a moving group's "
                                  "velocity, e.g. --dirichlet GROUP="
                                  + ",".join(["1"] + ["0"] * (d - 1)))
            return make_objective(name, mesh, velocities=dict(self.dirichlet),
                                  mu=self.constant("viscosity"), **options)
        data = dict(rhs=self.rhs, dirichlet=dict(self.dirichlet), neumann=dict(self.neumann))
        if name == "integral":
            return make_objective("integral", mesh, **data, **options)
        return make_objective("tracking", mesh, target=parse_objective(self.objective), **data,
                              **options)

    def body_facets(self, mesh) -> np.ndarray:
        """The oriented boundary facets (edges in 2D, triangles on tets) of the region the
        moving groups enclose (for ``keep_barycenter``); refused when they do not close
        around a region."""
        from ..fem.boundary_data import group_facets
        from .constraints import body_facets

        if not self.move:
            raise OptionError("--keep-barycenter keeps the moving body's barycenter: "
                              "name the body with --move")
        vertices = np.unique(np.concatenate([group_facets(mesh, g).ravel() for g in self.move]))
        facets = body_facets(mesh.points, _boundary_facets(mesh), vertices)
        if not _closed(facets):
            raise OptionError(f"--keep-barycenter: --move {', '.join(map(str, self.move))} "
                              "does not enclose a region (its facets do not close)")
        return facets

    def constraint(self, mesh, riesz, free=None):
        """The exact constraints as the line search uses them (None without any):
        :class:`~.area.AreaConstraint` for ``keep_area`` alone,
        :class:`~.constraints.ExactConstraints` on :meth:`body_facets` with
        ``keep_barycenter``. ``riesz`` is the metric's ``(Q, P) -> G⁻¹P``; a constraint
        that no free vertex (``free``, None: all) can change is refused."""
        from .area import AreaConstraint, shoelace_area, shoelace_gradient
        from .constraints import ExactConstraints

        if not (self.keep_area or self.keep_barycenter):
            return None
        Q = mesh.points
        if self.keep_barycenter or Q.shape[1] == 3:
            # on tets keep_area alone is the domain's volume, enclosed by all its faces
            facets = self.body_facets(mesh) if self.keep_barycenter else _boundary_facets(mesh)
            c = ExactConstraints(facets, Q, riesz, measure=self.keep_area,
                                 barycenter=self.keep_barycenter)
            J = c.jacobian(Q)
        else:
            c = AreaConstraint(mesh.boundary_edges, shoelace_area(Q, mesh.boundary_edges), riesz)
            J = shoelace_gradient(Q, mesh.boundary_edges)[None]
        if free is not None:
            J = np.where(np.asarray(free)[None, :, None], J, 0.0)
        if np.linalg.matrix_rank(J.reshape(len(J), -1), tol=1e-12 * np.abs(J).max()) < len(J):
            flags = " and ".join(f for f, on in (("--keep-area", self.keep_area),
                                                 ("--keep-barycenter", self.keep_barycenter)) if on)
            raise OptionError(f"{flags} cannot hold: the vertices free to move cannot change "
                              "what is kept")
        return c

    def fixed_mask(self, mesh) -> np.ndarray | None:
        """``(N,)`` True on the vertices that stay, or None when every vertex moves (groups
        of line elements on a planar mesh, of triangles on a tet mesh)."""
        from ..fem.boundary_data import group_facets

        fixed = np.zeros(mesh.n_vertices, bool)
        for g in self.fixed:
            fixed[np.unique(group_facets(mesh, g))] = True
        if self.move:
            moving = {tuple(e) for g in self.move
                      for e in np.sort(group_facets(mesh, g), 1).tolist()}
            be = np.sort(_boundary_facets(mesh), axis=1)
            stay = np.array([tuple(e) not in moving for e in be.tolist()], dtype=bool)
            fixed[np.unique(be[stay])] = True
            on_boundary = np.zeros(mesh.n_vertices, bool)
            on_boundary[np.unique(be[~stay])] = True
            if not (on_boundary & ~fixed).any():
                raise OptimizationError(f"--move {', '.join(map(str, self.move))}: no boundary "
                                        "vertex of these groups is free to move")
        return fixed if fixed.any() else None

    def weight(self, gradient_norm) -> float:
        """``w`` of ``F = w j + f2`` (:attr:`scale`); ``gradient_norm()`` is ``‖grad j‖`` at the
        initial mesh in the elasticity metric, asked for by ``"auto"`` only."""
        if self.scale != "auto":
            return float(self.scale)
        norm = float(gradient_norm())
        return AUTO_GRADIENT_NORM / norm if norm > 0 and math.isfinite(norm) else 1.0
