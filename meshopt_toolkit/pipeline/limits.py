"""Bounds on pipeline files and on what a pipeline may make.

A pipeline file is untrusted input: its size, its number of steps, the nesting depth of
its JSON and the length of its names are bounded before anything else looks at it, so a
hostile file fails in milliseconds with a one-line :class:`FilterError` naming the file
(never a ``RecursionError`` or a hang).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import FilterError, ReadError

__all__ = [
    "MAX_PIPELINE_BYTES",
    "MAX_STEPS",
    "MAX_DEPTH",
    "MAX_NAME",
    "DEFAULT_MAX_TRIANGLES",
    "json_depth",
    "check_json_text",
    "check_step_count",
    "check_name",
    "read_bounded",
]

#: pipeline files (JSON or .mlx) larger than this are refused before parsing
MAX_PIPELINE_BYTES = 1024 * 1024
#: at most this many steps in one pipeline
MAX_STEPS = 256
#: deepest nesting of JSON arrays/objects (a pipeline needs 5; a 4×4 matrix 6)
MAX_DEPTH = 16
#: longest filter or parameter name (keeps "did you mean" cheap)
MAX_NAME = 200
#: default size budget: triangles of the document after any step (``--max-triangles``)
DEFAULT_MAX_TRIANGLES = 5_000_000

_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*\\?(?:"|\Z)', re.DOTALL)


def json_depth(data: bytes) -> int:
    """Deepest nesting of ``[``/``{`` in JSON text, strings skipped (vectorized).

    Exact for valid JSON; for invalid JSON a bound good enough to refuse deep nesting
    before the parser recurses.

    Examples
    --------
    >>> json_depth(b'{"a": [1, {"b": "[[["}]}')
    3
    """
    stripped = _JSON_STRING.sub(b'""', data)
    b = np.frombuffer(stripped, dtype=np.uint8)
    step = (np.isin(b, (ord("["), ord("{"))).astype(np.int64)
            - np.isin(b, (ord("]"), ord("}"))).astype(np.int64))
    return int(np.cumsum(step).max(initial=0))


def check_json_text(data: bytes, where: str) -> None:
    """Refuse JSON text deeper than :data:`MAX_DEPTH` (before ``json.loads`` recurses)."""
    depth = json_depth(data)
    if depth > MAX_DEPTH:
        raise FilterError(f"{where}JSON nested {depth} levels deep; a pipeline may nest at "
                          f"most {MAX_DEPTH}")


def check_step_count(n: int, where: str) -> None:
    if n > MAX_STEPS:
        raise FilterError(f"{where}{n} steps; a pipeline may have at most {MAX_STEPS}")


def check_name(name: str, what: str) -> None:
    """Refuse a filter or parameter name longer than :data:`MAX_NAME` characters."""
    if len(name) > MAX_NAME:
        raise FilterError(f"{what} name of {len(name)} characters (at most {MAX_NAME}): "
                          f"{name[:40]!r}...")


def read_bounded(path, limit: int = MAX_PIPELINE_BYTES) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes.

    Raises
    ------
    FilterError
        Missing, not a regular file, larger than ``limit``, or unreadable; the message
        names the file.
    """
    from ..io._files import open_input

    p = Path(path)
    try:
        with open_input(p, limit) as fh:  # regular files only: a FIFO is never opened
            data = fh.read(limit + 1)
    except ReadError as exc:  # the same checks as for meshes, named as a pipeline's
        message = str(exc).removeprefix(f"{p}: ")
        if message == "no such file":
            message = "no such pipeline file"
        elif "larger than the limit" in message:
            message = f"pipeline file larger than {limit} bytes; refused"
        raise FilterError(f"{p}: {message}") from None
    except OSError as exc:
        raise FilterError(f"{p}: cannot read the pipeline file: {exc.strerror or exc}") from None
    if len(data) > limit:  # grew since stat
        raise FilterError(f"{p}: pipeline file larger than {limit} bytes; refused")
    return data
