"""Typed filter parameters: validation, JSON form and MeshLab ``<Param>`` elements.

Every parameter has a name, a default, an optional range and a help text; that is enough
to validate user values with clear messages and to write complete MeshLab ``Param``
elements (``type``, ``name``, ``value``, ``description``, ``tooltip``, ``min``/``max``,
``enum_cardinality``/``enum_valK``) that MeshLab and pymeshlab read back.

Kinds and their MeshLab types:

========  ==========================  ==============================================
kind      Python value                MeshLab type
========  ==========================  ==============================================
bool      ``bool``                    ``RichBool`` (``true``/``false``)
int       ``int``                     ``RichInt``
float     ``float``                   ``RichFloat``, ``RichDynamicFloat`` if bounded
enum      ``str`` (one of ``choices``) ``RichEnum`` (index in ``value``)
string    ``str``                     ``RichString``
path      ``str``                     ``RichOpenFile`` / ``RichSaveFile``
length    :class:`Length`             ``RichAbsPerc`` (absolute value, min/max)
========  ==========================  ==============================================
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any, ClassVar

from ..errors import FilterError
from .meshlab_values import Length, meshlab_float

__all__ = [
    "BoolParam",
    "EnumParam",
    "ExpressionParam",
    "FloatParam",
    "IntParam",
    "Length",
    "LengthParam",
    "NumberListParam",
    "Param",
    "PathParam",
    "StringParam",
    "did_you_mean",
    "param_from_mlx",
]


def did_you_mean(word: str, candidates) -> str:
    """``" (did you mean 'x'?)"`` for the closest candidate, or ``""``."""
    close = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def number_list(text: str, n: int, what: str) -> tuple[float, ...] | None:
    """Parse a string parameter holding ``n`` non-negative comma-separated numbers
    (e.g. β = ``"10,1,0,1.46"``); an empty string gives None (use the default).

    Raises
    ------
    FilterError
        Not exactly ``n`` numbers, a negative or a non-finite one (``nan``, ``inf``); the
        message names ``what``.
    """
    if not text.strip():
        return None
    shown = text if len(text) <= 60 else text[:57] + "..."
    try:
        values = tuple(float(x) for x in text.split(",", n))
    except ValueError:
        raise FilterError(f"{what}: expected {n} comma-separated numbers, got {shown!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise FilterError(f"{what}: expected {n} finite numbers, got {shown!r}")
    if len(values) != n or min(values) < 0:
        raise FilterError(f"{what}: expected {n} non-negative comma-separated numbers, got {shown!r}")
    return values


@dataclass(frozen=True)
class Param:
    """Base class of typed parameters.

    Attributes
    ----------
    name : str
        snake_case keyword used in Python and JSON (also the ``Param name`` in .mlx).
    default
        Default value (already valid).
    help : str
        One-line help, written as the MeshLab ``tooltip``.
    label : str
        Short GUI caption, the MeshLab ``description``; defaults to the name.
    """

    name: str
    default: Any = None
    help: str = ""
    label: str = ""

    kind: ClassVar[str] = "?"
    mlx_type: ClassVar[str] = "?"

    # -- validation -----------------------------------------------------------------
    def _error(self, filter_name: str, msg: str) -> FilterError:
        return FilterError(f"filter {filter_name!r}, parameter {self.name!r}: {msg}")

    def validate(self, value: Any, filter_name: str = "?") -> Any:
        """The value converted to this parameter's Python type, or a clear FilterError."""
        raise NotImplementedError

    # -- descriptions ---------------------------------------------------------------
    def spec(self) -> dict:
        """JSON-able description: kind, default, help, label and the range fields."""
        return {
            "name": self.name,
            "type": self.kind,
            "mlx_type": self.mlx_type,
            "default": self.to_json(self.default),
            "label": self.label or self.name,
            "help": self.help,
        }

    def to_json(self, value: Any) -> Any:
        return value

    # -- MeshLab --------------------------------------------------------------------
    def to_mlx(self, value: Any, diameter: float | None = None) -> dict[str, str]:
        """Attributes of a complete MeshLab ``<Param>`` element for ``value``."""
        return {
            "type": self.mlx_type,
            "name": self.name,
            "value": self._mlx_value(value),
            "description": self.label or self.name,
            "tooltip": self.help,
        }

    def _mlx_value(self, value: Any) -> str:
        return str(value)

    def from_mlx(self, attrs: dict[str, str], filter_name: str = "?") -> Any:
        """Value of a ``<Param>`` element (its ``value`` attribute), validated."""
        if "value" not in attrs:
            raise self._error(filter_name, "Param element has no 'value' attribute")
        return self._from_mlx_value(attrs["value"], attrs, filter_name)

    def _from_mlx_value(self, raw: str, attrs: dict[str, str], filter_name: str) -> Any:
        """The value of the ``value`` attribute ``raw`` (the element's ``attrs`` beside)."""
        return self.validate(raw, filter_name)


@dataclass(frozen=True)
class BoolParam(Param):
    default: bool = False
    kind: ClassVar[str] = "bool"
    mlx_type: ClassVar[str] = "RichBool"

    def validate(self, value, filter_name="?") -> bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.strip().lower() in ("true", "false"):
            return value.strip().lower() == "true"
        raise self._error(filter_name, f"expected true or false, got {value!r}")

    def _mlx_value(self, value) -> str:
        return "true" if value else "false"


@dataclass(frozen=True)
class _NumberParam(Param):
    min: float | None = None
    max: float | None = None
    #: the minimum itself is not allowed (``> min``, e.g. a positive weight)
    exclusive_min: bool = False

    def _check_range(self, v, filter_name):
        if self.min is not None and (v <= self.min if self.exclusive_min else v < self.min):
            bound = "must be above" if self.exclusive_min else "is below the minimum"
            raise self._error(filter_name, f"{v!r} {bound} {self.min!r}")
        if self.max is not None and v > self.max:
            raise self._error(filter_name, f"{v!r} is above the maximum {self.max!r}")
        return v

    def spec(self) -> dict:
        return {**super().spec(), "min": self.min, "max": self.max,
                "exclusive_min": self.exclusive_min}

    #: the words of a type error ("expected an integer, got ...")
    expected: ClassVar[str] = "a number"

    def _number(self, value):
        """``value`` (not a string) as this parameter's type, or None where it is not one."""
        raise NotImplementedError

    def _parse(self, text: str):
        raise NotImplementedError

    def validate(self, value, filter_name="?"):
        if isinstance(value, str):
            try:
                value = self._parse(value.strip())
            except ValueError:
                raise self._error(filter_name, f"expected {self.expected}, got {value!r}")
        number = None if isinstance(value, bool) else self._number(value)
        if number is None:
            raise self._error(filter_name, f"expected {self.expected}, got {value!r}")
        if isinstance(number, float) and not math.isfinite(number):
            raise self._error(filter_name, f"expected a finite number, got {value!r}")
        return self._check_range(number, filter_name)

    def to_mlx(self, value, diameter=None):
        out = super().to_mlx(value, diameter)
        # the range as attributes in the value's format (MeshLab's RichInt has none: it
        # ignores them)
        for key, bound in (("min", self.min), ("max", self.max)):
            if bound is not None:
                out[key] = self._mlx_value(bound)
        return out


@dataclass(frozen=True)
class IntParam(_NumberParam):
    default: int = 0
    kind: ClassVar[str] = "int"
    mlx_type: ClassVar[str] = "RichInt"

    expected: ClassVar[str] = "an integer"
    _parse = staticmethod(int)

    def _number(self, value) -> int | None:
        if isinstance(value, float) and value.is_integer():
            return int(value)
        return int(value) if isinstance(value, int) else None


@dataclass(frozen=True)
class FloatParam(_NumberParam):
    default: float = 0.0
    kind: ClassVar[str] = "float"

    @property
    def mlx_type(self) -> str:  # type: ignore[override]
        bounded = self.min is not None and self.max is not None
        return "RichDynamicFloat" if bounded else "RichFloat"

    _parse = staticmethod(float)

    def _number(self, value) -> float | None:
        return float(value) if isinstance(value, (int, float)) else None

    def _mlx_value(self, value) -> str:
        return meshlab_float(float(value))


@dataclass(frozen=True)
class EnumParam(Param):
    """A choice among labels; accepts the label (case-insensitive) or its index."""

    default: str = ""
    choices: tuple[str, ...] = ()
    kind: ClassVar[str] = "enum"
    mlx_type: ClassVar[str] = "RichEnum"

    def validate(self, value, filter_name="?") -> str:
        if isinstance(value, int) and not isinstance(value, bool):
            if 0 <= value < len(self.choices):
                return self.choices[value]
            raise self._error(filter_name, f"enum index {value} out of range 0..{len(self.choices) - 1}")
        if isinstance(value, str):
            for c in self.choices:
                if c == value or c.lower() == value.strip().lower():
                    return c
            raise self._error(
                filter_name,
                f"unknown choice {value!r}{did_you_mean(value, self.choices)}; "
                f"valid: {', '.join(map(repr, self.choices))}",
            )
        raise self._error(filter_name, f"expected one of {list(self.choices)}, got {value!r}")

    def spec(self) -> dict:
        return {**super().spec(), "choices": list(self.choices)}

    def to_mlx(self, value, diameter=None):
        out = super().to_mlx(value, diameter)
        out["value"] = str(self.choices.index(self.validate(value)))
        out["enum_cardinality"] = str(len(self.choices))
        for i, c in enumerate(self.choices):
            out[f"enum_val{i}"] = c
        return out

    def _from_mlx_value(self, raw, attrs, filter_name):
        try:
            return self.validate(int(raw), filter_name)
        except ValueError:
            return self.validate(raw, filter_name)


@dataclass(frozen=True)
class StringParam(Param):
    default: str = ""
    kind: ClassVar[str] = "string"
    mlx_type: ClassVar[str] = "RichString"

    def validate(self, value, filter_name="?") -> str:
        if not isinstance(value, str):
            raise self._error(filter_name, f"expected a string, got {value!r}")
        return value


@dataclass(frozen=True)
class NumberListParam(StringParam):
    """A string of ``count`` non-negative finite comma-separated numbers, or empty (the
    filter's default); checked when the pipeline is validated (``--dry-run``), passed on
    as the string (the filter parses it with :func:`number_list`)."""

    count: int = 1

    def validate(self, value, filter_name="?") -> str:
        value = super().validate(value, filter_name)
        number_list(value, self.count, f"filter {filter_name!r}, parameter {self.name!r}")
        return value

    def spec(self) -> dict:
        return {**super().spec(), "count": self.count}


@dataclass(frozen=True)
class ExpressionParam(StringParam):
    """A user expression in ``x, y`` (:mod:`meshopt_toolkit.expressions`: whitelisted, never
    ``eval``-ed), parsed when the pipeline is validated (``--dry-run``) so that a bad one
    (``1/0``, an unknown name) names the filter and parameter before any file is read."""

    def validate(self, value, filter_name="?") -> str:
        from ..errors import ExpressionError
        from ..expressions import parse_expression

        value = super().validate(value, filter_name)
        try:
            if parse_expression(value).uses_z:  # the filters' meshes are planar
                raise ExpressionError("z is not defined for a planar mesh")
        except ExpressionError as exc:
            message = str(exc) if repr(value) in str(exc) else f"{value!r}: {exc}"
            raise self._error(filter_name, message) from None
        return value


@dataclass(frozen=True)
class PathParam(StringParam):
    """A file path; ``save=True`` for output files (``RichSaveFile``). A path whose
    default is empty is optional: empty means not given (as a saved pipeline writes it)."""

    save: bool = False
    kind: ClassVar[str] = "path"

    @property
    def mlx_type(self) -> str:  # type: ignore[override]
        return "RichSaveFile" if self.save else "RichOpenFile"

    def validate(self, value, filter_name="?") -> str:
        value = super().validate(str(value) if hasattr(value, "__fspath__") else value, filter_name)
        if not value.strip():
            if self.default == "":
                return ""
            raise self._error(filter_name, "expected a file path, got an empty string")
        return value

    def to_mlx(self, value, diameter=None):
        out = super().to_mlx(value, diameter)
        ext = value.rsplit(".", 1)[-1] if "." in value else ""
        out["ext"] = ext
        return out


@dataclass(frozen=True)
class LengthParam(Param):
    """An absolute-or-percentage length (of the bounding-box diagonal), MeshLab AbsPerc."""

    default: Length = Length(0.0)
    min: float | None = 0.0
    kind: ClassVar[str] = "length"
    mlx_type: ClassVar[str] = "RichAbsPerc"

    def validate(self, value, filter_name="?") -> Length:
        try:
            length = Length.parse(value)
        except ValueError as exc:
            raise self._error(filter_name, str(exc))
        if not math.isfinite(length.value):
            raise self._error(filter_name, f"expected a finite length, got {value!r}")
        if self.min is not None and length.value < self.min:
            raise self._error(filter_name, f"{length} is below the minimum {self.min!r}")
        return length

    def to_json(self, value):
        return Length.parse(value).to_json()

    def spec(self) -> dict:
        return {**super().spec(), "min": self.min}

    def to_mlx(self, value, diameter=None):
        """MeshLab stores the absolute value with ``min=0``, ``max=diagonal``.

        Without a mesh (``diameter=None``) a percentage cannot be made absolute: it is
        written against a nominal diagonal of 100 with ``percent="true"`` (an attribute
        MeshLab ignores) so that reading back restores the percentage.
        """
        length = Length.parse(value)
        out = super().to_mlx(value, diameter)
        if length.percent and diameter is None:
            out.update(value=meshlab_float(length.value), min="0", max="100", percent="true")
        else:
            d = 1.0 if diameter is None else float(diameter)
            out.update(value=meshlab_float(length.resolve(d)), min="0",
                       max=meshlab_float(max(d, 0.0)))
        return out

    def _from_mlx_value(self, raw, attrs, filter_name):
        if attrs.get("percent", "").lower() == "true":
            return self.validate(f"{raw}%", filter_name)
        return self.validate(raw, filter_name)


def param_from_mlx(attrs: dict[str, str]) -> Any:
    """The Python value of a generic MeshLab ``<Param>`` (used for MeshLab filters).

    Returns values pymeshlab's ``apply_filter`` accepts once passed through
    :func:`meshopt_toolkit.pipeline.meshlab.to_pymeshlab_value`: ``bool``, ``int``,
    ``float``, ``str``, ``{"abs": x}`` for RichAbsPerc, lists for colors, positions and
    matrices.

    Raises
    ------
    FilterError
        Missing or malformed attributes.
    """
    kind = attrs.get("type", "")
    name = attrs.get("name", "?")
    try:
        if kind == "RichBool":
            v = attrs["value"].strip().lower()
            if v not in ("true", "false"):
                raise ValueError(v)
            return v == "true"
        if kind in ("RichInt", "RichMesh"):
            return int(attrs["value"])
        if kind in ("RichFloat", "RichDynamicFloat"):
            return float(attrs["value"])
        if kind == "RichEnum":
            return int(attrs["value"])
        if kind == "RichAbsPerc":
            return {"abs": float(attrs["value"])}
        if kind in ("RichString", "RichOpenFile", "RichSaveFile", "RichFileOpen", "RichFileSave"):
            return attrs["value"]
        if kind == "RichColor":
            return [int(attrs[c]) for c in ("r", "g", "b", "a")]
        if kind in ("RichPosition", "RichDirection", "RichPoint3f"):
            return [float(attrs[c]) for c in ("x", "y", "z")]
        if kind == "RichMatrix44f":
            return [float(attrs[f"val{i}"]) for i in range(16)]
        if kind == "RichShotf":
            raise FilterError(f"parameter {name!r}: RichShotf (camera) parameters are not supported")
    except (KeyError, ValueError) as exc:
        raise FilterError(f"parameter {name!r} ({kind}): malformed or missing attribute {exc}") from None
    raise FilterError(f"parameter {name!r}: unknown MeshLab parameter type {kind!r}")
