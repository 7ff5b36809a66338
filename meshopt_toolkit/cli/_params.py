"""Command-line options generated from a filter's typed parameters.

One schema per operation: the filter's :class:`~meshopt_toolkit.pipeline.params.Param`
list is the single source of an option's type, default, choices, help and range, and of
its one-line range error (the same words as :mod:`._validate`'s). A subcommand names the
parameters it exposes and the option spelling of each::

    OPTIONS = {"steps": "--steps", "weight": "--weight"}
    add_options(parser, PrescribedMotion, OPTIONS)      # in add_args
    check_options(args, PrescribedMotion, OPTIONS)      # before any work

An option is spelled as its parameter (``max_iterations`` → ``--max-iterations``); former
spellings follow it in a tuple and stay accepted, so that saved command lines keep working::

    OPTIONS = {"max_iterations": ("--max-iterations", "--max-iter")}
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence

from ..pipeline.params import BoolParam, EnumParam, FloatParam, IntParam, Param
from ._validate import bound_text, check_int, check_number


def _help(param: Param) -> str:
    parts = []
    if isinstance(param, (IntParam, FloatParam)):
        low, high = param.min, param.max
        if low is not None and high is not None and not param.exclusive_min:
            parts.append(f"{low:g} to {high:g}")
        elif low is not None or high is not None:
            parts.append(bound_text(low, high, param.exclusive_min))
    parts.append("default: %(default)s")
    return f"{param.help} ({'; '.join(parts)})"


Options = Mapping[str, "str | Sequence[str]"]


def _spellings(option: "str | Sequence[str]") -> tuple[str, ...]:
    return (option,) if isinstance(option, str) else tuple(option)


def add_options(parser: argparse.ArgumentParser, filter_cls, options: Options) -> None:
    """Add one option per named parameter of ``filter_cls`` (``{param_name: "--option"}``,
    or a tuple: the option, then its former spellings); the value lands in
    ``args.<param_name>``."""
    for name, option in options.items():
        param = filter_cls.param(name)
        kwargs = {"dest": name, "default": param.default, "help": _help(param)}
        if isinstance(param, BoolParam):
            raise TypeError(f"{name}: boolean parameters need a --flag/--no-flag pair")
        if isinstance(param, IntParam):
            kwargs["type"] = int
        elif isinstance(param, FloatParam):
            kwargs["type"] = float
        elif isinstance(param, EnumParam):
            kwargs["choices"] = param.choices
        parser.add_argument(*_spellings(option), **kwargs)


def check_options(args: argparse.Namespace, filter_cls, options: Options) -> None:
    """The parameters' ranges on the parsed values, as one-line
    :class:`~._validate.OptionError` messages naming the option."""
    for name, option in options.items():
        param, value = filter_cls.param(name), getattr(args, name)
        option = _spellings(option)[0]
        if isinstance(param, IntParam) and param.min is not None and param.max is not None:
            check_int(option, value, param.min + 1 if param.exclusive_min else param.min,
                      param.max)
        elif isinstance(param, (IntParam, FloatParam)):
            check_number(option, value, low=param.min, high=param.max,
                         low_open=param.exclusive_min)
