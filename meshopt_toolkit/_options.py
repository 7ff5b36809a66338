"""The one way an options dataclass is given: an instance, a mapping of its fields, or
None (the defaults), with changes on top (:func:`options_of`); the one check of a named
choice (:func:`check_choice`), of a number's range (:func:`require_positive`,
:func:`require_at_least`) and of an array's shape (:func:`require_shape`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from .errors import OptionError

__all__ = ["check_choice", "options_of", "require_at_least", "require_positive",
           "require_shape"]


def require_shape(name: str, array, shape: tuple, *, error: type[Exception] = ValueError):
    """``array`` if its shape is ``shape``, else ``error`` naming ``name`` and both shapes
    (``"derivative: shape (3, 2), expected (4, 2)"``)."""
    if np.shape(array) != tuple(shape):
        raise error(f"{name}: shape {np.shape(array)}, expected {tuple(shape)}")
    return array


def require_positive(name: str, value, *, error: type[Exception] = OptionError):
    """``value`` if it is None (left to its default) or > 0, else ``error`` naming ``name``
    (``"weight must be > 0, got -1"``); NaN is refused."""
    if value is not None and not value > 0:
        raise error(f"{name} must be > 0, got {value!r}")
    return value


def require_at_least(name: str, value, low: int, *, error: type[Exception] = OptionError):
    """``value`` if it is None (left to its default) or ``>= low``, else ``error`` naming
    ``name`` (``"frames must be at least 2, got 1"``); for counts such as frames and
    iterations."""
    if value is not None and not value >= low:
        raise error(f"{name} must be at least {low}, got {value!r}")
    return value


def check_choice(value, choices, what: str, *, error: type[Exception]):
    """``value`` if it is one of ``choices``, else ``error`` naming ``what`` and the
    choices (``"unknown method 'x'; choose one of a, b"``)."""
    if value not in choices:
        raise error(f"unknown {what} {value!r}; choose one of {', '.join(map(str, choices))}")
    return value


def options_of(cls, options, changes: Mapping, *, error: type[Exception], what: str):
    """``options`` as an instance of the dataclass ``cls``, with ``changes`` applied.

    Parameters
    ----------
    cls : a dataclass whose every field has a default
    options : an instance of ``cls``, a mapping of its fields, or None (the defaults)
    changes : fields set on top of ``options``
    error : the exception raised for a wrong type or an unknown field
    what : the fields' name in its message (e.g. ``"optimize option(s)"``)

    Raises
    ------
    error
        ``options`` of another type, or a field ``cls`` does not have (named, with the
        fields it has).
    """
    if options is None:
        base = cls()
    elif isinstance(options, Mapping):
        changes = {**options, **changes}
        base = cls()
    elif isinstance(options, cls):
        base = options
    else:
        raise error(f"options must be a {cls.__name__} or a mapping of its fields, got "
                    f"{type(options).__name__}")
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(changes) - known)
    if unknown:
        raise error(f"unknown {what} {', '.join(unknown)}; choose from {', '.join(sorted(known))}")
    return dataclasses.replace(base, **changes) if changes else base
