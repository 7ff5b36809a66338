"""Filter ``load_mesh``: read a mesh file into the document inside a pipeline."""

from __future__ import annotations

from pathlib import Path

from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.pipeline.filter import Filter, register
from meshopt_toolkit.pipeline.params import PathParam


@register
class LoadMesh(Filter):
    """Load a mesh (any format ``meshopt_toolkit.io.load`` reads) as the new current mesh.

    ``{stem}``, ``{name}`` and ``{input_dir}`` in the path are replaced by the run's
    variables; a relative path is relative to the folder of the pipeline's input.
    """

    name = "load_mesh"
    label = "Load Mesh (meshopt)"
    description = "Read a mesh file into the document and make it current."
    parameters = (
        PathParam("path", "mesh.msh", "mesh file to read ({stem}, {input_dir} expand)", label="File"),
    )

    def apply(self, document, *, path: str) -> dict:
        from meshopt_toolkit.io import load

        try:
            text = path.format(**document.variables)
        except (KeyError, IndexError, ValueError) as exc:
            raise FilterError(f"bad template in path {path!r}: {exc}") from None
        p = Path(text)
        if not p.is_absolute() and document.variables.get("input_dir"):
            p = Path(document.variables["input_dir"]) / p
        mesh = load(p)
        document.add(mesh, name=p.stem)
        return {"loaded": str(p), "n_vertices": mesh.n_vertices, "n_triangles": mesh.n_triangles}
