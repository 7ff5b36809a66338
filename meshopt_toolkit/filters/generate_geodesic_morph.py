"""Filter ``generate_geodesic_morph``: frames of the geodesic morph between two meshes."""

from __future__ import annotations

from meshopt_toolkit.bounds import MAX_FRAMES
from meshopt_toolkit.errors import FilterError, MeshoptError, OptionError
from meshopt_toolkit.operations import STOP_RULES
from meshopt_toolkit.pipeline.filter import PLANAR, SURFACE, Filter, register
from meshopt_toolkit.pipeline.params import (BoolParam, EnumParam, IntParam, NumberListParam,
                                             number_list)
from meshopt_toolkit.filters._shared import DISTORTION_WEIGHT

METHODS = ("discrete", "shooting", "auto")
METRICS = ("distortion", "scalar")
#: f2's coefficients when ``penalty`` is empty (:data:`meshopt_toolkit.motion.planar.scalar_morph.DEFAULT_BETA`)
DEFAULT_PENALTY = (1.0, 1.0, 0.0, 1.0)
#: the four floats that ``penalty`` replaced, still accepted in saved pipelines
FORMER_BETAS = ("beta1", "beta2", "beta3", "beta4")


@register
class GenerateGeodesicMorph(Filter):
    """Morph along a geodesic: frames as healthy as their ends (``metric="distortion"``,
    the per-triangle metric ``M + w² JᵀJ`` of :func:`meshopt_toolkit.morph`, as
    ``meshopt morph``), or only non-inverted (``metric="scalar"``: the complete metric of f2,
    :func:`meshopt_toolkit.morph` with ``metric="complete"``; the ``penalty``, ``normalize``
    and ``method`` parameters apply to it alone and are refused with the distortion metric).

    The source is document mesh ``source`` (default 0, the first), the target mesh
    ``target`` (default −1, the current one); both must be planar, admissible and share
    vertices and triangles, or be two poses of one triangle surface in 3D (morphed with
    membrane distortion and bending, as ``meshopt morph``; face quality the unsigned 2r/R).
    ``stop`` says when the morph of a surface in 3D stops: ``"healthy"`` (its default,
    ``"auto"``) as soon as every frame is as healthy as the worse end, ``"converged"`` on
    the energy tests alone; planar morphs stop on these only and refuse ``"healthy"``.
    ``contact`` (a surface in 3D, default True) keeps every frame, and the motion between
    frames, from passing through the surface where both poses are free of
    self-intersections (:mod:`meshopt_toolkit.motion.surface.morph_contact`).
    The ``frames`` meshes of
    the morph (frame 0 the source, the last the target) are appended to the document as ``morph_000``, ``morph_001``, …, the last
    one current, each with its per-face aspect ratio 2r/R as face quality. The summary
    holds the morph's diagnostics (``target_error``, ``min_aspect_ratio``,
    ``admissible``, ``linear_min_area``, …). The meshes go to ``mt.morph`` at the file's
    scale, as with ``meshopt morph`` (``mt.morph`` works at unit size itself,
    :mod:`meshopt_toolkit.scaling`).
    """

    name = "generate_geodesic_morph"
    label = "Geodesic Morph (meshopt)"
    description = "Append the frames of an inversion-free geodesic morph from one mesh to another."
    kinds = (PLANAR, SURFACE)
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
        DISTORTION_WEIGHT,
        NumberListParam("penalty", "", "with the scalar metric: f2's b1,b2,b3,b4 (mean shape "
                        "quality, inverse area, boundary pairs (costly), distance to the "
                        "source, unscaled); empty = 1,1,0,1", label="Penalty", count=4),
        BoolParam("normalize", True, "metric of √N·f2 (motion counted per vertex) instead "
                  "of f2", label="Normalize"),
        EnumParam("method", METHODS[0], "discrete geodesic, shooting geodesic, or shooting "
                  "with a fallback", label="Method", choices=METHODS),
        EnumParam("stop", STOP_RULES[0], "when to stop: surfaces in 3D as soon as every "
                  "frame is as healthy as the worse end (healthy, their auto) or on the energy "
                  "tests alone (converged, the only rule of planar and tet morphs)",
                  label="Stop", choices=STOP_RULES),
        BoolParam("contact", True, "surfaces in 3D: no frame, nor the motion between "
                  "frames, passes through the surface (where both poses are free of "
                  "self-intersections)", label="Contact"),
    )

    former_parameters = dict.fromkeys(FORMER_BETAS, "penalty")

    @classmethod
    def upgrade_params(cls, params: dict) -> dict:
        """The former ``beta1`` … ``beta4`` (four floats) as one ``penalty`` list."""
        out = super().upgrade_params(params)
        given = [b for b in FORMER_BETAS if b in out]
        if given:
            if "penalty" in out:
                raise FilterError(f"filter {cls.name!r}: give 'penalty' or its former "
                                  f"{', '.join(given)}, not both")
            values = [out.pop(b, d) for b, d in zip(FORMER_BETAS, DEFAULT_PENALTY)]
            for b, v in zip(FORMER_BETAS, values):
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise FilterError(f"filter {cls.name!r}, parameter {b!r}: expected a "
                                      f"number, got {v!r}")
            out["penalty"] = ",".join(repr(float(v)) for v in values)
        return out

    def apply(self, document, *, source: int = 0, target: int = -1, frames: int = 9,
              metric: str = METRICS[0], weight: float = 1.0, penalty: str = "",
              normalize: bool = True, method: str = METHODS[0],
              stop: str = STOP_RULES[0], contact: bool = True) -> dict:
        from meshopt_toolkit.kernels.triangles import aspect_ratios
        from meshopt_toolkit.motion.planar.scalar_morph import DEFAULT_BETA
        from meshopt_toolkit.operations import METRIC_ALIASES, CompleteMorph, morph
        from meshopt_toolkit.pipeline.document import MeshEntry
        from meshopt_toolkit.scaling import unit_scale

        beta1, beta2, beta3, beta4 = number_list(penalty, 4, "penalty") or DEFAULT_PENALTY
        n = len(document)
        for idx, what in ((source, "source"), (target, "target")):
            if not -n <= idx < n:
                raise FilterError(f"{self.name}: the document has {n} meshes, no {what} mesh {idx}")
        src = document.entries[source].workpiece(f"{self.name}: the source", required=False)
        if src is None:  # a surface in 3D (a tet mesh is refused there)
            return self._surface(document, document.entries[source], document.entries[target],
                                 frames, metric, weight, penalty, normalize, method, stop,
                                 contact)
        tgt = document.entries[target].workpiece(f"{self.name}: the target")
        try:
            # the source's plane at the file's scale (mt.morph works at unit size); the
            # frames carry the source's blocks, tags and data
            base, end = src.mesh, src.target(tgt.cells).mesh
            beta = (beta1, beta2, beta3, beta4)
            if METRIC_ALIASES.get(metric, metric) == "complete":
                metric = CompleteMorph(beta=None if beta == DEFAULT_BETA else beta,
                                       normalize=normalize, method=method)
            elif beta != DEFAULT_BETA or not normalize or method != METHODS[0]:
                raise OptionError("penalty, normalize and method apply to the scalar metric "
                                  "only")
            result = morph(base, end, frames, metric=metric, weight=weight, stop=stop)
            width = max(3, len(str(frames - 1)))
            # 2r/R is free of scale: taken at the frame's power-of-two unit size, exact and
            # in the float range at any scale
            meshes = [(f"morph_{k:0{width}d}", src.moved(m.points),
                       aspect_ratios(unit_scale(m.points).down(m.points), m.triangles))
                      for k, m in enumerate(result.frames)]
        except MeshoptError as exc:
            raise FilterError(f"{self.name}: {exc}") from None
        for name, wp, quality in meshes:
            entry = MeshEntry(wp.file_mesh(), name=name)
            entry.set_workpiece(wp)
            document.add(entry)
            entry.set_face_attribute("quality", quality)
        return result.summary()

    def _surface(self, document, source, target, frames: int, metric: str, weight: float,
                 penalty: str, normalize: bool, method: str, stop: str,
                 contact: bool = True) -> dict:
        """Morph two poses of a triangle surface in 3D; each frame keeps the source file's
        blocks, tags and data (``source_cells``) at its points."""
        from meshopt_toolkit.kernels.surface import aspect_ratios
        from meshopt_toolkit.mesh import SurfaceMesh, TriangleMesh
        from meshopt_toolkit.mesh.kinds import is_tets
        from meshopt_toolkit.operations import morph
        from meshopt_toolkit.pipeline.document import MeshEntry

        for entry, what in ((source, "source"), (target, "target")):
            if is_tets(entry.mesh):
                raise FilterError(f"{self.name}: the {what} needs a planar mesh or a surface "
                                  f"in 3D; {entry.name} has {entry.mesh.n_tets} tetrahedra")
        if metric != METRICS[0] or penalty or not normalize or method != METHODS[0]:
            raise FilterError(f"{self.name}: surfaces in 3D are morphed with the distortion "
                              "metric only (metric, penalty, normalize and method do not apply)")
        a, b = source.mesh, target.mesh
        try:
            result = morph(SurfaceMesh(a.points, a.triangles, **a._tag_kwargs()),
                           SurfaceMesh(b.points, b.triangles, **b._tag_kwargs()), frames,
                           weight=weight, stop=stop, contact=contact)
        except MeshoptError as exc:
            raise FilterError(f"{self.name}: {exc}") from None
        cells = source.source_cells if source.keeps_source_cells else None
        width = max(3, len(str(frames - 1)))
        for k, m in enumerate(result.frames):
            entry = MeshEntry(TriangleMesh(m.points, a.triangles, **a._tag_kwargs()),
                              name=f"morph_{k:0{width}d}", source_cells=cells)
            document.add(entry)
            entry.set_face_attribute("quality", aspect_ratios(m.points, a.triangles))
        return result.summary()
