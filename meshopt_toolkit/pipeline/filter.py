"""The filter API and the registry of filters.

A filter is a small class::

    from meshopt_toolkit.pipeline import Filter, IntParam, register

    @register
    class Twice(Filter):
        name = "meshing_twice"                 # snake_case, pymeshlab style
        label = "Twice (meshopt)"              # MeshLab-style label, <filter name="..."> in .mlx
        description = "Refine twice."          # one line
        parameters = (IntParam("times", 2, "how often", min=1),)
        aliases = ("refine_twice",)             # old names, still accepted (optional)
        renamed_parameters = {"n": "times"}    # old parameter names (optional)
        kinds = (PLANAR, SURFACE)              # the meshes it takes (default: all)

        def apply(self, document, *, times):
            ...

Built-ins live in ``meshopt_toolkit.filters`` (one module each, named as the filter) and are imported when
the registry is first used. Third-party filters are found through the entry-point group
``meshopt_toolkit.filters`` (each entry point names a :class:`Filter` subclass), loaded
lazily; a plugin that fails to load gives a :class:`PluginWarning`, not a crash.

Pipelines saved with a filter's old name or label, or its old parameter names, keep
running: :meth:`FilterRegistry.find` accepts ``aliases`` and :meth:`Filter.validate_params`
renames old parameters (:meth:`Filter.upgrade_params`); a pipeline written back uses the
current names.
"""

from __future__ import annotations

import importlib
import logging
import pkgutil
import re
import warnings
from typing import TYPE_CHECKING, Any, ClassVar, Iterator

from ..errors import FilterError
from .document import MESH_KINDS, PLANAR, SURFACE, TETS
from .params import Param, did_you_mean

if TYPE_CHECKING:  # pragma: no cover
    from .budget import MeshStats
    from .document import Document

logger = logging.getLogger(__name__)

__all__ = ["Filter", "FilterRegistry", "PluginWarning", "registry", "register", "ENTRY_POINT_GROUP",
           "PLANAR", "SURFACE", "TETS", "MESH_KINDS"]

ENTRY_POINT_GROUP = "meshopt_toolkit.filters"
_NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")


class PluginWarning(UserWarning):
    """A third-party filter plugin could not be loaded (the rest keeps working)."""


class Filter:
    """Base class of meshopt filters.

    Subclasses set the class attributes ``name``, ``label``, ``description`` and
    ``parameters`` and implement :meth:`apply`.
    """

    name: ClassVar[str] = ""
    label: ClassVar[str] = ""
    description: ClassVar[str] = ""
    parameters: ClassVar[tuple[Param, ...]] = ()
    #: former names and labels of the filter, still found by the registry
    aliases: ClassVar[tuple[str, ...]] = ()
    #: former parameter name -> current name (same type), accepted in saved pipelines
    renamed_parameters: ClassVar[dict[str, str]] = {}
    #: other former parameter name -> the current one it became (changed shape, e.g. four
    #: floats that became one list), converted by an overridden :meth:`upgrade_params`
    former_parameters: ClassVar[dict[str, str]] = {}
    #: where the filter comes from: "builtin" or the plugin's distribution name
    origin: ClassVar[str] = "builtin"
    #: the kinds of current mesh the filter takes (of :data:`MESH_KINDS`); a pipeline
    #: checks every step against them before it runs any (and ``--dry-run`` reports it)
    kinds: ClassVar[tuple[str, ...]] = MESH_KINDS

    @classmethod
    def kind_after(cls, kind: str, params: dict[str, Any]) -> str | None:
        """The kind of the current mesh after this step, given its kind before and the
        step's validated ``params``; None when only running the step tells (a file it
        loads). The default: the kind does not change."""
        return kind

    def apply(self, document: "Document", **params: Any) -> dict | None:
        """Run on ``document`` (mutating it); return a JSON-able summary dict or None."""
        raise NotImplementedError(f"{type(self).__name__}.apply is not implemented")

    @classmethod
    def plan(cls, document: "Document", params: dict[str, Any],
             stats: "MeshStats | None") -> "MeshStats | None":
        """Check what can be checked without running, and estimate the mesh after it.

        Called by the runner before every step and by ``--dry-run`` instead of
        :meth:`apply`, with validated ``params`` whose paths are already confined.
        ``stats`` describes the current mesh before the step (None if unknown).

        Returns
        -------
        MeshStats or None
            The current mesh after this step (an upper bound of its triangles), or None
            when unknown until run time. The default: unchanged.
        """
        return stats

    # -- parameters -----------------------------------------------------------------
    @classmethod
    def param(cls, name: str) -> Param:
        for p in cls.parameters:
            if p.name == name:
                return p
        raise FilterError(
            f"filter {cls.name!r} has no parameter {name!r}"
            f"{did_you_mean(name, [p.name for p in cls.parameters])}; "
            f"parameters: {', '.join(p.name for p in cls.parameters) or 'none'}"
        )

    @classmethod
    def upgrade_params(cls, params: dict[str, Any]) -> dict[str, Any]:
        """``params`` with former parameter names replaced by the current ones
        (:attr:`renamed_parameters`); a filter whose parameters changed shape overrides it.

        Raises
        ------
        FilterError
            A parameter given under both its former and its current name.
        """
        out = dict(params)
        for old, new in cls.renamed_parameters.items():
            if old in out:
                if new in out:
                    raise FilterError(f"filter {cls.name!r}: give {new!r} or its former name "
                                      f"{old!r}, not both")
                out[new] = out.pop(old)
        return out

    @classmethod
    def validate_params(cls, params: dict[str, Any] | None) -> dict[str, Any]:
        """All parameters with defaults filled in, each validated and converted;
        former parameter names are accepted (:meth:`upgrade_params`).

        Raises
        ------
        FilterError
            Unknown parameter (with a "did you mean"), wrong type, out of range or unknown
            enum label.
        """
        params = cls.upgrade_params(dict(params or {}))
        out = {}
        for key in params:
            cls.param(key)  # raises for unknown names
        for p in cls.parameters:
            out[p.name] = p.validate(params[p.name], cls.name) if p.name in params else p.default
        return out

    @classmethod
    def spec(cls) -> dict:
        """JSON-able description: name, label, description, parameters, origin."""
        return {
            "name": cls.name,
            "label": cls.label,
            "description": cls.description,
            "origin": cls.origin,
            "kinds": list(cls.kinds),
            "aliases": list(cls.aliases),
            "former_parameters": {**cls.renamed_parameters, **cls.former_parameters},
            "parameters": [p.spec() for p in cls.parameters],
        }

    def __call__(self, document: "Document", **params: Any) -> dict | None:
        """Validate ``params`` then :meth:`apply`."""
        return self.apply(document, **self.validate_params(params))


def _check_filter_class(obj: Any, where: str) -> type[Filter]:
    if not (isinstance(obj, type) and issubclass(obj, Filter)):
        raise FilterError(f"{where}: {obj!r} is not a Filter subclass")
    if not _NAME_RE.match(obj.name or ""):
        raise FilterError(f"{where}: filter name {obj.name!r} is not snake_case")
    if not obj.label or not obj.description:
        raise FilterError(f"{where}: filter {obj.name!r} needs a label and a description")
    if not obj.kinds or not set(obj.kinds) <= set(MESH_KINDS):
        raise FilterError(f"{where}: filter {obj.name!r}: kinds must be some of "
                          f"{', '.join(MESH_KINDS)}, got {obj.kinds!r}")
    names = [p.name for p in obj.parameters]
    if len(set(names)) != len(names):
        raise FilterError(f"{where}: filter {obj.name!r} has duplicate parameter names")
    former = {**obj.renamed_parameters, **obj.former_parameters}
    if set(former) & set(names) or not set(former.values()) <= set(names):
        raise FilterError(f"{where}: filter {obj.name!r}: former parameter names must map "
                          "to current parameters")
    return obj


class FilterRegistry:
    """Name → filter class, plus label → name; built-ins and plugins loaded lazily."""

    def __init__(self, builtin_package: str | None = "meshopt_toolkit.filters",
                 group: str | None = ENTRY_POINT_GROUP) -> None:
        self._filters: dict[str, type[Filter]] = {}
        self._builtin_package = builtin_package
        self._group = group
        self._builtins_loaded = builtin_package is None
        self._plugins_loaded = group is None

    # -- registration ---------------------------------------------------------------
    def register(self, cls: type[Filter], origin: str | None = None) -> type[Filter]:
        """Add a filter class (usable as a decorator); a clash raises FilterError."""
        _check_filter_class(cls, origin or cls.__module__)
        if origin is not None:
            cls.origin = origin
        old = self._filters.get(cls.name)
        if old is not None and old is not cls:
            raise FilterError(f"filter name {cls.name!r} already registered by {old.__module__}")
        mine = {k.lower() for k in (cls.name, cls.label, *cls.aliases)}
        for other in self._filters.values():
            if other is not cls and other.label.lower() == cls.label.lower():
                raise FilterError(f"filter label {cls.label!r} already used by {other.name!r}")
            theirs = {k.lower() for k in (other.name, other.label, *other.aliases)}
            if other is not cls and mine & theirs:
                raise FilterError(f"filter {cls.name!r}: name or alias "
                                  f"{sorted(mine & theirs)[0]!r} already used by {other.name!r}")
        self._filters[cls.name] = cls
        return cls

    def unregister(self, name: str) -> None:
        self._filters.pop(name, None)

    # -- lazy loading ---------------------------------------------------------------
    def _load_builtins(self) -> None:
        if self._builtins_loaded:
            return
        self._builtins_loaded = True
        pkg = importlib.import_module(self._builtin_package)
        for info in pkgutil.iter_modules(pkg.__path__):
            if not info.name.startswith("_"):
                importlib.import_module(f"{self._builtin_package}.{info.name}")

    def load_plugins(self) -> None:
        """Load the entry points of the group (once); broken ones give a PluginWarning."""
        if self._plugins_loaded:
            return
        self._plugins_loaded = True
        self._load_builtins()
        from importlib.metadata import entry_points

        for ep in entry_points(group=self._group):
            dist = getattr(getattr(ep, "dist", None), "name", None) or ep.value
            try:
                obj = ep.load()
                if obj.name in self._filters and self._filters[obj.name] is not obj:
                    raise FilterError(f"filter name {obj.name!r} is already taken")
                self.register(obj, origin=dist)
            except Exception as exc:  # a plugin must never take the toolkit down
                warnings.warn(
                    f"meshopt filter plugin {ep.name!r} ({ep.value}) could not be loaded: "
                    f"{type(exc).__name__}: {exc}",
                    PluginWarning,
                    stacklevel=2,
                )

    def _ensure(self, full: bool) -> None:
        self._load_builtins()
        if full:
            self.load_plugins()

    # -- lookup ---------------------------------------------------------------------
    def find(self, name_or_label: str) -> type[Filter] | None:
        """The filter with this name, (case-insensitive) label or alias (a former name
        or label), or None."""
        for full in (False, True):
            self._ensure(full)
            cls = self._filters.get(name_or_label)
            if cls is not None:
                return cls
            key = name_or_label.strip().lower()
            for c in self._filters.values():
                if c.label.lower() == key or key in (a.lower() for a in c.aliases):
                    return c
        return None

    def get(self, name_or_label: str) -> type[Filter]:
        """Like :meth:`find` but raises FilterError with a "did you mean"."""
        cls = self.find(name_or_label)
        if cls is None:
            cands = list(self._filters) + [c.label for c in self._filters.values()]
            raise FilterError(f"unknown filter {name_or_label!r}{did_you_mean(name_or_label, cands)}")
        return cls

    def names(self) -> list[str]:
        self._ensure(True)
        return sorted(self._filters)

    def __iter__(self) -> Iterator[type[Filter]]:
        return iter([self._filters[n] for n in self.names()])

    def __contains__(self, name: str) -> bool:
        return self.find(name) is not None


#: the process-wide registry
registry = FilterRegistry()


def register(cls: type[Filter]) -> type[Filter]:
    """Decorator registering a built-in filter class in :data:`registry`."""
    return registry.register(cls)
