"""Penalty (augmentation) functions f1 and f2 with exact derivatives (SPEC §3).

``from meshopt_toolkit.penalties import QualityPenalty`` keeps working; the terms, the
evaluation engines and the public classes live in submodules (see ARCHITECTURE.md).
"""

from __future__ import annotations

from .penalty import DEFAULT_MU, HeightPenalty, Penalty, QualityPenalty, cutoff
# the tuning constants, readable here; patch them on ``penalties.tuning``
from .tuning import BLOCK, PAIR_CACHE, PAIR_CHUNK, SIMPLE_BOUNDARY_CACHE  # noqa: F401

__all__ = ["DEFAULT_MU", "HeightPenalty", "Penalty", "QualityPenalty", "cutoff"]
