"""Typed parameters and filter parameter validation."""

from __future__ import annotations

import pytest

from meshopt_toolkit.errors import FilterError
from meshopt_toolkit.pipeline import (
    BoolParam,
    EnumParam,
    Filter,
    FilterRegistry,
    FloatParam,
    IntParam,
    Length,
    LengthParam,
    PathParam,
    StringParam,
    registry,
)


class AllKinds(Filter):
    name = "test_all_kinds"
    label = "Test All Kinds"
    description = "A filter with one parameter of each kind."
    parameters = (
        BoolParam("flag", True, "a flag", label="Flag"),
        IntParam("count", 3, "a count", min=1, max=10),
        FloatParam("weight", 0.25, "bounded", min=0.0, max=1.0),
        FloatParam("free", -1.5, "unbounded"),
        EnumParam("mode", "Mean ratio", "a choice", choices=("area/max side", "Mean ratio", "Area")),
        StringParam("note", "hello <world> & \"quotes\"", "text"),
        PathParam("target", "out/{stem}.ply", "where", save=True),
        LengthParam("size", Length(2.0, percent=True), "a length"),
    )

    def apply(self, document, **params):
        return {k: str(v) for k, v in params.items()}


def test_defaults_filled_and_converted():
    vals = AllKinds.validate_params({"count": "7", "weight": 1, "mode": "area", "size": 0.5})
    assert vals["count"] == 7 and isinstance(vals["count"], int)
    assert vals["weight"] == 1.0 and isinstance(vals["weight"], float)
    assert vals["mode"] == "Area"
    assert vals["size"] == Length(0.5)
    assert vals["flag"] is True and vals["free"] == -1.5


@pytest.mark.parametrize(
    "params, fragment",
    [
        ({"count": 0}, "below the minimum 1"),
        ({"count": 11}, "above the maximum 10"),
        ({"count": 2.5}, "expected an integer"),
        ({"count": True}, "expected an integer"),
        ({"weight": "heavy"}, "expected a number"),
        ({"weight": float("nan")}, "finite"),
        ({"weight": 1.5}, "above the maximum"),
        ({"flag": "yes"}, "expected true or false"),
        ({"flag": 1}, "expected true or false"),
        ({"mode": "mean rati"}, "did you mean 'Mean ratio'"),
        ({"mode": 5}, "out of range"),
        ({"note": 3}, "expected a string"),
        ({"target": ""}, "empty"),
        ({"size": "big"}, "not a length"),
        ({"size": -1}, "below the minimum"),
        ({"coutn": 3}, "no parameter 'coutn' (did you mean 'count'?)"),
    ],
)
def test_clear_errors(params, fragment):
    with pytest.raises(FilterError) as info:
        AllKinds.validate_params(params)
    assert fragment in str(info.value)
    assert "test_all_kinds" in str(info.value)


def test_length_parse_and_resolve():
    assert Length.parse("5%") == Length(5.0, True)
    assert Length.parse(" 0.3 ") == Length(0.3)
    assert Length.parse("5%").resolve(diameter=4.0) == pytest.approx(0.2)
    assert Length.parse(0.3).resolve(diameter=4.0) == 0.3
    assert Length(5.0, True).to_json() == "5%"


def test_mlx_attributes_complete():
    vals = AllKinds.validate_params({})
    attrs = {p.name: p.to_mlx(vals[p.name], diameter=2.0) for p in AllKinds.parameters}
    for a in attrs.values():
        assert {"type", "name", "value", "description", "tooltip"} <= set(a)
    assert attrs["flag"]["type"] == "RichBool" and attrs["flag"]["value"] == "true"
    assert attrs["weight"]["type"] == "RichDynamicFloat"
    assert (attrs["weight"]["min"], attrs["weight"]["max"]) == ("0", "1")
    assert attrs["free"]["type"] == "RichFloat"
    e = attrs["mode"]
    assert e["type"] == "RichEnum" and e["value"] == "1" and e["enum_cardinality"] == "3"
    assert [e[f"enum_val{i}"] for i in range(3)] == ["area/max side", "Mean ratio", "Area"]
    assert attrs["target"]["type"] == "RichSaveFile"
    s = attrs["size"]  # MeshLab stores the absolute value with the diagonal as max
    assert s["type"] == "RichAbsPerc" and float(s["value"]) == pytest.approx(0.04)
    assert (s["min"], s["max"]) == ("0", "2")
    # and every Param reads back to the same value
    for p in AllKinds.parameters:
        back = p.from_mlx(p.to_mlx(vals[p.name]))
        assert back == vals[p.name], p.name


def test_spec_has_everything_for_docs():
    spec = AllKinds.spec()
    assert spec["name"] == "test_all_kinds" and spec["label"] == "Test All Kinds"
    kinds = {p["name"]: p["type"] for p in spec["parameters"]}
    assert kinds == {"flag": "bool", "count": "int", "weight": "float", "free": "float",
                     "mode": "enum", "note": "string", "target": "path", "size": "length"}
    count = next(p for p in spec["parameters"] if p["name"] == "count")
    assert (count["min"], count["max"], count["default"]) == (1, 10, 3)
    size = next(p for p in spec["parameters"] if p["name"] == "size")
    assert size["default"] == "2%"


def test_registry_rejects_bad_filters():
    reg = FilterRegistry(builtin_package=None, group=None)

    class NoLabel(Filter):
        name = "no_label"
        description = "x"

    class BadName(Filter):
        name = "Bad Name"
        label = "B"
        description = "x"

    for cls in (NoLabel, BadName):
        with pytest.raises(FilterError):
            reg.register(cls)
    reg.register(AllKinds)

    class Clash(AllKinds):
        label = "Other"

    with pytest.raises(FilterError, match="already registered"):
        reg.register(Clash)
    assert reg.get("test all kinds") is AllKinds  # by label, case-insensitive
    with pytest.raises(FilterError, match="did you mean 'test_all_kinds'"):
        reg.get("test_al_kinds")


def test_builtins_registered_with_the_required_names():
    names = registry.names()
    for required in ("compute_scalar_by_shape_quality_per_face", "meshing_uniform_refinement",
                     "load_mesh", "save_mesh"):
        assert required in names
    labels = [c.label for c in registry]
    assert len(set(map(str.lower, labels))) == len(labels)
