"""``meshopt convert INPUT... -o OUTPUT [--to EXT] [--force]``: convert mesh files.

One input: OUTPUT is a file and its extension picks the format. Several inputs (or a glob
or directory): OUTPUT is a directory (created if missing) and ``--to`` picks the format;
``--recursive`` includes the sub-folders of an input directory (mirrored under OUTPUT),
otherwise skipped sub-folders are named in a warning.

Conversion is lossless or refused: every cell block (triangles, quads, polygons, lines,
vertices, ...), point, cell and field data is written, physical groups travel as
``gmsh:physical``/``gmsh:geometrical`` cell data, OBJ/PLY normals and texture coordinates
as point data; a target format that cannot hold a part refuses the file with one line
naming it, and so does an input with content the reader cannot represent (e.g. OBJ
groups). ``--allow-loss`` writes what the target can hold instead and names the rest in
one line (``meshopt convert: warning: IN: dropped: gmsh:physical cell data; 6 line
cells``). Each success prints ``wrote OUT (N vertices, M cells)``.

Existing outputs, the input included, are never overwritten without ``--force``; each
write is atomic. A bad file in a batch is reported and skipped; the exit status is then 1.
Usage errors exit with 2. :func:`convert_file` converts one file (for batch runners).
``-j``, ``--resume``, ``--scheduler`` and ``--shared-inputs`` work as in ``meshopt run``.
"""

from __future__ import annotations

import argparse
import glob
import sys
from dataclasses import dataclass
from pathlib import Path

from ..errors import MeshoptError, ReadError
from ._batch import add_batch_args, batch_client, check_batch_args, reporter
from ._common import add_force_flag, add_inputs, add_recursive_flag
from ._params import add_options

HELP = "convert mesh files between formats (msh, obj, ply, off, vtk, vtu, stl)"
#: options generated from the save_mesh filter's parameters (one schema: cli/_params.py)
OPTIONS = {"msh_version": "--msh-version"}


def add_args(parser) -> None:
    add_inputs(parser)
    parser.add_argument("-o", "--output", required=True, metavar="OUTPUT",
                        help="output file (one input) or directory (several inputs)")
    parser.add_argument("--to", metavar="EXT",
                        help="output format for a batch, e.g. vtu or .msh")
    add_force_flag(parser, "even an input")
    from ..filters.save_mesh import SaveMesh, binary_of

    # the output options of save_mesh (one schema): --binary/--ascii are its "encoding"
    mode = parser.add_mutually_exclusive_group()
    for encoding, help_text in (("binary", "binary output where the format has both (the "
                                           "default for all but obj and off)"),
                                ("ascii", "text output")):
        mode.add_argument(f"--{encoding}", dest="binary", action="store_const",
                          const=binary_of(encoding), default=binary_of("default"), help=help_text)
    add_options(parser, SaveMesh, OPTIONS)
    parser.add_argument("--allow-loss", action="store_true",
                        help="write what the output format can hold and name what is "
                             "dropped (physical groups, line cells, data, ...)")
    add_recursive_flag(parser)
    parser.add_argument("--max-file-size", type=_size, default=None, metavar="SIZE",
                        help="refuse input files larger than this (default 4G; e.g. 500M, 16G)")
    add_batch_args(parser)


def _size(text: str) -> int:
    from ..io._files import parse_size

    try:
        return parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


@dataclass
class ConvertOptions:
    """What :func:`convert_file` needs of the command line."""

    force: bool = False
    binary: bool | None = None
    msh_version: str = "input"
    max_bytes: int | None = None
    allow_loss: bool = False

    @classmethod
    def from_args(cls, args) -> "ConvertOptions":
        return cls(force=bool(getattr(args, "force", False)),
                   allow_loss=bool(getattr(args, "allow_loss", False)),
                   binary=getattr(args, "binary", None),
                   msh_version=getattr(args, "msh_version", "input"),
                   max_bytes=getattr(args, "max_file_size", None))


def convert_file(src: str | Path, dst: str | Path, options: ConvertOptions):
    """Convert one file losslessly (or refuse; with ``allow_loss``, what the output format
    can hold) and return the written :class:`~meshopt_toolkit.io.CellMesh`, whose
    ``dropped`` names what was left out (empty for a lossless conversion).

    Raises
    ------
    ReadError
        Unreadable input, or content the reader cannot represent (``dropped``) without
        ``allow_loss``.
    WriteError
        Existing output without ``force``, or a part the output format cannot hold
        without ``allow_loss``.
    """
    from ..errors import WriteError
    from ..io import fit_cells, load_cells, save_cells

    src, dst = Path(src), Path(dst)
    if not options.force and dst.exists():
        same = dst.resolve() == src.resolve()
        raise WriteError(f"{dst}: {'is the input file' if same else 'already exists'} "
                         "(use --force to overwrite)")
    cells = load_cells(src, max_bytes=options.max_bytes)
    hint = "; --allow-loss writes the rest and names what it drops"
    if cells.dropped and not options.allow_loss:
        raise ReadError(f"{src}: cannot convert without loss: {'; '.join(cells.dropped)} "
                        f"would not be kept{hint}")
    fitted, lost = fit_cells(cells, dst)
    try:
        save_cells(fitted if options.allow_loss else cells, dst, overwrite=options.force,
                   binary=options.binary, msh_version=options.msh_version)
    except WriteError as exc:
        raise WriteError(f"{exc}{hint}" if lost and not options.allow_loss else str(exc)) \
            from None
    return fitted


def _wrote(dst: Path, cells) -> str:
    return f"wrote {dst} ({cells.n_points} vertices, {cells.n_cells} cells)"


def _dropped(cells) -> list[str]:
    """The one warning of a lossy conversion (``["dropped: ..."]``), or none."""
    return [f"dropped: {'; '.join(cells.dropped)}"] if cells.dropped else []


def _convert_in_batch(src: Path, dst: Path, args) -> dict:
    """:func:`convert_file` as a batch task calls it (a worker process or a Dask worker)."""
    cells = convert_file(src, dst, ConvertOptions.from_args(args))
    return {"n_points": int(cells.n_points), "n_cells": int(cells.n_cells),
            "warnings": _dropped(cells)}


def _usage(msg: str, args) -> int:
    from ._errors import naming

    print(f"meshopt convert: error: {naming(msg, args.inputs, [args.output])}", file=sys.stderr)
    return 2


def _plan(args) -> tuple[list[tuple[Path, Path]], list[str]] | int:
    """``(jobs, failures)`` with jobs ``(input, output)``, or an exit status for usage errors."""
    from ..io import supported_extensions
    from ._common import expand_inputs

    writable = supported_extensions("write")
    to = None
    if args.to:
        to = args.to.lower() if args.to.startswith(".") else "." + args.to.lower()
        if to not in writable:
            return _usage(f"--to {args.to}: unknown format; choose from "
                          f"{', '.join(writable)}", args)
    inputs: list[Path] = []
    rel: dict[Path, Path] = {}  # input → output name relative to OUTPUT
    failures: list[str] = []
    batch = len(args.inputs) > 1
    recursive = bool(getattr(args, "recursive", False))
    for item in args.inputs:
        is_dir = Path(item).is_dir()
        if is_dir or (not Path(item).exists() and glob.has_magic(item)):
            batch = True
        try:
            for p in expand_inputs([item], recursive=recursive):
                if p not in inputs:
                    inputs.append(p)
                    rel[p] = p.relative_to(item).parent if is_dir and recursive else Path()
        except MeshoptError as exc:
            failures.append(str(exc))
    out = Path(args.output)
    batch = batch or len(inputs) > 1
    as_dir = (out.is_dir() or args.output.endswith(("/", "\\"))
              or (to is not None and not out.suffix))
    if not batch:
        if as_dir:
            if to is None:
                return _usage(f"{out} is a directory: give --to EXT or an output file name", args)
            return ([(p, out / (p.stem + to)) for p in inputs], failures)
        ext = out.suffix.lower()
        if to is not None and ext != to:
            return _usage(f"output {out} does not end in {to} given by --to", args)
        if ext not in writable:
            return _usage(f"output {out}: unknown format {ext or '(no extension)'!r}; "
                          f"choose from {', '.join(writable)}", args)
        return ([(p, out) for p in inputs], failures)
    if to is None:
        return _usage("several inputs: OUTPUT is a directory and --to EXT picks the format", args)
    if out.exists() and not out.is_dir():
        return _usage(f"several inputs: OUTPUT {out} must be a directory, it is a file", args)
    jobs = [(p, out / rel.get(p, Path()) / (p.stem + to)) for p in inputs]
    seen: dict[Path, Path] = {}
    for src, dst in jobs:
        if dst in seen:
            return _usage(f"{src} and {seen[dst]} would both be written to {dst}", args)
        seen[dst] = src
    return jobs, failures


def run(args) -> int:
    from ..batch.progress import BatchProgress
    from ..batch.run import Job, execute
    from ..batch.tasks import ConvertTask

    check_batch_args(args)
    plan = _plan(args)
    if isinstance(plan, int):
        return plan
    jobs, failures = plan
    for msg in failures:  # each names its item (expand_inputs)
        print(f"meshopt convert: error: {msg}", file=sys.stderr)
    if not jobs:
        return 1
    options = ConvertOptions.from_args(args)
    simple = not args.resume and not args.scheduler  # -j does not matter for one file
    if simple and len(jobs) == 1 and not failures and jobs[0][1] == Path(args.output):
        from ._common import check_output_file

        # before reading the input: the directory (convert_file refuses an existing file)
        check_output_file(jobs[0][1], force=True)
        cells = convert_file(*jobs[0], options)  # a single file: errors go to main()
        print(_wrote(jobs[0][1], cells), flush=True)
        for warning in _dropped(cells):
            print(f"meshopt convert: warning: {jobs[0][0]}: {warning}", file=sys.stderr)
        return 0
    outdir = Path(args.output) if jobs[0][1] != Path(args.output) else jobs[0][1].parent

    def wrote(rec: dict) -> str:
        info = rec["results"][0]
        return f"wrote {rec['outputs'][0]} ({info['n_points']} vertices, {info['n_cells']} cells)"

    task = ConvertTask(_convert_in_batch, args, args.to and jobs[0][1].suffix)
    with BatchProgress(len(jobs), "convert") as bar, batch_client(args) as client:
        result = execute(task, (Job(i, src, str(dst.relative_to(outdir)))
                                for i, (src, dst) in enumerate(jobs, 1)),
                         outdir, workers=args.jobs, client=client,
                         send_inputs="path" if args.shared_inputs else "bytes",
                         resume=args.resume, force=args.force,
                         on_record=reporter("convert", False, bar, wrote), progress=bar)
    result.failed += len(failures)  # inputs that matched nothing
    print(f"meshopt convert: {result.report()}", file=sys.stderr)
    return 1 if result.failed else 0
