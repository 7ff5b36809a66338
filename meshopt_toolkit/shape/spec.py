"""The user's shape problem in one value: which boundary moves, the boundary conditions,
the objective, the area constraint and the objective's weight.

:class:`ProblemSpec` is what ``meshopt optimize``'s options, the
``apply_coord_shape_optimization`` filter's parameters and library callers fill in; physical
groups are gmsh physical groups of line elements, by name or number
(:func:`~meshopt_toolkit.fem.boundary_data.group_key`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .._typing import FloatArray
from ..errors import MeshoptError, OptimizationError

__all__ = ["AUTO_GRADIENT_NORM", "GUARD_FACTOR", "GUARD_TRIES", "OBJECTIVES", "QUALITY_GUARD",
           "ProblemSpec", "ScaledObjective", "parse_assignment", "parse_objective",
           "parse_scale", "spec_from_options"]

#: objectives: ``integral`` (∫y) and ``tracking: EXPR`` (½∫(y − y_d)², y_d = EXPR)
OBJECTIVES = ("integral", "tracking: EXPR")

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
#: the weight divided by ``GUARD_FACTOR``, at most ``GUARD_TRIES`` times
QUALITY_GUARD = 0.5
GUARD_FACTOR = 4.0
GUARD_TRIES = 4


def parse_objective(text: str) -> str | None:
    """The tracking target of ``"tracking: EXPR"`` (None for ``"integral"``)."""
    t = (text or "integral").strip()
    if t in ("integral", "int y", "∫y"):
        return None
    head, sep, expr = t.partition(":")
    if sep and head.strip() == "tracking" and expr.strip():
        return expr.strip()
    raise MeshoptError(f"unknown objective {text!r}; use 'integral' or 'tracking: EXPR'")


def parse_assignment(text: str, option: str) -> tuple[str, float]:
    """``"GROUP=VALUE"`` → ``(GROUP, VALUE)``."""
    group, sep, value = str(text).partition("=")
    try:
        v = float(value)
    except ValueError:
        v = math.nan
    if not sep or not group.strip() or not math.isfinite(v):
        raise MeshoptError(f"{option} {text!r}: expected GROUP=VALUE with a finite number")
    return group.strip(), v


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


def spec_from_options(*, fixed=(), move=(), dirichlet=(), neumann=(), keep_area=False,
                      objective="integral", rhs="default", scale="auto") -> ProblemSpec:
    """A :class:`ProblemSpec` from option strings: groups and ``GROUP=VALUE`` items
    comma-separated (or repeated), ``scale`` ``"auto"`` or a number."""
    from ..fem.boundary_data import group_key

    return ProblemSpec(
        fixed=tuple(group_key(g) for g in _items(fixed)),
        move=tuple(group_key(g) for g in _items(move)),
        dirichlet=dict(parse_assignment(a, "--dirichlet") for a in _items(dirichlet)),
        neumann=dict(parse_assignment(a, "--neumann") for a in _items(neumann)),
        keep_area=bool(keep_area), objective=objective or "integral", rhs=rhs,
        scale=parse_scale(scale))


class ScaledObjective:
    """``w · j``: an objective weighed for the penalty (``value``, ``derivative``)."""

    def __init__(self, objective, weight: float) -> None:
        self.objective, self.weight = objective, float(weight)

    def value(self, Q: FloatArray) -> float:
        return self.weight * float(self.objective.value(Q))

    def derivative(self, Q: FloatArray) -> FloatArray:
        return self.weight * np.asarray(self.objective.derivative(Q), dtype=float)


@dataclass(frozen=True)
class ProblemSpec:
    """A shape problem on a mesh with physical groups.

    Attributes
    ----------
    fixed : groups whose vertices do not move
    move : if given, only these boundary groups move: every other boundary vertex (a
        corner shared with a moving group included) stays; interior vertices move
    dirichlet : ``{group: value}``, ``y = value`` there (``y = 0`` on the rest of the
        boundary that is not Neumann)
    neumann : ``{group: value}``, ``∂y/∂n = value`` there
    keep_area : the domain's area is an exact constraint (lbfgs and cg only)
    objective : ``"integral"`` (``∫y``) or ``"tracking: EXPR"`` (``½∫(y − y_d)²``)
    rhs : right-hand side ``r`` of ``−Δy = r`` (``"default"``: the thesis' disc demo rhs)
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

    def __post_init__(self) -> None:
        parse_objective(self.objective)
        if not (self.scale == "auto" or isinstance(self.scale, (int, float))
                and math.isfinite(self.scale) and self.scale > 0):
            raise OptimizationError(f"scale must be a positive number or 'auto', not {self.scale!r}")

    def make_objective(self, mesh, **options):
        """The objective of this problem (unweighed), the registered ``integral`` or
        ``tracking`` (:mod:`.objectives`); ``options`` (``solver``) go to its factory."""
        from .objectives import make_objective

        target = parse_objective(self.objective)
        data = dict(rhs=self.rhs, dirichlet=dict(self.dirichlet), neumann=dict(self.neumann))
        if target is None:
            return make_objective("integral", mesh, **data, **options)
        return make_objective("tracking", mesh, target=target, **data, **options)

    def fixed_mask(self, mesh) -> np.ndarray | None:
        """``(N,)`` True on the vertices that stay, or None when every vertex moves."""
        from ..fem.boundary_data import group_edges

        fixed = np.zeros(mesh.n_vertices, bool)
        for g in self.fixed:
            fixed[np.unique(group_edges(mesh, g))] = True
        if self.move:
            moving = {tuple(e) for g in self.move for e in np.sort(group_edges(mesh, g), 1).tolist()}
            be = np.sort(mesh.boundary_edges, axis=1)
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
