"""Checks on input files before they are opened: regular files only, a size cap.

A FIFO blocks a reader forever and ``/dev/zero`` (or a symlink to it) never ends; both
are refused from their ``stat`` before any byte is read. Files larger than the cap are
refused with a message that says how to raise it.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from ..errors import ReadError

#: default size cap of a mesh file (bytes); ``MESHOPT_MAX_FILE_BYTES`` overrides it
MAX_FILE_BYTES = 4 * 1024**3

_UNITS = {"": 1, "b": 1, "k": 1024, "kb": 1024, "m": 1024**2, "mb": 1024**2,
          "g": 1024**3, "gb": 1024**3, "t": 1024**4, "tb": 1024**4}


def parse_size(text: str) -> int:
    """``"512M"`` → 536870912; plain numbers are bytes; units k, M, G, T (powers of 1024).

    Raises
    ------
    ValueError
        Not a non-negative size.
    """
    t = str(text).strip().lower()
    num = t.rstrip("kmgtb")
    unit = t[len(num):]
    if unit not in _UNITS or not num:
        raise ValueError(f"not a size: {text!r} (e.g. 500M, 8G)")
    value = float(num)
    if not value >= 0 or value == float("inf"):
        raise ValueError(f"not a size: {text!r}")
    return int(value * _UNITS[unit])


def default_max_bytes() -> int:
    """:data:`MAX_FILE_BYTES`, or ``MESHOPT_MAX_FILE_BYTES`` from the environment."""
    env = os.environ.get("MESHOPT_MAX_FILE_BYTES")
    if env:
        try:
            return parse_size(env)
        except ValueError:
            raise ReadError(f"MESHOPT_MAX_FILE_BYTES={env!r} is not a size") from None
    return MAX_FILE_BYTES


def _human(n: int) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024 or unit == "TiB":
            return f"{n} bytes" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return str(n)  # pragma: no cover


def check_input_file(path: str | os.PathLike, max_bytes: int | None = None) -> int:
    """Refuse anything but an existing regular file of at most ``max_bytes``.

    Symlinks are followed (a link to ``/dev/zero`` is refused as a device).

    Returns
    -------
    int
        The file size in bytes.

    Raises
    ------
    ReadError
        Missing, a directory, a FIFO/socket/device, or larger than the cap.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ReadError(f"{path}: no such file") from None
    except OSError as exc:
        raise ReadError(f"{path}: {exc.strerror or exc}") from None
    mode = st.st_mode
    if stat.S_ISDIR(mode):
        raise ReadError(f"{path}: is a directory")
    if not stat.S_ISREG(mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else
                "a character device" if stat.S_ISCHR(mode) else
                "a block device" if stat.S_ISBLK(mode) else
                "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
        raise ReadError(f"{path}: is {kind}, not a regular file")
    cap = default_max_bytes() if max_bytes is None else int(max_bytes)
    if st.st_size > cap:
        raise ReadError(f"{path}: file is {_human(st.st_size)}, larger than the limit of "
                        f"{_human(cap)} (raise it with --max-file-size or "
                        "MESHOPT_MAX_FILE_BYTES)")
    return int(st.st_size)
