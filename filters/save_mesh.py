"""Filter ``save_mesh``: write the current mesh inside a pipeline (atomically)."""

from __future__ import annotations

from pathlib import Path

from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.pipeline.filter import Filter, register
from meshopt_toolkit.pipeline.params import BoolParam, PathParam


@register
class SaveMesh(Filter):
    """Write the current mesh with ``meshopt_toolkit.io.save``.

    ``{stem}`` and ``{name}`` (input file stem, current mesh name) expand; a relative path
    goes into the document's output folder (``meshopt run -o``). The file appears
    atomically and an existing file is replaced only with ``overwrite`` (or ``--force``).
    In a dry run nothing is written.
    """

    name = "save_mesh"
    label = "Save Mesh (meshopt)"
    description = "Write the current mesh to a file (atomic, never overwrites unless asked)."
    parameters = (
        PathParam("path", "{stem}.msh", "output file ({stem}, {name} expand)", label="File", save=True),
        BoolParam("overwrite", False, "replace an existing file", label="Overwrite"),
    )

    def apply(self, document, *, path: str, overwrite: bool = False) -> dict:
        from meshopt_toolkit.io import save

        variables = {"stem": "mesh", **document.variables, "name": document.current_entry.name}
        try:
            text = path.format(**variables)
        except (KeyError, IndexError, ValueError) as exc:
            raise FilterError(f"bad template in path {path!r}: {exc}") from None
        p = Path(text)
        if not p.is_absolute() and document.output_dir is not None:
            p = Path(document.output_dir) / p
        force = overwrite or document.overwrite
        if document.dry_run:
            if p.exists() and not force:
                raise FilterError(f"{p}: exists (use --force to replace it)")
            return {"would_write": str(p)}
        save(document.mesh, p, overwrite=force)  # atomic
        document.written.append(str(p))
        return {"written": str(p)}
