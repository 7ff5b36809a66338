"""Errors as one line on stderr naming the file: ``meshopt CMD: error: FILE: cause``.

Every line a subcommand prints for a failure goes through :func:`error_line` (whole
commands, from :func:`meshopt_toolkit.cli.main`) or :func:`naming` (one file of a batch,
one path of ``meshopt info``). A message that does not already name one of the
command's files (an input, the output, a table it reads) gets the file the command
works on in front, so an error raised deep in the library (``reference triangle 320 is
degenerate``) still says which file it is about. The failures of the machine and of the
file system (out of memory, a floating-point trap, a full disk, an existing file, a null
byte in a path) are one such line too; anything else is a bug, reported as
``internal error: FILE: TYPE: message`` (``--debug`` shows the traceback). Long user
text (expressions, paths) is cut. Log lines (warnings) take the same form
(:class:`LogLine`): ``meshopt CMD: warning: …``.
"""

from __future__ import annotations

import errno
import logging
import re
from collections.abc import Iterable
from pathlib import Path

from ..errors import MeshoptError

#: the longest error line printed (a safety net: messages cut user text themselves)
MAX_MESSAGE = 1000

#: arguments naming the files a command works on, in the order a message names them
SUBJECT_ARGS = ("mesh", "source", "target", "meshes", "inputs")
#: further arguments naming files: a message naming one of these names its file
OTHER_PATH_ARGS = ("pipeline", "output", "targets", "displacement", "allow_read")
#: the commands whose whole-command errors are about the pipeline, not the meshes
PIPELINE_COMMANDS = ("run",)


def _values(args, keys: Iterable[str]) -> list[str]:
    names: list[str] = []
    for key in keys:
        value = getattr(args, key, None)
        if value:
            names.extend(str(v) for v in (value if isinstance(value, (list, tuple))
                                          else [value]))
    return names


def subject(args) -> list[str]:
    """The files a whole command works on, for a message that names none: the pipeline
    of ``meshopt run``, else the input meshes (the bundled mesh of ``meshopt optimize``
    without one)."""
    if getattr(args, "command", None) in PIPELINE_COMMANDS:
        return _values(args, ("pipeline",))
    names = _values(args, SUBJECT_ARGS)
    if not names and getattr(args, "command", None) == "optimize":
        from .. import data_path
        from .optimize import DEFAULT_MESH

        names = [str(data_path(DEFAULT_MESH))]
    return list(dict.fromkeys(names))  # each once (a morph of a file into itself)


def _forms(name: str) -> set[str]:
    """The spellings of a path a message may use: as given, normalized, absolute."""
    forms = {name, str(Path(name))}
    try:
        forms |= {str(Path(name).absolute()), str(Path(name).resolve())}
    except (OSError, RuntimeError, ValueError):  # pragma: no cover - a broken path
        pass
    return {f for f in forms if f and f != "."}


def names_one_of(text: str, names: Iterable[str]) -> bool:
    """Whether ``text`` names one of the paths ``names`` (or a file under one) as a
    whole word: ``out`` is named by ``out/frame_000.msh: …``, not by ``about``."""
    for name in names:
        for form in _forms(name):
            if re.search(r"(?<![\w.-])" + re.escape(form) + r"(?![\w-]|\.\w)", text):
                return True
    return False


def _cut(name, limit: int = 200) -> str:
    """A path (or a file descriptor) for a message, cut past ``limit`` characters."""
    text = str(name)
    return text if len(text) <= limit else f"{text[:limit]}… ({len(text)} chars)"


def _joined(files: list[str]) -> str:
    if not files:
        return "the input"
    shown = ", ".join(_cut(f) for f in files[:3])
    return shown + (f" and {len(files) - 3} more" if len(files) > 3 else "")


def naming(text: str, files: list[str], others: Iterable[str] = ()) -> str:
    """``text`` as ``"FILE: cause"``: unchanged where it names one of ``files`` or
    ``others`` already (or a command has no file: ``meshopt filters``), else with
    ``files`` (joined) in front."""
    if files and not names_one_of(text, [*files, *others]):
        text = f"{_joined(files)}: {text}"
    return _one_line(text)


def _one_line(text: str) -> str:
    """``text`` on one line: line breaks as spaces, other control characters escaped,
    cut past :data:`MAX_MESSAGE` characters."""
    text = " ".join(text.splitlines())
    if not text.isprintable():
        text = "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii")
                       for c in text)
    return text if len(text) <= MAX_MESSAGE else f"{text[:MAX_MESSAGE]}… ({len(text)} chars)"


def _cause(exc: BaseException, args, files: list[str]) -> tuple[str, str]:
    """``(kind, message)`` of an exception: kind "error" or "internal error"."""
    output = getattr(args, "output", None)
    shown = _joined(files)
    if isinstance(exc, MeshoptError):
        return "error", str(exc)
    if isinstance(exc, MemoryError):
        return "error", (f"out of memory while running 'meshopt {args.command}' on {shown} "
                         "(try a smaller mesh, fewer frames or fewer jobs)")
    if isinstance(exc, FloatingPointError):
        return "error", (f"{shown}: floating-point error in the computation ({exc}); "
                         "the mesh or the options may be degenerate")
    if isinstance(exc, FileExistsError):
        name = exc.filename or output or shown
        return "error", f"{_cut(name)}: exists (use --force to overwrite)"
    if isinstance(exc, OSError) and exc.errno == errno.ENOSPC:
        name = exc.filename or output or shown
        return "error", f"{_cut(name)}: no space left on device (nothing was replaced)"
    if isinstance(exc, OSError) and exc.filename is not None:
        return "error", f"{_cut(exc.filename)}: {exc.strerror or exc}"
    if isinstance(exc, ValueError) and "null" in str(exc) and "byte" in str(exc):
        return "error", f"{shown}: a path or expression contains a null byte"
    return "internal error", (f"{type(exc).__name__}: {exc} "
                              "(run with --debug for the traceback)")


def error_line(exc: BaseException, args) -> str:
    """The one line a failed command prints: ``meshopt CMD: error: FILE: cause``.

    Parameters
    ----------
    exc : the exception that ended the command
    args : the parsed arguments (``args.command`` and the paths it names; the files the
        failure is about when its message names none: :func:`subject`)
    """
    files = subject(args)
    kind, text = _cause(exc, args, files)
    text = naming(text, files, _values(args, SUBJECT_ARGS + OTHER_PATH_ARGS))
    return f"meshopt {args.command}: {kind}: {text}"


class LogStream(logging.StreamHandler):
    """stderr's log handler at a verbosity: on a terminal each line is written over the
    line a progress bar may have drawn there (the bar is drawn again below it)."""

    def __init__(self, level: int) -> None:
        super().__init__()
        self.setLevel(level)

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        isatty = getattr(self.stream, "isatty", None)
        return "\r" + text.ljust(119) if isatty is not None and isatty() else text


class LogLine(logging.Formatter):
    """Log records of a command as its other lines: ``meshopt CMD: warning: message``
    (one line), not ``WARNING:...``."""

    def __init__(self, command: str) -> None:
        super().__init__()
        self.command = command

    def format(self, record: logging.LogRecord) -> str:
        return f"meshopt {self.command}: {record.levelname.lower()}: " \
               f"{_one_line(record.getMessage())}"
