"""Filter ``load_mesh``: read a mesh file into the document inside a pipeline."""

from __future__ import annotations

from pathlib import Path

from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.pipeline.filter import MESH_KINDS, Filter, register
from meshopt_toolkit.pipeline.params import PathParam


@register
class LoadMesh(Filter):
    """Load a mesh (any format ``meshopt_toolkit.io.load`` reads) as the new current mesh.

    The path is a template (``{stem}``, ``{name}``, ``{ext}``, ``{input_dir}``, ... see
    :mod:`meshopt_toolkit.pipeline.paths`); a relative path is relative to the folder of
    the pipeline's input. Only the run's inputs and paths given with ``--allow-read``
    (``Document.allow_read``) can be read; symlinks are followed before deciding.
    """

    name = "load_mesh"
    label = "Load Mesh (meshopt)"
    description = "Read a mesh file into the document and make it current."
    kinds = MESH_KINDS
    parameters = (
        PathParam("path", "mesh.msh", "mesh file to read ({stem}, {input_dir} expand); only "
                  "inputs and --allow-read paths", label="File"),
    )

    @classmethod
    def _path(cls, document, path: str) -> Path:
        from meshopt_toolkit.pipeline.paths import resolve_input

        p = resolve_input(document, path)
        if not p.exists():
            raise FilterError(f"{p}: no such file")
        if not p.is_file():
            raise FilterError(f"{p}: not a regular file")
        return p

    @classmethod
    def kind_after(cls, kind, params):
        """The file's kind is known once it is read (the steps after it are checked then)."""
        return None

    @classmethod
    def plan(cls, document, params, stats):
        """The path must be readable; in a dry run the mesh is read to know its size."""
        p = cls._path(document, params["path"])
        if not document.dry_run:
            return None  # measured after the step
        from meshopt_toolkit.pipeline.budget import stats_of
        from meshopt_toolkit.pipeline.document import load_entry

        return stats_of(load_entry(p).mesh)  # triangles, or tetrahedra

    def apply(self, document, *, path: str) -> dict:
        from meshopt_toolkit.mesh.kinds import is_tets
        from meshopt_toolkit.pipeline.document import load_entry

        p = self._path(document, path)
        entry = document.add(load_entry(p))  # with every block, tag and datum of the file
        mesh = entry.mesh
        cells = {"n_tets": mesh.n_tets} if is_tets(mesh) else \
            {"n_triangles": mesh.n_triangles}
        return {"loaded": str(p), "n_vertices": mesh.n_vertices, **cells}
