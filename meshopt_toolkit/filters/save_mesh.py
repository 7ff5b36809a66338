"""Filter ``save_mesh``: write the current mesh inside a pipeline (atomically)."""

from __future__ import annotations

from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.pipeline.filter import MESH_KINDS, Filter, register
from meshopt_toolkit.pipeline.params import BoolParam, EnumParam, PathParam

#: file encodings: the format's default (binary where it has one), binary, text
ENCODINGS = ("default", "binary", "ascii")
#: gmsh versions written for .msh files ("input": the input file's, 4.1 for other formats)
MSH_VERSIONS = ("input", "4.1", "2.2")


def binary_of(encoding: str) -> bool | None:
    """The ``binary`` argument of :func:`meshopt_toolkit.io.save` for an encoding."""
    return {"default": None, "binary": True, "ascii": False}[encoding]


@register
class SaveMesh(Filter):
    """Write the current mesh with every block, tag and datum of its file, and its vertex
    and face attributes as point and cell data (what the format cannot hold is left out
    with a warning naming it; :func:`meshopt_toolkit.pipeline.document.save_entry`).

    The path is a template (``{stem}``, ``{name}``, ``{ext}``, ``{index}``, ... see
    :mod:`meshopt_toolkit.pipeline.paths`) relative to the document's output folder
    (``meshopt run -o``); absolute paths, ``..`` and symlinks leading outside it are
    refused. The file appears atomically. An existing file is replaced only when the
    command line says so (``--force``, ``Document.overwrite``); the ``overwrite``
    parameter is kept so that older pipelines still load, but a pipeline cannot grant
    itself that permission. In a dry run nothing is written.
    """

    name = "save_mesh"
    label = "Save Mesh (meshopt)"
    description = "Write the current mesh to a file in the output folder (atomic, never overwrites without --force)."
    kinds = MESH_KINDS
    parameters = (
        PathParam("path", "{stem}.msh", "output file inside the output folder ({stem}, {name} "
                  "expand)", label="File", save=True),
        EnumParam("encoding", ENCODINGS[0], "binary or text output where the format has "
                  "both (default: binary, except the text formats obj and off)",
                  choices=ENCODINGS, label="Encoding"),
        EnumParam("msh_version", MSH_VERSIONS[0], "gmsh file version of .msh output "
                  "(input: the input gmsh file's version, encoding and entities; 4.1 "
                  "for other inputs)",
                  choices=MSH_VERSIONS, label="MSH version"),
        BoolParam("overwrite", False, "ignored: only --force on the command line replaces "
                  "files", label="Overwrite"),
    )

    @classmethod
    def _path(cls, document, path: str):
        from meshopt_toolkit.pipeline.paths import resolve_output

        p = resolve_output(document, path)
        if p.exists() and not document.overwrite:
            raise FilterError(f"{p}: already exists (only --force on the command line "
                              "replaces files)")
        return p

    @classmethod
    def plan(cls, document, params, stats):
        cls._path(document, params["path"])
        return stats

    def apply(self, document, *, path: str, encoding: str = ENCODINGS[0],
              msh_version: str = MSH_VERSIONS[0], overwrite: bool = False) -> dict:
        from meshopt_toolkit.pipeline.document import save_entry

        p = self._path(document, path)
        if document.dry_run:
            return {"would_write": str(p)}
        # atomic; every block, tag and datum of the input, the attributes as data
        save_entry(document.current_entry, p, overwrite=document.overwrite,
                   binary=binary_of(encoding), msh_version=msh_version)
        document.written.append(str(p))
        return {"written": str(p)}
