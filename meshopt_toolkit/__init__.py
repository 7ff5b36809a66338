"""meshopt-toolkit: keep planar triangle meshes healthy while they move.

The public API is exported here lazily, so ``import meshopt_toolkit`` stays cheap and a
feature's dependencies load only when it is used.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types

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
    "CellKind": "cells.base",
    "kind_of": "cells.registry",
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
    "Metric": "riemannian.metrics",
    "EuclideanMetric": "riemannian.metrics",
    "ElasticityMetric": "riemannian.metrics",
    "CompleteMetric": "riemannian.metrics",
    "GraphMetric": "motion.planar.metric",
    "metric_for": "cells.registry",
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
    "NoAdmissiblePathError": "motion.engine.continuation",
    "TriangleDistortion": "motion.planar.distortion",
    # shape optimization
    "PoissonObjective": "fem.poisson",
    "parse_expression": "expressions",
    "optimize": "optimize",
    "OptimizeResult": "optimize",
    "OptimizeOptions": "optimize",
    # morphing (one call; the metric is an option)
    "morph": "operations",
    "CompleteMorph": "operations",
    "log_map": "riemannian.log_map",
    "LogMapOptions": "riemannian.log_map",
    "MorphResult": "motion.planar.scalar_morph_result",
    "DistortionMorph": "motion.planar.morph",
    # the result protocol and the bad-argument error of the operations
    "Result": "results",
    "PathIteration": "results",
    "OptionError": "errors",
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


class _Package(types.ModuleType):
    """The package object: importing a submodule whose name is also an exported call
    (``meshopt_toolkit.deform``, ``meshopt_toolkit.optimize``) binds the call, never the
    module, so ``mt.deform`` is the function whatever was imported first."""

    def __setattr__(self, name: str, value) -> None:
        if (isinstance(value, types.ModuleType) and _EXPORTS.get(name) == name
                and value.__name__ == f"{__name__}.{name}" and hasattr(value, name)):
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
