"""Helpers shared by the format modules: quiet meshio, text number blocks."""

from __future__ import annotations

import contextlib
import io
import logging
from collections.abc import Iterator

import numpy as np

from ..errors import ReadError, WriteError

logger = logging.getLogger(__name__)


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """Route meshio's console warnings (printed to stderr) to the log instead."""
    buf = io.StringIO()
    with contextlib.redirect_stderr(buf):
        yield
    if buf.getvalue().strip():
        logger.debug("meshio: %s", buf.getvalue().strip())


def format_rows(values: np.ndarray, fmt: str, prefix: str = "", group: int = 1) -> str:
    """Format an ``(n, k)`` array as text lines ``prefix v1 ... vk`` in one C-level pass.

    ``fmt`` is a ``%`` format for ``group`` consecutive values (``"%d/%d"`` with
    ``group=2``): ``"%r"`` gives the shortest repr that reads back bit-exactly for floats
    (at most 17 significant digits), ``"%d"`` for ints.
    """
    values = np.asarray(values)
    if values.size == 0:
        return ""
    n, k = values.shape
    row = prefix + " ".join([fmt] * (k // group)) + "\n"
    return (row * n) % tuple(values.ravel().tolist())


def float_array(tokens, message: str) -> np.ndarray:
    """``tokens`` (number strings, or rows of them) as a float64 array; a
    :class:`ReadError` with ``message`` where one is not a number."""
    try:
        return np.array(tokens, dtype=np.float64)
    except ValueError:
        raise ReadError(message) from None


def parse_rows(lines: list[str], source, what: str, min_cols: int, dtype=np.float64) -> np.ndarray:
    """Parse whitespace-separated numbers, one row per line, into an ``(n, k)`` array.

    Rows may have different lengths; only the first ``k`` = shortest length columns are
    kept, and a row shorter than ``min_cols`` is an error.

    Raises
    ------
    ReadError
        A token is not a number or a row is too short (names the file and the line).
    """
    rows = [s.split() for s in lines]
    if not rows:
        return np.zeros((0, min_cols), dtype)
    lengths = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
    k = int(lengths.min())
    if k < min_cols:
        bad = int(np.argmin(lengths))
        raise ReadError(f"{source}: {what} {bad} has {k} values, expected at least {min_cols}: "
                        f"{lines[bad].strip()!r}")
    if (lengths != k).any():
        rows = [r[:k] for r in rows]
    try:
        arr = np.array(rows, dtype=np.float64)
    except ValueError as exc:
        raise ReadError(
            f"{source}: {what} section has a value that is not a number ({exc})"
        ) from None
    if dtype is not np.float64:
        if not np.isfinite(arr).all() or np.any(arr != np.round(arr)):
            raise ReadError(f"{source}: {what} indices must be integers")
        arr = arr.astype(dtype)
    return arr


def decode_text(data: bytes, source) -> str:
    """Decode a text file (UTF-8 with Latin-1 fallback); NUL bytes mean it is binary junk."""
    if b"\x00" in data[:4096]:
        raise ReadError(f"{source}: looks like a binary file, expected text")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def require_text_mode(binary: bool | None, path, fmt: str) -> None:
    """Raise :class:`WriteError` when binary output is requested from a text-only format."""
    if binary:
        raise WriteError(f"{path}: {fmt} is a text format; binary output is not available")
