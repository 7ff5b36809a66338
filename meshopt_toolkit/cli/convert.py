"""``meshopt convert INPUT... -o OUTPUT [--to EXT] [--force]``: convert mesh files.

One input: OUTPUT is a file and its extension picks the format. Several inputs (or a glob
or directory): OUTPUT is a directory (created if missing) and ``--to`` picks the format.
Existing outputs, the input included, are never overwritten without ``--force``; each
write is atomic. A bad file in a batch is reported and skipped; the exit status is then 1.
Usage errors exit with 2. ``-j``, ``--resume``, ``--scheduler`` and ``--shared-inputs``
work as in ``meshopt run``.
"""

from __future__ import annotations

import glob
import sys
from pathlib import Path

from ..errors import MeshoptError

HELP = "convert mesh files between formats (msh, obj, ply, off, vtk, vtu, stl)"


def add_args(parser) -> None:
    parser.add_argument("inputs", nargs="+", metavar="INPUT",
                        help="mesh files, globs or directories")
    parser.add_argument("-o", "--output", required=True, metavar="OUTPUT",
                        help="output file (one input) or directory (several inputs)")
    parser.add_argument("--to", metavar="EXT",
                        help="output format for a batch, e.g. vtu or .msh")
    parser.add_argument("--force", action="store_true",
                        help="overwrite existing output files (even an input)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--binary", dest="binary", action="store_const", const=True, default=None,
                      help="binary output where the format allows (the default)")
    mode.add_argument("--ascii", dest="binary", action="store_const", const=False,
                      help="text output")
    parser.add_argument("--msh-version", choices=("4.1", "2.2"), default="4.1",
                        help="gmsh version for .msh output (default 4.1)")
    from .run import add_batch_args

    add_batch_args(parser)


def _usage(msg: str) -> int:
    print(f"meshopt convert: error: {msg}", file=sys.stderr)
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
            return _usage(f"--to {args.to}: unknown format; choose from {', '.join(writable)}")
    inputs: list[Path] = []
    failures: list[str] = []
    batch = len(args.inputs) > 1
    for item in args.inputs:
        if Path(item).is_dir() or (not Path(item).exists() and glob.has_magic(item)):
            batch = True
        try:
            inputs.extend(p for p in expand_inputs([item]) if p not in inputs)
        except MeshoptError as exc:
            failures.append(str(exc))
    out = Path(args.output)
    batch = batch or len(inputs) > 1
    as_dir = (out.is_dir() or args.output.endswith(("/", "\\"))
              or (to is not None and not out.suffix))
    if not batch:
        if as_dir:
            if to is None:
                return _usage(f"{out} is a directory: give --to EXT or an output file name")
            return ([(p, out / (p.stem + to)) for p in inputs], failures)
        ext = out.suffix.lower()
        if to is not None and ext != to:
            return _usage(f"output {out} does not end in {to} given by --to")
        if ext not in writable:
            return _usage(f"output {out}: unknown format {ext or '(no extension)'!r}; "
                          f"choose from {', '.join(writable)}")
        return ([(p, out) for p in inputs], failures)
    if to is None:
        return _usage("several inputs: OUTPUT is a directory and --to EXT picks the format")
    if out.exists() and not out.is_dir():
        return _usage(f"several inputs: OUTPUT {out} must be a directory, it is a file")
    jobs = [(p, out / (p.stem + to)) for p in inputs]
    seen: dict[Path, Path] = {}
    for src, dst in jobs:
        if dst in seen:
            return _usage(f"{src} and {seen[dst]} would both be written to {dst}")
        seen[dst] = src
    return jobs, failures


def _convert_one(src: Path, dst: Path, args) -> None:
    from ..errors import WriteError
    from ..io import load, save

    if not args.force and dst.exists():
        same = dst.resolve() == src.resolve()
        raise WriteError(f"{dst}: {'is the input file' if same else 'already exists'} "
                         "(use --force to overwrite)")
    mesh = load(src)
    save(mesh, dst, overwrite=args.force, binary=args.binary, msh_version=args.msh_version)


def run(args) -> int:
    from ..pipeline.batch_progress import BatchProgress
    from ..pipeline.batch_run import Job, execute
    from ..pipeline.tasks import ConvertTask
    from .run import batch_client, check_batch_args, reporter

    check_batch_args(args)
    plan = _plan(args)
    if isinstance(plan, int):
        return plan
    jobs, failures = plan
    for msg in failures:
        print(f"meshopt convert: error: {msg}", file=sys.stderr)
    if not jobs:
        return 1
    simple = not args.resume and not args.scheduler  # -j does not matter for one file
    if simple and len(jobs) == 1 and not failures and jobs[0][1] == Path(args.output):
        _convert_one(*jobs[0], args)  # a single file: errors go to main()
        return 0
    outdir = jobs[0][1].parent
    task = ConvertTask(_convert_one, args, args.to and jobs[0][1].suffix)
    with BatchProgress(len(jobs), "convert") as bar, batch_client(args) as client:
        result = execute(task, (Job(i, src, dst.name) for i, (src, dst) in enumerate(jobs, 1)),
                         outdir, workers=args.jobs, client=client,
                         send_inputs="path" if args.shared_inputs else "bytes",
                         resume=args.resume, force=args.force,
                         on_record=reporter("convert", False, bar), progress=bar)
    result.failed += len(failures)  # inputs that matched nothing
    print(f"meshopt convert: {result.summary()}", file=sys.stderr)
    return 1 if result.failed else 0
