"""Parameters that mean the same in several filters, declared once (a module named with
``_`` is not a filter: the registry skips it)."""

from __future__ import annotations

from meshopt_toolkit.pipeline.params import FloatParam

#: w of the per-cell distortion metric ``M + w² JᵀJ`` (``mt.move``, ``mt.morph``)
DISTORTION_WEIGHT = FloatParam("weight", 1.0, "w of the distortion metric M + w² JᵀJ",
                               label="Weight", min=0.0, exclusive_min=True)
