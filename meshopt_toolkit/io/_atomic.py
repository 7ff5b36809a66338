"""Atomic file writes: a temporary file in the target's directory, then a rename.

The temporary file is hidden and named ``.NAME.PID.RANDOM.part``; it is removed when the
write fails. A process killed with SIGKILL cannot remove its own: such a file is left
(nothing is deleted for its name alone: it could be the user's). A batch writes into its
journaled scratch folder instead, which the next run removes
(:mod:`meshopt_toolkit.batch.journal`).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ..errors import FileWriteError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def place(staged: Path, final: Path, overwrite: bool, refusal: str = "not overwriting") -> None:
    """Put the complete file ``staged`` at ``final`` atomically (a rename, or a hard link
    that fails where ``final`` exists); without ``overwrite`` an existing ``final`` is a
    FileWriteError "already exists (``refusal``)", never replaced."""
    if overwrite:
        os.replace(staged, final)
        return
    try:
        os.link(staged, final)
    except FileExistsError:
        raise FileWriteError(f"{final}: already exists ({refusal})") from None
    except OSError:  # a file system without hard links: best effort
        if final.exists():
            raise FileWriteError(f"{final}: already exists ({refusal})") from None
        os.replace(staged, final)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, overwrite: bool = True) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it onto ``path``.

    If the body raises, the temporary file is removed and ``path`` is untouched: a reader
    never sees a partial file. With ``overwrite=False`` an existing ``path`` is refused,
    before any work and again at the final (hard-link based, race-free) publish step.

    Raises
    ------
    FileWriteError
        ``path`` exists and ``overwrite`` is false, its directory is missing, or the
        temporary file cannot be created or moved.
    """
    path = Path(path)
    if not overwrite and path.exists():
        raise FileWriteError(f"{path}: already exists (not overwriting)")
    if path.is_dir():
        raise FileWriteError(f"{path}: is a directory")
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise FileWriteError(f"{path}: directory {directory} does not exist")
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".part",
                                        dir=directory)
    except OSError as exc:
        raise FileWriteError(f"{path}: cannot create a file in {directory}: {exc.strerror}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        os.chmod(tmp, 0o666 & ~_umask())
        yield tmp
        place(tmp, path, overwrite)
    except OSError as exc:
        raise FileWriteError(f"{path}: {exc.strerror or exc}") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
