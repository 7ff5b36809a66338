"""Pipelines: a list of steps, each a meshopt filter or a MeshLab (pymeshlab) filter.

A step names a filter by its snake_case name or its MeshLab label. Our registry is asked
first; anything else is resolved against pymeshlab (imported only then). Consecutive
MeshLab steps share one ``pymeshlab.MeshSet``; the document is converted to it before the
first and back after the last of them.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, Callable

from ..errors import FilterError, MeshoptError
from .document import Document
from .filter import registry
from .params import did_you_mean

logger = logging.getLogger(__name__)

__all__ = ["Step", "Pipeline", "load_pipeline", "save_pipeline"]

MESHOPT = "meshopt"
MESHLAB = "meshlab"


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
        raise FilterError(f"a step needs a filter name, got {name!r}")
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
            raise FilterError(f"{where}unknown pipeline key {sorted(extra)[0]!r}")
        items = data["filters"]
        if not isinstance(items, list):
            raise FilterError(f'{where}"filters" must be a list')
        steps = []
        for i, item in enumerate(items):
            if not isinstance(item, dict) or "name" not in item:
                raise FilterError(f'{where}step {i}: expected {{"name": ..., "params": {{...}}}}')
            bad = set(item) - {"name", "params"}
            if bad:
                raise FilterError(f"{where}step {i}: unknown key {sorted(bad)[0]!r}")
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

    # -- validation and running -----------------------------------------------------
    def validate(self) -> list[dict]:
        """Check every step's parameters; returns the validated parameters per step.

        Raises
        ------
        FilterError
            Naming the step, its filter and the problem.
        """
        out = []
        for i, s in enumerate(self.steps):
            try:
                if s.kind == MESHOPT:
                    out.append(s.filter.validate_params(s.params))
                else:
                    from . import meshlab

                    meshlab.check_safe(s.name)
                    meshlab.validate_params(s.name, s.params)
                    out.append(dict(s.params))
            except FilterError as exc:
                raise FilterError(f"{self._where()}step {i} ({s.name}): {exc}") from None
        return out

    def _where(self) -> str:
        return f"{self.source}: " if self.source else ""

    def run(self, document: Document,
            callback: Callable[[int, Step], None] | None = None) -> Document:
        """Run every step on ``document`` (mutated and returned).

        ``callback(i, step)`` is called before each step. Results of steps that return a
        summary are appended to ``document.results`` as ``{"step": i, "filter": name, ...}``.
        """
        validated = self.validate()
        ms = None
        for i, (s, vals) in enumerate(zip(self.steps, validated)):
            if callback is not None:
                callback(i, s)
            try:
                if s.kind == MESHLAB:
                    from . import meshlab

                    if ms is None:
                        ms = document.to_meshset()
                    res = meshlab.apply(ms, s.name, vals)
                    nxt = self.steps[i + 1] if i + 1 < len(self.steps) else None
                    if nxt is None or nxt.kind != MESHLAB:
                        document.update_from_meshset(ms)
                        ms = None
                else:
                    res = s.filter().apply(document, **vals)
            except MeshoptError as exc:  # keep the error type, add where it happened
                try:
                    new = type(exc)(f"{self._where()}step {i} ({s.name}): {exc}")
                except Exception:  # pragma: no cover - an exotic constructor
                    new = FilterError(f"{self._where()}step {i} ({s.name}): {exc}")
                raise new from None
            if res:
                document.results.append({"step": i, "filter": s.name, **res})
        return document

    def __len__(self) -> int:
        return len(self.steps)

    def __repr__(self) -> str:
        return f"Pipeline({[s.name for s in self.steps]})"


def load_pipeline(path) -> Pipeline:
    """Read a pipeline from ``.json`` or ``.mlx`` (by extension; content sniffed otherwise)."""
    from pathlib import Path

    from . import json_format, mlx

    p = Path(path)
    if not p.is_file():
        raise FilterError(f"{p}: no such pipeline file")
    if p.suffix.lower() == ".mlx":
        return mlx.read_mlx(p)
    if p.suffix.lower() == ".json":
        return json_format.read_json(p)
    head = p.read_bytes()[:64].lstrip()
    return mlx.read_mlx(p) if head.startswith(b"<") else json_format.read_json(p)


def save_pipeline(pipeline: Pipeline, path, *, overwrite: bool = False,
                  diameter: float | None = None) -> None:
    """Write a pipeline as ``.json`` or ``.mlx`` (by extension)."""
    from pathlib import Path

    from . import json_format, mlx

    p = Path(path)
    if p.suffix.lower() == ".mlx":
        mlx.write_mlx(pipeline, p, overwrite=overwrite, diameter=diameter)
    elif p.suffix.lower() == ".json":
        json_format.write_json(pipeline, p, overwrite=overwrite)
    else:
        raise FilterError(f"{p}: pipeline files end in .json or .mlx")
