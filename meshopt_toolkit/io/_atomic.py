"""Atomic file writes: a temporary file in the target's directory, then a rename.

The temporary file is hidden and named ``.NAME.PID.RANDOM.part``. A run killed with
SIGKILL cannot remove its own; the next atomic write into the same directory removes the
``.part`` files whose process no longer runs on this machine, and logs a warning naming
them.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ..errors import WriteError

logger = logging.getLogger(__name__)

_PART = re.compile(r"^\..+\.(\d+)\.[A-Za-z0-9_]+\.part$")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):
        return True  # someone else's process (or unknown): leave its file alone
    return True


def clean_stale_parts(directory: str | os.PathLike) -> list[Path]:
    """Remove the ``.part`` files of dead writers in ``directory``; return their paths.

    Only hidden files that match this module's naming (``.NAME.PID.RANDOM.part``) and
    whose PID is not a running process are removed; errors are ignored.
    """
    removed = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for entry in entries:
        m = _PART.match(entry.name)
        if not m or not entry.is_file(follow_symlinks=False) or _alive(int(m.group(1))):
            continue
        with contextlib.suppress(OSError):
            os.unlink(entry.path)
            removed.append(Path(entry.path))
    if removed:
        logger.warning("removed %d partial file(s) left by an interrupted run: %s",
                       len(removed), ", ".join(p.name for p in removed))
    return removed


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, overwrite: bool = True) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it onto ``path``.

    Stale ``.part`` files of killed writers in the directory are removed first
    (:func:`clean_stale_parts`). If the body raises, the temporary file is removed and ``path`` is untouched: a reader
    never sees a partial file. With ``overwrite=False`` an existing ``path`` is refused,
    before any work and again at the final (hard-link based, race-free) publish step.

    Raises
    ------
    WriteError
        ``path`` exists and ``overwrite`` is false, its directory is missing, or the
        temporary file cannot be created or moved.
    """
    path = Path(path)
    if not overwrite and path.exists():
        raise WriteError(f"{path}: already exists (not overwriting)")
    if path.is_dir():
        raise WriteError(f"{path}: is a directory")
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise WriteError(f"{path}: directory {directory} does not exist")
    clean_stale_parts(directory)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".part",
                                        dir=directory)
    except OSError as exc:
        raise WriteError(f"{path}: cannot create a file in {directory}: {exc.strerror}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        os.chmod(tmp, 0o666 & ~_umask())
        yield tmp
        if overwrite:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)
            except FileExistsError:
                raise WriteError(f"{path}: already exists (not overwriting)") from None
            except OSError:  # file system without hard links: best effort
                if path.exists():
                    raise WriteError(f"{path}: already exists (not overwriting)") from None
                os.replace(tmp, path)
    except OSError as exc:
        raise WriteError(f"{path}: {exc.strerror or exc}") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
