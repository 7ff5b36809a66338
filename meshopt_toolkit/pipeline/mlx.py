"""MeshLab filter scripts (.mlx) as text, read with a hardened XML parser and written
complete (files of either format: :mod:`.formats`).

Reading uses :mod:`defusedxml` (``<!DOCTYPE FilterScript>`` is allowed, but any entity
declaration or external reference is refused before expansion), with a size limit, so a
hostile file fails within milliseconds with a clear :class:`FilterError`.

- ``<filter name="...">`` is a meshopt filter label (or name), or a MeshLab label that
  pymeshlab knows (see :mod:`.meshlab`); anything else is an error naming the filter.
- meshopt parameters are written with complete ``Param`` elements (type, name, value,
  description, tooltip, min/max, enum values) by :mod:`.params`.
- MeshLab steps read from a script keep their original ``Param`` attributes and are
  written back unchanged. MeshLab steps that come from JSON are recorded by pymeshlab
  itself (applied to a small probe mesh, then ``save_filter_script``) to get MeshLab's
  label, camelCase names and complete ``Param`` types; our values are then put back into
  the recorded elements (pymeshlab clamps bounded floats to the probe's range while
  recording). A step pymeshlab cannot record on the probe (or a filter refused as unsafe)
  is written under its pymeshlab name with pymeshlab parameter names: this toolkit reads
  it back, MeshLab does not.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from ..errors import FilterError
from .filter import registry
from .meshlab_values import meshlab_float
from .limits import MAX_PIPELINE_BYTES, check_name, check_step_count
from .params import did_you_mean, param_from_mlx
from .runner import MESHOPT, Pipeline, Step, make_step

__all__ = ["loads", "dumps", "MAX_BYTES"]

#: scripts larger than this are refused before parsing
MAX_BYTES = MAX_PIPELINE_BYTES


#: the only document type declaration a filter script may carry (MeshLab writes it)
_DOCTYPE = re.compile(rb"<!DOCTYPE\s+FilterScript\s*>")


def _parse(data: bytes, where: str):
    import defusedxml
    import defusedxml.ElementTree as DET

    if len(data) > MAX_BYTES:
        raise FilterError(f"{where}filter script larger than {MAX_BYTES} bytes; refused")
    # MeshLab's bare <!DOCTYPE FilterScript> is fine; any other DTD (internal subset with
    # entities, external DTD) is refused before anything is expanded or fetched
    data = _DOCTYPE.sub(b"", data, count=1)
    try:
        return DET.fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except defusedxml.EntitiesForbidden:
        raise FilterError(f"{where}the script declares XML entities (possible entity bomb); refused") from None
    except defusedxml.DTDForbidden:
        raise FilterError(f"{where}the script has a document type definition (DTD) other than "
                          "<!DOCTYPE FilterScript>; refused (entities and external resources "
                          "are not allowed)") from None
    except defusedxml.ExternalReferenceForbidden:
        raise FilterError(f"{where}the script references external XML resources; refused") from None
    except defusedxml.DefusedXmlException as exc:
        raise FilterError(f"{where}unsafe XML refused: {exc}") from None
    except ET.ParseError as exc:
        line, col = getattr(exc, "position", (0, 0))
        raise FilterError(f"{where}malformed XML at line {line}, column {col}: {exc}") from None


def loads(data: bytes | str, source: str | None = None) -> Pipeline:
    """Parse .mlx text into a :class:`Pipeline`.

    Raises
    ------
    FilterError
        Unsafe or malformed XML, a wrong root element, an unknown filter, or a bad
        parameter; the message names the filter and its position.
    """
    where = f"{source}: " if source else ""
    if isinstance(data, str):
        data = data.encode("utf-8")
    root = _parse(data, where)
    if root.tag != "FilterScript":
        raise FilterError(f"{where}not a MeshLab filter script (root element <{root.tag}>, "
                          "expected <FilterScript>)")
    check_step_count(len(root), where)
    steps = []
    for i, el in enumerate(root, start=1):
        if el.tag != "filter":
            raise FilterError(f"{where}step {i}: unexpected element <{_short(el.tag)}>")
        label = el.get("name")
        if not label:
            raise FilterError(f"{where}step {i}: <filter> without a name attribute")
        params = [dict(p.attrib) for p in el if p.tag in ("Param", "xmlparam")]
        try:
            check_name(label, "filter")
            steps.append(_step_from_mlx(label, params))
        except FilterError as exc:
            raise FilterError(f"{where}step {i} ({_short(label)}): {exc}") from None
    return Pipeline(steps, source)


def _short(text: str) -> str:
    shown = repr(text)
    return shown if len(shown) <= 60 else shown[:57] + "..."


def _step_from_mlx(label: str, params: list[dict[str, str]]) -> Step:
    cls = registry.find(label)
    if cls is not None:
        values = {}
        names = [p.name for p in cls.parameters]
        for attrs in params:
            pname = attrs.get("name", "")
            check_name(pname, "parameter")
            match = next((n for n in names if n == pname or n.lower() == pname.lower()), None)
            if match is None and pname in (*cls.renamed_parameters, *cls.former_parameters):
                # a former name (a script saved before the rename): upgraded on validation
                values[pname] = param_from_mlx(attrs)
                continue
            if match is None:
                raise FilterError(f"filter {cls.name!r} has no parameter {pname!r}"
                                  f"{did_you_mean(pname, names)}")
            values[match] = cls.param(match).to_json(cls.param(match).from_mlx(attrs, cls.name))
        return Step(cls.name, values, MESHOPT, label=label)
    values = {}
    for attrs in params:
        pname = attrs.get("name")
        if not pname:
            raise FilterError("<Param> without a name attribute")
        check_name(pname, "parameter")
        values[pname.lower()] = param_from_mlx(attrs)
    return make_step(label, values, label=label, mlx_params=params)


def dumps(pipeline: Pipeline, diameter: float | None = None) -> str:
    """The .mlx text of a pipeline.

    ``diameter`` (the bounding-box diagonal of the mesh it will run on) is used to write
    absolute-or-percentage lengths the way MeshLab stores them (absolute, max = diagonal).
    """
    root = ET.Element("FilterScript")
    for s in pipeline.steps:
        if s.kind == MESHOPT:
            cls = s.filter
            el = ET.SubElement(root, "filter", name=cls.label)
            vals = cls.validate_params(s.params)
            for p in cls.parameters:
                ET.SubElement(el, "Param", p.to_mlx(vals[p.name], diameter))
        else:
            recorded = None if s.mlx_params is not None else _record(s, diameter)
            if recorded is not None:
                root.append(recorded)
                continue
            el = ET.SubElement(root, "filter", name=s.label or s.name)
            original = {a.get("name", "").lower(): a for a in (s.mlx_params or [])}
            for key, value in s.params.items():
                attrs = original.get(key)
                if attrs is not None and _same(param_from_mlx(attrs), value):
                    ET.SubElement(el, "Param", attrs)
                else:
                    ET.SubElement(el, "Param", _meshlab_param(s.name, key, value))
    ET.indent(root, space=" ")
    return "<!DOCTYPE FilterScript>\n" + ET.tostring(root, encoding="unicode") + "\n"


def _probe_meshset(diameter: float | None):
    """A MeshSet with a small planar grid (quality, colors) whose diagonal is ``diameter``."""
    import numpy as np
    import pymeshlab

    n = 4
    x = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(x, x)
    pts = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1)
    pts[:, :2] *= (diameter or 1.0) / np.sqrt(2.0)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tri = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int32)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(pts, tri, v_scalar_array=pts[:, 0].copy(),
                               f_scalar_array=np.linspace(0.0, 1.0, len(tri)),
                               v_color_matrix=np.full((len(pts), 4), 0.5),
                               f_color_matrix=np.full((len(tri), 4), 0.5)))
    return ms


def _record(step: Step, diameter: float | None):
    """The ``<filter>`` element pymeshlab writes for a JSON MeshLab step, or None."""
    import logging
    import os
    import tempfile

    from . import meshlab

    log = logging.getLogger(__name__)
    if step.name in meshlab.UNSAFE_FILTERS:
        return None
    try:
        ms = _probe_meshset(diameter)
        kwargs = {k: meshlab.to_pymeshlab_value(step.name, k, v) for k, v in step.params.items()}
        ms.apply_filter(step.name, **kwargs)
        fd, tmp = tempfile.mkstemp(suffix=".mlx")
        os.close(fd)
        try:
            ms.save_filter_script(tmp)
            with open(tmp, "rb") as fh:
                root = _parse(fh.read(), "")
        finally:
            os.unlink(tmp)
        el = root[-1]
    except Exception as exc:  # the probe does not suit this filter: fall back
        log.info("cannot record MeshLab step %s with pymeshlab (%s); writing its "
                 "pymeshlab name", step.name, exc)
        return None
    for p in el:
        key = p.get("name", "").lower()
        if key in step.params:
            _put_value(p, step.params[key], diameter)
    return el


def _put_value(p, value, diameter) -> None:
    """Write our value into a recorded ``<Param>`` (undo pymeshlab's clamping)."""
    kind = p.get("type")
    if kind == "RichDynamicFloat":
        v = float(value)
        p.set("value", meshlab_float(v))
        p.set("min", meshlab_float(min(v, float(p.get("min", v)))))
        p.set("max", meshlab_float(max(v, float(p.get("max", v)))))
    elif kind == "RichFloat":
        p.set("value", meshlab_float(float(value)))
    elif kind == "RichAbsPerc":
        if isinstance(value, dict) and "abs" in value:
            value = value["abs"]
        if isinstance(value, (int, float)):
            p.set("value", meshlab_float(float(value)))
            p.set("max", meshlab_float(max(float(value), float(p.get("max", 0)))))
        # a percentage stays as pymeshlab recorded it (absolute for ``diameter``)


def _same(a, b) -> bool:
    return a == b or (isinstance(a, dict) and isinstance(b, (int, float)) and a.get("abs") == b)


def _meshlab_param(filter_name: str, key: str, value) -> dict[str, str]:
    """A ``<Param>`` for a MeshLab step given in JSON (pymeshlab names and types)."""
    from . import meshlab

    ptype = next((p["type"] for p in meshlab.parameter_list(filter_name) if p["name"] == key), "str")
    attrs = {"name": key, "description": key, "tooltip": ""}
    if isinstance(value, dict) and "abs" in value:
        value = value["abs"]
    if ptype.startswith("bool"):
        attrs.update(type="RichBool", value="true" if value else "false")
    elif ptype.startswith("int"):
        attrs.update(type="RichInt", value=str(int(value)))
    elif ptype.startswith("float (bounded)"):
        attrs.update(type="RichDynamicFloat", value=meshlab_float(float(value)),
                     min=meshlab_float(float(value)), max=meshlab_float(float(value)))
    elif ptype.startswith("float"):
        attrs.update(type="RichFloat", value=meshlab_float(float(value)))
    elif ptype.startswith("PercentageValue"):
        if isinstance(value, (str, dict)):
            raise FilterError(f"MeshLab step {filter_name!r}: parameter {key!r} is a percentage; "
                              ".mlx needs an absolute value (write the pipeline as JSON instead)")
        text = meshlab_float(float(value))
        attrs.update(type="RichAbsPerc", value=text, min="0", max=text)
    elif ptype.startswith("Color"):
        attrs.update(type="RichColor", **{c: str(int(v)) for c, v in zip("rgba", value)})
    elif ptype.startswith("numpy") and len(value) == 3:
        attrs.update(type="RichPosition",
                     **{c: meshlab_float(float(v)) for c, v in zip("xyz", value)})
    elif ptype.startswith("numpy"):
        attrs.update(type="RichMatrix44f",
                     **{f"val{i}": meshlab_float(float(v)) for i, v in enumerate(value)})
    else:
        attrs.update(type="RichString", value=str(value))
    return attrs
