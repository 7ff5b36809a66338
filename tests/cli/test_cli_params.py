"""One parameter schema per operation: the CLI options of ``move``, ``morph``, ``deform``
and ``optimize`` are generated from their filters' typed parameters (type, default,
choices, help, range and range errors), and the library's defaults agree with them."""

from __future__ import annotations

import argparse
import inspect

import pytest

from meshopt_toolkit.cli import deform as cli_deform
from meshopt_toolkit.cli import morph as cli_morph
from meshopt_toolkit.cli import move as cli_move
from meshopt_toolkit.cli import optimize as cli_optimize
from meshopt_toolkit.cli._params import add_options, check_options
from meshopt_toolkit.cli._validate import OptionError
from meshopt_toolkit.deform import deform
from meshopt_toolkit.filters.generate_geodesic_morph import GenerateGeodesicMorph
from meshopt_toolkit.filters.apply_coord_quality_preserving_deformation import QualityPreservingDeformation
from meshopt_toolkit.filters.apply_coord_prescribed_motion import PrescribedMotion
from meshopt_toolkit.filters.apply_coord_shape_optimization import ShapeOptimization
from meshopt_toolkit.operations import morph
from meshopt_toolkit.motion.move import move
from meshopt_toolkit.optimize import optimize
from meshopt_toolkit.pipeline.filter import Filter
from meshopt_toolkit.pipeline.params import EnumParam, FloatParam, IntParam


class _Demo(Filter):  # not registered: only its parameters are used
    name = "demo_schema"
    parameters = (
        IntParam("count", 3, "how many", min=1, max=10),
        FloatParam("weight", 2.5, "a weight", min=0.0, exclusive_min=True),
        EnumParam("mode", "b", "which mode", choices=("a", "b")),
    )

    def apply(self, document, **kw):  # pragma: no cover - never applied
        return {}


OPTIONS = {"count": "--count", "weight": "--weight", "mode": "--mode"}


def _parser(filter_cls, options):
    p = argparse.ArgumentParser()
    add_options(p, filter_cls, options)
    return p


def test_generated_options_take_type_default_choices_and_range_from_the_parameters():
    p = _parser(_Demo, OPTIONS)
    args = p.parse_args([])
    assert (args.count, args.weight, args.mode) == (3, 2.5, "b")
    args = p.parse_args(["--count", "7", "--weight", "0.5", "--mode", "a"])
    assert (args.count, args.weight, args.mode) == (7, 0.5, "a")
    check_options(args, _Demo, OPTIONS)
    with pytest.raises(SystemExit):
        p.parse_args(["--mode", "c"])
    text = p.format_help()
    assert "how many (1 to 10; default: 3)" in text and "(> 0; default: 2.5)" in text
    for argv, message in ((["--count", "11"], "--count must be between 1 and 10, got 11"),
                          (["--weight", "0"], "--weight must be a finite number > 0, got 0"),
                          (["--weight", "nan"], "--weight must be a finite number > 0, got nan")):
        with pytest.raises(OptionError, match=message):
            check_options(p.parse_args(argv), _Demo, OPTIONS)


@pytest.mark.parametrize("cli, filter_cls, library", [
    (cli_move, PrescribedMotion, move),
    (cli_morph, GenerateGeodesicMorph, morph),
    (cli_deform, QualityPreservingDeformation, deform),
    (cli_optimize, ShapeOptimization, optimize),
])
def test_cli_filter_and_library_defaults_agree(cli, filter_cls, library):
    """One vocabulary: the library takes the filter's and the command's names."""
    p = argparse.ArgumentParser()
    cli.add_args(p)
    defaults = {name: p.get_default(name) for name in cli.OPTIONS}
    assert defaults == {name: filter_cls.param(name).default for name in cli.OPTIONS}
    signature = inspect.signature(library).parameters
    shared = [name for name in cli.OPTIONS if name in signature]
    assert shared  # the library names the same parameters
    for name in shared:
        assert signature[name].default == defaults[name], name


@pytest.mark.parametrize("param, words", [
    (FloatParam("w", 1.0, "a weight", min=0.0, max=10.0, exclusive_min=True), "> 0 and <= 10"),
    (FloatParam("w", 1.0, "a weight", min=0.0, max=10.0), "0 to 10"),
    (IntParam("k", 1, "a count", min=1), ">= 1"),
    (IntParam("k", 1, "a count", max=5), "<= 5"),
])
def test_an_options_help_states_its_whole_range(param, words):
    from meshopt_toolkit.cli._params import _help

    assert f"({words}; default: %(default)s)" in _help(param)
