"""meshopt-toolkit: keep planar triangle meshes healthy while they move.

The public API is exported here lazily, so ``import meshopt_toolkit`` stays cheap and a
feature's dependencies load only when it is used.
"""

from __future__ import annotations

import importlib
import importlib.util

__version__ = "0.1.0"

# public name -> module that defines it
_EXPORTS = {
    # errors
    "MeshoptError": "errors",
    "InvalidMeshError": "errors",
    "NotAdmissibleError": "errors",
    "ReadError": "errors",
    "WriteError": "errors",
    "FilterError": "errors",
    "ExpressionError": "errors",
    "IntegrationError": "errors",
    "OptimizationError": "errors",
    # meshes
    "TriangleMesh": "mesh",
    "PlanarMesh": "mesh",
    "SurfaceMesh": "mesh",
    "TetMesh": "mesh",
    "MeshReport": "mesh",
    "check_mesh": "mesh",
    "require_admissible": "mesh",
    "quality_summary": "kernels.triangles",
    # file I/O
    "load": "io",
    "save": "io",
    # data
    "data_path": "datasets",
    # penalties, metrics, diagnostics
    "HeightPenalty": "penalties",
    "QualityPenalty": "penalties",
    "EuclideanMetric": "riemannian.metrics",
    "ElasticityMetric": "riemannian.metrics",
    "CompleteMetric": "riemannian.metrics",
    "GraphMetric": "motion.graph_metric",
    "check_gradient": "diagnostics",
    "check_hvp": "diagnostics",
    # geodesics and deformation
    "exp_map": "riemannian.geodesics",
    "geodesic": "riemannian.geodesics",
    "GeodesicResult": "riemannian.geodesics",
    "GeodesicOptions": "riemannian.geodesics",
    "discrete_geodesic": "riemannian.discrete_geodesic",
    "DiscreteGeodesic": "riemannian.geodesic_result",
    "deform": "deform",
    "DeformResult": "deform",
    # prescribed motion (the per-triangle distortion metric)
    "move": "motion.move",
    "MoveResult": "motion.move",
    "NoAdmissiblePathError": "motion.continuation",
    "TriangleDistortion": "motion.strain",
    # shape optimization
    "PoissonObjective": "fem.poisson",
    "parse_expression": "expressions",
    "optimize": "optimize",
    "OptimizeResult": "optimize",
    # morphing
    "log_map": "morph",
    "geodesic_morph": "morph",
    "MorphResult": "morph",
    "distortion_morph": "motion.morph",
    "DistortionMorph": "motion.morph",
    # filters and pipelines
    "Filter": "pipeline",
    "register": "pipeline.filter",
    "Document": "pipeline",
    "Pipeline": "pipeline",
    "load_pipeline": "pipeline",
    "save_pipeline": "pipeline",
    "run_batch": "batch",
}

__all__ = sorted(_EXPORTS) + ["__version__"]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        if not name.startswith("_") and importlib.util.find_spec(f"{__name__}.{name}"):
            return importlib.import_module(f".{name}", __name__)  # a submodule, e.g. mt.datasets
        raise AttributeError(f"module 'meshopt_toolkit' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
