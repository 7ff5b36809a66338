"""Shape optimization's iteration for :func:`meshopt_toolkit.optimize.optimize`: the
problem on ``M+`` (:mod:`.problem`), the Armijo and Wolfe line searches
(:mod:`.linesearch`), the steepest-descent, L-BFGS and CG direction rules
(:mod:`.directions`) and their one loop (:mod:`.driver`)."""

from .directions import DIRECTION_RULES, LBFGSMemory, hestenes_stiefel_plus
from .linesearch import LineSearchResult, armijo_backtracking, wolfe_line_search
from .problem import ShapeProblem, max_travel_step

__all__ = [
    "DIRECTION_RULES",
    "LBFGSMemory",
    "LineSearchResult",
    "ShapeProblem",
    "armijo_backtracking",
    "hestenes_stiefel_plus",
    "max_travel_step",
    "wolfe_line_search",
]
