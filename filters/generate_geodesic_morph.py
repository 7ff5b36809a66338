"""Filter ``generate_geodesic_morph``: frames of the geodesic morph between two meshes."""

from __future__ import annotations

from meshopt_toolkit.bounds import MAX_FRAMES
from meshopt_toolkit.errors import FilterError, MeshoptError
from meshopt_toolkit.pipeline.filter import Filter, register
from meshopt_toolkit.pipeline.params import BoolParam, EnumParam, FloatParam, IntParam

METHODS = ("discrete", "shooting", "auto")
METRICS = ("distortion", "scalar")


@register
class GenerateGeodesicMorph(Filter):
    """Morph along a geodesic: frames as healthy as their ends (``metric="distortion"``,
    the per-triangle metric ``M + w² JᵀJ`` of :func:`meshopt_toolkit.morph`, as
    ``meshopt morph``), or only non-inverted (``metric="scalar"``: the complete metric of f2,
    :func:`meshopt_toolkit.morph` with ``metric="complete"``; the ``beta*``, ``normalize``
    and ``method`` parameters apply to it alone and are refused with the distortion metric).

    The source is document mesh ``source`` (default 0, the first), the target mesh
    ``target`` (default −1, the current one); both must be planar, admissible and share
    vertices and triangles. The ``frames`` meshes of
    the morph (frame 0 the source, the last the target) are appended to the document as ``morph_000``, ``morph_001``, …, the last
    one current, each with its per-face aspect ratio 2r/R as face quality. The summary
    holds the morph's diagnostics (``target_error``, ``min_aspect_ratio``,
    ``admissible``, ``linear_min_area``, …). The morph runs at unit size (both meshes
    divided by one power of two, :mod:`meshopt_toolkit.scaling`) and the frames are scaled
    back, like ``meshopt morph``; the diagnostics are those of the unit-size problem, with
    the factor as ``unit_scale``.
    """

    name = "generate_geodesic_morph"
    label = "Geodesic Morph (meshopt)"
    description = "Append the frames of an inversion-free geodesic morph from one mesh to another."
    parameters = (
        IntParam("source", 0, "document index of the source mesh (negative counts from the end)",
                 label="Source mesh"),
        IntParam("target", -1, "document index of the target mesh (-1: the current mesh)",
                 label="Target mesh"),
        IntParam("frames", 9, "number of frames, source and target included", label="Frames",
                 min=2, max=MAX_FRAMES),
        EnumParam("metric", METRICS[0], "per-triangle distortion metric (frames as healthy as "
                  "their ends) or the complete metric of f2 (frames only non-inverted)",
                  label="Metric", choices=METRICS),
        FloatParam("weight", 1.0, "with the distortion metric: w of M + w² JᵀJ",
                   label="Weight", min=0.0, exclusive_min=True),
        FloatParam("beta1", 1.0, "f2 weight of the mean shape quality", label="beta1", min=0.0),
        FloatParam("beta2", 1.0, "f2 weight of the inverse total area", label="beta2", min=0.0),
        FloatParam("beta3", 0.0, "f2 weight of the boundary-pair term (costly)", label="beta3",
                   min=0.0),
        FloatParam("beta4", 1.0, "f2 weight of the distance to the source (unscaled)",
                   label="beta4", min=0.0),
        BoolParam("normalize", True, "metric of √N·f2 (motion counted per vertex) instead "
                  "of f2", label="Normalize"),
        EnumParam("method", METHODS[0], "discrete geodesic, shooting geodesic, or shooting "
                  "with a fallback", label="Method", choices=METHODS),
    )

    def apply(self, document, *, source: int = 0, target: int = -1, frames: int = 9,
              metric: str = METRICS[0], weight: float = 1.0, beta1: float = 1.0, beta2: float = 1.0, beta3: float = 0.0, beta4: float = 1.0,
              normalize: bool = True, method: str = METHODS[0]) -> dict:
        from meshopt_toolkit.kernels.triangles import aspect_ratios
        from meshopt_toolkit.motion.scalar_morph import DEFAULT_BETA
        from meshopt_toolkit.operations import morph
        from meshopt_toolkit.pipeline.document import MeshEntry

        n = len(document)
        for idx, what in ((source, "source"), (target, "target")):
            if not -n <= idx < n:
                raise FilterError(f"{self.name}: the document has {n} meshes, no {what} mesh {idx}")
        src = document.entries[source].workpiece(f"{self.name}: the source")
        tgt = document.entries[target].workpiece(f"{self.name}: the target")
        try:
            # the source's plane at unit size (one power of two for both); the frames
            # carry the source's blocks, tags and data
            src, tgt = src.with_target(tgt.cells)
            base, end = src.mesh, tgt.mesh
            beta = (beta1, beta2, beta3, beta4)
            result = morph(base, end, frames, metric=metric, weight=weight,
                           beta=None if beta == DEFAULT_BETA else beta, normalize=normalize,
                           method=method)
            width = max(3, len(str(frames - 1)))
            meshes = [(f"morph_{k:0{width}d}", src.moved(m.points, what=f"frame {k}"),
                       aspect_ratios(m.points, m.triangles))
                      for k, m in enumerate(result.frames)]
        except MeshoptError as exc:
            raise FilterError(f"{self.name}: {exc}") from None
        for name, wp, quality in meshes:
            entry = MeshEntry(wp.file_mesh(), name=name)
            entry.set_workpiece(wp)
            document.add(entry)
            entry.set_face_attribute("quality", quality)
        return {**result.summary(), "unit_scale": src.scale.factor}
