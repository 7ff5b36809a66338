"""Upper bounds on counts shared by the command line and the pipeline filters.

One place, so that ``meshopt morph --frames`` and the ``generate_geodesic_morph`` filter
refuse the same values.
"""

from __future__ import annotations

__all__ = ["MAX_FRAMES", "MAX_ITERATIONS", "MAX_STEPS"]

#: most frames written by deform, morph, move and generate_geodesic_morph
MAX_FRAMES = 1000
#: most continuation steps of move (CLI and apply_coord_prescribed_motion)
MAX_STEPS = 1000
#: most iterations of an iterative solve asked for on the command line
MAX_ITERATIONS = 100_000
