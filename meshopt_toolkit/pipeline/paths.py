"""Paths in pipelines: whitelisted templates, outputs confined, inputs allowed explicitly.

A pipeline file is untrusted; the command line is the only authority over the file system.

Templates
    ``{name}`` (the current mesh's name), ``{stem}``, ``{suffix}`` (``.msh``), ``{ext}``
    (``msh``), ``{input_dir}`` of the input file, and ``{index}`` (its position in the
    batch, from 1) are replaced; ``{{`` and ``}}`` are literal braces. Anything else —
    ``{0}``, ``{}``, ``{stem.__class__}``, ``{stem[0]}``, ``{stem!r}``, ``{stem:>9}`` — is
    refused: nothing is evaluated (``str.format`` is never called on user text).
Outputs
    Paths written by a pipeline (``save_mesh``, every :class:`PathParam` with
    ``save=True``) are relative to the output directory (``meshopt run -o``; the current
    directory when a document has none). An absolute path or a ``..`` component is
    refused when the pipeline is checked; at run time the resolved path (symlinks
    followed) must lie inside the output directory.
Inputs
    Paths read by a pipeline (``load_mesh``, every :class:`PathParam` with ``save=False``)
    are relative to the input file's folder. After resolving symlinks they must be one of
    the run's input files (:attr:`Document.inputs`) or lie inside a folder or be a file
    given with ``--allow-read`` (:attr:`Document.allow_read`); nothing else is readable.
    ``meshopt run`` always confines reads; a document made in Python leaves them to the
    calling program unless its ``allow_read`` is set to a list.
"""

from __future__ import annotations

import os
import re
from pathlib import Path, PurePath
from typing import TYPE_CHECKING, Mapping

from ..errors import FilterError

if TYPE_CHECKING:  # pragma: no cover
    from .document import Document

__all__ = [
    "TEMPLATE_FIELDS",
    "ResolvedPath",
    "expand_template",
    "check_output_template",
    "check_input_template",
    "template_variables",
    "resolve_output",
    "resolve_input",
]

#: the fields a path template may use
TEMPLATE_FIELDS = ("name", "stem", "suffix", "ext", "index", "input_dir")
#: fields whose values must be one plain path component (all but input_dir)
_COMPONENT_FIELDS = frozenset(TEMPLATE_FIELDS) - {"input_dir"}
_TOKEN = re.compile(r"\{\{|\}\}|\{([^{}]*)\}|[{}]")
#: values used when a template is checked before any input is known
_PLACEHOLDERS = {"name": "name", "stem": "stem", "suffix": ".msh", "ext": "msh",
                 "index": "1", "input_dir": "/input_dir"}


class ResolvedPath(str):
    """A path already expanded and checked by the runner (absolute, confined)."""


def expand_template(template: str, variables: Mapping[str, str]) -> str:
    """Replace the whitelisted ``{field}`` names of ``template`` by ``variables``.

    Raises
    ------
    FilterError
        A field outside :data:`TEMPLATE_FIELDS` (attribute or index access, positional
        fields, conversions, format specs), a stray brace, a field without a value, or a
        value that is not one plain path component (``/``, ``..``) where one is needed.

    Examples
    --------
    >>> expand_template("{stem}_fine.{ext}", {"stem": "a", "ext": "ply"})
    'a_fine.ply'
    """
    allowed = ", ".join("{" + f + "}" for f in TEMPLATE_FIELDS)

    def bad(why: str) -> FilterError:
        return FilterError(f"bad template in path {template!r}: {why}; only {allowed} "
                           "(and {{ }} for literal braces) may appear")

    def sub(m: re.Match) -> str:
        tok = m.group(0)
        if tok in ("{{", "}}"):
            return tok[0]
        field = m.group(1)
        if field is None:
            raise bad(f"unmatched {tok!r}")
        if field not in TEMPLATE_FIELDS:
            raise bad(f"field {'{' + field + '}'!r} is not allowed")
        if field not in variables:
            raise bad(f"{'{' + field + '}'} has no value here")
        value = str(variables[field])
        if field in _COMPONENT_FIELDS and not _is_component(value):
            raise FilterError(f"path {template!r}: {{{field}}} = {value!r} is not a plain "
                              "file name")
        return value

    return _TOKEN.sub(sub, template)


def _is_component(value: str) -> bool:
    return (value not in ("", ".", "..") and "/" not in value and "\\" not in value
            and "\0" not in value)


def template_variables(document: Document) -> dict[str, str]:
    """The template values for ``document`` (its variables, ``name`` = current mesh)."""
    out = {k: str(v) for k, v in document.variables.items() if k in TEMPLATE_FIELDS}
    if "suffix" in out and "ext" not in out:
        out["ext"] = out["suffix"].lstrip(".")
    if document.entries:
        out["name"] = document.current_entry.name
    out.setdefault("name", out.get("stem", "mesh"))
    out.setdefault("stem", "mesh")
    return out


def _check_relative(text: str, template: str) -> None:
    pure = PurePath(text)
    if not text.strip():
        raise FilterError(f"output path {template!r} is empty")
    if pure.is_absolute() or text.startswith(("/", "\\", "~")) or re.match(r"^[A-Za-z]:", text):
        raise FilterError(f"output path {template!r} is absolute; a pipeline writes only "
                          "inside the output directory (-o), give a relative path")
    if ".." in re.split(r"[/\\]", text):
        raise FilterError(f"output path {template!r} contains '..'; a pipeline writes only "
                          "inside the output directory (-o)")


def check_output_template(template: str) -> None:
    """Check an output path template without any input (syntax, relative, no ``..``)."""
    _check_relative(expand_template(template, _PLACEHOLDERS), template)


def check_input_template(template: str) -> None:
    """Check an input path template without any input (syntax only)."""
    if not expand_template(template, _PLACEHOLDERS).strip():
        raise FilterError(f"input path {template!r} is empty")


def _output_root(document: Document) -> Path:
    return Path(document.output_dir) if document.output_dir is not None else Path.cwd()


def _inside(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip(os.sep) + os.sep)


def _expanded(document: Document, template: str, to_path) -> Path:
    """``to_path`` of ``template`` with the run's variables; a :class:`ResolvedPath`
    (made by the runner) as it is."""
    if isinstance(template, ResolvedPath):
        return Path(template)
    return to_path(expand_template(template, template_variables(document)))


def resolve_output(document: Document, template: str) -> Path:
    """The confined output path for ``template`` (relative to the output directory).

    A :class:`ResolvedPath` (made by the runner) is only re-checked for containment.

    Raises
    ------
    FilterError
        Bad template, absolute path, ``..``, or a path that resolves (through symlinks)
        outside the output directory.
    """
    root = _output_root(document)

    def inside_root(text: str) -> Path:
        _check_relative(text, template)
        return root / text

    path = _expanded(document, template, inside_root)
    real_root = os.path.realpath(root)
    real = os.path.realpath(path)
    if not _inside(real, real_root):
        raise FilterError(f"output path {str(template)!r} resolves to {real}, outside the "
                          f"output directory {root} (a symlink?); refused")
    if real == real_root:
        raise FilterError(f"output path {str(template)!r} is the output directory itself")
    return path


def resolve_input(document: Document, template: str) -> Path:
    """The path for reading ``template``, if the run allows reading it.

    Relative paths are relative to ``{input_dir}`` (the current directory without one).
    With ``document.allow_read`` None (a document made in Python, not by ``meshopt run``)
    any path is returned.

    Raises
    ------
    FilterError
        Bad template, or a file that is neither an input of the run nor inside a path
        given with ``--allow-read`` (symlinks are followed before deciding).
    """
    def from_input_dir(text: str) -> Path:
        if not text.strip():
            raise FilterError(f"input path {template!r} is empty")
        path = Path(text)
        if not path.is_absolute() and document.variables.get("input_dir"):
            path = Path(document.variables["input_dir"]) / path
        return path

    path = _expanded(document, template, from_input_dir)
    if document.allow_read is None:  # a document made in Python: the program decides
        return path
    real = os.path.realpath(path)
    if any(real == os.path.realpath(p) for p in document.inputs):
        return path
    if any(_inside(real, os.path.realpath(p)) for p in document.allow_read):
        return path
    raise FilterError(f"reading {str(template)!r} ({real}) is not allowed: a pipeline reads "
                      "only the run's inputs and paths given with --allow-read")
