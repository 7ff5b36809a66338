"""A tiny third-party filter plugin used by the tests (not installed; see test_pipeline_plugin)."""

from __future__ import annotations

import os

from meshopt_toolkit.pipeline import BoolParam, Filter, FloatParam, StringParam


class DemoScale(Filter):
    """Scale the current mesh about the origin."""

    name = "demo_scale"
    label = "Demo Scale (plugin)"
    description = "Scale the current mesh by a factor."
    parameters = (FloatParam("factor", 2.0, "scale factor", min=0.0),)

    def apply(self, document, *, factor: float) -> dict:
        entry = document.current_entry
        mesh = entry.mesh
        entry.mesh = mesh.with_points(mesh.points * factor)
        return {"factor": factor}


class DemoCrash(Filter):
    """Abort the whole process (like a native MeshLab filter without a GPU) for some inputs."""

    name = "demo_crash"
    label = "Demo Crash (plugin)"
    description = "Abort the process when the current mesh name contains a marker."
    parameters = (
        StringParam("marker", "bad", "abort when the mesh name contains this"),
        BoolParam("enabled", True, "whether to abort at all"),
    )

    def apply(self, document, *, marker: str, enabled: bool) -> None:
        if enabled and marker in document.current_entry.name:
            os.abort()
        return None
