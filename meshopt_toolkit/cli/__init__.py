"""The ``meshopt`` command line: ``main(argv=None)`` with argparse subcommands.

Each subcommand lives in its own module of this package and defines

- ``HELP``: a one-line description,
- ``EPILOG`` (optional): text shown after the options, its line breaks kept,
- ``add_args(parser)``: its arguments,
- ``run(args) -> int``: the handler, returning the exit status.

Modules are discovered by name, so adding a subcommand means adding a module. Only the
chosen subcommand's ``add_args`` runs (it may import heavy defaults, e.g. the optimizer's
variants), so ``meshopt info`` and ``meshopt convert`` load neither scipy nor pymeshlab nor
gmsh nor matplotlib; ``build_parser()`` without a command builds every subcommand. Errors
derived from :class:`~meshopt_toolkit.errors.MeshoptError` become one line on stderr and
exit status 1 (2 for usage errors); ``--debug`` shows the traceback instead. So do the
failures of the machine and of the file system. Every such line names the file
(:mod:`._errors`).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys

from .. import __version__
from ..errors import MeshoptError
from ._errors import LogLine, LogStream, error_line

# the order in which subcommands are listed in --help
_ORDER = ["optimize", "deform", "morph", "info", "convert", "run", "filters"]


def _subcommand_modules() -> list[str]:
    found = [m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_")]
    return sorted(found, key=lambda n: (_ORDER.index(n) if n in _ORDER else len(_ORDER), n))


def _command_of(argv: list[str]) -> str | None:
    """The subcommand named in ``argv`` (its first word not starting with ``-``), if any.

    The top-level options take no value, so the first plain word is the subcommand.
    """
    for word in argv:
        if word == "--":
            return None
        if not word.startswith("-"):
            return word
    return None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser (used by ``main`` and by the docs).

    Parameters
    ----------
    command : str, optional
        Build only this subcommand's arguments (the others are listed with their help
        line but take no arguments); None builds all of them.
    """
    parser = argparse.ArgumentParser(
        prog="meshopt",
        description="Keep planar triangle meshes healthy while they move.",
    )
    parser.add_argument("--version", action="version", version=f"meshopt {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    names = _subcommand_modules()
    for name in names:
        module = importlib.import_module(f".{name}", __name__)
        p = sub.add_parser(name, help=module.HELP, description=module.HELP,
                           epilog=getattr(module, "EPILOG", None),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        if command is not None and command in names and name != command:
            continue
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help="show tracebacks on errors")
        module.add_args(p)
        p.set_defaults(_handler=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 failure, 2 usage error)."""
    words = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(_command_of(words))
    args = parser.parse_args(words)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    stderr = LogStream(level)  # at the verbosity asked, whatever a logger lets through
    stderr.setFormatter(LogLine(args.command or ""))
    logging.basicConfig(level=level, handlers=[stderr])  # "meshopt CMD: warning: ..."
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        _refuse_null_bytes(words)
        return int(args._handler(args) or 0)
    except KeyboardInterrupt:
        print(f"meshopt {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        if args.debug:
            raise
        print(error_line(exc, args), file=sys.stderr)
        return 1


def _refuse_null_bytes(words: list[str]) -> None:
    """A null byte cannot be in a path (or an expression): refused with the argument."""
    from ..expressions import quoted

    for word in words:
        if "\0" in word:
            raise MeshoptError(f"argument {quoted(word)} contains a null byte")


def entry_point() -> None:  # pragma: no cover - thin wrapper for console scripts
    sys.exit(main())
