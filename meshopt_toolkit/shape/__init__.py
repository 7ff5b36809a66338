"""Optimization methods of :func:`meshopt_toolkit.optimize.optimize` beyond steepest descent:
the problem on ``M+`` (:mod:`.problem`), the Wolfe line search (:mod:`.linesearch`),
L-BFGS and CG directions (:mod:`.directions`) and their iteration (:mod:`.driver`)."""

from .directions import LBFGSMemory, hestenes_stiefel_plus
from .linesearch import LineSearchResult, wolfe_line_search
from .problem import ShapeProblem, segment_limit

__all__ = [
    "LBFGSMemory",
    "LineSearchResult",
    "ShapeProblem",
    "hestenes_stiefel_plus",
    "segment_limit",
    "wolfe_line_search",
]
