"""Pipelines: a list of steps, each a meshopt filter or a MeshLab (pymeshlab) filter.

A step names a filter by its snake_case name or its MeshLab label. Our registry is asked
first; anything else is resolved against pymeshlab (imported only then). Consecutive
MeshLab steps share one ``pymeshlab.MeshSet``; the document is converted to it before the
first and back after the last of them.

A pipeline is untrusted input; running one is confined by its :class:`Document`:

- paths: outputs inside ``document.output_dir``, inputs only those allowed, templates
  whitelisted (:mod:`.paths`); ``document.overwrite`` (``--force``) is the only way to
  replace a file;
- size: the current mesh's triangles are estimated before each step and measured after
  it against ``document.max_triangles`` (:mod:`.budget`);
- MeshLab steps that invert triangles of a planar mesh that was admissible fail (or warn
  with ``document.allow_inverted``) (:mod:`.orientation`).

Before any step runs, and again before each step with the mesh as it is then, every
step left is checked to take the kind of mesh it will get (planar, a surface in 3D,
tetrahedra: :meth:`Pipeline.check_kinds`, from the filters' declared ``kinds``).

:meth:`Pipeline.check` does all of it without running a filter (``--dry-run``). Errors
name the step, counted from 1: ``step 2 (apply_coord_laplacian_smoothing): ...``.
Reading and writing pipeline files is :mod:`.files`.
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

from ..errors import FilterError, MeshoptError
from .budget import check_budget, check_measured, estimate_meshlab, stats_of, stats_of_arrays
from .document import KIND_NAMES, PLANAR, SURFACE, TETS, Document, kind_of
from .filter import registry
from .limits import check_name, check_step_count
from .orientation import admissible_normal, count_inverted
from .params import PathParam, did_you_mean
from .paths import (
    ResolvedPath,
    check_input_template,
    check_output_template,
    resolve_input,
    resolve_output,
)

logger = logging.getLogger(__name__)

__all__ = ["Step", "Pipeline", "make_step", "MESHOPT", "MESHLAB"]

MESHOPT = "meshopt"
MESHLAB = "meshlab"
#: the kinds of mesh a MeshLab step takes (pymeshlab holds triangles); it keeps the kind
MESHLAB_KINDS = (PLANAR, SURFACE)
_PLURAL = {PLANAR: "planar triangle meshes", SURFACE: "triangle surfaces in 3D",
           TETS: "tetrahedral meshes"}


@dataclass
class Step:
    """One pipeline step.

    Attributes
    ----------
    name : str
        Our filter name, or the pymeshlab filter name.
    params : dict
        Parameter values as given (JSON-friendly); validated by :meth:`Pipeline.validate`.
    kind : {"meshopt", "meshlab"}
    label : str or None
        The MeshLab label it was read under (.mlx), if any.
    mlx_params : list of dict or None
        The original ``<Param>`` attributes of a MeshLab step read from .mlx, written back
        unchanged so that MeshLab reads its own script again.
    """

    name: str
    params: dict[str, Any] = field(default_factory=dict)
    kind: str = MESHOPT
    label: str | None = None
    mlx_params: list[dict[str, str]] | None = None

    @property
    def filter(self):
        """The filter class of a meshopt step."""
        return registry.get(self.name)

    def to_dict(self) -> dict:
        if self.kind == MESHOPT:
            cls = self.filter
            vals = cls.validate_params(self.params)
            return {"name": self.name,
                    "params": {k: cls.param(k).to_json(v) for k, v in vals.items()}}
        return {"name": self.name, "params": dict(self.params)}


def make_step(name: str, params: dict | None = None, *, label: str | None = None,
              mlx_params=None) -> Step:
    """Resolve a filter name or label to a :class:`Step` (meshopt first, then MeshLab)."""
    if not isinstance(name, str) or not name.strip():
        shown = repr(name) if len(repr(name)) <= 60 else repr(name)[:57] + "..."
        raise FilterError(f"a step needs a filter name, got {shown}")
    check_name(name, "filter")
    params = dict(params or {})
    cls = registry.find(name)
    if cls is not None:
        return Step(cls.name, params, MESHOPT, label=label)
    from . import meshlab

    ml = meshlab.resolve(name)
    if ml is None:
        ours = registry.names() + [c.label for c in registry]
        hint = did_you_mean(name, ours) or meshlab.suggestions(name)
        raise FilterError(
            f"unknown filter {name!r}{hint}: not a meshopt filter (see 'meshopt filters') "
            "nor a MeshLab filter known to pymeshlab (see 'meshopt filters --all')"
        )
    return Step(ml, params, MESHLAB, label=label or name, mlx_params=mlx_params)


class Pipeline:
    """An ordered list of :class:`Step`.

    Examples
    --------
    >>> p = Pipeline.from_dict({"filters": [{"name": "meshing_uniform_refinement"}]})
    >>> [s.name for s in p.steps]
    ['meshing_uniform_refinement']
    """

    def __init__(self, steps: list[Step] | None = None, source: str | None = None) -> None:
        self.steps = list(steps or [])
        self.source = source

    # -- construction ---------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Any, source: str | None = None) -> "Pipeline":
        """From the JSON structure ``{"filters": [{"name": ..., "params": {...}}, ...]}``."""
        where = f"{source}: " if source else ""
        if not isinstance(data, dict) or "filters" not in data:
            raise FilterError(f'{where}a pipeline is an object {{"filters": [...]}}')
        extra = set(data) - {"filters", "description", "version"}
        if extra:
            raise FilterError(f"{where}unknown pipeline key {_short(sorted(extra)[0])}")
        items = data["filters"]
        if not isinstance(items, list):
            raise FilterError(f'{where}"filters" must be a list')
        check_step_count(len(items), where)
        steps = []
        for i, item in enumerate(items, start=1):
            if not isinstance(item, dict) or "name" not in item:
                raise FilterError(f'{where}step {i}: expected {{"name": ..., "params": {{...}}}}')
            bad = set(item) - {"name", "params"}
            if bad:
                raise FilterError(f"{where}step {i}: unknown key {_short(sorted(bad)[0])}")
            params = item.get("params", {})
            if not isinstance(params, dict):
                raise FilterError(f'{where}step {i}: "params" must be an object')
            try:
                steps.append(make_step(item["name"], params))
            except FilterError as exc:
                raise FilterError(f"{where}step {i}: {exc}") from None
        return cls(steps, source)

    def to_dict(self) -> dict:
        return {"filters": [s.to_dict() for s in self.steps]}

    @property
    def has_meshlab_steps(self) -> bool:
        return any(s.kind == MESHLAB for s in self.steps)

    @property
    def only_builtin(self) -> bool:
        """True if every step is a built-in meshopt filter (no pymeshlab, no plugin)."""
        return all(s.kind == MESHOPT and s.filter.origin == "builtin" for s in self.steps)

    # -- validation -----------------------------------------------------------------
    def _where(self) -> str:
        return f"{self.source}: " if self.source else ""

    @contextlib.contextmanager
    def _at(self, i: int, step: Step) -> Iterator[None]:
        """Prefix errors with the file and the step (counted from 1), keeping their type."""
        try:
            yield
        except MeshoptError as exc:
            msg = f"{self._where()}step {i + 1} ({step.name}): {exc}"
            try:
                new = type(exc)(msg)
            except Exception:  # pragma: no cover - an exotic constructor
                new = FilterError(msg)
            raise new from None

    def validate(self) -> list[dict]:
        """Check every step's parameters and path templates; the validated parameters.

        Nothing is read: types, ranges, finite numbers, MeshLab parameter names and types,
        refused filters, and output paths that are absolute or contain ``..``.

        Raises
        ------
        FilterError
            Naming the file, the step (from 1), its filter and the problem.
        """
        check_step_count(len(self.steps), self._where())
        out = []
        for i, s in enumerate(self.steps):
            with self._at(i, s):
                if s.kind == MESHOPT:
                    vals = s.filter.validate_params(s.params)
                    for p in s.filter.parameters:
                        if isinstance(p, PathParam) and vals.get(p.name):
                            try:
                                (check_output_template if p.save else check_input_template)(
                                    vals[p.name])
                            except FilterError as exc:
                                raise FilterError(f"parameter {p.name!r}: {exc}") from None
                    out.append(vals)
                else:
                    from . import meshlab

                    meshlab.check_safe(s.name)
                    meshlab.validate_params(s.name, s.params)
                    for key in _meshlab_read_params(s):
                        check_input_template(s.params[key])
                    out.append(dict(s.params))
        return out

    def check_kinds(self, document: Document, validated: list[dict], start: int = 0) -> None:
        """Check that each step from ``start`` on takes the kind of mesh it will get: the
        kind of the document's current mesh, changed only by steps that say so
        (:attr:`Filter.kinds`, :meth:`Filter.kind_after`; a MeshLab step takes triangles
        and keeps the kind). Nothing runs; the chain stops at a step whose result is
        known only once it runs (a file it loads), and without a current mesh.

        Raises
        ------
        FilterError
            ``"PIPELINE: step 2 (apply_coord_shape_optimization): supports planar
            triangle meshes; the current mesh is a tetrahedral mesh"``.
        """
        kind = kind_of(document.mesh) if document.entries else None
        for i in range(start, len(self.steps)):
            if kind is None:
                return
            s, vals = self.steps[i], validated[i]
            kinds = s.filter.kinds if s.kind == MESHOPT else MESHLAB_KINDS
            if kind not in kinds:
                why = "" if s.kind == MESHOPT else " (pymeshlab holds triangles only)"
                with self._at(i, s):
                    raise FilterError(f"supports {' and '.join(_PLURAL[k] for k in kinds)}"
                                      f"{why}; the current mesh is {KIND_NAMES[kind]}")
            if s.kind == MESHOPT:
                kind = s.filter.kind_after(kind, vals)

    def _resolved(self, document: Document, s: Step, vals: dict) -> dict:
        """``vals`` with every file path expanded and confined (:class:`ResolvedPath`)."""
        out = dict(vals)
        if s.kind == MESHOPT:
            for p in s.filter.parameters:
                if isinstance(p, PathParam) and vals.get(p.name):
                    resolve = resolve_output if p.save else resolve_input
                    out[p.name] = ResolvedPath(str(resolve(document, vals[p.name])))
        else:
            for key in _meshlab_read_params(s):
                out[key] = ResolvedPath(str(resolve_input(document, vals[key])))
        return out

    def check(self, document: Document) -> list[dict]:
        """Everything that can be known without running a filter (``--dry-run``).

        :meth:`validate`, then for each step its paths against ``document`` (outputs
        confined and not existing without ``document.overwrite``, inputs allowed) and the
        estimated triangles after it, chained from the current mesh, against
        ``document.max_triangles``.

        Returns
        -------
        list of dict
            The validated parameters per step.
        """
        validated = self.validate()
        self.check_kinds(document, validated)
        stats = stats_of(document.mesh) if document.entries else None
        basis = "" if stats is None else f"the input's {stats.n_triangles:,} triangles"
        for i, (s, vals) in enumerate(zip(self.steps, validated)):
            with self._at(i, s):
                rv = self._resolved(document, s, vals)
                if s.kind == MESHLAB:
                    document.require_triangles()
                    est = None if stats is None else estimate_meshlab(s.name, rv, stats)
                else:
                    est = s.filter.plan(document, rv, stats)
                    if stats is None and est is not None:
                        basis = f"the {est.n_triangles:,} triangles loaded in step {i + 1}"
                check_budget(est, document.max_triangles, basis)
                stats = est
        return validated

    # -- running --------------------------------------------------------------------
    def run(self, document: Document,
            callback: Callable[[int, Step], None] | None = None) -> Document:
        """Run every step on ``document`` (mutated and returned).

        ``callback(i, step)`` is called before each step (``i`` from 0). Results of steps
        that return a summary are appended to ``document.results`` as
        ``{"step": i + 1, "filter": name, ...}``; warnings go to ``document.warnings``.

        Raises
        ------
        MeshoptError
            The first failing step, named (from 1) with its filter; a step that does not
            take the kind of mesh it would get (before any step runs), over budget, a
            path outside what is allowed, or inverted triangles after a MeshLab step.
        """
        validated = self.validate()
        ms = None
        for i, (s, vals) in enumerate(zip(self.steps, validated)):
            if ms is None:  # the steps left, before any work (the mesh as it is now)
                self.check_kinds(document, validated, i)
            if callback is not None:
                callback(i, s)
            with self._at(i, s):
                rv = self._resolved(document, s, vals)
                if s.kind == MESHLAB:
                    if ms is None:
                        ms = document.to_meshset()
                    res = self._run_meshlab(document, ms, i, s, rv)
                    nxt = self.steps[i + 1] if i + 1 < len(self.steps) else None
                    if nxt is None or nxt.kind != MESHLAB:
                        document.update_from_meshset(
                            ms, step=f"{self._where()}step {i + 1} ({s.name})")
                        ms = None
                else:
                    stats = stats_of(document.mesh) if document.entries else None
                    basis = "" if stats is None else f"{stats.n_triangles:,} triangles before it"
                    check_budget(s.filter.plan(document, rv, stats), document.max_triangles, basis)
                    res = s.filter().apply(document, **rv)
                    if document.entries:
                        check_measured(stats_of(document.mesh).n_triangles,
                                       document.max_triangles)
            if res:
                document.results.append({"step": i + 1, "filter": s.name, **res})
        return document

    def _run_meshlab(self, document: Document, ms, i: int, s: Step, vals: dict) -> dict | None:
        from . import meshlab

        normal = None
        if ms.mesh_number():
            V, F = _arrays(ms)
            stats = stats_of_arrays(V, F)
            check_budget(estimate_meshlab(s.name, vals, stats), document.max_triangles,
                         f"{stats.n_triangles:,} triangles before it")
            normal = admissible_normal(V, F)
        res = meshlab.apply(ms, s.name, vals)
        if ms.mesh_number():
            check_measured(ms.current_mesh().face_number(), document.max_triangles)
        if normal is not None and ms.mesh_number():
            n_bad = count_inverted(*_arrays(ms), normal)
            if n_bad:
                msg = (f"{n_bad} inverted triangles after this step (negative signed area; "
                       "the planar mesh was admissible before)")
                if not document.allow_inverted:
                    raise FilterError(f"{msg}; nothing written (--allow-inverted writes it "
                                      "anyway)")
                warning = f"{self._where()}step {i + 1} ({s.name}): {msg}"
                document.warnings.append(warning)
                logger.info("%s", warning)
        return res

    def __len__(self) -> int:
        return len(self.steps)

    def __repr__(self) -> str:
        return f"Pipeline({[s.name for s in self.steps]})"


def _arrays(ms):
    """Vertex and face arrays of the current mesh of a MeshSet (compacted first)."""
    m = ms.current_mesh()
    if not m.is_compact():
        m.compact()
    return m.vertex_matrix(), m.face_matrix()


def _meshlab_read_params(s: Step) -> list[str]:
    """Parameters of a MeshLab step that name a file it reads (non-empty ones)."""
    from . import meshlab

    return [k for k, v in s.params.items()
            if (s.name, k) in meshlab.READ_PATH_PARAMS and isinstance(v, str) and v]


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
