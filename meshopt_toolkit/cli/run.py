"""``meshopt run PIPELINE INPUT... -o OUTDIR``: run a JSON or .mlx pipeline over meshes.

Each input is loaded, the pipeline runs on it (meshopt filters in Python, MeshLab filters
routed to pymeshlab) and the current mesh is saved as ``OUTDIR/<stem><ext>`` unless the
pipeline has its own ``save_mesh`` step. Outputs are atomic and never overwrite without
``--force``. A failing file is reported and the others go on (exit status 1 with a
summary). Pipelines with MeshLab or plugin steps run each file in a worker process
(``--isolate auto``) so that a native crash cannot take the batch down.

The pipeline file is untrusted; the command line is the only authority:

- it writes only inside ``-o`` (absolute paths, ``..`` and escaping symlinks refused) and
  replaces files only with ``--force`` (whatever ``"overwrite"`` it says);
- it reads only the inputs and what ``--allow-read`` names;
- the current mesh may not grow past ``--max-triangles`` (estimated before each step,
  measured after it);
- a MeshLab step that inverts triangles of a planar mesh that was admissible fails the
  file (nothing written) unless ``--allow-inverted`` (then a warning on stderr).

``--dry-run`` runs no filter and writes nothing, but checks all of this from the inputs
(``-o`` is optional then: without it existing outputs are not looked for). It prints the
steps, then ``checked INPUT -> would write OUTPUT`` per input, and ends with
``dry run: N checked, F failed, nothing written``.

Batches (shared with ``meshopt convert``, see :mod:`meshopt_toolkit.batch.run`):
``-j N`` runs files in N worker processes (0: all cores), each file isolated; ``--resume``
skips files a journal in OUTDIR knows as done with the same input and pipeline;
``--scheduler ADDRESS`` runs on a Dask cluster (inputs sent as bytes, or read from the
same path with ``--shared-inputs``). Records and errors come in input order; the last
line is ``N done, K skipped, F failed in T s``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import MeshoptError
from ._batch import add_batch_args, batch_client, check_batch_args, reporter
from ._common import (add_force_flag, add_inputs, check_mesh_format, check_writable,
                      make_output_dir)
from ._validate import int_at_least

HELP = "run a pipeline (.json or MeshLab .mlx) over one mesh or a batch"


def add_args(parser) -> None:
    from ..pipeline.limits import DEFAULT_MAX_TRIANGLES

    parser.add_argument("pipeline", metavar="PIPELINE", help="pipeline file (.json or .mlx)")
    add_inputs(parser)
    parser.add_argument("-o", "--output", metavar="OUTDIR",
                        help="output directory (created if missing); the only place the "
                             "pipeline writes (optional with --dry-run)")
    parser.add_argument("--to", metavar="EXT", help="output format (default: the input's)")
    add_force_flag(parser, "a pipeline cannot grant this itself")
    parser.add_argument("--dry-run", action="store_true",
                        help="check the pipeline, paths and size budget on the inputs; run "
                             "no filter, write nothing")
    parser.add_argument("--allow-read", action="append", default=[], metavar="PATH",
                        help="a file or folder the pipeline may read (load_mesh), besides "
                             "the inputs; repeatable")
    parser.add_argument("--max-triangles", type=int_at_least(1, "a positive integer"),
                        default=DEFAULT_MAX_TRIANGLES, metavar="N",
                        help="refuse steps that would make the mesh larger "
                             f"(default {DEFAULT_MAX_TRIANGLES:,})")
    parser.add_argument("--allow-inverted", action="store_true",
                        help="write meshes a MeshLab step left with inverted triangles "
                             "(warning) instead of failing the file")
    parser.add_argument("--isolate", choices=("auto", "always", "never"), default="auto",
                        help="run each file in a worker process (auto: when the pipeline "
                             "has MeshLab or plugin steps)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON record per file (results of each step)")
    add_batch_args(parser)


def _outdir(args) -> Path | None:
    if args.output is None:
        if not args.dry_run:
            raise MeshoptError("-o/--output OUTDIR is required (except with --dry-run)")
        return None
    outdir = Path(args.output)
    if outdir.exists() and not outdir.is_dir():
        raise MeshoptError(f"{outdir}: exists and is not a directory")
    if not args.dry_run:
        make_output_dir(outdir)
        check_writable(outdir)  # before any file is processed
    return outdir


def run(args) -> int:
    from ..pipeline import load_pipeline
    from ..batch.file_job import RunOptions
    from ..batch.progress import BatchProgress
    from ..batch.run import Job, execute
    from ..batch.tasks import RunTask
    from ._common import expand_inputs
    from ._errors import naming

    pipeline = load_pipeline(args.pipeline)  # errors here are fatal (one line, exit 1)
    pipeline.validate()
    check_batch_args(args)
    ext = None if not args.to else check_mesh_format(args.to, "--to")
    errors: list[str] = []
    inputs: list[Path] = []
    seen: set[Path] = set()
    for item in args.inputs:
        try:
            for p in expand_inputs([item], include_hint="name them as inputs to include them"):
                if p not in seen:
                    seen.add(p)
                    inputs.append(p)
        except MeshoptError as exc:
            errors.append(str(exc))
            print(f"meshopt run: error: {naming(str(exc), [item])}", file=sys.stderr)
    del seen
    for item in args.allow_read:
        if not Path(item).exists():
            raise MeshoptError(f"--allow-read {item}: no such file or directory")
    outdir = _outdir(args)
    stems: dict[str, Path] = {}
    for p in inputs:
        key = p.stem + (ext or p.suffix.lower())
        if key in stems:
            where = key if outdir is None else outdir / key
            raise MeshoptError(f"{p} and {stems[key]} would both be written to {where}")
        stems[key] = p
    del stems
    # a dry run executes no filter, so nothing native can crash
    auto = not pipeline.only_builtin and not args.dry_run
    isolate = {"always": True, "never": False}.get(args.isolate, auto)
    options = RunOptions(ext=ext, force=args.force, dry_run=args.dry_run,
                         inputs=[str(p) for p in inputs], allow_read=list(args.allow_read),
                         max_triangles=args.max_triangles, allow_inverted=args.allow_inverted)
    if args.dry_run and not args.json:
        print(_plan(args.pipeline, pipeline, len(inputs), outdir), flush=True)
    line = None if args.json or not args.dry_run else _would_write(outdir)
    with BatchProgress(len(inputs), "run") as bar, batch_client(args) as client:
        result = execute(RunTask(pipeline, options),
                         (Job(i, p) for i, p in enumerate(inputs, start=1)), outdir,
                         workers=args.jobs, isolate=isolate, client=client,
                         send_inputs="path" if args.shared_inputs else "bytes",
                         resume=args.resume, force=args.force, dry_run=args.dry_run,
                         on_record=reporter("run", args.json, bar, line, args.dry_run),
                         progress=bar)
    result.failed += len(errors)  # inputs that matched nothing
    print(f"meshopt run: {result.report()}", file=sys.stderr)
    return 1 if errors or result.failed or not inputs else 0


def _plan(source: str, pipeline, n_inputs: int, outdir: Path | None) -> str:
    """What a dry run checks: the steps, the inputs, where outputs would go."""
    steps = "; ".join(f"{i}. {s.name}" for i, s in enumerate(pipeline.steps, start=1))
    where = ("outputs not looked for (no -o)" if outdir is None
             else f"outputs into {outdir}/")
    return (f"dry run of {source}: {len(pipeline.steps)} step(s): {steps or '(none)'}; "
            f"{n_inputs} input(s), {where}; no filter runs, nothing is written")


def _would_write(outdir: Path | None):
    """A dry run's line for each input checked."""

    def line(rec: dict) -> str:
        if rec.get("outputs"):
            return f"checked {rec['input']} -> would write {', '.join(rec['outputs'])}"
        why = ("no -o: outputs not looked for" if outdir is None
               else "the pipeline's save_mesh steps name its outputs")
        return f"checked {rec['input']} ({why})"

    return line
