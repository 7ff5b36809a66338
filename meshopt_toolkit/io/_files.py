"""Opening input files: regular files only, a size cap; one function for every reader.

A FIFO blocks a reader forever and ``/dev/zero`` (or a symlink to it) never ends; both
are refused from their ``stat`` (symlinks resolved) before any byte is read, and so are
sockets and other devices. :func:`open_input` is how every input is opened (mesh readers,
the batch's input hashing, a Dask client sending inputs): it stats first, opens without
blocking and checks again on the open descriptor that it is the same regular file. Files
larger than the cap are refused with a message that says how to raise it.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import BinaryIO

from ..errors import ReadError

#: default size cap of a mesh file (bytes); ``MESHOPT_MAX_FILE_BYTES`` overrides it
MAX_FILE_BYTES = 4 * 1024**3
#: ``max_bytes`` of a reader whose caller has checked the user's cap (``load``/``load_cells``)
UNCAPPED = 1 << 62

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
    return int(_stat_regular(Path(path), max_bytes).st_size)


def _kind(mode: int) -> str:
    return ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else
            "a character device" if stat.S_ISCHR(mode) else
            "a block device" if stat.S_ISBLK(mode) else
            "a socket" if stat.S_ISSOCK(mode) else "not a regular file")


def _stat_regular(path: Path, max_bytes: int | None) -> os.stat_result:
    """``os.stat`` of ``path`` (symlinks followed) if it is a regular file under the cap."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ReadError(f"{path}: no such file") from None
    except OSError as exc:
        raise ReadError(f"{path}: {exc.strerror or exc}") from None
    mode = st.st_mode
    real = os.path.realpath(path)  # name what a symlink points to: "a.msh (-> /dev/zero)"
    target = f" (-> {real})" if real != os.path.abspath(path) else ""
    if stat.S_ISDIR(mode):
        raise ReadError(f"{path}{target}: is a directory")
    if not stat.S_ISREG(mode):
        raise ReadError(f"{path}{target}: is {_kind(mode)}, not a regular file")
    cap = default_max_bytes() if max_bytes is None else int(max_bytes)
    if st.st_size > cap:
        raise ReadError(f"{path}: file is {_human(st.st_size)}, larger than the limit of "
                        f"{_human(cap)} (raise it with --max-file-size or "
                        "MESHOPT_MAX_FILE_BYTES)")
    return st


def open_input(path: str | os.PathLike, max_bytes: int | None = None) -> BinaryIO:
    """Open an input file for binary reading, refusing anything but a regular file.

    The path is stat'ed first (a FIFO is never opened), then opened with ``O_NONBLOCK``
    and checked again on the descriptor: a file swapped for a FIFO or a device in between
    is refused too, and the open never blocks.

    Parameters
    ----------
    path : str or PathLike
    max_bytes : int, optional
        Size cap (default :func:`default_max_bytes`; :data:`UNCAPPED` when the caller
        checked it).

    Returns
    -------
    BinaryIO
        An open file; close it (``with open_input(p) as fh: ...``).

    Raises
    ------
    ReadError
        As :func:`check_input_file`, or the file cannot be opened; names the file.
    """
    path = Path(path)
    before = _stat_regular(path, max_bytes)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise ReadError(f"{path}: cannot open: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or (st.st_dev, st.st_ino) != (before.st_dev,
                                                                      before.st_ino):
            raise ReadError(f"{path}: is {_kind(st.st_mode)}, not a regular file "
                            "(it changed while being opened)")
        if getattr(os, "O_NONBLOCK", 0):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_input(path: str | os.PathLike, max_bytes: int | None = None) -> bytes:
    """The bytes of an input file opened by :func:`open_input` (at most the cap).

    Raises
    ------
    ReadError
        As :func:`open_input`, or the file grew past the cap while it was read.
    """
    cap = default_max_bytes() if max_bytes is None else int(max_bytes)
    with open_input(path, cap) as fh:
        try:
            data = fh.read(cap + 1) if cap < UNCAPPED else fh.read()
        except OSError as exc:
            raise ReadError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if len(data) > cap:
        raise ReadError(f"{path}: file grew past the limit of {_human(cap)} while being read")
    return data
