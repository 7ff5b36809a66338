"""The shape objectives by name: each a factory of an objective (``value(Q)``,
``derivative(Q)``, exact w.r.t. every node) on a mesh with physical groups, and the
dimensions it supports.

| name | PDE | objective |
| --- | --- | --- |
| ``integral`` | Poisson, P1 | ``∫ y`` |
| ``tracking`` | Poisson, P1 | ``½ ∫ (y − y_d)²`` |
| ``compliance`` | linear elasticity, P1/P2 | ``∫_Γ t·u`` |
| ``dissipation`` | Stokes, Taylor–Hood P2–P1 | ``∫ 2μ |ε(u)|²`` |

A new objective is one module with a factory ``factory(mesh, **parameters)`` registered by
:func:`register_objective`. On planar meshes ``integral`` and ``tracking`` are the
:class:`~meshopt_toolkit.fem.poisson.PoissonObjective` that ``meshopt optimize`` runs;
on tet meshes the dimension-free :class:`~meshopt_toolkit.fem.poisson_simplex.SimplexPoisson`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from numbers import Real

import numpy as np

from ..errors import OptionError
from ..expressions import DEFAULT_RHS
from ..fem.boundary_data import group_facets
from ..mesh.kinds import is_tets

__all__ = ["OBJECTIVE_REGISTRY", "ObjectiveEntry", "make_objective", "register_objective"]


@dataclass(frozen=True)
class ObjectiveEntry:
    """A registered objective: its factory, the dimensions it supports and one line."""

    name: str
    factory: Callable
    dims: tuple[int, ...]
    description: str


#: name → :class:`ObjectiveEntry`
OBJECTIVE_REGISTRY: dict[str, ObjectiveEntry] = {}


def register_objective(name: str, dims: tuple[int, ...], description: str):
    """Decorator registering ``factory(mesh, **parameters)`` under ``name``."""
    def wrap(factory: Callable) -> Callable:
        if name in OBJECTIVE_REGISTRY:
            raise OptionError(f"objective {name!r} is registered already")
        OBJECTIVE_REGISTRY[name] = ObjectiveEntry(name, factory, tuple(dims), description)
        return factory
    return wrap


def _arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    """Points and cells: a ``TetMesh``'s tets or a planar mesh's triangles."""
    cells = mesh.tets if is_tets(mesh) else mesh.triangles
    return np.asarray(mesh.points, dtype=float), np.asarray(cells, dtype=np.int64)


def make_objective(name: str, mesh, **parameters):
    """The objective ``name`` on ``mesh`` (a planar mesh or a ``TetMesh``).

    Raises
    ------
    OptionError
        An unknown name, or a mesh of a dimension the objective does not support.
    """
    entry = OBJECTIVE_REGISTRY.get(name)
    if entry is None:
        known = ", ".join(sorted(OBJECTIVE_REGISTRY))
        raise OptionError(f"unknown objective {name!r}; known: {known}")
    dim = _arrays(mesh)[0].shape[1]
    if dim not in entry.dims:
        raise OptionError(f"objective {name!r} needs a mesh in {entry.dims} dimensions, not {dim}")
    return entry.factory(mesh, **parameters)


def _poisson(mesh, rhs, dirichlet, neumann, tracking, solver):
    if not is_tets(mesh):
        from ..fem.poisson import PoissonObjective

        bc = {}
        if dirichlet or neumann:
            bc = {"dirichlet": dict(dirichlet or {}), "neumann": dict(neumann or {})}
        return PoissonObjective(mesh, rhs=rhs, tracking=tracking, solver=solver, **bc)
    from ..fem.poisson_simplex import SimplexPoisson

    if neumann:
        raise OptionError("--neumann: Neumann data is planar only, not supported on tetrahedra")
    lift = np.zeros(mesh.n_vertices)
    nodes = [mesh.boundary_vertices]
    for group, value in (dirichlet or {}).items():
        v = np.unique(group_facets(mesh, group))
        lift[v] = float(value)
        nodes.append(v)
    nodes = np.unique(np.concatenate(nodes))
    return SimplexPoisson(mesh.tets, nodes, DEFAULT_RHS if rhs == "default" else rhs,
                          dirichlet_values=lift[nodes], tracking=tracking, solver=solver)


@register_objective("integral", (2, 3), "∫y, −Δy = r, y = 0 on the boundary but on groups")
def integral(mesh, *, rhs="default", dirichlet: Mapping | None = None,
             neumann: Mapping | None = None, solver: str = "auto"):
    """``∫ y`` (:mod:`~meshopt_toolkit.fem.poisson`,
    :mod:`~meshopt_toolkit.fem.poisson_simplex`)."""
    return _poisson(mesh, rhs, dirichlet, neumann, None, solver)


@register_objective("tracking", (2, 3), "½∫(y − y_d)² of the Poisson state y")
def tracking(mesh, *, target, rhs="default", dirichlet: Mapping | None = None,
             neumann: Mapping | None = None, solver: str = "auto"):
    """``½ ∫ (y − y_d)²``, ``y_d`` = ``target`` (an expression, number or callable)."""
    return _poisson(mesh, rhs, dirichlet, neumann, target, solver)


def _stress(value, d: int) -> np.ndarray:
    """A traction group's stress: a ``(d, d)`` tensor, or a number ``p`` meaning ``−p I``
    (a pressure)."""
    if isinstance(value, Real) and not isinstance(value, bool):
        return -float(value) * np.eye(d)
    s = np.asarray(value, dtype=float)
    if s.shape != (d, d):
        raise OptionError(f"a traction is a pressure or a {d}×{d} stress tensor, not {s.shape}")
    return s


@register_objective("compliance", (2, 3), "∫_Γ t·u of linear elasticity (plane stress in 2D)")
def compliance(mesh, *, clamped, tractions: Mapping, E: float = 1.0, nu: float = 0.3,
               degree: int = 1, solver: str = "auto"):
    """:class:`~meshopt_toolkit.fem.linear_elasticity.ComplianceObjective`: ``clamped``
    groups with ``u = 0``, ``tractions`` ``{group: stress or pressure}``."""
    from ..fem.linear_elasticity import ComplianceObjective

    points, cells = _arrays(mesh)
    d = points.shape[1]
    groups = [clamped] if isinstance(clamped, (str, int)) else list(clamped)
    fixed = np.concatenate([group_facets(mesh, g) for g in groups]) if groups else np.zeros((0, d))
    loads = [(group_facets(mesh, g), _stress(s, d)) for g, s in tractions.items()]
    return ComplianceObjective(points, cells, fixed, loads, E=E, nu=nu, degree=degree,
                               solver=solver)


@register_objective("dissipation", (2, 3), "∫2μ|ε(u)|² of Stokes flow (moved bodies' drag)")
def dissipation(mesh, *, velocities: Mapping, mu: float = 1.0, solver: str = "auto"):
    """:class:`~meshopt_toolkit.fem.stokes.StokesDissipation`: ``u`` = the given vector on
    each group of ``velocities``, ``u = 0`` on the rest of the boundary."""
    from ..fem.simplex import all_boundary_facets
    from ..fem.stokes import StokesDissipation

    points, cells = _arrays(mesh)
    d = points.shape[1]
    groups = [(group_facets(mesh, g), np.asarray(v, dtype=float)) for g, v in velocities.items()]
    walls = all_boundary_facets(cells)
    if groups:
        listed = np.sort(np.concatenate([g[0] for g in groups]), axis=1)
        listed = {tuple(f) for f in listed.tolist()}
        walls = walls[np.array([tuple(f) not in listed for f in walls.tolist()], dtype=bool)]
    return StokesDissipation(points, cells, [(walls, np.zeros(d))] + groups, mu=mu,
                             solver=solver)
