"""Atomic file output: write to a temporary file beside the target, then move it in."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from ..errors import WriteError

__all__ = ["atomic_output"]


@contextlib.contextmanager
def atomic_output(path, *, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path (same folder, same extension) that replaces ``path`` on success.

    Without ``overwrite`` an existing target is never replaced (checked before and, with a
    hard link, atomically at the end). On error the temporary file is removed.

    Raises
    ------
    WriteError
        The target exists and ``overwrite`` is false, or the folder is not writable.
    """
    target = Path(path)
    if target.exists() and not overwrite:
        raise WriteError(f"{target}: exists (use --force / overwrite=True to replace it)")
    if not target.parent.is_dir():
        raise WriteError(f"{target}: folder {target.parent} does not exist")
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=f".tmp{target.suffix}",
                                        dir=target.parent)
    except OSError as exc:
        raise WriteError(f"{target}: cannot write: {exc}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        if overwrite:
            os.replace(tmp, target)
        else:
            try:
                os.link(tmp, target)
            except FileExistsError:
                raise WriteError(f"{target}: exists (use --force / overwrite=True to replace it)") from None
            except OSError:  # file systems without hard links
                if target.exists():
                    raise WriteError(f"{target}: exists (use --force to replace it)") from None
                os.replace(tmp, target)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def write_text_atomic(path, text: str, *, overwrite: bool = False) -> None:
    """Write a text file atomically (see :func:`atomic_output`)."""
    with atomic_output(path, overwrite=overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
